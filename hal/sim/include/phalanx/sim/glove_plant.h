#pragma once
/// Simulated physical plant of the RML five-finger haptic glove (Ma & Ben-Tzvi 2015, seeds/000) and of the
/// hand wearing it. docs/glove-plant.md lists every constant with its source and what is not modelled.
///
/// Per finger, from the firmware's PWM duty to the ADC counts it reads back:
///   H-bridge (duty × 9 V, 4 A current regulation) → FA-130 brushed DC motor (current from the averaged
///   voltage; the electrical time constant is neglected) → 101:1 gearbox whose last stage is a self-locking
///   worm (forward efficiency < 50 %; the load can never back-drive the motor; beyond the passive limit,
///   35 N at the fingertip, the locked worm drive slips) → spool winding an antagonistic tendon pair
///   (positive duty winds the release tendon, unwinds the grasp tendon) → each tendon: spool segment,
///   capstan contact on the pulleys (glove/capstan.h, eq 15–16, wrap γ(α); the contact sticks, or slides
///   with T_spool/T_tip = e^{±μγ} depending on which end pulls), tip segment in series with the fingertip
///   pad → net tip tension T acting on the fingertip as a pad-normal force c·T (the routing's design intent,
///   §3.4: τ_α = (J_α^u)ᵀ f_y) → finger joints τ_θ = (J_θ^u)ᵀ F. The glove linkage is massless and
///   follows the finger through the closure α = f(θ) (eq 6–8).
///   The finger has three joints with small inertia, passive stiffness/damping and soft range limits, and is
///   driven by a "muscle" impedance towards the intended trajectory θ_d(t) of the hand scenario.
///   Sensors: 15 Hall angles (of α), 5 pad strain gauges (force along glove::padNormal), 5 motor currents,
///   as 12-bit counts through board.h's nominal transfers plus gain/offset/mounting errors, noise, drift,
///   quantisation and saturation.
///
/// Sign conventions: board.h (positive duty → spool + → release tendon → finger opens → positive pad force
/// along padNormal → positive current). Frames, θ/α conventions: glove/kinematics.h.
///
/// Real-time rules: no allocation after construction (all state in std::array), deterministic for a seed
/// (noise from std::mt19937 with a portable Box–Muller, scenario randomness from a second seeded stream).
#include <array>
#include <cstdint>
#include <limits>
#include <random>

#include "phalanx/glove/board.h"
#include "phalanx/glove/capstan.h"
#include "phalanx/glove/kinematics.h"
#include "phalanx/glove/tendon.h"
#include "phalanx/sim/plant.h"

