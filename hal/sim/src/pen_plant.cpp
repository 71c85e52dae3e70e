#include "phalanx/sim/pen_plant.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace phalanx::sim {

namespace pp = phalanx::pen;
using V3 = pp::Vec3<double>;

struct PenPlant::Eval {
  bool ok = false;
  pp::Data<double> kin{};
  pp::JointVec<double> q_dot{}, tau_motor{}, tau_fric{};
  PenVec5 Q_motor{}, Q_fric{}, Q_hand{}, Q_grav{}, Q_stop{};
  V3 hand_force{};    // on the pen centre
  V3 hand_accel{};    // of the hand mass
  V3 v_end[2]{};
  PenVec5 x_ddot{};
  bool at_stop = false;
};

namespace {

bool solve3(const pp::Mat3<double>& A, const V3& b, V3& x) {
  const double det = pp::det3(A);
  if (!(std::fabs(det) > 1e-18)) return false;
  for (int k = 0; k < 3; ++k) {
    pp::Mat3<double> Ak = A;
    for (int r = 0; r < 3; ++r) Ak[r][k] = b[r];
    x[k] = pp::det3(Ak) / det;
  }
  return true;
}

void requireFinite(double v, const char* what) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("pen plant: non-finite ") + what);
}

}  // namespace

PenPlant::PenPlant(const PenPlantConfig& config)
    : config_(config), model_(pp::defaultModel<double>()), rng_(config.seed) {
  const PenPlantParams& p = config_.params;
  for (const auto& row : p.D_paper)
    for (double v : row) requireFinite(v, "mass matrix entry");
  D_ = pp::massMatrixSI<double>(p.D_paper);  // eq 29 → SI
  if (!pp::invertSpd5(D_, D_inv_)) throw std::invalid_argument("pen plant: mass matrix not positive definite");
  for (double v : {p.coulomb_smoothing_rad_s, p.viscous_Nm_s_per_rad, p.weight_near_kg, p.weight_far_kg,
                   p.gravity_m_s2, p.hand_mass_kg, p.grip_stiffness_N_per_m, p.grip_damping_N_s_per_m,
                   p.arm_stiffness_N_per_m, p.arm_damping_N_s_per_m, p.grip_rot_stiffness_Nm_per_rad,
                   p.grip_rot_damping_Nm_s_per_rad, p.stop_stiffness_N_per_m, p.stop_stiffness_Nm_per_rad,
                   p.current_noise_counts, p.max_substep_s}) {
    requireFinite(v, "parameter");
    if (v < 0.0) throw std::invalid_argument("pen plant: negative parameter");
  }
  if (!(p.coulomb_smoothing_rad_s > 0.0) || !(p.hand_mass_kg > 0.0) || !(p.max_substep_s > 0.0)) {
    throw std::invalid_argument("pen plant: smoothing, hand mass and substep must be > 0");
  }
  pp::JointVec<double> q;
  if (pp::computeInverse(model_, config_.start, q) != pp::Status::kOk) {
    throw std::invalid_argument("pen plant: start pose outside the reachable workspace");
  }
  x_ = {config_.start.centre_m[0], config_.start.centre_m[1], config_.start.centre_m[2], config_.start.theta_x_rad,
        config_.start.theta_z_rad};
  hand_p_ = {x_[0], x_[1], x_[2]};
  hand_target_ = x_;
  hand_released_ = config_.scenario == PenHandScenario::kReleased;
  std::uniform_real_distribution<double> ph(0.0, 6.283185307179586);
  for (double& v : random_phase_) v = ph(rng_);
  SimIo io;
  Eval e;
  evaluate(x_, xd_, hand_p_, hand_v_, 0.0, io, false, e);
  truth_.q_rad = e.kin.q_rad;
  sample(io);
}

double PenPlant::weightKg(double z_m) const {
  const PenPlantParams& p = config_.params;
  const double s = (z_m - 0.1625) / 0.075;
  const double w = p.weight_near_kg + (p.weight_far_kg - p.weight_near_kg) * s;
  return w > 0.0 ? w : 0.0;
}

