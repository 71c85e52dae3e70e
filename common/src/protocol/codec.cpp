#include "phalanx/protocol/codec.h"

#include <cstring>

namespace phalanx::protocol {
namespace {

// Table-driven CRC-16/CCITT-FALSE, generated at compile time (one 512-byte table in flash on the MCU).
struct Crc16Table {
  uint16_t v[256];
  constexpr Crc16Table() : v{} {
    for (int i = 0; i < 256; ++i) {
      uint16_t c = static_cast<uint16_t>(i << 8);
      for (int b = 0; b < 8; ++b) c = static_cast<uint16_t>((c & 0x8000u) ? ((c << 1) ^ 0x1021u) : (c << 1));
      v[i] = c;
    }
  }
};
constexpr Crc16Table kCrcTable{};

class Writer {
 public:
  explicit Writer(uint8_t* p) : p_(p) {}
  void u8(uint8_t v) { *p_++ = v; }
  void u16(uint16_t v) { u8(static_cast<uint8_t>(v)); u8(static_cast<uint8_t>(v >> 8)); }
  void u32(uint32_t v) { u16(static_cast<uint16_t>(v)); u16(static_cast<uint16_t>(v >> 16)); }
  void i16(int16_t v) { u16(static_cast<uint16_t>(v)); }
  void f32(float v) {
    uint32_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    u32(bits);
  }

 private:
  uint8_t* p_;
};

class Reader {
 public:
  explicit Reader(const uint8_t* p) : p_(p) {}
  uint8_t u8() { return *p_++; }
  uint16_t u16() {
    const uint16_t lo = u8();
    return static_cast<uint16_t>(lo | (u8() << 8));
  }
  uint32_t u32() {
    const uint32_t lo = u16();
    return lo | (static_cast<uint32_t>(u16()) << 16);
  }
  int16_t i16() { return static_cast<int16_t>(u16()); }
  float f32() {
    const uint32_t bits = u32();
    float v;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }

