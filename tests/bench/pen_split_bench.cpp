// Host-cycle cost of the Twin-Pantograph force split (seeds/004 §VI, Fig. 18): forward kinematics with both 3×3
// tip Jacobians from the six joint angles, then wrench → end forces → effort-optimal internal force → τ = Jᵀf.
// Budget: ≤ 1 µs median per cycle, 0 allocations (counter allocs_per_cycle).
//
//   pen_split_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>
#include <vector>

#include "phalanx/host/pen/force_split.h"

#include "../support/counting_allocator.h"  // g_allocations

namespace {

using namespace phalanx::host::pen;
namespace pp = phalanx::pen;
constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr std::size_t kFrames = 512;

struct Frame {
  pp::JointVec<double> q;
  PenWrench w;
};

// kFrames random workspace configurations (Table X) with random wrenches of bound `force_N` per axis.
std::vector<Frame> frames(double force_N, double torque_Nm) {
  const pp::Model<double> m = pp::defaultModel<double>();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Frame> out(kFrames);
  for (Frame& f : out) {
    pp::PenPose<double> p;
    p.centre_m = {0.06 * u(rng), 0.0375 * u(rng), 0.20 + 0.0375 * u(rng)};
    p.theta_x_rad = 45 * kDeg * u(rng);
    p.theta_z_rad = 45 * kDeg * u(rng);
    pp::computeInverse(m, p, f.q);
    for (int i = 0; i < 3; ++i) {
      f.w.force_N[i] = force_N * u(rng);
      f.w.torque_Nm[i] = torque_Nm * u(rng);
    }
  }
  return out;
}

void runCycle(benchmark::State& state, double force_N, double torque_Nm) {
  const pp::Model<double> model = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  const std::vector<Frame> fr = frames(force_N, torque_Nm);
  pp::Data<double> kin;
  SplitResult r;
  std::size_t k = 0;
  long limited = 0;
  const long allocs_before = g_allocations.load();
  for (auto _ : state) {
    pp::computeForward(model, fr[k].q, kin);
    splitter.split(kin, fr[k].w, r);
    benchmark::DoNotOptimize(r);
    limited += r.status != SplitStatus::kOk ? 1 : 0;
    k = (k + 1) % kFrames;
  }
  state.counters["allocs_per_cycle"] =
      benchmark::Counter(double(g_allocations.load() - allocs_before) / double(state.iterations()));
  state.counters["limited_fraction"] = benchmark::Counter(double(limited) / double(state.iterations()));
}

// Table X continuous range: unsaturated, the common case.
void BM_PenSplitCycle(benchmark::State& state) { runCycle(state, 5.0, 0.35); }
BENCHMARK(BM_PenSplitCycle);

// Beyond peak: every cycle goes through the saturation redistribution (worst case).
void BM_PenSplitCycleSaturated(benchmark::State& state) { runCycle(state, 150.0, 5.0); }
BENCHMARK(BM_PenSplitCycleSaturated);

// Forward kinematics + both Jacobians alone, double and float (the firmware's precision).
template <class T>
void BM_PenForwardKinematics(benchmark::State& state) {
  const pp::Model<T> model = pp::defaultModel<T>();
  const std::vector<Frame> fr = frames(1.0, 0.1);
  std::vector<pp::JointVec<T>> qs(kFrames);
  for (std::size_t i = 0; i < kFrames; ++i)
    for (std::size_t j = 0; j < pp::kNumJoints; ++j) qs[i][j] = T(fr[i].q[j]);
  pp::Data<T> kin;
  std::size_t k = 0;
  for (auto _ : state) {
    pp::computeForward(model, qs[k], kin);
    benchmark::DoNotOptimize(kin);
    k = (k + 1) % kFrames;
  }
}
BENCHMARK(BM_PenForwardKinematics<double>);
BENCHMARK(BM_PenForwardKinematics<float>);

}  // namespace