namespace phalanx::sim {

/// Motion of the simulated hand (all five fingers, with per-finger phase and amplitude variation).
enum class HandScenario : std::uint8_t {
  kStill = 0,      ///< relaxed hand, constant intent
  kCloseOpen = 1,  ///< full close/open maneuvers, 1 s each (raised cosine) + 0.5 s rest (paper §4.3)
  kGrasp = 2,      ///< reach and squeeze: intent closes past any object, effort saturates at squeeze_force_N
  kRandom = 3,     ///< band-limited random motion (seeded) within Table 2's ranges
  kPush = 4,       ///< finger at the mid-grasp pose presses into the glove with push_force_N on the pad
};

/// Tendon/pulley friction condition (paper §4.2).
enum class TendonLubrication : std::uint8_t {
  kLubricated = 0,  ///< μ_L = 0.053
  kDry = 1,         ///< μ_NL = 0.0631
};

/// Physical constants of the plant. Defaults are the documented model (docs/glove-plant.md gives each
/// source); tests and studies may change them. SI units throughout. Motor R, K, supply, bridge, gear
/// ratio and spool radius are board.h constants.
struct GlovePlantParams {
  // Motor (FA-130 class) and gearbox.
  double rotor_inertia_kg_m2 = 1.0e-7;        ///< rotor (≈ 0.9 g·cm²) + spur gears, at the motor shaft
  double motor_coulomb_friction_Nm = 2.0e-4;  ///< brushes + bearings (≈ K·0.15 A of the 0.2 A no-load current)
  double motor_viscous_Nm_s_per_rad = 7.0e-8; ///< rest of the no-load current at 9100 rpm
  double spur_efficiency = 0.87;              ///< spur stages before the worm (two stages at ≈ 0.93)
  double worm_lead_rad = 0.06981317;          ///< 4°: single-start worm lead angle λ
  double worm_friction_coeff = 0.08;          ///< steel worm on brass wheel, greased: ρ = atan μ = 4.6° > λ
  double spool_inertia_kg_m2 = 2.0e-7;        ///< spool + worm wheel + shaft, at the spool
  double worm_wheel_inertia_kg_m2 = 1.0e-7;   ///< worm wheel alone (only while the spool slips on it)
  double passive_hold_margin = 1.0;           ///< worm slip torque / spool torque of a 35 N push at θ_ref
  double slip_kinetic_fraction = 0.85;        ///< kinetic / static slip torque of the overloaded worm drive
  double slip_damping_Nm_s_per_rad = 2.5e-4;  ///< viscous part of the slipping interface (greased)
  // Tendon routing and compliance.
  /// c: pad-normal force per N of net tip tension (the routing design of glove/tendon.h).
  double pad_transmission = glove::TendonDesign<double>{}.pad_transmission;
  /// θ_ref (mid-grasp, glove/tendon.h): kPush pose and reference of the passive limit.
  glove::Vec3<double> ref_pose_deg = glove::TendonDesign<double>{}.ref_pose_deg;
  double tendon_stiffness_N_per_m = 40000.0;  ///< Dyneema, ≈ 0.25 m spool→tip, EA ≈ 10 kN (incl. knots)
  double spool_segment_fraction = 0.4;        ///< share of the tendon length between spool and pulleys
  double tendon_damping_N_s_per_m = 10.0;     ///< material damping of the tendon (only while taut)
  double pretension_N = 1.0;                  ///< both tendons at rest
  double pad_stiffness_N_per_m = 8000.0;      ///< fingertip pulp + fabric + Velcro under load, pad normal
  // Finger (human) — index values; other fingers scale with their length (docs/glove-plant.md).
  double phalanx_mass_per_length_kg_per_m = 0.25;              ///< ≈ 12 / 7 / 5 g for the index
  glove::Vec3<double> muscle_stiffness_Nm_per_rad = {1.0, 0.5, 0.2};  ///< MCP, PIP, DIP (index)
  double muscle_damping_ratio = 0.7;                             ///< of each joint's own mode
  glove::Vec3<double> passive_stiffness_Nm_per_rad = {0.05, 0.03, 0.01};
  glove::Vec3<double> rest_pose_deg = {-20.0, -30.0, -20.0};    ///< passive equilibrium (relaxed hand)
  double passive_damping_Nm_s_per_rad = 0.002;
  double limit_stiffness_Nm_per_rad = 3.0;                       ///< soft stop beyond Table 2's range
  double limit_damping_Nm_s_per_rad = 0.01;
  // Sensor imperfections (1σ). Noise terms only when GlovePlantConfig::noise.
  double hall_noise_counts = 2.0;             ///< DRV5055-class output noise after a 1 kHz RC filter
  /// Strain channel noise (derivation in docs/glove-plant.md "Sensors"): the bridge amplifier's (INA333,
  /// 50 nV/√Hz through a 1 kHz RC, at the gain that maps 2 mV/V to ±1.5 V) ...
  double strain_amp_noise_counts = 0.56;
  /// ... and the ADC's own per conversion (SNR 66 dB, quantisation excluded), averaged over
  /// board::kAdcOversampling conversions: 0.65 counts (≈ 7 mN) together.
  double adc_noise_counts = 0.67;
  /// Zero drift: the pad's temperature × the bridge's zero coefficient (per part, see strain_zero_tc_N_per_K).
  /// The pad warms from the room towards the fingertip's temperature by this much (K) ...
  double pad_warmup_K = 10.0;
  double pad_thermal_time_s = 120.0;          ///< ... with this time constant (pad + fabric, estimated)
  double current_noise_counts = 3.0;          ///< residual PWM ripple + amplifier noise, ≈ 5 mA
  // Per-sensor calibration errors (1σ, clipped at 3σ). Only when GlovePlantConfig::calibration_errors.
  double hall_gain_error = 0.015;             ///< DRV5055 sensitivity tolerance + magnet strength spread
  double hall_offset_error_counts = 6.0;      ///< quiescent-voltage tolerance
  double hall_angle_error_rad = 0.0087266;    ///< 0.5° magnet mounting angle
  double strain_gain_error = 0.02;
  double strain_offset_error_N = 0.15;        ///< bridge imbalance after assembly (tare removes it)
  /// Zero shift per kelvin of the pad bridge (N/K): 3σ = 36 mN/K, the worst case of foil gauges whose apparent
  /// strain is within ±1.8 µε/K, at 1000 µε for 20 N full scale.
  double strain_zero_tc_N_per_K = 0.012;
  double current_gain_error = 0.01;
  double current_offset_error_counts = 5.0;
  // Integration.
  double max_substep_s = 1e-4;                ///< internal step; step() subdivides dt_s
};

/// Plant configuration.
struct GlovePlantConfig {
  std::uint32_t seed = 1;                                  ///< noise, calibration errors and kRandom motion
  TendonLubrication lubrication = TendonLubrication::kLubricated;
  bool noise = true;               ///< sensor noise and strain drift; false: deterministic, noise-free counts
  /// How long the glove has been worn when the plant starts (s): the pad has been warming up for that long, so
  /// its temperature, and the gauge's zero with it, still changes after the start-up tare (docs/glove-plant.md).
  double worn_before_start_s = 60.0;
  bool calibration_errors = true;  ///< per-sensor gain/offset/mounting errors (seeded)
  std::array<bool, 5> finger_enabled = {true, true, true, true, true};  ///< false: not simulated, ADC reads 0
  /// true: that finger's tendons are removed (paper §4.3 "without cabling"): the glove linkage is dragged
  /// by the finger with no force, the motor spins unloaded.
  std::array<bool, 5> cables_removed = {false, false, false, false, false};
  HandScenario scenario = HandScenario::kStill;
  double squeeze_force_N = 5.0;  ///< kGrasp: the finger's maximum effort, as a pad-normal force (N)
  /// kPush: pad force (N, ≥ 0) the finger presses into the glove with (towards flexion); the person adjusts
  /// the effort by feel until the pad force matches (or the glove gives way) and holds the θ_ref posture.
  double push_force_N = 0.0;
  double push_ramp_s = 0.5;      ///< kPush: linear ramp time of the target force (s)
  /// kPush: the person stops pressing at this time (s; infinity: never), ramping the target back to 0 over
  /// push_ramp_s: a clenched hand that relaxes.
  double push_until_s = std::numeric_limits<double>::infinity();
  GlovePlantParams params{};
};

/// Ground truth of one finger after the last step() (for tests and metrics; the firmware sees only counts).
struct GloveFingerTruth {
  glove::Vec3<double> theta_rad{};         ///< finger joint angles MCP, PIP, DIP (kinematics.h frame)
  glove::Vec3<double> theta_dot_rad_s{};
  glove::Vec3<double> theta_d_rad{};       ///< intended finger angles θ_d (scenario)
  glove::Vec3<double> alpha_rad{};         ///< mechanism joint angles (what the Hall sensors measure)
  glove::Vec3<double> O_u_tip{};           ///< fingertip pose (x m, y m, φ rad) in {O}
  glove::Vec3<double> O_F_tip{};           ///< planar wrench glove → fingertip (f_x N, f_y N, m_z N·m) in {O}
  glove::Vec3<double> tau_alpha_Nm{};      ///< tendon torques on the mechanism joints, (J_α^u)ᵀ F (eq 18)
  double pad_force_N = 0;                  ///< O_F_tip along padNormal(φ) (+: pushes towards extension)
  double tension_release_spool_N = 0;      ///< release tendon, spool end
  double tension_release_tip_N = 0;        ///< release tendon, link-3 end (after capstan friction)
  double tension_grasp_spool_N = 0;
  double tension_grasp_tip_N = 0;
  double wrap_release_rad = 0;             ///< capstan wrap γ of each tendon (eq 16, capstan.h)
  double wrap_grasp_rad = 0;
  int release_sliding = 0;                 ///< capstan contact: +1 slides towards spool, −1 towards tip, 0 sticks
  int grasp_sliding = 0;
  double spool_angle_rad = 0;              ///< + winds the release tendon; 0 at construction
  double spool_speed_rad_s = 0;
  double motor_speed_rad_s = 0;            ///< at the motor shaft (= gear ratio × worm-wheel speed)
  double motor_voltage_V = 0;              ///< averaged bridge output (0 when the bridge is off)
  double motor_current_A = 0;
  bool bridge_on = false;                  ///< pwm_enabled && drive_enable && !estop_pressed
  bool worm_locked = true;                 ///< worm at rest, held by self-locking
  bool worm_slipping = false;              ///< load beyond the passive limit: spool slips on the locked worm
  bool kinematics_ok = true;               ///< false if α = f(θ) had no solution (last α kept)
};

/// Per-finger constants derived at construction (exposed for tests, docs and controller design).
struct GloveFingerConstants {
  glove::Model<double> model{};               ///< glove::defaultModel for this finger
  glove::CapstanModel<double> capstan{};      ///< μ from the config, γ_c = 90°, α range from the model
  glove::Vec3<double> ref_theta_rad{};        ///< θ_ref (kPush pose, passive-limit reference)
  glove::Vec3<double> ref_alpha_rad{};
  double pad_transmission = 0;                ///< c (N of pad force per N of net tip tension)
  double spool_segment_stiffness_N_per_m = 0; ///< spool → capstan contact
  double tip_segment_stiffness_N_per_m = 0;   ///< capstan contact → link 3, with the pad reflected (c²/k_pad)
  double series_stiffness_N_per_m = 0;        ///< whole tendon + pad with the contact stuck, along the tendon
  double pad_stiffness_locked_N_per_m = 0;    ///< c²·series: what the fingertip feels with the spool locked
  double pretension_stretch_spool_m = 0;
  double pretension_stretch_tip_m = 0;
  double slip_torque_Nm = 0;                  ///< static slip torque at the spool (passive limit, §2.2)
  glove::Vec3<double> inertia_kg_m2{};        ///< finger joint inertias (diagonal, extended posture)
  glove::Vec3<double> muscle_stiffness_Nm_per_rad{};
  glove::Vec3<double> muscle_damping_Nm_s_per_rad{};
};

/// The glove + hand plant. Writes ADC channels 0..24 of SimIo (board.h map); reads PWM 0..4, pwm_enabled,
/// drive_enable and estop_pressed (the e-stop cuts the bridge supply in hardware, as on the real board).
class GlovePlant final : public Plant {
 public:
  /// Throws std::invalid_argument for a non-finite or out-of-range configuration value.
  explicit GlovePlant(const GlovePlantConfig& config = GlovePlantConfig{});

