// The compact CAN-FD mapping (phalanx/protocol/can.h, Flavor::kFdCompact; docs/protocol.md "CAN-FD compact"):
// one short command frame and one 32-byte telemetry frame per tick, their round trips for every device, every
// rejection path on receive, every refusal on send, and the 1 kHz bus-load budget it exists for (≤ 20 % at
// 1/5 Mbit/s with worst-case stuffing).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "phalanx/host/can_budget.h"
#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;
using namespace phalanx::protocol::can;

namespace {

constexpr uint8_t kNode = 9;
constexpr DeviceType kDevices[] = {DeviceType::kGlove5, DeviceType::kSeaFinger, DeviceType::kPantograph};

template <class M>
std::vector<uint8_t> payloadOf(const M& m) {
  std::vector<uint8_t> p(M::kWireSize);
  encodePayload(m, p.data());
  return p;
}

struct Endpoints {
  Mapper host{Flavor::kFdCompact, Role::kHost, kNode};
  Mapper dev{Flavor::kFdCompact, Role::kDevice, kNode};
  explicit Endpoints(DeviceType type) {
    host.setDevice(type, 1000);
    dev.setDevice(type, 1000);
  }
};

/// A command whose values the compact encoding carries exactly (setpoints on the LSB grid, gains on 8 ‰).
Command exactCommand(const DeviceLayout& l, uint16_t seq) {
  Command c;
  c.seq = seq;
  c.timeout_ms = 1000;
  c.mode = Mode::kSetpoint;
  c.channel_count = l.setpoint_count;
  for (uint8_t i = 0; i < l.setpoint_count; ++i) {
    const int16_t code = static_cast<int16_t>(1234 * (i + 1) * (i % 2 ? -1 : 1));
    c.setpoint[i] = decodeSample(code, classicProfile(l.type).setpoint_kind);
    c.gain_scale_permille[i] = static_cast<uint16_t>(8 * (100 + 30 * i));
  }
  for (uint8_t i = l.setpoint_count; i < kMaxSetpoints; ++i) c.gain_scale_permille[i] = 1000;
  return c;
}

bool encode(Mapper& m, uint8_t id, const std::vector<uint8_t>& p, CanFrame& f, EncodeStatus& st) {
  CanFrame out[kMaxFramesPerMessage];
  const size_t n = m.encode(id, p.data(), p.size(), out, st);
  if (n == 1) f = out[0];
  return n == 1;
}

CanFrame commandFrame(Mapper& host, const Command& c) {
  CanFrame f;
  EncodeStatus st;
  EXPECT_TRUE(encode(host, static_cast<uint8_t>(MsgId::kCommand), payloadOf(c), f, st));
  EXPECT_EQ(st, EncodeStatus::kOk);
  return f;
}

Telemetry telemetry(uint16_t seq, uint8_t samples) {
  Telemetry t;
  t.seq = seq;
  t.cmd_seq_echo = static_cast<uint16_t>(seq + 3);
  t.mode = Mode::kLock;
  t.state_flags = state::kSessionOpen | state::kFaultLatched | state::kEstopPressed;
  t.fault_bits = fault::kEstop | fault::kTickOverrun;
  t.cmd_lost = 200;  // full 8-bit counters, unlike classic's 4-bit residues
  t.rx_errors = 17;
  for (uint8_t i = 0; i < samples; ++i) t.sample[i] = static_cast<int16_t>(-16000 + 1111 * i + seq);
  return t;
}

CanFrame telemetryFrame(Mapper& dev, const Telemetry& t) {
  CanFrame f;
  EncodeStatus st;
  EXPECT_TRUE(encode(dev, static_cast<uint8_t>(MsgId::kTelemetry), payloadOf(t), f, st));
  return f;
}

bool decode(Mapper& m, const CanFrame& f, uint8_t* payload) {
  uint8_t id;
  size_t len;
  return m.decode(f, id, payload, len);
}

/// Recompute a compact command's end-to-end CRC after a test changed a field (so that the field check, not the
/// CRC, is what rejects it).
void reseal(CanFrame& f, uint8_t setpoints) {
  const size_t body = kCompactCommandHeader + 3u * setpoints;
  const uint8_t id = static_cast<uint8_t>(MsgId::kCommand);
  const uint16_t crc = crc16(f.data, body, crc16(&id, 1));
  f.data[body] = static_cast<uint8_t>(crc);
  f.data[body + 1] = static_cast<uint8_t>(crc >> 8);
}

}  // namespace

