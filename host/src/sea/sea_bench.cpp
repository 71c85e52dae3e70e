#include "phalanx/host/sea/sea_bench.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "phalanx/apps/sea_finger.h"
#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/metrics.h"
#include "phalanx/host/sea/sea_finger_controller.h"

namespace phalanx::host::sea {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr size_t kSampleMotor0 = 5;
constexpr size_t kSampleTorque0 = 7;
constexpr size_t kSampleLoadCell0 = 11;

struct Trace {
  std::vector<double> t, desired, measured, estimate, truth_load_cell, truth_joint, motor;
  uint16_t faults = 0;
  std::string error;
};

sim::SeaPlantConfig rigPlant(const SeaBenchOptions& o) {
  sim::SeaPlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.variant = sim::SeaVariant::kRig;
  for (auto& ch : c.params.channel) {
    ch.backlash_base_m *= o.plant_backlash_scale;
    ch.backlash_per_Nm_m *= o.plant_backlash_scale;
  }
  return c;
}

/// Runs the trajectory on SEA 0 (MCP: the only SEA that reaches 0.3 N·m inside the ±60° window) and records
/// from settle_s after the trajectory started.
Trace run(const SeaBenchOptions& o, SeaTrajectoryController& ctl, double seconds, double settle_s) {
  Trace tr;
  fw_sim::SeaFingerSimDevice device(rigPlant(o));
  LockstepRig rig(device, ctl);
  if (std::string err = rig.handshake(); !err.empty()) {
    tr.error = err;
    return tr;
  }
  const auto steps = static_cast<long>(std::lround(seconds * 1000.0));
  for (long i = 0; i < steps; ++i) {
    rig.step();
    const TelemetryFrame& tel = rig.session().latest();
    tr.faults |= tel.fault_bits;
    const double t = rig.timeS() - ctl.startS();
    if (ctl.startS() < 0.0 || t < settle_s) continue;
    tr.t.push_back(t);
    tr.desired.push_back(ctl.desired(t));
    tr.measured.push_back(tel.value[kSampleLoadCell0]);
    tr.estimate.push_back(tel.value[kSampleTorque0]);
    tr.truth_load_cell.push_back(device.seaPlant().truth(0).load_cell_torque_Nm);
    tr.truth_joint.push_back(device.seaPlant().truth(0).joint_torque_Nm);
    tr.motor.push_back(tel.value[kSampleMotor0]);
  }
  return tr;
}

double peakAbs(const std::vector<double>& v) {
  double p = 0.0;
  for (double x : v) p = std::max(p, std::fabs(x));
  return p;
}

std::vector<std::string> controllersOf(const SeaBenchOptions& o) {
  if (o.controller == "paper") return {"paper"};
  if (o.controller == "ours") return {"ours"};
  return {"paper", "ours"};
}

nlohmann::json commonHeader(const SeaBenchOptions& o, const char* scenario, double seconds) {
  nlohmann::json out;
  out["scenario"] = scenario;
  out["seconds"] = seconds;
  out["seed"] = o.seed;
  out["noise"] = o.noise;
  out["plant_backlash_scale"] = o.plant_backlash_scale;
  return out;
}

nlohmann::json rigHeader(const SeaBenchOptions& o, const char* scenario, double seconds) {
  nlohmann::json out = commonHeader(o, scenario, seconds);
  out["sea"] = "MCP (k = 2816 N/m), joint clamped to the load cell (001 §7.1)";
  return out;
}

/// Forwards to a host controller and selects the firmware's torque controller at start-up.
class FirmwareSelect : public Controller {
 public:
  FirmwareSelect(Controller& inner, bool paper) : inner_(inner), paper_(paper) {}
  const char* name() const override { return inner_.name(); }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override {
    inner_.update(tel, t_s, dt_s, cmd);
  }
  std::vector<std::pair<uint16_t, float>> startupParams() const override {
    auto p = inner_.startupParams();
    p.emplace_back(apps::sea_param::kController, paper_ ? 1.0f : 0.0f);
    return p;
  }
  double startupSettleS() const override { return std::max(0.2, inner_.startupSettleS()); }

