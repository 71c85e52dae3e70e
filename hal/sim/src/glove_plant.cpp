#include "phalanx/sim/glove_plant.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace phalanx::sim {

namespace {

using glove::Mat3;
using glove::Vec3;
namespace board = glove::board;

constexpr double kPi = glove::kPi<double>;
constexpr double degToRad(double deg) { return deg * kPi / 180.0; }
double sq(double x) { return x * x; }
double sign(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }
double dot3(const Vec3<double>& a, const Vec3<double>& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double asDouble(float x) { return static_cast<double>(x); }

// ---- Hand motion: a one-parameter closure synergy θ(s) = open + s·(closed − open), s ∈ [0, 1] --------------
// s = 0 is an open hand with slight MCP hyperextension, s = 1 a full fist, both inside Table 2's ranges
// (MCP [-90, 30]°, PIP [-120, 0]°, DIP [-80, 0]°). The three joints of a finger flex together (the DIP–PIP
// coupling of a free finger), which is how the §4.3 close/open maneuvers look.
constexpr Vec3<double> kSynergyOpen_deg = {20.0, -2.0, -2.0};
constexpr Vec3<double> kSynergyClosed_deg = {-85.0, -115.0, -75.0};
// Per-finger variation (thumb, index, middle, ring, little): where "open" and "closed" sit on the synergy,
// the relaxed posture of kStill, and the onset delay of each finger (a hand never moves as one block).
constexpr std::array<double, 5> kOpenS = {0.12, 0.10, 0.10, 0.11, 0.13};
constexpr std::array<double, 5> kClosedS = {0.80, 0.86, 0.88, 0.86, 0.83};
constexpr std::array<double, 5> kStillS = {0.30, 0.33, 0.36, 0.38, 0.40};
constexpr std::array<double, 5> kDelay_s = {0.0, 0.02, 0.04, 0.06, 0.08};
// kCloseOpen timing (§4.3: "about 1 s for one full close/open maneuver", two maneuvers in ≈ 3 s).
constexpr double kCloseOpenLeadIn_s = 0.5;
constexpr double kManeuver_s = 1.0;
constexpr double kCloseOpenPeriod_s = 1.5;
// kGrasp timing: reach starts after 0.3 s and the intent reaches a full fist (s = 1) after 0.8 s more.
constexpr double kGraspStart_s = 0.3;
constexpr double kGraspDuration_s = 0.8;
constexpr double kGraspTargetS = 1.0;
// kGrasp: the effort bound never drops below this joint torque, so the finger can always move freely.
constexpr double kMinEffort_Nm = 0.005;
// kRandom: closure s ∈ 0.5 ± 0.36, band 0.1–1.0 Hz; per-joint deviations ±8°, band 0.2–1.5 Hz.
constexpr double kRandomCentreS = 0.5;
constexpr double kRandomSpanS = 0.36;
constexpr double kRandomJointSpan_rad = 8.0 * kPi / 180.0;
// kPush: time constant of the person's fingertip-force regulation (a slow tactile loop, a few Hz).
constexpr double kPushForceLoop_s = 0.15;

double uniform01(std::mt19937& rng) { return (static_cast<double>(rng()) + 0.5) * (1.0 / 4294967296.0); }
double uniform(std::mt19937& rng, double lo, double hi) { return lo + (hi - lo) * uniform01(rng); }
/// Portable standard normal (Box–Muller on mt19937 words: the same numbers with every standard library).
double normal(std::mt19937& rng) {
  const double u1 = uniform01(rng);
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}
// Words of the noise stream one sample() of an enabled finger takes: 3 Hall + 1 strain + 1 current normal,
// 2 words each (normal()).
constexpr unsigned long long kNoiseWordsPerSample = 10;
double clippedNormal(std::mt19937& rng, double sigma) { return sigma * std::clamp(normal(rng), -3.0, 3.0); }

bool finitePositive(double x) { return std::isfinite(x) && x > 0.0; }
bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }

void requireValid(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(what);
}

void validate(const GlovePlantConfig& c) {
  const GlovePlantParams& p = c.params;
  requireValid(finitePositive(c.squeeze_force_N), "GlovePlantConfig: squeeze_force_N must be finite and > 0");
  requireValid(finiteNonNegative(c.push_force_N), "GlovePlantConfig: push_force_N must be finite and >= 0");
  requireValid(finitePositive(c.push_ramp_s), "GlovePlantConfig: push_ramp_s must be finite and > 0");
  requireValid(!std::isnan(c.push_until_s) && c.push_until_s >= 0.0, "GlovePlantConfig: push_until_s must be >= 0");
  const double positive[] = {p.rotor_inertia_kg_m2, p.spur_efficiency, p.worm_lead_rad, p.worm_friction_coeff,
                             p.spool_inertia_kg_m2, p.worm_wheel_inertia_kg_m2, p.passive_hold_margin,
                             p.slip_kinetic_fraction, p.pad_transmission, p.tendon_stiffness_N_per_m,
                             p.spool_segment_fraction, p.pad_stiffness_N_per_m, p.phalanx_mass_per_length_kg_per_m,
                             p.muscle_damping_ratio, p.limit_stiffness_Nm_per_rad, p.pad_thermal_time_s,
                             p.max_substep_s};
  for (double v : positive) requireValid(finitePositive(v), "GlovePlantParams: a value that must be > 0 is not");
  const double non_negative[] = {p.motor_coulomb_friction_Nm, p.motor_viscous_Nm_s_per_rad,
                                 p.slip_damping_Nm_s_per_rad, p.tendon_damping_N_s_per_m, p.pretension_N,
                                 p.passive_damping_Nm_s_per_rad, p.limit_damping_Nm_s_per_rad,
                                 p.hall_noise_counts, p.strain_amp_noise_counts, p.adc_noise_counts,
                                 p.pad_warmup_K, p.strain_zero_tc_N_per_K,
                                 p.current_noise_counts, p.hall_gain_error, p.hall_offset_error_counts,
                                 p.hall_angle_error_rad, p.strain_gain_error, p.strain_offset_error_N,
                                 p.current_gain_error, p.current_offset_error_counts};
  for (double v : non_negative) requireValid(finiteNonNegative(v), "GlovePlantParams: a value must be >= 0");
  for (std::size_t j = 0; j < 3; ++j) {
    requireValid(finitePositive(p.muscle_stiffness_Nm_per_rad[j]), "GlovePlantParams: muscle stiffness");
    requireValid(finiteNonNegative(p.passive_stiffness_Nm_per_rad[j]), "GlovePlantParams: passive stiffness");
    requireValid(std::isfinite(p.ref_pose_deg[j]) && std::isfinite(p.rest_pose_deg[j]), "GlovePlantParams: pose");
  }
  requireValid(p.spur_efficiency <= 1.0 && p.slip_kinetic_fraction <= 1.0, "GlovePlantParams: efficiency > 1");
  requireValid(p.spool_segment_fraction < 1.0, "GlovePlantParams: spool_segment_fraction must be < 1");
  requireValid(p.max_substep_s <= 1e-3, "GlovePlantParams: max_substep_s must be <= 1 ms");
  requireValid(finiteNonNegative(c.worn_before_start_s), "GlovePlantConfig: worn_before_start_s must be finite and >= 0");
  // Self-locking needs the lead angle below the friction angle (λ < ρ); the forward efficiency is then < 50 %.
  requireValid(p.worm_lead_rad < std::atan(p.worm_friction_coeff), "GlovePlantParams: worm is not self-locking");
}

std::int32_t toCounts(double value) {
  const double clamped = std::clamp(value, 0.0, static_cast<double>(board::kAdcMaxCounts));
  return static_cast<std::int32_t>(std::lround(clamped));
}

}  // namespace

