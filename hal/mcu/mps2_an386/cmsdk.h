#pragma once
/// CMSDK APB peripherals of the MPS2 AN386 image as QEMU 7.2 models them (ARM DDI0479C Cortex-M System Design
/// Kit TRM §4.5 APB UART; AN386 memory map; QEMU hw/arm/mps2.c for the IRQ wiring). Only what the board uses.
#include <cstdint>

namespace phalanx::mcu::mps2 {

constexpr uint32_t kSysclkHz = 25000000u;  ///< SYSCLK = PCLK; SysTick counts it (40 ns per count)

constexpr uint32_t kUart0Base = 0x40004000u;  ///< protocol link (QEMU -serial #0)
constexpr uint32_t kUart1Base = 0x40005000u;  ///< debug console (QEMU -serial #1)
constexpr uint32_t kUart2Base = 0x40006000u;  ///< the simulated instrument's output (QEMU -serial #2)
constexpr uint32_t kUart0RxIrq = 0;
constexpr uint32_t kUart0TxIrq = 1;

// APB UART registers (DDI0479C Table 4-9)
constexpr uint32_t kUartData = 0x00;
constexpr uint32_t kUartState = 0x04;      ///< TXFULL [0], RXFULL [1], TXOVR [2], RXOVR [3] (W1C)
constexpr uint32_t kUartCtrl = 0x08;       ///< TXEN [0], RXEN [1], TXINTEN [2], RXINTEN [3], TXOVRINTEN [4], RXOVRINTEN [5]
constexpr uint32_t kUartIntStatus = 0x0C;  ///< TX [0], RX [1], TXOVR [2], RXOVR [3]; write 1 to clear
constexpr uint32_t kUartBaudDiv = 0x10;    ///< ≥ 16; baud = PCLK / BAUDDIV

constexpr uint32_t kStateTxFull = 1u << 0;
constexpr uint32_t kStateRxFull = 1u << 1;
constexpr uint32_t kStateRxOverrun = 1u << 3;
constexpr uint32_t kCtrlTxEn = 1u << 0;
constexpr uint32_t kCtrlRxEn = 1u << 1;
constexpr uint32_t kCtrlTxIntEn = 1u << 2;
constexpr uint32_t kCtrlRxIntEn = 1u << 3;
constexpr uint32_t kIntTx = 1u << 0;
constexpr uint32_t kIntRx = 1u << 1;

inline volatile uint32_t& uart(uint32_t base, uint32_t offset) {
  return *reinterpret_cast<volatile uint32_t*>(base + offset);
}

}  // namespace phalanx::mcu::mps2
