#include "phalanx/sim/sea_plant.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phalanx::sim {

namespace {

namespace board = ::phalanx::sea::board;

constexpr double kPi = 3.14159265358979323846;
double asDouble(float x) { return static_cast<double>(x); }
double sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }

bool finitePositive(double x) { return std::isfinite(x) && x > 0.0; }
bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }
void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

void validate(const SeaPlantConfig& c) {
  const SeaPlantParams& p = c.params;
  require(c.variant == SeaVariant::kRig || c.variant == SeaVariant::kFinger, "SeaPlantConfig: unknown variant");
  require(c.motion == SeaUserMotion::kRelaxed || c.motion == SeaUserMotion::kRandom ||
              c.motion == SeaUserMotion::kCloseOpen || c.motion == SeaUserMotion::kHold,
          "SeaPlantConfig: unknown user motion");
  const SeaFingerParams& f = c.params.finger;
  for (size_t j = 0; j < 2; ++j) {
    const double pos[] = {f.A_Nm[j], f.B_per_rad[j], f.C_Nm[j], f.D_per_rad[j], f.exo_inertia_kg_m2[j]};
    for (double v : pos) require(finitePositive(v), "SeaFingerParams: A, B, C, D and exo_inertia must be > 0");
    const double nonneg[] = {f.finger_damping_Nm_s_per_rad[j], f.exo_damping_Nm_s_per_rad[j],
                             f.muscle_stiffness_Nm_per_rad[j], f.muscle_damping_Nm_s_per_rad[j],
                             f.random_amplitude_rad[j], f.close_open_amplitude_rad[j],
                             f.reflex_gain_Nm_s_per_rad[j], f.reflex_threshold_rad_s[j], f.max_voluntary_Nm[j]};
    for (double v : nonneg) require(finiteNonNegative(v), "SeaFingerParams: a value that must be >= 0 is not");
    require(std::isfinite(f.reflex_catch_flexion_rad[j]), "SeaFingerParams: reflex_catch_flexion_rad must be finite");
    require(std::isfinite(f.E_rad[j]) && std::isfinite(f.F_rad[j]) && f.E_rad[j] < f.F_rad[j],
            "SeaFingerParams: E and F must be finite with E < F");
  }
  require(std::isfinite(f.max_effort_start_s) && finiteNonNegative(f.max_effort_duration_s),
          "SeaFingerParams: max_effort_start_s must be finite and max_effort_duration_s >= 0");
  require(std::isfinite(f.dip_pip_coupling), "SeaFingerParams: dip_pip_coupling must be finite");
  require(finitePositive(f.close_open_hz), "SeaFingerParams: close_open_hz must be > 0");
  for (const SeaChannelParams& s : p.channel) {
    require(finitePositive(s.spring_stiffness_N_per_m), "SeaChannelParams: spring_stiffness_N_per_m must be > 0");
    require(finitePositive(s.joint_pulley_radius_m), "SeaChannelParams: joint_pulley_radius_m must be > 0");
    require(finitePositive(s.motor_pulley_radius_m), "SeaChannelParams: motor_pulley_radius_m must be > 0");
    require(finiteNonNegative(s.pretension_N), "SeaChannelParams: pretension_N must be >= 0");
    require(finiteNonNegative(s.backlash_base_m), "SeaChannelParams: backlash_base_m must be >= 0");
    require(finiteNonNegative(s.backlash_per_Nm_m), "SeaChannelParams: backlash_per_Nm_m must be >= 0");
    require(finiteNonNegative(s.play_damping_ratio), "SeaChannelParams: play_damping_ratio must be >= 0");
    require(finiteNonNegative(s.sheath_friction) && s.sheath_friction < 1.0,
            "SeaChannelParams: sheath_friction must be in [0, 1)");
    require(finitePositive(s.clamp_stiffness_Nm_per_rad), "SeaChannelParams: clamp_stiffness_Nm_per_rad must be > 0");
  }
  const double positive[] = {p.supply_V, p.motor_resistance_Ohm, p.bridge_current_limit_A, p.motor_inductance_H,
                             p.torque_constant_Nm_per_A, p.rotor_inertia_kg_m2, p.gear_ratio, p.gear_efficiency,
                             p.max_substep_s};
  for (double v : positive) require(finitePositive(v), "SeaPlantParams: a value that must be > 0 is not");
  require(p.gear_efficiency <= 1.0, "SeaPlantParams: gear_efficiency must be <= 1");
  const double non_negative[] = {p.bridge_on_resistance_Ohm, p.no_load_current_A, p.output_inertia_kg_m2,
                                 p.joint_noise_counts, p.current_noise_counts, p.load_cell_noise_counts,
                                 p.donning_offset_sd_rad};
  for (double v : non_negative) require(finiteNonNegative(v), "SeaPlantParams: a value that must be >= 0 is not");
}

