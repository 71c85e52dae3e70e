#include "phalanx/host/glove/glove_controller.h"

#include "phalanx/geometry_fingerprint.h"

#include <cmath>
#include <cstdio>

#include "phalanx/protocol/devices.h"

namespace phalanx::host::glove {

namespace {
constexpr size_t kForceSample0 = 15;  // kGlove5Layout: samples 15..19 are pad forces
/// v rounded to `decimals`, never -0 (a display of "-0.00 N" reads as a push that is not there).
double shown(double v, int decimals) {
  const double k = std::pow(10.0, decimals);
  const double r = std::round(v * k) / k;
  return r == 0.0 ? 0.0 : r;
}
}  // namespace

GloveController::GloveController(const GloveControllerConfig& config) : config_(config), scene_(config.hand) {
  loadDemoScene(scene_, config.scene);
}

std::string GloveController::startupWarning(uint16_t id, float value) const { return tareWarning(id, value); }

std::string tareWarning(uint16_t id, float value) {
  if (id != apps::glove5_param::kTare || !(value < 0.0f)) return {};
  const auto mask = static_cast<unsigned>(std::lround(-value));
  std::string fingers;
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    if ((mask & (1u << f)) == 0) continue;
    if (!fingers.empty()) fingers += ", ";
    fingers += kFingerNames[f];
  }
  char limit[16];
  std::snprintf(limit, sizeof limit, "%.1f", static_cast<double>(apps::kTareMaxShift_N));
  return "strain-gauge tare refused for " + fingers + ": the pad was pressed (more than " + limit +
         " N from its zero) at start-up; the previous zero is kept, and the glove holds those fingers (motor off) until "
         "their pads are relieved. Relax the hand and start again to re-zero.";
}

std::vector<Controller::RequiredParam> GloveController::requiredParams() const {
  std::vector<RequiredParam> r;
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    if (config_.geometry_file[f].empty()) continue;
    const std::uint32_t fp = geometryFingerprint(config_.hand.fingers[f].mech);
    r.push_back({static_cast<uint16_t>(0x0200 + f), static_cast<float>(fp),
                 "glove geometry file '" + config_.geometry_file[f] + "' (finger " + std::to_string(f) +
                     ", mechanism fingerprint " + std::to_string(fp) + ")"});
  }
  return r;
}

void GloveController::update(const TelemetryFrame& tel, double, double dt_s, protocol::Command& cmd) {
  // α̇ from successive telemetry, on the device clock (a repeated frame gives no new information).
  const double dt_dev = primed_ && tel.device_time_us > last_device_time_us_
                            ? static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6
                            : 0.0;
  const double a = dt_dev > 0.0 ? dt_dev / (dt_dev + 1.0 / (2.0 * M_PI * config_.rate_cutoff_hz)) : 0.0;
  for (size_t f = 0; f < kNumFingers; ++f) {
    for (size_t j = 0; j < 3; ++j) {
      const double alpha = static_cast<double>(tel.value[3 * f + j]);
      in_[f].alpha_rad[j] = alpha;
      if (dt_dev > 0.0) {
        const double raw_rate = (alpha - last_alpha_[f][j]) / dt_dev;
        in_[f].alpha_dot_rad_per_s[j] += a * (raw_rate - in_[f].alpha_dot_rad_per_s[j]);
      }
      last_alpha_[f][j] = alpha;
    }
  }
  if (!primed_ || dt_dev > 0.0) last_device_time_us_ = tel.device_time_us;
  primed_ = true;

  if (config_.max_stiffness_period_N_s_per_m > 0.0 && dt_s > 0.0) {
    scene_.setStiffnessLimit(config_.max_stiffness_period_N_s_per_m / dt_s);
  }
  scene_.render(in_, out_);
  cmd.mode = config_.transparent ? protocol::Mode::kTransparent : protocol::Mode::kSetpoint;
  for (size_t f = 0; f < kNumFingers; ++f) {
    const double setpoint = config_.transparent ? 0.0 : out_[f].force_setpoint_N;
    cmd.setpoint[f] = static_cast<float>(setpoint);
    double gain = 1.0;
    if (!config_.transparent && out_[f].in_contact && out_[f].contact_object >= 0 && config_.contact_gain_ref_N_per_m > 0.0) {
      const double k = scene_.object(static_cast<std::size_t>(out_[f].contact_object)).material.stiffness_N_per_m;
      if (k > config_.contact_gain_ref_N_per_m) gain = config_.contact_gain_ref_N_per_m / k;
    }
    cmd.gain_scale_permille[f] = static_cast<uint16_t>(std::lround(gain * 1000.0));
    FingerStats& s = stats_[f];
    const double measured = static_cast<double>(tel.value[kForceSample0 + f]);
    s.peak_force_N = std::fmax(s.peak_force_N, std::fabs(measured));
    s.peak_setpoint_N = std::fmax(s.peak_setpoint_N, std::fabs(setpoint));
    if (!config_.transparent && out_[f].in_contact) {
      s.contact_s += dt_s;
      s.sq_error_contact += (measured - setpoint) * (measured - setpoint);
      s.sq_setpoint_contact += setpoint * setpoint;
      ++s.contact_cycles;
    } else {
      s.sq_force_free += measured * measured;
      ++s.free_cycles;
    }
  }
}

