#pragma once
/// Simulated plant of the index-finger exoskeleton's Bowden-cable series elastic actuators (seeds/001, Agarwal
/// et al. 2015, §3.2, §4.1, §7.1). docs/sea-plant.md lists every constant with its source.
///
/// Per SEA (MCP, PIP), from the firmware's PWM duty to the counts it reads back:
///   H-bridge (duty × 24 V, cycle-by-cycle current regulation, high impedance when disabled) → RE-max 29 DC
///   motor (armature current from L di/dt = V − R i − k_e ω, integrated exactly per substep) → planetary
///   gearhead 33:1 (Coulomb friction = no-load friction + the gear loss (1 − η)·|motor torque|, with stiction)
///   → motor pulley r_m → two antagonistic Bowden cables, each through its sheath to a pre-tensioned
///   compression spring k at the joint (eq 1–2). The cable pair is modelled as a play (backlash) element
///   between the motor-side cable travel x_m = r_m θ_m and the spring-side travel x_e, with a load-dependent
///   width b = b_0 + b_1·|τ_j| (Kaneko et al. 1991, cited in §8.1.1: "load- and configuration-dependent
///   effective backlash"); inside the play the sheath friction F_s (μΘ times the cable tensions) builds up
///   linearly at the motor side (an elastic cable stretch, damped by the sheath's micro-slip), and when the motor
///   drags the cable the full F_s opposes it.
///   Spring deflection d = x_e − r_j(θ_j − θ_j0); tensions T_{1,2} = max(0, T_0 ∓ k d) (a cable goes slack
///   beyond the pretension); joint torque τ_j = (T_2 − T_1) r_j, which is eq 2 while both cables are taut.
///   Rig variant (§7.1): the exoskeleton joint is clamped to a load cell through a compliant interface
///   (k_clamp; §8.1.1 reports the joint still moving slightly under load). The joint side is massless and
///   quasi-static: θ_j solves k_clamp θ_j = τ_j(θ_j). The load cell reads k_clamp θ_j.
///   Finger variant (§4.2, §6.1): the SEAs drive the exoskeleton's MCP and PIP chains closed around an index
///   finger (phalanx/sea/kinematics.h: four-bar/slider chains MCP → PIP → DIP, Table 4 subject). Dynamics of
///   eq 13 in the exoskeleton joint coordinates Θ_r = (θ_1r, θ_6r):
///       I_j Θ̈_r + B_j Θ̇_r + J_nᵀ τ_f = τ_j,     τ_f = −(τ_passive(θ_f) − B_f θ̇_f + τ_muscle)
///   with the double-exponential passive joint torque of eq 14 at the finger MCP and PIP, a linear finger
///   damping, and the user's muscle torque (an impedance around the intended motion θ_d(t) of the scenario).
///   The DIP follows the PIP (anatomical coupling θ_dip = c·θ_8); its chain only sets the DIP sensor.
///   The velocity update is semi-implicit in the damping (J_nᵀ B J_n grows large near the workspace edge).
///   Sensors: joint angle (KMA210) counts with white noise and 12-bit quantisation (the paper's moving-average
///   filter is the firmware's job), motor encoders (quantised, noise-free), motor current sense with noise,
///   load-cell counts with noise.
///
/// Sign conventions: phalanx/sea/board.h. Real-time rules: no allocation after construction, deterministic for
/// a seed (mt19937 + a portable Box–Muller).
#include <array>
#include <cstdint>
#include <random>

#include "phalanx/sea/board.h"
#include "phalanx/sea/kinematics.h"
#include "phalanx/sim/plant.h"