int32_t toCounts(double counts) {
  const double r = std::round(counts);
  return static_cast<int32_t>(std::clamp(r, 0.0, static_cast<double>(board::kAdcMaxCounts)));
}

}  // namespace

SeaPlant::SeaPlant(const SeaPlantConfig& config) : config_(config), rng_(config.seed) {
  validate(config_);
  const SeaPlantParams& p = config_.params;
  for (size_t i = 0; i < ch_.size(); ++i) {
    Channel& c = ch_[i];
    c.p = p.channel[i];
    c.inertia = p.rotor_inertia_kg_m2 * p.gear_ratio * p.gear_ratio + p.output_inertia_kg_m2;
    if (config_.variant == SeaVariant::kRig) solveJoint(c);
  }
  if (config_.variant == SeaVariant::kFinger) {
    model_ = sea::defaultModel<double>();
    // Rest pose: where eq 14 is zero (the relaxed finger); the springs are neutral there (θ_j0, eq 1).
    const SeaFingerParams& f = p.finger;
    for (size_t j = 0; j < 2; ++j) {
      // Bisection on the monotone (decreasing in φ) passive torque over (E − 1, F + 1).
      double lo = f.E_rad[j] - 1.0, hi = f.F_rad[j] + 1.0;
      for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (passiveTorque_Nm(static_cast<int>(j), -mid) < 0.0 ? lo : hi) = mid;  // +θ torque < 0 ⇔ flexion torque > 0
      }
      rest_theta_[j] = -0.5 * (lo + hi);
    }
    sea::FingerAngles<double> rest{rest_theta_[0], rest_theta_[1], f.dip_pip_coupling * rest_theta_[1], 0.0};
    const sea::Status st = sea::computeFromFinger(model_, rest, kin_);
    require(sea::isUsable(st) && kin_.J_valid, "SeaPlant: the finger rest pose is outside the exoskeleton's workspace");
    finger_.exo_rest_rad = {kin_.theta1_rad, kin_.theta6r_rad};
    finger_.J_n = kin_.J_n;
    // kRandom: sums of sinusoids, 0.2–1.5 Hz, seeded (a second stream, so noise and motion are independent).
    std::mt19937 motion_rng(config_.seed * 7919u + 17u);
    const auto uni = [&motion_rng](double lo, double hi) {
      return lo + (hi - lo) * (static_cast<double>(motion_rng()) + 0.5) * (1.0 / 4294967296.0);
    };
    for (size_t j = 0; j < 2; ++j) {
      double total = 0.0;
      for (int k = 0; k < RandomMotion::kTerms; ++k) {
        random_.amp[j][static_cast<size_t>(k)] = uni(0.5, 1.0);
        random_.freq_hz[j][static_cast<size_t>(k)] = uni(0.2, 1.5);
        random_.phase[j][static_cast<size_t>(k)] = uni(0.0, 2.0 * kPi);
        total += random_.amp[j][static_cast<size_t>(k)];
      }
      for (auto& a : random_.amp[j]) a *= f.random_amplitude_rad[j] / total;  // peak ≤ the configured amplitude
      for (size_t k = 0; k < random_.phase[j].size(); ++k) random_.sin_phase[j][k] = std::sin(random_.phase[j][k]);
    }
    drawDonning();
    fingerDynamics(0.0);
    fingerSensors();
  }
}

// A third random stream (noise and motion keep theirs), so donning variation changes nothing else.
void SeaPlant::drawDonning() {
  const double sd = config_.params.donning_offset_sd_rad;
  if (sd <= 0.0) return;
  std::mt19937 rng(config_.seed * 104729u + 31u);
  const auto u = [&rng] { return (static_cast<double>(rng()) + 0.5) * (1.0 / 4294967296.0); };
  for (double& off : donning_rad_) off = sd * std::sqrt(-2.0 * std::log(u())) * std::cos(2.0 * kPi * u());
}

