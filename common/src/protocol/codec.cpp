#include "phalanx/protocol/codec.h"

#include <cstring>
#include <limits>

namespace phalanx::protocol {
namespace {

// CRC-16/CCITT-FALSE, slicing by 4, tables generated at compile time. kCrc.v[0][b] is the CRC of byte b from
// state 0, kCrc.v[k][b] that of b followed by k zero bytes; four bytes then cost four lookups, the register's two
// bytes folded into the first two message bytes (the CRC is linear). The register and the tables are kept with
// their two bytes swapped (the register's high byte in bits 0–7), so that the register folds into a little-endian
// word with one xor. 4 × 256 × 2 = 2 048 bytes of flash on the MCU (the byte-at-a-time table was 512).
constexpr uint16_t swap16(uint16_t v) { return static_cast<uint16_t>((v >> 8) | (v << 8)); }

struct Crc16Tables {
  uint16_t v[4][256];
  constexpr Crc16Tables() : v{} {
    uint16_t plain[4][256] = {};
    for (int i = 0; i < 256; ++i) {
      uint16_t c = static_cast<uint16_t>(i << 8);
      for (int b = 0; b < 8; ++b) c = static_cast<uint16_t>((c & 0x8000u) ? ((c << 1) ^ 0x1021u) : (c << 1));
      plain[0][i] = c;
    }
    for (int k = 1; k < 4; ++k) {
      for (int i = 0; i < 256; ++i) {
        const uint16_t c = plain[k - 1][i];
        plain[k][i] = static_cast<uint16_t>((c << 8) ^ plain[0][c >> 8]);
      }
    }
    for (int k = 0; k < 4; ++k) {
      for (int i = 0; i < 256; ++i) v[k][i] = swap16(plain[k][i]);
    }
  }
};
constexpr Crc16Tables kCrc{};

// One byte into the swapped register s.
inline uint32_t crcByte(uint32_t s, uint8_t b) { return (s >> 8) ^ kCrc.v[0][(s ^ b) & 0xFFu]; }

// Four message bytes, loaded little-endian into w (first byte in bits 0–7), into the swapped register s.
inline uint32_t crcWord(uint32_t s, uint32_t w) {
  w ^= s;
  return static_cast<uint32_t>(kCrc.v[3][w & 0xFFu] ^ kCrc.v[2][(w >> 8) & 0xFFu] ^ kCrc.v[1][(w >> 16) & 0xFFu] ^
                               kCrc.v[0][w >> 24]);
}

// Four bytes at p (any alignment) with the first byte in bits 0–7, whatever the host's byte order.
inline uint32_t loadLe32(const uint8_t* p) {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
  uint32_t w;
  std::memcpy(&w, p, sizeof w);
  return w;
#else
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
#endif
}

// Bit 7 of each byte of the result is set exactly where w's byte is 0 (no borrow between bytes, unlike the
// classic (w - 0x01010101) & ~w trick, whose bits above a zero byte can be false positives).
inline uint32_t zeroBytes(uint32_t w) { return ~(((w & 0x7F7F7F7Fu) + 0x7F7F7F7Fu) | w | 0x7F7F7F7Fu); }

// Every body is shorter than one COBS block (254 bytes): each code byte is then the distance to the next zero
// (or to the end), COBS never inserts a 0xFF block, and encoding is in place.
static_assert(kMaxFrameBody < 254, "single-block COBS framing");

// On a little-endian target with IEEE-754 floats an array of i16/u16/f32 already has its wire layout: copied whole.
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
constexpr bool kWireLayoutNative = std::numeric_limits<float>::is_iec559;
#else
constexpr bool kWireLayoutNative = false;
#endif

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
  template <class T, size_t N>
  void array(const T (&a)[N]) {
    if constexpr (kWireLayoutNative) {
      std::memcpy(p_, a, sizeof a);
      p_ += sizeof a;
    } else {
      for (const T& v : a) put(v);
    }
  }

 private:
  void put(int16_t v) { i16(v); }
  void put(uint16_t v) { u16(v); }
  void put(float v) { f32(v); }
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
  template <class T, size_t N>
  void array(T (&a)[N]) {
    if constexpr (kWireLayoutNative) {
      std::memcpy(a, p_, sizeof a);
      p_ += sizeof a;
    } else {
      for (T& v : a) get(v);
    }
  }

