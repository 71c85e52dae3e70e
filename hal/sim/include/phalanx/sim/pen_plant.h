#pragma once
/// Simulated physical plant of the Twin-Pantograph haptic pen (seeds/004 §VI) and of the hand holding it.
/// docs/pen-plant.md lists every constant with its source and what is not modelled.
///
/// From the firmware's PWM duty to the counts it reads back:
///   current-mode amplifier (duty × 21 A, clamped: the motor torque limit, pen/board.h) → direct-drive motor
///   (τ = K_t·i, no gearing) minus joint friction (Coulomb, smoothed, + viscous) → the two pantographs
///   (massless linkages in this model: their inertia is in D) → end forces f = J⁻ᵀτ on the pen ends → the pen as
///   a rigid body in the five pose coordinates x = (c_x, c_y, c_z, θx, θz) with the constant mass matrix D of
///   eq 28–29 measured at home (generalised force Q = Σ (∂p_end/∂x)ᵀ f_end, i.e. virtual work) + gravity (the
///   unbalanced 70–130 g weight of Table X) + the hand.
///   The hand: a point mass coupled to the pen centre through the grip (spring–damper), driven by the arm
///   (spring–damper) towards the intended hand position; the grip also holds the two pen angles.
///   Sensors: six encoders (4000 counts/turn, quantised from the exact joint angles of the pose), six current
///   sense channels (12-bit, with noise).
///   Workspace: soft stops (stiff springs) just outside Table X's workspace keep the linkage assembled.
///
/// Real-time rules: no allocation after construction, deterministic for a seed.
#include <array>
#include <cstdint>
#include <random>

#include "phalanx/pen/board.h"
#include "phalanx/pen/dynamics.h"
#include "phalanx/pen/kinematics.h"
#include "phalanx/sim/plant.h"