 private:
  Controller& inner_;
  bool paper_;
};

struct FingerTrace {
  std::array<std::vector<double>, 2> desired, estimate_f, truth_f, exo_est, exo_truth, theta, exo_cmd;
  std::array<double, 2> motor_peak_deg{};
  uint16_t faults = 0;
  long invalid = 0;
  std::string error;
};

FingerTrace runFinger(const SeaBenchOptions& o, sim::SeaUserMotion motion, sea::SeaFingerMode mode, bool paper,
                      double seconds, double settle_s) {
  FingerTrace tr;
  sim::SeaPlantConfig plant;
  plant.seed = o.seed;
  plant.noise = o.noise;
  plant.variant = sim::SeaVariant::kFinger;
  plant.motion = motion;
  for (auto& ch : plant.params.channel) {
    ch.backlash_base_m *= o.plant_backlash_scale;
    ch.backlash_per_Nm_m *= o.plant_backlash_scale;
  }
  fw_sim::SeaFingerSimDevice device(plant);
  sea::SeaFingerControllerConfig cfg;
  cfg.mode = mode;
  sea::SeaFingerController ctl(cfg);
  FirmwareSelect select(ctl, paper);
  LockstepRig rig(device, select);
  if (std::string err = rig.handshake(); !err.empty()) {
    tr.error = err;
    return tr;
  }
  const auto steps = static_cast<long>(std::lround(seconds * 1000.0));
  for (long i = 0; i < steps; ++i) {
    rig.step();
    const TelemetryFrame& tel = rig.session().latest();
    tr.faults |= tel.fault_bits;
    for (size_t j = 0; j < 2; ++j) {
      tr.motor_peak_deg[j] = std::max(tr.motor_peak_deg[j], std::fabs(device.seaPlant().truth(static_cast<int>(j)).motor_angle_rad) * 180.0 / kPi);
    }
    if (rig.timeS() < settle_s) continue;
    const auto& map = ctl.lastMap();
    if (!map.tau_f_hat_valid) ++tr.invalid;
    sea::Vec2 y_d{}, y_d_rate{};
    ctl.desired(rig.timeS(), y_d, y_d_rate);
    const auto& f = device.seaPlant().finger();
    for (size_t j = 0; j < 2; ++j) {
      tr.desired[j].push_back(y_d[j]);
      tr.estimate_f[j].push_back(map.tau_f_hat_valid ? map.tau_f_hat_Nm[j] : 0.0);
      tr.truth_f[j].push_back(f.applied_Nm[j]);
      tr.exo_est[j].push_back(tel.value[kSampleTorque0 + j]);
      tr.exo_truth[j].push_back(device.seaPlant().truth(static_cast<int>(j)).joint_torque_Nm);
      tr.theta[j].push_back(f.theta_rad[j]);
      tr.exo_cmd[j].push_back(rig.lastCommand().setpoint[j]);
    }
  }
  return tr;
}

double range(const std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *hi - *lo;
}

double rms(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / static_cast<double>(v.size()));
}

}  // namespace

SeaTrajectoryController::SeaTrajectoryController(Shape shape, double amplitude_Nm, double f0_hz, double f1_hz, bool paper,
                                                 int sea)
    : shape_(shape), amplitude_(amplitude_Nm), f0_(f0_hz), f1_(f1_hz), paper_(paper), sea_(sea) {}

double SeaTrajectoryController::desired(double t) const {
  if (t < 0.0) return 0.0;
  if (shape_ == Shape::kSine) return amplitude_ * std::sin(2.0 * kPi * f0_ * t);  // eq 18, φ = 0, mean 0
  return amplitude_ * std::sin(2.0 * kPi * (f0_ + f1_ * t) * t);                   // eq 16
}

void SeaTrajectoryController::update(const TelemetryFrame&, double t_s, double, protocol::Command& cmd) {
  if (start_s_ < 0.0) start_s_ = t_s;
  cmd.mode = protocol::Mode::kSetpoint;
  for (auto& s : cmd.setpoint) s = 0.0f;
  cmd.setpoint[sea_] = static_cast<float>(desired(t_s - start_s_));
}

std::vector<std::pair<uint16_t, float>> SeaTrajectoryController::startupParams() const {
  return {{apps::sea_param::kController, paper_ ? 1.0f : 0.0f}};
}

double fidelityPercent(const std::vector<double>& y, const std::vector<double>& y_d) {
  if (y.size() != y_d.size() || y.size() < 2) return std::nan("");
  auto variance = [](const std::vector<double>& v) {
    double mean = 0.0;
    for (double x : v) mean += x;
    mean /= static_cast<double>(v.size());
    double s = 0.0;
    for (double x : v) s += (x - mean) * (x - mean);
    return s / static_cast<double>(v.size());
  };
  std::vector<double> err(y.size());
  for (size_t i = 0; i < y.size(); ++i) err[i] = y[i] - y_d[i];
  return (1.0 - variance(err) / variance(y)) * 100.0;  // eq 15
}

