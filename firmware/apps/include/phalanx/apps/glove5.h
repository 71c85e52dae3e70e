#pragma once
/// Firmware app for the RML five-finger glove (000: Ma & Ben-Tzvi 2015): per finger a worm-geared DC motor on an
/// H-bridge, three Hall-effect mechanism-angle sensors and a fingertip strain gauge.
///
/// Control, per finger and tick (admittance form: the 101:1 self-locking worm drive is a velocity source, not a
/// torque source, so force is controlled through the tendon's velocity):
///   v_ff   = r(α)·α̇                          tendon velocity that keeps its length as the finger moves,
///                                             r(α) = c·(J_α^u)ᵀ n(φ) (glove/tendon.h, eq 5, 9, 18)
///   v_fb   = PID(F_desired − F_measured)       fingertip-force PID with anti-windup, output in m/s
///   ω_m    = (v_ff + v_fb) · N / r_spool       motor speed that winds the spool at that velocity
///   duty   = (K_e·ω_m + c_IR·R·I_measured) / V back-EMF plus IR compensation from the current sense
/// Freestanding: no heap, no exceptions, single precision.
#include <cstdint>

#include "phalanx/control/pid.h"
#include "phalanx/apps/frozen_sensor.h"
#include "phalanx/fw/app.h"
#include "phalanx/glove/kinematics.h"

