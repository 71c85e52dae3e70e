// The single-pass framing (issue 20) against the framing it replaced, kept here as the reference: the body copied
// into a scratch buffer, a byte-at-a-time table CRC, a separate COBS pass; decoding byte by byte into a raw buffer,
// COBS-decoded into a second one. The new encoder must produce the same bytes for every payload, and the new
// decoder (push() and feed() with any chunking) the same frames and the same counters for every byte stream.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <utility>
#include <vector>

#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;

namespace {

uint16_t refCrc16(const uint8_t* data, size_t len, uint16_t crc = 0xFFFF) {
  for (size_t i = 0; i < len; ++i) {  // bit by bit: independent of any table
    crc = static_cast<uint16_t>(crc ^ (data[i] << 8));
    for (int b = 0; b < 8; ++b) crc = static_cast<uint16_t>((crc & 0x8000u) ? ((crc << 1) ^ 0x1021u) : (crc << 1));
  }
  return crc;
}

size_t refCobsEncode(const uint8_t* src, size_t len, uint8_t* dst) {
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

size_t refCobsDecode(const uint8_t* src, size_t len, uint8_t* dst, size_t dst_cap) {
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

std::vector<uint8_t> refEncodeFrame(uint8_t id, const uint8_t* payload, size_t len) {
  uint8_t body[kMaxFrameBody];
  body[0] = id;
  if (len > 0) std::memcpy(body + 1, payload, len);  // an empty payload may come with a null pointer
  const uint16_t crc = refCrc16(body, 1 + len);
  body[1 + len] = static_cast<uint8_t>(crc);
  body[2 + len] = static_cast<uint8_t>(crc >> 8);
  std::vector<uint8_t> out(kMaxEncodedFrame);
  const size_t n = refCobsEncode(body, len + 3, out.data());
  out[n] = 0;
  out.resize(n + 1);
  return out;
}

// The byte-at-a-time stream decoder as it was before issue 20 (with resync() as the decoder has it now).
class RefDecoder {
 public:
  bool push(uint8_t byte) {
    if (byte != 0) {
      if (raw_len_ < sizeof raw_) {
        raw_[raw_len_++] = byte;
      } else {
        overflow_ = true;
      }
      return false;
    }
    const size_t n = raw_len_;
    const bool overflow = overflow_;
    raw_len_ = 0;
    overflow_ = false;
    const bool quiet = after_resync_;
    after_resync_ = false;
    if (n == 0 && !overflow) return false;
    const DecodeStats before = stats;
    if (judge(n, overflow)) return true;
    if (quiet) stats = before;  // the first frame after resync() is not counted when rejected
    return false;
  }
  bool judge(size_t n, bool overflow) {
    if (overflow) {
      ++stats.framing_errors;
      return false;
    }
    const size_t len = refCobsDecode(raw_, n, decoded_, sizeof decoded_);
    if (len == 0 || len < 3) {
      ++stats.framing_errors;
      return false;
    }
    if (refCrc16(decoded_, len - 2) != static_cast<uint16_t>(decoded_[len - 2] | (decoded_[len - 1] << 8))) {
      ++stats.crc_errors;
      return false;
    }
    const size_t want = wireSize(decoded_[0]);
    if (want == 0) {
      ++stats.unknown_id;
      return false;
    }
    if (want != len - 3) {
      ++stats.bad_length;
      return false;
    }
    ++stats.frames_ok;
    frame.id = decoded_[0];
    frame.payload = decoded_ + 1;
    frame.len = len - 3;
    return true;
  }
  void resync() {
    raw_len_ = 0;
    overflow_ = false;
    after_resync_ = true;
  }
  Frame frame;
  DecodeStats stats;

 private:
  bool after_resync_ = false;
  uint8_t raw_[kMaxEncodedFrame] = {};
  uint8_t decoded_[kMaxFrameBody] = {};
  size_t raw_len_ = 0;
  bool overflow_ = false;
};

using Frames = std::vector<std::pair<uint8_t, std::vector<uint8_t>>>;
void add(Frames& out, const Frame& f) { out.emplace_back(f.id, std::vector<uint8_t>(f.payload, f.payload + f.len)); }

void expectSameStats(const DecodeStats& a, const DecodeStats& b, const char* what) {
  EXPECT_EQ(a.frames_ok, b.frames_ok) << what;
  EXPECT_EQ(a.crc_errors, b.crc_errors) << what;
  EXPECT_EQ(a.framing_errors, b.framing_errors) << what;
  EXPECT_EQ(a.unknown_id, b.unknown_id) << what;
  EXPECT_EQ(a.bad_length, b.bad_length) << what;
}

// Payload bytes with a given share of zeros (zeros are what COBS and the word-wise zero search care about), and
// 0x01 / 0x80 / 0xFF often enough to catch a borrow or carry between the bytes of a word.
std::vector<uint8_t> randomBytes(std::mt19937& rng, size_t len, double zero_share) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<uint8_t> v(len);
  for (auto& b : v) {
    const double x = u(rng);
    if (x < zero_share) {
      b = 0;
    } else {
      switch (rng() % 6) {
        case 0: b = 0x01; break;
        case 1: b = 0x80; break;
        case 2: b = 0xFF; break;
        default: b = static_cast<uint8_t>(rng()); break;
      }
    }
  }
  return v;
}

constexpr double kZeroShares[] = {0.0, 0.02, 0.1, 0.3, 0.6, 0.9, 1.0};

}  // namespace

TEST(SinglePassFraming, CrcMatchesTheBitwiseReferenceAtEveryLengthAlignmentAndStart) {
  std::mt19937 rng(20);
  const std::vector<uint8_t> data = randomBytes(rng, 400, 0.1);
  for (size_t offset = 0; offset < 4; ++offset) {
    for (size_t len = 0; len + offset <= 300; ++len) {
      const uint16_t init = static_cast<uint16_t>(rng());
      ASSERT_EQ(crc16(data.data() + offset, len, init), refCrc16(data.data() + offset, len, init))
          << "offset " << offset << " len " << len;
      ASSERT_EQ(crc16(data.data() + offset, len), refCrc16(data.data() + offset, len));
    }
  }
  const char* s = "123456789";
  EXPECT_EQ(refCrc16(reinterpret_cast<const uint8_t*>(s), 9), 0x29B1);  // the reference itself is right
}

TEST(SinglePassFraming, EncoderIsBitIdenticalToTheOldEncoderOnRandomPayloads) {
  std::mt19937 rng(2020);
  size_t frames = 0;
  for (double share : kZeroShares) {
    for (size_t len = 0; len <= kMaxPayload; ++len) {
      for (int k = 0; k < 60; ++k) {
        const std::vector<uint8_t> payload = randomBytes(rng, len, share);
        const uint8_t id = static_cast<uint8_t>(k % 5 == 0 ? 0 : rng());
        const std::vector<uint8_t> want = refEncodeFrame(id, payload.data(), len);
        uint8_t got[kMaxEncodedFrame + 8];
        std::memset(got, 0xA5, sizeof got);
        const size_t n = encodeFrameRaw(id, payload.data(), len, got);
        ASSERT_EQ(n, want.size()) << "len " << len << " zero share " << share;
        ASSERT_EQ(std::memcmp(got, want.data(), n), 0) << "len " << len << " zero share " << share;
        ASSERT_EQ(got[n], 0xA5) << "wrote past the frame";
        ++frames;
      }
    }
  }
  EXPECT_EQ(frames, std::size(kZeroShares) * (kMaxPayload + 1) * 60);
  uint8_t out[kMaxEncodedFrame];
  EXPECT_EQ(encodeFrameRaw(1, out, kMaxPayload + 1, out), 0u) << "a payload longer than any message is refused";
}

namespace {
template <class Msg>
void expectTypedFrameMatches(const Msg& m) {
  uint8_t payload[Msg::kWireSize];
  encodePayload(m, payload);
  const std::vector<uint8_t> want = refEncodeFrame(static_cast<uint8_t>(Msg::kId), payload, Msg::kWireSize);
  uint8_t got[kMaxEncodedFrame];
  const size_t n = encodeFrame(m, got);
  ASSERT_EQ(n, want.size());
  ASSERT_EQ(std::memcmp(got, want.data(), n), 0);
}

// A field value: zero, a small value or random bits, so that whole fields and single bytes are often 0.
template <class T>
T field(std::mt19937& rng) {
  const uint32_t r = static_cast<uint32_t>(rng());
  switch (r % 3) {
    case 0: return T{};
    case 1: return static_cast<T>(r % 7);
    default: return static_cast<T>(rng());
  }
}
float floatField(std::mt19937& rng) {
  const uint32_t bits = rng() % 3 == 0 ? 0u : static_cast<uint32_t>(rng());
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
}  // namespace

TEST(SinglePassFraming, TypedEncodeFrameMatchesTheOldPathForEveryMessage) {
  std::mt19937 rng(6);
  for (int k = 0; k < 3000; ++k) {
    Telemetry t;
    t.time_us = field<uint32_t>(rng);
    t.seq = field<uint16_t>(rng);
    t.cmd_seq_echo = field<uint16_t>(rng);
    t.mode = static_cast<Mode>(rng() % kModeCount);
    t.state_flags = field<uint8_t>(rng);
    t.fault_bits = field<uint16_t>(rng);
    t.cmd_lost = field<uint8_t>(rng);
    t.rx_errors = field<uint8_t>(rng);
    for (auto& s : t.sample) s = field<int16_t>(rng);
    expectTypedFrameMatches(t);
    Command c;
    c.seq = field<uint16_t>(rng);
    c.timeout_ms = field<uint16_t>(rng);
    c.mode = static_cast<Mode>(rng() % kModeCount);
    c.flags = field<uint8_t>(rng);
    c.channel_count = field<uint8_t>(rng);
    c.reserved = field<uint8_t>(rng);
    for (auto& s : c.setpoint) s = floatField(rng);
    for (auto& g : c.gain_scale_permille) g = field<uint16_t>(rng);
    expectTypedFrameMatches(c);
    Event e;
    e.time_us = field<uint32_t>(rng);
    e.code = static_cast<EventCode>(1 + rng() % 5);
    e.channel = field<uint8_t>(rng);
    e.detail = field<uint8_t>(rng);
    e.value = floatField(rng);
    expectTypedFrameMatches(e);
    Hello h;
    h.session_id = field<uint32_t>(rng);
    expectTypedFrameMatches(h);
    HelloAck a;
    a.session_id = field<uint32_t>(rng);
    a.firmware_build_id = field<uint32_t>(rng);
    expectTypedFrameMatches(a);
    ClearFaults cf;
    cf.session_id = field<uint32_t>(rng);
    expectTypedFrameMatches(cf);
    ParamGet pg;
    pg.param_id = field<uint16_t>(rng);
    expectTypedFrameMatches(pg);
    ParamSet ps;
    ps.param_id = field<uint16_t>(rng);
    ps.value = floatField(rng);
    expectTypedFrameMatches(ps);
    ParamValue pv;
    pv.param_id = field<uint16_t>(rng);
    pv.value = floatField(rng);
    expectTypedFrameMatches(pv);
  }
}

namespace {
// A stream of valid frames of known IDs and lengths, damaged frames (a flipped bit, a cut, an inserted zero, a
// wrong length or ID), random garbage, overlong runs and idle zeros.
std::vector<uint8_t> randomStream(std::mt19937& rng, size_t pieces) {
  static constexpr uint8_t kIds[] = {0x01, 0x02, 0x10, 0x20, 0x30, 0x31, 0x40, 0x41, 0x42};
  std::vector<uint8_t> s;
  for (size_t k = 0; k < pieces; ++k) {
    const uint32_t kind = static_cast<uint32_t>(rng() % 10);
    if (kind == 8) {  // garbage, sometimes longer than any frame
      const std::vector<uint8_t> g = randomBytes(rng, rng() % 160, rng() % 2 == 0 ? 0.0 : 0.05);
      s.insert(s.end(), g.begin(), g.end());
      continue;
    }
    if (kind == 9) {  // idle fill
      s.insert(s.end(), 1 + rng() % 3, 0);
      continue;
    }
    uint8_t id = kIds[rng() % std::size(kIds)];
    size_t len = wireSize(id);
    if (kind == 7) len = rng() % (kMaxPayload + 1);      // probably the wrong length
    if (kind == 6) id = static_cast<uint8_t>(rng());      // probably an unknown ID
    const std::vector<uint8_t> payload = randomBytes(rng, len, kZeroShares[rng() % std::size(kZeroShares)]);
    std::vector<uint8_t> f = refEncodeFrame(id, payload.data(), len);
    if (kind == 5) f[rng() % (f.size() - 1)] ^= static_cast<uint8_t>(1u << (rng() % 8));  // may hit a code byte
    if (kind == 4) f.resize(1 + rng() % (f.size() - 1));                               // cut: runs into the next
    if (kind == 3) f.insert(f.begin() + static_cast<long>(rng() % f.size()), 0);      // a spurious delimiter
    s.insert(s.end(), f.begin(), f.end());
  }
  return s;
}
}  // namespace

TEST(SinglePassFraming, DecoderReportsTheSameFramesAndCountsAsTheOldDecoder) {
  std::mt19937 rng(4);
  DecodeStats total;
  for (int run = 0; run < 300; ++run) {
    const std::vector<uint8_t> stream = randomStream(rng, 40);
    // Interruptions (a port reopened): the same resync() points for every decoder.
    std::vector<size_t> resync_at;
    if (run % 3 == 0) resync_at = {stream.size() / 3, stream.size() / 2};
    RefDecoder ref;
    StreamDecoder by_byte;
    StreamDecoder by_run;
    Frames want;
    Frames got_byte;
    Frames got_run;
    size_t next_resync = 0;
    for (size_t i = 0; i < stream.size(); ++i) {
      if (next_resync < resync_at.size() && resync_at[next_resync] == i) {
        ref.resync();
        by_byte.resync();
        ++next_resync;
      }
      if (ref.push(stream[i])) add(want, ref.frame);
      if (by_byte.push(stream[i])) add(got_byte, by_byte.frame());
    }
    // feed() in random chunks (1 byte to the whole rest), with the same resync points.
    size_t i = 0;
    next_resync = 0;
    while (i < stream.size()) {
      size_t chunk = 1 + rng() % (run % 2 == 0 ? 8 : 200);
      if (next_resync < resync_at.size()) {
        if (resync_at[next_resync] == i) {
          by_run.resync();
          ++next_resync;
        }
        if (next_resync < resync_at.size() && i + chunk > resync_at[next_resync]) chunk = resync_at[next_resync] - i;
      }
      chunk = std::min(chunk, stream.size() - i);
      const uint8_t* p = stream.data() + i;
      const uint8_t* end = p + chunk;
      while (p < end) {
        const uint8_t* before = p;
        if (by_run.feed(p, end)) add(got_run, by_run.frame());
        ASSERT_GT(p, before) << "feed() must consume at least one byte";
        ASSERT_LE(p, end);
      }
      i += chunk;
    }
    ASSERT_EQ(got_byte, want) << "run " << run;
    ASSERT_EQ(got_run, want) << "run " << run;
    expectSameStats(by_byte.stats(), ref.stats, "push()");
    expectSameStats(by_run.stats(), ref.stats, "feed()");
    total.frames_ok += ref.stats.frames_ok;
    total.crc_errors += ref.stats.crc_errors;
    total.framing_errors += ref.stats.framing_errors;
    total.unknown_id += ref.stats.unknown_id;
    total.bad_length += ref.stats.bad_length;
  }
  // The streams exercised every outcome.
  EXPECT_GT(total.frames_ok, 1000u);
  EXPECT_GT(total.crc_errors, 100u);
  EXPECT_GT(total.framing_errors, 100u);
  EXPECT_GT(total.unknown_id, 100u);
  EXPECT_GT(total.bad_length, 100u);
}

TEST(SinglePassFraming, FeedStopsAfterEachFrameSoTheCallerSeesEveryOne) {
  Telemetry t;
  t.seq = 1;
  uint8_t stream[3 * kMaxEncodedFrame];
  size_t n = 0;
  for (uint16_t k = 0; k < 3; ++k) {
    t.seq = static_cast<uint16_t>(100 + k);
    n += encodeFrame(t, stream + n);
  }
  StreamDecoder d;
  const uint8_t* p = stream;
  std::vector<uint16_t> seqs;
  while (p < stream + n) {
    if (!d.feed(p, stream + n)) continue;
    Telemetry back;
    ASSERT_TRUE(decodePayload(d.frame().payload, d.frame().len, back));
    seqs.push_back(back.seq);
  }
  EXPECT_EQ(seqs, (std::vector<uint16_t>{100, 101, 102}));
  EXPECT_EQ(d.stats().frames_ok, 3u);
}
