#include "phalanx/host/pen/pen_scene.h"

#include <cmath>

namespace phalanx::host::pen {

namespace pp = phalanx::pen;

PenScene::PenScene(const PenSceneConfig& config, const pp::Model<double>& model) : config_(config), model_(model) {
  pp::invertSpd5(pp::massMatrixSI<double>(), D_inv_);  // eq 29 is positive definite (tests/unit/pen_plant_test)
}

void PenScene::reset() {
  primed_ = false;
  last_p_ = {};
  v_filt_ = {};
  was_in_ = {};
  clicked_ = false;
  clicks_ = 0;
  marks_ = 0;
}

void PenScene::capBrake(const pp::Data<double>& kin, double dt_s, PenRenderOutput& out) {
  if (brake_count_[0] + brake_count_[1] == 0) return;
  double scale = 1.0;
  if (config_.brake_momentum_cap && dt_s > 0.0) {
    // Velocity change of each end after one period of the brake forces alone: Δv_end = G_end·D⁻¹·Σ G_kᵀ f_k·T.
    std::array<pp::Mat35<double>, 2> G{pp::endJacobian(model_, pp::kBottom, kin.pose.theta_x_rad, kin.pose.theta_z_rad),
                                       pp::endJacobian(model_, pp::kTop, kin.pose.theta_x_rad, kin.pose.theta_z_rad)};
    std::array<double, 5> Q{};
    for (std::size_t k = 0; k < 2; ++k)
      for (std::size_t j = 0; j < 5; ++j)
        for (std::size_t i = 0; i < 3; ++i) Q[j] += G[k][i][j] * out.end[k].brake_force_N[i];
    std::array<double, 5> dx{};
    for (std::size_t i = 0; i < 5; ++i)
      for (std::size_t j = 0; j < 5; ++j) dx[i] += D_inv_[i][j] * Q[j] * dt_s;
    for (std::size_t k = 0; k < 2; ++k) {
      Vec3d dv{};
      for (std::size_t i = 0; i < 3; ++i)
        for (std::size_t j = 0; j < 5; ++j) dv[i] += G[k][i][j] * dx[j];
      for (int n = 0; n < brake_count_[k]; ++n) {
        const double v_n = brake_vn_[k][static_cast<std::size_t>(n)];
        const double dv_n = pp::dot(dv, brake_normal_[k][static_cast<std::size_t>(n)]);
        if (dv_n > -v_n && dv_n > 0.0) scale = std::fmin(scale, -v_n / dv_n);  // stop the end, do not reverse it
      }
    }
  }
  out.brake_scale = scale;
  for (std::size_t k = 0; k < 2; ++k) {
    for (std::size_t i = 0; i < 3; ++i) {
      out.end[k].brake_force_N[i] *= scale;
      out.end[k].force_N[i] += out.end[k].brake_force_N[i];
    }
  }
}

double PenScene::weightKg(double z_m) const {
  const double s = (z_m - 0.1625) / 0.075;
  const double w = config_.weight_near_kg + (config_.weight_far_kg - config_.weight_near_kg) * s;
  return w > 0.0 ? w : 0.0;
}

void PenScene::wall(std::size_t end, double depth, double v_n, const Vec3d& normal, const WallGains& g,
                    std::size_t wall_id, PenRenderOutput& out) {
  bool& was = was_in_[end][wall_id];
  if (!(depth > 0.0)) {
    was = false;
    return;
  }
  double f = g.stiffness_N_per_m * depth - g.damping_N_s_per_m * v_n;
  if (f < 0.0) f = 0.0;
  EndContact& c = out.end[end];
  if (!was && config_.braking && v_n < 0.0) {
    // Braking pulse [22]: one control period at contact onset, proportional to the approach velocity.
    const double fb = -g.brake_N_s_per_m * v_n;
    for (std::size_t i = 0; i < 3; ++i) c.brake_force_N[i] += fb * normal[i];
    c.brake_applied = true;
    const int n = brake_count_[end]++;
    brake_normal_[end][static_cast<std::size_t>(n)] = normal;
    brake_vn_[end][static_cast<std::size_t>(n)] = v_n;
  }
  was = true;
  c.in_contact = true;
  c.penetration_m = depth > c.penetration_m ? depth : c.penetration_m;
  for (std::size_t i = 0; i < 3; ++i) c.force_N[i] += f * normal[i];
}

void PenScene::render(const pp::Data<double>& kin, double dt_s, PenRenderOutput& out) {
  out = PenRenderOutput{};
  const double a = (primed_ && dt_s > 0.0) ? dt_s / (dt_s + 1.0 / (2.0 * M_PI * config_.velocity_cutoff_hz)) : 0.0;
  for (std::size_t e = 0; e < 2; ++e) {
    const Vec3d& p = kin.pantograph[e].B_p_tip;
    if (primed_ && dt_s > 0.0) {
      for (std::size_t i = 0; i < 3; ++i) v_filt_[e][i] += a * ((p[i] - last_p_[e][i]) / dt_s - v_filt_[e][i]);
    }
    last_p_[e] = p;
    out.p_end_m[e] = p;
    out.v_end_m_s[e] = v_filt_[e];
  }
  primed_ = true;
  brake_count_ = {0, 0};

  for (std::size_t e = 0; e < 2; ++e) {
    const Vec3d& p = out.p_end_m[e];
    const Vec3d& v = out.v_end_m_s[e];
    if (config_.box) {
      const Vec3d& lo = config_.box_min;
      const Vec3d& hi = config_.box_max;
      wall(e, lo[0] - p[0], v[0], {1.0, 0.0, 0.0}, config_.horizontal, 0, out);
      wall(e, p[0] - hi[0], -v[0], {-1.0, 0.0, 0.0}, config_.horizontal, 1, out);
      // Floor. Over the button's disc the cap stands button_travel_m above it; the floor is the cap's bottom stop.
      const double dx = p[0] - config_.button_x_m, dz = p[2] - config_.button_z_m;
      const bool over_button = config_.button && dx * dx + dz * dz <= config_.button_radius_m * config_.button_radius_m;
      const double floor_depth = lo[1] - p[1];
      wall(e, floor_depth, v[1], {0.0, 1.0, 0.0}, config_.vertical, 2, out);
      wall(e, lo[2] - p[2], v[2], {0.0, 0.0, 1.0}, config_.horizontal, 3, out);
      wall(e, p[2] - hi[2], -v[2], {0.0, 0.0, -1.0}, config_.horizontal, 4, out);
      if (e == pp::kBottom && over_button) {
        const double d = lo[1] + config_.button_travel_m - p[1];  // depth below the cap
        if (d > 0.0) {
          const double dd = d < config_.button_travel_m ? d : config_.button_travel_m;
          if (dd >= config_.button_click_depth_m && !clicked_) {
            clicked_ = true;
            ++clicks_;
            marks_ = 0;  // the click erases the pencil marks (§VI)
          }
          if (dd <= config_.button_release_depth_m) clicked_ = false;
          double f = config_.button_stiffness_N_per_m * dd;
          if (clicked_) f *= (1.0 - config_.button_click_drop);
          EndContact& c = out.end[e];
          c.in_contact = true;
          c.force_N[1] += f;
          out.button_pressed = true;
          out.button_depth_m = dd;
        } else {
          clicked_ = false;
        }
      }
    }
  }
  // Writing: the tip in contact with a wall while moving along it leaves a mark.
  if (out.end[pp::kBottom].in_contact && !out.button_pressed) {
    const Vec3d& v = out.v_end_m_s[pp::kBottom];
    if (std::sqrt(pp::dot(v, v)) > 0.005) ++marks_;
  }
  capBrake(kin, dt_s, out);
  out.button_clicked = clicked_;
  out.clicks = clicks_;
  out.marks = marks_;

  endForcesToWrench(kin, out.end[pp::kBottom].force_N, out.end[pp::kTop].force_N, out.wrench);
  if (config_.gravity_compensation) {
    out.gravity_force_N = {0.0, weightKg(kin.B_p_centre[2]) * config_.gravity_m_s2, 0.0};
    out.wrench.force_N[1] += out.gravity_force_N[1];
  }
}

}  // namespace phalanx::host::pen