double amplitudeAt(const std::vector<double>& x, double fs_hz, double f_hz) {
  double re = 0.0, im = 0.0;
  const double w = 2.0 * kPi * f_hz / fs_hz;
  for (size_t n = 0; n < x.size(); ++n) {
    re += x[n] * std::cos(w * static_cast<double>(n));
    im -= x[n] * std::sin(w * static_cast<double>(n));
  }
  return 2.0 * std::hypot(re, im) / static_cast<double>(x.size());  // single-sided amplitude
}

nlohmann::json benchRigSine(const SeaBenchOptions& o) {
  const double seconds = o.seconds > 0.0 ? o.seconds : 12.0;
  const double settle_s = 2.0;  // one full period at 0.5 Hz after the start transient
  nlohmann::json out = rigHeader(o, "sea-rig-sine", seconds);
  out["peak_Nm"] = o.peak_Nm;
  out["hz"] = o.hz;
  out["window_s"] = {settle_s, seconds};
  for (const std::string& name : controllersOf(o)) {
    SeaTrajectoryController ctl(SeaTrajectoryController::Shape::kSine, o.peak_Nm, o.hz, 0.0, name == "paper");
    const Trace tr = run(o, ctl, seconds + 0.25, settle_s);
    nlohmann::json r;
    if (!tr.error.empty()) {
      r["error"] = tr.error;
      out["controllers"][name] = r;
      continue;
    }
    const double e_meas = rmse(tr.measured, tr.desired);
    const double e_est = rmse(tr.estimate, tr.desired);
    r["faults"] = tr.faults;
    r["samples"] = tr.t.size();
    r["rmse_Nm"] = e_meas;
    r["nrmse_percent"] = 100.0 * e_meas / o.peak_Nm;
    r["fidelity_percent"] = fidelityPercent(tr.measured, tr.desired);
    r["estimate"] = {{"rmse_Nm", e_est},
                     {"nrmse_percent", 100.0 * e_est / o.peak_Nm},
                     {"fidelity_percent", fidelityPercent(tr.estimate, tr.desired)},
                     {"rmse_vs_load_cell_Nm", rmse(tr.estimate, tr.measured)}};
    const double e_truth = rmse(tr.truth_joint, tr.desired);
    r["truth"] = {{"rmse_Nm", e_truth},
                  {"nrmse_percent", 100.0 * e_truth / o.peak_Nm},
                  {"fidelity_percent", fidelityPercent(tr.truth_joint, tr.desired)}};
    r["peak_motor_angle_deg"] = peakAbs(tr.motor) * 180.0 / kPi;
    out["controllers"][name] = r;
  }
  out["paper_reported"] = {{"0.15", {{"nrmse_percent", 9.28}, {"rmse_Nm", 0.0136}, {"fidelity_percent", 98.58}}},
                           {"0.30", {{"nrmse_percent", 11.59}, {"rmse_Nm", 0.0374}, {"fidelity_percent", 97.70}}}};
  out["target"] = {{"peak_Nm", 0.3}, {"hz", 0.5}, {"fidelity_percent_min", 99.5}, {"nrmse_percent_max", 3.0}};
  return out;
}

