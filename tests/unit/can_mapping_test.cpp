// The protocol's CAN mapping (phalanx/protocol/can.h): identifiers, CAN-FD whole-message frames with the
// end-to-end CRC, classic CAN compact encodings and their reassembly, rejection of bad frames, and the bus-time
// model behind the bus-load budget in docs/protocol.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "phalanx/host/can_budget.h"
#include "phalanx/protocol/can.h"
#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;
using namespace phalanx::protocol::can;

namespace {

constexpr uint8_t kNode = 5;

struct Msg {
  uint8_t id = 0;
  std::vector<uint8_t> payload;
};

template <class M>
std::vector<uint8_t> payloadOf(const M& m) {
  std::vector<uint8_t> p(M::kWireSize);
  encodePayload(m, p.data());
  return p;
}

template <class M>
std::vector<CanFrame> encodeOk(Mapper& tx, const M& m) {
  CanFrame out[kMaxFramesPerMessage];
  EncodeStatus st;
  const auto p = payloadOf(m);
  const size_t n = tx.encode(static_cast<uint8_t>(M::kId), p.data(), p.size(), out, st);
  EXPECT_EQ(st, EncodeStatus::kOk);
  return std::vector<CanFrame>(out, out + n);
}

std::vector<Msg> decodeAll(Mapper& rx, const std::vector<CanFrame>& frames) {
  std::vector<Msg> out;
  for (const CanFrame& f : frames) {
    uint8_t id;
    uint8_t payload[64];
    size_t len;
    if (rx.decode(f, id, payload, len)) out.push_back({id, std::vector<uint8_t>(payload, payload + len)});
  }
  return out;
}

Command glove5Command(uint16_t seq) {
  Command c;
  c.seq = seq;
  c.timeout_ms = 20;
  c.mode = Mode::kSetpoint;
  c.channel_count = 5;
  for (int i = 0; i < 5; ++i) {
    c.setpoint[i] = -4.0f + 1.5f * static_cast<float>(i);
    c.gain_scale_permille[i] = 1000;
  }
  return c;
}

Telemetry telemetry(uint16_t seq, uint8_t samples) {
  Telemetry t;
  t.time_us = 123456;
  t.seq = seq;
  t.cmd_seq_echo = static_cast<uint16_t>(seq + 7);
  t.mode = Mode::kSetpoint;
  t.state_flags = state::kSessionOpen | state::kOutputsActive;
  t.fault_bits = fault::kForceLimit;
  t.cmd_lost = 3;
  t.rx_errors = 2;
  for (uint8_t i = 0; i < samples; ++i) t.sample[i] = static_cast<int16_t>(100 * i - 1000 + seq);
  return t;
}

}  // namespace

TEST(CanMapping, IdentifierCarriesFunctionAndNodeIn11Bits) {
  EXPECT_EQ(canId(Function::kCommand, 5), 0x45u);
  EXPECT_EQ(canId(Function::kParamValue, 63), (0x13u << 6) | 63u);
  EXPECT_LE(canId(Function::kParamValue, 63), 0x7FFu);
  EXPECT_EQ(nodeOf(0x45), 5);
  EXPECT_EQ(functionOf(0x45), 1);
  // Commands win arbitration against telemetry of any node.
  EXPECT_LT(canId(Function::kCommand, 63), canId(Function::kTelemetry, 1));
}

TEST(CanMapping, FdLengthsRoundUpToValidDataLengths) {
  EXPECT_EQ(fdLength(8), 8);
  EXPECT_EQ(fdLength(9), 12);
  EXPECT_EQ(fdLength(10), 12);
  EXPECT_EQ(fdLength(18), 20);
  EXPECT_EQ(fdLength(58), 64);
  EXPECT_EQ(fdLength(64), 64);
}