 private:
  void get(int16_t& v) { v = i16(); }
  void get(uint16_t& v) { v = u16(); }
  void get(float& v) { v = f32(); }
  const uint8_t* p_;
};

bool validDevice(uint8_t v) { return v <= static_cast<uint8_t>(DeviceType::kPantograph); }
bool validMode(uint8_t v) { return v < kModeCount; }

}  // namespace

uint16_t crc16(const uint8_t* data, size_t len, uint16_t crc) {
  uint32_t s = swap16(crc);
  size_t i = 0;
  for (; i + 4 <= len; i += 4) s = crcWord(s, loadLe32(data + i));
  for (; i < len; ++i) s = crcByte(s, data[i]);
  return swap16(static_cast<uint16_t>(s));
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
  w.array(m.setpoint);
  w.array(m.gain_scale_permille);
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
  r.array(m.setpoint);
  r.array(m.gain_scale_permille);
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
  w.array(m.sample);
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
  r.array(m.sample);
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
  if (status > static_cast<uint8_t>(ParamStatus::kFailed)) return false;
  m.status = static_cast<ParamStatus>(status);
  m.reserved = r.u8();
  m.value = r.f32();
  return true;
}

void encodePayload(const UpdateBegin& m, uint8_t* out) {
  Writer w(out);
  w.u32(m.image_size);
  w.u32(m.image_crc32);
  w.u32(m.build_id);
  w.u8(m.device_type);
  w.u8(m.board);
  w.u16(m.reserved);
  w.u32(m.session_id);
}
bool decodePayload(const uint8_t* in, size_t len, UpdateBegin& m) {
  if (len != UpdateBegin::kWireSize) return false;
  Reader r(in);
  m.image_size = r.u32();
  m.image_crc32 = r.u32();
  m.build_id = r.u32();
  m.device_type = r.u8();
  m.board = r.u8();
  m.reserved = r.u16();
  m.session_id = r.u32();
  return true;
}

void encodePayload(const UpdateData& m, uint8_t* out) {
  Writer w(out);
  w.u32(m.offset);
  w.u8(m.length);
  for (uint8_t b : m.reserved) w.u8(b);
  for (uint8_t b : m.data) w.u8(b);
}
bool decodePayload(const uint8_t* in, size_t len, UpdateData& m) {
  if (len != UpdateData::kWireSize) return false;
  Reader r(in);
  m.offset = r.u32();
  m.length = r.u8();
  for (uint8_t& b : m.reserved) b = r.u8();
  for (uint8_t& b : m.data) b = r.u8();
  return true;
}

void encodePayload(const UpdateCommit& m, uint8_t* out) {
  Writer w(out);
  w.u32(m.image_crc32);
  w.u32(m.build_id);
}
bool decodePayload(const uint8_t* in, size_t len, UpdateCommit& m) {
  if (len != UpdateCommit::kWireSize) return false;
  Reader r(in);
  m.image_crc32 = r.u32();
  m.build_id = r.u32();
  return true;
}

void encodePayload(const UpdateStatus& m, uint8_t* out) {
  Writer w(out);
  w.u8(static_cast<uint8_t>(m.answers));
  w.u8(static_cast<uint8_t>(m.result));
  w.u8(m.detail);
  w.u8(m.slot);
  w.u32(m.next_offset);
  w.u32(m.value);
}
bool decodePayload(const uint8_t* in, size_t len, UpdateStatus& m) {
  if (len != UpdateStatus::kWireSize) return false;
  Reader r(in);
  const uint8_t answers = r.u8();
  if (answers < static_cast<uint8_t>(MsgId::kUpdateBegin) || answers > static_cast<uint8_t>(MsgId::kUpdateCommit)) {
    return false;
  }
  m.answers = static_cast<MsgId>(answers);
  const uint8_t result = r.u8();
  if (result >= kUpdateResultCount) return false;
  m.result = static_cast<UpdateResult>(result);
  m.detail = r.u8();
  m.slot = r.u8();
  m.next_offset = r.u32();
  m.value = r.u32();
  return true;
}