  /// Advances the physics by dt_s (s, finite, in (0, 1]; subdivided into steps ≤ params.max_substep_s)
  /// using the duty cycles in io, then samples all sensors into io.adc. Throws std::invalid_argument on a
  /// bad dt_s. Does not allocate.
  void step(double dt_s, SimIo& io) override;
  /// `steps` calls of step(dt_s, io) (Plant::advance): the same physics, truth, noise stream and final sensor
  /// counts bit for bit; the sensors and truth of the steps before the last are not computed.
  void advance(double dt_s, unsigned steps, SimIo& io) override;

  /// Simulated time since construction (s).
  double time_s() const { return time_s_; }
  const GlovePlantConfig& config() const { return config_; }
  /// Worm forward efficiency η_w = tan λ / tan(λ+ρ) and back efficiency tan(λ−ρ)/tan λ (< 0: self-locking).
  double wormForwardEfficiency() const { return worm_eff_forward_; }
  double wormBackEfficiency() const { return worm_eff_backward_; }

  /// Ground truth and derived constants of finger 0..4 (thumb … little). Throw std::out_of_range otherwise.
  const GloveFingerTruth& truth(int finger) const { return fingers_[idx(finger)].truth; }
  const GloveFingerConstants& constants(int finger) const { return fingers_[idx(finger)].k; }

