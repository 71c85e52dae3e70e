#pragma once
/// The messages UsbLink holds back while all of its OUT transfers are in flight (a stalled bus, a slow device).
/// Pure logic, no libusb: tested on its own (tests/unit/usb_out_queue_test.cpp).
/// Commands and telemetry carry the full state, so a newer one supersedes every older one of the same kind still
/// waiting here (it is removed and the new one goes to the back, as CanLink does with its frame queue): a stall
/// never refuses the newest command and never sends a stale one after it. Other messages (Hello, ParamSet,
/// ClearFaults, ...) are kept in order and never superseded; only when the queue holds kCapacity of them is a
/// message refused. A body that the kernel already has (a submitted transfer) cannot be withdrawn: that is why
/// UsbLink keeps few transfers in flight (docs/usb.md).
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "phalanx/protocol/codec.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::linux_hal {

class UsbOutQueue {
 public:
  static constexpr size_t kCapacity = 8;  ///< see docs/usb.md
  struct Body {
    uint8_t msg_id = 0;
    uint8_t len = 0;  ///< bytes of data: id | payload | crc16
    uint8_t data[protocol::kMaxFrameBody] = {};
  };
  enum class Push : uint8_t {
    kQueued = 0,      ///< appended
    kSuperseded = 1,  ///< appended after removing older messages of the same kind (superseded() counts them)
    kFull = 2,        ///< refused: kCapacity messages that cannot be superseded are waiting
    kTooLong = 3,     ///< refused: longer than a protocol body
  };

  static bool supersedes(uint8_t msg_id) {
    return msg_id == static_cast<uint8_t>(protocol::MsgId::kCommand) ||
           msg_id == static_cast<uint8_t>(protocol::MsgId::kTelemetry);
  }

  Push push(uint8_t msg_id, const uint8_t* body, size_t len) {
    if (len > protocol::kMaxFrameBody) return Push::kTooLong;
    size_t removed = 0;
    if (supersedes(msg_id)) {
      size_t w = 0;
      for (size_t r = 0; r < len_; ++r) {
        if (at(r).msg_id == msg_id) {
          ++removed;
          continue;
        }
        if (w != r) at(w) = at(r);
        ++w;
      }
      len_ = w;
    }
    if (len_ == kCapacity) return Push::kFull;
    Body& b = at(len_);
    b.msg_id = msg_id;
    b.len = static_cast<uint8_t>(len);
    std::memcpy(b.data, body, len);
    ++len_;
    superseded_ += removed;
    return removed > 0 ? Push::kSuperseded : Push::kQueued;
  }

  bool empty() const { return len_ == 0; }
  size_t size() const { return len_; }
  const Body& front() const { return at(0); }
  void pop() {
    if (len_ == 0) return;
    head_ = (head_ + 1) % kCapacity;
    --len_;
  }
  /// Forget everything waiting (the device is gone: nothing from before an unplug may go out afterwards).
  /// Returns how many messages were discarded.
  size_t clear() {
    const size_t n = len_;
    len_ = 0;
    head_ = 0;
    return n;
  }
  /// Messages removed because a newer one of the same kind replaced them (since construction).
  uint64_t superseded() const { return superseded_; }

 private:
  Body& at(size_t i) { return q_[(head_ + i) % kCapacity]; }
  const Body& at(size_t i) const { return q_[(head_ + i) % kCapacity]; }

  Body q_[kCapacity] = {};
  size_t head_ = 0;
  size_t len_ = 0;
  uint64_t superseded_ = 0;
};

}  // namespace phalanx::linux_hal
