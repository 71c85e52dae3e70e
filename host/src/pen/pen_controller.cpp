#include "phalanx/host/pen/pen_controller.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "phalanx/geometry_fingerprint.h"

#include "phalanx/protocol/devices.h"

namespace phalanx::host::pen {

namespace pp = phalanx::pen;

namespace {
pp::Model<double> modelOf(const pp::Geometry<double>& g) {
  pp::Model<double> m;
  if (pp::makeModel(g, m) != pp::Status::kOk) throw std::invalid_argument("pen controller: geometry is not a pen");
  return m;
}
}  // namespace

PenController::PenController(const PenControllerConfig& config)
    : config_(config), model_(modelOf(config.geometry)), scene_(config.scene, model_), splitter_(config.split) {}

std::vector<Controller::RequiredParam> PenController::requiredParams() const {
  if (config_.geometry_file.empty()) return {};
  const std::uint32_t fp = geometryFingerprint(config_.geometry);
  return {{0x0200, static_cast<float>(fp),
           "pen geometry file '" + config_.geometry_file + "' (fingerprint " + std::to_string(fp) + ")"}};
}

void PenController::update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) {
  ++stats_.cycles;
  // dt on the device clock (the encoder samples' own spacing); the host period if it is not available.
  double dt = dt_s;
  if (primed_ && tel.device_time_us > last_device_time_us_) {
    dt = static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6;
  }
  last_device_time_us_ = tel.device_time_us;
  primed_ = true;

  pp::JointVec<double> q{};
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) q[i] = model_.q_home_rad[i] + static_cast<double>(tel.value[i]);
  const pp::Status ks = pp::computeForward(model_, q, kin_);
  cmd.mode = config_.transparent ? protocol::Mode::kTransparent : protocol::Mode::kSetpoint;
  for (auto& s : cmd.setpoint) s = 0.0f;
  if (!pp::isUsable(ks)) {
    // No trustworthy pose: no force (the firmware's own checks decide whether this is a fault).
    ++stats_.kinematics_unusable;
    scene_.reset();
    return;
  }
  scene_.render(kin_, dt, render_);
  if (config_.transparent) return;
  const SplitStatus ss = splitter_.split(kin_, render_.wrench, split_result_);
  if (ss == SplitStatus::kInternalForceRedistributed) ++stats_.split_redistributed;
  if (ss == SplitStatus::kScaled) ++stats_.split_scaled;
  stats_.limit_active_mask_seen |= split_result_.limit_active_mask;
  const float limit = protocol::kPantographLayout.setpoint_limit;
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    float t = static_cast<float>(split_result_.tau_Nm[i]);
    t = t > limit ? limit : (t < -limit ? -limit : t);  // float rounding of a torque at its limit
    cmd.setpoint[i] = t;
    stats_.peak_torque_Nm = std::fmax(stats_.peak_torque_Nm, std::fabs(split_result_.tau_Nm[i]));
  }
  const EndContact& tip = render_.end[pp::kBottom];
  stats_.peak_tip_force_N = std::fmax(stats_.peak_tip_force_N, std::sqrt(pp::dot(tip.force_N, tip.force_N)));
  stats_.peak_tip_penetration_m = std::fmax(stats_.peak_tip_penetration_m, tip.penetration_m);
  stats_.clicks = render_.clicks;
  noteSettledContact(t_s);
}

void PenController::noteSettledContact(double t_s) {
  const EndContact& tip = render_.end[pp::kBottom];
  constexpr double kSettleS = 1.0;
  const double gap_m = render_.p_end_m[pp::kBottom][1] - config_.scene.box_min[1];
  if (tip.in_contact) stats_.floor_touched = true;
  if (t_s >= kSettleS) {
    ++stats_.settled_cycles;
    if (stats_.floor_touched) stats_.settled_max_separation_m = std::fmax(stats_.settled_max_separation_m, gap_m);
    if (stats_.last_tip_contact && !tip.in_contact) ++stats_.settled_contact_breaks;
    if (tip.in_contact) {
      ++stats_.settled_contact_cycles;
      stats_.settled_penetration_min_m = std::fmin(stats_.settled_penetration_min_m, tip.penetration_m);
      stats_.settled_penetration_max_m = std::fmax(stats_.settled_penetration_max_m, tip.penetration_m);
      const Vec3d& v = render_.v_end_m_s[pp::kBottom];
      stats_.settled_tip_speed_sq_sum += pp::dot(v, v);
    }
  }
  stats_.last_tip_contact = tip.in_contact;
}

void PenController::summarize(nlohmann::json& out) const {
  out["pen"] = {{"cycles", stats_.cycles},
                {"kinematics_unusable", stats_.kinematics_unusable},
                {"split_redistributed", stats_.split_redistributed},
                {"split_scaled", stats_.split_scaled},
                {"limit_active_mask_seen", stats_.limit_active_mask_seen},
                {"peak_tip_force_N", stats_.peak_tip_force_N},
                {"peak_tip_penetration_mm", stats_.peak_tip_penetration_m * 1e3},
                {"peak_torque_Nm", stats_.peak_torque_Nm},
                {"button_clicks", stats_.clicks},
                {"settled_tip_contact", {{"cycles", stats_.settled_cycles},
                                         {"contact_cycles", stats_.settled_contact_cycles},
                                         {"contact_breaks", stats_.settled_contact_breaks},
                                         {"penetration_min_mm", stats_.settled_contact_cycles ? stats_.settled_penetration_min_m * 1e3 : 0.0},
                                         {"penetration_max_mm", stats_.settled_penetration_max_m * 1e3},
                                         {"max_separation_mm", stats_.settled_max_separation_m * 1e3},
                                         {"tip_speed_rms_mm_s", stats_.settled_contact_cycles
                                              ? std::sqrt(stats_.settled_tip_speed_sq_sum / static_cast<double>(stats_.settled_contact_cycles)) * 1e3
                                              : 0.0}}},
                {"geometry_file", config_.geometry_file.empty() ? "(compile-time default)" : config_.geometry_file},
                {"geometry_m", {{"l1", config_.geometry.l1_m}, {"l2", config_.geometry.l2_m}, {"l3", config_.geometry.l3_m},
                                {"l4", config_.geometry.l4_m}, {"l6", config_.geometry.l6_m},
                                {"home_z", config_.geometry.home_z_m}}}};
}

std::string PenController::liveLegend() const {
  return "Live view, every 0.1 s: c = pen centre (cm, base frame); tip F = force\n"
         "  rendered at the tip (N); pen = penetration into the virtual box (mm);\n"
         "  clicks = button clicks rendered";
}

std::string PenController::liveLine(const TelemetryFrame&) const {
  char buf[160];
  const auto& c = kin_.B_p_centre;
  std::snprintf(buf, sizeof buf, "pen c=(%+.1f %+.1f %.1f) cm tip F=%.2f N pen=%.1f mm clicks=%u", c[0] * 100,
                c[1] * 100, c[2] * 100, std::sqrt(pp::dot(render_.end[0].force_N, render_.end[0].force_N)),
                render_.end[0].penetration_m * 1e3, render_.clicks);
  return buf;
}

}  // namespace phalanx::host::pen
