#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "phalanx/protocol/codec.h"
#include "phalanx/protocol/devices.h"

using namespace phalanx::protocol;

namespace {

// Feed a byte vector to a fresh decoder and collect the frames it reports.
struct Collected {
  std::vector<std::pair<uint8_t, std::vector<uint8_t>>> frames;
  DecodeStats stats;
};
Collected feed(const std::vector<uint8_t>& bytes) {
  StreamDecoder d;
  Collected c;
  for (uint8_t b : bytes) {
    if (d.push(b)) c.frames.emplace_back(d.frame().id, std::vector<uint8_t>(d.frame().payload, d.frame().payload + d.frame().len));
  }
  c.stats = d.stats();
  return c;
}

template <class Msg>
std::vector<uint8_t> frameOf(const Msg& m) {
  std::vector<uint8_t> out(kMaxEncodedFrame);
  out.resize(encodeFrame(m, out.data()));
  return out;
}

template <class Msg>
Msg roundTrip(const Msg& m) {
  const Collected c = feed(frameOf(m));
  EXPECT_EQ(c.frames.size(), 1u);
  Msg back{};
  if (c.frames.size() == 1) {
    EXPECT_EQ(c.frames[0].first, static_cast<uint8_t>(Msg::kId));
    EXPECT_TRUE(decodePayload(c.frames[0].second.data(), c.frames[0].second.size(), back));
  }
  return back;
}

}  // namespace

TEST(Crc16, MatchesTheCcittFalseCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(crc16(reinterpret_cast<const uint8_t*>(s), 9), 0x29B1);
}

TEST(Cobs, EncodesZerosAwayAndDecodesBack) {
  std::mt19937 rng(7);
  for (size_t len : {1u, 2u, 10u, 253u, 254u, 255u, 300u}) {
    std::vector<uint8_t> src(len);
    for (auto& b : src) b = static_cast<uint8_t>(rng() % 4 == 0 ? 0 : rng());
    std::vector<uint8_t> enc(len + len / 254 + 2);
    const size_t n = cobsEncode(src.data(), len, enc.data());
    for (size_t i = 0; i < n; ++i) EXPECT_NE(enc[i], 0) << "zero byte inside an encoded frame";
    std::vector<uint8_t> dec(len + 8);
    ASSERT_EQ(cobsDecode(enc.data(), n, dec.data(), dec.size()), len);
    EXPECT_EQ(std::memcmp(dec.data(), src.data(), len), 0);
  }
}

TEST(Cobs, KnownVectorFromTheCobsPaper) {
  // 0x11 0x22 0x00 0x33 → 0x03 0x11 0x22 0x02 0x33
  const uint8_t src[] = {0x11, 0x22, 0x00, 0x33};
  uint8_t enc[8];
  ASSERT_EQ(cobsEncode(src, 4, enc), 5u);
  const uint8_t want[] = {0x03, 0x11, 0x22, 0x02, 0x33};
  EXPECT_EQ(std::memcmp(enc, want, 5), 0);
}

TEST(Messages, HelloRoundTripsEveryField) {
  Hello h;
  h.expected_device = DeviceType::kSeaFinger;
  h.session_id = 0xDEADBEEF;
  const Hello b = roundTrip(h);
  EXPECT_EQ(b.protocol_version, kProtocolVersion);
  EXPECT_EQ(b.expected_device, DeviceType::kSeaFinger);
  EXPECT_EQ(b.session_id, 0xDEADBEEFu);
}

TEST(Messages, HelloAckRoundTripsEveryField) {
  HelloAck a;
  a.device_type = DeviceType::kGlove5;
  a.status = HandshakeStatus::kDeviceMismatch;
  a.session_id = 42;
  a.firmware_build_id = 0x01020304;
  a.tick_rate_hz = 1000;
  a.setpoint_count = 5;
  a.sample_count = 25;
  const HelloAck b = roundTrip(a);
  EXPECT_EQ(b.device_type, DeviceType::kGlove5);
  EXPECT_EQ(b.status, HandshakeStatus::kDeviceMismatch);
  EXPECT_EQ(b.session_id, 42u);
  EXPECT_EQ(b.firmware_build_id, 0x01020304u);
  EXPECT_EQ(b.tick_rate_hz, 1000);
  EXPECT_EQ(b.setpoint_count, 5);
  EXPECT_EQ(b.sample_count, 25);
}

TEST(Messages, CommandRoundTripsEveryField) {
  Command c;
  c.seq = 65535;
  c.timeout_ms = 20;
  c.mode = Mode::kSetpoint;
  c.channel_count = 5;
  for (int i = 0; i < 8; ++i) {
    c.setpoint[i] = -1.5f + 0.25f * static_cast<float>(i);
    c.gain_scale_permille[i] = static_cast<uint16_t>(900 + i);
  }
  const Command b = roundTrip(c);
  EXPECT_EQ(b.seq, 65535);
  EXPECT_EQ(b.timeout_ms, 20);
  EXPECT_EQ(b.mode, Mode::kSetpoint);
  EXPECT_EQ(b.channel_count, 5);
  for (int i = 0; i < 8; ++i) {
    EXPECT_EQ(b.setpoint[i], c.setpoint[i]);
    EXPECT_EQ(b.gain_scale_permille[i], c.gain_scale_permille[i]);
  }
}