void PenPlant::setHandTarget(const PenVec5& x_target, const PenVec5& x_dot_target) {
  hand_target_ = x_target;
  hand_target_dot_ = x_dot_target;
}

void PenPlant::handTarget(double t, PenVec5& target, PenVec5& target_dot) const {
  switch (config_.scenario) {
    case PenHandScenario::kRandom: {
      // Sum of two sinusoids per axis, ≤ 0.4 Hz, within ±4 cm / ±2.5 cm / ±25°.
      const double w1 = 2 * 3.141592653589793 * 0.23, w2 = 2 * 3.141592653589793 * 0.37;
      const std::array<double, 5> amp{0.04, 0.025, 0.025, 0.43, 0.43};
      for (std::size_t i = 0; i < 5; ++i) {
        const double a = random_phase_[i % 4] + static_cast<double>(i);
        const double base = i == 2 ? 0.20 : 0.0;
        target[i] = base + 0.5 * amp[i] * (std::sin(w1 * t + a) + std::sin(w2 * t + 2 * a));
        target_dot[i] = 0.5 * amp[i] * (w1 * std::cos(w1 * t + a) + w2 * std::cos(w2 * t + 2 * a));
      }
      return;
    }
    case PenHandScenario::kPress: {
      constexpr double kStart_s = 2.0, kRamp_s = 1.0, kDistance_m = 0.035, kPi = 3.141592653589793;
      const double u = std::clamp((t - kStart_s) / kRamp_s, 0.0, 1.0);
      target = hand_target_;  // the start pose
      target_dot = {};
      target[0] += kDistance_m * 0.5 * (1.0 - std::cos(kPi * u));
      if (u > 0.0 && u < 1.0) target_dot[0] = kDistance_m * 0.5 * kPi / kRamp_s * std::sin(kPi * u);
      return;
    }
    case PenHandScenario::kHold:
    case PenHandScenario::kReleased:
    case PenHandScenario::kExternal:
    default:
      target = hand_target_;
      target_dot = config_.scenario == PenHandScenario::kExternal ? hand_target_dot_ : PenVec5{};
      return;
  }
}

