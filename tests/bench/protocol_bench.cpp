// The protocol's telemetry path: the payload codec alone, the framed path (payload + COBS + CRC-16) and, when
// nanopb is installed (Debian `nanopb` + `libnanopb-dev`), nanopb encoding and decoding the same fields and values
// (tests/bench/nanopb/phalanx_telemetry.proto), side by side in one binary.
// Run: build/host/bin/protocol_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
// Instructions per operation (callgrind, all six in one run): tools/bench/protocol-instructions.sh
#include <benchmark/benchmark.h>

#include "phalanx/protocol/codec.h"

#ifdef PHALANX_HAVE_NANOPB
#include <pb_decode.h>
#include <pb_encode.h>

#include "phalanx_telemetry.pb.h"
#endif

using namespace phalanx::protocol;

namespace {

Telemetry fullTelemetry() {
  Telemetry t;
  t.time_us = 123456789;
  t.seq = 4242;
  t.cmd_seq_echo = 4241;
  t.mode = Mode::kSetpoint;
  t.state_flags = state::kSessionOpen | state::kOutputsActive;
  for (int i = 0; i < static_cast<int>(kMaxSamples); ++i) t.sample[i] = static_cast<int16_t>(i * 1311 - 16000);
  return t;
}

}  // namespace

// One operation each, never inlined, so that callgrind attributes their instructions (inclusive) per call.
// Framed: encodeFrame into the output buffer; decode = StreamDecoder::feed over the frame + decodePayload.
__attribute__((noinline)) size_t phxFrameEncode(const Telemetry& t, uint8_t* frame) { return encodeFrame(t, frame); }
__attribute__((noinline)) bool phxFrameDecode(StreamDecoder& d, const uint8_t* frame, size_t n, Telemetry& out) {
  bool ok = false;
  for (const uint8_t* p = frame; p < frame + n;) {
    if (d.feed(p, frame + n)) ok = decodePayload(d.frame().payload, d.frame().len, out);
  }
  return ok;
}
__attribute__((noinline)) void phxPayloadEncode(const Telemetry& t, uint8_t* payload) { encodePayload(t, payload); }
__attribute__((noinline)) bool phxPayloadDecode(const uint8_t* payload, Telemetry& out) {
  return decodePayload(payload, Telemetry::kWireSize, out);
}

#ifdef PHALANX_HAVE_NANOPB
namespace {
phalanx_nanopb_Telemetry nanopbTelemetry(const Telemetry& t) {
  phalanx_nanopb_Telemetry m = phalanx_nanopb_Telemetry_init_zero;
  m.time_us = t.time_us;
  m.seq = t.seq;
  m.cmd_seq_echo = t.cmd_seq_echo;
  m.mode = static_cast<uint32_t>(t.mode);
  m.state_flags = t.state_flags;
  m.fault_bits = t.fault_bits;
  m.cmd_lost = t.cmd_lost;
  m.rx_errors = t.rx_errors;
  for (size_t i = 0; i < kMaxSamples; ++i) m.sample[i] = t.sample[i];
  return m;
}
}  // namespace
__attribute__((noinline)) size_t nanopbEncode(const phalanx_nanopb_Telemetry& m, uint8_t* buf, size_t cap) {
  pb_ostream_t s = pb_ostream_from_buffer(buf, cap);
  return pb_encode(&s, phalanx_nanopb_Telemetry_fields, &m) ? s.bytes_written : 0;
}
__attribute__((noinline)) bool nanopbDecode(const uint8_t* buf, size_t n, phalanx_nanopb_Telemetry& m) {
  pb_istream_t s = pb_istream_from_buffer(buf, n);
  return pb_decode(&s, phalanx_nanopb_Telemetry_fields, &m);
}
#endif

static void BM_TelemetryEncode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  for (auto _ : state) {
    benchmark::DoNotOptimize(phxFrameEncode(t, frame));
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_TelemetryEncode);

