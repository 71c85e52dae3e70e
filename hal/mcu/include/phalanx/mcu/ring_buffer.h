#pragma once
/// Single-producer / single-consumer byte ring for a link driver: one side is an interrupt handler (UART RX ISR,
/// DMA bookkeeping) and the other the control tick, or the other way round for TX. Lock-free on a single core:
/// the producer only writes head_, the consumer only writes tail_, and each index is published after the data
/// it covers (release/acquire fences compile to DMB on Cortex-M and to nothing on x86). Capacity is a power of
/// two; head_/tail_ run freely and wrap modulo 2^32, so "full" and "empty" never alias.
/// Freestanding: no heap, no exceptions; compiles on the host for the unit tests.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace phalanx::mcu {

template <size_t kCapacity>
class ByteRing {
  static_assert(kCapacity >= 2 && (kCapacity & (kCapacity - 1)) == 0, "capacity must be a power of two");
  static_assert(kCapacity <= 0x80000000u, "indices are 32-bit");

 public:
  static constexpr size_t capacity() { return kCapacity; }

  size_t size() const { return static_cast<uint32_t>(head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire)); }
  size_t space() const { return kCapacity - size(); }
  bool empty() const { return size() == 0; }

  /// Producer: append one byte; false (byte dropped, counted) when full.
  bool push(uint8_t byte) {
    const uint32_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= kCapacity) {
      ++overflows_;
      return false;
    }
    buf_[head & kMask] = byte;
    head_.store(head + 1u, std::memory_order_release);
    return true;
  }

  /// Producer: append up to len bytes; returns how many fitted (the rest is not counted as overflow).
  size_t write(const uint8_t* src, size_t len) {
    const uint32_t head = head_.load(std::memory_order_relaxed);
    const size_t free = kCapacity - static_cast<uint32_t>(head - tail_.load(std::memory_order_acquire));
    const size_t n = len < free ? len : free;
    // At most two contiguous pieces (up to the end of the storage, then from its start): two memcpy, not a loop.
    const size_t at = head & kMask;
    const size_t first = n < kCapacity - at ? n : kCapacity - at;
    std::memcpy(buf_ + at, src, first);
    std::memcpy(buf_, src + first, n - first);
    head_.store(head + static_cast<uint32_t>(n), std::memory_order_release);
    return n;
  }

  /// Consumer: take one byte; false when empty.
  bool pop(uint8_t& byte) {
    const uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (head_.load(std::memory_order_acquire) == tail) return false;
    byte = buf_[tail & kMask];
    tail_.store(tail + 1u, std::memory_order_release);
    return true;
  }

  /// Consumer: take up to max_len bytes.
  size_t read(uint8_t* dst, size_t max_len) {
    const uint32_t tail = tail_.load(std::memory_order_relaxed);
    const size_t avail = static_cast<uint32_t>(head_.load(std::memory_order_acquire) - tail);
    const size_t n = max_len < avail ? max_len : avail;
    const size_t at = tail & kMask;
    const size_t first = n < kCapacity - at ? n : kCapacity - at;
    std::memcpy(dst, buf_ + at, first);
    std::memcpy(dst + first, buf_, n - first);
    tail_.store(tail + static_cast<uint32_t>(n), std::memory_order_release);
    return n;
  }

  /// Bytes refused by push() because the ring was full (a receive overrun).
  uint32_t overflows() const { return overflows_; }

 private:
  static constexpr uint32_t kMask = static_cast<uint32_t>(kCapacity - 1);
  uint8_t buf_[kCapacity] = {};
  std::atomic<uint32_t> head_{0};
  std::atomic<uint32_t> tail_{0};
  uint32_t overflows_ = 0;
};

}  // namespace phalanx::mcu
