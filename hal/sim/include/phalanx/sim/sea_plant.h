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
///   linearly at the motor side, and when the motor drags the cable the full F_s opposes it.
///   Spring deflection d = x_e − r_j(θ_j − θ_j0); tensions T_{1,2} = max(0, T_0 ∓ k d) (a cable goes slack
///   beyond the pretension); joint torque τ_j = (T_2 − T_1) r_j, which is eq 2 while both cables are taut.
///   Rig variant (§7.1): the exoskeleton joint is clamped to a load cell through a compliant interface
///   (k_clamp; §8.1.1 reports the joint still moving slightly under load). The joint side is massless and
///   quasi-static: θ_j solves k_clamp θ_j = τ_j(θ_j). The load cell reads k_clamp θ_j.
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
#include "phalanx/sim/plant.h"

namespace phalanx::sim {

/// Which mechanism the SEAs drive.
enum class SeaVariant : std::uint8_t {
  kRig = 0,  ///< §7.1 test rig: each exoskeleton joint clamped to a load cell
};

/// Constants of one SEA channel (MCP or PIP).
struct SeaChannelParams {
  double spring_stiffness_N_per_m = 2816.0;  ///< k of each of the two compression springs (§6.2)
  double joint_pulley_radius_m = static_cast<double>(::phalanx::sea::board::kJointPulleyRadius_m);
  double motor_pulley_radius_m = static_cast<double>(::phalanx::sea::board::kMotorPulleyRadius_m);
  double pretension_N = 20.0;                ///< T_0 of each cable at rest (cable tensioning mechanism, §3.4)
  double backlash_base_m = 0.4e-3;           ///< b_0: cable play at zero load (cable travel, full width)
  double backlash_per_Nm_m = 2.0e-3;         ///< b_1: additional play per N·m of joint torque
  double sheath_friction = 0.2;              ///< μΘ: sheath friction force F_s = μΘ·(T_1 + T_2)
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
  // Integration.
  double max_substep_s = 1e-4;
};

struct SeaPlantConfig {
  std::uint32_t seed = 1;
  bool noise = true;
  SeaVariant variant = SeaVariant::kRig;
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
  double joint_angle_rad = 0;        ///< θ_j − θ_j0
  double joint_torque_Nm = 0;        ///< τ_j = (T_2 − T_1) r_j, what the SEA applies to the joint
  double load_cell_torque_Nm = 0;    ///< rig: k_clamp θ_j (equal to τ_j, quasi-static)
  double cable_load_torque_Nm = 0;   ///< what the cables exert on the motor pulley (incl. sheath friction)
  bool bridge_on = false;
};

class SeaPlant final : public Plant {
 public:
  /// Throws std::invalid_argument for a non-finite or out-of-range configuration value.
  explicit SeaPlant(const SeaPlantConfig& config = SeaPlantConfig{});
  /// Advances the physics by dt_s (finite, in (0, 1]; subdivided into steps ≤ max_substep_s), then samples the
  /// sensors into io. Throws std::invalid_argument on a bad dt_s. Does not allocate.
  void step(double dt_s, SimIo& io) override;

  double time_s() const { return time_s_; }
  const SeaPlantConfig& config() const { return config_; }
  /// Ground truth of SEA 0 (MCP) or 1 (PIP); throws std::out_of_range otherwise.
  const SeaTruth& truth(int sea) const;
  /// The ideal SEA law of eq 2 evaluated on the true state: 2k(r_m θ_m − r_j(θ_j − θ_j0)) r_j — what a perfect
  /// estimator (eq 7, noise-free sensors) would report. Differs from truth().joint_torque_Nm by the cable play.
  double idealSeaTorque_Nm(int sea) const;

 private:
  struct Channel {
    SeaChannelParams p{};
    double inertia = 0;         ///< at the pulley
    double theta_m = 0, omega_m = 0, current = 0;
    double x_e = 0;             ///< spring-side cable travel
    double theta_j = 0;
    SeaTruth truth{};
  };
  static int idx(int sea);
  void substep(Channel& c, double duty, bool bridge_on, double h);
  void solveJoint(Channel& c) const;
  void sample(SimIo& io);
  double gaussian();

  SeaPlantConfig config_;
  double time_s_ = 0;
  std::array<Channel, 2> ch_{};
  std::mt19937 rng_;
};

}  // namespace phalanx::sim