void GloveController::summarize(nlohmann::json& out) const {
  static const char* kScenes[] = {"none", "rigid-ball", "soft-ball", "wall"};
  out["scene"] = config_.transparent ? "none (transparent)" : kScenes[static_cast<int>(config_.scene)];
  for (size_t f = 0; f < kNumFingers; ++f) {
    const FingerStats& s = stats_[f];
    out["fingers"][kFingerNames[f]] = {
        {"peak_force_N", s.peak_force_N},
        {"peak_setpoint_N", s.peak_setpoint_N},
        {"contact_s", s.contact_s},
        {"contact_cycles", s.contact_cycles},
        {"free_cycles", s.free_cycles},
        {"force_rms_error_in_contact_N", s.contact_cycles ? std::sqrt(s.sq_error_contact / static_cast<double>(s.contact_cycles)) : 0.0},
        // RMS error as a share of the rendered force's RMS over the same cycles (issue 20: ≤ 5 %).
        {"force_rms_error_in_contact_percent", s.sq_setpoint_contact > 0.0 ? 100.0 * std::sqrt(s.sq_error_contact / s.sq_setpoint_contact) : 0.0},
        {"force_rms_free_N", s.free_cycles ? std::sqrt(s.sq_force_free / static_cast<double>(s.free_cycles)) : 0.0}};
  }
}

std::string GloveController::liveLine(const TelemetryFrame& tel) const {
  std::string lines;
  char buf[96];
  for (size_t f = 0; f < kNumFingers; ++f) {
    const auto force = static_cast<double>(tel.value[kForceSample0 + f]);
    std::snprintf(buf, sizeof buf, "  %-6s  a %4.0f %4.0f %4.0f deg   force %5.2f N   set %5.2f N  %s%s", kFingerNames[f],
                  shown(static_cast<double>(tel.value[3 * f]) * 57.29578, 0),
                  shown(static_cast<double>(tel.value[3 * f + 1]) * 57.29578, 0),
                  shown(static_cast<double>(tel.value[3 * f + 2]) * 57.29578, 0), shown(force, 2),
                  shown(out_[f].force_setpoint_N, 2), out_[f].in_contact ? "contact" : "",
                  f + 1 < kNumFingers ? "\n" : "");
    lines += buf;
  }
  return lines;
}

std::string GloveController::liveLegend() const {
  return "Live view, every 0.1 s, one line per finger:\n"
         "  a = the glove linkage's three mechanism angles (deg, Hall sensors; not the\n"
         "      finger's joint angles: the session record and report have those)\n"
         "  force = measured fingertip pad force; set = force commanded (N; + resists\n"
         "      flexion); contact = the finger touches the virtual object";
}

}  // namespace phalanx::host::glove