TEST(Messages, TelemetryRoundTripsEveryField) {
  Telemetry t;
  t.time_us = 0xFFFFFFF0u;
  t.seq = 77;
  t.cmd_seq_echo = 76;
  t.mode = Mode::kLock;
  t.state_flags = 0x0F;
  t.fault_bits = fault::kCommandTimeout | fault::kSensorStuck;
  t.cmd_lost = 3;
  t.rx_errors = 250;
  for (int i = 0; i < 25; ++i) t.sample[i] = static_cast<int16_t>(i * 1000 - 12000);
  const Telemetry b = roundTrip(t);
  EXPECT_EQ(b.time_us, t.time_us);
  EXPECT_EQ(b.seq, 77);
  EXPECT_EQ(b.cmd_seq_echo, 76);
  EXPECT_EQ(b.mode, Mode::kLock);
  EXPECT_EQ(b.state_flags, 0x0F);
  EXPECT_EQ(b.fault_bits, t.fault_bits);
  EXPECT_EQ(b.cmd_lost, 3);
  EXPECT_EQ(b.rx_errors, 250);
  for (int i = 0; i < 25; ++i) EXPECT_EQ(b.sample[i], t.sample[i]);
}

TEST(Messages, EventClearParamMessagesRoundTrip) {
  Event e;
  e.time_us = 123;
  e.code = EventCode::kCommandRejected;
  e.channel = 2;
  e.detail = static_cast<uint8_t>(RejectReason::kNonFinite);
  e.value = 3.5f;
  const Event eb = roundTrip(e);
  EXPECT_EQ(eb.code, EventCode::kCommandRejected);
  EXPECT_EQ(eb.channel, 2);
  EXPECT_EQ(eb.detail, e.detail);
  EXPECT_EQ(eb.value, 3.5f);
  ClearFaults c;
  c.session_id = 99;
  EXPECT_EQ(roundTrip(c).session_id, 99u);
  ParamGet g;
  g.param_id = 0x101;
  EXPECT_EQ(roundTrip(g).param_id, 0x101);
  ParamSet s;
  s.param_id = 0x102;
  s.value = -2.0f;
  EXPECT_EQ(roundTrip(s).value, -2.0f);
  ParamValue v;
  v.param_id = 7;
  v.status = ParamStatus::kReadOnly;
  v.value = 1.0f;
  EXPECT_EQ(roundTrip(v).status, ParamStatus::kReadOnly);
}

TEST(Messages, AParamValueCarriesTheFailedStatusAndRefusesAnUnknownOne) {
  ParamValue v;
  v.param_id = 0x0010;
  v.status = ParamStatus::kFailed;  // a settings save whose flash write failed (docs/params.md)
  EXPECT_EQ(roundTrip(v).status, ParamStatus::kFailed);
  uint8_t p[ParamValue::kWireSize];
  encodePayload(v, p);
  p[2] = static_cast<uint8_t>(ParamStatus::kFailed) + 1;
  ParamValue out;
  EXPECT_FALSE(decodePayload(p, sizeof p, out));
}

TEST(Messages, WireLayoutIsLittleEndianAtTheDocumentedOffsets) {
  Command c;
  c.seq = 0x0102;
  c.timeout_ms = 0x0304;
  c.mode = Mode::kSetpoint;
  c.channel_count = 5;
  c.setpoint[0] = 1.0f;  // 0x3F800000
  uint8_t p[Command::kWireSize];
  encodePayload(c, p);
  EXPECT_EQ(p[0], 0x02);
  EXPECT_EQ(p[1], 0x01);
  EXPECT_EQ(p[2], 0x04);
  EXPECT_EQ(p[3], 0x03);
  EXPECT_EQ(p[4], 2);
  EXPECT_EQ(p[6], 5);
  EXPECT_EQ(p[8], 0x00);
  EXPECT_EQ(p[11], 0x3F);
  EXPECT_EQ(p[10], 0x80);
}

TEST(Decoder, RejectsACorruptedFrameAndCountsACrcError) {
  Telemetry t;
  t.seq = 5;
  auto bytes = frameOf(t);
  bytes[10] ^= 0x40;  // one bit flipped inside the frame (never produces a 0x00 here)
  ASSERT_NE(bytes[10], 0);
  const Collected c = feed(bytes);
  EXPECT_TRUE(c.frames.empty());
  EXPECT_EQ(c.stats.crc_errors + c.stats.framing_errors, 1u);
}

TEST(Decoder, RejectsTruncatedFramesAndResynchronisesOnTheNextDelimiter) {
  Telemetry t;
  auto good = frameOf(t);
  std::vector<uint8_t> bytes(good.begin(), good.begin() + 20);
  bytes.push_back(0);  // truncated frame, then delimiter
  bytes.insert(bytes.end(), good.begin(), good.end());
  const Collected c = feed(bytes);
  EXPECT_EQ(c.frames.size(), 1u);
  EXPECT_EQ(c.stats.total_rejected(), 1u);
}

