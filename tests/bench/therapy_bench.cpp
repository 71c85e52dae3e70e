// What the therapy layer adds to the 1 kHz loop: the therapy controller's update (device observation through
// the glove kinematics, exercise, patient limits) and handing a cycle to the session recorder's queue.
// Run: build/host/bin/therapy_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cmath>
#include <vector>

#include "phalanx/host/record/record_writer.h"
#include "phalanx/host/therapy/glove_device.h"
#include "phalanx/host/therapy/sea_device.h"
#include "phalanx/sea/kinematics.h"
#include "phalanx/host/therapy/therapy_controller.h"

using namespace phalanx;
using namespace phalanx::host::therapy;

namespace {

host::TelemetryFrame gloveTelemetry(double phase) {
  host::TelemetryFrame t;
  t.sample_count = 25;
  t.mode = protocol::Mode::kSetpoint;
  // A mid-range glove pose (α within every finger's mechanism range, glove-model.md) that moves a little.
  for (int f = 0; f < 5; ++f) {
    t.value[3 * f] = static_cast<float>(0.3 + 0.1 * std::sin(phase));
    t.value[3 * f + 1] = static_cast<float>(-1.6 + 0.1 * std::sin(phase));
    t.value[3 * f + 2] = static_cast<float>(0.6);
    t.value[15 + f] = 0.2f;
  }
  return t;
}

void controllerUpdate(benchmark::State& state, const char* exercise) {
  std::string err;
  auto dev = GloveTherapyDevice::make({}, err);
  Profile profile;
  profile.limits = PatientLimits::deviceDefaults(*dev);
  auto pattern = std::make_shared<Pattern>(5);
  auto ex = makeExercise(exercise, nullptr, *dev, profile, pattern, err);
  TherapyController c(std::move(dev), profile.limits, std::move(ex), nullptr);
  protocol::Command cmd;
  double t = 0.0;
  for (auto _ : state) {
    t += 0.001;
    const auto tel = gloveTelemetry(t);
    c.update(tel, t, 0.001, cmd);
    benchmark::DoNotOptimize(cmd);
  }
}

void BM_TherapyUpdateAssessment(benchmark::State& s) { controllerUpdate(s, "assessment"); }
void BM_TherapyUpdateAssistance(benchmark::State& s) { controllerUpdate(s, "assistance"); }
void BM_TherapyUpdateGrasp(benchmark::State& s) { controllerUpdate(s, "grasp"); }
BENCHMARK(BM_TherapyUpdateAssessment);
BENCHMARK(BM_TherapyUpdateAssistance);
BENCHMARK(BM_TherapyUpdateGrasp);

// sea_finger: observation through the four-bar estimator (eq 3–5, 10, 20), J_n^{-T} (eq 9), exercise, limits and
// the J_nᵀ command (eq 6). Telemetry from the sensors of a finger moving around a mid-range pose.
void seaUpdate(benchmark::State& state, const char* exercise) {
  std::string err;
  auto dev = SeaTherapyDevice::make({}, err);
  Profile profile;
  profile.limits = PatientLimits::deviceDefaults(*dev);
  auto pattern = std::make_shared<Pattern>(2);
  auto ex = makeExercise(exercise, nullptr, *dev, profile, pattern, err);
  TherapyController c(std::move(dev), profile.limits, std::move(ex), nullptr);
  const auto model = phalanx::sea::defaultModel<double>();
  std::vector<host::TelemetryFrame> frames(1000);
  phalanx::sea::Data<double> d;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const double ph = 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(frames.size());
    phalanx::sea::FingerAngles<double> f{};
    f.mcp_rad = -0.5 + 0.2 * std::sin(ph);  // flexion negative (kinematics.h)
    f.pip_rad = -0.6 + 0.3 * std::sin(ph);
    f.dip_rad = 2.0 / 3.0 * f.pip_rad;
    phalanx::sea::computeFromFinger(model, f, d);
    auto& t = frames[i];
    t.sample_count = 13;
    t.mode = protocol::Mode::kSetpoint;
    t.device_time_us = i * 1000;
    for (std::size_t k = 0; k < 5; ++k) t.value[k] = static_cast<float>(d.sensors_rad[k]);
    t.value[7] = 0.01f;
    t.value[8] = -0.01f;
  }
  protocol::Command cmd;
  double t = 0.0;
  std::size_t i = 0;
  for (auto _ : state) {
    t += 0.001;
    auto& tel = frames[i++ % frames.size()];
    tel.device_time_us = static_cast<uint64_t>(t * 1e6);
    c.update(tel, t, 0.001, cmd);
    benchmark::DoNotOptimize(cmd);
  }
}
void BM_SeaTherapyUpdateAssessment(benchmark::State& s) { seaUpdate(s, "assessment"); }
void BM_SeaTherapyUpdateAssistance(benchmark::State& s) { seaUpdate(s, "assistance"); }
BENCHMARK(BM_SeaTherapyUpdateAssessment);
BENCHMARK(BM_SeaTherapyUpdateAssistance);

void BM_RecorderPushCycle(benchmark::State& state) {
  char path[] = "/tmp/phalanx-bench-XXXXXX";
  const int fd = mkstemp(path);
  close(fd);
  unlink(path);
  host::record::WriterConfig cfg;
  cfg.queue_cycles = 65536;  // holds every iteration below: the push is measured, not the writer keeping up
  host::record::RecordWriter w(cfg);
  if (!w.open(path, {}).empty()) {
    state.SkipWithError("cannot open the record");
    return;
  }
  host::record::CycleRecord c;
  c.sample_count = 25;
  c.setpoint_count = 5;
  c.aux_count = 22;
  long dropped = 0;
  for (auto _ : state) {
    c.t_s += 0.001;
    if (!w.pushCycle(c)) ++dropped;
  }
  state.counters["dropped"] = static_cast<double>(dropped);
  w.close();
  unlink(path);
}
BENCHMARK(BM_RecorderPushCycle)->Iterations(50000);

}  // namespace
