#pragma once
/// Bounded single-producer / single-consumer queue: the 1 kHz loop pushes, one other thread pops. Lock-free and
/// wait-free on both sides; push() never blocks and never allocates (the storage is allocated once, up front) —
/// when the queue is full the item is refused and the producer counts the drop.
#include <atomic>
#include <cstddef>
#include <memory>

namespace phalanx::host::record {

template <class T>
class SpscQueue {
 public:
  /// capacity is rounded up to a power of two.
  explicit SpscQueue(std::size_t capacity) {
    std::size_t c = 1;
    while (c < capacity) c <<= 1;
    mask_ = c - 1;
    slots_ = std::make_unique<T[]>(c);
  }
  std::size_t capacity() const { return mask_ + 1; }

  /// Producer only. false: full, nothing changed.
  bool push(const T& item) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) > mask_) return false;
    slots_[head & mask_] = item;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  /// Consumer only. false: empty.
  bool pop(T& out) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    out = slots_[tail & mask_];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

 private:
  std::unique_ptr<T[]> slots_;
  std::size_t mask_ = 0;
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
};

}  // namespace phalanx::host::record
