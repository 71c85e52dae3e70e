// The DDS bridge's view of the device-model stage's results (no kinematics of its own; docs/dds.md).
#include "phalanx/host/dds/model_view.h"

#include <cmath>
#include <limits>

#include "phalanx/host/client/device_model.h"

namespace phalanx::host::dds {
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
constexpr size_t kGloveForce0 = 15;  // kGlove5Layout: 15..19 pad forces
constexpr size_t kPenTorque0 = 6;    // kPantographLayout: 6..11 measured motor torques
constexpr size_t kSeaTorque0 = 7;    // kSeaFingerLayout: 7..8 SEA torque estimates

void invalidBody(ModelState& out, size_t b) {
  out.body_valid[b] = false;
  out.pose[b].position = {kNaN, kNaN, kNaN};
  out.pose[b].orientation = {kNaN, kNaN, kNaN, kNaN};
}

/// Per finger: flexion −θ, the mechanism angles α (telemetry), the fingertip pose u = (x, y, φ) in {O} as a
/// rotation about z by φ, and the pad force along +y of the fingertip frame (positive resists flexion).
void gloveView(const client::DeviceModelStage& st, const TelemetryFrame& tel, ModelState& out) {
  out.joint_count = 30;
  out.body_count = 5;
  for (size_t f = 0; f < 5; ++f) {
    const bool ok = st.gloveValid(f);
    const auto& d = st.gloveKinematics(f);
    for (size_t j = 0; j < 3; ++j) {
      out.position[3 * f + j] = ok ? -d.theta_rad[j] : kNaN;
      out.position[15 + 3 * f + j] = tel.value[3 * f + j];
    }
    out.wrench[f].force = {0.0, static_cast<double>(tel.value[kGloveForce0 + f]), 0.0};
    if (!ok) {
      invalidBody(out, f);
      continue;
    }
    out.body_valid[f] = true;
    out.pose[f].position = {d.O_u_tip[0], d.O_u_tip[1], 0.0};
    out.pose[f].orientation = {0.0, 0.0, std::sin(0.5 * d.O_u_tip[2]), std::cos(0.5 * d.O_u_tip[2])};
  }
}

/// Joint angles q = home + telemetry (the kinematics' q), measured torques as effort, the pen centre with the
/// orientation Rz(θz)·Rx(θx) (takes y_B onto the pen axis; roll passive), the measured wrench at the centre.
void penView(const client::DeviceModelStage& st, const TelemetryFrame& tel, ModelState& out) {
  out.joint_count = 6;
  out.has_effort = true;
  out.body_count = 1;
  const auto& k = st.penKinematics();
  for (size_t i = 0; i < 6; ++i) {
    out.position[i] = st.penModelOk() ? k.q_rad[i] : kNaN;
    out.effort[i] = tel.value[kPenTorque0 + i];
  }
  host::pen::PenWrench w{};
  if (!st.penWrench(w)) {
    invalidBody(out, 0);
    out.wrench[0].force = {kNaN, kNaN, kNaN};
    out.wrench[0].torque = {kNaN, kNaN, kNaN};
    return;
  }
  out.body_valid[0] = true;
  out.pose[0].position = k.B_p_centre;
  const double hx = 0.5 * k.pose.theta_x_rad, hz = 0.5 * k.pose.theta_z_rad;
  out.pose[0].orientation = {std::cos(hz) * std::sin(hx), std::sin(hz) * std::sin(hx), std::sin(hz) * std::cos(hx),
                             std::cos(hz) * std::cos(hx)};
  out.wrench[0].force = w.force_N;
  out.wrench[0].torque = w.torque_Nm;
}

}  // namespace

ModelNames modelNames(protocol::DeviceType type) {
  switch (type) {
    case protocol::DeviceType::kGlove5: return {kGloveJoints, 30, kFingers, kFingerBase, kFingerTip, 5};
    case protocol::DeviceType::kPantograph: return {kPenJoints, 6, kPen, kPenBase, kPenBase, 1};
    case protocol::DeviceType::kSeaFinger: return {kSeaJoints, 2, nullptr, nullptr, nullptr, 0};
    default: return {};
  }
}

void modelView(const protocol::DeviceLayout& layout, const client::DeviceModelStage& stage, const TelemetryFrame& tel,
               ModelState& out) {
  out = ModelState{};
  switch (layout.type) {
    case protocol::DeviceType::kGlove5: gloveView(stage, tel, out); break;
    case protocol::DeviceType::kPantograph: penView(stage, tel, out); break;
    case protocol::DeviceType::kSeaFinger:  // the exoskeleton's joint sensors and SEA torques, as measured
      out.joint_count = 2;
      out.has_effort = true;
      for (size_t i = 0; i < 2; ++i) {
        out.position[i] = tel.value[i];
        out.effort[i] = tel.value[kSeaTorque0 + i];
      }
      break;
    default: break;
  }
}

}  // namespace phalanx::host::dds