TEST(CanFdCompact, CommandRoundTripsExactlyForEveryDeviceInOneShortFrame) {
  for (DeviceType type : kDevices) {
    const DeviceLayout& l = *layoutFor(type);
    Endpoints e(type);
    const Command c = exactCommand(l, 0xBEEF);
    const CanFrame f = commandFrame(e.host, c);
    EXPECT_TRUE(f.fd);
    EXPECT_EQ(f.id, canId(Function::kCommand, kNode));
    EXPECT_EQ(f.len, fdLength(compactCommandBytes(l.setpoint_count))) << l.name;
    EXPECT_EQ(f.len, type == DeviceType::kSeaFinger ? 12 : 24) << l.name;
    uint8_t p[64];
    ASSERT_TRUE(decode(e.dev, f, p)) << l.name;
    EXPECT_EQ(std::vector<uint8_t>(p, p + Command::kWireSize), payloadOf(c)) << l.name;
  }
}

TEST(CanFdCompact, CommandQuantisesGainsTo8PermilleAndSetpointsToTheirLsb) {
  Endpoints e(DeviceType::kGlove5);
  Command c = exactCommand(kGlove5Layout, 1);
  const uint16_t gains[5] = {333, 1000, 2000, 1999, 0};
  const uint16_t expect[5] = {336, 1000, 2000, 2000, 0};
  for (int i = 0; i < 5; ++i) c.gain_scale_permille[i] = gains[i];
  c.setpoint[0] = 1.23456f;
  uint8_t p[64];
  ASSERT_TRUE(decode(e.dev, commandFrame(e.host, c), p));
  Command d;
  ASSERT_TRUE(decodePayload(p, Command::kWireSize, d));
  for (int i = 0; i < 5; ++i) EXPECT_EQ(d.gain_scale_permille[i], expect[i]) << i;
  EXPECT_NEAR(d.setpoint[0], 1.235f, 1e-6f);
  EXPECT_EQ(d.timeout_ms, 1000);
  EXPECT_EQ(d.mode, Mode::kSetpoint);
}

TEST(CanFdCompact, CommandKeepsNonFiniteAndOutOfRangeRejectableByTheDevice) {
  Endpoints e(DeviceType::kPantograph);
  Command c = exactCommand(kPantographLayout, 2);
  c.setpoint[0] = NAN;
  c.setpoint[1] = kPantographLayout.setpoint_limit + 4e-5f;  // beyond the limit, rounds onto it: sent saturated
  c.setpoint[2] = -1e6f;
  c.timeout_ms = 0;           // carried as is: the device rejects it (bad timeout)
  uint8_t p[64];
  ASSERT_TRUE(decode(e.dev, commandFrame(e.host, c), p));
  Command d;
  ASSERT_TRUE(decodePayload(p, Command::kWireSize, d));
  EXPECT_TRUE(std::isnan(d.setpoint[0]));
  EXPECT_GT(d.setpoint[1], kPantographLayout.setpoint_limit);
  EXPECT_LT(d.setpoint[2], -kPantographLayout.setpoint_limit);
  EXPECT_EQ(d.timeout_ms, 0);
}

TEST(CanFdCompact, SenderRefusesWhatTheEncodingCannotCarryNamingTheField) {
  Endpoints e(DeviceType::kGlove5);
  struct Case {
    const char* field;
    void (*spoil)(std::vector<uint8_t>&);
  };
  const Case cases[] = {
      {"flags", [](std::vector<uint8_t>& p) { p[5] = 1; }},
      {"channel_count", [](std::vector<uint8_t>& p) { p[6] = 4; }},
      {"reserved", [](std::vector<uint8_t>& p) { p[7] = 1; }},
      {"timeout_ms", [](std::vector<uint8_t>& p) { p[2] = 0x00, p[3] = 0x04; }},  // 1024
      {"mode", [](std::vector<uint8_t>& p) { p[4] = 4; }},
      {"gain scale", [](std::vector<uint8_t>& p) { p[40 + 2 * 3] = 0xD1, p[41 + 2 * 3] = 0x07; }},  // 2001
  };
  for (const Case& k : cases) {
    auto p = payloadOf(exactCommand(kGlove5Layout, 5));
    k.spoil(p);
    CanFrame f;
    EncodeStatus st;
    EXPECT_FALSE(encode(e.host, static_cast<uint8_t>(MsgId::kCommand), p, f, st)) << k.field;
    EXPECT_EQ(st, EncodeStatus::kNotRepresentable) << k.field;
    ASSERT_NE(e.host.refusal(), nullptr) << k.field;
    EXPECT_NE(std::string(e.host.refusal()).find(k.field), std::string::npos) << e.host.refusal();
  }
  // A good command clears the reason; timeout 1023 and gain 2000 are the largest that fit.
  auto p = payloadOf(exactCommand(kGlove5Layout, 6));
  p[2] = 0xFF, p[3] = 0x03;
  CanFrame f;
  EncodeStatus st;
  EXPECT_TRUE(encode(e.host, static_cast<uint8_t>(MsgId::kCommand), p, f, st));
  EXPECT_EQ(e.host.refusal(), nullptr);

  // Telemetry fields beyond their bit widths, and either message before the device is known.
  auto t = payloadOf(telemetry(1, 25));
  t[8] = 4;
  EXPECT_FALSE(encode(e.dev, static_cast<uint8_t>(MsgId::kTelemetry), t, f, st));
  EXPECT_EQ(st, EncodeStatus::kNotRepresentable);
  t = payloadOf(telemetry(1, 25));
  t[9] = 0x10;
  EXPECT_FALSE(encode(e.dev, static_cast<uint8_t>(MsgId::kTelemetry), t, f, st));
  EXPECT_EQ(st, EncodeStatus::kNotRepresentable);
  Mapper fresh(Flavor::kFdCompact, Role::kHost, kNode);
  EXPECT_FALSE(encode(fresh, static_cast<uint8_t>(MsgId::kCommand), payloadOf(exactCommand(kGlove5Layout, 1)), f, st));
  EXPECT_EQ(st, EncodeStatus::kNoDevice);
}

