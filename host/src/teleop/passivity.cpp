// Time-domain passivity control of the delayed position-force channel (host/include/phalanx/host/teleop/passivity.h,
// docs/teleop.md).
#include "phalanx/host/teleop/passivity.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace phalanx::teleop {
namespace {

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec3 axpy(const Vec3& y, double a, const Vec3& x) { return {y[0] + a * x[0], y[1] + a * x[1], y[2] + a * x[2]}; }
constexpr double kTinySquare = 1e-18;  // |v|² or |F|² below which a port carries no power worth correcting

}  // namespace

const char* schemeName(Scheme s) { return s == Scheme::kPassive ? "passive" : "plain"; }

bool parseScheme(const char* text, Scheme& out) {
  if (std::strcmp(text, "passive") == 0) out = Scheme::kPassive;
  else if (std::strcmp(text, "plain") == 0) out = Scheme::kPlain;
  else return false;
  return true;
}

void PortEnergy::add(double power_W, double dt_s) {
  if (power_W > 0.0) in_J += power_W * dt_s;
  else out_J -= power_W * dt_s;
}

Vec3 ImpedancePort::step(const Vec3& x, const Vec3& F_N, double available_in_J, bool bounded, double dt_s) {
  if (started_) {
    // The last period: the force then exerted, against the displacement since. Moving along the force, the
    // device took energy out of the network; against it, the device (operator or arm) put energy in.
    const Vec3 dx = {x[0] - x_prev_[0], x[1] - x_prev_[1], x[2] - x_prev_[2]};
    energy_.add(-dot(F_prev_, dx) / dt_s, dt_s);
    v_ = {dx[0] / dt_s, dx[1] / dt_s, dx[2] / dt_s};
  }
  Vec3 F = F_N;
  const double out_planned_J = std::max(0.0, dot(F, v_)) * dt_s;  // the coming period, moving as in the last
  if (scheme_ == Scheme::kPassive && bounded && out_planned_J > 0.0) {
    const double allowed_J = std::max(0.0, available_in_J - energy_.out_J);
    const double v2 = dot(v_, v_);
    if (out_planned_J > allowed_J && v2 > kTinySquare) {
      const double alpha = std::min((out_planned_J - allowed_J) / (v2 * dt_s), max_damping_);
      F = axpy(F, -alpha, v_);
      energy_.dissipated_J += alpha * v2 * dt_s;
      ++energy_.pc_active_cycles;
    }
  }
  x_prev_ = x;
  F_prev_ = F;
  started_ = true;
  return F;
}

Vec3 MasterPort::step(const Vec3& x_m, const Sample& slave, bool has_slave, double dt_s) {
  x_f_prev_ = filter_started_ ? x_f_ : x_m;
  if (!filter_started_ || cfg_.position_filter_hz <= 0.0) {
    x_f_ = x_m;
  } else {
    const double a = 1.0 - std::exp(-2.0 * 3.141592653589793 * cfg_.position_filter_hz * dt_s);
    for (int i = 0; i < 3; ++i) x_f_[i] += a * (x_m[i] - x_f_[i]);
  }
  filter_started_ = true;
  const Vec3 F = has_slave ? Vec3{-slave.force_N[0], -slave.force_N[1], -slave.force_N[2]} : Vec3{};
  Vec3 F_out = port_.step(x_f_, F, slave.energy_in_J, has_slave, dt_s);
  for (int i = 0; i < 3; ++i) F_out[i] -= cfg_.local_damping_N_s_per_m * (x_f_[i] - x_f_prev_[i]) / dt_s;
  return F_out;
}

Vec3 SlavePort::step(const Vec3& x_s, const Vec3& v_s, const Sample& master, bool has_master, double dt_s) {
  if (!held_) x_ref_ = x_s;  // held where it is until the master is heard
  held_ = true;
  Vec3 F_c;
  for (int i = 0; i < 3; ++i) F_c[i] = cfg_.stiffness_N_per_m * (x_ref_[i] - x_s[i]) - cfg_.damping_N_s_per_m * v_s[i];
  if (!has_master) return F_c;
  // The reference moves by the master's displacement since the sample used before (a sample reused because none
  // arrived this period adds none; one lost is made up by the next), plus, in kPassive, a drift term back to the
  // master's position. The network delivers F_c·v to the slave side while the reference moves.
  Vec3 v{};
  const bool fresh = master.seq != last_master_seq_;
  for (int i = 0; i < 3; ++i) {
    if (fresh && started_) v[i] = (master.position_m[i] - last_master_pos_[i]) / dt_s;
    if (cfg_.scheme == Scheme::kPassive) v[i] += cfg_.drift_gain_per_s * (master.position_m[i] - x_ref_[i]);
  }
  last_master_seq_ = master.seq;
  last_master_pos_ = master.position_m;
  if (!started_ && cfg_.scheme == Scheme::kPlain) x_ref_ = master.position_m;
  started_ = true;
  if (cfg_.scheme == Scheme::kPassive) {
    // Bounded: E_out_S ≤ E_in_M(received); the excess is taken off the reference's velocity along F_c.
    const double out_planned_J = std::max(0.0, dot(F_c, v)) * dt_s;
    const double allowed_J = std::max(0.0, master.energy_in_J - energy_.out_J);
    const double f2 = dot(F_c, F_c);
    if (out_planned_J > allowed_J && f2 > kTinySquare) {
      const double beta = (out_planned_J - allowed_J) / (f2 * dt_s);
      v = axpy(v, -beta, F_c);
      energy_.dissipated_J += beta * f2 * dt_s;
      ++energy_.pc_active_cycles;
    }
  }
  energy_.add(-dot(F_c, v), dt_s);
  x_ref_ = axpy(x_ref_, dt_s, v);
  return F_c;
}

void SlaveArm::step(const Vec3& coupling_force_N, double dt_s) {
  const int n = std::max(1, static_cast<int>(std::ceil(dt_s / 1e-4)));
  const double h = dt_s / n;
  for (int k = 0; k < n; ++k) {
    const double depth = x_m[0] - cfg.wall_x_m;
    const double push = depth > 0.0 ? std::max(0.0, cfg.wall_stiffness_N_per_m * depth + cfg.wall_damping_N_s_per_m * v_m_s[0])
                                     : 0.0;
    contact_force_N = {-push, 0.0, 0.0};
    for (int i = 0; i < 3; ++i) {
      const double a = (coupling_force_N[i] + contact_force_N[i] - cfg.viscous_N_s_per_m * v_m_s[i]) / cfg.mass_kg;
      v_m_s[i] += a * h;
    }
    wall_work_J += contact_force_N[0] * v_m_s[0] * h;
    for (int i = 0; i < 3; ++i) x_m[i] += v_m_s[i] * h;
  }
}

}  // namespace phalanx::teleop
