#include "uart16550.h"

#include "phalanx/mcu/cortex_m.h"

namespace phalanx::mcu::ast1030 {
namespace {
inline volatile uint32_t& reg(uint32_t base, uint32_t offset) {
  return *reinterpret_cast<volatile uint32_t*>(base + offset);
}
}  // namespace

void Uart16550Link::init(uint32_t base, uint32_t /*baud*/) {
  base_ = base;
  // Divisor 1: the fastest rate of the UART clock. QEMU does not pace the bytes by it; it only times the receive
  // character timeout (four character times) with it.
  reg(base_, kLcr) = kLcrDlab | kLcr8N1;
  reg(base_, kDll) = 1;
  reg(base_, kDlm) = 0;
  reg(base_, kLcr) = kLcr8N1;
  reg(base_, kIirFcr) = kFcrEnable | kFcrRxReset | kFcrTxReset | kFcrTrigger14;
  reg(base_, kIer) = kIerRxData;
}

void Uart16550Link::kick() {
  cm4::reg(0xE000E200u + 4u * (kUart5Irq / 32u)) = 1u << (kUart5Irq % 32u);  // NVIC ISPR: pend the interrupt
}

void Uart16550Link::onInterrupt() {
  const uint32_t iir = reg(base_, kIirFcr);  // reading IIR acknowledges a THR-empty interrupt
  static_cast<void>(iir);
  // Receive: at most two FIFOs' worth per entry (bounded), and only while the ring has room. When the ring is full
  // the bytes stay in the UART's FIFO and its receive interrupt is masked until the tick has consumed some (the
  // next kick); QEMU then stops moving bytes from the pty into the full FIFO, so a host burst waits in the pty
  // (the host sees "link full") instead of being dropped here. Without this, a 1 kHz host that caught up after a
  // stall overflowed the 512-byte ring (the tick takes at most 70 bytes per ms): 114 rejected frames in 4 s.
  for (size_t i = 0; i < 2 * kFifoDepth && rx_.space() > 0; ++i) {
    const uint32_t lsr = reg(base_, kLsr);
    if ((lsr & kLsrOverrun) != 0) ++uart_overruns_;
    if ((lsr & kLsrDataReady) == 0) break;
    rx_.push(static_cast<uint8_t>(reg(base_, kRbrThr)));
  }
  // Transmit: fill the TX FIFO while the holding register reports empty; ask for the THR-empty interrupt while
  // the ring still holds bytes.
  uint8_t b = 0;
  for (size_t i = 0; i < tx_.capacity() && (reg(base_, kLsr) & kLsrThrEmpty) != 0 && tx_.pop(b); ++i) {
    reg(base_, kRbrThr) = b;
  }
  reg(base_, kIer) = (rx_.space() > 0 ? kIerRxData : 0u) | (tx_.empty() ? 0u : kIerTxEmpty);
}

void Uart16550ConsolePort::init(uint32_t base) {
  base_ = base;
  reg(base_, kLcr) = kLcr8N1;
  reg(base_, kIirFcr) = kFcrEnable;
}

void Uart16550ConsolePort::put(char c) {
  for (int spin = 0; spin < 100000 && (reg(base_, kLsr) & kLsrThrEmpty) == 0; ++spin) {
  }
  reg(base_, kRbrThr) = static_cast<uint8_t>(c);
}

}  // namespace phalanx::mcu::ast1030
