#include "cmsdk_uart.h"

#include "phalanx/mcu/cortex_m.h"

namespace phalanx::mcu::mps2 {

void CmsdkUartLink::init(uint32_t base, uint32_t baud) {
  base_ = base;
  uart(base_, kUartBaudDiv) = kSysclkHz / baud;
  uart(base_, kUartCtrl) = kCtrlTxEn | kCtrlRxEn | kCtrlRxIntEn;
}

void CmsdkUartLink::kick() {
  // NVIC ISPR: pend the TX interrupt; it runs as soon as the tick handler returns.
  cm4::reg(0xE000E200u) = 1u << kUart0TxIrq;
}

void CmsdkUartLink::onInterrupt() {
  // Receive. Bounded: the UART holds one byte; a byte arriving while this runs raises the interrupt again.
  if ((uart(base_, kUartIntStatus) & kIntRx) != 0) uart(base_, kUartIntStatus) = kIntRx;
  if ((uart(base_, kUartState) & kStateRxOverrun) != 0) {
    ++uart_overruns_;
    uart(base_, kUartState) = kStateRxOverrun;
  }
  for (int i = 0; i < 4 && (uart(base_, kUartState) & kStateRxFull) != 0; ++i) {
    rx_.push(static_cast<uint8_t>(uart(base_, kUartData)));
  }
  // Transmit: at most one ring's worth per entry; stop when the UART reports full and ask to be called when it
  // drains.
  uart(base_, kUartIntStatus) = kIntTx;
  uint8_t b = 0;
  for (size_t i = 0; i < tx_.capacity() && (uart(base_, kUartState) & kStateTxFull) == 0 && tx_.pop(b); ++i) {
    uart(base_, kUartData) = b;
  }
  const uint32_t ctrl = uart(base_, kUartCtrl);
  uart(base_, kUartCtrl) = tx_.empty() ? (ctrl & ~kCtrlTxIntEn) : (ctrl | kCtrlTxIntEn);
}

void CmsdkConsolePort::init(uint32_t base) {
  base_ = base;
  uart(base_, kUartBaudDiv) = kSysclkHz / 115200u;
  uart(base_, kUartCtrl) = kCtrlTxEn;
}

void CmsdkConsolePort::put(char c) {
  for (int spin = 0; spin < 100000 && (uart(base_, kUartState) & kStateTxFull) != 0; ++spin) {
  }
  uart(base_, kUartData) = static_cast<uint8_t>(c);
}

}  // namespace phalanx::mcu::mps2
