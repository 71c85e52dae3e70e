// Vector table, reset and fault entry of the emulated mps2-an386 image (ARMv7-M B1.5.3 vector table; AN386
// interrupt map as wired by QEMU hw/arm/mps2.c: UART0 RX = IRQ 0, UART0 TX = IRQ 1).
#include <cstdint>

#include "phalanx/mcu/cortex_m.h"

extern "C" [[noreturn]] void phalanx_fatal(const char* why);
extern "C" void SysTick_Handler();
extern "C" void PendSV_Handler();
extern "C" void Uart0Rx_Handler();
extern "C" void Uart0Tx_Handler();
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

using Handler = void (*)();
extern "C" __attribute__((section(".isr_vector"), used)) const Handler g_vectors[16 + 32] = {
    phalanx_initial_sp, Reset_Handler,      NMI_Handler,        HardFault_Handler,  MemManage_Handler,
    BusFault_Handler,   UsageFault_Handler, nullptr,            nullptr,            nullptr,
    nullptr,            Unexpected_Handler, Unexpected_Handler, nullptr,            PendSV_Handler,
    SysTick_Handler,
    // IRQ 0..31
    Uart0Rx_Handler,    Uart0Tx_Handler,    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler, Unexpected_Handler,
    Unexpected_Handler, Unexpected_Handler,
};
