#pragma once
/// What firmware/boards/qemu (board_main.cpp, startup.cpp) needs from the ast1030-evb board (QEMU 7.2
/// hw/arm/aspeed_ast10x0.c: an ASPEED AST1030 with a Cortex-M4F): its link UART (UART5, the board's first
/// `-serial`, a 16550 with 16-byte FIFOs; hal/mcu/ast1030/uart16550.h), the debug console (UART1, the second
/// `-serial`), the SysTick clock and the link's interrupt.
#include <cstdint>

#include "uart16550.h"

namespace phalanx::mcu::board {
using LinkUart = ast1030::Uart16550Link;
using DebugConsole = ast1030::Uart16550Console;
/// The Cortex-M4's clock as QEMU wires it for this SoC (SYSCLK 200 MHz, SysTick CLKSOURCE = 1); checked on
/// QEMU 7.2 with a 3 s run: 1.00 firmware ms per wall ms (docs/firmware-mcu.md).
constexpr uint32_t kSysclkHz = 200000000u;
constexpr const char* kBoardName = "ast1030-evb";
constexpr const char* kLinkName = "uart5";
constexpr uint32_t kLinkBase = ast1030::kUart5Base;
constexpr uint32_t kConsoleBase = ast1030::kUart1Base;
constexpr uint32_t kInstrumentBase = ast1030::kUart2Base;  ///< option instrument=1: the plant's truth, one line per step
/// UART5 = IRQ 8 (QEMU aspeed_soc_ast1030_irqmap); handler LinkUart_Handler (startup.cpp).
constexpr uint32_t kLinkIrqs[] = {ast1030::kUart5Irq};
}  // namespace phalanx::mcu::board