namespace phalanx::sim {

/// Which mechanism the SEAs drive.
enum class SeaVariant : std::uint8_t {
  kRig = 0,     ///< §7.1 test rig: each exoskeleton joint clamped to a load cell
  kFinger = 1,  ///< the exoskeleton on an index finger (eq 13–14)
};

/// What the simulated user does (finger variant).
enum class SeaUserMotion : std::uint8_t {
  kRelaxed = 0,    ///< muscles off: the finger is moved by the device against its passive torque (eq 14)
  kRandom = 1,     ///< band-limited random flexion/extension around the rest pose (§7.7 "fast random motions")
  kCloseOpen = 2,  ///< slow sinusoidal flexion/extension of MCP and PIP, 0.5 Hz
  kHold = 3,       ///< the user keeps the rest posture with the muscle impedance (resists the device gently)
};

/// Finger and exoskeleton-link dynamics (eq 13–14). Index 0: MCP, 1: PIP. docs/sea-plant.md gives the sources.
struct SeaFingerParams {
  /// eq 14, τ(φ) = A(e^{−B(φ−E)} − 1) − C(e^{D(φ−F)} − 1) in the FLEXION-positive angle φ = −θ (the paper's
  /// form; kinematics.h counts flexion negative). A, C in N·m, B, D in 1/rad, E, F in rad.
  std::array<double, 2> A_Nm = {0.15, 0.04};
  std::array<double, 2> B_per_rad = {3.0, 3.0};
  std::array<double, 2> C_Nm = {0.15, 0.04};
  std::array<double, 2> D_per_rad = {3.0, 3.0};
  std::array<double, 2> E_rad = {-0.1, 0.05};
  std::array<double, 2> F_rad = {1.1, 1.25};
  std::array<double, 2> finger_damping_Nm_s_per_rad = {0.01, 0.005};  ///< human joint damping (finger coords)
  std::array<double, 2> exo_inertia_kg_m2 = {4.0e-5, 1.5e-5};          ///< I_j: exo links + phalanges, at Θ_r
  std::array<double, 2> exo_damping_Nm_s_per_rad = {0.002, 0.001};     ///< B_j: exo joint bearings
  std::array<double, 2> muscle_stiffness_Nm_per_rad = {1.0, 0.5};      ///< user's impedance around θ_d
  std::array<double, 2> muscle_damping_Nm_s_per_rad = {0.02, 0.01};
  double dip_pip_coupling = 2.0 / 3.0;                                  ///< θ_dip = c·θ_8
  std::array<double, 2> random_amplitude_rad = {0.30, 0.42};          ///< kRandom: ±17° MCP, ±24° PIP peak
  std::array<double, 2> close_open_amplitude_rad = {0.30, 0.40};      ///< kCloseOpen
  double close_open_hz = 0.5;
  /// Stretch reflex of the finger flexors (spasticity; off while reflex_gain is 0, the default). Stretching a
  /// flexor = extending the joint (flexion φ = −θ decreasing). With the stretch velocity v = θ̇_f = −φ̇:
  ///     τ_reflex = −G·(v − v_th)⁺   (+θ direction: it resists the extension)   while φ < φ_catch,
  /// i.e. a reflex torque growing linearly with the stretch velocity above a threshold velocity v_th, in the
  /// stretched part of the range beyond the catch angle φ_catch (the angle of the Tardieu "catch", R1).
  /// The linear growth with velocity: Kamper & Rymer 2000 (Muscle Nerve 23:954, doi 10.1002/(SICI)1097-4598
  /// (200006)23:6<954::AID-MUS17>3.0.CO;2-0): the reflex work of imposed MCP extension grew proportionally
  /// with the stretch velocity in stroke subjects; a threshold angle that varies little with velocity:
  /// McPherson et al. 2018 (Exp Brain Res 237:121, doi 10.1007/s00221-018-5389-x: ~15 % of the velocity
  /// dependence from the threshold angle, ~74 % from reflex stiffness). The numbers are chosen (docs/sea-plant.md
  /// "Stretch reflex"): no finger value of v_th or G was found in the seeds.
  std::array<double, 2> reflex_gain_Nm_s_per_rad = {0.0, 0.0};      ///< G; 0: no reflex (every default test)
  std::array<double, 2> reflex_threshold_rad_s = {1.047, 1.047};    ///< v_th (60°/s)
  std::array<double, 2> reflex_catch_flexion_rad = {0.349, 0.524};  ///< φ_catch (20° MCP, 30° PIP flexion)
  /// A maximal voluntary flexion effort (as a therapist asks "push as hard as you can, now"): from
  /// max_effort_start_s (plant time; < 0: never, the default) for max_effort_duration_s, the relaxed user's
  /// muscle torque rises to max_voluntary_Nm (flexing) over kMaxEffortRiseS and holds. kRelaxed only.
  std::array<double, 2> max_voluntary_Nm = {0.2, 0.1};
  double max_effort_start_s = -1.0;
  double max_effort_duration_s = 3.0;
};

/// The spastic finger of firmware-sim's `--scenario spastic` (sea_finger; docs/sea-plant.md "Stretch reflex"):
/// f with the stretch reflex on, G = 0.05 N·m·s/rad at the MCP and 0.015 at the PIP (the MCP value scaled by the
/// PIP/MCP ratio of eq 14's A), v_th = 60°/s, φ_catch = 20° MCP / 30° PIP. Chosen values, not measured ones:
/// 0.05 N·m·s/rad gives 0.1 N·m at 175°/s, a third of the device's 0.3 N·m finger-torque limit, so the device can
/// stretch through it.
inline SeaFingerParams withStretchReflex(SeaFingerParams f) {
  f.reflex_gain_Nm_s_per_rad = {0.05, 0.015};
  return f;
}

/// Constants of one SEA channel (MCP or PIP).
struct SeaChannelParams {
  double spring_stiffness_N_per_m = 2816.0;  ///< k of each of the two compression springs (§6.2)
  double joint_pulley_radius_m = static_cast<double>(::phalanx::sea::board::kJointPulleyRadius_m);
  double motor_pulley_radius_m = static_cast<double>(::phalanx::sea::board::kMotorPulleyRadius_m);
  double pretension_N = 20.0;                ///< T_0 of each cable at rest (cable tensioning mechanism, §3.4)
  double backlash_base_m = 0.4e-3;           ///< b_0: cable play at zero load (cable travel, full width)
  double backlash_per_Nm_m = 2.0e-3;         ///< b_1: additional play per N·m of joint torque
  double sheath_friction = 0.2;              ///< μΘ: sheath friction force F_s = μΘ·(T_1 + T_2)
  /// Inside the play the motor-side cable stretch is an elastic element (stiffness F_s / (b/2)) with the micro-
  /// slip damping of the sheath; this is its damping ratio against the motor inertia (1: critically damped).
  double play_damping_ratio = 1.0;
  double clamp_stiffness_Nm_per_rad = 30.0;  ///< rig: joint-to-load-cell interface (three cantilever screws)
};

/// Channel defaults: the spring of §6.2 for SEA 0 (MCP, 2816 N/m) or 1 (PIP, 744 N/m), the rest as above.
inline SeaChannelParams seaChannelDefaults(int sea) {
  SeaChannelParams p;
  p.spring_stiffness_N_per_m = sea == 0 ? 2816.0 : 744.0;
  return p;
}

/// Physical constants of the plant. SI units. Defaults: docs/sea-plant.md.
struct SeaPlantParams {
  std::array<SeaChannelParams, 2> channel = {seaChannelDefaults(0), seaChannelDefaults(1)};  ///< MCP, PIP
  SeaFingerParams finger{};
  // Motor + gearhead (per SEA, identical).
  double supply_V = static_cast<double>(::phalanx::sea::board::kSupply_V);
  double motor_resistance_Ohm = static_cast<double>(::phalanx::sea::board::kMotorResistance_Ohm);
  double bridge_on_resistance_Ohm = static_cast<double>(::phalanx::sea::board::kBridgeOnResistance_Ohm);
  double bridge_current_limit_A = static_cast<double>(::phalanx::sea::board::kBridgeCurrentLimit_A);
  double motor_inductance_H = static_cast<double>(::phalanx::sea::board::kMotorInductance_H);
  double torque_constant_Nm_per_A = static_cast<double>(::phalanx::sea::board::kMotorTorqueConstant_Nm_per_A);
  double rotor_inertia_kg_m2 = static_cast<double>(::phalanx::sea::board::kMotorRotorInertia_kg_m2);
  double no_load_current_A = static_cast<double>(::phalanx::sea::board::kMotorNoLoadCurrent_A);  ///< → Coulomb friction k_t·I_0 at the motor
  double gear_ratio = static_cast<double>(::phalanx::sea::board::kGearRatio);
  double gear_efficiency = static_cast<double>(::phalanx::sea::board::kGearEfficiency);
  double output_inertia_kg_m2 = 2.0e-6;      ///< gearhead output stage + motor pulley, at the pulley
  // Sensor imperfections (1σ); only with SeaPlantConfig::noise.
  double joint_noise_counts = 2.0;           ///< KMA210 + ADC noise, ≈ 0.1°
  double current_noise_counts = 3.0;         ///< PWM ripple residue + amplifier, ≈ 6 mA
  double load_cell_noise_counts = 1.5;       ///< ≈ 0.4 mN·m
  /// Donning variation (finger variant): each session (seed) mounts the five joint sensors with a constant
  /// offset drawn from N(0, σ²) on its own random stream — the fit of straps and links shifts between
  /// donnings. 0 (default): none. Applied with or without SeaPlantConfig::noise.
  double donning_offset_sd_rad = 0.0;
  // Integration.
  double max_substep_s = 1e-4;
};

struct SeaPlantConfig {
  std::uint32_t seed = 1;
  bool noise = true;
  SeaVariant variant = SeaVariant::kRig;
  SeaUserMotion motion = SeaUserMotion::kRelaxed;  ///< finger variant only
  SeaPlantParams params{};
};

/// Ground truth of one SEA after the last step().
struct SeaTruth {
  double motor_angle_rad = 0;        ///< θ_m at the motor pulley (0 at construction)
  double motor_speed_rad_s = 0;
  double motor_current_A = 0;
  double motor_voltage_V = 0;        ///< averaged bridge output, 0 when the bridge is off
  double cable_motor_m = 0;          ///< x_m = r_m θ_m
  double cable_spring_m = 0;         ///< x_e (after the play)
  double backlash_m = 0;             ///< current play width b
  double spring_deflection_m = 0;    ///< d = x_e − r_j(θ_j − θ_j0)
  double tension1_N = 0, tension2_N = 0;
  double joint_angle_rad = 0;        ///< θ_j − θ_j0 (exoskeleton joint θ_1r or θ_6r on the finger)
  double joint_torque_Nm = 0;        ///< τ_j = (T_2 − T_1) r_j, what the SEA applies to the joint
  double load_cell_torque_Nm = 0;    ///< rig: k_clamp θ_j (equal to τ_j, quasi-static)
  double cable_load_torque_Nm = 0;   ///< what the cables exert on the motor pulley (incl. sheath friction)
  bool bridge_on = false;
};

/// Ground truth of the finger (finger variant). Angles in kinematics.h's convention (flexion negative).
struct SeaFingerTruth {
  std::array<double, 2> exo_rad{};            ///< Θ_r = (θ_1r, θ_6r)
  std::array<double, 2> exo_rate_rad_s{};
  std::array<double, 2> exo_rest_rad{};       ///< Θ_r0: exoskeleton angles where the springs are neutral
  std::array<double, 3> theta_rad{};          ///< finger MCP θ_4, PIP θ_8, DIP
  std::array<double, 2> theta_rate_rad_s{};
  std::array<double, 2> intent_rad{};         ///< the user's intended MCP, PIP (kRandom, kCloseOpen)
  std::array<double, 2> passive_Nm{};         ///< eq 14 in the +θ direction
  std::array<double, 2> muscle_Nm{};
  std::array<double, 2> reflex_Nm{};          ///< stretch-reflex torque in the +θ direction (≤ 0)
  /// Finger joint torques the exoskeleton applies (+θ = extension): J_n^{-T} τ_j (eq 9 on the true state).
  std::array<double, 2> applied_Nm{};
  std::array<std::array<double, 2>, 2> J_n{};  ///< eq 10 at the true pose
  std::array<double, 5> sensors_rad{};        ///< true sensor angles (kinematics.h SensorIndex)
  bool kinematics_ok = true;
};

class SeaPlant final : public Plant {
 public:
  /// Throws std::invalid_argument for a non-finite or out-of-range configuration value.
  explicit SeaPlant(const SeaPlantConfig& config = SeaPlantConfig{});
  /// Advances the physics by dt_s (finite, in (0, 1]; subdivided into steps ≤ max_substep_s), then samples the
  /// sensors into io. Throws std::invalid_argument on a bad dt_s. Does not allocate.
  void step(double dt_s, SimIo& io) override;
  /// `steps` calls of step(dt_s, io) (Plant::advance), bit for bit; the sensor samples before the last are not
  /// computed (their noise draws are skipped in the stream).
  void advance(double dt_s, unsigned steps, SimIo& io) override;

