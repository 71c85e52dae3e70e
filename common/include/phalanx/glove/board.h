#pragma once
/// RML five-finger glove board: channel map, sign conventions and nominal sensor/drive transfer constants.
///
/// Shared by the glove firmware (drivers decode raw counts with these tables) and the simulated plant
/// (hal/sim GlovePlant encodes its physics into counts with the same nominal transfers plus imperfections).
/// Freestanding C++17: constexpr data and constexpr helpers only — no heap, no exceptions, no <cmath>.
/// Single precision on purpose: these constants are used in float arithmetic on the Cortex-M4F.
///
/// The paper (seeds/000, Ma & Ben-Tzvi 2015) names the parts (FA-130 motor, 101:1 worm gearbox, Hall
/// sensors on the PCB links, fingertip strain gauge, 9 V battery) but not the board electronics. Every
/// number below is therefore either from the paper (section given), from the datasheet class of a part a
/// board designer would pick (part class given), or a design choice (reason given). docs/glove-plant.md
/// collects them.
///
/// SIGN CONVENTIONS (one direction for everything, chosen so that a force controller needs no sign flips):
///   duty > 0  →  bridge drives the motor +  →  motor shaft and spool turn +  →  the RELEASE tendon is wound
///   in (paper Fig 2: "active pulley rotates clockwise, the release tendon (blue) is tensioned and the
///   mechanism/finger opens")  →  mechanism angles α grow (opening, kinematics.h: flexion is negative)  →
///   the pad pushes the fingertip towards extension, i.e. along glove::padNormal() (dorsal)  →  the strain
///   gauge reads a POSITIVE force  →  the current sense reads a POSITIVE current.
///   So "positive pad force" = the glove resists the finger's closing (contact with a virtual object);
///   negative duty winds the grasp tendon and pulls the fingertip towards flexion (negative force).
///   Hall counts grow with the mechanism angle α of their joint.
#include <array>
#include <cstdint>