void PenPlant::evaluate(const PenVec5& x, const PenVec5& xd, const std::array<double, 3>& hp,
                        const std::array<double, 3>& hv, double t, const SimIo& io, bool bridge_on, Eval& e) const {
  const PenPlantParams& p = config_.params;
  e = Eval{};
  pp::PenPose<double> pose{{x[0], x[1], x[2]}, x[3], x[4]};
  pp::JointVec<double> q;
  if (pp::computeInverse(model_, pose, q) != pp::Status::kOk) return;
  if (!pp::isUsable(pp::computeForward(model_, q, e.kin))) return;
  // End positions p = c ± l6·a(θx, θz) (pen::endOffset): ṗ = G·ẋ, Q = Gᵀf (virtual work).
  std::array<pp::Mat35<double>, 2> G{pp::endJacobian(model_, pp::kBottom, x[3], x[4]),
                                     pp::endJacobian(model_, pp::kTop, x[3], x[4])};
  for (std::size_t k = 0; k < 2; ++k) {
    for (std::size_t i = 0; i < 3; ++i) {
      e.v_end[k][i] = 0.0;
      for (std::size_t j = 0; j < 5; ++j) e.v_end[k][i] += G[k][i][j] * xd[j];
    }
    V3 qd{};
    if (!solve3(e.kin.pantograph[k].J, e.v_end[k], qd)) return;
    for (std::size_t i = 0; i < 3; ++i) e.q_dot[3 * k + i] = qd[i];
  }
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    double duty = io.pwm_duty[i];
    if (!std::isfinite(duty)) duty = 0.0;
    duty = duty > 1.0 ? 1.0 : (duty < -1.0 ? -1.0 : duty);
    e.tau_motor[i] = bridge_on ? static_cast<double>(pen::board::torqueFromDuty(static_cast<float>(duty))) : 0.0;
    e.tau_fric[i] = -p.coulomb_Nm[i] * std::tanh(e.q_dot[i] / p.coulomb_smoothing_rad_s) -
                    p.viscous_Nm_s_per_rad * e.q_dot[i];
  }
  // End forces f = J⁻ᵀτ, then Q = Σ (∂p/∂x)ᵀ f (virtual work), separately for motor and friction torques.
  for (std::size_t k = 0; k < 2; ++k) {
    pp::Mat3<double> Jt{};
    for (std::size_t r = 0; r < 3; ++r)
      for (std::size_t c = 0; c < 3; ++c) Jt[r][c] = e.kin.pantograph[k].J[c][r];
    for (int which = 0; which < 2; ++which) {
      const pp::JointVec<double>& tau = which == 0 ? e.tau_motor : e.tau_fric;
      PenVec5& Q = which == 0 ? e.Q_motor : e.Q_fric;
      V3 f{};
      if (!solve3(Jt, {tau[3 * k], tau[3 * k + 1], tau[3 * k + 2]}, f)) return;
      for (std::size_t j = 0; j < 5; ++j) Q[j] += G[k][0][j] * f[0] + G[k][1][j] * f[1] + G[k][2][j] * f[2];
    }
  }
  if (config_.gravity) e.Q_grav[1] = -weightKg(x[2]) * p.gravity_m_s2;
  // Hand: arm drives the hand mass towards the target; the grip couples hand and pen.
  PenVec5 tgt{}, tgt_dot{};
  handTarget(t, tgt, tgt_dot);
  if (!hand_released_) {
    for (std::size_t i = 0; i < 3; ++i) {
      e.hand_force[i] = p.grip_stiffness_N_per_m * (hp[i] - x[i]) + p.grip_damping_N_s_per_m * (hv[i] - xd[i]);
      const double arm = p.arm_stiffness_N_per_m * (tgt[i] - hp[i]) + p.arm_damping_N_s_per_m * (tgt_dot[i] - hv[i]);
      e.hand_accel[i] = (arm - e.hand_force[i]) / p.hand_mass_kg;
      e.Q_hand[i] = e.hand_force[i];
    }
    for (std::size_t i = 3; i < 5; ++i) {
      e.Q_hand[i] = p.grip_rot_stiffness_Nm_per_rad * (tgt[i] - x[i]) + p.grip_rot_damping_Nm_s_per_rad * (tgt_dot[i] - xd[i]);
    }
  } else {
    // Hand off the pen: it rests at the arm's target.
    for (std::size_t i = 0; i < 3; ++i) {
      e.hand_accel[i] = (p.arm_stiffness_N_per_m * (tgt[i] - hp[i]) + p.arm_damping_N_s_per_m * (tgt_dot[i] - hv[i])) /
                        p.hand_mass_kg;
    }
  }
  for (std::size_t i = 0; i < 5; ++i) {
    const double k = i < 3 ? p.stop_stiffness_N_per_m : p.stop_stiffness_Nm_per_rad;
    if (x[i] < p.stop_lo[i]) {
      e.Q_stop[i] = k * (p.stop_lo[i] - x[i]) - 0.02 * k * xd[i];
      e.at_stop = true;
    } else if (x[i] > p.stop_hi[i]) {
      e.Q_stop[i] = k * (p.stop_hi[i] - x[i]) - 0.02 * k * xd[i];
      e.at_stop = true;
    }
  }
  PenVec5 Q{};
  for (std::size_t i = 0; i < 5; ++i) Q[i] = e.Q_motor[i] + e.Q_fric[i] + e.Q_grav[i] + e.Q_hand[i] + e.Q_stop[i];
  for (std::size_t i = 0; i < 5; ++i) {
    double a = 0.0;
    for (std::size_t j = 0; j < 5; ++j) a += D_inv_[i][j] * Q[j];
    e.x_ddot[i] = a;
  }
  e.ok = true;
}