double SeaPlant::reflexTorque_Nm(int joint, double theta_rad, double theta_rate_rad_s) const {
  const SeaFingerParams& f = config_.params.finger;
  const auto j = static_cast<size_t>(joint);
  if (f.reflex_gain_Nm_s_per_rad[j] <= 0.0 || -theta_rad >= f.reflex_catch_flexion_rad[j]) return 0.0;
  // Stretch velocity of the flexors = extension rate = +θ̇.
  return -f.reflex_gain_Nm_s_per_rad[j] * std::max(0.0, theta_rate_rad_s - f.reflex_threshold_rad_s[j]);
}

// The user's muscle torque (+θ) on joint j: an impedance around the intent, or a maximal flexion effort.
double SeaPlant::muscleTorque_Nm(size_t j, double th_d, double th_d_dot, double wf) const {
  const SeaFingerParams& f = config_.params.finger;
  if (config_.motion == SeaUserMotion::kRelaxed) {
    const double t = time_s_ - f.max_effort_start_s;
    if (f.max_effort_start_s < 0.0 || t < 0.0 || t > f.max_effort_duration_s) return 0.0;
    return -f.max_voluntary_Nm[j] * std::min(1.0, t / kMaxEffortRiseS);
  }
  // The user drives the intended motion: cancels their own passive torque at θ_d, plus an impedance.
  return -passiveTorque_Nm(static_cast<int>(j), th_d) + f.muscle_stiffness_Nm_per_rad[j] * (th_d - finger_.theta_rad[j]) +
         f.muscle_damping_Nm_s_per_rad[j] * (th_d_dot - wf);
}

double SeaPlant::passiveTorque_Nm(int joint, double theta_rad) const {
  const SeaFingerParams& f = config_.params.finger;
  const auto j = static_cast<size_t>(joint);
  const double phi = -theta_rad;  // flexion positive, the form of eq 14
  const double flexion_torque = f.A_Nm[j] * (std::exp(-f.B_per_rad[j] * (phi - f.E_rad[j])) - 1.0) -
                                f.C_Nm[j] * (std::exp(f.D_per_rad[j] * (phi - f.F_rad[j])) - 1.0);  // eq 14
  return -flexion_torque;
}

void SeaPlant::intent(double t, std::array<double, 2>& theta_d, std::array<double, 2>& theta_d_dot) const {
  const SeaFingerParams& f = config_.params.finger;
  for (size_t j = 0; j < 2; ++j) {
    theta_d[j] = rest_theta_[j];
    theta_d_dot[j] = 0.0;
    if (config_.motion == SeaUserMotion::kRandom) {
      for (int k = 0; k < RandomMotion::kTerms; ++k) {
        const auto kk = static_cast<size_t>(k);
        const double w = 2.0 * kPi * random_.freq_hz[j][kk];
        // Faded in over the first second, so the motion starts from rest.
        const double fade = std::min(1.0, t);
        theta_d[j] += fade * random_.amp[j][kk] * std::sin(w * t + random_.phase[j][kk]) -
                      fade * random_.amp[j][kk] * random_.sin_phase[j][kk];
        theta_d_dot[j] += fade * random_.amp[j][kk] * w * std::cos(w * t + random_.phase[j][kk]);
      }
    } else if (config_.motion == SeaUserMotion::kCloseOpen) {
      const double w = 2.0 * kPi * f.close_open_hz;
      // Flexion is negative: the finger closes first.
      theta_d[j] -= f.close_open_amplitude_rad[j] * std::sin(w * t);
      theta_d_dot[j] -= f.close_open_amplitude_rad[j] * w * std::cos(w * t);
    }
  }
}

