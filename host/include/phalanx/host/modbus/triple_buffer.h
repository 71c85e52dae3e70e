#pragma once
/// Wait-free single-producer / single-consumer "latest value" hand-over (triple buffering). The producer never
/// waits for the consumer and vice versa: the 1 kHz loop publishes with one copy and one atomic exchange, and a
/// slow reader can never make it block. Race-free by construction (each slot is owned by exactly one side at a
/// time), so ThreadSanitizer has nothing to forgive.
#include <atomic>
#include <cstdint>

namespace phalanx::host::modbus {

template <class T>
class TripleBuffer {
 public:
  /// Producer: copy value in and make it the newest.
  void publish(const T& value) {
    slot_[back_] = value;
    const uint8_t prev = middle_.exchange(static_cast<uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = prev & kIndex;
  }
  /// Consumer: the newest value published so far (false if nothing was ever published). `fresh` tells whether
  /// it is newer than the previous read.
  bool read(T& out, bool* fresh = nullptr) {
    const bool is_fresh = (middle_.load(std::memory_order_relaxed) & kFresh) != 0;
    if (is_fresh) {
      const uint8_t prev = middle_.exchange(front_, std::memory_order_acq_rel);
      front_ = prev & kIndex;
      have_ = true;
    }
    if (fresh != nullptr) *fresh = is_fresh;
    if (!have_) return false;
    out = slot_[front_];
    return true;
  }

 private:
  static constexpr uint8_t kFresh = 0x4;
  static constexpr uint8_t kIndex = 0x3;
  T slot_[3]{};
  uint8_t back_ = 0;                      // producer-owned
  std::atomic<uint8_t> middle_{1};        // shared: index | kFresh
  uint8_t front_ = 2;                     // consumer-owned
  bool have_ = false;                     // consumer-owned
};

}  // namespace phalanx::host::modbus
