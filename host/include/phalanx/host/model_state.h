#pragma once
/// Model-level state of a device from one telemetry frame, through the host's device models (glove six-bar
/// kinematics, pen forward kinematics and Jacobians): joint angles, fingertip / pen poses and the forces the
/// device applies. Used by the DDS bridge (docs/dds.md); kept in its own file so other outputs can share it.
/// compute() allocates nothing and runs in bounded time (fine on any thread).
#include <array>
#include <cstdint>

#include "phalanx/glove/kinematics.h"
#include "phalanx/host/session.h"
#include "phalanx/pen/kinematics.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host {

/// A pose (position m, unit quaternion x, y, z, w) in the frame named by ModelState's frame names.
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

/// Names and frames per device type (static strings), in the order ModelState fills them.
struct ModelNames {
  const char* const* joints = nullptr;
  uint8_t joint_count = 0;
  const char* const* bodies = nullptr;       ///< "thumb".."little" or "pen"
  const char* const* pose_frames = nullptr;  ///< frame of pose[i] (finger base frame, pen base frame)
  const char* const* wrench_frames = nullptr;
  uint8_t body_count = 0;
};

class ModelStateComputer {
 public:
  /// glove: one model per finger (thumb..little); pen: the pen's model. Only the one for layout.type is used.
  ModelStateComputer(const protocol::DeviceLayout& layout, const std::array<glove::Model<double>, 5>& glove,
                     const pen::Model<double>& pen);
  static ModelNames names(protocol::DeviceType type);
  void compute(const TelemetryFrame& tel, ModelState& out);

 private:
  void computeGlove(const TelemetryFrame& tel, ModelState& out) const;
  void computePen(const TelemetryFrame& tel, ModelState& out);
  void computeSea(const TelemetryFrame& tel, ModelState& out) const;
  const protocol::DeviceLayout& layout_;
  std::array<glove::Model<double>, 5> glove_;
  pen::Model<double> pen_;
  pen::Data<double> pen_data_{};
};

}  // namespace phalanx::host