// eq 13 in Θ_r with τ_f = −(finger's own torques); finger angles and J_n from the kinematics (eq 3–5, 10).
void SeaPlant::fingerDynamics(double h) {
  const SeaFingerParams& f = config_.params.finger;
  sea::Sensors<double> s{};
  s[sea::kSensorExoMcp] = finger_.exo_rest_rad[0] + ch_[0].theta_j;
  s[sea::kSensorExoPip] = finger_.exo_rest_rad[1] + ch_[1].theta_j;
  s[sea::kSensorDip] = finger_.sensors_rad[sea::kSensorDip];
  const sea::Status st = sea::computeFromSensors(model_, s, kin_);
  finger_.kinematics_ok = sea::isUsable(st) && kin_.J_valid;
  if (finger_.kinematics_ok) {
    finger_.J_n = kin_.J_n;
    finger_.theta_rad[0] = kin_.theta4_rad;
    finger_.theta_rad[1] = kin_.theta8_rad;
  }  // else: keep the last pose and J_n (the state cannot leave the workspace by more than a substep)
  finger_.theta_rad[2] = f.dip_pip_coupling * finger_.theta_rad[1];
  const auto& Jn = finger_.J_n;
  const std::array<double, 2> wj = {ch_[0].omega_j, ch_[1].omega_j};
  const std::array<double, 2> wf = {Jn[0][0] * wj[0] + Jn[0][1] * wj[1], Jn[1][0] * wj[0] + Jn[1][1] * wj[1]};
  std::array<double, 2> th_d{}, th_d_dot{};
  intent(time_s_, th_d, th_d_dot);
  const bool active = config_.motion != SeaUserMotion::kRelaxed;
  std::array<double, 2> tau_fin{};  // finger's own torques (+θ), without the damping (implicit below)
  std::array<double, 2> damping{};  // finger-coordinate damping (finger + muscle)
  for (size_t j = 0; j < 2; ++j) {
    finger_.passive_Nm[j] = passiveTorque_Nm(static_cast<int>(j), finger_.theta_rad[j]);
    finger_.muscle_Nm[j] = muscleTorque_Nm(j, th_d[j], th_d_dot[j], wf[j]);
    finger_.reflex_Nm[j] = reflexTorque_Nm(static_cast<int>(j), finger_.theta_rad[j], wf[j]);
    tau_fin[j] = finger_.passive_Nm[j] + finger_.muscle_Nm[j] + finger_.reflex_Nm[j] +
                 (active ? f.muscle_damping_Nm_s_per_rad[j] * wf[j] : 0.0);  // the −D·θ̇_f part goes implicit
    damping[j] = f.finger_damping_Nm_s_per_rad[j] + (active ? f.muscle_damping_Nm_s_per_rad[j] : 0.0);
    finger_.intent_rad[j] = th_d[j];
    finger_.theta_rate_rad_s[j] = wf[j];
    finger_.exo_rate_rad_s[j] = wj[j];
    finger_.exo_rad[j] = finger_.exo_rest_rad[j] + ch_[j].theta_j;
  }
  // Applied finger torques (eq 9 on the truth): τ_f = J_n^{-T} τ_j.
  sea::Vec2<double> tau_f{};
  sea::fingerTorqueFromExoTorque<double>(Jn, {ch_[0].truth.joint_torque_Nm, ch_[1].truth.joint_torque_Nm}, 1e-9,
                                         tau_f);
  finger_.applied_Nm = {tau_f[0], tau_f[1]};
  if (h <= 0.0) return;

  // Generalised forces at Θ_r: τ_j − B_j Θ̇_r + J_nᵀ τ_fin − J_nᵀ D J_n Θ̇_r. Semi-implicit in all damping:
  // (I + h (B_j + J_nᵀ D J_n)) Θ̇⁺ = I Θ̇ + h (τ_j + J_nᵀ τ_fin).
  const sea::Vec2<double> gen = sea::exoTorqueFromFingerTorque<double>(Jn, {tau_fin[0], tau_fin[1]});
  double m[2][2];
  double rhs[2];
  for (size_t a = 0; a < 2; ++a) {
    for (size_t b = 0; b < 2; ++b) {
      const double jdj = Jn[0][a] * damping[0] * Jn[0][b] + Jn[1][a] * damping[1] * Jn[1][b];
      m[a][b] = h * (jdj + (a == b ? f.exo_damping_Nm_s_per_rad[a] : 0.0)) + (a == b ? f.exo_inertia_kg_m2[a] : 0.0);
    }
    rhs[a] = f.exo_inertia_kg_m2[a] * wj[a] + h * (ch_[a].truth.joint_torque_Nm + gen[a]);
  }
  const double det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
  const double w0 = (rhs[0] * m[1][1] - m[0][1] * rhs[1]) / det;
  const double w1 = (m[0][0] * rhs[1] - rhs[0] * m[1][0]) / det;
  ch_[0].omega_j = w0;
  ch_[1].omega_j = w1;
  ch_[0].theta_j += h * w0;
  ch_[1].theta_j += h * w1;
}