// Everything one evaluation of a finger produces: forces and accelerations from the state at one instant.
struct GlovePlant::Eval {
  Vec3<double> theta_d{}, theta_d_dot{};
  Vec3<double> alpha{}, u{}, n{}, tau{};
  Vec3<double> F{}, tau_alpha{};  // truth only: filled by truthWrench(), not on the integration path
  bool kin_ok = true;
  double pad_N = 0;
  double q_m_dot = 0;  // release-path shortening rate (m/s)
  double tr_spool = 0, tr_tip = 0, tg_spool = 0, tg_tip = 0;
  double wrap_r = 0, wrap_g = 0;
  double x_release = 0, x_grasp = 0;  // capstan contact positions after this evaluation
  int slide_release = 0, slide_grasp = 0;
  double tau_load_Nm = 0;  // tendon torque on the spool, + turns it +
  double voltage_V = 0, current_A = 0;
  double push_target_N = 0;  // kPush: the pad force the person aims for now
  double push_effort_cap = 1;  // kPush: fraction of the maximum effort left (falls to 0 as the person lets go)
  // Linearly implicit finger step: local joint stiffness/damping (diagonal) and the tendon's rank-1 terms
  // along a = ∂q_m/∂θ.
  Vec3<double> k_diag{}, b_diag{}, a{};
  double k_tendon = 0, b_tendon = 0;
};

/// One tendon of the antagonistic pair: two springs joined by the capstan contact on the pulleys.
/// u_s: tendon wound onto the spool, u_m: shortening of its path at the mechanism (both m, 0 at start),
/// x_prev: cable passed over the pulleys towards the spool so far (m). Eq 15 with stiction: the contact
/// sticks while e^{-μγ} ≤ T_spool/T_tip ≤ e^{μγ}; beyond, the cable slides and the ratio sits at the bound,
/// F1 being the end the cable slides towards. Rate independent, as §4.2 measured it.
GlovePlant::TendonState GlovePlant::solveTendon(const GloveFingerConstants& k, double u_s, double u_m,
                                                double x_prev, double ratio) {
  const double k1 = k.spool_segment_stiffness_N_per_m;
  const double k2 = k.tip_segment_stiffness_N_per_m;
  const double e1 = k.pretension_stretch_spool_m + u_s;  // spool segment stretch for x = 0
  const double e2 = k.pretension_stretch_tip_m - u_m;    // tip segment stretch for x = 0
  TendonState st{};
  st.x_m = x_prev;
  if (e1 + e2 <= 0.0) return st;  // the whole tendon is slack: no tension, the contact does not move
  st.spool_N = k1 * std::max(0.0, e1 - x_prev);
  st.tip_N = k2 * std::max(0.0, e2 + x_prev);
  if (st.spool_N > ratio * st.tip_N) {
    // The spool pulls harder than friction holds: slides towards the spool until T_spool = e^{μγ}·T_tip.
    st.x_m = (k1 * e1 - ratio * k2 * e2) / (k1 + ratio * k2);
    st.tip_N = k2 * (e2 + st.x_m);
    st.spool_N = ratio * st.tip_N;
    st.sliding = 1;
  } else if (st.tip_N > ratio * st.spool_N) {
    // The finger pulls the tendon out: slides towards the tip until T_tip = e^{μγ}·T_spool.
    st.x_m = (ratio * k1 * e1 - k2 * e2) / (ratio * k1 + k2);
    st.spool_N = k1 * (e1 - st.x_m);
    st.tip_N = ratio * st.spool_N;
    st.sliding = -1;
  }
  return st;
}