TEST(CanMapping, FdCarriesEveryMessageInOneFrameBothWays) {
  Mapper host(Flavor::kFd, Role::kHost, kNode), dev(Flavor::kFd, Role::kDevice, kNode);
  const Command c = glove5Command(42);
  const auto frames = encodeOk(host, c);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_TRUE(frames[0].fd);
  EXPECT_EQ(frames[0].len, 64);  // 56 payload + 2 CRC, padded
  const auto got = decodeAll(dev, frames);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, static_cast<uint8_t>(MsgId::kCommand));
  EXPECT_EQ(got[0].payload, payloadOf(c));

  const Telemetry t = telemetry(9, 25);
  const auto tf = encodeOk(dev, t);
  ASSERT_EQ(tf.size(), 1u);
  EXPECT_EQ(tf[0].len, 64);  // device → host: no CRC (the frame is full)
  const auto back = decodeAll(host, tf);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].payload, payloadOf(t));
}

TEST(CanMapping, FdRejectsBadCrcLengthPaddingIdNodeAndDirection) {
  Mapper host(Flavor::kFd, Role::kHost, kNode), dev(Flavor::kFd, Role::kDevice, kNode);
  const CanFrame good = encodeOk(host, glove5Command(1))[0];
  uint8_t id;
  uint8_t p[64];
  size_t len;

  CanFrame crc = good;
  crc.data[10] ^= 0x01;  // a setpoint bit flips: the end-to-end CRC catches it
  EXPECT_FALSE(dev.decode(crc, id, p, len));
  EXPECT_EQ(dev.stats().crc, 1u);

  CanFrame shortf = good;
  shortf.len = 48;
  EXPECT_FALSE(dev.decode(shortf, id, p, len));
  CanFrame pad = good;
  pad.data[63] = 0xAA;
  EXPECT_FALSE(dev.decode(pad, id, p, len));
  CanFrame classic = good;
  classic.fd = false;
  classic.len = 8;
  EXPECT_FALSE(dev.decode(classic, id, p, len));
  EXPECT_EQ(dev.stats().bad_length, 3u);

  CanFrame unknown = good;
  unknown.id = (0x1Fu << 6) | kNode;
  EXPECT_FALSE(dev.decode(unknown, id, p, len));
  CanFrame other = good;
  other.id = canId(Function::kCommand, kNode + 1);
  EXPECT_FALSE(dev.decode(other, id, p, len));
  CanFrame ext = good;
  ext.extended = true;
  EXPECT_FALSE(dev.decode(ext, id, p, len));
  // The device never accepts device → host messages (a looped-back or misaddressed telemetry frame).
  const CanFrame tel = encodeOk(dev, telemetry(1, 25))[0];
  Mapper dev2(Flavor::kFd, Role::kDevice, kNode);
  EXPECT_FALSE(dev2.decode(tel, id, p, len));
  EXPECT_EQ(dev.stats().bad_id, 3u);
  EXPECT_EQ(dev2.stats().bad_id, 1u);
  EXPECT_EQ(dev.stats().messages_ok, 0u);
  EXPECT_TRUE(dev.decode(good, id, p, len));
}

TEST(CanMapping, EncoderRefusesMessagesOfTheOtherDirection) {
  Mapper dev(Flavor::kFd, Role::kDevice, kNode);
  CanFrame out[kMaxFramesPerMessage];
  EncodeStatus st;
  const auto p = payloadOf(glove5Command(1));
  EXPECT_EQ(dev.encode(static_cast<uint8_t>(MsgId::kCommand), p.data(), p.size(), out, st), 0u);
  EXPECT_EQ(st, EncodeStatus::kWrongDirection);
  EXPECT_EQ(dev.encode(0x77, p.data(), p.size(), out, st), 0u);
  EXPECT_EQ(st, EncodeStatus::kUnknownMessage);
}

