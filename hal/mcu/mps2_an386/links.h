#pragma once
/// Byte links and the debug console of the emulated board.
///
/// CmsdkUartLink: hal::ByteLink over CMSDK APB UART0, interrupt driven: the RX interrupt moves each received byte
/// into a ring the control tick reads; the tick's frames go into a TX ring that the TX interrupt drains into the
/// UART (the tick only pends that interrupt, so the ring has one consumer). Both UART interrupts sit below
/// SysTick in priority, so they never preempt (or inflate the measurement of) a control tick.
///
/// SemihostLink: the same interface over QEMU's semihosting console (SYS_READC / SYS_WRITEC on a chardev).
/// It exists because QEMU's CMSDK UART model accepts one byte per host main-loop iteration (measured on this
/// project's machines: 20–28 kB/s), below the 61 kB/s of a 1 kHz command stream; QEMU's semihosting console
/// buffers 1 KiB per iteration and keeps up. See docs/firmware-mcu.md.
#include <cstddef>
#include <cstdint>

#include "cmsdk.h"
#include "phalanx/hal/hal.h"
#include "phalanx/mcu/ring_buffer.h"

namespace phalanx::mcu::mps2 {

class CmsdkUartLink final : public hal::ByteLink {
 public:
  void init(uint32_t base, uint32_t baud);
  size_t read(uint8_t* dst, size_t max_len) override { return rx_.read(dst, max_len); }
  size_t write(const uint8_t* src, size_t len) override { return tx_.space() >= len ? tx_.write(src, len) : 0; }
  size_t writeSpace() const override { return tx_.space(); }
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
};

class SemihostLink final : public hal::ByteLink {
 public:
  size_t read(uint8_t* dst, size_t max_len) override { return rx_.read(dst, max_len); }
  size_t write(const uint8_t* src, size_t len) override { return writeSpace() >= len ? tx_.write(src, len) : 0; }
  /// Zero while the host has been silent for kHostSilentMs: QEMU writes the console with a blocking write, so
  /// the link stops sending when nobody is reading rather than stall the emulated CPU on a full pty.
  size_t writeSpace() const override;
  /// Thread mode only: block (the CPU halts like WFI; interrupts still run) until one byte arrives.
  void receiveBlocking();
  /// From the tick interrupt only: write out what the tick queued.
  void flush();
  uint32_t rxOverflows() const { return rx_.overflows(); }
  uint32_t rxBytes() const { return rx_bytes_; }

  static constexpr uint32_t kHostSilentMs = 100;

 private:
  ByteRing<1024> rx_;
  ByteRing<1024> tx_;
  volatile uint32_t last_rx_ms_ = 0;
  volatile bool heard_ = false;
  volatile uint32_t rx_bytes_ = 0;
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

/// Milliseconds since the tick started (written by the SysTick handler).
uint32_t millis();

}  // namespace phalanx::mcu::mps2
