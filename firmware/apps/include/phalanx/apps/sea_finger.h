#pragma once
/// Firmware app for the index-finger exoskeleton with Bowden-cable series elastic actuators (seeds/001, Agarwal
/// et al. 2015): two DC motors with encoders (MCP, PIP SEA), five joint angle sensors, motor current sense and,
/// on the §7.1 test rig, a load cell per SEA joint. docs/sea-firmware.md describes the loops and every default.
///
/// Per SEA and tick (1 kHz), in SI units:
///   sense     θ_j  = moving average of the joint sensor (the paper's FPGA filter, §7.5), Δθ_j = θ_j − θ_j0
///             θ_m  = encoder angle at the motor pulley since zeroing
///             τ̂_j = 2k r_j (r_m θ_m − r_j Δθ_j)                                   (eq 7, SEA torque estimate)
///   control   u    = (1/r_m)(y_d / (2k r_j) + r_j Δθ_j) + K_p e + K_d ė + K_i ∫e   (eq 8, desired motor angle)
///             duty = motor position loop(u)                                         (§7.5: EPOS position PID)
///   watchdog  |θ_m| > 60° latches kMotorAngle (§6.2); u is clamped inside the window first.
/// Two controllers behind one switch (device parameter kController), so benches compare them on one plant:
///   kPaper  the paper's plain PID: eq 7 estimate, eq 8 at 500 Hz (§7.5), a position PID without feed-forward.
///   kOurs   eq 8 at 1 kHz with (i) a Bowden-cable play model in the estimate (the motor-side travel passes a
///           play of width b̂ = b_0 + b_1 |τ̂| before it reaches the spring, §8.1.1), (ii) the play's inverse in
///           the feed-forward (adds ±b̂/2 in the direction the cable must move), and (iii) a motor position loop
///           with velocity, spring-load and sheath-friction feed-forward and back-EMF compensation.
/// Modes: kSetpoint tracks the exoskeleton joint torques in the command (N·m); kTransparent tracks zero torque;
/// kSafe/kLock: bridges off (the core's safe state, mode 0 in telemetry: the SEA is back-drivable, nothing holds it;
/// the SEAs relax by back-driving the geared motors).
/// Freestanding: no heap, no exceptions, single precision, bounded loops.
#include <cstdint>

#include "phalanx/apps/frozen_sensor.h"
#include "phalanx/fw/app.h"

