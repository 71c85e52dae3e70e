#pragma once
/// What firmware/boards/qemu (board_main.cpp, startup.cpp) needs from the mps2-an386 board: its link UART (CMSDK
/// UART0, a one-byte receive buffer; hal/mcu/mps2_an386/cmsdk_uart.h), the debug console (UART1), the SysTick
/// clock and the link's interrupts.
#include <cstdint>

#include "cmsdk.h"
#include "cmsdk_uart.h"

namespace phalanx::mcu::board {
using LinkUart = mps2::CmsdkUartLink;
using mps2::DebugConsole;
using mps2::kSysclkHz;
constexpr const char* kBoardName = "mps2-an386";
constexpr const char* kLinkName = "uart0";
constexpr uint32_t kLinkBase = mps2::kUart0Base;
constexpr uint32_t kConsoleBase = mps2::kUart1Base;
constexpr uint32_t kInstrumentBase = mps2::kUart2Base;  ///< option instrument=1: the plant's truth, one line per step
/// UART0 RX = IRQ 0, TX = IRQ 1 (QEMU hw/arm/mps2.c); both enter LinkUart_Handler (startup.cpp).
constexpr uint32_t kLinkIrqs[] = {mps2::kUart0RxIrq, mps2::kUart0TxIrq};
}  // namespace phalanx::mcu::board