namespace phalanx::apps {

constexpr int kGloveFingers = 5;
constexpr int kGloveJoints = 3;
constexpr int kGloveHallChannels = kGloveFingers * kGloveJoints;

/// Piecewise-linear Hall transfer: raw counts (strictly increasing) → mechanism angle.
struct HallTable {
  static constexpr int kMaxPoints = 17;
  uint8_t points = 0;
  float counts[kMaxPoints] = {};
  float angle_rad[kMaxPoints] = {};
};

/// Everything board- and unit-specific, in one place (defaults: glove5DefaultCalibration()).
struct Glove5Calibration {
  HallTable hall[kGloveHallChannels];
  int32_t hall_valid_min = 0;       ///< raw counts below/above this are an open or shorted sensor
  int32_t hall_valid_max = 4095;
  float strain_counts_per_N[kGloveFingers] = {};
  float strain_zero_counts[kGloveFingers] = {};
  int32_t strain_saturation_min = 0;  ///< raw at or beyond these: the gauge amplifier is saturated
  int32_t strain_saturation_max = 0;
  float current_counts_per_A = 1.0f;
  float current_zero_counts = 0.0f;
  /// Mechanism geometry per finger and the tendon's pad transmission c, for r(α) (glove/tendon.h).
  glove::MechanismGeometry<float> mech[kGloveFingers] = {};
  float pad_transmission = 0.3f;
  /// Motor speed per tendon speed at the spool, N / r_spool (rad/s per m/s).
  float motor_rad_per_tendon_m = 0.0f;
  /// Duty per motor rad/s of back-EMF, K_e / V_supply.
  float duty_per_motor_rad_per_s = 0.0f;
  /// Duty per ampere of resistive drop, (R_motor + R_bridge) / V_supply.
  float duty_per_A = 0.0f;
  /// +1 if positive duty winds the tendon that increases the measured pad force, -1 otherwise.
  float force_per_duty_sign = 1.0f;
};

/// Largest zero shift a tare accepts (N): the per-part offset's 3σ (0.45 N) plus the gauge's whole thermal drift
/// (≤ 0.36 N: 36 mN/K over the pad's 10 K warm-up, docs/glove-plant.md), with margin; a hand pressing the pad
/// (≥ 1 N) is refused.
inline constexpr float kTareMaxShift_N = 1.0f;

struct Glove5Config {
  control::PidConfig force_pid{};   ///< pad force error (N) → tendon velocity (m/s); out_min/max: ± max speed
  float ff_scale = 1.0f;            ///< 0 disables the finger-motion feed-forward
  float ir_compensation = 0.7f;     ///< c_IR: fraction of the resistive drop compensated (< 1 keeps it stable)
  float force_filter_hz = 300.0f;
  float velocity_filter_hz = 40.0f;
  float max_duty = 0.9f;
  /// The command's per-finger gain scale is applied at once when it falls (contact) and rises at most this fast
  /// (1/s) when it grows back (leaving contact), so the full free-motion gain does not meet the force the reduced
  /// contact gain left behind all at once.
  float gain_scale_rise_per_s = 2.0f;
  /// Engagement: a finger entering an active mode (from lock, safe or start-up) keeps its motor off — the worm
  /// holds — until its measured pad force is within this (N). The admittance loop cannot release a finger that
  /// keeps pressing (it chases the finger into the fist at full speed and overshoots, docs/glove-firmware.md), so a
  /// hand clenched when the session starts or the link comes back is held until it relaxes. kTareMaxShift_N: a
  /// relaxed pad whose tare was refused still reads within it (its zero's error is smaller).
  float engage_max_force_N = kTareMaxShift_N;
  float current_limit_A = 1.5f;     ///< sustained |I| above this for current_limit_ticks → fault
  uint16_t current_limit_ticks = 100;
  float active_force_limit_N = 10.0f;  ///< 000 §2.2: maximum active fingertip force
  float strain_full_scale_N = 30.0f;
  /// Glove joint limits per finger (the mechanism's range over the finger's Table 2 range, widened by a
  /// margin; each span ≤ 150°, eq 22), checked while driving.
  float joint_min_rad[kGloveFingers][kGloveJoints] = {};
  float joint_max_rad[kGloveFingers][kGloveJoints] = {};
  /// `sensor-stuck`: a Hall count unchanged for 250 ticks while the finger's other two sensors changed ≥ 40
  /// counts in total (frozen_sensor.h).
  FrozenSensorLimits hall_stuck{};
};

/// Device parameters (ParamGet/ParamSet, only settable while outputs are safe).
namespace glove5_param {
constexpr uint16_t kForceKp = 0x0100;
constexpr uint16_t kForceKi = 0x0101;
constexpr uint16_t kForceKd = 0x0102;
constexpr uint16_t kFeedForwardScale = 0x0103;
/// Write 1: re-zero every strain gauge over the next 64 ticks (hand relaxed). A finger whose new zero lies more than
/// kTareMaxShift_N from its current zero keeps the current one: its pad is loaded (a hand squeezing at a session
/// start or a reconnect), and a zero taken there would make the glove push that force into the relaxed finger
/// later. Read: ticks left while running; then 0 (all fingers re-zeroed) or −mask of the refused fingers
/// (bit = FingerId).
constexpr uint16_t kTare = 0x0110;
/// Read-only, 0x0200 + finger (FingerId order): fingerprint (geometry_fingerprint.h) of the mechanism geometry in
/// the calibration (tendon moment arms, joint windows). The host refuses a geometry file that does not match it.
constexpr uint16_t kGeometryFingerprintBase = 0x0200;
/// Kept in flash by the settings store (docs/params.md), in the order applied. Layout 1 kept the force PID gains;
/// layout 2 adds the feed-forward scale (an update from 1 to 2 keeps the gains, the scale starts at its default).
/// Layout 1 never shipped: it is the firmware before an update that the test plays (firmware-sim --settings-layout 1).
inline constexpr uint16_t kPersistedV1[] = {kForceKp, kForceKi, kForceKd};
inline constexpr uint16_t kPersisted[] = {kForceKp, kForceKi, kForceKd, kFeedForwardScale};
inline constexpr fw::SettingsLayout kSettingsLayouts[] = {{1, kPersistedV1, 3, nullptr, 0}, {2, kPersisted, 4, nullptr, 0}};
}  // namespace glove5_param

Glove5Calibration glove5DefaultCalibration();
Glove5Config glove5DefaultConfig();

/// Per-finger state, visible for tests and telemetry.
struct GloveFingerState {
  float alpha_rad[kGloveJoints] = {};
  float alpha_rate_rad_per_s[kGloveJoints] = {};
  float force_N = 0.0f;       ///< filtered pad force, positive resists flexion
  float current_A = 0.0f;
  float tendon_velocity_m_per_s = 0.0f;  ///< commanded, v_ff + v_fb
  float duty = 0.0f;
  float gain_scale = 1.0f;    ///< the force loop's gain scale in use (the command's, its rises slew-limited)
  bool engaged = false;       ///< the force loop drives the motor (false in lock and safe, and while held, above)
  control::PidState pid{};
};

class Glove5App : public fw::DeviceApp {
 public:
  Glove5App(const Glove5Calibration& calibration, const Glove5Config& config);
  const protocol::DeviceLayout& layout() const override;
  void init(hal::Board& board) override;
  uint16_t sense(float dt_s) override;
  uint16_t control(const protocol::Command& cmd, float dt_s) override;
  void safe() override;
  void fillSamples(int16_t* samples) const override;
  protocol::ParamStatus getParam(uint16_t id, float& value) const override;
  protocol::ParamStatus setParam(uint16_t id, float value) override;
  fw::SettingsHistory settingsHistory() const override;

  const GloveFingerState& finger(int i) const { return finger_[i]; }

 private:
  Glove5Calibration cal_;
  Glove5Config cfg_;
  hal::Board* board_ = nullptr;
  GloveFingerState finger_[kGloveFingers];
  control::LowPass force_lp_[kGloveFingers];
  control::LowPass rate_lp_[kGloveHallChannels];
  float last_alpha_[kGloveHallChannels] = {};
  bool primed_ = false;
  int32_t last_raw_[kGloveHallChannels] = {};
  FrozenSensor hall_frozen_[kGloveHallChannels];
  uint16_t overcurrent_ticks_[kGloveFingers] = {};
  uint16_t tare_ticks_left_ = 0;
  float tare_sum_[kGloveFingers] = {};
  uint8_t tare_refused_mask_ = 0;  ///< fingers whose last tare was refused (loaded pad)
};

}  // namespace phalanx::apps