GlovePlant::GlovePlant(const GlovePlantConfig& config) : config_(config), noise_rng_(config.seed) {
  validate(config_);
  const GlovePlantParams& p = config_.params;
  mu_ = config_.lubrication == TendonLubrication::kDry ? glove::kMuDry<double> : glove::kMuLubricated<double>;
  const double rho = std::atan(p.worm_friction_coeff);
  worm_eff_forward_ = std::tan(p.worm_lead_rad) / std::tan(p.worm_lead_rad + rho);
  worm_eff_backward_ = std::tan(p.worm_lead_rad - rho) / std::tan(p.worm_lead_rad);
  const double adc_noise = p.adc_noise_counts / std::sqrt(static_cast<double>(board::kAdcOversampling));
  strain_noise_counts_ = std::sqrt(p.strain_amp_noise_counts * p.strain_amp_noise_counts + adc_noise * adc_noise);
  // Separate streams, so that switching noise or calibration errors never changes the hand's motion.
  std::mt19937 calib_rng(config_.seed ^ 0x9E3779B9u);
  std::mt19937 motion_rng(config_.seed ^ 0x7F4A7C15u);
  for (int i = 0; i < board::kFingerCount; ++i) initFinger(fingers_[i], i, calib_rng, motion_rng);
}

int GlovePlant::idx(int finger) {
  if (finger < 0 || finger >= board::kFingerCount) throw std::out_of_range("GlovePlant: finger index must be 0..4");
  return finger;
}

void GlovePlant::initFinger(Finger& f, int index, std::mt19937& calib_rng, std::mt19937& motion_rng) {
  const GlovePlantParams& p = config_.params;
  f.index = index;
  f.enabled = config_.finger_enabled[index];
  f.cables = !config_.cables_removed[index];
  GloveFingerConstants& k = f.k;
  k.model = glove::defaultModel<double>(static_cast<glove::FingerId>(index));
  k.capstan = glove::makeCapstanModel(k.model.mech, mu_);
  k.pad_transmission = p.pad_transmission;
  for (std::size_t j = 0; j < 3; ++j) k.ref_theta_rad[j] = degToRad(p.ref_pose_deg[j]);
  if (!glove::isUsable(glove::alphaFromTheta(k.model, k.ref_theta_rad, k.ref_alpha_rad))) {
    throw std::invalid_argument("GlovePlantParams: ref_pose_deg is not reachable by the glove mechanism");
  }

  // Tendon and pad in series. The pad deflects δ = F/k_pad = c·T/k_pad; seen along the tendon that is
  // c·δ = c²·T/k_pad. The capstan contact splits the tendon into a spool segment and a tip segment (which
  // also carries the pad compliance).
  const double c = p.pad_transmission;
  k.spool_segment_stiffness_N_per_m = p.tendon_stiffness_N_per_m / p.spool_segment_fraction;
  k.tip_segment_stiffness_N_per_m =
      1.0 / ((1.0 - p.spool_segment_fraction) / p.tendon_stiffness_N_per_m + sq(c) / p.pad_stiffness_N_per_m);
  k.series_stiffness_N_per_m =
      1.0 / (1.0 / k.spool_segment_stiffness_N_per_m + 1.0 / k.tip_segment_stiffness_N_per_m);
  k.pad_stiffness_locked_N_per_m = sq(c) * k.series_stiffness_N_per_m;
  k.pretension_stretch_spool_m = p.pretension_N / k.spool_segment_stiffness_N_per_m;
  k.pretension_stretch_tip_m = p.pretension_N / k.tip_segment_stiffness_N_per_m;

  // Passive limit (§2.2: "passive force as high as 35 N"). A finger pressing on the locked glove pulls the
  // release tendon out against the capstan friction of the routing, so the spool sees the tip tension
  // divided by e^{μ_L γ}; the nominal lubricated μ is used because the slip torque is a property of the
  // gear, not of the lubrication setting. 35 N at the pad at θ_ref is a tip tension of 35 N / c.
  const double gamma_ref = glove::wrapAngle_rad(k.capstan, glove::Tendon::kRelease, k.ref_alpha_rad);
  k.slip_torque_Nm = p.passive_hold_margin * asDouble(board::kSpoolRadius_m) *
                     (asDouble(board::kPassiveHoldForce_N) / c) /
                     glove::capstanRatio(glove::kMuLubricated<double>, gamma_ref);

  // Finger: phalanx masses ∝ length; diagonal joint inertias in the extended posture (an upper bound).
  const std::array<double, 3> len = {k.model.finger.p1_m, k.model.finger.p2_m, k.model.finger.p3_m};
  for (std::size_t j = 0; j < 3; ++j) {
    double inertia = 0.0;
    double dist = 0.0;  // from joint j to the start of segment s
    for (std::size_t s = j; s < 3; ++s) {
      const double m = p.phalanx_mass_per_length_kg_per_m * len[s];
      inertia += m * sq(len[s]) / 12.0 + m * sq(dist + 0.5 * len[s]);
      dist += len[s];
    }
    k.inertia_kg_m2[j] = inertia;
  }
  // Muscle impedance: index values scaled by (finger length / index length)², so that every fingertip has
  // about the same stiffness (fingertip stiffness ≈ K / L²).
  const glove::Model<double> index_model = glove::defaultModel<double>(glove::FingerId::kIndex);
  const double l_index = index_model.finger.p1_m + index_model.finger.p2_m + index_model.finger.p3_m;
  const double scale = sq((len[0] + len[1] + len[2]) / l_index);
  for (std::size_t j = 0; j < 3; ++j) {
    k.muscle_stiffness_Nm_per_rad[j] = p.muscle_stiffness_Nm_per_rad[j] * scale;
    k.muscle_damping_Nm_s_per_rad[j] =
        2.0 * p.muscle_damping_ratio * std::sqrt(k.muscle_stiffness_Nm_per_rad[j] * k.inertia_kg_m2[j]);
  }

  // Scenario shaping.
  f.s_open = kOpenS[index];
  f.s_closed = kClosedS[index];
  f.s_still = kStillS[index];
  f.delay_s = kDelay_s[index];
  RandomMotion& rm = f.random;
  for (int i = 0; i < RandomMotion::kClosureTerms; ++i) {
    rm.closure_amp[i] = uniform(motion_rng, 0.5, 1.0);
    rm.closure_freq_hz[i] = uniform(motion_rng, 0.1, 1.0);
    rm.closure_phase_rad[i] = uniform(motion_rng, 0.0, 2.0 * kPi);
  }
  for (std::size_t j = 0; j < 3; ++j) {
    for (int i = 0; i < RandomMotion::kJointTerms; ++i) {
      rm.joint_amp_rad[j][i] = uniform(motion_rng, 0.5, 1.0);
      rm.joint_freq_hz[j][i] = uniform(motion_rng, 0.2, 1.5);
      rm.joint_phase_rad[j][i] = uniform(motion_rng, 0.0, 2.0 * kPi);
    }
  }

  // Per-sensor calibration errors: always drawn (keeps the stream aligned), applied only when enabled.
  const double on = config_.calibration_errors ? 1.0 : 0.0;
  for (std::size_t j = 0; j < 3; ++j) {
    f.err.hall_gain[j] = on * clippedNormal(calib_rng, p.hall_gain_error);
    f.err.hall_offset_counts[j] = on * clippedNormal(calib_rng, p.hall_offset_error_counts);
    f.err.hall_angle_rad[j] = on * clippedNormal(calib_rng, p.hall_angle_error_rad);
  }
  f.err.strain_gain = on * clippedNormal(calib_rng, p.strain_gain_error);
  f.err.strain_offset_N = on * clippedNormal(calib_rng, p.strain_offset_error_N);
  f.err.current_gain = on * clippedNormal(calib_rng, p.current_gain_error);
  f.err.current_offset_counts = on * clippedNormal(calib_rng, p.current_offset_error_counts);
  f.err.strain_zero_tc_N_per_K = on * clippedNormal(calib_rng, p.strain_zero_tc_N_per_K);

  // Initial state: the finger at its intent, both tendons at their pretension, worm at rest and locked.
  Vec3<double> theta_d{}, theta_d_dot{};
  intent(f, 0.0, theta_d, theta_d_dot);
  f.theta = theta_d;
  f.theta_dot = theta_d_dot;
  if (!glove::isUsable(glove::alphaFromTheta(k.model, f.theta, f.alpha_last))) {
    throw std::invalid_argument("GlovePlant: initial finger pose not reachable by the glove mechanism");
  }
  Eval e{};
  evaluate(f, 0.0, 0.0, false, e);
  truthWrench(f, e);
  fillTruth(f, e, false);
}

