#pragma once
/// Twin-Pantograph haptic pen board: channel map, sign conventions and drive/sensor transfer constants, shared
/// by the `pantograph` firmware app (decodes and encodes with them) and the simulated plant (hal/sim PenPlant).
///
/// The paper (seeds/004 §VI) gives: six direct-drive Maxon motors (larger at the waists), 4000 counts/turn optical
/// encoders on every active joint, a 1 kHz control rate. The drive electronics are not described; the choices
/// below are documented in docs/pen-plant.md.
///
/// SIGN CONVENTIONS: joint i = encoder channel i = PWM channel i = current channel i, in the order q1..q6 of
/// kinematics.h (bottom waist, bottom shoulders a/b, top waist, top shoulders a/b). Positive duty → positive
/// motor current → positive joint torque → the joint angle grows → the encoder counts up.
#include <cstdint>

namespace phalanx::pen::board {

inline constexpr int kJointCount = 6;
inline constexpr int kPwmChannelCount = 6;
inline constexpr int kEncoderChannelCount = 6;
/// ADC channels 0..5: motor current sense, one per joint.
inline constexpr int kAdcChannelCount = 6;

/// 4000 counts per joint turn (§VI), counted from the home pose (index pulse at home).
inline constexpr float kEncoderCountsPerRev = 4000.0f;

/// Drive: a current-mode servo amplifier per motor; the PWM duty is the current command as a fraction of the
/// amplifier's peak current. Peak joint torque 2.1 N·m on all six joints (docs/pen-model.md §"Torque limits").
inline constexpr float kTorqueConstant_Nm_per_A = 0.10f;   ///< motor K_t (design choice, docs/pen-plant.md)
inline constexpr float kPeakCurrent_A = 21.0f;             ///< amplifier limit: 21 A · 0.1 N·m/A = 2.1 N·m
inline constexpr float kPeakTorque_Nm = kTorqueConstant_Nm_per_A * kPeakCurrent_A;

/// Current sense: ±kPeakCurrent_A · 1.25 over a 12-bit ADC, mid-scale = 0 A.
inline constexpr int32_t kAdcMaxCounts = 4095;
inline constexpr int32_t kAdcMidCounts = 2048;
inline constexpr float kCurrentSenseFullScale_A = 1.25f * kPeakCurrent_A;
inline constexpr float kAmpsPerCount = kCurrentSenseFullScale_A / 2048.0f;

constexpr float dutyFromTorque(float torque_Nm) { return torque_Nm / kPeakTorque_Nm; }
constexpr float torqueFromDuty(float duty) { return duty * kPeakTorque_Nm; }

}  // namespace phalanx::pen::board