  /// True finger angles θ (rad), velocities θ̇ (rad/s), mechanism angles α (rad).
  const glove::Vec3<double>& theta_rad(int finger) const { return truth(finger).theta_rad; }
  const glove::Vec3<double>& thetaDot_rad_s(int finger) const { return truth(finger).theta_dot_rad_s; }
  const glove::Vec3<double>& alpha_rad(int finger) const { return truth(finger).alpha_rad; }
  /// Spool angle (rad, + winds the release tendon), motor current (A), true pad normal force (N).
  double spoolAngle_rad(int finger) const { return truth(finger).spool_angle_rad; }
  double motorCurrent_A(int finger) const { return truth(finger).motor_current_A; }
  double padForce_N(int finger) const { return truth(finger).pad_force_N; }
  /// The simulated user's intended finger angles θ_d (rad) at the current time.
  const glove::Vec3<double>& fingerIntent(int finger) const { return truth(finger).theta_d_rad; }
  /// Current strain-gauge zero drift (N, thermal, since the pad was at room temperature) — ground truth for
  /// tests of tare/drift handling.
  double strainDrift_N(int finger) const { return config_.noise ? thermalDrift_N(fingers_[idx(finger)]) : 0.0; }

 private:
  struct SensorErrors {
    glove::Vec3<double> hall_gain{};          ///< relative
    glove::Vec3<double> hall_offset_counts{};
    glove::Vec3<double> hall_angle_rad{};
    double strain_gain = 0;
    double strain_offset_N = 0;
    double strain_zero_tc_N_per_K = 0;
    double current_gain = 0;
    double current_offset_counts = 0;
  };
  /// kRandom: band-limited closure s(t) and per-joint deviations (sums of sinusoids).
  struct RandomMotion {
    static constexpr int kClosureTerms = 4;
    static constexpr int kJointTerms = 3;
    std::array<double, kClosureTerms> closure_amp{}, closure_freq_hz{}, closure_phase_rad{};
    std::array<std::array<double, kJointTerms>, 3> joint_amp_rad{}, joint_freq_hz{}, joint_phase_rad{};
  };
  struct Finger {
    int index = 0;
    bool enabled = true;
    bool cables = true;
    GloveFingerConstants k{};
    SensorErrors err{};
    RandomMotion random{};
    double s_open = 0.1, s_closed = 0.85, s_still = 0.35, delay_s = 0;  ///< scenario shaping
    // State.
    glove::Vec3<double> theta{}, theta_dot{};
    glove::Vec3<double> alpha_last{};      ///< last α that the kinematics solved (fallback)
    double q_m = 0;                        ///< release-path shortening at the mechanism since start (m)
    double x_release = 0, x_grasp = 0;     ///< cable passed over the pulleys towards the spool (m)
    double worm_speed = 0;                 ///< worm-wheel speed (rad/s, spool coordinates)
    double worm_angle = 0;
    double spool_speed = 0;
    double spool_angle = 0;
    bool worm_stuck = true;
    bool slipping = false;
    double push_effort_N = 0;              ///< kPush: the person's effort, as a tendon tension (N)
    GloveFingerTruth truth{};
  };
  struct Eval;  // forces and accelerations of one finger at one instant (glove_plant.cpp)
  struct TendonState {
    double spool_N = 0, tip_N = 0, x_m = 0;
    int sliding = 0;
  };