namespace phalanx::sim {

using PenVec5 = std::array<double, 5>;

/// What the simulated hand does.
enum class PenHandScenario : std::uint8_t {
  kReleased = 0,  ///< no hand on the pen (Fig. 19, t0–t1: the pencil lies untouched)
  kHold = 1,      ///< holds the pen still at the start pose
  kRandom = 2,    ///< band-limited random motion inside the workspace (seeded)
  kExternal = 3,  ///< the hand target is set by the caller every tick (setHandTarget): benches and tests
  kPress = 4,     ///< presses along +x: from 2 s on the target moves 3.5 cm in 1 s (a smooth ramp) and stays there
                  ///< (teleoperation against a remote wall, docs/teleop.md)
};

struct PenPlantParams {
  /// Mass matrix of eq 29 in the paper's units (N, cm/s², N·cm, rad/s²) × 1e-5, rows (x, y, z, rot x, rot z).
  std::array<std::array<double, 5>, 5> D_paper = phalanx::pen::kMassMatrixEq29;
  // Joint friction: Coulomb from Table X's minimum force, viscous from motor data class.
  std::array<double, 6> coulomb_Nm{4.5e-3, 1.0e-3, 1.0e-3, 4.5e-3, 1.0e-3, 1.0e-3};
  double coulomb_smoothing_rad_s = 0.02;   ///< tanh velocity scale of the smoothed Coulomb friction
  double viscous_Nm_s_per_rad = 2.0e-4;    ///< bearings + motor viscous loss, every joint
  // Gravity: unbalanced weight felt at the pen centre, Table X "Weight 70 g – 130 g", linear in z over the
  // workspace depth (heavier further from the counterweighted motors), along −y (y is up).
  double weight_near_kg = 0.070;           ///< at z = 16.25 cm (workspace face nearest the motors)
  double weight_far_kg = 0.130;            ///< at z = 23.75 cm
  double gravity_m_s2 = 9.81;
  // Hand (pencil grip).
  double hand_mass_kg = 0.25;
  double grip_stiffness_N_per_m = 2000.0;
  double grip_damping_N_s_per_m = 8.0;
  double arm_stiffness_N_per_m = 200.0;
  double arm_damping_N_s_per_m = 5.0;
  double grip_rot_stiffness_Nm_per_rad = 0.5;
  double grip_rot_damping_Nm_s_per_rad = 0.005;
  // Soft stops just outside Table X's workspace (x ±6, y ±3.75, z ±3.75 cm, ±45°).
  std::array<double, 5> stop_lo{-0.075, -0.05, 0.145, -0.95, -0.95};
  std::array<double, 5> stop_hi{0.075, 0.05, 0.255, 0.95, 0.95};
  double stop_stiffness_N_per_m = 5000.0;
  double stop_stiffness_Nm_per_rad = 20.0;
  // Sensors.
  double current_noise_counts = 1.0;       ///< 1σ, only when PenPlantConfig::noise
  double max_substep_s = 1e-4;
};

struct PenPlantConfig {
  std::uint32_t seed = 1;
  bool noise = true;
  bool gravity = true;
  PenHandScenario scenario = PenHandScenario::kHold;
  phalanx::pen::PenPose<double> start{{0.0, 0.0, 0.20}, 0.0, 0.0};
  PenPlantParams params{};
};

/// Ground truth after the last step().
struct PenTruth {
  PenVec5 x{};          ///< (c_x, c_y, c_z m, θx, θz rad)
  PenVec5 x_dot{};
  phalanx::pen::JointVec<double> q_rad{}, q_dot_rad_s{};
  phalanx::pen::JointVec<double> motor_torque_Nm{};  ///< after the amplifier clamp, 0 with the bridge off
  phalanx::pen::Vec3<double> B_p_tip{}, B_v_tip{};   ///< bottom end (pencil tip)
  phalanx::pen::Vec3<double> B_p_eraser{}, B_v_eraser{};
  phalanx::pen::Vec3<double> hand_force_N{};         ///< grip force on the pen centre
  phalanx::pen::Vec3<double> hand_pos_m{};
  double kinetic_energy_J = 0;      ///< pen ½ẋᵀDẋ
  double motor_work_J = 0;          ///< ∫ τ_m·q̇ dt since construction
  double friction_work_J = 0;       ///< ∫ τ_f·q̇ dt (≤ 0)
  double hand_work_J = 0;           ///< ∫ Q_hand·ẋ dt
  double gravity_work_J = 0;
  double stop_work_J = 0;
  bool bridge_on = false;
  bool at_stop = false;
};

/// The pen + hand plant. Reads PWM 0..5, pwm_enabled, drive_enable, estop_pressed; writes encoders 0..5 and
/// ADC 0..5 (pen/board.h).
class PenPlant final : public Plant {
 public:
  /// Throws std::invalid_argument for a bad configuration (non-finite value, start pose unreachable, D not
  /// positive definite).
  explicit PenPlant(const PenPlantConfig& config = PenPlantConfig{});
  void step(double dt_s, SimIo& io) override;

  const PenPlantConfig& config() const { return config_; }
  const PenTruth& truth() const { return truth_; }
  const phalanx::pen::Model<double>& model() const { return model_; }
  double time_s() const { return time_s_; }
  /// Mass matrix in SI (kg, kg·m, kg·m²) in the pose coordinates x.
  const std::array<std::array<double, 5>, 5>& massMatrix() const { return D_; }
  /// kExternal: where the hand wants to be (centre position m, pen angles rad) and with which velocity.
  void setHandTarget(const PenVec5& x_target, const PenVec5& x_dot_target = {});
  /// Take the hand off the pen (true) or put it back (false) at any time.
  void setHandReleased(bool released) { hand_released_ = released; }
  /// The unbalanced weight (kg) at a centre depth z (m): the gravity model, for gravity compensation tests.
  double weightKg(double z_m) const;

 private:
  struct Eval;
  void evaluate(const PenVec5& x, const PenVec5& xd, const std::array<double, 3>& hp, const std::array<double, 3>& hv,
                double t, const SimIo& io, bool bridge_on, Eval& e) const;
  void handTarget(double t, PenVec5& target, PenVec5& target_dot) const;
  void sample(SimIo& io);

  PenPlantConfig config_;
  phalanx::pen::Model<double> model_;
  std::array<std::array<double, 5>, 5> D_{}, D_inv_{};
  PenVec5 x_{}, xd_{};
  std::array<double, 3> hand_p_{}, hand_v_{};
  PenVec5 hand_target_{}, hand_target_dot_{};
  bool hand_released_ = false;
  double time_s_ = 0;
  PenTruth truth_{};
  std::mt19937 rng_;
  std::array<double, 4> random_phase_{};
};

}  // namespace phalanx::sim
