#pragma once
/// What the therapy layer needs to know about a device, so that exercises, patient limits, records and reports
/// are written once for every device. A device joins by implementing TherapyDevice (glove5 today; the SEA
/// finger exoskeleton adds its own adapter and one line in makeTherapyDevice()).
///
/// Conventions (all devices):
///  - joint flexion angles in rad, FLEXION POSITIVE (the clinical convention; device kinematics may differ);
///  - a channel is one actuated effort (glove: one finger's pad force in N; SEA: one joint torque in N·m);
///    its coordinate q is the sum of the flexion of the joints it moves (rad; "total active motion" of that
///    finger on the glove), so one exercise law fits every device;
///  - effort sign: POSITIVE RESISTS FLEXION (pushes towards extension), negative assists flexion.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "phalanx/host/controller.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::therapy {

inline constexpr std::size_t kMaxJoints = 16;
inline constexpr std::size_t kMaxChannels = protocol::kMaxSetpoints;

/// One cycle's view of the hand, from telemetry. Fixed size: filled in the 1 kHz loop without allocation.
struct Observation {
  std::array<double, kMaxJoints> flexion_rad{};
  std::array<bool, kMaxJoints> joint_valid{};
  std::array<double, kMaxChannels> q_rad{};   ///< channel coordinate (sum of its joints' flexion)
  std::array<double, kMaxChannels> q_dot_rad_per_s{};  ///< its rate (filled by TherapyController, low-pass)
  std::array<double, kMaxChannels> effort{};  ///< measured interaction effort, + resists flexion
  std::array<bool, kMaxChannels> channel_valid{};
};

/// Per-patient kinematic parameters a device may use (glove: finger segment lengths, mm, by channel name).
struct KinematicParams {
  std::vector<std::pair<std::string, std::array<double, 3>>> segment_lengths_mm;
};

class TherapyDevice {
 public:
  virtual ~TherapyDevice() = default;
  virtual std::string name() const = 0;
  virtual std::size_t channelCount() const = 0;
  virtual std::string channelName(std::size_t channel) const = 0;
  virtual std::string effortUnit() const = 0;  ///< "N" (fingertip force) or "N·m" (joint torque)
  /// The device's own |effort| limit per channel (the profile may only lower it).
  virtual double effortLimit(std::size_t channel) const = 0;
  virtual std::size_t jointCount() const = 0;
  virtual std::string jointName(std::size_t joint) const = 0;
  virtual std::size_t jointChannel(std::size_t joint) const = 0;
  /// Physiological bounds on a joint's flexion (rad) that any profile range must lie within.
  virtual std::pair<double, double> jointBounds(std::size_t joint) const = 0;
  /// Names of the telemetry samples and setpoints, for records and CSV.
  virtual std::vector<std::string> sampleNames() const = 0;
  virtual std::vector<std::string> setpointNames() const;
  /// Real time: telemetry → observation. Must not allocate.
  virtual void observe(const TelemetryFrame& tel, Observation& out) = 0;
  /// Effort (+ resists flexion) → the device's setpoint value for that channel, and back.
  virtual float setpointFromEffort(std::size_t channel, double effort) const = 0;
  virtual double effortFromSetpoint(std::size_t channel, float setpoint) const = 0;
  /// Real time, after observe(): the channels' efforts → the device's setpoints (the first channelCount()).
  /// Devices whose channels couple (the SEA exoskeleton: exoskeleton torque = J_nᵀ · finger torque, 001 eq 6)
  /// override it; the default maps each channel with setpointFromEffort. An override may only scale the efforts
  /// DOWN (e.g. an actuator saturating) and writes back what it commanded, so limits applied before it hold.
  virtual void commandFromEffort(std::array<double, kMaxChannels>& effort,
                                 std::array<float, kMaxChannels>& setpoint) const {
    for (std::size_t c = 0; c < channelCount(); ++c) setpoint[c] = setpointFromEffort(c, effort[c]);
  }
  /// Real time, after observe(): the inverse of commandFromEffort — the channels' efforts a command's setpoints
  /// exert (the patient's limits stage). The default maps each channel with effortFromSetpoint.
  virtual void effortFromCommand(const std::array<float, kMaxChannels>& setpoint,
                                 std::array<double, kMaxChannels>& effort) const {
    for (std::size_t c = 0; c < channelCount(); ++c) effort[c] = effortFromSetpoint(c, setpoint[c]);
  }
  /// Start-up parameters (e.g. the glove's strain-gauge tare) and settle time, as Controller.
  virtual std::vector<std::pair<uint16_t, float>> startupParams() const { return {}; }
  virtual double startupSettleS() const { return 0.0; }
  /// Parameters read back after start-up and the warning each value gives, as Controller.
  virtual std::vector<uint16_t> startupReadback() const { return {}; }
  virtual std::string startupWarning(uint16_t /*id*/, float /*value*/) const { return {}; }
  /// The virtual-object grasp exercise (glove: GloveController's scene rendering), nullptr when the device
  /// has none. scene: rigid-ball | soft-ball | wall.
  virtual std::unique_ptr<Controller> makeGraspController(const std::string& scene, std::string& error) const {
    error = name() + " has no virtual-object grasp exercise";
    (void)scene;
    return nullptr;
  }
  /// Index of a channel / joint by name, −1 if unknown.
  int channelIndex(const std::string& name) const;
  int jointIndex(const std::string& name) const;
};

/// The adapter for a device layout, with the patient's kinematic parameters. nullptr + error when the device
/// has no therapy adapter yet or the parameters do not fit it.
std::unique_ptr<TherapyDevice> makeTherapyDevice(const protocol::DeviceLayout& layout, const KinematicParams& params,
                                                 std::string& error);
/// Same by device name ("glove5"), for validating profiles without a connected device.
std::unique_ptr<TherapyDevice> makeTherapyDevice(const std::string& device_name, const KinematicParams& params,
                                                 std::string& error);

}  // namespace phalanx::host::therapy
