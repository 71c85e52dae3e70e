#include "links.h"

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

void CmsdkUartLink::onRxInterrupt() {
  uart(base_, kUartIntStatus) = kIntRx;
  if ((uart(base_, kUartState) & kStateRxOverrun) != 0) {
    ++uart_overruns_;
    uart(base_, kUartState) = kStateRxOverrun;
  }
  // Bounded: the UART holds one byte; a byte arriving while this runs raises the interrupt again.
  for (int i = 0; i < 4 && (uart(base_, kUartState) & kStateRxFull) != 0; ++i) {
    rx_.push(static_cast<uint8_t>(uart(base_, kUartData)));
  }
}

void CmsdkUartLink::onTxInterrupt() {
  uart(base_, kUartIntStatus) = kIntTx;
  uint8_t b = 0;
  // At most one ring's worth per entry; stop when the UART reports full and ask to be called when it drains.
  for (size_t i = 0; i < tx_.capacity() && (uart(base_, kUartState) & kStateTxFull) == 0 && tx_.pop(b); ++i) {
    uart(base_, kUartData) = b;
  }
  const uint32_t ctrl = uart(base_, kUartCtrl);
  uart(base_, kUartCtrl) = tx_.empty() ? (ctrl & ~kCtrlTxIntEn) : (ctrl | kCtrlTxIntEn);
}

void DebugConsole::init(uint32_t base) {
  base_ = base;
  uart(base_, kUartBaudDiv) = kSysclkHz / 115200u;
  uart(base_, kUartCtrl) = kCtrlTxEn;
}

void DebugConsole::put(char c) {
  for (int spin = 0; spin < 100000 && (uart(base_, kUartState) & kStateTxFull) != 0; ++spin) {
  }
  uart(base_, kUartData) = static_cast<uint8_t>(c);
}

DebugConsole& DebugConsole::str(const char* s) {
  for (int i = 0; i < 256 && s[i] != 0; ++i) put(s[i]);
  return *this;
}

DebugConsole& DebugConsole::u64(uint64_t v) {
  char buf[21];
  int i = 20;
  buf[i] = 0;
  do {
    buf[--i] = static_cast<char>('0' + v % 10u);
    v /= 10u;
  } while (v != 0 && i > 0);
  return str(buf + i);
}

DebugConsole& DebugConsole::u32(uint32_t v) { return u64(v); }

DebugConsole& DebugConsole::hex16(uint16_t v) {
  constexpr char kDigits[] = "0123456789abcdef";
  char buf[7] = {'0', 'x', kDigits[(v >> 12) & 0xF], kDigits[(v >> 8) & 0xF], kDigits[(v >> 4) & 0xF], kDigits[v & 0xF], 0};
  return str(buf);
}

}  // namespace phalanx::mcu::mps2
