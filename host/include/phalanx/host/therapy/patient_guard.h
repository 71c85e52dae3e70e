#pragma once
/// The active patient's limits as the session's limits stage applies them (host/include/phalanx/host/
/// command_limits.h): every command that reaches the device — a therapy exercise's, the device's default
/// controller's, a Modbus write, the dashboard's — is turned back into channel efforts, held to the profile's
/// |effort| and range-of-motion limits (PatientLimits::apply), and turned into setpoints again. It observes the hand
/// itself, so it holds whether or not an exercise runs.
#include <array>
#include <atomic>
#include <memory>
#include <mutex>

#include "phalanx/host/command_limits.h"
#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/profile.h"

namespace phalanx::host::therapy {

class PatientGuard : public PatientLimitStage {
 public:
  PatientGuard(std::unique_ptr<TherapyDevice> device, const PatientLimits& limits);
  /// Real time: saturate cmd to the patient's limits; a bit per channel changed.
  uint32_t limit(const TelemetryFrame& tel, protocol::Command& cmd) override;
  /// From the API thread: limits tightened at run time take effect at the next cycle that can take them.
  void offerLimits(const PatientLimits& limits);
  /// The efforts of the command last sent (after the limits), per channel.
  std::array<double, kMaxChannels> sentEffort() const;

 private:
  std::unique_ptr<TherapyDevice> device_;
  PatientLimits limits_;
  Observation obs_;
  std::mutex pending_mutex_;
  PatientLimits pending_;
  std::atomic<bool> limits_pending_{false};
  mutable std::mutex sent_mutex_;
  std::array<double, kMaxChannels> sent_{};
};

}  // namespace phalanx::host::therapy