TEST(CanMapping, ClassicHandshakeTeachesTheHostTheDevice) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  dev.setDevice(DeviceType::kGlove5, 1000);
  HelloAck a;
  a.device_type = DeviceType::kGlove5;
  a.session_id = 0xCAFEF00D;
  a.firmware_build_id = 77;
  a.tick_rate_hz = 1000;
  a.setpoint_count = 5;
  a.sample_count = 25;
  const auto frames = encodeOk(dev, a);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(host.layout(), nullptr);
  const auto got = decodeAll(host, frames);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].payload, payloadOf(a));
  ASSERT_NE(host.layout(), nullptr);
  EXPECT_EQ(host.layout()->type, DeviceType::kGlove5);
}

TEST(CanMapping, ClassicCommandTravelsCompactAndReassembles) {
  for (DeviceType type : {DeviceType::kGlove5, DeviceType::kSeaFinger, DeviceType::kPantograph}) {
    Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
    host.setDevice(type, 1000);
    dev.setDevice(type, 1000);
    const DeviceLayout& l = *layoutFor(type);
    Command c;
    c.seq = 301;
    c.timeout_ms = 20;
    c.mode = Mode::kSetpoint;
    c.channel_count = l.setpoint_count;
    for (uint8_t i = 0; i < l.setpoint_count; ++i) {
      c.setpoint[i] = l.setpoint_limit * (static_cast<float>(i) / l.setpoint_count - 0.45f);
      c.gain_scale_permille[i] = 1000;
    }
    const auto frames = encodeOk(host, c);
    EXPECT_EQ(frames.size(), l.setpoint_count > 2 ? 2u : 1u) << l.name;
    for (const CanFrame& f : frames) EXPECT_LE(f.len, 8);
    const auto got = decodeAll(dev, frames);
    ASSERT_EQ(got.size(), 1u) << l.name;
    Command d;
    ASSERT_TRUE(decodePayload(got[0].payload.data(), got[0].payload.size(), d));
    EXPECT_EQ(d.seq, c.seq);
    EXPECT_EQ(d.mode, c.mode);
    EXPECT_EQ(d.timeout_ms, c.timeout_ms);
    EXPECT_EQ(d.channel_count, c.channel_count);
    const float lsb = sampleScale(classicProfile(type).setpoint_kind);
    for (uint8_t i = 0; i < l.setpoint_count; ++i) {
      EXPECT_NEAR(d.setpoint[i], c.setpoint[i], 0.5f * lsb + 1e-6f) << l.name << " channel " << int(i);
      EXPECT_EQ(d.gain_scale_permille[i], 1000);
    }
  }
}

TEST(CanMapping, ClassicCommandKeepsNonFiniteAndOutOfRangeRejectableByTheDevice) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  host.setDevice(DeviceType::kGlove5, 1000);
  dev.setDevice(DeviceType::kGlove5, 1000);
  Command c = glove5Command(2);
  c.setpoint[1] = NAN;
  c.setpoint[3] = 1e6f;
  const auto got = decodeAll(dev, encodeOk(host, c));
  ASSERT_EQ(got.size(), 1u);
  Command d;
  ASSERT_TRUE(decodePayload(got[0].payload.data(), got[0].payload.size(), d));
  EXPECT_TRUE(std::isnan(d.setpoint[1]));
  EXPECT_GT(std::fabs(d.setpoint[3]), kGlove5Layout.setpoint_limit);
}

TEST(CanMapping, ClassicRefusesWhatItCannotCarry) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode);
  CanFrame out[kMaxFramesPerMessage];
  EncodeStatus st;
  auto p = payloadOf(glove5Command(1));
  EXPECT_EQ(host.encode(static_cast<uint8_t>(MsgId::kCommand), p.data(), p.size(), out, st), 0u);
  EXPECT_EQ(st, EncodeStatus::kNoDevice);
  host.setDevice(DeviceType::kGlove5, 1000);
  Command gains = glove5Command(1);
  gains.gain_scale_permille[2] = 500;
  p = payloadOf(gains);
  EXPECT_EQ(host.encode(static_cast<uint8_t>(MsgId::kCommand), p.data(), p.size(), out, st), 0u);
  EXPECT_EQ(st, EncodeStatus::kNotRepresentable);
  Command slow = glove5Command(1);
  slow.timeout_ms = 500;
  p = payloadOf(slow);
  EXPECT_EQ(host.encode(static_cast<uint8_t>(MsgId::kCommand), p.data(), p.size(), out, st), 0u);
  EXPECT_EQ(st, EncodeStatus::kNotRepresentable);
}

