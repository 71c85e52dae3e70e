// Host-cycle cost of the RML glove model: five fingers of θ-from-α kinematics, Jacobians, contact rendering
// (eq 1), J^T mapping (eq 18) and capstan feed-forward (eq 15–16). Budget: ≤ 5 µs median per cycle.
//
//   glove_kinematics_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <array>
#include <cmath>
#include <vector>

#include "phalanx/glove/kinematics.h"
#include "phalanx/host/glove/scene.h"

namespace {

using namespace phalanx::host::glove;
namespace pg = phalanx::glove;

constexpr double kDeg = 3.14159265358979323846 / 180.0;
constexpr std::size_t kFrames = 512;

// A close/open maneuver sampled at kFrames points (the §4.3 1 s maneuver at 512 Hz), every finger flexing
// from open to a fist around the demo ball. A constant plausible α̇ is enough for timing.
std::vector<RenderInput> closeOpenTrajectory(const HandModel& hand) {
  std::vector<RenderInput> frames(kFrames);
  for (std::size_t k = 0; k < kFrames; ++k) {
    const double s = 0.5 - 0.5 * std::cos(2.0 * 3.14159265358979323846 * double(k) / double(kFrames));
    const pg::Vec3<double> theta{-80 * kDeg * s, -100 * kDeg * s, -60 * kDeg * s};
    for (std::size_t i = 0; i < kNumFingers; ++i) {
      pg::Data<double> d;
      pg::computeFromTheta(hand.fingers[i], theta, d);
      frames[k][i].alpha_rad = d.alpha_rad;
      frames[k][i].alpha_dot_rad_per_s = {0.8, -0.5, 0.6};
    }
  }
  return frames;
}

void BM_GloveHostCycle(benchmark::State& state) {
  GloveScene scene;
  loadDemoScene(scene, DemoScene::kRigidBall);
  scene.addObject(plane({0.0, -0.075, 0.0}, {0.0, 1.0, 0.0}));  // a table under the ball
  const std::vector<RenderInput> frames = closeOpenTrajectory(scene.hand());
  RenderOutput out{};
  std::size_t k = 0;
  std::size_t contacts = 0;
  for (auto _ : state) {
    scene.render(frames[k], out);
    benchmark::DoNotOptimize(out);
    contacts += out[1].in_contact ? 1u : 0u;
    k = (k + 1) % kFrames;
  }
  state.counters["contact_fraction_index"] =
      benchmark::Counter(double(contacts) / double(state.iterations()));
}
BENCHMARK(BM_GloveHostCycle);

// The kinematic part alone (θ from α, u, J_θ^u, J_α^u, J_α^θ) for five fingers, double and float.
template <class T>
void BM_GloveKinematicsOnly(benchmark::State& state) {
  std::array<pg::Model<T>, kNumFingers> models{};
  for (std::size_t i = 0; i < kNumFingers; ++i) models[i] = pg::defaultModel<T>(static_cast<FingerId>(i));
  const std::vector<RenderInput> frames = closeOpenTrajectory(defaultHandModel());
  std::vector<std::array<pg::Vec3<T>, kNumFingers>> alpha(kFrames);
  for (std::size_t k = 0; k < kFrames; ++k)
    for (std::size_t i = 0; i < kNumFingers; ++i)
      for (std::size_t q = 0; q < 3; ++q) alpha[k][i][q] = static_cast<T>(frames[k][i].alpha_rad[q]);
  std::array<pg::Data<T>, kNumFingers> data{};
  std::size_t k = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < kNumFingers; ++i) pg::computeFromAlpha(models[i], alpha[k][i], data[i]);
    benchmark::DoNotOptimize(data);
    k = (k + 1) % kFrames;
  }
}
BENCHMARK_TEMPLATE(BM_GloveKinematicsOnly, double);
BENCHMARK_TEMPLATE(BM_GloveKinematicsOnly, float);

}  // namespace
