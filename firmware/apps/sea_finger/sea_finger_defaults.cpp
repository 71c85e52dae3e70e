// Default calibration and configuration of the sea_finger app: the board's nominal transfers and SEA constants
// (phalanx/sea/board.h) and the gains chosen in the lockstep benches (docs/sea-firmware.md gives each reason).
#include "phalanx/apps/sea_finger.h"
#include "phalanx/sea/board.h"

namespace phalanx::apps {

namespace board = sea::board;

SeaFingerCalibration seaFingerDefaultCalibration() {
  SeaFingerCalibration c;
  c.joint_counts_per_rad = board::kJointCountsPerRad;
  c.joint_zero_counts = static_cast<float>(board::kAdcMidCounts);
  for (int s = 0; s < kSeaJointSensors; ++s) c.joint_centre_rad[s] = board::kJointCentre_rad[static_cast<size_t>(s)];
  c.joint_valid_min = board::kJointPlausibleMinCounts;
  c.joint_valid_max = board::kJointPlausibleMaxCounts;
  for (int i = 0; i < kSeaCount; ++i) c.joint_sensor_of_sea[i] = board::seaJointSensor(i);
  c.motor_rad_per_count = board::kMotorRadPerCount;
  c.current_counts_per_A = board::kCurrentCountsPerAmp;
  c.current_zero_counts = static_cast<float>(board::kAdcMidCounts);
  c.load_cell_counts_per_Nm = board::kLoadCellCountsPerNm;
  c.load_cell_zero_counts = static_cast<float>(board::kAdcMidCounts);
  for (int i = 0; i < kSeaCount; ++i) c.spring_N_per_m[i] = board::kSpringStiffness_N_per_m[static_cast<size_t>(i)];
  c.joint_pulley_radius_m = board::kJointPulleyRadius_m;
  c.motor_pulley_radius_m = board::kMotorPulleyRadius_m;
  c.supply_V = board::kSupply_V;
  c.resistance_Ohm = board::kMotorResistance_Ohm + board::kBridgeOnResistance_Ohm;
  c.torque_constant_Nm_per_A = board::kMotorTorqueConstant_Nm_per_A;
  c.gear_ratio = board::kGearRatio;
  // Rotor inertia reflected through the gearhead (J N²) plus the output stage and pulley (2e-6 kg·m²).
  c.inertia_kg_m2 = board::kMotorRotorInertia_kg_m2 * board::kGearRatio * board::kGearRatio + 2.0e-6f;
  c.coulomb_Nm = board::kGearRatio * board::kMotorTorqueConstant_Nm_per_A * board::kMotorNoLoadCurrent_A;
  // Bowden cable: the nominal play and sheath friction of docs/sea-plant.md (identified on the rig: the play is
  // the motor travel between the two torque branches of a slow triangle, the friction the motor current step
  // at a reversal).
  for (int i = 0; i < kSeaCount; ++i) {
    c.backlash_base_m[i] = 0.4e-3f;
    c.backlash_per_Nm_m[i] = 2.0e-3f;
  }
  c.sheath_friction = 0.2f;
  c.pretension_N = 20.0f;
  return c;
}

SeaFingerConfig seaFingerDefaultConfig() {
  SeaFingerConfig c;
  // Gains: docs/sea-firmware.md (chosen on `phalanx bench sea-rig-sine|sea-rig-chirp`).
  for (int i = 0; i < kSeaCount; ++i) {
    c.ours[i].kp_rad_per_Nm = 0.5f;
    c.ours[i].ki_rad_per_Nm_s = 20.0f;
    c.ours[i].kd_rad_s_per_Nm = 0.0f;
    c.ours[i].i_limit_rad = 0.3f;
    c.paper[i].kp_rad_per_Nm = 1.0f;
    c.paper[i].ki_rad_per_Nm_s = 10.0f;
    c.paper[i].kd_rad_s_per_Nm = 0.0f;
    c.paper[i].i_limit_rad = 0.3f;
  }
  return c;
}

}  // namespace phalanx::apps