TEST(CanFdCompact, TelemetryRotatesAWindowSoEverySampleArrivesAtTheDocumentedRate) {
  for (DeviceType type : kDevices) {
    const DeviceLayout& l = *layoutFor(type);
    Endpoints e(type);
    const uint8_t s = l.sample_count, k = compactWindow(s);
    EXPECT_EQ(k, 11) << l.name;
    std::vector<int> deliveries(s, 0);
    std::vector<int> last(s, -1), max_gap(s, 0);
    constexpr int kTicks = 25 * 13 * 12;
    for (int tick = 0; tick < kTicks; ++tick) {
      const Telemetry t = telemetry(static_cast<uint16_t>(65500 + tick), s);  // the sequence wraps in here
      const CanFrame f = telemetryFrame(e.dev, t);
      EXPECT_EQ(f.len, 32) << l.name;
      EXPECT_EQ(f.data[9], (tick * k) % s) << l.name;
      for (uint8_t i = 0; i < k; ++i) {
        const int idx = (f.data[9] + i) % s;
        ++deliveries[idx];
        if (last[idx] >= 0) max_gap[idx] = std::max(max_gap[idx], tick - last[idx]);
        last[idx] = tick;
      }
      uint8_t p[64];
      ASSERT_TRUE(decode(e.host, f, p)) << l.name;
      Telemetry d;
      ASSERT_TRUE(decodePayload(p, Telemetry::kWireSize, d));
      EXPECT_EQ(d.seq, t.seq);
      EXPECT_EQ(d.cmd_seq_echo, t.cmd_seq_echo);
      EXPECT_EQ(d.mode, t.mode);
      EXPECT_EQ(d.state_flags, t.state_flags);
      EXPECT_EQ(d.fault_bits, t.fault_bits);
      EXPECT_EQ(d.cmd_lost, 200);
      EXPECT_EQ(d.rx_errors, 17);
      EXPECT_EQ(d.time_us, 1000u * static_cast<uint32_t>(tick));  // derived from the sequence, 1 kHz
      // Once every window came round (⌈S/K⌉ ticks) every sample is the one sent at most ⌈S/K⌉−1 ticks ago.
      if (tick >= (s + k - 1) / k) {
        for (uint8_t i = 0; i < s; ++i) {
          const int age = tick - last[i];
          EXPECT_EQ(d.sample[i], static_cast<int16_t>(-16000 + 1111 * i + static_cast<uint16_t>(65500 + tick - age)));
        }
      }
    }
    // Rate per sample = 1 kHz · K / S: glove5 440 Hz, sea_finger 846 Hz, pantograph 917 Hz; gap ≤ ⌈S/K⌉ ticks.
    for (uint8_t i = 0; i < s; ++i) {
      EXPECT_EQ(deliveries[i], kTicks * k / s) << l.name << " sample " << int(i);
      EXPECT_LE(max_gap[i], (s + k - 1) / k) << l.name;
    }
  }
}

