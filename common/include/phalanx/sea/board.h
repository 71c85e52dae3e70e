#pragma once
/// sea_finger board (index-finger exoskeleton with Bowden-cable SEAs, seeds/001 Agarwal et al. 2015): channel
/// map, sign conventions and the nominal sensor / drive / SEA constants.
///
/// Shared by the firmware app (decodes counts with these transfers, eq 7 uses the SEA constants) and the
/// simulated plant (hal/sim SeaPlant encodes its physics into counts with the same transfers plus noise).
/// Freestanding C++17: constexpr data only, single precision (used in float arithmetic on the Cortex-M4F).
///
/// The paper gives the spring stiffnesses (§6.2), the motor (RE-max 29, 22 W, planetary gearhead, encoder,
/// §3.4), the joint angle sensor (KMA210, §3.4), the ±60° motor-angle window (§6.2) and the 0.3 N·m peak torque
/// (§1); it does not give pulley radii, gear ratio, encoder resolution or electronics. Each number below says
/// where it comes from: the paper (section), the datasheet class of a part (part named), or a design choice
/// (reason given). docs/sea-plant.md collects them.
///
/// SIGN CONVENTIONS (one direction for everything):
///   duty > 0 → positive motor current → motor and motor pulley turn + (θ_m grows, encoder counts grow)
///   → cable 2 is pulled, cable 1 released → positive SEA torque τ_j on the exoskeleton joint (eq 2), which
///   drives θ_j +. Joint angle sensor counts grow with θ_j. Load cell counts grow with the torque it receives
///   from the joint (rig).
#include <array>
#include <cstdint>