void SeaPlant::fingerSensors() {
  const SeaFingerParams& f = config_.params.finger;
  sea::Data<double> d;
  const sea::FingerAngles<double> angles{finger_.theta_rad[0], finger_.theta_rad[1], finger_.theta_rad[2], 0.0};
  sea::computeFromFinger(model_, angles, d);
  finger_.sensors_rad = d.sensors_rad;
  // θ_1r and θ_6r are the state itself (computeFromFinger reproduces them to rounding).
  finger_.sensors_rad[sea::kSensorExoMcp] = finger_.exo_rest_rad[0] + ch_[0].theta_j;
  finger_.sensors_rad[sea::kSensorExoPip] = finger_.exo_rest_rad[1] + ch_[1].theta_j;
  (void)f;
}

int SeaPlant::idx(int sea) {
  if (sea < 0 || sea > 1) throw std::out_of_range("SeaPlant: SEA index must be 0 (MCP) or 1 (PIP)");
  return sea;
}

const SeaTruth& SeaPlant::truth(int sea) const { return ch_[static_cast<size_t>(idx(sea))].truth; }

double SeaPlant::idealSeaTorque_Nm(int sea) const {
  const Channel& c = ch_[static_cast<size_t>(idx(sea))];
  const double rj = c.p.joint_pulley_radius_m;
  // eq 2 with θ_j0 = 0 (the plant's joint zero is the unloaded clamp pose).
  return 2.0 * c.p.spring_stiffness_N_per_m * (c.p.motor_pulley_radius_m * c.theta_m - rj * c.theta_j) * rj;
}

// Tensions and the joint torque for the current x_e and θ_j (finger variant; the rig solves θ_j first).
void SeaPlant::tensions(Channel& c) const {
  const double k = c.p.spring_stiffness_N_per_m;
  const double r = c.p.joint_pulley_radius_m;
  const double d = c.x_e - r * c.theta_j;
  const double t1 = std::max(0.0, c.p.pretension_N - k * d);
  const double t2 = std::max(0.0, c.p.pretension_N + k * d);
  SeaTruth& t = c.truth;
  t.joint_angle_rad = c.theta_j;
  t.spring_deflection_m = d;
  t.tension1_N = t1;
  t.tension2_N = t2;
  t.joint_torque_Nm = (t2 - t1) * r;  // eq 2 while both cables are taut
  t.load_cell_torque_Nm = 0.0;
}

// Rig: massless joint pulley held by the clamp, k_clamp θ_j = τ_j(θ_j). τ_j is piecewise linear in θ_j (both
// cables taut, or one slack), so each region is solved in closed form and the consistent one is kept.
void SeaPlant::solveJoint(Channel& c) const {
  const double k = c.p.spring_stiffness_N_per_m;
  const double r = c.p.joint_pulley_radius_m;
  const double a = c.p.clamp_stiffness_Nm_per_rad;
  const double t0 = c.p.pretension_N;
  const double x = c.x_e;
  double theta = 2.0 * k * r * x / (a + 2.0 * k * r * r);  // both taut: τ_j = 2k d r_j (eq 2)
  double d = x - r * theta;
  if (k * d > t0) {
    theta = r * (t0 + k * x) / (a + k * r * r);  // cable 1 slack: τ_j = (T_0 + k d) r_j
  } else if (k * d < -t0) {
    theta = r * (k * x - t0) / (a + k * r * r);  // cable 2 slack: τ_j = −(T_0 − k d) r_j
  }
  d = x - r * theta;
  const double t1 = std::max(0.0, t0 - k * d);
  const double t2 = std::max(0.0, t0 + k * d);
  c.theta_j = theta;
  SeaTruth& t = c.truth;
  t.joint_angle_rad = theta;
  t.spring_deflection_m = d;
  t.tension1_N = t1;
  t.tension2_N = t2;
  t.joint_torque_Nm = (t2 - t1) * r;
  t.load_cell_torque_Nm = a * theta;
}