TEST(CanMapping, ClassicCommandPartsOutOfOrderAreRejectedNotMixed) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  host.setDevice(DeviceType::kGlove5, 1000);
  dev.setDevice(DeviceType::kGlove5, 1000);
  const auto a = encodeOk(host, glove5Command(10));
  const auto b = encodeOk(host, glove5Command(11));
  // Part 0 of 10 lost, part 1 of 10 arrives alone; then part 0 of 11 followed by part 1 of 10 (wrong parity).
  EXPECT_TRUE(decodeAll(dev, {a[1]}).empty());
  EXPECT_TRUE(decodeAll(dev, {b[0], a[1]}).empty());
  EXPECT_EQ(dev.stats().sequence, 2u);
  const auto ok = decodeAll(dev, b);
  ASSERT_EQ(ok.size(), 1u);
}

TEST(CanMapping, ClassicTelemetryMultiplexesSampleGroupsWithinTheBudget) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  host.setDevice(DeviceType::kSeaFinger, 1000);
  dev.setDevice(DeviceType::kSeaFinger, 1000);
  // sea_finger: groups of 4 samples, 2 groups per tick, rotating: after two ticks every sample has arrived.
  const uint8_t n = phalanx::protocol::kSeaFingerLayout.sample_count;
  const int groups = (n + 3) / 4;
  ASSERT_GE(groups, 3);
  ASSERT_LE(groups, 4);
  std::vector<Msg> got;
  for (uint16_t seq = 100; seq < 102; ++seq) {
    const auto frames = encodeOk(dev, telemetry(seq, n));
    EXPECT_EQ(frames.size(), 3u);
    EXPECT_EQ(functionOf(frames.back().id), static_cast<uint8_t>(Function::kTelemetry));
    const auto m = decodeAll(host, frames);
    ASSERT_EQ(m.size(), 1u);
    got.push_back(m[0]);
  }
  Telemetry t;
  ASSERT_TRUE(decodePayload(got[1].payload.data(), got[1].payload.size(), t));
  const Telemetry sent = telemetry(101, n);
  const Telemetry before = telemetry(100, n);
  EXPECT_EQ(t.seq, 101);
  EXPECT_EQ(t.cmd_seq_echo, sent.cmd_seq_echo);
  EXPECT_EQ(t.mode, sent.mode);
  EXPECT_EQ(t.state_flags, sent.state_flags);
  EXPECT_EQ(t.fault_bits, sent.fault_bits);
  EXPECT_EQ(t.time_us, 1000u);  // derived: one tick after the first status frame
  // Tick 100 sent groups 0 and 1; tick 101 sent groups 2 and 3 (mod the group count): each sample holds the
  // value of the newest tick that carried its group.
  for (int i = 0; i < n; ++i) {
    const int g = i / 4;
    const bool in_tick_101 = g == 2 % groups || g == 3 % groups;
    EXPECT_EQ(t.sample[i], in_tick_101 ? sent.sample[i] : before.sample[i]) << "sample " << i;
  }
}