double GlovePlant::closureS(const Finger& f, double t, double& s_dot) const {
  s_dot = 0.0;
  switch (config_.scenario) {
    case HandScenario::kCloseOpen: {
      const double t0 = t - kCloseOpenLeadIn_s - f.delay_s;
      if (t0 < 0.0) return f.s_open;
      const double phase = std::fmod(t0, kCloseOpenPeriod_s);
      if (phase >= kManeuver_s) return f.s_open;
      // Raised cosine: open → closed → open in kManeuver_s, zero velocity at both ends.
      const double w = 2.0 * kPi / kManeuver_s;
      s_dot = (f.s_closed - f.s_open) * 0.5 * w * std::sin(w * phase);
      return f.s_open + (f.s_closed - f.s_open) * 0.5 * (1.0 - std::cos(w * phase));
    }
    case HandScenario::kGrasp: {
      const double t0 = t - kGraspStart_s - f.delay_s;
      if (t0 <= 0.0) return f.s_open;
      const double tau = std::min(1.0, t0 / kGraspDuration_s);
      // Minimum-jerk reach towards a full fist: an object in the way stops the finger, not the intent.
      const double shape = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
      const double shape_dot = 30.0 * tau * tau * (1.0 - tau) * (1.0 - tau) / kGraspDuration_s;
      s_dot = (kGraspTargetS - f.s_open) * shape_dot;
      return f.s_open + (kGraspTargetS - f.s_open) * shape;
    }
    case HandScenario::kRandom: {
      const RandomMotion& rm = f.random;
      double sum = 0.0, sum_dot = 0.0, norm = 0.0;
      for (int i = 0; i < RandomMotion::kClosureTerms; ++i) {
        const double w = 2.0 * kPi * rm.closure_freq_hz[i];
        sum += rm.closure_amp[i] * std::sin(w * t + rm.closure_phase_rad[i]);
        sum_dot += rm.closure_amp[i] * w * std::cos(w * t + rm.closure_phase_rad[i]);
        norm += rm.closure_amp[i];
      }
      s_dot = kRandomSpanS * sum_dot / norm;
      return kRandomCentreS + kRandomSpanS * sum / norm;
    }
    case HandScenario::kStill:
    case HandScenario::kPush:
    default:
      return f.s_still;
  }
}

void GlovePlant::intent(const Finger& f, double t, Vec3<double>& theta_d, Vec3<double>& theta_d_dot) const {
  if (config_.scenario == HandScenario::kPush) {
    theta_d = f.k.ref_theta_rad;
    theta_d_dot = {0.0, 0.0, 0.0};
    return;
  }
  const glove::FingerGeometry<double>& g = f.k.model.finger;
  double s_dot = 0.0;
  const double s = closureS(f, t, s_dot);
  for (std::size_t j = 0; j < 3; ++j) {
    const double span = degToRad(kSynergyClosed_deg[j] - kSynergyOpen_deg[j]);
    theta_d[j] = degToRad(kSynergyOpen_deg[j]) + s * span;
    theta_d_dot[j] = s_dot * span;
    if (config_.scenario == HandScenario::kRandom) {
      const RandomMotion& rm = f.random;
      double sum = 0.0, sum_dot = 0.0, norm = 0.0;
      for (int i = 0; i < RandomMotion::kJointTerms; ++i) {
        const double w = 2.0 * kPi * rm.joint_freq_hz[j][i];
        sum += rm.joint_amp_rad[j][i] * std::sin(w * t + rm.joint_phase_rad[j][i]);
        sum_dot += rm.joint_amp_rad[j][i] * w * std::cos(w * t + rm.joint_phase_rad[j][i]);
        norm += rm.joint_amp_rad[j][i];
      }
      theta_d[j] += kRandomJointSpan_rad * sum / norm;
      theta_d_dot[j] += kRandomJointSpan_rad * sum_dot / norm;
    }
    if (theta_d[j] < g.theta_min_rad[j] || theta_d[j] > g.theta_max_rad[j]) {
      theta_d[j] = std::clamp(theta_d[j], g.theta_min_rad[j], g.theta_max_rad[j]);
      theta_d_dot[j] = 0.0;
    }
  }
}