void SeaPlant::electrical(Channel& c, double duty, bool bridge_on, double h) {
  const SeaPlantParams& p = config_.params;
  const double n = p.gear_ratio;
  const double kt = p.torque_constant_Nm_per_A;
  const double r_total = p.motor_resistance_Ohm + p.bridge_on_resistance_Ohm;

  // Armature: L di/dt = V − R i − k_e N ω, exact over the substep for a constant V and ω. The bridge regulates
  // the current cycle by cycle at its limit. Disabled bridge: high impedance, the current collapses through the
  // body diodes within microseconds (back-EMF stays below the supply at every reachable speed), so i = 0.
  double voltage = 0.0;
  if (bridge_on) {
    voltage = std::clamp(duty, -1.0, 1.0) * p.supply_V;
    const double i_ss = (voltage - kt * n * c.omega_m) / r_total;
    c.current = i_ss + (c.current - i_ss) * std::exp(-h * r_total / p.motor_inductance_H);
    c.current = std::clamp(c.current, -p.bridge_current_limit_A, p.bridge_current_limit_A);
  } else {
    c.current = 0.0;
  }
  c.truth.motor_voltage_V = voltage;
  c.truth.bridge_on = bridge_on;
}

// Bowden cable play: the spring side follows the motor side only once the motor has taken up the play.
void SeaPlant::play(Channel& c) {
  const double x_m = c.p.motor_pulley_radius_m * c.theta_m;
  const double half = 0.5 * (c.p.backlash_base_m + c.p.backlash_per_Nm_m * std::fabs(c.truth.joint_torque_Nm));
  c.x_e = std::clamp(c.x_e, x_m - half, x_m + half);
  c.truth.cable_motor_m = x_m;
  c.truth.backlash_m = 2.0 * half;
}

void SeaPlant::motorMechanics(Channel& c, double h) {
  const SeaPlantParams& p = config_.params;
  const double n = p.gear_ratio;
  const double kt = p.torque_constant_Nm_per_A;
  const double x_m = c.truth.cable_motor_m;
  const double half = 0.5 * c.truth.backlash_m;
  const double sheath_N = c.p.sheath_friction * (c.truth.tension1_N + c.truth.tension2_N);
  const double s = half > 0.0 ? (x_m - c.x_e) / half : 0.0;
  double cable_load = c.p.motor_pulley_radius_m * ((c.truth.tension2_N - c.truth.tension1_N) + sheath_N * s);
  if (half > 0.0 && std::fabs(s) < 1.0) {
    // Damping of the stretch inside the play: ζ · 2√(k_play J) with k_play = r_m² F_s / (b/2) at the pulley.
    const double k_play = c.p.motor_pulley_radius_m * c.p.motor_pulley_radius_m * sheath_N / half;
    cable_load += c.p.play_damping_ratio * 2.0 * std::sqrt(k_play * c.inertia) * c.omega_m;
  }

  // Motor + gearhead at the pulley: Coulomb friction (no-load friction + the gear loss on the transmitted motor
  // torque), with stiction, integrated at the velocity level so that a stuck drive stays exactly stuck.
  const double tau_motor = n * kt * c.current;
  double coulomb = n * kt * p.no_load_current_A + (1.0 - p.gear_efficiency) * std::fabs(tau_motor);
  if (half <= 0.0) coulomb += c.p.motor_pulley_radius_m * sheath_N;  // rigid cable: sheath friction at the motor
  const double v_free = c.omega_m + h * (tau_motor - cable_load) / c.inertia;
  const double dv_friction = h * coulomb / c.inertia;
  c.omega_m = std::fabs(v_free) <= dv_friction ? 0.0 : v_free - sign(v_free) * dv_friction;
  c.theta_m += h * c.omega_m;

  SeaTruth& t = c.truth;
  t.motor_angle_rad = c.theta_m;
  t.motor_speed_rad_s = c.omega_m;
  t.motor_current_A = c.current;
  t.cable_spring_m = c.x_e;
  t.cable_load_torque_Nm = cable_load;
}

void SeaPlant::step(double dt_s, SimIo& io) { advance(dt_s, 1, io); }

