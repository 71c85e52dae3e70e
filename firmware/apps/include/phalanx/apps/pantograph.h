#pragma once
/// Firmware app for the Twin-Pantograph haptic pen (004: Stocco, Salcudean & Sassani, §VI): six direct-drive
/// motors on current-mode amplifiers (the PWM duty is the current command), six 4000 counts/turn encoders, six
/// motor current sense channels (pen/board.h).
///
/// The pen is an impedance device: the firmware is a joint-torque servo. Each tick:
///   q_i     = counts_i · 2π/4000                 joint angle relative to home (the host adds q_home)
///   q̇_i     = low-pass(Δq_i / dt)                for telemetry and the velocity plausibility check
///   τ_i     = clamp(setpoint_i · gain_i, ±τmax_i) kSetpoint; 0 in kTransparent (kLock: the core's safe state, back-drivable)
///   duty_i  = τ_i / (K_t · I_peak)
/// Safety (faults latch in the core, which then calls safe(): every duty 0, bridges off): encoder jump beyond a
/// physical speed (kSensorRange), joint outside its window (kJointLimit), measured current beyond the amplifier
/// limit or disagreeing with the command for too long (kCurrentLimit), current sense at full scale
/// (kSensorSaturated), and the six encoders no longer describing one rigid pen (kSensorStuck, below). The core adds
/// the command watchdog (link loss) and the e-stop.
/// Freestanding: no heap, no exceptions, single precision.
#include <cstdint>

#include "phalanx/control/pid.h"
#include "phalanx/fw/app.h"
#include "phalanx/pen/board.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::apps {

constexpr int kPenJoints = pen::board::kJointCount;

struct PantographConfig {
  float torque_limit_Nm[kPenJoints] = {2.1f, 2.1f, 2.1f, 2.1f, 2.1f, 2.1f};
  /// Joint windows relative to home (rad), for the compile-time geometry pen::defaultGeometry (l6 = centre to
  /// universal joint, pen 14 cm). The plant's soft-stop workspace spans bottom waist −24…+46°, top waist
  /// −46…+24°, shoulders ±76° (docs/pen-plant.md); the windows add ≥ 14° margin (checked against the model by
  /// tests/unit/pen_firmware_test.cpp JointWindowsContainTheSoftStopWorkspace).
  float joint_min_rad[kPenJoints] = {-0.698f, -1.571f, -1.571f, -1.047f, -1.571f, -1.571f};
  float joint_max_rad[kPenJoints] = {1.047f, 1.571f, 1.571f, 0.698f, 1.571f, 1.571f};
  /// An encoder moving more than this in one tick is a glitch (500 counts/ms = 785 rad/s, far beyond a hand).
  int32_t max_counts_per_tick = 500;
  float velocity_filter_hz = 100.0f;
  /// |I_measured − I_commanded| above this for current_mismatch_ticks: amplifier or wiring fault.
  float current_mismatch_A = 3.0f;
  uint16_t current_mismatch_ticks = 20;
  float overcurrent_A = 1.1f * pen::board::kPeakCurrent_A;
  /// The rigid-pen encoder watch: six encoders measure a pen with five degrees of freedom (004 §VI: the waist
  /// actuator q4 is redundant), so the two pen ends they place must stay one pen length apart
  /// (pen::Model::ends_tolerance_m, 2 mm ≈ 10 counts of tip motion) and both five-bars must close. An encoder that
  /// freezes (or slips counts) breaks that as soon as the pen moves in a way it should have seen; this many ticks
  /// in a row latch kSensorStuck. An encoder's count is legitimately constant while the pen is still, so, unlike
  /// the glove's Hall sensors, "unchanged" alone is no evidence here.
  uint16_t ends_inconsistent_ticks = 10;
};

PantographConfig pantographDefaultConfig();

/// Device parameters (ParamGet/ParamSet).
namespace pantograph_param {
constexpr uint16_t kTorqueLimitBase = 0x0100;  ///< 0x0100 + joint: torque limit (N·m), 0 < value ≤ 2.1
/// Read-only: fingerprint (geometry_fingerprint.h) of the compile-time geometry pen::defaultGeometry that the
/// joint windows were made for. The host refuses a geometry file that does not match it.
constexpr uint16_t kGeometryFingerprint = 0x0200;
/// Kept in flash by the settings store (layout version 1; docs/params.md): the six torque limits.
inline constexpr uint16_t kPersisted[] = {kTorqueLimitBase,     kTorqueLimitBase + 1, kTorqueLimitBase + 2,
                                          kTorqueLimitBase + 3, kTorqueLimitBase + 4, kTorqueLimitBase + 5};
inline constexpr fw::SettingsLayout kSettingsLayouts[] = {{1, kPersisted, 6, nullptr, 0}};
}  // namespace pantograph_param

struct PenJointState {
  int32_t counts = 0;
  float angle_rad = 0.0f;        ///< relative to home
  float rate_rad_per_s = 0.0f;
  float current_A = 0.0f;        ///< measured
  float torque_cmd_Nm = 0.0f;
  float duty = 0.0f;
};

class PantographApp : public fw::DeviceApp {
 public:
  explicit PantographApp(const PantographConfig& config = pantographDefaultConfig());
  const protocol::DeviceLayout& layout() const override;
  void init(hal::Board& board) override;
  uint16_t sense(float dt_s) override;
  uint16_t control(const protocol::Command& cmd, float dt_s) override;
  void safe() override;
  void fillSamples(int16_t* samples) const override;
  protocol::ParamStatus getParam(uint16_t id, float& value) const override;
  protocol::ParamStatus setParam(uint16_t id, float value) override;
  fw::SettingsHistory settingsHistory() const override;

  const PenJointState& joint(int i) const { return joint_[i]; }
  const PantographConfig& config() const { return cfg_; }

 private:
  uint16_t watchRigidPen();

  PantographConfig cfg_;
  const pen::Model<float> model_ = pen::defaultModel<float>();  ///< the compile-time geometry (kGeometryFingerprint)
  pen::Data<float> kin_{};  ///< computeEnds' workspace
  uint16_t inconsistent_ticks_ = 0;
  hal::Board* board_ = nullptr;
  PenJointState joint_[kPenJoints];
  control::LowPass rate_lp_[kPenJoints];
  bool primed_ = false;
  uint16_t mismatch_ticks_[kPenJoints] = {};
};

}  // namespace phalanx::apps