void GlovePlant::evaluate(const Finger& f, double t, double duty, bool bridge_on, Eval& e) const {
  const GlovePlantParams& p = config_.params;
  const GloveFingerConstants& k = f.k;
  const double c = k.pad_transmission;
  intent(f, t, e.theta_d, e.theta_d_dot);

  // Kinematics: the massless glove follows the finger through the closure α = f(θ) (eq 6–8).
  // The sines and cosines of θ are computed once for α, J_θ^u and u.
  const glove::ThetaTrig<double> trig = glove::thetaTrig(f.theta);
  e.kin_ok = glove::allFinite(f.theta) && glove::isUsable(glove::alphaFromTheta(k.model, trig, e.alpha));
  if (!e.kin_ok) e.alpha = f.alpha_last;
  const Mat3<double> Jt = glove::jacobianThetaU(k.model.finger, trig);
  e.u = glove::tipPoseFromTheta(k.model.finger, trig);
  const Vec3<double>& n = e.n = glove::padNormal(e.u[2]);
  // The tendon acts on the fingertip as a pad-normal force c·T (§3.4's model: only f_y, eq 18), so the
  // tendon path changes with the pad-normal motion of the fingertip: q̇_m = c·n·u̇, and the finger feels
  // a = ∂q_m/∂θ = c·(J_θ^u)ᵀ n per newton of net tension. The mechanism joint torques are
  // τ_α = (J_α^u)ᵀ F, i.e. effective moment arms c·(J_α^u)ᵀ n that change with the pose.
  const Vec3<double> Jtn = glove::mulTransposed(Jt, n);
  for (std::size_t j = 0; j < 3; ++j) e.a[j] = c * Jtn[j];
  e.q_m_dot = dot3(e.a, f.theta_dot);

  // Tendons. q_m: shortening of the release path (= lengthening of the grasp path) since construction;
  // q_s: release tendon wound on the spool (the grasp tendon is unwound by the same length).
  e.tr_spool = e.tr_tip = e.tg_spool = e.tg_tip = 0.0;
  e.x_release = f.x_release;
  e.x_grasp = f.x_grasp;
  e.slide_release = e.slide_grasp = 0;
  e.wrap_r = glove::wrapAngle_rad(k.capstan, glove::Tendon::kRelease, e.alpha);
  e.wrap_g = glove::wrapAngle_rad(k.capstan, glove::Tendon::kGrasp, e.alpha);
  double taut = 0.0;
  if (f.cables) {
    const double r_s = asDouble(board::kSpoolRadius_m);
    const double q_s = r_s * f.spool_angle;
    const TendonState release = solveTendon(k, q_s, f.q_m, f.x_release, glove::capstanRatio(mu_, e.wrap_r));
    const TendonState grasp = solveTendon(k, -q_s, -f.q_m, f.x_grasp, glove::capstanRatio(mu_, e.wrap_g));
    // Material damping of the whole tendon (Kelvin–Voigt on its total stretch rate): the same force along it.
    const double damp = p.tendon_damping_N_s_per_m * (r_s * f.spool_speed - e.q_m_dot);
    const auto withDamping = [](double tension, double force) {
      return tension > 0.0 ? std::max(0.0, tension + force) : 0.0;
    };
    e.tr_spool = withDamping(release.spool_N, damp);
    e.tr_tip = withDamping(release.tip_N, damp);
    e.tg_spool = withDamping(grasp.spool_N, -damp);
    e.tg_tip = withDamping(grasp.tip_N, -damp);
    e.x_release = release.x_m;
    e.x_grasp = grasp.x_m;
    e.slide_release = release.sliding;
    e.slide_grasp = grasp.sliding;
    taut = (release.tip_N > 0.0 ? 1.0 : 0.0) + (grasp.tip_N > 0.0 ? 1.0 : 0.0);
  }
  const double net_tip = e.tr_tip - e.tg_tip;
  e.pad_N = c * net_tip;

  // Finger: muscle impedance towards θ_d (with the passive torque at θ_d fed forward, as the CNS does),
  // passive stiffness/damping, soft range limits, and the glove.
  const glove::FingerGeometry<double>& g = k.model.finger;
  Vec3<double> tau_muscle{};
  for (std::size_t j = 0; j < 3; ++j) {
    const double rest = degToRad(p.rest_pose_deg[j]);
    tau_muscle[j] = k.muscle_stiffness_Nm_per_rad[j] * (e.theta_d[j] - f.theta[j]) +
                    k.muscle_damping_Nm_s_per_rad[j] * (e.theta_d_dot[j] - f.theta_dot[j]) +
                    p.passive_stiffness_Nm_per_rad[j] * (e.theta_d[j] - rest);
  }
  e.push_target_N = 0.0;
  e.push_effort_cap = 1.0;
  if (config_.scenario == HandScenario::kGrasp) {
    // Effort saturates at the squeeze force: the joint torques that a pad-normal force of that size needs.
    for (std::size_t j = 0; j < 3; ++j) {
      const double limit = std::fabs(Jtn[j]) * config_.squeeze_force_N + kMinEffort_Nm;
      tau_muscle[j] = std::clamp(tau_muscle[j], -limit, limit);
    }
  } else if (config_.scenario == HandScenario::kPush) {
    // The finger presses into the pad (along −a) with the effort push_effort_N (a tendon tension, N) and
    // holds its θ_ref posture (muscle + passive torque projected off a) in the two directions the tendon
    // leaves free. The person adjusts the effort by feel (integrate()).
    const double aa = dot3(e.a, e.a);
    Vec3<double> posture = tau_muscle;
    for (std::size_t j = 0; j < 3; ++j) {
      posture[j] -= p.passive_stiffness_Nm_per_rad[j] * (f.theta[j] - degToRad(p.rest_pose_deg[j]));
    }
    const double along = aa > 0.0 ? dot3(e.a, posture) / aa : 0.0;
    for (std::size_t j = 0; j < 3; ++j) tau_muscle[j] -= e.a[j] * (along + f.push_effort_N);
    const double on = std::min(1.0, t / config_.push_ramp_s);
    const double off = std::clamp((t - config_.push_until_s) / config_.push_ramp_s, 0.0, 1.0);
    e.push_target_N = config_.push_force_N * std::min(on, 1.0 - off);
    e.push_effort_cap = 1.0 - off;
  }
  for (std::size_t j = 0; j < 3; ++j) {
    const double rest = degToRad(p.rest_pose_deg[j]);
    const double kp = p.passive_stiffness_Nm_per_rad[j];
    const double tau_passive = -kp * (f.theta[j] - rest) - p.passive_damping_Nm_s_per_rad * f.theta_dot[j];
    const double over = f.theta[j] > g.theta_max_rad[j]   ? f.theta[j] - g.theta_max_rad[j]
                        : f.theta[j] < g.theta_min_rad[j] ? f.theta[j] - g.theta_min_rad[j]
                                                           : 0.0;
    const double k_limit = over != 0.0 ? p.limit_stiffness_Nm_per_rad : 0.0;
    const double b_limit = over != 0.0 ? p.limit_damping_Nm_s_per_rad : 0.0;
    const double tau_limit = -k_limit * over - b_limit * f.theta_dot[j];
    e.tau[j] = tau_muscle[j] + tau_passive + tau_limit + e.a[j] * net_tip;
    e.k_diag[j] = k.muscle_stiffness_Nm_per_rad[j] + kp + k_limit;
    e.b_diag[j] = k.muscle_damping_Nm_s_per_rad[j] + p.passive_damping_Nm_s_per_rad + b_limit;
  }
  e.k_tendon = taut * k.tip_segment_stiffness_N_per_m;
  e.b_tendon = taut * p.tendon_damping_N_s_per_m;

  // Tendon torque on the spool: the release tendon pulls it back (−), the grasp tendon forward (+).
  e.tau_load_Nm = -asDouble(board::kSpoolRadius_m) * (e.tr_spool - e.tg_spool);

  // Motor: averaged bridge voltage; the electrical time constant (≈ 0.1 ms) is neglected at these steps.
  const double gear = asDouble(board::kGearRatio);
  const double kt = asDouble(board::kMotorTorqueConstant_Nm_per_A);
  e.voltage_V = bridge_on ? duty * asDouble(board::kSupply_V) : 0.0;
  if (bridge_on) {
    const double r_total = asDouble(board::kMotorResistance_Ohm) + asDouble(board::kBridgeOnResistance_Ohm);
    const double limit = asDouble(board::kBridgeCurrentLimit_A);
    e.current_A = std::clamp((e.voltage_V - kt * gear * f.worm_speed) / r_total, -limit, limit);
  } else {
    // Bridge off: terminals open. No current can flow: the self-locking worm never lets the load spin the
    // motor fast enough to forward-bias the bridge's body diodes.
    e.current_A = 0.0;
  }
}

