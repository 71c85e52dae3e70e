#pragma once
/// The pen's pose and measured wrench from one telemetry frame, for the recordings' pen channels (MCAP
/// /phalanx/pen/pose and /phalanx/pen/wrench, the --record CSV's pen_* columns; docs/records.md). The same
/// computation as the client channel's model stage (host/src/client/device_model.cpp): forward kinematics of both
/// pantographs from the six joint angles, then f = J⁻ᵀ τ per pantograph from the measured motor torques and the
/// statics of the two end forces at the pen centre. Runs on the recorder's writer thread, never in the loop.
#include <array>
#include <string>
#include <vector>

#include "phalanx/pen/kinematics.h"

namespace phalanx::host::record {

struct PenMeasurement {
  bool pose_valid = false;    ///< the kinematics were usable (else every field is 0 / identity)
  bool wrench_valid = false;  ///< both pantograph Jacobians were invertible
  std::array<double, 3> centre_m{};     ///< pen centre in the base frame {B}
  double theta_x_rad = 0.0, theta_z_rad = 0.0;  ///< the two actuated rotations (Table X)
  std::array<double, 4> orientation{0.0, 0.0, 0.0, 1.0};  ///< quaternion x, y, z, w of Rz(θz)·Rx(θx): its y axis is the pen axis
  std::array<double, 3> force_N{}, torque_Nm{};  ///< measured wrench on the pen at its centre, {B}
};

/// samples: the pantograph's 12 telemetry samples (six joint angles from home, six measured motor torques).
PenMeasurement measurePen(const phalanx::pen::Model<double>& model, const float* samples);

/// The --record CSV's pen column names (with units), in the order penCsvValues writes them.
const std::vector<std::string>& penCsvColumns();
/// Appends ",v" per pen column (%.9g; empty fields when the pose / wrench is not valid).
void appendPenCsv(std::string& out, const PenMeasurement& m);

}  // namespace phalanx::host::record