size_t finishFrame(uint8_t* out, size_t len) {
  // out[1] = id, out[2 .. 2 + len) = payload. One pass over id | payload: CRC four bytes at a time, and every zero
  // byte found in the same words becomes a COBS code pointing back at the previous code position.
  const size_t n = 1 + len;
  uint8_t* body = out + 1;
  uint32_t crc = 0xFFFF;  // swapped register (0xFFFF either way)
  size_t code_pos = 0;  // index in out of the code byte still waiting for the distance to the next zero
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {  // at most 16 words (n ≤ 65)
    const uint32_t w = loadLe32(body + i);
    crc = crcWord(crc, w);
    for (uint32_t z = zeroBytes(w); z != 0; z &= z - 1) {  // at most 4 zero bytes
      const size_t at = i + 1 + (static_cast<unsigned>(__builtin_ctz(z)) >> 3);
      out[code_pos] = static_cast<uint8_t>(at - code_pos);
      code_pos = at;
    }
  }
  for (; i < n; ++i) {  // at most 3 trailing bytes
    crc = crcByte(crc, body[i]);
    if (body[i] == 0) {
      out[code_pos] = static_cast<uint8_t>(i + 1 - code_pos);
      code_pos = i + 1;
    }
  }
  out[n + 1] = static_cast<uint8_t>(crc >> 8);  // the CRC's low byte first (little-endian), from the swapped register
  out[n + 2] = static_cast<uint8_t>(crc);
  for (size_t at = n + 1; at <= n + 2; ++at) {
    if (out[at] == 0) {
      out[code_pos] = static_cast<uint8_t>(at - code_pos);
      code_pos = at;
    }
  }
  out[code_pos] = static_cast<uint8_t>(n + 3 - code_pos);
  out[n + 3] = 0;
  return n + 4;
}

size_t encodeFrameRaw(uint8_t id, const uint8_t* payload, size_t len, uint8_t* out) {
  if (len > kMaxPayload) return 0;
  out[1] = id;
  if (len > 0) std::memcpy(out + 2, payload, len);  // an empty payload may come as a null pointer
  return finishFrame(out, len);
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
  if (byte != 0) {
    if (raw_len_ < sizeof raw_) {
      raw_[raw_len_++] = byte;
    } else {
      overflow_ = true;
    }
    return false;
  }
  return judge();
}

bool StreamDecoder::feed(const uint8_t*& data, const uint8_t* end) {
  while (data < end) {  // bounded: every pass consumes at least one byte
    const size_t avail = static_cast<size_t>(end - data);
    const auto* zero = static_cast<const uint8_t*>(std::memchr(data, 0, avail));
    const size_t run = zero != nullptr ? static_cast<size_t>(zero - data) : avail;
    if (run <= sizeof raw_ - raw_len_) {
      std::memcpy(raw_ + raw_len_, data, run);
      raw_len_ += run;
    } else {
      raw_len_ = sizeof raw_;  // the content no longer matters: the frame is discarded at its delimiter
      overflow_ = true;
    }
    if (zero == nullptr) {
      data = end;
      return false;
    }
    data = zero + 1;
    if (judge()) return true;
  }
  return false;
}

bool StreamDecoder::judge() {
  const size_t n = raw_len_;
  const bool overflow = overflow_;
  const bool first_after_resync = after_resync_;
  raw_len_ = 0;
  overflow_ = false;
  after_resync_ = false;
  if (n == 0 && !overflow) return false;  // back-to-back delimiters are idle fill, not errors
  if (!first_after_resync) return judgeCollected(n, overflow);
  const DecodeStats before = stats_;
  if (judgeCollected(n, overflow)) return true;
  stats_ = before;  // the tail of a frame the interruption cut: dropped, not counted
  return false;
}

bool StreamDecoder::judgeCollected(size_t n, bool overflow) {
  if (overflow) {
    ++stats_.framing_errors;
    return false;
  }
  // COBS in place: follow the code chain (one step per zero of the body, not per byte), zeroing each code byte
  // after the first. raw_ holds no 0x00 and fewer than 255 bytes, so a 0xFF code always runs past the end.
  static_assert(sizeof raw_ < 255, "a 0xFF code cannot complete inside the buffer");
  size_t pos = raw_[0];
  while (pos < n) {  // at most n steps: every code is ≥ 1
    const uint8_t code = raw_[pos];
    raw_[pos] = 0;
    pos += code;
  }
  if (pos != n || n - 1 > kMaxFrameBody) {  // a group runs past the end, or the body is longer than any frame
    ++stats_.framing_errors;
    return false;
  }
  switch (checkBody(raw_ + 1, n - 1, frame_)) {
    case BodyStatus::kOk: ++stats_.frames_ok; return true;
    case BodyStatus::kTooShort: ++stats_.framing_errors; return false;
    case BodyStatus::kCrc: ++stats_.crc_errors; return false;
    case BodyStatus::kUnknownId: ++stats_.unknown_id; return false;
    case BodyStatus::kBadLength: ++stats_.bad_length; return false;
  }
  return false;
}

}  // namespace phalanx::protocol