static void BM_TelemetryDecode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  const size_t n = encodeFrame(t, frame);
  StreamDecoder d;
  Telemetry out;
  for (auto _ : state) benchmark::DoNotOptimize(phxFrameDecode(d, frame, n, out));
  if (d.stats().frames_ok != state.iterations()) state.SkipWithError("a frame was not decoded");
}
BENCHMARK(BM_TelemetryDecode);

// The per-byte push() path the firmware and the host used before issue 20 (still supported).
static void BM_TelemetryDecodeByteByByte(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  const size_t n = encodeFrame(t, frame);
  StreamDecoder d;
  Telemetry out;
  for (auto _ : state) {
    for (size_t i = 0; i < n; ++i) {
      if (d.push(frame[i])) benchmark::DoNotOptimize(decodePayload(d.frame().payload, d.frame().len, out));
    }
  }
}
BENCHMARK(BM_TelemetryDecodeByteByByte);

static void BM_TelemetryEncodeDecode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  StreamDecoder d;
  Telemetry out;
  for (auto _ : state) {
    const size_t n = phxFrameEncode(t, frame);
    benchmark::DoNotOptimize(phxFrameDecode(d, frame, n, out));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_TelemetryEncodeDecode);

static void BM_PayloadEncode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t payload[Telemetry::kWireSize];
  for (auto _ : state) {
    phxPayloadEncode(t, payload);
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_PayloadEncode);

static void BM_PayloadDecode(benchmark::State& state) {
  uint8_t payload[Telemetry::kWireSize];
  encodePayload(fullTelemetry(), payload);
  Telemetry out;
  for (auto _ : state) benchmark::DoNotOptimize(phxPayloadDecode(payload, out));
}
BENCHMARK(BM_PayloadDecode);

#ifdef PHALANX_HAVE_NANOPB
static void BM_NanopbEncode(benchmark::State& state) {
  const phalanx_nanopb_Telemetry m = nanopbTelemetry(fullTelemetry());
  uint8_t buf[phalanx_nanopb_Telemetry_size];
  for (auto _ : state) {
    benchmark::DoNotOptimize(nanopbEncode(m, buf, sizeof buf));
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_NanopbEncode);

static void BM_NanopbDecode(benchmark::State& state) {
  const phalanx_nanopb_Telemetry m = nanopbTelemetry(fullTelemetry());
  uint8_t buf[phalanx_nanopb_Telemetry_size];
  const size_t n = nanopbEncode(m, buf, sizeof buf);
  phalanx_nanopb_Telemetry out;
  for (auto _ : state) benchmark::DoNotOptimize(nanopbDecode(buf, n, out));
  if (n == 0 || out.sample[24] != m.sample[24] || out.time_us != m.time_us) state.SkipWithError("nanopb round trip");
}
BENCHMARK(BM_NanopbDecode);
#endif

// Fixed iteration count: every operation above exactly 10 000 times, for callgrind (instructions per call of
// phxFrameEncode, phxFrameDecode, phxPayloadEncode, phxPayloadDecode, nanopbEncode, nanopbDecode):
//   tools/bench/protocol-instructions.sh   (runs valgrind --tool=callgrind on --benchmark_filter=BM_Fixed10k)
static void BM_Fixed10k(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  uint8_t payload[Telemetry::kWireSize];
  StreamDecoder d;
  Telemetry out;
#ifdef PHALANX_HAVE_NANOPB
  const phalanx_nanopb_Telemetry m = nanopbTelemetry(t);
  uint8_t buf[phalanx_nanopb_Telemetry_size];
  phalanx_nanopb_Telemetry back;
#endif
  bool ok = true;
  for (auto _ : state) {
    const size_t n = phxFrameEncode(t, frame);
    ok &= phxFrameDecode(d, frame, n, out);
    phxPayloadEncode(t, payload);
    ok &= phxPayloadDecode(payload, out);
#ifdef PHALANX_HAVE_NANOPB
    const size_t k = nanopbEncode(m, buf, sizeof buf);
    ok &= nanopbDecode(buf, k, back);
#endif
    benchmark::ClobberMemory();
  }
  if (!ok) state.SkipWithError("a round trip failed");
}
BENCHMARK(BM_Fixed10k)->Iterations(10000);
