// Host-cycle cost of the SEA finger model: estimator (eq 3–4, MCP → PIP → DIP), Jacobian (eq 5), J_n and
// J̇_n (eq 10, 20), finger-torque mapping (eq 6, 9–11). Budget: ≤ 3 µs median per cycle, 0 allocations.
//
//   sea_model_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include "phalanx/host/sea/sea_finger_controller.h"

// Count allocations during the timed loops (reported as a counter; must be 0).
#include "../support/counting_allocator.h"  // g_allocations

namespace {

using namespace phalanx::host::sea;
constexpr std::size_t kFrames = 500;

/// Sensor frames of a finger moving through the workspace (MCP and PIP sines, 1 s at 500 Hz).
std::vector<Sensors> trajectory() {
  const ps::Model<double> m = ps::defaultModel<double>();
  std::vector<Sensors> out(kFrames);
  for (std::size_t k = 0; k < kFrames; ++k) {
    const double t = double(k) / double(kFrames);
    ps::Data<double> d;
    ps::computeFromFinger(m,
                          ps::FingerAngles<double>{-0.5 + 0.45 * std::sin(2 * M_PI * t),
                                                   -0.7 + 0.6 * std::sin(4 * M_PI * t + 1.0), -0.3, 0.0},
                          d);
    out[k] = d.sensors_rad;
  }
  return out;
}

/// Estimator + J + J_n + J̇_n + finger-torque mapping: the per-cycle model work of the host controller.
void BM_SeaModelCycle(benchmark::State& state) {
  const std::vector<Sensors> frames = trajectory();
  SeaEstimator est;
  FingerTorqueLimits lim;
  std::size_t k = 0;
  double t = 0.0;
  const long before = g_allocations.load();
  for (auto _ : state) {
    est.update(frames[k], 0.002);
    const Vec2 y_d{0.12 * std::sin(t), 0.018 * std::cos(t)};
    const Vec2 y_d_rate{0.12 * std::cos(t), -0.018 * std::sin(t)};
    const FingerTorqueMap map = mapFingerTorque(est.data(), est.jacobianNRate(), y_d, y_d_rate, {0.01, 0.002}, lim);
    benchmark::DoNotOptimize(map);
    k = (k + 1) % kFrames;
    t += 0.002;
  }
  state.counters["allocations"] = benchmark::Counter(double(g_allocations.load() - before));
}
BENCHMARK(BM_SeaModelCycle);

/// The whole host Controller::update (telemetry decode, estimator, mapping, statistics).
void BM_SeaControllerUpdate(benchmark::State& state) {
  const std::vector<Sensors> frames = trajectory();
  std::vector<phalanx::host::TelemetryFrame> tel(kFrames);
  for (std::size_t k = 0; k < kFrames; ++k) {
    tel[k].mode = phalanx::protocol::Mode::kSetpoint;
    tel[k].sample_count = 11;
    for (std::size_t i = 0; i < ps::kNumSensors; ++i) tel[k].value[i] = static_cast<float>(frames[k][i]);
  }
  SeaFingerController ctl(SeaFingerControllerConfig{});
  phalanx::protocol::Command cmd;
  std::size_t k = 0;
  uint64_t t_us = 0;
  const long before = g_allocations.load();
  for (auto _ : state) {
    t_us += 1000;
    tel[k].device_time_us = t_us;
    ctl.update(tel[k], double(t_us) * 1e-6, 0.001, cmd);
    benchmark::DoNotOptimize(cmd);
    k = (k + 1) % kFrames;
  }
  state.counters["allocations"] = benchmark::Counter(double(g_allocations.load() - before));
}
BENCHMARK(BM_SeaControllerUpdate);

/// Single-precision instantiation of the freestanding model (what a microcontroller would run).
void BM_SeaKinematicsFloat(benchmark::State& state) {
  const std::vector<Sensors> frames = trajectory();
  const ps::Model<float> m = ps::defaultModel<float>();
  std::vector<ps::Sensors<float>> f(kFrames);
  for (std::size_t k = 0; k < kFrames; ++k) {
    for (std::size_t i = 0; i < ps::kNumSensors; ++i) f[k][i] = static_cast<float>(frames[k][i]);
  }
  ps::Data<float> d;
  std::size_t k = 0;
  for (auto _ : state) {
    ps::computeFromSensors(m, f[k], d);
    benchmark::DoNotOptimize(d);
    k = (k + 1) % kFrames;
  }
}
BENCHMARK(BM_SeaKinematicsFloat);

}  // namespace
