#pragma once
/// What hal/mcu/qemu/board_main.cpp needs from the mps2-an386 board: its link UART (CMSDK UART0, a one-byte
/// receive buffer; links.h), the debug console (UART1), the SysTick clock and the link's interrupts.
#include <cstdint>

#include "cmsdk.h"
#include "links.h"

#define PHALANX_QEMU_LINK_CMSDK 1

namespace phalanx::mcu::board {
using LinkUart = mps2::CmsdkUartLink;
using mps2::DebugConsole;
using mps2::kSysclkHz;
constexpr const char* kBoardName = "mps2-an386";
constexpr const char* kLinkName = "uart0";
constexpr uint32_t kLinkBase = mps2::kUart0Base;
constexpr uint32_t kConsoleBase = mps2::kUart1Base;
/// UART0 RX = IRQ 0, TX = IRQ 1 (QEMU hw/arm/mps2.c); handlers Uart0Rx_Handler / Uart0Tx_Handler (startup.cpp).
constexpr uint32_t kLinkIrqs[] = {mps2::kUart0RxIrq, mps2::kUart0TxIrq};
}  // namespace phalanx::mcu::board
