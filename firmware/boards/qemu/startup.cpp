// Vector table, reset and fault entry of the emulated boards' images (ARMv7-M B1.5.3 vector table). One table for
// both: the board's link-UART interrupts (board_config.h kLinkIrqs: mps2-an386 UART0 RX = IRQ 0 and TX = IRQ 1 as
// wired by QEMU hw/arm/mps2.c; ast1030-evb UART5 = IRQ 8 as wired by QEMU 7.2 hw/arm/aspeed_ast10x0.c) all enter
// LinkUart_Handler (board_main.cpp); every other interrupt is unexpected and faults.
#include <cstdint>

#include "board_config.h"
#include "phalanx/mcu/cortex_m.h"

extern "C" [[noreturn]] void phalanx_fatal(const char* why);
extern "C" void SysTick_Handler();
extern "C" void PendSV_Handler();
extern "C" void LinkUart_Handler();
extern "C" void phalanx_initial_sp();  // = __stack_top__ (linker script); a function type makes its address a constant
extern "C" [[noreturn]] void phalanx_board_main();

PHALANX_CM4_RESET_HANDLER()

extern "C" [[noreturn]] void phalanx_reset_continue() {
  phalanx::mcu::cm4::runtimeInit();
  phalanx_board_main();
}

extern "C" void NMI_Handler() { phalanx_fatal("NMI"); }
extern "C" void HardFault_Handler() { phalanx_fatal("HardFault"); }
extern "C" void MemManage_Handler() { phalanx_fatal("MemManage"); }
extern "C" void BusFault_Handler() { phalanx_fatal("BusFault"); }
extern "C" void UsageFault_Handler() { phalanx_fatal("UsageFault"); }
extern "C" void Unexpected_Handler() { phalanx_fatal("unexpected interrupt"); }

namespace {
using Handler = void (*)();
constexpr uint32_t kIrqs = 32;

struct VectorTable {
  Handler core[16];
  Handler irq[kIrqs];
};

constexpr VectorTable makeTable() {
  VectorTable t{};
  t.core[0] = phalanx_initial_sp;
  t.core[1] = Reset_Handler;
  t.core[2] = NMI_Handler;
  t.core[3] = HardFault_Handler;
  t.core[4] = MemManage_Handler;
  t.core[5] = BusFault_Handler;
  t.core[6] = UsageFault_Handler;
  t.core[11] = Unexpected_Handler;  // SVCall
  t.core[12] = Unexpected_Handler;  // DebugMon
  t.core[14] = PendSV_Handler;      // the simulated plant (board_main.cpp)
  t.core[15] = SysTick_Handler;
  for (uint32_t i = 0; i < kIrqs; ++i) t.irq[i] = Unexpected_Handler;
  for (const uint32_t irq : phalanx::mcu::board::kLinkIrqs) t.irq[irq] = LinkUart_Handler;
  return t;
}

static_assert([] {
  for (const uint32_t irq : phalanx::mcu::board::kLinkIrqs) {
    if (irq >= kIrqs) return false;
  }
  return true;
}(), "board_config.h: a link interrupt beyond the vector table");
}  // namespace

extern "C" __attribute__((section(".isr_vector"), used)) const VectorTable g_vectors = makeTable();