TEST(CanFdCompact, LostTelemetryAdvancesTheDerivedClockAndAHelloAckResetsIt) {
  Endpoints e(DeviceType::kSeaFinger);
  uint8_t p[64];
  Telemetry d;
  ASSERT_TRUE(decode(e.host, telemetryFrame(e.dev, telemetry(10, 13)), p));
  (void)telemetryFrame(e.dev, telemetry(11, 13));  // lost on the bus
  ASSERT_TRUE(decode(e.host, telemetryFrame(e.dev, telemetry(12, 13)), p));
  ASSERT_TRUE(decodePayload(p, Telemetry::kWireSize, d));
  EXPECT_EQ(d.time_us, 2000u);
  // A new session (HelloAck, carried whole) restarts the clock and forgets the old session's samples.
  HelloAck a;
  a.device_type = DeviceType::kSeaFinger;
  a.tick_rate_hz = 500;
  a.setpoint_count = 2;
  a.sample_count = 13;
  CanFrame out[kMaxFramesPerMessage];
  EncodeStatus st;
  const auto ap = payloadOf(a);
  ASSERT_EQ(e.dev.encode(static_cast<uint8_t>(MsgId::kHelloAck), ap.data(), ap.size(), out, st), 1u);
  EXPECT_EQ(out[0].len, 16);  // whole, as on kFd
  ASSERT_TRUE(decode(e.host, out[0], p));
  Mapper dev2(Flavor::kFdCompact, Role::kDevice, kNode);
  dev2.setDevice(DeviceType::kSeaFinger, 500);
  ASSERT_TRUE(decode(e.host, telemetryFrame(dev2, telemetry(500, 13)), p));
  ASSERT_TRUE(decode(e.host, telemetryFrame(dev2, telemetry(501, 13)), p));
  ASSERT_TRUE(decodePayload(p, Telemetry::kWireSize, d));
  EXPECT_EQ(d.time_us, 2000u);  // one tick at 500 Hz
}

TEST(CanFdCompact, DeviceRejectsEveryBadCommandFrameAndCountsIt) {
  Endpoints e(DeviceType::kGlove5);
  const CanFrame good = commandFrame(e.host, exactCommand(kGlove5Layout, 7));
  ASSERT_EQ(good.len, 24);  // 21 bytes used: 3 bytes of padding
  uint8_t p[64];

  CanFrame crc = good;
  crc.data[6] ^= 0x04;  // a setpoint bit
  EXPECT_FALSE(decode(e.dev, crc, p));
  EXPECT_EQ(e.dev.stats().crc, 1u);

  CanFrame whole = good;  // a whole-message (kFd) command on a compact link
  whole.len = 64;
  EXPECT_FALSE(decode(e.dev, whole, p));
  CanFrame shortf = good;
  shortf.len = 20;
  EXPECT_FALSE(decode(e.dev, shortf, p));
  CanFrame pad = good;
  pad.data[23] = 1;
  EXPECT_FALSE(decode(e.dev, pad, p));
  CanFrame classic = good;
  classic.fd = false;
  classic.len = 8;
  EXPECT_FALSE(decode(e.dev, classic, p));
  CanFrame reserved = good;
  reserved.data[3] |= 0x10;  // bit 12 of the timeout/mode word
  reseal(reserved, 5);
  EXPECT_FALSE(decode(e.dev, reserved, p));
  CanFrame gain = good;
  gain.data[4 + 10 + 2] = kCompactMaxGainCode + 1;
  reseal(gain, 5);
  EXPECT_FALSE(decode(e.dev, gain, p));
  EXPECT_EQ(e.dev.stats().bad_length, 6u);

  CanFrame other = good;
  other.id = canId(Function::kCommand, kNode + 1);
  EXPECT_FALSE(decode(e.dev, other, p));
  CanFrame part1 = good;  // a classic-only function
  part1.id = canId(Function::kCommandPart1Even, kNode);
  EXPECT_FALSE(decode(e.dev, part1, p));
  EXPECT_FALSE(decode(e.dev, telemetryFrame(e.dev, telemetry(1, 25)), p));  // wrong direction
  EXPECT_EQ(e.dev.stats().bad_id, 3u);
  EXPECT_EQ(e.dev.stats().messages_ok, 0u);
  ASSERT_TRUE(decode(e.dev, good, p));
  EXPECT_EQ(e.dev.stats().messages_ok, 1u);
}