  static int idx(int finger);
  static TendonState solveTendon(const GloveFingerConstants& k, double u_s, double u_m, double x_prev, double ratio);
  void initFinger(Finger& f, int index, std::mt19937& calib_rng, std::mt19937& motion_rng);
  double closureS(const Finger& f, double t, double& s_dot) const;
  void intent(const Finger& f, double t, glove::Vec3<double>& theta_d, glove::Vec3<double>& theta_d_dot) const;
  void evaluate(const Finger& f, double t, double duty, bool bridge_on, Eval& e) const;
  void integrate(Finger& f, const Eval& e, double h);
  static void truthWrench(const Finger& f, Eval& e);  ///< e.F and e.tau_alpha, which only the truth reports
  static void fillTruth(Finger& f, const Eval& e, bool bridge_on);
  void sample(Finger& f, SimIo& io);
  double thermalDrift_N(const Finger& f) const;  ///< the gauge's zero shift at the pad's temperature now
  double gaussian();

  GlovePlantConfig config_;
  double mu_ = 0;
  double worm_eff_forward_ = 0;   ///< η_w = tan λ / tan(λ + ρ)
  double worm_eff_backward_ = 0;  ///< η_wb = tan(λ − ρ) / tan λ (< 0: self-locking)
  double strain_noise_counts_ = 0;  ///< σ of a strain sample: amplifier + ADC noise, the ADC's averaged (counts)
  double time_s_ = 0;
  std::array<Finger, 5> fingers_{};
  std::mt19937 noise_rng_;
};

}  // namespace phalanx::sim