void GlovePlant::truthWrench(const Finger& f, Eval& e) {
  e.F = {e.pad_N * e.n[0], e.pad_N * e.n[1], 0.0};
  e.tau_alpha = glove::mechanismTorqueFromWrench(glove::jacobianAlphaU(f.k.model.mech, e.alpha), e.F);
}

void GlovePlant::integrate(Finger& f, const Eval& e, double h) {
  const GlovePlantParams& p = config_.params;
  const double gear = asDouble(board::kGearRatio);
  const double kt = asDouble(board::kMotorTorqueConstant_Nm_per_A);

  // ---- Worm drive. Spool coordinates: ω is the worm-wheel speed, torques are referred to the wheel.
  // Mesh with lead λ and friction angle ρ: steady motion in direction s against a load Q (torque opposing
  // + rotation) needs the (ideal-ratio) input torque Q·g, with g = 1/η_w when the worm drives the load
  // (Q·s > 0) and g = η_wb = tan(λ−ρ)/tan λ < 0 when the load would drive it — then the motor must still
  // push along the motion: the load can never back-drive the motor (self-locking). With the inertias:
  //   ω̇ = (τ_in + g·τ_load) / (J_in + g·J_load).
  const double tau_in = gear * p.spur_efficiency * kt * e.current_A;
  const double tau_coulomb_in = gear * p.spur_efficiency * p.motor_coulomb_friction_Nm;
  const double j_in = sq(gear) * p.rotor_inertia_kg_m2;
  // While the spool slips on the locked worm the wheel feels the kinetic slip torque instead of the tendons.
  const double slip_kinetic = p.slip_kinetic_fraction * f.k.slip_torque_Nm;
  double slip_dir = 0.0;
  if (f.slipping) {
    slip_dir = sign(f.spool_speed - f.worm_speed);
    if (slip_dir == 0.0) slip_dir = sign(e.tau_load_Nm);
  }
  const double tau_load = f.slipping ? slip_dir * slip_kinetic : e.tau_load_Nm;
  const double j_load = f.slipping ? p.worm_wheel_inertia_kg_m2 : p.spool_inertia_kg_m2;
  const double q = -tau_load;
  const double eta_f = worm_eff_forward_;
  const double eta_b = worm_eff_backward_;
  double worm_acc = 0.0;
  double dir = 0.0;
  if (f.worm_stuck) {
    // Break-away thresholds of the input torque for + and − motion (the motor's Coulomb friction added).
    const double thr_pos = q > 0.0 ? q / eta_f : q * eta_b;
    const double thr_neg = q > 0.0 ? q * eta_b : q / eta_f;
    if (tau_in - tau_coulomb_in > thr_pos) {
      dir = 1.0;
    } else if (tau_in + tau_coulomb_in < thr_neg) {
      dir = -1.0;
    }
    if (dir != 0.0) f.worm_stuck = false;
  } else {
    dir = sign(f.worm_speed);
  }
  if (!f.worm_stuck) {
    const double g = q * dir >= 0.0 ? 1.0 / eta_f : eta_b;
    const double tau_net = tau_in - dir * tau_coulomb_in -
                           gear * p.spur_efficiency * p.motor_viscous_Nm_s_per_rad * gear * f.worm_speed;
    worm_acc = (tau_net + g * tau_load) / (j_in + g * j_load);
    const double next = f.worm_speed + h * worm_acc;
    if (next * dir <= 0.0) {
      // Came to rest within the step: the worm locks; the next step decides whether it breaks away again.
      f.worm_speed = 0.0;
      f.worm_stuck = true;
      worm_acc = 0.0;
    } else {
      f.worm_speed = next;
    }
  }
  f.worm_angle += h * f.worm_speed;

  // ---- Spool on the worm wheel: held unless the tendon torque exceeds the passive limit (§2.2).
  if (!f.slipping) {
    const double clutch_torque = p.spool_inertia_kg_m2 * worm_acc - e.tau_load_Nm;
    if (std::fabs(clutch_torque) > f.k.slip_torque_Nm) {
      f.slipping = true;
      slip_dir = sign(e.tau_load_Nm);
    } else {
      f.spool_speed = f.worm_speed;
      f.spool_angle += h * f.spool_speed;
    }
  }
  if (f.slipping) {
    const double acc = (e.tau_load_Nm - slip_dir * slip_kinetic -
                        p.slip_damping_Nm_s_per_rad * (f.spool_speed - f.worm_speed)) /
                       p.spool_inertia_kg_m2;
    const double next = f.spool_speed + h * acc;
    if ((next - f.worm_speed) * slip_dir <= 0.0 && std::fabs(e.tau_load_Nm) <= f.k.slip_torque_Nm) {
      f.slipping = false;  // the relative motion stopped and the load is back within the limit: grips again
      f.spool_speed = f.worm_speed;
    } else {
      f.spool_speed = next;
    }
    f.spool_angle += h * f.spool_speed;
  }

  // ---- kPush: the person regulates the fingertip force by feel — the effort integrates the force error
  // with a 0.15 s time constant, never negative, at most twice the nominal effort; letting go (push_until_s),
  // that bound falls to 0 with the target: a relaxed finger does not regulate a zero force, it stops pushing.
  if (config_.scenario == HandScenario::kPush) {
    const double c = f.k.pad_transmission;
    f.push_effort_N += h * (e.push_target_N - e.pad_N) / (c * kPushForceLoop_s);
    f.push_effort_N = std::clamp(f.push_effort_N, 0.0, e.push_effort_cap * 2.0 * config_.push_force_N / c);
  }

  // ---- Finger: linearly implicit Euler, (M + h·B + h²·K)·Δθ̇ = h·τ, then θ += h·θ̇, with B and K the
  // diagonal local joint terms plus the tendon's rank-1 terms along a (solved exactly by Sherman–Morrison).
  // The distal joint has ≈ 1e-6 kg·m² against tendon/limit stiffnesses of N·m/rad, which an explicit step
  // at 0.1 ms would not keep stable.
  Vec3<double> y{}, z{};
  for (std::size_t j = 0; j < 3; ++j) {
    const double m = f.k.inertia_kg_m2[j] + h * e.b_diag[j] + h * h * e.k_diag[j];
    y[j] = h * e.tau[j] / m;
    z[j] = e.a[j] / m;
  }
  const double ct = h * e.b_tendon + h * h * e.k_tendon;
  const double corr = ct * dot3(e.a, y) / (1.0 + ct * dot3(e.a, z));
  for (std::size_t j = 0; j < 3; ++j) {
    f.theta_dot[j] += y[j] - z[j] * corr;
    f.theta[j] += h * f.theta_dot[j];
  }
  // Tendon path (non-holonomic: integrated along the motion with the same a as the forces, so the tendon
  // does exactly the work c·T·(n·u̇) on the finger).
  f.q_m += h * dot3(e.a, f.theta_dot);
  if (e.kin_ok) f.alpha_last = e.alpha;
  f.x_release = e.x_release;
  f.x_grasp = e.x_grasp;
}