TEST(CanMapping, ClassicCountersSurviveTheirFourBitResidues) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  host.setDevice(DeviceType::kPantograph, 1000);
  dev.setDevice(DeviceType::kPantograph, 1000);
  uint8_t rx = 250;
  uint8_t prev_rx = 0, prev_lost = 0;
  for (uint16_t seq = 0; seq < 40; ++seq) {
    Telemetry t = telemetry(seq, 12);
    t.rx_errors = rx;
    t.cmd_lost = static_cast<uint8_t>(seq / 3);
    const auto m = decodeAll(host, encodeOk(dev, t));
    ASSERT_EQ(m.size(), 1u);
    Telemetry d;
    ASSERT_TRUE(decodePayload(m[0].payload.data(), m[0].payload.size(), d));
    // The host only uses differences of these counters: those must be exact.
    if (seq > 0) {
      EXPECT_EQ(static_cast<uint8_t>(d.rx_errors - prev_rx), 5) << seq;
      EXPECT_EQ(static_cast<uint8_t>(d.cmd_lost - prev_lost), seq % 3 == 0 ? 1 : 0) << seq;
    }
    prev_rx = d.rx_errors;
    prev_lost = d.cmd_lost;
    rx = static_cast<uint8_t>(rx + 5);
  }
}

TEST(CanMapping, ClassicRejectsBadLengthsAndUnknownGroups) {
  Mapper host(Flavor::kClassic, Role::kHost, kNode), dev(Flavor::kClassic, Role::kDevice, kNode);
  host.setDevice(DeviceType::kSeaFinger, 1000);
  dev.setDevice(DeviceType::kSeaFinger, 1000);
  auto frames = encodeOk(dev, telemetry(1, 11));
  frames.back().len = 7;
  EXPECT_TRUE(decodeAll(host, frames).empty());
  EXPECT_EQ(host.stats().bad_length, 1u);
  CanFrame g5;
  g5.id = canId(static_cast<Function>(static_cast<uint8_t>(Function::kTelemetryGroup0) + 5), kNode);
  g5.len = 8;
  EXPECT_TRUE(decodeAll(host, {g5}).empty());  // sea_finger has 3 groups
  EXPECT_EQ(host.stats().bad_id, 1u);
}

TEST(CanBusTime, ClassicFrameBitsMatchTheStandardFormula) {
  // Davis et al. 2007, eq. (1): 8-byte 11-bit frame is 111 bits without stuffing, 135 worst case.
  EXPECT_EQ(classicFrameBits(8, false), 111u);
  EXPECT_EQ(classicFrameBits(8, true), 135u);
  EXPECT_EQ(classicFrameBits(0, true), 55u);
  CanFrame f;
  f.len = 8;
  EXPECT_NEAR(frameTimeS(f, 1e6, 1e6, true), 135e-6, 1e-12);
}

TEST(CanBusTime, FdFrameIsShorterWithBitRateSwitch) {
  CanFrame f;
  f.fd = true;
  f.len = 64;
  const double slow = frameTimeS(f, 1e6, 1e6, true);
  const double fast = frameTimeS(f, 1e6, 5e6, true);
  // 64 bytes: 30 + 4 arbitration/tail bits at 1 Mbit/s; 5+512+stuff+4+21+7 data-phase bits.
  EXPECT_GT(slow, 600e-6);
  EXPECT_LT(fast, slow / 3.0);
  EXPECT_GT(fast, (34.0 / 1e6) + (549.0 / 5e6));
}


// The classic profiles (sample groups per tick) are chosen so that every device stays within 60 % of a 1 Mbit/s
// bus at 1 kHz with worst-case bit stuffing (docs/protocol.md "Bus load"); a change to the mapping that breaks
// the budget fails here.
TEST(CanBusLoad, ClassicBudgetOfEveryDeviceIsWithinSixtyPercent) {
  const auto b = phalanx::host::canBudget(1000.0, 1e6);
  for (const char* dev : {"glove5", "sea_finger", "pantograph"}) {
    const double load = b["devices"][dev]["classic"]["load_pct_worst_stuffing"].get<double>();
    EXPECT_LE(load, 60.0) << dev;
    EXPECT_GT(load, 40.0) << dev;  // and the sample groups do go out (not an empty telemetry)
    EXPECT_EQ(b["devices"][dev]["classic"]["frames_per_tick"].get<double>(), 4.0) << dev;
  }
}
