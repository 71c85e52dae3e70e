#include "phalanx/host/model_state.h"

#include <cmath>
#include <limits>

namespace phalanx::host {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// glove5: the finger joints first (flexion = −θ, so a flexed finger reads positive), then the glove mechanism's
// joints at B0, B1, B2 (α, as the Hall sensors measure them).
constexpr const char* kGloveJoints[] = {
    "thumb_mcp",   "thumb_pip",   "thumb_dip",   "index_mcp",   "index_pip",   "index_dip",
    "middle_mcp",  "middle_pip",  "middle_dip",  "ring_mcp",    "ring_pip",    "ring_dip",
    "little_mcp",  "little_pip",  "little_dip",  "thumb_mech1", "thumb_mech2", "thumb_mech3",
    "index_mech1", "index_mech2", "index_mech3", "middle_mech1", "middle_mech2", "middle_mech3",
    "ring_mech1",  "ring_mech2",  "ring_mech3",  "little_mech1", "little_mech2", "little_mech3"};
constexpr const char* kFingers[] = {"thumb", "index", "middle", "ring", "little"};
constexpr const char* kFingerBase[] = {"thumb_base", "index_base", "middle_base", "ring_base", "little_base"};
constexpr const char* kFingerTip[] = {"thumb_tip", "index_tip", "middle_tip", "ring_tip", "little_tip"};
// pantograph: q1..q3 bottom pantograph (waist, arm a, arm b), q4..q6 top; absolute angles (home + telemetry).
constexpr const char* kPenJoints[] = {"bottom_waist", "bottom_arm_a", "bottom_arm_b",
                                      "top_waist",    "top_arm_a",    "top_arm_b"};
constexpr const char* kPen[] = {"pen"};
constexpr const char* kPenBase[] = {"pen_base"};
constexpr const char* kSeaJoints[] = {"exo_mcp", "exo_pip"};

/// Rotation about z by phi as a quaternion (x, y, z, w).
std::array<double, 4> aboutZ(double phi) { return {0.0, 0.0, std::sin(0.5 * phi), std::cos(0.5 * phi)}; }

/// Solve Jᵀ f = τ for f (3×3, Cramer's rule); false when J is singular.
bool solveTransposed(const pen::Mat3<double>& J, const pen::Vec3<double>& tau, pen::Vec3<double>& f) {
  pen::Mat3<double> A{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) A[r][c] = J[c][r];
  }
  const double det = pen::det3(A);
  if (!(std::fabs(det) > 1e-12)) return false;
  for (std::size_t k = 0; k < 3; ++k) {
    pen::Mat3<double> Ak = A;
    for (std::size_t r = 0; r < 3; ++r) Ak[r][k] = tau[r];
    f[k] = pen::det3(Ak) / det;
  }
  return true;
}

}  // namespace

ModelStateComputer::ModelStateComputer(const protocol::DeviceLayout& layout,
                                       const std::array<glove::Model<double>, 5>& glove, const pen::Model<double>& pen)
    : layout_(layout), glove_(glove), pen_(pen) {}

ModelNames ModelStateComputer::names(protocol::DeviceType type) {
  switch (type) {
    case protocol::DeviceType::kGlove5: return {kGloveJoints, 30, kFingers, kFingerBase, kFingerTip, 5};
    case protocol::DeviceType::kPantograph: return {kPenJoints, 6, kPen, kPenBase, kPenBase, 1};
    case protocol::DeviceType::kSeaFinger: return {kSeaJoints, 2, nullptr, nullptr, nullptr, 0};
    default: return {};
  }
}

void ModelStateComputer::compute(const TelemetryFrame& tel, ModelState& out) {
  out = ModelState{};
  switch (layout_.type) {
    case protocol::DeviceType::kGlove5: computeGlove(tel, out); break;
    case protocol::DeviceType::kPantograph: computePen(tel, out); break;
    case protocol::DeviceType::kSeaFinger: computeSea(tel, out); break;
    default: break;
  }
}