namespace phalanx::apps {

constexpr int kSeaCount = 2;         ///< 0: exoskeleton MCP joint, 1: exoskeleton PIP joint
constexpr int kSeaJointSensors = 5;  ///< five joint angle sensors, one redundant
/// The joint sensors of the finger's planar chain that no SEA uses (sea/kinematics.h SensorIndex: 2 the redundant
/// θ7r, 3 the DIP chain; 0 and 1 are the SEA joints, 4 the passive abduction).
constexpr int kSeaChainSensorsFirst = 2;
constexpr int kSeaChainSensorsLast = 3;
constexpr int kSeaMaxMovingAverage = 32;

enum class SeaControllerKind : uint8_t {
  kOurs = 0,   ///< eq 8 + cable-play model and inverse + feed-forward position loop, 1 kHz
  kPaper = 1,  ///< the paper's plain PID baseline (eq 7–8 at 500 Hz, position PID)
};

/// Board- and unit-specific constants (defaults: seaFingerDefaultCalibration(), from phalanx/sea/board.h).
struct SeaFingerCalibration {
  float joint_counts_per_rad = 1.0f;
  float joint_zero_counts = 2048.0f;
  float joint_centre_rad[kSeaJointSensors] = {};   ///< angle at joint_zero_counts, per sensor
  int32_t joint_valid_min = 0;                     ///< counts outside [min, max]: open/shorted sensor
  int32_t joint_valid_max = 4095;
  int joint_sensor_of_sea[kSeaCount] = {0, 1};     ///< which sensor measures each SEA joint
  float motor_rad_per_count = 1.0f;                ///< encoder count → motor pulley angle
  float current_counts_per_A = 1.0f;
  float current_zero_counts = 2048.0f;
  float load_cell_counts_per_Nm = 1.0f;
  float load_cell_zero_counts = 2048.0f;
  // SEA (eq 7): spring stiffness per SEA, joint and motor pulley radii.
  float spring_N_per_m[kSeaCount] = {};
  float joint_pulley_radius_m = 0.0f;
  float motor_pulley_radius_m = 0.0f;
  // Drive: supply, armature + bridge resistance, torque constant, gear ratio, inertia at the pulley.
  float supply_V = 24.0f;
  float resistance_Ohm = 1.0f;
  float torque_constant_Nm_per_A = 0.01f;
  float gear_ratio = 1.0f;
  float inertia_kg_m2 = 1e-3f;
  float coulomb_Nm = 0.0f;                         ///< motor + gear friction at the pulley (no load)
  // Bowden cable model (kOurs): play b = b_0 + b_1 |τ|, sheath friction μΘ and the cable pretension.
  float backlash_base_m[kSeaCount] = {};
  float backlash_per_Nm_m[kSeaCount] = {};
  float sheath_friction = 0.0f;
  float pretension_N = 0.0f;
};

/// Torque-loop gains (eq 8): u in rad of motor angle per N·m of torque error.
struct SeaTorqueGains {
  float kp_rad_per_Nm = 0.0f;
  float ki_rad_per_Nm_s = 0.0f;
  float kd_rad_s_per_Nm = 0.0f;
  float i_limit_rad = 0.2f;      ///< |K_i ∫e| bound (anti-windup)
};

struct SeaFingerConfig {
  SeaControllerKind controller = SeaControllerKind::kOurs;
  SeaTorqueGains ours[kSeaCount] = {};
  SeaTorqueGains paper[kSeaCount] = {};
  uint8_t paper_rate_divider = 2;        ///< eq 8 runs every n-th tick for kPaper (500 Hz at a 1 kHz tick, §7.5)
  uint8_t joint_ma_samples = 8;          ///< moving-average window on the joint sensors (§7.5)
  float torque_derivative_filter_hz = 60.0f;
  float joint_velocity_filter_hz = 20.0f;
  float motor_velocity_filter_hz = 150.0f;
  // Motor position loop, kOurs: PD with bandwidth ω_c and damping ζ on the inertia at the pulley, plus
  // feed-forward; kPaper: a position PID (EPOS-like) without feed-forward.
  float pos_bandwidth_hz = 50.0f;
  float pos_damping = 1.0f;
  float backlash_compensation = 1.0f;    ///< scale of the play model and its inverse (0: off)
  /// kOurs: the feed-forward uses the joint angle predicted this far ahead (θ_j + θ̇_j·lead), which makes up
  /// for the moving average's group delay ((n − 1)/2 ticks) and the motor position loop's lag.
  float joint_lead_s = 0.008f;
  /// The inverse moves the motor to the other side of the play once the desired spring-side cable position is
  /// this far beyond the play model's spring side (a deadband: sensor noise on a still joint, ≈ 6 µm of cable,
  /// must not dither the motor across the play), ramping over backlash_switch_s.
  float backlash_deadband_m = 20e-6f;
  float backlash_switch_s = 0.002f;
  float paper_pos_kp_Nm_per_rad = 20.0f;
  float paper_pos_ki_Nm_per_rad_s = 200.0f;
  float paper_pos_kd_Nm_s_per_rad = 0.25f;
  // Limits.
  float max_torque_Nm[kSeaCount] = {0.4f, 0.15f};   ///< setpoints are clamped here (limit, not fault)
  float torque_fault_Nm[kSeaCount] = {0.6f, 0.25f}; ///< |τ̂| beyond this for torque_fault_ticks → kForceLimit
  uint16_t torque_fault_ticks = 50;
  float motor_command_limit_rad = 0.95993109f;      ///< u clamped to ±55°, inside the watchdog window
  float motor_angle_limit_rad = 1.04719755f;        ///< watchdog: |θ_m| > 60° → kMotorAngle (§6.2)
  float max_duty = 0.95f;
  float current_limit_A = 2.5f;                     ///< sustained |I| beyond this → kCurrentLimit
  uint16_t current_limit_ticks = 200;
  /// `sensor-stuck`: an SEA joint's sensor (joint_sensor_of_sea) unchanged for 250 ticks while the chain's
  /// redundant and DIP sensors changed ≥ 40 counts in total (frozen_sensor.h).
  FrozenSensorLimits joint_stuck{};
};

/// Device parameters (ParamGet/ParamSet; settable only while the outputs are safe).
namespace sea_param {
constexpr uint16_t kController = 0x0100;            ///< 0 ours, 1 paper baseline
constexpr uint16_t kBacklashCompensation = 0x0101;  ///< 0..2
constexpr uint16_t kJointMovingAverage = 0x0102;    ///< 1..32 samples
constexpr uint16_t kZero = 0x0103;                  ///< write 1: re-zero θ_j0, θ_m and the load cell (64 ticks)
constexpr uint16_t kKp = 0x0110;                    ///< + SEA index: K_p of the active controller
constexpr uint16_t kKi = 0x0120;                    ///< + SEA index
constexpr uint16_t kKd = 0x0130;                    ///< + SEA index
/// Kept in flash by the settings store (layout version 1; docs/params.md), in the order applied: the controller
/// first, since the gains are those of the active controller.
inline constexpr uint16_t kPersisted[] = {kController, kBacklashCompensation, kJointMovingAverage,
                                          kKp, kKp + 1, kKi, kKi + 1, kKd, kKd + 1};
inline constexpr fw::SettingsLayout kSettingsLayouts[] = {{1, kPersisted, 9, nullptr, 0}};
}  // namespace sea_param

SeaFingerCalibration seaFingerDefaultCalibration();
SeaFingerConfig seaFingerDefaultConfig();

/// Per-SEA state, visible to tests and telemetry.
struct SeaChannelState {
  float joint_rad = 0.0f;             ///< θ_j − θ_j0 (filtered)
  float joint_rate_rad_s = 0.0f;
  float motor_rad = 0.0f;             ///< θ_m
  float motor_rate_rad_s = 0.0f;
  float current_A = 0.0f;
  float load_cell_Nm = 0.0f;
  float tau_eq7_Nm = 0.0f;            ///< eq 7 estimate
  float tau_play_Nm = 0.0f;           ///< estimate through the cable-play model (kOurs)
  float cable_spring_m = 0.0f;        ///< play model: spring-side cable travel
  float tau_hat_Nm = 0.0f;            ///< the estimate the active controller uses
  float tau_desired_Nm = 0.0f;
  float tau_desired_rate_Nm_s = 0.0f;
  float tau_hat_rate_Nm_s = 0.0f;
  float integral_rad = 0.0f;
  float u_rad = 0.0f;                 ///< desired motor angle (eq 8), after the command clamp
  float u_ff_rad = 0.0f;
  float u_ff_rate_rad_s = 0.0f;
  float pos_integral_Nm = 0.0f;       ///< kPaper position PID integral
  float play_side = 0.0f;             ///< kOurs: side of the play the feed-forward holds the motor on, −1…1
  float play_side_target = 0.0f;
  float duty = 0.0f;
  bool command_limited = false;
};

class SeaFingerApp : public fw::DeviceApp {
 public:
  SeaFingerApp(const SeaFingerCalibration& calibration, const SeaFingerConfig& config);
  const protocol::DeviceLayout& layout() const override;
  void init(hal::Board& board) override;
  uint16_t sense(float dt_s) override;
  uint16_t control(const protocol::Command& cmd, float dt_s) override;
  void safe() override;
  void fillSamples(int16_t* samples) const override;
  protocol::ParamStatus getParam(uint16_t id, float& value) const override;
  protocol::ParamStatus setParam(uint16_t id, float value) override;
  fw::SettingsHistory settingsHistory() const override;