TEST(CanFdCompact, HostRejectsEveryBadTelemetryFrameWithoutTouchingItsHeldSamples) {
  Endpoints e(DeviceType::kPantograph);
  uint8_t p[64];
  // Before the HelloAck the host does not know the layout: nothing to decode.
  Mapper fresh(Flavor::kFdCompact, Role::kHost, kNode);
  EXPECT_FALSE(decode(fresh, telemetryFrame(e.dev, telemetry(1, 12)), p));
  EXPECT_EQ(fresh.stats().bad_id, 1u);

  ASSERT_TRUE(decode(e.host, telemetryFrame(e.dev, telemetry(1, 12)), p));  // samples 0..10
  ASSERT_TRUE(decode(e.host, telemetryFrame(e.dev, telemetry(2, 12)), p));  // 11, 0..9
  const std::vector<uint8_t> before(p, p + Telemetry::kWireSize);
  CanFrame good = telemetryFrame(e.dev, telemetry(3, 12));
  for (int i = 0; i < 11; ++i) good.data[10 + 2 * i] = 0x7F;  // a recognisable window

  CanFrame len = good;
  len.len = 48;
  CanFrame bits = good;
  bits.data[6] |= 0x40;
  CanFrame first = good;
  first.data[9] = 12;  // the pantograph has 12 samples
  CanFrame classic = good;
  classic.fd = false;
  classic.len = 8;
  for (const CanFrame& bad : {len, bits, first, classic}) EXPECT_FALSE(decode(e.host, bad, p));
  EXPECT_EQ(e.host.stats().bad_length, 4u);
  CanFrame group = good;  // a classic sample-group function
  group.id = canId(Function::kTelemetryGroup0, kNode);
  EXPECT_FALSE(decode(e.host, group, p));
  EXPECT_EQ(e.host.stats().bad_id, 1u);

  // The next good frame decodes on top of the samples held before the bad ones: nothing of them was applied.
  CanFrame next = telemetryFrame(e.dev, telemetry(3, 12));
  ASSERT_TRUE(decode(e.host, next, p));
  Telemetry a, b;
  ASSERT_TRUE(decodePayload(before.data(), before.size(), a));
  ASSERT_TRUE(decodePayload(p, Telemetry::kWireSize, b));
  for (int i = 0; i < 12; ++i) {
    const bool in_window = ((i - next.data[9] + 12) % 12) < 11;
    EXPECT_EQ(b.sample[i], in_window ? telemetry(3, 12).sample[i] : a.sample[i]) << i;
    EXPECT_NE(b.sample[i], 0x7F7F);
  }
}

TEST(CanFdCompact, OtherMessagesTravelWholeAsOnCanFd) {
  Endpoints e(DeviceType::kGlove5);
  Mapper fd_dev(Flavor::kFd, Role::kDevice, kNode);
  Hello h;
  h.session_id = 0x12345678;
  ClearFaults cf;
  cf.session_id = 7;
  for (auto [id, p] : {std::pair{static_cast<uint8_t>(MsgId::kHello), payloadOf(h)},
                       std::pair{static_cast<uint8_t>(MsgId::kClearFaults), payloadOf(cf)}}) {
    CanFrame f, g;
    EncodeStatus st;
    ASSERT_TRUE(encode(e.host, id, p, f, st));
    Mapper fd_host(Flavor::kFd, Role::kHost, kNode);
    ASSERT_TRUE(encode(fd_host, id, p, g, st));
    EXPECT_EQ(f.len, g.len);
    EXPECT_EQ(std::memcmp(f.data, g.data, f.len), 0);
    uint8_t out[64];
    ASSERT_TRUE(decode(e.dev, f, out));
    EXPECT_EQ(std::vector<uint8_t>(out, out + p.size()), p);
  }
}

TEST(CanBusLoad, CompactFdBudgetOfEveryDeviceIsWithinTwentyPercentAt1Over5Mbps) {
  const auto b = phalanx::host::canBudget(1000.0, 1e6);
  for (const char* dev : {"glove5", "sea_finger", "pantograph"}) {
    const auto& c = b["devices"][dev]["fd_compact_5x_data_rate"];
    const double load = c["load_pct_worst_stuffing"].get<double>();
    EXPECT_LE(load, 20.0) << dev;
    EXPECT_GT(load, 15.0) << dev;  // two frames with data, not an empty telemetry
    EXPECT_EQ(c["frames_per_tick"].get<double>(), 2.0) << dev;
    // The whole-message mapping stays available and is what does not fit.
    EXPECT_GT(b["devices"][dev]["fd_5x_data_rate"]["load_pct_worst_stuffing"].get<double>(), 30.0) << dev;
  }
  EXPECT_EQ(b["devices"]["glove5"]["fd_compact_5x_data_rate"]["data_bytes_per_tick"].get<double>(), 24.0 + 32.0);
  EXPECT_EQ(b["devices"]["sea_finger"]["fd_compact_5x_data_rate"]["data_bytes_per_tick"].get<double>(), 12.0 + 32.0);
  EXPECT_NEAR(b["devices"]["glove5"]["fd_compact_sample_rate_hz"].get<double>(), 440.0, 1e-9);
}
