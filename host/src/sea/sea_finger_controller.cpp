#include "phalanx/host/sea/sea_finger_controller.h"

#include <cmath>
#include <cstdio>

namespace phalanx::host::sea {

SeaFingerController::SeaFingerController(const SeaFingerControllerConfig& config)
    : config_(config), estimator_(config.model) {}

void SeaFingerController::desired(double t_s, Vec2& y_d_Nm, Vec2& y_d_rate_Nm_s) const {
  y_d_Nm = {0.0, 0.0};
  y_d_rate_Nm_s = {0.0, 0.0};
  if (config_.mode != SeaFingerMode::kFingerTorque) return;
  const FingerTorqueProfile& p = config_.profile;
  const double w = 2.0 * M_PI * p.frequency_hz;
  // Smooth ramp r(t) = sin²(π t / 2T) on [0, T] scales the whole profile (mean included).
  double r = 1.0;
  double r_dot = 0.0;
  if (config_.ramp_s > 0.0 && t_s < config_.ramp_s) {
    const double x = M_PI * std::fmax(t_s, 0.0) / (2.0 * config_.ramp_s);
    r = std::sin(x) * std::sin(x);
    r_dot = std::sin(2.0 * x) * M_PI / (2.0 * config_.ramp_s);
  }
  for (size_t j = 0; j < 2; ++j) {
    const double s = p.amplitude_Nm[j] * std::sin(w * t_s + p.phase_rad[j]) + p.mean_Nm[j];
    const double s_dot = p.amplitude_Nm[j] * w * std::cos(w * t_s + p.phase_rad[j]);
    y_d_Nm[j] = r * s;
    y_d_rate_Nm_s[j] = r * s_dot + r_dot * s;
  }
}

void SeaFingerController::update(const TelemetryFrame& tel, double t_s, double, protocol::Command& cmd) {
  Sensors sensors{};
  for (size_t i = 0; i < ps::kNumSensors; ++i) sensors[i] = static_cast<double>(tel.value[kSampleSensor0 + i]);
  const Vec2 tau_j_meas{static_cast<double>(tel.value[kSampleSeaTorque0]),
                        static_cast<double>(tel.value[kSampleSeaTorque0 + 1])};
  // J̇_n (eq 20) over the device clock; a repeated frame gives dt = 0 and holds the last rate.
  const double dt_dev = primed_ && tel.device_time_us > last_device_time_us_
                            ? static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6
                            : 0.0;
  if (!primed_ || dt_dev > 0.0) last_device_time_us_ = tel.device_time_us;
  primed_ = true;
  const ps::Status st = estimator_.update(sensors, dt_dev);

  Vec2 y_d{};
  Vec2 y_d_rate{};
  desired(t_s, y_d, y_d_rate);
  map_ = mapFingerTorque(estimator_.data(), estimator_.jacobianNRate(), y_d, y_d_rate, tau_j_meas,
                         config_.limits);

  ++stats_.cycles;
  if (!map_.valid) ++stats_.invalid_kinematics;
  if (st == ps::Status::kLeastSquares) ++stats_.least_squares;
  if (map_.scale < 1.0) ++stats_.saturated;

  const bool transparent = config_.mode == SeaFingerMode::kTransparent;
  // No valid kinematics: zero exoskeleton torque (the transparent command), never a stale setpoint.
  cmd.mode = transparent || !map_.valid ? protocol::Mode::kTransparent : protocol::Mode::kSetpoint;
  const bool finite = std::isfinite(map_.tau_j_d_Nm[0]) && std::isfinite(map_.tau_j_d_Nm[1]);
  for (size_t j = 0; j < 2; ++j) {
    cmd.setpoint[j] = transparent || !map_.valid || !finite ? 0.0f : static_cast<float>(map_.tau_j_d_Nm[j]);
  }
  if (!finite) cmd.mode = protocol::Mode::kTransparent;

  // Scoring only where the device is actually tracking the setpoint we sent.
  if (tel.mode == (transparent ? protocol::Mode::kTransparent : protocol::Mode::kSetpoint)) {
    ++stats_.scored;
    for (size_t j = 0; j < 2; ++j) {
      stats_.sq_exo_torque[j] += tau_j_meas[j] * tau_j_meas[j];
      if (map_.tau_f_hat_valid) {
        const double e = map_.tau_f_hat_Nm[j] - last_y_d_[j];
        stats_.sq_err_finger[j] += e * e;
      }
      stats_.min_y_d[j] = std::fmin(stats_.min_y_d[j], last_y_d_[j]);
      stats_.max_y_d[j] = std::fmax(stats_.max_y_d[j], last_y_d_[j]);
    }
  }
  last_y_d_ = y_d;
}

void SeaFingerController::summarize(nlohmann::json& out) const {
  const double n = stats_.scored > 0 ? static_cast<double>(stats_.scored) : 1.0;
  static const char* kJoints[] = {"mcp", "pip"};
  out["sea_mode"] = config_.mode == SeaFingerMode::kTransparent ? "transparent" : "finger-torque";
  out["cycles"] = stats_.cycles;
  out["cycles_scored"] = stats_.scored;
  out["cycles_invalid_kinematics"] = stats_.invalid_kinematics;
  out["cycles_least_squares"] = stats_.least_squares;
  out["cycles_saturated"] = stats_.saturated;
  for (size_t j = 0; j < 2; ++j) {
    const double rmse = std::sqrt(stats_.sq_err_finger[j] / n);
    const double range = stats_.max_y_d[j] - stats_.min_y_d[j];
    out["finger"][kJoints[j]] = {{"torque_rmse_Nm", rmse},
                                 {"torque_nrmse", range > 0.0 ? rmse / range : 0.0},
                                 {"exo_torque_rms_Nm", std::sqrt(stats_.sq_exo_torque[j] / n)}};
  }
}

std::string SeaFingerController::liveLine(const TelemetryFrame&) const {
  const Data& d = estimator_.data();
  const auto z = [](double v) {  // rounded to the 3 decimals shown, never "-0.000"
    const double r = std::round(v * 1000.0) / 1000.0;
    return r == 0.0 ? 0.0 : r;
  };
  const auto z1 = [](double v) {  // the same at the angles' 1 decimal
    const double r = std::round(v * 10.0) / 10.0;
    return r == 0.0 ? 0.0 : r;
  };
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "  finger angle (deg)    MCP %6.1f   PIP %6.1f   DIP %6.1f\n"
                "  exo torque set (N m)  MCP %6.3f   PIP %6.3f\n"
                "  finger torque (N m)   MCP %6.3f   PIP %6.3f",
                z1(d.theta4_rad * 57.29578), z1(d.theta8_rad * 57.29578), z1(d.theta_dip_rad * 57.29578), z(map_.tau_j_d_Nm[0]),
                z(map_.tau_j_d_Nm[1]), z(map_.tau_f_hat_Nm[0]), z(map_.tau_f_hat_Nm[1]));
  return buf;
}

std::string SeaFingerController::liveLegend() const {
  return "Live view, every 0.1 s:\n"
         "  finger angle = the estimated finger joint angles (deg, theta4/theta8/DIP of\n"
         "      the four-bar estimator; sensor sign convention)\n"
         "  exo torque set = the exoskeleton joint torques commanded (N m)\n"
         "  finger torque = the finger joint torques estimated from the springs (N m)";
}

}  // namespace phalanx::host::sea