nlohmann::json benchRigChirp(const SeaBenchOptions& o) {
  const double seconds = o.seconds > 0.0 ? o.seconds : 25.0;
  // eq 16: instantaneous frequency f0 + 2 f1 t reaches fmax at the end.
  const double f1 = (o.chirp_fmax_hz - o.chirp_f0_hz) / (2.0 * seconds);
  nlohmann::json out = rigHeader(o, "sea-rig-chirp", seconds);
  out["amplitude_Nm"] = o.chirp_amplitude_Nm;
  out["f0_hz"] = o.chirp_f0_hz;
  out["fmax_hz"] = o.chirp_fmax_hz;
  const double fs = 1000.0;
  const double df = 1.0 / seconds;             // DFT bin spacing
  const double smooth_hz = 0.5;                // moving-average width over frequency (the paper's "filtered")
  const double f_lo = o.chirp_f0_hz + 0.2;     // the reference spectrum's edges are ramps: excluded
  const double f_hi = o.chirp_fmax_hz - 0.5;
  out["smoothing_hz"] = smooth_hz;
  out["evaluated_band_hz"] = {f_lo, f_hi};
  for (const std::string& name : controllersOf(o)) {
    SeaTrajectoryController ctl(SeaTrajectoryController::Shape::kChirp, o.chirp_amplitude_Nm, o.chirp_f0_hz, f1,
                                name == "paper");
    Trace tr = run(o, ctl, seconds + 0.25, 0.0);
    nlohmann::json r;
    if (!tr.error.empty()) {
      r["error"] = tr.error;
      out["controllers"][name] = r;
      continue;
    }
    const auto n = static_cast<size_t>(std::lround(seconds * fs));
    tr.measured.resize(std::min(n, tr.measured.size()));
    tr.desired.resize(tr.measured.size());
    tr.estimate.resize(tr.measured.size());
    // eq 17 on every DFT bin of the swept band (plus the smoothing margin).
    std::vector<double> freq, ratio, ratio_est;
    for (double f = f_lo - smooth_hz; f <= f_hi + smooth_hz + 1e-9; f += df) {
      const double ref = amplitudeAt(tr.desired, fs, f);
      freq.push_back(f);
      ratio.push_back(ref > 0.0 ? amplitudeAt(tr.measured, fs, f) / ref : 0.0);
      ratio_est.push_back(ref > 0.0 ? amplitudeAt(tr.estimate, fs, f) / ref : 0.0);
    }
    const auto half = static_cast<long>(std::lround(0.5 * smooth_hz / df));
    auto smoothed = [&](const std::vector<double>& v, size_t i) {
      double s = 0.0;
      long cnt = 0;
      for (long j = static_cast<long>(i) - half; j <= static_cast<long>(i) + half; ++j) {
        if (j < 0 || j >= static_cast<long>(v.size())) continue;
        s += v[static_cast<size_t>(j)];
        ++cnt;
      }
      return cnt > 0 ? s / static_cast<double>(cnt) : 0.0;
    };
    const double limit = std::pow(10.0, -3.0 / 20.0);
    double bw = -1.0, bw_est = -1.0, peak_db = -1e9;
    nlohmann::json table = nlohmann::json::array();
    double next_report = 0.5;
    for (size_t i = 0; i < freq.size(); ++i) {
      const double f = freq[i];
      if (f < f_lo || f > f_hi) continue;
      const double g = smoothed(ratio, i);
      const double g_est = smoothed(ratio_est, i);
      peak_db = std::max(peak_db, 20.0 * std::log10(std::max(g, 1e-12)));
      if (bw < 0.0 && g < limit) bw = f;
      if (bw_est < 0.0 && g_est < limit) bw_est = f;
      if (f >= next_report) {
        table.push_back({{"hz", f}, {"magnitude_db", 20.0 * std::log10(std::max(g, 1e-12))}});
        next_report += 0.5;
      }
    }
    r["faults"] = tr.faults;
    r["bandwidth_hz"] = bw > 0.0 ? bw : f_hi;
    r["bandwidth_beyond_band"] = bw < 0.0;
    r["estimate_bandwidth_hz"] = bw_est > 0.0 ? bw_est : f_hi;
    r["peak_magnitude_db"] = peak_db;
    r["magnitude_db"] = table;
    r["peak_motor_angle_deg"] = peakAbs(tr.motor) * 180.0 / kPi;
    out["controllers"][name] = r;
  }
  out["paper_reported"] = {{"bandwidth_hz", 2.5}};
  out["target"] = {{"bandwidth_hz_min", 5.0}};
  return out;
}