void GlovePlant::fillTruth(Finger& f, const Eval& e, bool bridge_on) {
  GloveFingerTruth& t = f.truth;
  t.theta_rad = f.theta;
  t.theta_dot_rad_s = f.theta_dot;
  t.theta_d_rad = e.theta_d;
  t.alpha_rad = e.alpha;
  t.O_u_tip = e.u;
  t.O_F_tip = e.F;
  t.tau_alpha_Nm = e.tau_alpha;
  t.pad_force_N = e.pad_N;
  t.tension_release_spool_N = e.tr_spool;
  t.tension_release_tip_N = e.tr_tip;
  t.tension_grasp_spool_N = e.tg_spool;
  t.tension_grasp_tip_N = e.tg_tip;
  t.wrap_release_rad = e.wrap_r;
  t.wrap_grasp_rad = e.wrap_g;
  t.release_sliding = e.slide_release;
  t.grasp_sliding = e.slide_grasp;
  t.spool_angle_rad = f.spool_angle;
  t.spool_speed_rad_s = f.spool_speed;
  t.motor_speed_rad_s = asDouble(board::kGearRatio) * f.worm_speed;
  t.motor_voltage_V = e.voltage_V;
  t.motor_current_A = e.current_A;
  t.bridge_on = bridge_on;
  t.worm_locked = f.worm_stuck;
  t.worm_slipping = f.slipping;
  t.kinematics_ok = e.kin_ok;
}

