#pragma once
/// The part the interrupt-driven UART links of the emulated boards share (mps2-an386's CMSDK UART, ast1030-evb's
/// 16550): a hal::ByteLink whose receive ring the UART interrupt fills and the control tick reads, and whose
/// transmit ring the tick fills and the interrupt drains, so each ring has one producer and one consumer. A UART
/// driver derives from it and adds init(), kick() (after the tick: pend the interrupt) and onInterrupt().
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/hal.h"
#include "phalanx/mcu/ring_buffer.h"

namespace phalanx::mcu {

class IrqUartLink : public hal::ByteLink {
 public:
  size_t read(uint8_t* dst, size_t max_len) override {
    const size_t n = rx_.read(dst, max_len);
    bytes_read_ += static_cast<uint32_t>(n);
    return n;
  }
  /// All of a frame or nothing: a frame is never split across ticks by a full ring.
  size_t write(const uint8_t* src, size_t len) override { return tx_.space() >= len ? tx_.write(src, len) : 0; }
  size_t writeSpace() const override { return tx_.space(); }
  /// Bytes handed to the core so far (for the per-tick receive-work breakdown).
  uint32_t bytesRead() const { return bytes_read_; }
  /// Bytes lost on receive: the ring was full, or the UART itself overran.
  uint32_t rxOverflows() const { return rx_.overflows() + uart_overruns_; }

 protected:
  ByteRing<512> rx_;
  ByteRing<1024> tx_;
  uint32_t uart_overruns_ = 0;

 private:
  uint32_t bytes_read_ = 0;
};

}  // namespace phalanx::mcu