void SeaPlant::advance(double dt_s, unsigned steps, SimIo& io) {
  if (!(std::isfinite(dt_s) && dt_s > 0.0 && dt_s <= 1.0)) {
    throw std::invalid_argument("SeaPlant::step: dt_s must be finite and in (0, 1]");
  }
  if (steps == 0) return;
  const bool bridge_on = io.pwm_enabled && io.drive_enable && !io.estop_pressed;
  std::array<double, 2> duty{};
  for (size_t i = 0; i < ch_.size(); ++i) {
    duty[i] = asDouble(io.pwm_duty[i]);
    if (!std::isfinite(duty[i])) duty[i] = 0.0;
  }
  for (unsigned s = 0; s < steps; ++s) stepPhysics(dt_s, bridge_on, duty);
  // The samples of the steps before the last are overwritten unread: skip their draws in the noise stream
  // (sample() takes a normal for each joint sensor and current, and each load cell on the rig; 2 words each).
  const bool rig = config_.variant == SeaVariant::kRig;
  const unsigned long long normals = board::kJointSensorCount + ch_.size() * (rig ? 2u : 1u);
  if (steps > 1) rng_.discard(2ull * normals * (steps - 1));
  sample(io);
}

void SeaPlant::stepPhysics(double dt_s, bool bridge_on, const std::array<double, 2>& duty) {
  const auto n = static_cast<long>(std::ceil(dt_s / config_.params.max_substep_s - 1e-9));
  const double h = dt_s / static_cast<double>(n);
  const bool rig = config_.variant == SeaVariant::kRig;
  for (long k = 0; k < n; ++k) {
    for (size_t i = 0; i < ch_.size(); ++i) {
      Channel& c = ch_[i];
      electrical(c, duty[i], bridge_on, h);
      play(c);
      if (rig) {
        solveJoint(c);
      } else {
        tensions(c);
      }
      motorMechanics(c, h);
    }
    if (!rig) fingerDynamics(h);
    time_s_ += h;
  }
  if (!rig) {
    // Truth at the end of the step; the DIP sensor angle it leaves is the next step's kinematics input.
    fingerDynamics(0.0);
    fingerSensors();
  }
}

double SeaPlant::gaussian() {
  const auto u = [this] { return (static_cast<double>(rng_()) + 0.5) * (1.0 / 4294967296.0); };
  const double u1 = u();
  const double u2 = u();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

void SeaPlant::sample(SimIo& io) {
  const SeaPlantParams& p = config_.params;
  const double noise = config_.noise ? 1.0 : 0.0;
  const double mid = static_cast<double>(board::kAdcMidCounts);
  // Joint sensors. Rig: sensors 0 and 1 sit on the clamped SEA joints, mounted at mid-scale; the other three
  // on an unmoving fixture. Finger: the five angles of the closed chains (kinematics.h SensorIndex).
  const bool rig = config_.variant == SeaVariant::kRig;
  for (int s = 0; s < board::kJointSensorCount; ++s) {
    const auto si = static_cast<size_t>(s);
    const double centre = asDouble(board::kJointCentre_rad[si]);
    const double angle = rig ? centre + (s < 2 ? ch_[si].theta_j : 0.0) : finger_.sensors_rad[si] + donning_rad_[si];
    const double counts = mid + (angle - centre) * asDouble(board::kJointCountsPerRad);
    io.adc[static_cast<size_t>(board::kAdcFirstJoint + s)] = toCounts(counts + noise * p.joint_noise_counts * gaussian());
  }
  for (size_t i = 0; i < ch_.size(); ++i) {
    const Channel& c = ch_[i];
    // Encoder at the motor shaft; quantised to whole counts (floor, as a quadrature counter does).
    const double motor_counts = c.theta_m / asDouble(board::kMotorRadPerCount);
    io.encoder[i] = static_cast<int32_t>(std::floor(motor_counts));
    const double current_counts = mid + c.current * asDouble(board::kCurrentCountsPerAmp);
    io.adc[static_cast<size_t>(board::kAdcFirstCurrent) + i] =
        toCounts(current_counts + noise * p.current_noise_counts * gaussian());
    // Load cell: only on the rig (the finger device has none; its input reads mid-scale).
    const double lc_counts = mid + c.truth.load_cell_torque_Nm * asDouble(board::kLoadCellCountsPerNm);
    io.adc[static_cast<size_t>(board::kAdcFirstLoadCell) + i] =
        rig ? toCounts(lc_counts + noise * p.load_cell_noise_counts * gaussian()) : board::kAdcMidCounts;
  }
}

}  // namespace phalanx::sim
