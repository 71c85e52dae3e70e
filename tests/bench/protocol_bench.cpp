// Encode + decode of a full telemetry frame through the byte-stream framing (COBS + CRC-16).
// Run: build/host/bin/protocol_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "phalanx/protocol/codec.h"

using namespace phalanx::protocol;

static Telemetry fullTelemetry() {
  Telemetry t;
  t.time_us = 123456789;
  t.seq = 4242;
  t.cmd_seq_echo = 4241;
  t.mode = Mode::kSetpoint;
  t.state_flags = state::kSessionOpen | state::kOutputsActive;
  for (int i = 0; i < static_cast<int>(kMaxSamples); ++i) t.sample[i] = static_cast<int16_t>(i * 1311 - 16000);
  return t;
}

static void BM_TelemetryEncode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  for (auto _ : state) {
    benchmark::DoNotOptimize(encodeFrame(t, frame));
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
  for (auto _ : state) {
    for (size_t i = 0; i < n; ++i) {
      if (d.push(frame[i])) benchmark::DoNotOptimize(decodePayload(d.frame().payload, d.frame().len, out));
    }
  }
}
BENCHMARK(BM_TelemetryDecode);

static void BM_TelemetryEncodeDecode(benchmark::State& state) {
  const Telemetry t = fullTelemetry();
  uint8_t frame[kMaxEncodedFrame];
  StreamDecoder d;
  Telemetry out;
  for (auto _ : state) {
    const size_t n = encodeFrame(t, frame);
    for (size_t i = 0; i < n; ++i) {
      if (d.push(frame[i])) benchmark::DoNotOptimize(decodePayload(d.frame().payload, d.frame().len, out));
    }
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_TelemetryEncodeDecode);

// Fixed iteration count, for a stable instruction figure under callgrind:
//   valgrind --tool=callgrind --toggle-collect='BM_TelemetryFixed*' build/host/bin/protocol_bench
//     --benchmark_filter=BM_TelemetryFixed      (instructions / 10000 = instructions per frame)
static void BM_TelemetryFixed10k(benchmark::State& state) { BM_TelemetryEncodeDecode(state); }
BENCHMARK(BM_TelemetryFixed10k)->Iterations(10000);