TEST(Decoder, RejectsAnUnknownMessageId) {
  uint8_t payload[4] = {1, 2, 3, 4};
  std::vector<uint8_t> out(kMaxEncodedFrame);
  out.resize(encodeFrameRaw(0x7E, payload, 4, out.data()));
  const Collected c = feed(out);
  EXPECT_TRUE(c.frames.empty());
  EXPECT_EQ(c.stats.unknown_id, 1u);
}

TEST(Decoder, RejectsAKnownIdWithTheWrongLength) {
  uint8_t payload[10] = {};
  std::vector<uint8_t> out(kMaxEncodedFrame);
  out.resize(encodeFrameRaw(static_cast<uint8_t>(MsgId::kCommand), payload, 10, out.data()));
  const Collected c = feed(out);
  EXPECT_TRUE(c.frames.empty());
  EXPECT_EQ(c.stats.bad_length, 1u);
}

TEST(Decoder, DiscardsAnOversizedFrameWithoutOverflowing) {
  std::vector<uint8_t> bytes(5000, 0x55);
  bytes.push_back(0);
  Telemetry t;
  auto good = frameOf(t);
  bytes.insert(bytes.end(), good.begin(), good.end());
  const Collected c = feed(bytes);
  EXPECT_EQ(c.frames.size(), 1u);
  EXPECT_EQ(c.stats.framing_errors, 1u);
}

TEST(Decoder, RejectsOutOfRangeEnumsInsteadOfCastingThem) {
  Command c;
  uint8_t p[Command::kWireSize];
  encodePayload(c, p);
  p[4] = 17;  // mode
  Command back;
  EXPECT_FALSE(decodePayload(p, sizeof p, back));
}

TEST(Decoder, SurvivesRandomGarbageAndStillDecodesTheFramesAfterIt) {
  std::mt19937 rng(1234);
  std::vector<uint8_t> bytes;
  for (int i = 0; i < 100000; ++i) bytes.push_back(static_cast<uint8_t>(rng()));
  bytes.push_back(0);
  Telemetry t;
  t.seq = 9;
  for (int i = 0; i < 3; ++i) {
    auto good = frameOf(t);
    bytes.insert(bytes.end(), good.begin(), good.end());
  }
  const Collected c = feed(bytes);
  ASSERT_GE(c.frames.size(), 3u);
  EXPECT_GT(c.stats.total_rejected(), 100u);
}

TEST(Samples, EncodeWithTheKindsScaleAndSaturate) {
  EXPECT_EQ(encodeSample(1.0f, SampleKind::kAngle), 10000);
  EXPECT_EQ(encodeSample(-0.5f, SampleKind::kForce), -500);
  EXPECT_EQ(encodeSample(100.0f, SampleKind::kForce), 32767);
  EXPECT_EQ(encodeSample(NAN, SampleKind::kForce), 0);
  EXPECT_NEAR(decodeSample(encodeSample(0.12345f, SampleKind::kAngle), SampleKind::kAngle), 0.12345f, 0.5e-4f);
}

TEST(Layouts, FitTheMessageArraysAndNameTheirDevices) {
  for (DeviceType t : {DeviceType::kGlove5, DeviceType::kSeaFinger, DeviceType::kPantograph}) {
    const DeviceLayout* l = layoutFor(t);
    ASSERT_NE(l, nullptr);
    EXPECT_EQ(l->type, t);
    EXPECT_LE(l->sample_count, kMaxSamples);
    EXPECT_LE(l->setpoint_count, kMaxSetpoints);
  }
  EXPECT_EQ(layoutFor(DeviceType::kAny), nullptr);
}

// encodeSample rounds without std::lround (roundHalfAway): the same integer as lround for every half of the
// sample range and the floats either side of it, for random values, and the encoded samples likewise.
TEST(SampleEncoding, RoundsExactlyAsLround) {
  size_t checked = 0;
  for (int n = -70000; n <= 70000; ++n) {
    const float half = static_cast<float>(n) + 0.5f;
    for (const float x : {std::nextafter(half, -1e9f), half, std::nextafter(half, 1e9f), static_cast<float>(n)}) {
      ASSERT_EQ(roundHalfAway(x), std::lround(x)) << x;
      ++checked;
    }
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> any(-40.0f, 40.0f);
  for (int i = 0; i < 200000; ++i) {
    const float v = any(rng);
    for (const SampleKind k : {SampleKind::kAngle, SampleKind::kForce, SampleKind::kDuty}) {
      const float lsb = v / sampleScale(k);
      const long want = lsb >= 32767.0f ? 32767 : lsb <= -32767.0f ? -32767 : std::lround(lsb);
      ASSERT_EQ(encodeSample(v, k), want) << v;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 4u * 140001u + 600000u);
}
