#pragma once
/// Byte links and the debug console of the emulated board.
///
/// CmsdkUartLink: hal::ByteLink over CMSDK APB UART0, interrupt driven: the RX interrupt moves each received byte
/// into a ring the control tick reads; the tick's frames go into a TX ring that the TX interrupt drains into the
/// UART (the tick only pends that interrupt, so the ring has one consumer). Both UART interrupts sit below
/// SysTick in priority, so they never preempt (or inflate the measurement of) a control tick.
///
/// QEMU's model of this UART has a one-byte receive buffer and takes one byte per iteration of QEMU's main loop:
/// measured here at 20–28 kB/s host → device when idle and about 12 kB/s while the device sends 1 kHz telemetry
/// (70 kB/s) the other way; docs/firmware-mcu.md has the numbers and what they mean for the host loop rate.
#include <cstddef>
#include <cstdint>

#include "cmsdk.h"
#include "phalanx/hal/hal.h"
#include "phalanx/mcu/ring_buffer.h"

namespace phalanx::mcu::mps2 {

class CmsdkUartLink final : public hal::ByteLink {
 public:
  void init(uint32_t base, uint32_t baud);
  size_t read(uint8_t* dst, size_t max_len) override {
    const size_t n = rx_.read(dst, max_len);
    bytes_read_ += static_cast<uint32_t>(n);
    return n;
  }
  size_t write(const uint8_t* src, size_t len) override { return tx_.space() >= len ? tx_.write(src, len) : 0; }
  size_t writeSpace() const override { return tx_.space(); }
  /// Bytes handed to the core so far (for the per-tick receive-work breakdown).
  uint32_t bytesRead() const { return bytes_read_; }
  /// After the tick: let the TX interrupt start draining.
  void kick();
  void onRxInterrupt();
  void onTxInterrupt();
  uint32_t rxOverflows() const { return rx_.overflows() + uart_overruns_; }

 private:
  uint32_t base_ = 0;
  ByteRing<512> rx_;
  ByteRing<1024> tx_;
  uint32_t uart_overruns_ = 0;
  uint32_t bytes_read_ = 0;
};

/// Polled output on UART1 for boot, safe-state and statistics lines (never on the protocol link).
class DebugConsole {
 public:
  void init(uint32_t base);
  DebugConsole& str(const char* s);
  DebugConsole& u32(uint32_t v);
  DebugConsole& u64(uint64_t v);
  DebugConsole& hex16(uint16_t v);
  DebugConsole& end() { return str("\n"); }

 private:
  void put(char c);
  uint32_t base_ = 0;
};

}  // namespace phalanx::mcu::mps2
