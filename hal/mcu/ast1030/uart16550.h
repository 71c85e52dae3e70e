#pragma once
/// The 16550-compatible UARTs of the ASPEED AST1030 as QEMU 7.2 models them (hw/char/serial.c behind
/// serial_mm with regshift 2: one register per 32-bit word). Registers and bits from the 16550 data sheet (TI
/// PC16550D): RBR/THR 0, IER 1, IIR/FCR 2, LCR 3, MCR 4, LSR 5, DLL/DLM at 0/1 with LCR.DLAB.
///
/// Why this board: QEMU's receive path offers a UART as many bytes as it says it can take; the CMSDK UART of
/// mps2-an386 (and the STM32F4 USART of netduinoplus2) take one and then wait for the guest to read it, this
/// model fills its receive FIFO up to the trigger level without a guest round trip (measured rates in
/// docs/firmware-mcu.md "The emulated UART's throughput").
///
/// Uart16550Link: the interrupt-driven link (phalanx/mcu/irq_uart_link.h), like the CMSDK link: the interrupt (RX
/// data/timeout, TX holding register empty) moves received bytes from the FIFO into the receive ring and drains
/// the transmit ring into the UART; the tick only pends that interrupt after its frame (kick). The interrupt sits
/// below SysTick, so it never preempts or inflates a control tick.
#include <cstddef>
#include <cstdint>

#include "phalanx/mcu/irq_uart_link.h"
#include "phalanx/mcu/text_console.h"

namespace phalanx::mcu::ast1030 {

constexpr uint32_t kUart1Base = 0x7E783000u;  ///< debug console (QEMU: the second -serial)
constexpr uint32_t kUart2Base = 0x7E78D000u;  ///< the simulated instrument's output (QEMU: the third -serial)
constexpr uint32_t kUart5Base = 0x7E784000u;  ///< protocol link (QEMU: the first -serial, the board's default UART)
constexpr uint32_t kUart5Irq = 8;

// Register offsets (index × 4, regshift 2)
constexpr uint32_t kRbrThr = 0x00;
constexpr uint32_t kIer = 0x04;
constexpr uint32_t kIirFcr = 0x08;
constexpr uint32_t kLcr = 0x0C;
constexpr uint32_t kLsr = 0x14;
constexpr uint32_t kDll = 0x00;  ///< with LCR.DLAB
constexpr uint32_t kDlm = 0x04;  ///< with LCR.DLAB

constexpr uint32_t kIerRxData = 1u << 0;   ///< ERBFI: received data available / character timeout
constexpr uint32_t kIerTxEmpty = 1u << 1;  ///< ETBEI: transmitter holding register empty
constexpr uint32_t kLcr8N1 = 0x03;
constexpr uint32_t kLcrDlab = 0x80;
constexpr uint32_t kFcrEnable = 1u << 0;
constexpr uint32_t kFcrRxReset = 1u << 1;
constexpr uint32_t kFcrTxReset = 1u << 2;
constexpr uint32_t kFcrTrigger14 = 3u << 6;  ///< RX interrupt at 14 of 16 bytes (tail: timeout, or the tick's kick)
constexpr uint32_t kLsrDataReady = 1u << 0;
constexpr uint32_t kLsrOverrun = 1u << 1;
constexpr uint32_t kLsrThrEmpty = 1u << 5;
constexpr size_t kFifoDepth = 16;

class Uart16550Link final : public IrqUartLink {
 public:
  void init(uint32_t base, uint32_t baud);
  /// After the tick: pend the UART interrupt, which sends the new frame and collects a receive-FIFO tail below
  /// the trigger level (so no byte waits for the UART's character timeout longer than one tick).
  void kick();
  void onInterrupt();

 private:
  uint32_t base_ = 0;
};

/// Polled character output on a 16550 (the debug console, UART1).
class Uart16550ConsolePort {
 public:
  void init(uint32_t base);
  void put(char c);

 private:
  uint32_t base_ = 0;
};
using Uart16550Console = TextConsole<Uart16550ConsolePort>;

}  // namespace phalanx::mcu::ast1030