 private:
  const uint8_t* p_;
};

bool validDevice(uint8_t v) { return v <= static_cast<uint8_t>(DeviceType::kPantograph); }
bool validMode(uint8_t v) { return v < kModeCount; }

}  // namespace

uint16_t crc16(const uint8_t* data, size_t len, uint16_t crc) {
  for (size_t i = 0; i < len; ++i) {
    crc = static_cast<uint16_t>((crc << 8) ^ kCrcTable.v[((crc >> 8) ^ data[i]) & 0xFFu]);
  }
  return crc;
}

size_t cobsEncode(const uint8_t* src, size_t len, uint8_t* dst) {
  size_t code_pos = 0;
  size_t out = 1;
  uint8_t code = 1;
  for (size_t i = 0; i < len; ++i) {
    if (src[i] == 0) {
      dst[code_pos] = code;
      code_pos = out++;
      code = 1;
    } else {
      dst[out++] = src[i];
      if (++code == 0xFF) {
        dst[code_pos] = code;
        code_pos = out++;
        code = 1;
      }
    }
  }
  dst[code_pos] = code;
  return out;
}

size_t cobsDecode(const uint8_t* src, size_t len, uint8_t* dst, size_t dst_cap) {
  size_t in = 0;
  size_t out = 0;
  while (in < len) {
    const uint8_t code = src[in++];
    if (code == 0) return 0;
    for (uint8_t k = 1; k < code; ++k) {
      if (in >= len || src[in] == 0 || out >= dst_cap) return 0;
      dst[out++] = src[in++];
    }
    if (code != 0xFF && in < len) {
      if (out >= dst_cap) return 0;
      dst[out++] = 0;
    }
  }
  return out;
}

void encodePayload(const Hello& m, uint8_t* out) {
  Writer w(out);
  w.u16(m.protocol_version);
  w.u8(static_cast<uint8_t>(m.expected_device));
  w.u8(m.reserved);
  w.u32(m.session_id);
}
bool decodePayload(const uint8_t* in, size_t len, Hello& m) {
  if (len != Hello::kWireSize) return false;
  Reader r(in);
  m.protocol_version = r.u16();
  const uint8_t dev = r.u8();
  if (!validDevice(dev)) return false;
  m.expected_device = static_cast<DeviceType>(dev);
  m.reserved = r.u8();
  m.session_id = r.u32();
  return true;
}

void encodePayload(const HelloAck& m, uint8_t* out) {
  Writer w(out);
  w.u16(m.protocol_version);
  w.u8(static_cast<uint8_t>(m.device_type));
  w.u8(static_cast<uint8_t>(m.status));
  w.u32(m.session_id);
  w.u32(m.firmware_build_id);
  w.u16(m.tick_rate_hz);
  w.u8(m.setpoint_count);
  w.u8(m.sample_count);
}
bool decodePayload(const uint8_t* in, size_t len, HelloAck& m) {
  if (len != HelloAck::kWireSize) return false;
  Reader r(in);
  m.protocol_version = r.u16();
  const uint8_t dev = r.u8();
  const uint8_t status = r.u8();
  if (!validDevice(dev) || status > static_cast<uint8_t>(HandshakeStatus::kDeviceMismatch)) return false;
  m.device_type = static_cast<DeviceType>(dev);
  m.status = static_cast<HandshakeStatus>(status);
  m.session_id = r.u32();
  m.firmware_build_id = r.u32();
  m.tick_rate_hz = r.u16();
  m.setpoint_count = r.u8();
  m.sample_count = r.u8();
  return true;
}

void encodePayload(const Command& m, uint8_t* out) {
  Writer w(out);
  w.u16(m.seq);
  w.u16(m.timeout_ms);
  w.u8(static_cast<uint8_t>(m.mode));
  w.u8(m.flags);
  w.u8(m.channel_count);
  w.u8(m.reserved);
  for (float s : m.setpoint) w.f32(s);
  for (uint16_t g : m.gain_scale_permille) w.u16(g);
}
bool decodePayload(const uint8_t* in, size_t len, Command& m) {
  if (len != Command::kWireSize) return false;
  Reader r(in);
  m.seq = r.u16();
  m.timeout_ms = r.u16();
  const uint8_t mode = r.u8();
  if (!validMode(mode)) return false;
  m.mode = static_cast<Mode>(mode);
  m.flags = r.u8();
  m.channel_count = r.u8();
  m.reserved = r.u8();
  for (float& s : m.setpoint) s = r.f32();
  for (uint16_t& g : m.gain_scale_permille) g = r.u16();
  return true;
}

void encodePayload(const Telemetry& m, uint8_t* out) {
  Writer w(out);
  w.u32(m.time_us);
  w.u16(m.seq);
  w.u16(m.cmd_seq_echo);
  w.u8(static_cast<uint8_t>(m.mode));
  w.u8(m.state_flags);
  w.u16(m.fault_bits);
  w.u8(m.cmd_lost);
  w.u8(m.rx_errors);
  for (int16_t s : m.sample) w.i16(s);
}
bool decodePayload(const uint8_t* in, size_t len, Telemetry& m) {
  if (len != Telemetry::kWireSize) return false;
  Reader r(in);
  m.time_us = r.u32();
  m.seq = r.u16();
  m.cmd_seq_echo = r.u16();
  const uint8_t mode = r.u8();
  if (!validMode(mode)) return false;
  m.mode = static_cast<Mode>(mode);
  m.state_flags = r.u8();
  m.fault_bits = r.u16();
  m.cmd_lost = r.u8();
  m.rx_errors = r.u8();
  for (int16_t& s : m.sample) s = r.i16();
  return true;
}

void encodePayload(const Event& m, uint8_t* out) {
  Writer w(out);
  w.u32(m.time_us);
  w.u16(static_cast<uint16_t>(m.code));
  w.u8(m.channel);
  w.u8(m.detail);
  w.f32(m.value);
}
bool decodePayload(const uint8_t* in, size_t len, Event& m) {
  if (len != Event::kWireSize) return false;
  Reader r(in);
  m.time_us = r.u32();
  const uint16_t code = r.u16();
  if (code < 1 || code > static_cast<uint16_t>(EventCode::kSessionOpened)) return false;
  m.code = static_cast<EventCode>(code);
  m.channel = r.u8();
  m.detail = r.u8();
  m.value = r.f32();
  return true;
}

void encodePayload(const ClearFaults& m, uint8_t* out) { Writer(out).u32(m.session_id); }
bool decodePayload(const uint8_t* in, size_t len, ClearFaults& m) {
  if (len != ClearFaults::kWireSize) return false;
  m.session_id = Reader(in).u32();
  return true;
}

void encodePayload(const ParamGet& m, uint8_t* out) { Writer(out).u16(m.param_id); }
bool decodePayload(const uint8_t* in, size_t len, ParamGet& m) {
  if (len != ParamGet::kWireSize) return false;
  m.param_id = Reader(in).u16();
  return true;
}

void encodePayload(const ParamSet& m, uint8_t* out) {
  Writer w(out);
  w.u16(m.param_id);
  w.u16(m.reserved);
  w.f32(m.value);
}
bool decodePayload(const uint8_t* in, size_t len, ParamSet& m) {
  if (len != ParamSet::kWireSize) return false;
  Reader r(in);
  m.param_id = r.u16();
  m.reserved = r.u16();
  m.value = r.f32();
  return true;
}

void encodePayload(const ParamValue& m, uint8_t* out) {
  Writer w(out);
  w.u16(m.param_id);
  w.u8(static_cast<uint8_t>(m.status));
  w.u8(m.reserved);
  w.f32(m.value);
}
bool decodePayload(const uint8_t* in, size_t len, ParamValue& m) {
  if (len != ParamValue::kWireSize) return false;
  Reader r(in);
  m.param_id = r.u16();
  const uint8_t status = r.u8();
  if (status > static_cast<uint8_t>(ParamStatus::kBusy)) return false;
  m.status = static_cast<ParamStatus>(status);
  m.reserved = r.u8();
  m.value = r.f32();
  return true;
}

size_t encodeFrameRaw(uint8_t id, const uint8_t* payload, size_t len, uint8_t* out) {
  if (len > kMaxPayload) return 0;
  uint8_t body[kMaxFrameBody];
  body[0] = id;
  std::memcpy(body + 1, payload, len);
  const uint16_t crc = crc16(body, 1 + len);
  body[1 + len] = static_cast<uint8_t>(crc);
  body[2 + len] = static_cast<uint8_t>(crc >> 8);
  const size_t n = cobsEncode(body, len + 3, out);
  out[n] = 0;
  return n + 1;
}

BodyStatus checkBody(const uint8_t* body, size_t len, Frame& out) {
  if (len < 3) return BodyStatus::kTooShort;
  const uint16_t expected = static_cast<uint16_t>(body[len - 2] | (body[len - 1] << 8));
  if (crc16(body, len - 2) != expected) return BodyStatus::kCrc;
  const size_t want = wireSize(body[0]);
  if (want == 0) return BodyStatus::kUnknownId;
  if (want != len - 3) return BodyStatus::kBadLength;
  out.id = body[0];
  out.payload = body + 1;
  out.len = len - 3;
  return BodyStatus::kOk;
}

bool StreamDecoder::push(uint8_t byte) {
  if (hunting_) {
    hunting_ = byte != 0;
    return false;
  }
  if (byte != 0) {
    if (raw_len_ < sizeof raw_) {
      raw_[raw_len_++] = byte;
    } else {
      overflow_ = true;
    }
    return false;
  }
  // Delimiter: judge what was collected.
  const size_t n = raw_len_;
  const bool overflow = overflow_;
  raw_len_ = 0;
  overflow_ = false;
  if (n == 0 && !overflow) return false;  // back-to-back delimiters are idle fill, not errors
  if (overflow) {
    ++stats_.framing_errors;
    return false;
  }
  const size_t body_len = cobsDecode(raw_, n, decoded_, sizeof decoded_);
  if (body_len == 0) {
    ++stats_.framing_errors;
    return false;
  }
  switch (checkBody(decoded_, body_len, frame_)) {
    case BodyStatus::kOk: ++stats_.frames_ok; return true;
    case BodyStatus::kTooShort: ++stats_.framing_errors; return false;
    case BodyStatus::kCrc: ++stats_.crc_errors; return false;
    case BodyStatus::kUnknownId: ++stats_.unknown_id; return false;
    case BodyStatus::kBadLength: ++stats_.bad_length; return false;
  }
  return false;
}

}  // namespace phalanx::protocol