namespace phalanx::glove::board {

// -------------------------------------------------------------------------------------------------------
// Channel map
// -------------------------------------------------------------------------------------------------------

inline constexpr int kFingerCount = 5;       ///< thumb, index, middle, ring, little (= glove::FingerId order)
inline constexpr int kJointsPerFinger = 3;   ///< mechanism joints α1..α3 (B0, B1, B2), kinematics.h

/// PWM (H-bridge) channels 0..4: one finger motor each, in finger order.
inline constexpr int kPwmFirstMotor = 0;
inline constexpr int kPwmChannelCount = 5;
constexpr int motorPwmChannel(int finger) { return kPwmFirstMotor + finger; }

/// ADC channels 0..14: Hall sensors, channel 3·finger + joint (joint 0..2 = α1..α3).
inline constexpr int kAdcFirstHall = 0;
/// ADC channels 15..19: fingertip-pad strain gauges, one per finger.
inline constexpr int kAdcFirstStrain = 15;
/// ADC channels 20..24: motor current sense, one per finger.
inline constexpr int kAdcFirstCurrent = 20;
inline constexpr int kAdcChannelCount = 25;
constexpr int hallAdcChannel(int finger, int joint) { return kAdcFirstHall + kJointsPerFinger * finger + joint; }
constexpr int strainAdcChannel(int finger) { return kAdcFirstStrain + finger; }
constexpr int currentAdcChannel(int finger) { return kAdcFirstCurrent + finger; }
static_assert(hallAdcChannel(kFingerCount - 1, kJointsPerFinger - 1) + 1 == kAdcFirstStrain, "channel map");
static_assert(strainAdcChannel(kFingerCount - 1) + 1 == kAdcFirstCurrent, "channel map");
static_assert(currentAdcChannel(kFingerCount - 1) + 1 == kAdcChannelCount, "channel map");

// -------------------------------------------------------------------------------------------------------
// ADC
// -------------------------------------------------------------------------------------------------------

/// 12-bit SAR ADC of the microcontroller (STM32G4 class), single-ended, reference = the 3.3 V sensor supply
/// (ratiometric: Hall ICs and bridge excitation run from the same rail, so supply drift cancels).
inline constexpr int kAdcBits = 12;
inline constexpr int32_t kAdcMaxCounts = (1 << kAdcBits) - 1;  ///< 4095
inline constexpr float kAdcReference_V = 3.3f;
inline constexpr float kAdcCountsPerVolt = static_cast<float>(1 << kAdcBits) / kAdcReference_V;
/// Bipolar signals (strain, current) are referenced to mid-supply, 1.65 V = 2048 counts.
inline constexpr int32_t kAdcMidCounts = 1 << (kAdcBits - 1);
/// Conversions the ADC's hardware oversampler averages into each 12-bit sample (STM32G4 ADC_CFGR2: ratio 4,
/// right shift 2; RM0440 §21.4.30). It halves the converter's own noise; the noise of the sensor amplifiers ahead
/// of it, band-limited by their RC filters, is the same in the four conversions (2.4 µs apart) and stays.
/// The busiest ADC converts 8 channels: 8 × 4 × 25 ADC clocks at 42.5 MHz = 19 µs of the 50 µs PWM period that
/// triggers each scan.
inline constexpr int kAdcOversampling = 4;

// -------------------------------------------------------------------------------------------------------
// Hall-effect joint angle sensors (15)
// -------------------------------------------------------------------------------------------------------
// Part class: ratiometric linear Hall IC, DRV5055A2-class, 30 mV/mT at 3.3 V, quiescent output VCC/2, linear
// output swing 0.2 … VCC−0.2 V. It sits on the PCB link (paper §2.1: "PCB … carries … Hall Effect sensors to
// measure joint angles") facing a small diametric magnet on the neighbouring link. The field component it
// sees is an odd, saturating function of the joint angle — close to a sine of the "field angle"
// x = κ·(α − α_c) with a small 3rd harmonic from the magnet's finite size:
//     counts(α) = 2048 + A·(sin x − h3·sin 3x),   A = 40 mT · 30 mV/mT · 4096/3.3 V = 1489 counts.
// Peak field 40 mT keeps the output inside the linear swing (|x| ≤ 67.5° → 650 … 3447 counts).
// α_c and κ differ per joint (magnet placement) so that each joint's mechanical range spans x ∈ ±67.5°
// where the curve is still monotonic (slope ≥ 0.49 of the centre slope). Ranges covered (whole degrees,
// enclosing the five default mechanisms' α ranges of kinematics.h with margin):
//     α1: −100° … +80°,   α2: −160° … −40°,   α3: −90° … +90°.
// The firmware decodes with the 17-point table below (piecewise linear). Interpolating the nominal curve
// costs ≤ 0.6° at the table ends and ≤ 0.1° near the centre; real parts add per-sensor gain/offset and
// mounting-angle errors (modelled by the plant, docs/glove-plant.md) that a per-glove calibration removes.

inline constexpr int kHallTablePoints = 17;
/// Nominal magnet/Hall model that generated the table (the plant evaluates it analytically).
inline constexpr float kHallAmplitude_counts = 0.040f * 30.0f * kAdcCountsPerVolt;  ///< 40 mT × 30 mV/mT
inline constexpr float kHallThirdHarmonic = 0.04f;                                  ///< h3 above
inline constexpr float kHallHalfFieldAngle_rad = 1.1780972f;                        ///< 67.5°, |x| at table ends
/// Per joint (α1, α2, α3): centre angle α_c and half of the covered range (rad). κ = 67.5° / half-range.
inline constexpr std::array<float, 3> kHallCentre_rad = {-0.17453293f, -1.74532925f, 0.0f};   ///< −10°, −100°, 0°
inline constexpr std::array<float, 3> kHallHalfRange_rad = {1.57079633f, 1.04719755f, 1.57079633f};  ///< 90°, 60°, 90°

/// Nominal counts at the 17 table points (shared by the three joints: point i is at field angle
/// x_i = −67.5° + i·8.4375°). Increasing with α.
inline constexpr std::array<int16_t, kHallTablePoints> kHallTableCounts = {
    649, 773, 925, 1096, 1279, 1469, 1662, 1855, 2048, 2241, 2434, 2627, 2817, 3000, 3171, 3323, 3447};

/// Mechanism angle (rad) of table point `i` for joint `joint` (0..2): α_c + half-range·(i/8 − 1).
constexpr float hallTableAngle_rad(int joint, int i) {
  return kHallCentre_rad[joint] + kHallHalfRange_rad[joint] * (static_cast<float>(i) / 8.0f - 1.0f);
}

/// Decodes Hall counts to the mechanism angle α (rad) of `joint` (0..2) by linear interpolation in the
/// nominal table. Counts outside the table clamp to its end angles (the firmware's plausibility check
/// should flag counts beyond kHallPlausibleMin/MaxCounts as a sensor fault).
constexpr float hallCountsToAngle_rad(int joint, float counts) {
  if (counts <= static_cast<float>(kHallTableCounts[0])) return hallTableAngle_rad(joint, 0);
  for (int i = 1; i < kHallTablePoints; ++i) {
    const float c1 = static_cast<float>(kHallTableCounts[i]);
    if (counts <= c1) {
      const float c0 = static_cast<float>(kHallTableCounts[i - 1]);
      const float a0 = hallTableAngle_rad(joint, i - 1);
      const float a1 = hallTableAngle_rad(joint, i);
      return a0 + (a1 - a0) * (counts - c0) / (c1 - c0);
    }
  }
  return hallTableAngle_rad(joint, kHallTablePoints - 1);
}
/// Outside this band the Hall IC is railed, disconnected (pulled to 0) or shorted: a sensor fault.
/// DRV5055 output swing 0.2 … 3.1 V → 248 … 3848 counts.
inline constexpr int32_t kHallPlausibleMinCounts = 248;
inline constexpr int32_t kHallPlausibleMaxCounts = 3848;

// -------------------------------------------------------------------------------------------------------
// Fingertip strain gauges (5) — bidirectional force normal to the fingertip pad
// -------------------------------------------------------------------------------------------------------
// Part class: foil-gauge full bridge on the fingertip-pad flexure (paper §2.1: "measured by strain gauge
// attached to the fingertip pad"), 3.3 V excitation, rail-to-rail instrumentation amplifier (INA333 class)
// with its REF pin at mid-supply, into the same 12-bit ADC. A 24-bit bridge ADC (HX711 class) would resolve
// more but samples at 10–80 Hz, too slow for the ≥ 1 kHz force loop (DESIGN.md).
// Gain chosen so that ±20 N fills ±1.5 V: full scale is twice the 10 N maximum active force (§2.2) and
// keeps 10.7 mN/count, about a tenth of the 100 mN free-motion contact force of §4.3. Passive loads up to
// the 35 N worm hold (§2.2) saturate it — the firmware must treat a reading at the clamp as "≥ 20 N".
// Force is the component along glove::padNormal(φ) (positive: glove pushes the fingertip towards extension).
inline constexpr int32_t kStrainZeroCounts = kAdcMidCounts;                     ///< 0 N (nominal; tare at start)
inline constexpr float kStrainFullScale_N = 20.0f;                              ///< ± linear range
inline constexpr float kStrainCountsPerNewton = (1.5f / kStrainFullScale_N) * kAdcCountsPerVolt;  ///< 93.09
/// The amplifier output clamps here; readings at or beyond these are saturated (± full scale).
inline constexpr int32_t kStrainMaxCounts = kStrainZeroCounts + 1862;  ///< = zero + round(20 N · 93.09)
inline constexpr int32_t kStrainMinCounts = kStrainZeroCounts - 1862;
static_assert(static_cast<float>(kStrainMaxCounts - kStrainZeroCounts) > kStrainFullScale_N * kStrainCountsPerNewton - 0.5f &&
                  static_cast<float>(kStrainMaxCounts - kStrainZeroCounts) < kStrainFullScale_N * kStrainCountsPerNewton + 0.5f,
              "strain clamp must equal the full scale");

/// Pad normal force (N) from strain counts, nominal transfer (saturated readings decode to ± full scale).
constexpr float strainCountsToForce_N(int32_t counts) {
  return static_cast<float>(counts - kStrainZeroCounts) / kStrainCountsPerNewton;
}

// -------------------------------------------------------------------------------------------------------
// Motor current sense (5)
// -------------------------------------------------------------------------------------------------------
// Part class: bidirectional in-line current-sense amplifier with PWM rejection (INA240A1 class, 20 V/V)
// across a 20 mΩ shunt in series with the motor, REF at mid-supply: 0.4 V/A → ±4.1 A full scale, covering
// the bridge's 4 A current regulation. Positive = current that drives the motor in the positive direction.
// (The bridge's own current-mirror output is unidirectional, hence the separate amplifier.)
inline constexpr int32_t kCurrentZeroCounts = kAdcMidCounts;
inline constexpr float kCurrentSenseGain_V_per_A = 20.0f * 0.020f;                             ///< 0.4 V/A
inline constexpr float kCurrentCountsPerAmp = kCurrentSenseGain_V_per_A * kAdcCountsPerVolt;   ///< 496.5
constexpr float currentCountsToAmps_A(int32_t counts) {
  return static_cast<float>(counts - kCurrentZeroCounts) / kCurrentCountsPerAmp;
}

// -------------------------------------------------------------------------------------------------------
// Drive and actuator (per finger)
// -------------------------------------------------------------------------------------------------------
/// Motor supply: the glove's 9 V rechargeable battery (paper Table 1, §2.2).
inline constexpr float kSupply_V = 9.0f;
/// H-bridge PWM frequency: above the audible band. A 130-size motor's electrical time constant L/R is of
/// the order of 0.1 ms — longer than the 50 µs PWM period (small ripple) and much shorter than the 1 ms
/// control period (the current follows the averaged voltage within a tick).
inline constexpr float kPwmFrequency_Hz = 20000.0f;
/// H-bridge (DRV8874 class: 4.5–37 V, 6 A peak, cycle-by-cycle current regulation) set to regulate at
/// 4.0 A: the FA-130 stall current at its 3 V rating is ≈ 4.4 A, so 4 A lets it reach its rated stall
/// torque in bursts while protecting it at the 9 V supply.
inline constexpr float kBridgeCurrentLimit_A = 4.0f;
/// Bridge on-resistance, high side + low side (DRV8874 class, typical).
inline constexpr float kBridgeOnResistance_Ohm = 0.2f;
/// Mabuchi FA-130RA-2270 (paper §2.2), datasheet figures at its 1.5 V nominal point: no load 9100 rpm /
/// 0.20 A, stall 2.6 mN·m / 2.2 A → R = 1.5 V / 2.2 A, K = 2.6 mN·m / (2.2 − 0.2) A ≈ 1.3e-3 and
/// K_e = (1.5 − 0.2·0.68) V / 953 rad/s ≈ 1.43e-3; the mean is used for both K_t and K_e.
inline constexpr float kMotorResistance_Ohm = 0.68f;
inline constexpr float kMotorTorqueConstant_Nm_per_A = 1.37e-3f;
/// The motor is rated 1.5–3 V: a continuous |duty| above kMotorRated_V / kSupply_V overdrives it (the
/// bridge's current regulation still protects it). Transients up to full duty are what makes a 1 s
/// close/open maneuver trackable.
inline constexpr float kMotorRated_V = 3.0f;
/// Gearbox ratio, motor : spool (Tamiya 70103 universal gearbox in its 101:1 configuration, §2.2); the last
/// stage is a non-back-drivable (self-locking) metal worm.
inline constexpr float kGearRatio = 101.0f;
/// Tendon spool ("active pulley") radius: a design choice (the paper does not give it). With the 4 A limit
/// and the plant's pad transmission (0.3 N per N of tendon tension) it gives ≈ 10 N of active fingertip
/// force (§2.2) and a no-load fingertip speed of ≈ 1 m/s, enough to follow 1 s close/open maneuvers
/// (§4.3); a smaller spool would give more force but less speed and more reflected motor inertia.
inline constexpr float kSpoolRadius_m = 0.005f;
/// Maximum active fingertip force (§2.2) and the worm's passive holding force (§2.2: 35 N, male sustained
/// finger hold) — the simulated worm slips beyond the latter.
inline constexpr float kMaxActiveForce_N = 10.0f;
inline constexpr float kPassiveHoldForce_N = 35.0f;

}  // namespace phalanx::glove::board
