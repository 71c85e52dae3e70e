#pragma once
/// SEA finger exoskeleton, host side: the kinematics estimator (sensor angles → finger angles, J, J_n, J̇_n) and
/// the finger-joint torque mapping of eq 9–11. Preallocated; nothing here allocates per cycle.
#include "phalanx/sea/kinematics.h"

namespace phalanx::host::sea {

namespace ps = phalanx::sea;
using Model = ps::Model<double>;
using Data = ps::Data<double>;
using Sensors = ps::Sensors<double>;
using Vec2 = ps::Vec2<double>;
using Mat2 = ps::Mat2<double>;

/// Sensor angles → full pose each cycle, and J̇_n by the backward difference of eq 20.
class SeaEstimator {
 public:
  explicit SeaEstimator(const Model& model = ps::defaultModel<double>()) : model_(model) {}

  /// One cycle (eq 3–5, 10, 20). dt_s: time since the previous call's sensors (device clock); J̇_n is held at
  /// its last value when dt_s ≤ 0 (a repeated telemetry frame) and is 0 until two valid Jacobians were seen.
  ps::Status update(const Sensors& sensors_rad, double dt_s) {
    const ps::Status s = ps::computeFromSensors(model_, sensors_rad, data_);
    if (!data_.J_valid) {
      have_prev_ = false;
      J_n_dot_ = Mat2{};
      return s;
    }
    if (have_prev_ && dt_s > 0.0) J_n_dot_ = ps::jacobianNRate(data_.J_n, J_n_prev_, dt_s);
    if (!have_prev_ || dt_s > 0.0) J_n_prev_ = data_.J_n;
    have_prev_ = true;
    return s;
  }

  void reset() {
    data_ = Data{};
    J_n_dot_ = Mat2{};
    have_prev_ = false;
  }
  const Data& data() const { return data_; }
  /// dJ_n/dt (1/s), eq 20.
  const Mat2& jacobianNRate() const { return J_n_dot_; }
  const Model& model() const { return model_; }
  void setModel(const Model& model) {
    model_ = model;
    reset();
  }

 private:
  Model model_;
  Data data_{};
  Mat2 J_n_prev_{};
  Mat2 J_n_dot_{};
  bool have_prev_ = false;
};

/// Limits of the finger-torque → exoskeleton-torque mapping.
struct FingerTorqueLimits {
  /// |τ_j,d| per exoskeleton joint (N·m). 0.5 N·m: above the paper's 0.3 N·m design peak (§1), below the
  /// sea_finger setpoint limit of 1 N·m. Both components are scaled by the same factor, so the commanded
  /// finger-torque DIRECTION is kept when one joint saturates.
  double max_exo_torque_Nm = 0.5;
  /// |det J_n| below this: J_n^{-T} (eq 9) is not evaluated, the estimate ŷ is reported invalid.
  double min_abs_det_Jn = 1e-6;
};

/// One cycle of the finger-joint torque controller's host part.
struct FingerTorqueMap {
  Vec2 tau_j_d_Nm{};          ///< exoskeleton joint torque setpoints J_nᵀ y_d (eq 6/11), after saturation
  Vec2 tau_j_d_rate_Nm_s{};   ///< d/dt(J_nᵀ y_d) = J̇_nᵀ y_d + J_nᵀ ẏ_d: the eq 11 derivative feed-forward
  Vec2 tau_f_hat_Nm{};        ///< finger torque estimate ŷ = J_n^{-T} τ̂_j (eq 9) from the measured SEA torques
  double scale = 1.0;         ///< saturation factor applied to τ_j,d (1 = none)
  bool tau_f_hat_valid = false;
  bool valid = false;         ///< false: no valid J_n this cycle → τ_j,d = 0
};

/// Finger torque setpoints y_d (MCP, PIP; N·m, positive = extension, as θ4, θ8) → exoskeleton joint torque
/// setpoints. Eq 11 splits into this host mapping plus the firmware's eq 8 SEA torque PID: with
/// τ_fe = y_d − J_n^{-T} τ̂_j, the eq 11 error e = J_nᵀ τ_fe equals J_nᵀ y_d − τ̂_j, i.e. the exoskeleton torque
/// error for the setpoint J_nᵀ y_d, and ė = J̇_nᵀ τ_fe + J_nᵀ τ̇_fe = d/dt(J_nᵀ y_d) − τ̂̇_j (docs/sea-model.md).
/// Transparency (§7.7) is y_d = 0 ⇒ τ_j,d = 0.
inline FingerTorqueMap mapFingerTorque(const Data& d, const Mat2& J_n_dot, const Vec2& y_d_Nm,
                                       const Vec2& y_d_rate_Nm_s, const Vec2& tau_j_measured_Nm,
                                       const FingerTorqueLimits& lim) {
  FingerTorqueMap out{};
  if (!d.J_valid) return out;
  out.valid = true;
  const Vec2 t = ps::exoTorqueFromFingerTorque(d.J_n, y_d_Nm);
  const Vec2 r1 = ps::exoTorqueFromFingerTorque(J_n_dot, y_d_Nm);
  const Vec2 r2 = ps::exoTorqueFromFingerTorque(d.J_n, y_d_rate_Nm_s);
  double scale = 1.0;
  for (int i = 0; i < 2; ++i) {
    const double a = t[i] < 0 ? -t[i] : t[i];
    if (a > lim.max_exo_torque_Nm && lim.max_exo_torque_Nm / a < scale) scale = lim.max_exo_torque_Nm / a;
  }
  out.scale = scale;
  out.tau_j_d_Nm = {t[0] * scale, t[1] * scale};
  out.tau_j_d_rate_Nm_s = {(r1[0] + r2[0]) * scale, (r1[1] + r2[1]) * scale};
  out.tau_f_hat_valid =
      ps::fingerTorqueFromExoTorque(d.J_n, tau_j_measured_Nm, lim.min_abs_det_Jn, out.tau_f_hat_Nm) ==
      ps::Status::kOk;
  return out;
}

}  // namespace phalanx::host::sea