double GlovePlant::gaussian() { return normal(noise_rng_); }

double GlovePlant::thermalDrift_N(const Finger& f) const {
  const GlovePlantParams& p = config_.params;
  const double worn_s = config_.worn_before_start_s + time_s_;
  return f.err.strain_zero_tc_N_per_K * p.pad_warmup_K * (1.0 - std::exp(-worn_s / p.pad_thermal_time_s));
}

void GlovePlant::sample(Finger& f, SimIo& io) {
  const GlovePlantParams& p = config_.params;
  const int i = f.index;
  if (!f.enabled) {
    for (int j = 0; j < board::kJointsPerFinger; ++j) io.adc[board::hallAdcChannel(i, j)] = 0;
    io.adc[board::strainAdcChannel(i)] = 0;
    io.adc[board::currentAdcChannel(i)] = 0;
    return;
  }
  const bool noise = config_.noise;
  // Hall sensors: board.h's nominal curve with this part's gain/offset/mounting errors, noise, 12 bits.
  const double amp = asDouble(board::kHallAmplitude_counts);
  const double h3 = asDouble(board::kHallThirdHarmonic);
  for (std::size_t j = 0; j < 3; ++j) {
    const double kappa = asDouble(board::kHallHalfFieldAngle_rad) / asDouble(board::kHallHalfRange_rad[j]);
    const double x = kappa * (f.truth.alpha_rad[j] + f.err.hall_angle_rad[j] - asDouble(board::kHallCentre_rad[j]));
    double v = static_cast<double>(board::kAdcMidCounts) + f.err.hall_offset_counts[j] +
               amp * (1.0 + f.err.hall_gain[j]) * (std::sin(x) - h3 * std::sin(3.0 * x));
    if (noise) v += p.hall_noise_counts * gaussian();
    io.adc[board::hallAdcChannel(i, static_cast<int>(j))] = toCounts(v);
  }
  // Strain gauge: zero drift with the pad's temperature (first-order warm-up since the glove was put on), noise,
  // amplifier clamp at ± full scale.
  const double drift_N = noise ? thermalDrift_N(f) : 0.0;
  const double cpn = asDouble(board::kStrainCountsPerNewton);
  double s = static_cast<double>(board::kStrainZeroCounts) +
             cpn * ((1.0 + f.err.strain_gain) * f.truth.pad_force_N + f.err.strain_offset_N + drift_N);
  if (noise) s += strain_noise_counts_ * gaussian();
  s = std::clamp(s, static_cast<double>(board::kStrainMinCounts), static_cast<double>(board::kStrainMaxCounts));
  io.adc[board::strainAdcChannel(i)] = toCounts(s);
  // Current sense.
  double cur = static_cast<double>(board::kCurrentZeroCounts) + f.err.current_offset_counts +
               asDouble(board::kCurrentCountsPerAmp) * (1.0 + f.err.current_gain) * f.truth.motor_current_A;
  if (noise) cur += p.current_noise_counts * gaussian();
  io.adc[board::currentAdcChannel(i)] = toCounts(cur);
}

void GlovePlant::step(double dt_s, SimIo& io) { advance(dt_s, 1, io); }

void GlovePlant::advance(double dt_s, unsigned steps, SimIo& io) {
  // 1 s bounds the work of one step (10^4 substeps per finger); a lockstep rig steps at 1 ms.
  if (!std::isfinite(dt_s) || !(dt_s > 0.0) || dt_s > 1.0) {
    throw std::invalid_argument("GlovePlant::step: dt_s must be finite and in (0, 1] s");
  }
  if (steps == 0) return;
  const int n = std::max(1, static_cast<int>(std::ceil(dt_s / config_.params.max_substep_s - 1e-9)));
  const double h = dt_s / n;
  const bool bridge_on = io.pwm_enabled && io.drive_enable && !io.estop_pressed;
  Eval e{};
  int enabled = 0;
  for (Finger& f : fingers_) {
    if (!f.enabled) continue;
    ++enabled;
    const double raw = asDouble(io.pwm_duty[static_cast<std::size_t>(board::motorPwmChannel(f.index))]);
    const double duty = std::isfinite(raw) ? std::clamp(raw, -1.0, 1.0) : 0.0;
    // The same clock as `steps` calls of step(): time_s_ advanced by dt_s after each.
    double t = time_s_;
    for (unsigned s = 0; s < steps; ++s) {
      for (int k = 0; k < n; ++k) {
        evaluate(f, t + k * h, duty, bridge_on, e);
        integrate(f, e, h);
      }
      t += dt_s;
    }
    // Truth after the last step only: nothing reads it in between.
    evaluate(f, t, duty, bridge_on, e);
    truthWrench(f, e);
    fillTruth(f, e, bridge_on);
  }
  for (unsigned s = 0; s < steps; ++s) time_s_ += dt_s;
  // The sensors of the steps before the last are overwritten unread; their noise draws are skipped in the
  // stream (sample() takes 5 normals per enabled finger, 2 words each) so the last sample is the same.
  if (config_.noise && steps > 1) {
    noise_rng_.discard(static_cast<unsigned long long>(steps - 1) * static_cast<unsigned long long>(enabled) *
                       kNoiseWordsPerSample);
  }
  for (Finger& f : fingers_) sample(f, io);
}

}  // namespace phalanx::sim