nlohmann::json benchFingerTorque(const SeaBenchOptions& o) {
  const double seconds = o.seconds > 0.0 ? o.seconds : 12.0;
  const double settle_s = 2.0;
  nlohmann::json out = commonHeader(o, "sea-finger-torque", seconds);
  out["window_s"] = {settle_s, seconds};
  out["user"] = o.finger_user_holds ? "user holds the rest posture (muscle impedance), eq 13-14, Table 4 subject"
                                    : "relaxed finger (eq 13-14), Table 4 subject, host model = plant model";
  const sea::FingerTorqueProfile profile{};
  out["profile"] = {{"amplitude_Nm", profile.amplitude_Nm}, {"mean_Nm", profile.mean_Nm}, {"hz", profile.frequency_hz}};
  static const char* kJoint[] = {"mcp", "pip"};
  for (const std::string& name : controllersOf(o)) {
    const FingerTrace tr = runFinger(o, o.finger_user_holds ? sim::SeaUserMotion::kHold : sim::SeaUserMotion::kRelaxed,
                                     sea::SeaFingerMode::kFingerTorque,
                                     name == "paper", seconds, settle_s);
    nlohmann::json r;
    if (!tr.error.empty()) {
      r["error"] = tr.error;
      out["controllers"][name] = r;
      continue;
    }
    r["faults"] = tr.faults;
    r["cycles_without_estimate"] = tr.invalid;
    for (size_t j = 0; j < 2; ++j) {
      const double span = range(tr.desired[j]);
      const double e_est = rmse(tr.estimate_f[j], tr.desired[j]);
      const double e_true = rmse(tr.truth_f[j], tr.desired[j]);
      r[kJoint[j]] = {{"nrmse_percent", 100.0 * e_est / span},
                      {"rmse_Nm", e_est},
                      {"truth", {{"nrmse_percent", 100.0 * e_true / span}, {"rmse_Nm", e_true}}},
                      {"desired_peak_to_peak_Nm", span},
                      {"finger_angle_range_deg", range(tr.theta[j]) * 180.0 / kPi},
                      {"exo_setpoint_peak_Nm", std::max(std::fabs(*std::min_element(tr.exo_cmd[j].begin(), tr.exo_cmd[j].end())),
                                                        std::fabs(*std::max_element(tr.exo_cmd[j].begin(), tr.exo_cmd[j].end())))},
                      {"peak_motor_angle_deg", tr.motor_peak_deg[j]}};
    }
    out["controllers"][name] = r;
  }
  out["paper_reported"] = {{"mcp", {{"nrmse_percent", 1.7}, {"rmse_Nm", 0.0041}}},
                           {"pip", {{"nrmse_percent", 3.4}, {"rmse_Nm", 0.0012}}}};
  out["target"] = {{"mcp_nrmse_percent_max", 2.0}, {"pip_nrmse_percent_max", 3.0}};
  return out;
}

nlohmann::json benchTransparency(const SeaBenchOptions& o) {
  const double seconds = o.seconds > 0.0 ? o.seconds : 20.0;
  const double settle_s = 2.0;
  nlohmann::json out = commonHeader(o, "sea-transparency", seconds);
  out["window_s"] = {settle_s, seconds};
  out["user"] = "random finger motion, 0.2-1.5 Hz (SeaUserMotion::kRandom)";
  static const char* kJoint[] = {"mcp", "pip"};
  for (const std::string& name : controllersOf(o)) {
    const FingerTrace tr = runFinger(o, sim::SeaUserMotion::kRandom, sea::SeaFingerMode::kTransparent,
                                     name == "paper", seconds, settle_s);
    nlohmann::json r;
    if (!tr.error.empty()) {
      r["error"] = tr.error;
      out["controllers"][name] = r;
      continue;
    }
    r["faults"] = tr.faults;
    for (size_t j = 0; j < 2; ++j) {
      double peak_rate = 0.0;
      for (size_t i = 1; i < tr.theta[j].size(); ++i) {
        peak_rate = std::max(peak_rate, std::fabs(tr.theta[j][i] - tr.theta[j][i - 1]) * 1000.0);
      }
      r[kJoint[j]] = {{"residual_rmse_Nm", rms(tr.exo_est[j])},
                      {"truth", {{"residual_rmse_Nm", rms(tr.exo_truth[j])},
                                 {"finger_torque_rmse_Nm", rms(tr.truth_f[j])}}},
                      {"finger_angle_range_deg", range(tr.theta[j]) * 180.0 / kPi},
                      {"finger_peak_speed_deg_s", peak_rate * 180.0 / kPi},
                      {"peak_motor_angle_deg", tr.motor_peak_deg[j]}};
    }
    out["controllers"][name] = r;
  }
  out["paper_reported"] = {{"mcp", {{"residual_rmse_Nm", 0.0029}}}, {"pip", {{"residual_rmse_Nm", 0.0092}}}};
  out["target"] = {{"mcp_residual_rmse_Nm_max", 0.002}, {"pip_residual_rmse_Nm_max", 0.005}};
  return out;
}

}  // namespace phalanx::host::sea
