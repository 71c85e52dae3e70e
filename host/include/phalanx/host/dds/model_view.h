#pragma once
/// The DDS bridge's view of a device's model-level state (docs/dds.md): the client channel's device-model stage
/// (client/device_model.h, the one place telemetry becomes joints, fingertips, pen pose and wrench) put into the
/// shapes of the ROS 2 messages - names, flexion sign, quaternions, NaN where the model has no solution. No
/// kinematics here. modelView() allocates nothing; the bridge runs it on its own thread.
#include <array>
#include <cstdint>

#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::client {
class DeviceModelStage;
}

namespace phalanx::host::dds {

/// A pose (position m, unit quaternion x, y, z, w) in the frame named by ModelNames.
struct ModelPose {
  std::array<double, 3> position{};
  std::array<double, 4> orientation{0.0, 0.0, 0.0, 1.0};
};

/// A wrench (force N, torque N·m).
struct ModelWrench {
  std::array<double, 3> force{};
  std::array<double, 3> torque{};
};

struct ModelState {
  static constexpr std::size_t kMaxJoints = 30;
  static constexpr std::size_t kMaxBodies = 5;  ///< fingertips (glove) or the pen
  uint8_t joint_count = 0;
  bool has_effort = false;                      ///< effort[] is filled (pantograph, sea_finger)
  std::array<double, kMaxJoints> position{};    ///< rad; NaN where the model has no solution this frame
  std::array<double, kMaxJoints> effort{};      ///< N·m (measured)
  uint8_t body_count = 0;                       ///< glove: 5 fingertips; pantograph: 1 pen; sea_finger: 0
  std::array<ModelPose, kMaxBodies> pose{};
  std::array<ModelWrench, kMaxBodies> wrench{};
  std::array<bool, kMaxBodies> body_valid{};    ///< false: the model has no usable solution this frame
};

/// Names and frames per device type (static strings), in the order ModelState is filled.
struct ModelNames {
  const char* const* joints = nullptr;
  uint8_t joint_count = 0;
  const char* const* bodies = nullptr;       ///< "thumb".."little" or "pen"
  const char* const* pose_frames = nullptr;  ///< frame of pose[i] (finger base frame, pen base frame)
  const char* const* wrench_frames = nullptr;
  uint8_t body_count = 0;
};

ModelNames modelNames(protocol::DeviceType type);
/// The stage's results after stage.observe(tel), as the bridge publishes them.
void modelView(const protocol::DeviceLayout& layout, const client::DeviceModelStage& stage, const TelemetryFrame& tel,
               ModelState& out);

}  // namespace phalanx::host::dds
