#pragma once
/// The CMSDK APB UARTs of the mps2-an386 board: the protocol link (UART0) and the debug console port (UART1).
///
/// CmsdkUartLink: the interrupt-driven link (phalanx/mcu/irq_uart_link.h) over UART0: its RX interrupt moves each
/// received byte into the receive ring; its TX interrupt, pended by the tick after its frame (kick), drains the
/// transmit ring into the UART. Both interrupts sit below SysTick in priority and run the same handler
/// (onInterrupt), so they never preempt (or inflate the measurement of) a control tick.
///
/// QEMU's model of this UART has a one-byte receive buffer and takes one byte per iteration of QEMU's main loop:
/// measured here at 20–28 kB/s host → device when idle and about 12 kB/s while the device sends 1 kHz telemetry
/// (70 kB/s) the other way; docs/firmware-mcu.md has the numbers and what they mean for the host loop rate.
#include <cstdint>

#include "cmsdk.h"
#include "phalanx/mcu/irq_uart_link.h"
#include "phalanx/mcu/text_console.h"

namespace phalanx::mcu::mps2 {

class CmsdkUartLink final : public IrqUartLink {
 public:
  void init(uint32_t base, uint32_t baud);
  /// After the tick: let the TX interrupt start draining.
  void kick();
  /// The RX and the TX interrupt of the UART: takes the received byte, then refills the transmitter.
  void onInterrupt();

 private:
  uint32_t base_ = 0;
};

/// Polled character output on a CMSDK UART (the debug console, UART1).
class CmsdkConsolePort {
 public:
  void init(uint32_t base);
  void put(char c);

 private:
  uint32_t base_ = 0;
};
using DebugConsole = TextConsole<CmsdkConsolePort>;

}  // namespace phalanx::mcu::mps2
