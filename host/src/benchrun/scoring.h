#pragma once
// The bench runner's stages shared by its two ways of running a plan (lockstep, runner.cpp; real time on a device,
// session_bench.cpp): the run-time safety watch, the checks against the plan's limits, and the scoring of a step's
// aligned series. Internal to host/src/benchrun.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/sea/sea_bench.h"

namespace phalanx::host::benchrun {

constexpr double kFs = 1000.0;       // one rig tick or one session cycle: 1 kHz
constexpr size_t kSeaTorque0 = 7;    // sea_finger sample: SEA 0 joint torque estimate (devices.h)
constexpr size_t kGloveForce0 = 15;  // glove5 sample: pad force of finger 0 (devices.h)

/// A glove step's controller, as `phalanx bench glove-free-motion` / `glove-grasp` run it: transparent, or the
/// rigid ball rendered.
inline glove::GloveControllerConfig gloveStepControllerConfig(const Step& st) {
  glove::GloveControllerConfig cc;
  if (st.kind == "glove-grasp") {
    cc.scene = glove::DemoScene::kRigidBall;
  } else {
    cc.transparent = true;
  }
  return cc;
}

/// A SEA rig step's controller: the trajectory controller of eq 16 (sine, or the chirp whose instantaneous
/// frequency f0 + 2 f1 t reaches fmax at the end of the step), ours or the paper's.
inline std::unique_ptr<sea::SeaTrajectoryController> seaStepController(const Plan& plan, const Step& st) {
  const bool chirp = st.kind == "sea-rig-chirp";
  const double f1 = chirp ? (st.fmax_hz - st.f0_hz) / (2.0 * st.seconds) : 0.0;
  return std::make_unique<sea::SeaTrajectoryController>(
      chirp ? sea::SeaTrajectoryController::Shape::kChirp : sea::SeaTrajectoryController::Shape::kSine,
      chirp ? st.amplitude_Nm : st.peak_Nm, chirp ? st.f0_hz : st.hz, f1, plan.controller == "paper");
}

/// The plan's run-time safety stage (`safety:`), counted in rig ticks (1 ms each): an instrument silent, or
/// disagreeing with the device's estimate on every fresh sample, for longer than the plan allows stops the step.
/// The margins (longest silence, longest disagreeing run, largest disagreement) go into the step's result.
class SafetyWatch {
 public:
  explicit SafetyWatch(const Plan& plan)
      : plan_(plan),
        silence_ticks_(static_cast<size_t>(std::lround(plan.safety.instrument_silence_ms * kFs / 1000.0))),
        disagree_ticks_(static_cast<size_t>(std::lround(plan.safety.disagreement_ms * kFs / 1000.0))) {}

  /// A fresh sample at tick k against the device's estimate at the rig step whose truth it carried.
  void sample(size_t k, double value, double estimate, StepResult& r) {
    last_value_ = value;
    if (!std::isfinite(estimate) || !std::isfinite(value)) return;
    const double d = std::fabs(value - estimate);
    r.largest_disagreement = std::max(r.largest_disagreement, d);
    if (d <= plan_.safety.disagreement_max) {
      disagree_since_ = -1;
    } else if (disagree_since_ < 0) {
      disagree_since_ = static_cast<long>(k);
    }
  }

  /// After tick k, silent for `silent` ticks: "" or the cause of a stop.
  std::string check(size_t k, size_t silent, const char* last_error, double estimate, StepResult& r) const {
    r.longest_silence_ticks = std::max(r.longest_silence_ticks, static_cast<long>(silent));
    const long disagreeing = disagree_since_ < 0 ? -1 : static_cast<long>(k) - disagree_since_;
    r.longest_disagreement_ticks = std::max(r.longest_disagreement_ticks, disagreeing);
    char cause[240] = "";
    if (silent > silence_ticks_) {
      std::snprintf(cause, sizeof cause,
                    "safety stop: instrument silent, no fresh sample for %zu ms (safety.instrument_silence_ms %g); last error: %s",
                    silent, plan_.safety.instrument_silence_ms, last_error);
    } else if (disagreeing > static_cast<long>(disagree_ticks_)) {
      std::snprintf(cause, sizeof cause,
                    "safety stop: instrument disagrees with the device's estimate by more than %g %s for %ld ms "
                    "(safety.disagreement_max %g, disagreement_ms %g; last: instrument %.4g, estimate %.4g)",
                    plan_.safety.disagreement_max, plan_.instrument.unit.c_str(), disagreeing,
                    plan_.safety.disagreement_max, plan_.safety.disagreement_ms, last_value_, estimate);
    }
    return cause;
  }

 private:
  const Plan& plan_;
  const size_t silence_ticks_;
  const size_t disagree_ticks_;
  long disagree_since_ = -1;  ///< tick of the first fresh sample of the current run of disagreeing ones
  double last_value_ = 0.0;
};


inline void judge(const PairLimits& l, const PairMetrics& m, const std::string& pair, std::vector<Check>& out) {
  auto add = [&](const char* name, const std::optional<double>& limit, double value, bool is_min) {
    if (!limit) return;
    const bool pass = std::isfinite(value) && (is_min ? value >= *limit : value <= *limit);
    out.push_back({pair + "." + name, value, *limit, is_min, pass});
  };
  add("rmse", l.rmse_max, m.rmse, false);
  add("nrmse_percent", l.nrmse_percent_max, m.nrmse_percent, false);
  add("fidelity_percent", l.fidelity_percent_min, m.fidelity_percent, true);
  add("bandwidth_hz", l.bandwidth_hz_min, m.bandwidth_hz, true);
  if (l.bandwidth_hz_min && m.bandwidth_beyond_band) {
    out.back().note = "-3 dB not reached within the sweep: the bandwidth is at least this";
  }
}


/// One step's series, one entry per tick (rig step or device telemetry frame): setpoint, the device's estimate,
/// the instrument aligned to it (NaN: none), and which ticks are stale (no young instrument sample) or excluded by
/// design (pen-wall's braking pulses). The first `settle` ticks are not scored.
struct StepSeries {
  std::vector<double> sp, est, inst;
  std::vector<uint8_t> stale, excluded;
  size_t settle = 0;
};

/// Score the series into r (samples, pair metrics, checks). false: nothing could be scored (r.error says why).
bool scoreSeries(const Plan& plan, const Step& st, StepSeries& s, const char* last_error, StepResult& r);

}  // namespace phalanx::host::benchrun
