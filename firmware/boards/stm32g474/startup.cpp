// Vector table, reset and fault entry of the STM32G474 image (ARMv7-M B1.5.3; RM0440 Table 97: 102 interrupts).
#include <cstdint>

#include "flash_pages.h"
#include "phalanx/mcu/cortex_m.h"
#include "regs.h"

extern "C" [[noreturn]] void phalanx_fatal(const char* why);
extern "C" [[noreturn]] void phalanx_board_main();
extern "C" void SysTick_Handler();
extern "C" void EstopExti_Handler();
extern "C" void UsartTxDma_Handler();
extern "C" void phalanx_initial_sp();  // = __stack_top__ (linker script)

PHALANX_CM4_RESET_HANDLER()

extern "C" [[noreturn]] void phalanx_reset_continue() {
  phalanx::mcu::cm4::runtimeInit();
  phalanx_board_main();
}

/// A double-bit ECC error in a settings page (a save cut by a reset) is survivable: the read returned garbage the
/// record's CRC rejects, and the other slot holds the previous record. Any other NMI is fatal.
extern "C" void NMI_Handler() {
  if (phalanx::mcu::g474::takeSettingsEccError()) return;
  phalanx_fatal("NMI (clock security system?)");
}
extern "C" void HardFault_Handler() { phalanx_fatal("HardFault"); }
extern "C" void MemManage_Handler() { phalanx_fatal("MemManage"); }
extern "C" void BusFault_Handler() { phalanx_fatal("BusFault"); }
extern "C" void UsageFault_Handler() { phalanx_fatal("UsageFault"); }
extern "C" void Unexpected_Handler() { phalanx_fatal("unexpected interrupt"); }

namespace {
using Handler = void (*)();
constexpr uint32_t kIrqs = phalanx::mcu::g474::kIrqCount;

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
  t.core[14] = Unexpected_Handler;  // PendSV
  t.core[15] = SysTick_Handler;
  for (uint32_t i = 0; i < kIrqs; ++i) t.irq[i] = Unexpected_Handler;
  t.irq[phalanx::mcu::g474::kIrqExti15_10] = EstopExti_Handler;
  t.irq[phalanx::mcu::g474::kIrqDma1Ch4] = UsartTxDma_Handler;
  return t;
}
}  // namespace

extern "C" __attribute__((section(".isr_vector"), used)) const VectorTable g_vectors = makeTable();
