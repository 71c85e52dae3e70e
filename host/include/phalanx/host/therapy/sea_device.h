#pragma once
/// sea_finger (the index-finger exoskeleton with Bowden-cable SEAs, seeds/001) as a therapy device:
///  - 2 channels, "mcp" and "pip": the FINGER joint torque τ_f (N·m, + = extension = resists flexion, the
///    therapy convention and the sign of θ4, θ8 in phalanx/sea/kinematics.h);
///  - 3 joints "mcp", "pip", "dip" (flexion = −θ4, −θ8, −θ_dip, estimated from the five joint-angle sensors,
///    eq 3–5); DIP is not actuated and belongs to the pip channel (q_pip = PIP + DIP flexion, like a glove finger);
///  - the measured effort is the finger torque estimate τ̂_f = J_n^{-T} τ̂_j (eq 9) from the SEA torques;
///  - the command is the exoskeleton joint torque τ_j,d = J_nᵀ τ_f,d (eq 6/11): the channels couple, so the
///    adapter overrides commandFromEffort(). The firmware's eq 8 SEA torque PID closes the loop.
#include <array>
#include <memory>

#include "phalanx/host/sea/sea_estimator.h"
#include "phalanx/host/therapy/device.h"

namespace phalanx::host::therapy {

class SeaTherapyDevice : public TherapyDevice {
 public:
  /// |finger joint torque| the adapter ever commands (N·m): 0.3 N·m, the device's design peak (001 §1).
  static constexpr double kFingerTorqueLimit_Nm = 0.3;
  /// |exoskeleton joint torque| setpoint (N·m): host::sea::FingerTorqueLimits' 0.5 N·m (docs/sea-model.md).
  static constexpr double kExoTorqueLimit_Nm = 0.5;

  /// params: the SEA's subject parameters come from `phalanx sea-calibrate` (eq 12), not from profile segment
  /// lengths: any kinematics entry is refused with that reason.
  static std::unique_ptr<SeaTherapyDevice> make(const KinematicParams& params, std::string& error);

  std::string name() const override { return "sea_finger"; }
  std::size_t channelCount() const override { return 2; }
  std::string channelName(std::size_t channel) const override;
  std::string effortUnit() const override { return "N·m"; }
  double effortLimit(std::size_t) const override { return kFingerTorqueLimit_Nm; }
  std::size_t jointCount() const override { return 3; }
  std::string jointName(std::size_t joint) const override;
  std::size_t jointChannel(std::size_t joint) const override { return joint == 0 ? 0 : 1; }
  std::pair<double, double> jointBounds(std::size_t joint) const override;
  std::vector<std::string> sampleNames() const override;
  std::vector<std::string> setpointNames() const override;
  void observe(const TelemetryFrame& tel, Observation& out) override;
  /// Per channel without the Jacobian: the exoskeleton torque for an uncoupled joint (J_n = I). Used only where
  /// no therapy aux columns exist (records of sessions without an exercise); the loop uses commandFromEffort.
  float setpointFromEffort(std::size_t, double effort) const override { return static_cast<float>(effort); }
  double effortFromSetpoint(std::size_t, float setpoint) const override { return static_cast<double>(setpoint); }
  /// τ_j,d = J_nᵀ τ_f,d at the last observed pose (eq 6), scaled down together (direction kept) so that
  /// |τ_j,d| ≤ kExoTorqueLimit_Nm; the efforts are scaled with it. No valid J_n: zero torque.
  void commandFromEffort(std::array<double, kMaxChannels>& effort,
                         std::array<float, kMaxChannels>& setpoint) const override;
  /// τ_f = J_n^{-T} τ_j (eq 9) at the last observed pose; no valid, non-singular J_n: the exoskeleton torques
  /// themselves (J_n = I), the conservative reading for limits.
  void effortFromCommand(const std::array<float, kMaxChannels>& setpoint,
                         std::array<double, kMaxChannels>& effort) const override;

  const host::sea::SeaEstimator& estimator() const { return estimator_; }

 private:
  host::sea::SeaEstimator estimator_;
  uint64_t last_device_time_us_ = 0;
  bool primed_ = false;
};

}  // namespace phalanx::host::therapy