namespace phalanx::sea::board {

// -------------------------------------------------------------------------------------------------------
// Channel map
// -------------------------------------------------------------------------------------------------------
inline constexpr int kSeaCount = 2;          ///< SEA 0: exoskeleton MCP joint (θ_1r), SEA 1: PIP joint (θ_6r)
inline constexpr int kJointSensorCount = 5;  ///< five KMA210 angle sensors, one redundant (§3.4)

/// PWM (H-bridge) channels 0..1: MCP motor, PIP motor.
inline constexpr int kPwmChannelCount = 2;
/// Encoder channels 0..1: MCP motor, PIP motor (counts at the motor shaft).
inline constexpr int kEncoderChannelCount = 2;
/// ADC 0..4: joint angle sensors in the order of phalanx/sea/kinematics.h SensorIndex: 0 θ_1r (exoskeleton MCP
/// SEA joint), 1 θ_6r (exoskeleton PIP SEA joint), 2 θ_7r (the redundant sensor of eq 12), 3 the DIP chain
/// sensor, 4 the passive abduction joint.
inline constexpr int kAdcFirstJoint = 0;
/// ADC 5..6: motor current sense, MCP, PIP.
inline constexpr int kAdcFirstCurrent = 5;
/// ADC 7..8: test-rig load cell torque (§7.1), MCP SEA, PIP SEA. Mid-scale (0 N·m) when no load cell is wired.
inline constexpr int kAdcFirstLoadCell = 7;
inline constexpr int kAdcChannelCount = 9;
/// Which joint sensor measures the SEA joint angle θ_j of SEA `sea` (eq 1, 7).
constexpr int seaJointSensor(int sea) { return sea; }

// -------------------------------------------------------------------------------------------------------
// ADC: 12-bit SAR, 3.3 V ratiometric reference (same class as the glove board).
// -------------------------------------------------------------------------------------------------------
inline constexpr int32_t kAdcMaxCounts = 4095;
inline constexpr int32_t kAdcMidCounts = 2048;
inline constexpr float kAdcCountsPerVolt = 4096.0f / 3.3f;

// -------------------------------------------------------------------------------------------------------
// Joint angle sensors (5): NXP KMA210 magneto-resistive angle sensor (§3.4), analog ratiometric output,
// programmed for a 180° range (its maximum) mapped to 5 %…95 % of the supply (its clamp levels are outside
// that band, so a reading there is an open/shorted sensor). Centre per sensor: the magnet's mounting angle.
// -------------------------------------------------------------------------------------------------------
inline constexpr float kJointCountsPerRad = 0.90f * 4096.0f / 3.14159265f;  ///< 1173.4 counts/rad, 0.049°/count
/// Joint angle (rad) that reads mid-scale, per sensor (magnet mounting): the middle of each sensor's range over
/// the finger workspace MCP −60…0°, PIP −80…0° (DIP = ⅔ PIP) of the default model (kinematics.h): θ_1r −36…−1°,
/// θ_6r 34…159°, θ_7r (redundant, at F) −16…117°, DIP chain −32…−6°, abduction 0 → centres −20°, 95°, 50°,
/// −20°, 0°.
inline constexpr std::array<float, kJointSensorCount> kJointCentre_rad = {-0.34906585f, 1.65806279f, 0.87266463f,
                                                                          -0.34906585f, 0.0f};
/// Plausible output band: 5 %…95 % of 4096 (outside: KMA210 diagnostic clamp levels, open wire, short).
inline constexpr int32_t kJointPlausibleMinCounts = 180;
inline constexpr int32_t kJointPlausibleMaxCounts = 3915;

// -------------------------------------------------------------------------------------------------------
// Motor, gearhead, encoder, drive (per SEA)
// -------------------------------------------------------------------------------------------------------
/// Supply of the H-bridges. 24 V: the usual bus for a 24 V RE-max winding (EPOS2 50/5, §7.5, takes 11–50 V).
inline constexpr float kSupply_V = 24.0f;
/// Maxon RE-max 29, 22 W (§3.4), 24 V winding class: terminal resistance, torque constant (= back-EMF
/// constant in SI), terminal inductance, rotor inertia, no-load current. Catalogue-class values (rounded).
inline constexpr float kMotorResistance_Ohm = 8.0f;
inline constexpr float kMotorTorqueConstant_Nm_per_A = 0.027f;
inline constexpr float kMotorInductance_H = 0.8e-3f;
inline constexpr float kMotorRotorInertia_kg_m2 = 9.0e-7f;
inline constexpr float kMotorNoLoadCurrent_A = 0.03f;
/// Planetary gearhead (maxon GP 32 class, 3 stages): ratio and efficiency. Design choice: 33:1 gives the
/// pulley ≈ 26 rad/s no-load at 24 V (0.3 N·m at 5 Hz needs ≈ 22 rad/s peak) and ≈ 2 N·m stall.
inline constexpr float kGearRatio = 33.0f;
inline constexpr float kGearEfficiency = 0.75f;
/// Encoder: maxon MR type-L class, 512 lines, quadrature → 2048 counts per motor turn.
inline constexpr float kEncoderCountsPerMotorRev = 2048.0f;
inline constexpr float kMotorRadPerCount = 6.2831853f / (kEncoderCountsPerMotorRev * kGearRatio);  ///< at the pulley
/// Bridge on-resistance (DRV8874 class, high + low side) and its cycle-by-cycle current regulation.
inline constexpr float kBridgeOnResistance_Ohm = 0.2f;
inline constexpr float kBridgeCurrentLimit_A = 3.0f;
/// Current sense: INA240A1-class (20 V/V) over 20 mΩ, REF at mid-supply → 0.4 V/A.
inline constexpr float kCurrentCountsPerAmp = 0.4f * kAdcCountsPerVolt;  ///< 496.5

// -------------------------------------------------------------------------------------------------------
// Series elastic actuators (§3.2, §4.1, §6.2)
// -------------------------------------------------------------------------------------------------------
/// Effective spring stiffness k of each compression spring (§6.2: k_MCP = 2816 N/m, k_PIP = 744 N/m).
inline constexpr std::array<float, kSeaCount> kSpringStiffness_N_per_m = {2816.0f, 744.0f};
/// Joint pulley radius r_j and motor pulley radius r_m (not given in the paper). Design choice: the motor angle
/// is θ_m = (r_j/r_m)(θ_j − θ_j0) + τ_j / (2 k r_j r_m) (eq 1–2), and both terms share §6.2's ±60° window. The
/// largest r_m that keeps the MCP SEA's 0.3 N·m (§1) above §6.2's 20° resolution floor is 15 mm (0.3 N·m →
/// 20.4°; PIP SEA 0.1 N·m → 25.7°); it maps the exoskeleton joints' motion to ⅔ at the motor, so the finger's
/// motion (θ_6r spans 125° over the full workspace) leaves room for torque inside the window.
inline constexpr float kJointPulleyRadius_m = 0.010f;
inline constexpr float kMotorPulleyRadius_m = 0.015f;
/// Motor-angle watchdog window (§6.2: "motor angle lies within ±60 degrees at peak torque").
inline constexpr float kMotorAngleLimit_rad = 1.04719755f;

// -------------------------------------------------------------------------------------------------------
// Test-rig load cell (§7.1): six-axis load cell (ATI Nano17 class) whose joint-axis torque is amplified to the
// ADC: ±0.5 N·m over ±1.5 V around mid-scale (0.27 mN·m per count; the 0.3 N·m test peak uses 60 %).
// -------------------------------------------------------------------------------------------------------
inline constexpr float kLoadCellFullScale_Nm = 0.5f;
inline constexpr float kLoadCellCountsPerNm = 1.5f / kLoadCellFullScale_Nm * kAdcCountsPerVolt;  ///< 3723.6

}  // namespace phalanx::sea::board