  double time_s() const { return time_s_; }
  const SeaPlantConfig& config() const { return config_; }
  /// Ground truth of SEA 0 (MCP) or 1 (PIP); throws std::out_of_range otherwise.
  const SeaTruth& truth(int sea) const;
  /// Finger ground truth (finger variant; zeros on the rig).
  const SeaFingerTruth& finger() const { return finger_; }
  /// Passive finger joint torque of eq 14 for joint 0 (MCP) / 1 (PIP) at angle θ (kinematics.h convention), in
  /// the +θ direction.
  double passiveTorque_Nm(int joint, double theta_rad) const;
  /// Stretch-reflex torque (+θ direction) of joint 0/1 at angle θ and rate θ̇ (kinematics.h convention).
  double reflexTorque_Nm(int joint, double theta_rad, double theta_rate_rad_s) const;
  /// The donning offsets of the five joint sensors for this seed (rad; zeros without donning variation).
  const std::array<double, 5>& donningOffsets() const { return donning_rad_; }
  /// The ideal SEA law of eq 2 evaluated on the true state: 2k(r_m θ_m − r_j(θ_j − θ_j0)) r_j — what a perfect
  /// estimator (eq 7, noise-free sensors) would report. Differs from truth().joint_torque_Nm by the cable play.
  double idealSeaTorque_Nm(int sea) const;