  const SeaChannelState& channel(int sea) const { return ch_[sea]; }
  float jointSensor_rad(int sensor) const { return joint_rad_[sensor]; }
  bool zeroed() const { return zero_ticks_left_ == 0; }
  const SeaFingerConfig& config() const { return cfg_; }

 private:
  void resetControllers();
  float playWidth(int sea, float tau_abs) const;
  uint16_t frozenJointSensors(const int32_t (&raw)[kSeaJointSensors]);

  SeaFingerCalibration cal_;
  SeaFingerConfig cfg_;
  hal::Board* board_ = nullptr;
  SeaChannelState ch_[kSeaCount];
  // Joint sensor moving averages.
  int32_t ma_buf_[kSeaJointSensors][kSeaMaxMovingAverage] = {};
  int32_t ma_sum_[kSeaJointSensors] = {};
  uint8_t ma_pos_ = 0;
  uint8_t ma_fill_ = 0;
  float joint_rad_[kSeaJointSensors] = {};  ///< filtered sensor angles (sensor frame)
  int32_t joint_raw_[kSeaJointSensors] = {};  ///< the previous tick's raw counts (frozen-sensor watch)
  FrozenSensor joint_frozen_[kSeaCount];
  // Zeroing (θ_j0, encoder zero, load-cell zero).
  uint16_t zero_ticks_left_ = 0;
  float zero_joint_sum_[kSeaCount] = {};
  float zero_lc_sum_[kSeaCount] = {};
  float joint_zero_rad_[kSeaCount] = {};
  int32_t encoder_zero_[kSeaCount] = {};
  float load_cell_zero_counts_[kSeaCount] = {};
  // Differentiators.
  bool primed_ = false;
  float last_joint_[kSeaCount] = {};
  float last_motor_[kSeaCount] = {};
  bool ctl_primed_ = false;
  float last_tau_d_[kSeaCount] = {};
  float last_tau_hat_[kSeaCount] = {};
  float last_u_ff_[kSeaCount] = {};
  uint8_t paper_phase_ = 0;
  uint16_t overtorque_ticks_[kSeaCount] = {};
  uint16_t overcurrent_ticks_[kSeaCount] = {};
};

}  // namespace phalanx::apps