/// Per finger: θ from α (inverse kinematics, eq 3–5), the fingertip pose u = (x, y, φ) in the finger base frame
/// {O} (forward, from α), and the pad force in the fingertip frame (x along the distal phalanx, y dorsal): the
/// pad force pushes the fingertip dorsally when positive (it resists flexion), so it is +y.
void ModelStateComputer::computeGlove(const TelemetryFrame& tel, ModelState& out) const {
  out.joint_count = 30;
  out.body_count = 5;
  for (std::size_t f = 0; f < glove::kNumFingers; ++f) {
    const glove::Vec3<double> alpha{tel.value[3 * f], tel.value[3 * f + 1], tel.value[3 * f + 2]};
    glove::Vec3<double> theta{};
    const bool ik_ok = glove::isUsable(glove::thetaFromAlpha(glove_[f], alpha, theta));
    for (std::size_t j = 0; j < 3; ++j) {
      out.position[3 * f + j] = ik_ok ? -theta[j] : kNaN;
      out.position[15 + 3 * f + j] = alpha[j];
    }
    const bool finite = glove::allFinite(alpha);
    const glove::Vec3<double> u = glove::tipPoseFromAlpha(glove_[f].mech, alpha);
    out.body_valid[f] = finite;
    out.pose[f].position = {finite ? u[0] : kNaN, finite ? u[1] : kNaN, 0.0};
    out.pose[f].orientation = finite ? aboutZ(u[2]) : std::array<double, 4>{kNaN, kNaN, kNaN, kNaN};
    out.wrench[f].force = {0.0, static_cast<double>(tel.value[15 + f]), 0.0};
  }
}

/// Joint angles q = home + telemetry (as the pen controller reads them), the pen pose from the forward
/// kinematics (centre; orientation Rz(θz)·Rx(θx), the rotation taking y_B onto the pen axis, roll passive), and
/// the wrench the motors apply to the pen from the measured torques: f = J⁻ᵀ τ per pantograph (τ = Jᵀ f), summed
/// at the centre: F = f_b + f_t, M = (L/2)·a × (f_t − f_b).
void ModelStateComputer::computePen(const TelemetryFrame& tel, ModelState& out) {
  out.joint_count = 6;
  out.has_effort = true;
  out.body_count = 1;
  pen::JointVec<double> q{};
  for (std::size_t i = 0; i < pen::kNumJoints; ++i) {
    q[i] = pen_.q_home_rad[i] + static_cast<double>(tel.value[i]);
    out.position[i] = q[i];
    out.effort[i] = tel.value[6 + i];
  }
  const pen::Status s = pen::computeForward(pen_, q, pen_data_);
  pen::Vec3<double> fb{}, ft{};
  const bool usable = pen::isUsable(s) &&
                      solveTransposed(pen_data_.pantograph[pen::kBottom].J, {out.effort[0], out.effort[1], out.effort[2]}, fb) &&
                      solveTransposed(pen_data_.pantograph[pen::kTop].J, {out.effort[3], out.effort[4], out.effort[5]}, ft);
  out.body_valid[0] = usable;
  if (!usable) {
    out.pose[0].position = {kNaN, kNaN, kNaN};
    out.pose[0].orientation = {kNaN, kNaN, kNaN, kNaN};
    out.wrench[0].force = {kNaN, kNaN, kNaN};
    out.wrench[0].torque = {kNaN, kNaN, kNaN};
    return;
  }
  out.pose[0].position = pen_data_.B_p_centre;
  const double hx = 0.5 * pen_data_.pose.theta_x_rad, hz = 0.5 * pen_data_.pose.theta_z_rad;
  out.pose[0].orientation = {std::cos(hz) * std::sin(hx), std::sin(hz) * std::sin(hx), std::sin(hz) * std::cos(hx),
                             std::cos(hz) * std::cos(hx)};
  const pen::Vec3<double> d{ft[0] - fb[0], ft[1] - fb[1], ft[2] - fb[2]};
  const pen::Vec3<double> m = pen::cross(pen_data_.B_axis, d);
  for (std::size_t i = 0; i < 3; ++i) {
    out.wrench[0].force[i] = fb[i] + ft[i];
    out.wrench[0].torque[i] = 0.5 * pen_data_.length_m * m[i];
  }
}

/// The exoskeleton's joint angle sensors (MCP, PIP) and the SEA joint torque estimates.
void ModelStateComputer::computeSea(const TelemetryFrame& tel, ModelState& out) const {
  out.joint_count = 2;
  out.has_effort = true;
  for (std::size_t i = 0; i < 2; ++i) {
    out.position[i] = tel.value[i];
    out.effort[i] = tel.value[7 + i];
  }
}

}  // namespace phalanx::host