 private:
  struct Channel {
    SeaChannelParams p{};
    double inertia = 0;         ///< at the pulley
    double theta_m = 0, omega_m = 0, current = 0;
    double x_e = 0;             ///< spring-side cable travel
    double theta_j = 0;         ///< exoskeleton joint angle relative to θ_j0
    double omega_j = 0;
    SeaTruth truth{};
  };
  struct RandomMotion {
    static constexpr int kTerms = 4;
    std::array<std::array<double, kTerms>, 2> amp{}, freq_hz{}, phase{};
    std::array<std::array<double, kTerms>, 2> sin_phase{};  ///< sin(phase), the fade-in's offset
  };
  static int idx(int sea);
  void electrical(Channel& c, double duty, bool bridge_on, double h);
  void play(Channel& c);
  void tensions(Channel& c) const;
  void solveJoint(Channel& c) const;
  void motorMechanics(Channel& c, double h);
  void fingerDynamics(double h);
  static constexpr double kMaxEffortRiseS = 0.5;  ///< a maximal effort ramps to its maximum over 0.5 s
  void drawDonning();
  double muscleTorque_Nm(size_t j, double th_d, double th_d_dot, double wf) const;
  void intent(double t, std::array<double, 2>& theta_d, std::array<double, 2>& theta_d_dot) const;
  void fingerSensors();
  void stepPhysics(double dt_s, bool bridge_on, const std::array<double, 2>& duty);
  void sample(SimIo& io);
  double gaussian();

  SeaPlantConfig config_;
  double time_s_ = 0;
  std::array<Channel, 2> ch_{};
  SeaFingerTruth finger_{};
  sea::Model<double> model_{};
  sea::Data<double> kin_{};
  std::array<double, 2> rest_theta_{};  ///< finger rest pose (eq 14 zero), MCP and PIP
  RandomMotion random_{};
  std::array<double, 5> donning_rad_{};
  std::mt19937 rng_;
};

}  // namespace phalanx::sim
