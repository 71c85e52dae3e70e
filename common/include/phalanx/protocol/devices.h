#pragma once
/// Per-device channel maps: what each telemetry sample and command setpoint means, and the fixed-point scale of
/// each sample kind. One table used by firmware (to encode) and host (to decode).
#include <cmath>
#include <cstdint>

#include "phalanx/protocol/messages.h"

namespace phalanx::protocol {

/// The physical kind of a telemetry sample; each kind has one fixed-point scale (SI units per LSB).
enum class SampleKind : uint8_t {
  kAngle = 0,    ///< rad, 1e-4 rad/LSB (±3.2767 rad)
  kForce = 1,    ///< N, 1e-3 N/LSB (±32.767 N)
  kTorque = 2,   ///< N·m, 1e-4 N·m/LSB (±3.2767 N·m)
  kDuty = 3,     ///< PWM duty, 1e-4/LSB (±1 used)
  kCurrent = 4,  ///< A, 1e-3 A/LSB
};

constexpr float sampleScale(SampleKind kind) {
  switch (kind) {
    case SampleKind::kAngle: return 1e-4f;
    case SampleKind::kForce: return 1e-3f;
    case SampleKind::kTorque: return 1e-4f;
    case SampleKind::kDuty: return 1e-4f;
    case SampleKind::kCurrent: return 1e-3f;
  }
  return 1.0f;
}

/// std::lround for |x| < 2^31 without the library call (on the MCU a soft routine; a glove5 telemetry frame
/// rounds 25 samples): truncate toward zero, then the remainder, which is exact, decides - half away from zero.
inline int32_t roundHalfAway(float x) {
  int32_t i = static_cast<int32_t>(x);
  const float frac = x - static_cast<float>(i);
  if (frac >= 0.5f) ++i;
  else if (frac <= -0.5f) --i;
  return i;
}

/// SI value → int16 sample, rounded to nearest and saturated; NaN encodes as 0.
inline int16_t encodeSample(float value, SampleKind kind) {
  if (!(value == value)) return 0;
  const float lsb = value / sampleScale(kind);
  if (lsb >= 32767.0f) return 32767;
  if (lsb <= -32767.0f) return -32767;
  return static_cast<int16_t>(roundHalfAway(lsb));
}

inline float decodeSample(int16_t raw, SampleKind kind) { return static_cast<float>(raw) * sampleScale(kind); }

/// What a device of a given type is mounted on or built as (core parameter core_param::kDeviceVariant): the
/// device type and layout stay the same, the host can tell the variants apart.
namespace variant {
constexpr uint8_t kStandard = 0;    ///< the device as such (glove5 on a hand, sea_finger on a finger, the pen)
constexpr uint8_t kSeaTestRig = 1;  ///< sea_finger on the §7.1 test rig: both joints clamped to load cells
}  // namespace variant

/// A device's channel layout.
struct DeviceLayout {
  DeviceType type;
  const char* name;            ///< "glove5", "sea_finger", "pantograph"
  uint8_t setpoint_count;
  float setpoint_limit;        ///< |setpoint| hard limit in SI units (device side rejects beyond)
  uint8_t sample_count;
  SampleKind sample_kind[kMaxSamples];
  /// Mode kLock holds the mechanism passively (the glove's self-locking worm drives): an active mode, the app
  /// runs. false (back-drivable devices): kLock is the safe state, outputs off.
  bool passive_lock = false;
};

/// glove5: samples 0..14 mechanism angles α (3·finger + joint), 15..19 fingertip pad force, 20..24 motor duty.
/// Setpoints 0..4: fingertip pad force in N (positive resists flexion), |F| ≤ 10 N (000 §2.2).
constexpr DeviceLayout kGlove5Layout{
    DeviceType::kGlove5, "glove5", 5, 10.0f, 25,
    {SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle,
     SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle,
     SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle,
     SampleKind::kForce, SampleKind::kForce, SampleKind::kForce, SampleKind::kForce, SampleKind::kForce,
     SampleKind::kDuty, SampleKind::kDuty, SampleKind::kDuty, SampleKind::kDuty, SampleKind::kDuty},
    true};

/// sea_finger: samples 0..4 joint angle sensors (moving-averaged, sensor frame; 0 = exoskeleton MCP joint θ_1r,
/// 1 = exoskeleton PIP joint θ_6r, 4 = redundant), 5..6 motor angles θ_m (MCP, PIP, since zeroing), 7..8 SEA
/// joint torque estimate (eq 7, through the cable-play model with the default controller), 9..10 motor duty,
/// 11..12 test-rig load-cell torque (§7.1; ≈ 0 when no load cell is wired). Setpoints 0..1: exoskeleton joint
/// torque in N·m (docs/sea-firmware.md).
constexpr DeviceLayout kSeaFingerLayout{
    DeviceType::kSeaFinger, "sea_finger", 2, 1.0f, 13,
    {SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle,
     SampleKind::kAngle, SampleKind::kAngle, SampleKind::kTorque, SampleKind::kTorque, SampleKind::kDuty,
     SampleKind::kDuty, SampleKind::kTorque, SampleKind::kTorque}};

/// pantograph: samples 0..5 joint angles q1..q6 relative to home (encoder counts · 2π/4000), 6..11 measured motor
/// torque (current sense · K_t). Setpoints 0..5: joint torque in N·m, |τ| ≤ 2.1 N·m (the amplifier peak,
/// pen/board.h; docs/pen-model.md §"Torque limits").
constexpr DeviceLayout kPantographLayout{
    DeviceType::kPantograph, "pantograph", 6, 2.1f, 12,
    {SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle, SampleKind::kAngle,
     SampleKind::kAngle, SampleKind::kTorque, SampleKind::kTorque, SampleKind::kTorque, SampleKind::kTorque,
     SampleKind::kTorque, SampleKind::kTorque}};

/// Layout for a device type, or nullptr.
constexpr const DeviceLayout* layoutFor(DeviceType type) {
  switch (type) {
    case DeviceType::kGlove5: return &kGlove5Layout;
    case DeviceType::kSeaFinger: return &kSeaFingerLayout;
    case DeviceType::kPantograph: return &kPantographLayout;
    case DeviceType::kAny: return nullptr;
  }
  return nullptr;
}

}  // namespace phalanx::protocol
