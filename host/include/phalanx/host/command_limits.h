#pragma once
/// The one limits stage every command passes before it leaves the host, whatever its source (a built-in
/// controller, a therapy exercise, a Modbus write, the dashboard, an external client): first the device's limits,
/// then the active patient's. Nothing non-finite leaves the host; a setpoint beyond a limit is saturated to it
/// (what is sent is the saturated command) and every engagement is counted. The device's firmware checks the
/// device limits again on its side (docs/protocol.md).
#include <cstdint>

#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host {

/// The active patient's limits in the device's setpoint space (the therapy layer implements it from the
/// patient's profile). Real time: must not allocate or block.
class PatientLimitStage {
 public:
  virtual ~PatientLimitStage() = default;
  /// Saturate cmd's setpoints to the patient's limits given the newest telemetry; a bit per channel limited.
  virtual uint32_t limit(const TelemetryFrame& tel, protocol::Command& cmd) = 0;
};

struct LimitCounters {
  uint64_t refused = 0;          ///< commands replaced by the safe command (non-finite value, undefined mode)
  uint64_t device_limited = 0;   ///< commands with a setpoint or gain saturated to the device's limit
  uint64_t patient_limited = 0;  ///< commands with a setpoint saturated to the patient's limit
};

class CommandLimits {
 public:
  explicit CommandLimits(const protocol::DeviceLayout& layout) : layout_(layout) {}
  void setPatientStage(PatientLimitStage* stage) { patient_ = stage; }
  enum class Verdict : uint8_t { kPassed, kLimited, kRefused };
  /// Real time: the device's limits, then the patient's, applied to cmd in place.
  Verdict apply(const TelemetryFrame& tel, protocol::Command& cmd);
  const LimitCounters& counters() const { return counters_; }

 private:
  bool deviceLimits(protocol::Command& cmd);
  const protocol::DeviceLayout& layout_;
  PatientLimitStage* patient_ = nullptr;
  LimitCounters counters_;
};

/// The safe command: mode safe, every setpoint 0, nominal gains.
void makeSafe(protocol::Command& cmd);

}  // namespace phalanx::host
