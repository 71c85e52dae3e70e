#pragma once
/// One received message-per-packet body (USB bulk, FunctionFS): `id | payload | crc16` checked by the protocol's
/// body check; a bad one is counted in the link's receive statistics and dropped.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "phalanx/hal/hal.h"
#include "phalanx/protocol/codec.h"

namespace phalanx::linux_hal {

/// True with the message in (msg_id, payload, len) when the body is valid; false after counting why it is not.
inline bool acceptBody(const uint8_t* body, size_t body_len, hal::PacketRxStats& stats, uint8_t& msg_id,
                       uint8_t* payload, size_t& len) {
  protocol::Frame f;
  switch (protocol::checkBody(body, body_len, f)) {
    case protocol::BodyStatus::kOk:
      msg_id = f.id;
      len = f.len;
      std::memcpy(payload, f.payload, f.len);
      return true;
    case protocol::BodyStatus::kCrc: ++stats.crc; break;
    case protocol::BodyStatus::kUnknownId: ++stats.bad_id; break;
    case protocol::BodyStatus::kTooShort:
    case protocol::BodyStatus::kBadLength: ++stats.bad_length; break;
  }
  return false;
}

}  // namespace phalanx::linux_hal