void PenPlant::step(double dt_s, SimIo& io) {
  if (!(std::isfinite(dt_s) && dt_s > 0.0 && dt_s <= 1.0)) throw std::invalid_argument("pen plant: bad dt_s");
  const bool bridge_on = io.pwm_enabled && io.drive_enable && !io.estop_pressed;
  const int n = static_cast<int>(std::ceil(dt_s / config_.params.max_substep_s - 1e-9));
  const double h = dt_s / n;
  Eval e;
  for (int s = 0; s < n; ++s) {
    evaluate(x_, xd_, hand_p_, hand_v_, time_s_, io, bridge_on, e);
    if (!e.ok) {
      // Outside the assembled workspace (cannot happen behind the soft stops): stop the pen where it is.
      xd_ = {};
      time_s_ += h;
      continue;
    }
    // Semi-implicit Euler: velocities first, positions with the new velocities.
    PenVec5 xd_new{};
    for (std::size_t i = 0; i < 5; ++i) xd_new[i] = xd_[i] + h * e.x_ddot[i];
    // Work bookkeeping with the mid-step velocity: exact for forces held constant over the substep.
    for (std::size_t i = 0; i < 5; ++i) {
      const double v_mid = 0.5 * (xd_[i] + xd_new[i]);
      truth_.motor_work_J += h * e.Q_motor[i] * v_mid;
      truth_.friction_work_J += h * e.Q_fric[i] * v_mid;
      truth_.hand_work_J += h * e.Q_hand[i] * v_mid;
      truth_.gravity_work_J += h * e.Q_grav[i] * v_mid;
      truth_.stop_work_J += h * e.Q_stop[i] * v_mid;
    }
    xd_ = xd_new;
    for (std::size_t i = 0; i < 5; ++i) x_[i] += h * xd_[i];
    for (std::size_t i = 0; i < 3; ++i) {
      hand_v_[i] += h * e.hand_accel[i];
      hand_p_[i] += h * hand_v_[i];
    }
    time_s_ += h;
  }
  // Truth at the end of the step.
  evaluate(x_, xd_, hand_p_, hand_v_, time_s_, io, bridge_on, e);
  truth_.x = x_;
  truth_.x_dot = xd_;
  truth_.bridge_on = bridge_on;
  truth_.at_stop = e.at_stop;
  truth_.hand_pos_m = hand_p_;
  if (e.ok) {
    truth_.q_rad = e.kin.q_rad;
    truth_.q_dot_rad_s = e.q_dot;
    truth_.motor_torque_Nm = e.tau_motor;
    truth_.B_p_tip = e.kin.pantograph[pp::kBottom].B_p_tip;
    truth_.B_p_eraser = e.kin.pantograph[pp::kTop].B_p_tip;
    truth_.B_v_tip = e.v_end[pp::kBottom];
    truth_.B_v_eraser = e.v_end[pp::kTop];
    truth_.hand_force_N = e.hand_force;
  }
  double ke = 0.0;
  for (std::size_t i = 0; i < 5; ++i)
    for (std::size_t j = 0; j < 5; ++j) ke += 0.5 * xd_[i] * D_[i][j] * xd_[j];
  truth_.kinetic_energy_J = ke;
  sample(io);
}

void PenPlant::sample(SimIo& io) {
  const auto counts = pp::countsFromAngles(model_, truth_.q_rad);
  std::normal_distribution<double> noise(0.0, config_.params.current_noise_counts);
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    io.encoder[i] = counts[i];
    const double amps = truth_.motor_torque_Nm[i] / static_cast<double>(pen::board::kTorqueConstant_Nm_per_A);
    double c = pen::board::kAdcMidCounts + amps / static_cast<double>(pen::board::kAmpsPerCount);
    if (config_.noise) c += noise(rng_);
    long v = std::lround(c);
    v = v < 0 ? 0 : (v > pen::board::kAdcMaxCounts ? pen::board::kAdcMaxCounts : v);
    io.adc[i] = static_cast<int32_t>(v);
  }
}

}  // namespace phalanx::sim
