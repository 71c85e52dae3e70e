#include "phalanx/protocol/can.h"

#include <cmath>
#include <cstring>

#include "phalanx/protocol/codec.h"

namespace phalanx::protocol::can {
namespace {

void put16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
void put32(uint8_t* p, uint32_t v) {
  put16(p, static_cast<uint16_t>(v));
  put16(p + 2, static_cast<uint16_t>(v >> 16));
}
uint16_t get16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t get32(const uint8_t* p) { return get16(p) | (static_cast<uint32_t>(get16(p + 2)) << 16); }

/// The function a whole message travels under (CAN-FD; classic for the messages that fit one frame).
bool functionFor(uint8_t msg_id, Function& fn) {
  switch (static_cast<MsgId>(msg_id)) {
    case MsgId::kHello: fn = Function::kHello; return true;
    case MsgId::kHelloAck: fn = Function::kHelloAck; return true;
    case MsgId::kCommand: fn = Function::kCommand; return true;
    case MsgId::kTelemetry: fn = Function::kTelemetry; return true;
    case MsgId::kEvent: fn = Function::kEvent; return true;
    case MsgId::kClearFaults: fn = Function::kClearFaults; return true;
    case MsgId::kParamGet: fn = Function::kParamGet; return true;
    case MsgId::kParamSet: fn = Function::kParamSet; return true;
    case MsgId::kParamValue: fn = Function::kParamValue; return true;
    case MsgId::kUpdateBegin: fn = Function::kUpdateBegin; return true;
    case MsgId::kUpdateData: fn = Function::kUpdateData; return true;
    case MsgId::kUpdateCommit: fn = Function::kUpdateCommit; return true;
    case MsgId::kUpdateStatus: fn = Function::kUpdateStatus; return true;
  }
  return false;
}

/// Message carried whole by a function (0 for classic-only part/group functions and unknown codes).
uint8_t messageFor(uint8_t fn) {
  switch (static_cast<Function>(fn)) {
    case Function::kHello: return static_cast<uint8_t>(MsgId::kHello);
    case Function::kHelloAck: return static_cast<uint8_t>(MsgId::kHelloAck);
    case Function::kCommand: return static_cast<uint8_t>(MsgId::kCommand);
    case Function::kTelemetry: return static_cast<uint8_t>(MsgId::kTelemetry);
    case Function::kEvent: return static_cast<uint8_t>(MsgId::kEvent);
    case Function::kClearFaults: return static_cast<uint8_t>(MsgId::kClearFaults);
    case Function::kParamGet: return static_cast<uint8_t>(MsgId::kParamGet);
    case Function::kParamSet: return static_cast<uint8_t>(MsgId::kParamSet);
    case Function::kParamValue: return static_cast<uint8_t>(MsgId::kParamValue);
    case Function::kUpdateBegin: return static_cast<uint8_t>(MsgId::kUpdateBegin);
    case Function::kUpdateData: return static_cast<uint8_t>(MsgId::kUpdateData);
    case Function::kUpdateCommit: return static_cast<uint8_t>(MsgId::kUpdateCommit);
    case Function::kUpdateStatus: return static_cast<uint8_t>(MsgId::kUpdateStatus);
    default: return 0;
  }
}

/// Messages the host sends (the others are sent by devices).
bool hostSends(uint8_t msg_id) {
  switch (static_cast<MsgId>(msg_id)) {
    case MsgId::kHello:
    case MsgId::kCommand:
    case MsgId::kClearFaults:
    case MsgId::kParamGet:
    case MsgId::kParamSet:
    case MsgId::kUpdateBegin:
    case MsgId::kUpdateData:
    case MsgId::kUpdateCommit: return true;
    default: return false;
  }
}

bool hostSendsFunction(uint8_t fn) {
  if (fn == static_cast<uint8_t>(Function::kCommandPart1Even) || fn == static_cast<uint8_t>(Function::kCommandPart1Odd)) {
    return true;
  }
  const uint8_t msg = messageFor(fn);
  return msg != 0 && hostSends(msg);
}

/// Firmware update messages: CAN-FD only (UpdateData alone is 56 bytes).
bool isUpdateMessage(uint8_t msg_id) {
  return msg_id >= static_cast<uint8_t>(MsgId::kUpdateBegin) && msg_id <= static_cast<uint8_t>(MsgId::kUpdateStatus);
}

/// CRC-16/CCITT-FALSE over msg_id | payload: the same check as the byte-stream framing.
uint16_t messageCrc(uint8_t msg_id, const uint8_t* payload, size_t len) {
  return crc16(payload, len, crc16(&msg_id, 1));
}

int16_t setpointCode(float value, SampleKind kind) {
  if (!std::isfinite(value)) return kClassicNotFinite;
  return encodeSample(value, kind);  // saturates at ±32767: beyond every device's setpoint limit
}

float setpointValue(int16_t code, SampleKind kind) {
  return code == kClassicNotFinite ? NAN : decodeSample(code, kind);
}

/// Compact CAN-FD setpoint: as classic, and a value beyond the device's limit is sent saturated (±32767 LSB, also
/// beyond the limit) so that rounding can never turn a setpoint the device must reject into one it accepts.
int16_t compactSetpointCode(float value, const DeviceLayout& layout, SampleKind kind) {
  if (!std::isfinite(value)) return kClassicNotFinite;
  if (std::fabs(value) > layout.setpoint_limit) return value > 0.0f ? 32767 : -32767;
  return encodeSample(value, kind);
}

bool zeroPadded(const CanFrame& f, size_t used) {
  for (size_t i = used; i < f.len; ++i) {
    if (f.data[i] != 0) return false;
  }
  return true;
}

}  // namespace

void Mapper::setDevice(DeviceType type, uint16_t tick_rate_hz) {
  layout_ = layoutFor(type);
  profile_ = classicProfile(type);
  period_us_ = tick_rate_hz > 0 ? 1000000u / tick_rate_hz : 1000u;
  next_group_ = 0;
  next_first_ = 0;
}

void Mapper::resetTelemetryClock() {
  have_tel_seq_ = false;
  tel_ticks_ = 0;
  for (int16_t& v : held_) v = 0;
}

uint32_t Mapper::derivedTimeUs() const { return static_cast<uint32_t>(tel_ticks_ * period_us_); }

size_t Mapper::encode(uint8_t msg_id, const uint8_t* payload, size_t len, CanFrame* out, EncodeStatus& status) {
  refusal_ = nullptr;
  Function fn = Function::kHello;
  if (!functionFor(msg_id, fn) || len != wireSize(msg_id)) {
    status = EncodeStatus::kUnknownMessage;
    return 0;
  }
  if (hostSends(msg_id) != (role_ == Role::kHost)) {
    status = EncodeStatus::kWrongDirection;
    return 0;
  }
  if (flavor_ == Flavor::kClassic) return encodeClassic(msg_id, payload, len, out, status);
  if (flavor_ == Flavor::kFdCompact && (msg_id == static_cast<uint8_t>(MsgId::kCommand) ||
                                        msg_id == static_cast<uint8_t>(MsgId::kTelemetry))) {
    return encodeCompact(msg_id, payload, out[0], status) ? 1 : 0;
  }

  // CAN-FD: the whole payload; host → device frames append CRC-16(msg_id | payload) little-endian; zero padding
  // up to the next CAN-FD length.
  CanFrame& f = out[0];
  f = CanFrame{};
  f.id = canId(fn, node_);
  f.fd = true;
  std::memcpy(f.data, payload, len);
  size_t used = len;
  if (hostSends(msg_id)) {
    put16(f.data + len, messageCrc(msg_id, payload, len));
    used += 2;
  }
  f.len = fdLength(used);
  status = EncodeStatus::kOk;
  return 1;
}

bool Mapper::encodeCompact(uint8_t msg_id, const uint8_t* payload, CanFrame& f, EncodeStatus& status) {
  if (layout_ == nullptr) {
    status = EncodeStatus::kNoDevice;
    return false;
  }
  auto refuse = [&](const char* why) {
    refusal_ = why;
    status = EncodeStatus::kNotRepresentable;
    return false;
  };
  f = CanFrame{};
  f.fd = true;
  if (msg_id == static_cast<uint8_t>(MsgId::kCommand)) {
    // seq u16 | timeout_ms (bits 0-9) + mode (bits 10-11) u16 | setpoint i16[n] | gain code u8[n] | CRC-16.
    const uint8_t n = layout_->setpoint_count;
    const uint16_t timeout = get16(payload + 2);
    const uint8_t mode = payload[4];
    if (payload[5] != 0) return refuse("flags != 0 (CAN-FD compact carries none)");
    if (payload[7] != 0) return refuse("reserved byte != 0 (CAN-FD compact carries none)");
    if (payload[6] != n) return refuse("channel_count differs from the device's setpoint count");
    if (timeout > kCompactMaxTimeoutMs) return refuse("timeout_ms > 1023 (CAN-FD compact: 10 bits)");
    if (mode > 3) return refuse("mode > 3 (CAN-FD compact: 2 bits)");
    uint8_t gain_code[kMaxSetpoints] = {};
    for (uint8_t i = 0; i < n; ++i) {
      const uint16_t g = get16(payload + 40 + 2 * i);
      if (g > kCompactMaxGainCode * kCompactGainStepPermille) return refuse("gain scale > 2000 permille");
      // Round to the nearest 8 ‰ (0, 1000 and 2000 exact); ≤ 2000 stays ≤ 2000.
      gain_code[i] = static_cast<uint8_t>((g + kCompactGainStepPermille / 2) / kCompactGainStepPermille);
    }
    put16(f.data, get16(payload));
    put16(f.data + 2, static_cast<uint16_t>(timeout | (mode << 10)));
    for (uint8_t i = 0; i < n; ++i) {
      const uint32_t bits = get32(payload + 8 + 4 * i);
      float v;
      std::memcpy(&v, &bits, sizeof v);
      put16(f.data + 4 + 2 * i, static_cast<uint16_t>(compactSetpointCode(v, *layout_, profile_.setpoint_kind)));
      f.data[4 + 2 * n + i] = gain_code[i];
    }
    const size_t body = kCompactCommandHeader + 3u * n;
    put16(f.data + body, messageCrc(msg_id, f.data, body));
    f.id = canId(Function::kCommand, node_);
    f.len = fdLength(body + 2);
  } else {
    // seq u16 | cmd_seq_echo u16 | fault_bits u16 | mode (bits 0-1) + state_flags (bits 2-5) u8 | cmd_lost u8 |
    // rx_errors u8 | first u8 | sample i16[K]: samples first .. first+K-1 (mod S), the window rotating by K.
    const uint8_t mode = payload[8], flags = payload[9];
    if (mode > 3) return refuse("telemetry mode > 3 (CAN-FD compact: 2 bits)");
    if (flags > 0x0F) return refuse("telemetry state_flags above bit 3 (CAN-FD compact: 4 bits)");
    const uint8_t s = layout_->sample_count;
    const uint8_t k = compactWindow(s);
    const uint8_t first = next_first_ < s ? next_first_ : 0;
    next_first_ = static_cast<uint8_t>(s > 0 ? (first + k) % s : 0);
    std::memcpy(f.data, payload + 4, 4);       // seq, cmd_seq_echo
    std::memcpy(f.data + 4, payload + 10, 2);  // fault_bits
    f.data[6] = static_cast<uint8_t>(mode | (flags << 2));
    f.data[7] = payload[12];  // cmd_lost
    f.data[8] = payload[13];  // rx_errors
    f.data[9] = first;
    for (uint8_t i = 0; i < k; ++i) {
      const uint8_t idx = static_cast<uint8_t>((first + i) % s);
      std::memcpy(f.data + kCompactTelemetryHeader + 2 * i, payload + 14 + 2 * idx, 2);
    }
    f.id = canId(Function::kTelemetry, node_);
    f.len = fdLength(compactTelemetryBytes(s));
  }
  status = EncodeStatus::kOk;
  return true;
}

size_t Mapper::encodeClassic(uint8_t msg_id, const uint8_t* payload, size_t len, CanFrame* out, EncodeStatus& status) {
  status = EncodeStatus::kOk;
  if (isUpdateMessage(msg_id)) {
    refusal_ = "firmware update messages travel on CAN-FD only (docs/firmware-update.md)";
    status = EncodeStatus::kNotRepresentable;
    return 0;
  }
  auto frame = [&](size_t i, Function fn, uint8_t n) -> CanFrame& {
    out[i] = CanFrame{};
    out[i].id = canId(fn, node_);
    out[i].len = n;
    return out[i];
  };
  switch (static_cast<MsgId>(msg_id)) {
    case MsgId::kCommand: {
      if (layout_ == nullptr) {
        status = EncodeStatus::kNoDevice;
        return 0;
      }
      // Read the fields directly: an undefined mode byte is carried as is, so the device rejects it itself.
      Command c;
      c.seq = get16(payload);
      c.timeout_ms = get16(payload + 2);
      c.flags = payload[5];
      c.channel_count = payload[6];
      for (size_t i = 0; i < kMaxSetpoints; ++i) {
        const uint32_t bits = get32(payload + 8 + 4 * i);
        std::memcpy(&c.setpoint[i], &bits, sizeof bits);
        c.gain_scale_permille[i] = get16(payload + 40 + 2 * i);
      }
      const uint8_t n = layout_->setpoint_count;
      bool nominal = true;
      for (uint8_t i = 0; i < n; ++i) nominal = nominal && c.gain_scale_permille[i] == 1000;
      if (c.flags != 0 || c.channel_count != n || c.timeout_ms > kClassicMaxTimeoutMs || !nominal) {
        refusal_ = c.flags != 0                  ? "flags != 0 (classic CAN carries none)"
                   : c.channel_count != n        ? "channel_count differs from the device's setpoint count"
                   : c.timeout_ms > kClassicMaxTimeoutMs ? "timeout_ms > 255 (classic CAN: one byte)"
                                                 : "gain scale != 1000 permille (classic CAN carries none)";
        status = EncodeStatus::kNotRepresentable;
        return 0;
      }
      // Part 0: seq u16 | mode u8 | timeout_ms u8 | setpoints 0..1 (i16). Part 1: setpoints 2..n-1.
      const uint8_t first = n < 2 ? n : 2;
      CanFrame& p0 = frame(0, Function::kCommand, static_cast<uint8_t>(4 + 2 * first));
      put16(p0.data, c.seq);
      p0.data[2] = payload[4];
      p0.data[3] = static_cast<uint8_t>(c.timeout_ms);
      for (uint8_t i = 0; i < first; ++i) {
        put16(p0.data + 4 + 2 * i, static_cast<uint16_t>(setpointCode(c.setpoint[i], profile_.setpoint_kind)));
      }
      if (n <= 2) return 1;
      CanFrame& p1 = frame(1, (c.seq & 1u) ? Function::kCommandPart1Odd : Function::kCommandPart1Even,
                           static_cast<uint8_t>(2 * (n - 2)));
      for (uint8_t i = 2; i < n; ++i) {
        put16(p1.data + 2 * (i - 2), static_cast<uint16_t>(setpointCode(c.setpoint[i], profile_.setpoint_kind)));
      }
      return 2;
    }
    case MsgId::kTelemetry: {
      if (layout_ == nullptr) {
        status = EncodeStatus::kNoDevice;
        return 0;
      }
      // Sample groups first (rotating through the device's groups), the status frame last: it closes the tick.
      const uint8_t groups = static_cast<uint8_t>((layout_->sample_count + 3) / 4);
      size_t k = 0;
      for (uint8_t g = 0; g < profile_.groups_per_tick && g < groups; ++g) {
        const uint8_t grp = next_group_;
        next_group_ = static_cast<uint8_t>((next_group_ + 1) % groups);
        const uint8_t first = static_cast<uint8_t>(4 * grp);
        const uint8_t count = static_cast<uint8_t>(layout_->sample_count - first < 4 ? layout_->sample_count - first : 4);
        CanFrame& gf = frame(k++, static_cast<Function>(static_cast<uint8_t>(Function::kTelemetryGroup0) + grp),
                             static_cast<uint8_t>(2 * count));
        std::memcpy(gf.data, payload + 14 + 2 * first, 2u * count);
      }
      // Status: seq u16 | cmd_seq_echo u16 | fault_bits u16 | mode (bits 0-1) + state_flags (bits 2-5) |
      // cmd_lost mod 16 (bits 0-3) + rx_errors mod 16 (bits 4-7).
      CanFrame& s = frame(k++, Function::kTelemetry, 8);
      std::memcpy(s.data, payload + 4, 4);        // seq, cmd_seq_echo
      std::memcpy(s.data + 4, payload + 10, 2);   // fault_bits
      s.data[6] = static_cast<uint8_t>((payload[8] & 0x03u) | ((payload[9] & 0x0Fu) << 2));
      s.data[7] = static_cast<uint8_t>((payload[12] & 0x0Fu) | ((payload[13] & 0x0Fu) << 4));
      return k;
    }
    case MsgId::kHelloAck: {
      CanFrame& a0 = frame(0, Function::kHelloAck, 8);
      std::memcpy(a0.data, payload, 8);  // version, device, status, session
      CanFrame& a1 = frame(1, Function::kHelloAckPart1, 8);
      std::memcpy(a1.data, payload + 8, 8);  // build id, tick rate, channel counts
      return 2;
    }
    case MsgId::kEvent: {
      // code u8 | channel u8 | detail u8 | 0 | value f32; the device time is not carried.
      CanFrame& e = frame(0, Function::kEvent, 8);
      e.data[0] = payload[4];
      e.data[1] = payload[6];
      e.data[2] = payload[7];
      std::memcpy(e.data + 4, payload + 8, 4);
      return 1;
    }
    default: {
      // Hello, ClearFaults, ParamGet, ParamSet, ParamValue: at most 8 bytes, one frame as they are.
      Function fn = Function::kHello;
      functionFor(msg_id, fn);
      CanFrame& f = frame(0, fn, static_cast<uint8_t>(len));
      std::memcpy(f.data, payload, len);
      return 1;
    }
  }
}

bool Mapper::decode(const CanFrame& f, uint8_t& msg_id, uint8_t* payload, size_t& len) {
  const uint8_t fn = functionOf(f.id);
  if (f.extended || f.remote || f.id > 0x7FFu || nodeOf(f.id) != node_ || fn == 0 ||
      hostSendsFunction(fn) != (role_ == Role::kDevice)) {
    ++stats_.bad_id;
    return false;
  }
  if (f.fd != isFd(flavor_)) {
    ++stats_.bad_length;
    return false;
  }
  return isFd(flavor_) ? decodeFd(f, fn, msg_id, payload, len) : decodeClassic(f, fn, msg_id, payload, len);
}

bool Mapper::decodeFd(const CanFrame& f, uint8_t fn, uint8_t& msg_id, uint8_t* payload, size_t& len) {
  const uint8_t msg = messageFor(fn);
  if (msg == 0) {
    ++stats_.bad_id;
    return false;
  }
  if (flavor_ == Flavor::kFdCompact &&
      (msg == static_cast<uint8_t>(MsgId::kCommand) || msg == static_cast<uint8_t>(MsgId::kTelemetry))) {
    if (layout_ == nullptr) {  // the host learns the device from the HelloAck: nothing to decode before it
      ++stats_.bad_id;
      return false;
    }
    const bool ok = msg == static_cast<uint8_t>(MsgId::kCommand) ? decodeCompactCommand(f, payload)
                                                                  : decodeCompactTelemetry(f, payload);
    if (!ok) return false;
    msg_id = msg;
    len = wireSize(msg);
    ++stats_.frames_ok;
    ++stats_.messages_ok;
    return true;
  }
  const size_t n = wireSize(msg);
  const bool with_crc = hostSends(msg);
  const size_t used = n + (with_crc ? 2 : 0);
  if (f.len != fdLength(used)) {
    ++stats_.bad_length;
    return false;
  }
  for (size_t i = used; i < f.len; ++i) {
    if (f.data[i] != 0) {
      ++stats_.bad_length;
      return false;
    }
  }
  if (with_crc && get16(f.data + n) != messageCrc(msg, f.data, n)) {
    ++stats_.crc;
    return false;
  }
  if (msg == static_cast<uint8_t>(MsgId::kHelloAck) && role_ == Role::kHost) {
    HelloAck a;
    if (decodePayload(f.data, n, a) && a.status == HandshakeStatus::kOk) {
      setDevice(a.device_type, a.tick_rate_hz);
      resetTelemetryClock();
    }
  }
  std::memcpy(payload, f.data, n);
  msg_id = msg;
  len = n;
  ++stats_.frames_ok;
  ++stats_.messages_ok;
  return true;
}

bool Mapper::decodeCompactCommand(const CanFrame& f, uint8_t* payload) {
  const uint8_t n = layout_->setpoint_count;
  const size_t body = kCompactCommandHeader + 3u * n;
  if (f.len != fdLength(body + 2) || !zeroPadded(f, body + 2)) {
    ++stats_.bad_length;
    return false;
  }
  if (get16(f.data + body) != messageCrc(static_cast<uint8_t>(MsgId::kCommand), f.data, body)) {
    ++stats_.crc;
    return false;
  }
  const uint16_t word = get16(f.data + 2);
  if ((word & 0xF000u) != 0) {  // reserved bits 12-15
    ++stats_.bad_length;
    return false;
  }
  for (uint8_t i = 0; i < n; ++i) {
    if (f.data[4 + 2 * n + i] > kCompactMaxGainCode) {
      ++stats_.bad_length;
      return false;
    }
  }
  Command c;
  c.seq = get16(f.data);
  c.timeout_ms = static_cast<uint16_t>(word & 0x03FFu);
  c.mode = static_cast<Mode>((word >> 10) & 0x03u);
  c.channel_count = n;
  for (uint8_t i = 0; i < n; ++i) {
    c.setpoint[i] = setpointValue(static_cast<int16_t>(get16(f.data + 4 + 2 * i)), profile_.setpoint_kind);
    c.gain_scale_permille[i] = static_cast<uint16_t>(f.data[4 + 2 * n + i] * kCompactGainStepPermille);
  }
  for (uint8_t i = n; i < kMaxSetpoints; ++i) c.gain_scale_permille[i] = 1000;
  encodePayload(c, payload);
  return true;
}

bool Mapper::decodeCompactTelemetry(const CanFrame& f, uint8_t* payload) {
  const uint8_t s = layout_->sample_count;
  const uint8_t k = compactWindow(s);
  const size_t used = compactTelemetryBytes(s);
  if (f.len != fdLength(used) || !zeroPadded(f, used) || (f.data[6] & 0xC0u) != 0 || f.data[9] >= s) {
    ++stats_.bad_length;
    return false;
  }
  const uint16_t seq = get16(f.data);
  tel_ticks_ += have_tel_seq_ ? static_cast<uint16_t>(seq - last_tel_seq_) : 0u;
  have_tel_seq_ = true;
  last_tel_seq_ = seq;
  for (uint8_t i = 0; i < k; ++i) {
    held_[(f.data[9] + i) % s] = static_cast<int16_t>(get16(f.data + kCompactTelemetryHeader + 2 * i));
  }
  Telemetry t;
  t.time_us = derivedTimeUs();
  t.seq = seq;
  t.cmd_seq_echo = get16(f.data + 2);
  t.fault_bits = get16(f.data + 4);
  t.mode = static_cast<Mode>(f.data[6] & 0x03u);
  t.state_flags = static_cast<uint8_t>(f.data[6] >> 2);
  t.cmd_lost = f.data[7];
  t.rx_errors = f.data[8];
  for (uint8_t i = 0; i < kMaxSamples; ++i) t.sample[i] = held_[i];
  encodePayload(t, payload);
  return true;
}

bool Mapper::decodeClassic(const CanFrame& f, uint8_t fn, uint8_t& msg_id, uint8_t* payload, size_t& len) {
  auto badLength = [&]() {
    ++stats_.bad_length;
    return false;
  };
  auto deliver = [&](MsgId id, size_t n) {
    msg_id = static_cast<uint8_t>(id);
    len = n;
    ++stats_.frames_ok;
    ++stats_.messages_ok;
    return true;
  };
  const Function function = static_cast<Function>(fn);
  if (fn >= static_cast<uint8_t>(Function::kTelemetryGroup0) &&
      fn < static_cast<uint8_t>(Function::kTelemetryGroup0) + kTelemetryGroups) {
    const uint8_t grp = static_cast<uint8_t>(fn - static_cast<uint8_t>(Function::kTelemetryGroup0));
    if (layout_ == nullptr || 4 * grp >= layout_->sample_count) {
      ++stats_.bad_id;
      return false;
    }
    const uint8_t first = static_cast<uint8_t>(4 * grp);
    const uint8_t count = static_cast<uint8_t>(layout_->sample_count - first < 4 ? layout_->sample_count - first : 4);
    if (f.len != 2 * count) return badLength();
    for (uint8_t i = 0; i < count; ++i) held_[first + i] = static_cast<int16_t>(get16(f.data + 2 * i));
    ++stats_.frames_ok;
    return false;
  }
  switch (function) {
    case Function::kCommand:
    case Function::kCommandPart1Even:
    case Function::kCommandPart1Odd: {
      if (layout_ == nullptr) {
        ++stats_.bad_id;
        return false;
      }
      const uint8_t n = layout_->setpoint_count;
      const uint8_t first = n < 2 ? n : 2;
      const uint8_t* p0 = f.data;
      const uint8_t* p1 = nullptr;
      if (function == Function::kCommand) {
        if (f.len != 4 + 2 * first) return badLength();
        if (cmd_pending_) ++stats_.sequence;  // the previous command never got its part 1
        cmd_pending_ = false;
        if (n > 2) {
          std::memcpy(cmd_part0_, f.data, 8);
          cmd_pending_ = true;
          ++stats_.frames_ok;
          return false;
        }
      } else {
        if (n <= 2 || f.len != 2 * (n - 2)) return badLength();
        const bool odd = function == Function::kCommandPart1Odd;
        if (!cmd_pending_ || ((get16(cmd_part0_) & 1u) != 0) != odd) {
          cmd_pending_ = false;
          ++stats_.sequence;
          return false;
        }
        cmd_pending_ = false;
        p0 = cmd_part0_;
        p1 = f.data;
      }
      Command c;
      c.seq = get16(p0);
      c.timeout_ms = p0[3];
      c.channel_count = n;
      for (uint8_t i = 0; i < n; ++i) {
        const uint8_t* src = i < 2 ? p0 + 4 + 2 * i : p1 + 2 * (i - 2);
        c.setpoint[i] = setpointValue(static_cast<int16_t>(get16(src)), profile_.setpoint_kind);
        c.gain_scale_permille[i] = 1000;
      }
      encodePayload(c, payload);
      payload[4] = p0[2];  // the mode byte as received: an undefined mode is rejected by the device, not here
      return deliver(MsgId::kCommand, Command::kWireSize);
    }
    case Function::kTelemetry: {
      if (layout_ == nullptr) {
        ++stats_.bad_id;
        return false;
      }
      if (f.len != 8) return badLength();
      const uint16_t seq = get16(f.data);
      tel_ticks_ += have_tel_seq_ ? static_cast<uint16_t>(seq - last_tel_seq_) : 0u;
      have_tel_seq_ = true;
      last_tel_seq_ = seq;
      // Running 8-bit counters rebuilt from their 4-bit residues (exact while fewer than 16 per tick).
      const uint8_t lost = f.data[7] & 0x0Fu, rxe = static_cast<uint8_t>(f.data[7] >> 4);
      cmd_lost_ = static_cast<uint8_t>(cmd_lost_ + ((lost - cmd_lost_nibble_) & 0x0Fu));
      rx_errors_ = static_cast<uint8_t>(rx_errors_ + ((rxe - rx_err_nibble_) & 0x0Fu));
      cmd_lost_nibble_ = lost;
      rx_err_nibble_ = rxe;
      Telemetry t;
      t.time_us = derivedTimeUs();
      t.seq = seq;
      t.cmd_seq_echo = get16(f.data + 2);
      t.fault_bits = get16(f.data + 4);
      t.state_flags = static_cast<uint8_t>((f.data[6] >> 2) & 0x0Fu);
      t.cmd_lost = cmd_lost_;
      t.rx_errors = rx_errors_;
      for (uint8_t i = 0; i < kMaxSamples; ++i) t.sample[i] = held_[i];
      encodePayload(t, payload);
      payload[8] = f.data[6] & 0x03u;  // mode
      return deliver(MsgId::kTelemetry, Telemetry::kWireSize);
    }
    case Function::kHelloAck: {
      if (f.len != 8) return badLength();
      if (ack_pending_) ++stats_.sequence;
      std::memcpy(ack_part0_, f.data, 8);
      ack_pending_ = true;
      ++stats_.frames_ok;
      return false;
    }
    case Function::kHelloAckPart1: {
      if (f.len != 8) return badLength();
      if (!ack_pending_) {
        ++stats_.sequence;
        return false;
      }
      ack_pending_ = false;
      std::memcpy(payload, ack_part0_, 8);
      std::memcpy(payload + 8, f.data, 8);
      HelloAck a;
      if (decodePayload(payload, HelloAck::kWireSize, a) && a.status == HandshakeStatus::kOk) {
        setDevice(a.device_type, a.tick_rate_hz);
        have_tel_seq_ = false;
        tel_ticks_ = 0;
      }
      return deliver(MsgId::kHelloAck, HelloAck::kWireSize);
    }
    case Function::kEvent: {
      if (f.len != 8 || f.data[3] != 0) return badLength();
      put32(payload, derivedTimeUs());
      payload[4] = f.data[0];
      payload[5] = 0;
      payload[6] = f.data[1];
      payload[7] = f.data[2];
      std::memcpy(payload + 8, f.data + 4, 4);
      return deliver(MsgId::kEvent, Event::kWireSize);
    }
    default: {
      const uint8_t msg = messageFor(fn);
      if (msg == 0 || isUpdateMessage(msg)) {
        ++stats_.bad_id;
        return false;
      }
      const size_t n = wireSize(msg);
      if (f.len != n) return badLength();
      std::memcpy(payload, f.data, n);
      return deliver(static_cast<MsgId>(msg), n);
    }
  }
}

double frameTimeS(const CanFrame& f, double nominal_bps, double data_bps, bool worst) {
  const uint32_t n = f.len;
  if (!f.fd) return classicFrameBits(n, worst) / nominal_bps;
  // CAN-FD base format (ISO 11898-1:2015). Arbitration phase at the nominal rate: SOF, 11-bit ID, RRS, IDE, FDF,
  // res, BRS (17 bits). Data phase at the data rate: ESI, DLC, data, stuff count (4), CRC-17 (≤ 16 bytes) or
  // CRC-21 with its fixed stuff bits (6 or 7). Back at the nominal rate: CRC delimiter, ACK, ACK delimiter, EOF,
  // intermission (13 bits). Dynamic stuffing (worst case one per 4 bits) covers SOF..data.
  const uint32_t arb = 17u, tail = 13u;
  const uint32_t crc = n <= 16 ? 17u : 21u;
  const uint32_t fixed_stuff = n <= 16 ? 6u : 7u;
  const uint32_t dyn_region = arb + 5u + 8u * n;
  const uint32_t dyn_stuff = worst ? (dyn_region - 1u) / 4u : 0u;
  const uint32_t arb_stuff = worst ? (arb - 1u) / 4u : 0u;
  const uint32_t data_bits = 5u + 8u * n + (dyn_stuff - arb_stuff) + 4u + crc + fixed_stuff;
  return (arb + arb_stuff + tail) / nominal_bps + data_bits / data_bps;
}

}  // namespace phalanx::protocol::can
