#include "phalanx/host/record/pen_channels.h"

#include <cmath>
#include <cstdio>

#include "phalanx/host/pen/force_split.h"

namespace phalanx::host::record {

namespace pp = phalanx::pen;

namespace {
constexpr std::size_t kTorqueSample0 = 6;  // protocol::kPantographLayout: samples 6..11 are the motor torques

/// Rz(θz)·Rx(θx) as a quaternion (x, y, z, w): the pen axis is Rz·Rx·y_B (kinematics.h penAxis).
std::array<double, 4> quaternionZX(double theta_x, double theta_z) {
  const double cx = std::cos(0.5 * theta_x), sx = std::sin(0.5 * theta_x);
  const double cz = std::cos(0.5 * theta_z), sz = std::sin(0.5 * theta_z);
  return {cz * sx, sz * sx, cx * sz, cz * cx};
}
}  // namespace

PenMeasurement measurePen(const pp::Model<double>& model, const float* samples) {
  PenMeasurement m;
  pp::JointVec<double> q{};
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) q[i] = model.q_home_rad[i] + static_cast<double>(samples[i]);
  pp::Data<double> k{};
  if (!pp::isUsable(pp::computeForward(model, q, k))) return m;
  m.pose_valid = true;
  m.centre_m = k.B_p_centre;
  m.theta_x_rad = k.pose.theta_x_rad;
  m.theta_z_rad = k.pose.theta_z_rad;
  m.orientation = quaternionZX(m.theta_x_rad, m.theta_z_rad);
  std::array<pen::Vec3d, pp::kNumPantographs> f{};
  bool ok = true;
  for (std::size_t p = 0; p < pp::kNumPantographs; ++p) {
    const float* tau = samples + kTorqueSample0 + 3 * p;
    ok = pen::tipForceFromTorques(k.pantograph[p].J, {tau[0], tau[1], tau[2]}, f[p]) && ok;
  }
  if (!ok) return m;
  pen::PenWrench w{};
  pen::endForcesToWrench(k, f[pp::kBottom], f[pp::kTop], w);
  m.wrench_valid = true;
  m.force_N = w.force_N;
  m.torque_Nm = w.torque_Nm;
  return m;
}

const std::vector<std::string>& penCsvColumns() {
  static const std::vector<std::string> kColumns{
      "pen_x_m",       "pen_y_m",        "pen_z_m",        "pen_theta_x_rad", "pen_theta_z_rad", "pen_force_x_N",
      "pen_force_y_N", "pen_force_z_N", "pen_torque_x_Nm", "pen_torque_y_Nm", "pen_torque_z_Nm"};
  return kColumns;
}

void appendPenCsv(std::string& out, const PenMeasurement& m) {
  char buf[40];
  auto put = [&](bool valid, double v) {
    out += ',';
    if (!valid) return;
    std::snprintf(buf, sizeof buf, "%.9g", v);
    out += buf;
  };
  for (double v : m.centre_m) put(m.pose_valid, v);
  put(m.pose_valid, m.theta_x_rad);
  put(m.pose_valid, m.theta_z_rad);
  for (double v : m.force_N) put(m.wrench_valid, v);
  for (double v : m.torque_Nm) put(m.wrench_valid, v);
}

}  // namespace phalanx::host::record
