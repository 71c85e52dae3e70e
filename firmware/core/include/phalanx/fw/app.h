#pragma once
/// The interface between the device-independent firmware core and one device's app (glove5, sea_finger, …).
/// The core owns the protocol, the watchdog and the fault latch; the app owns sensing and control.
#include <cstdint>

#include "phalanx/hal/hal.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::fw {

class DeviceApp {
 public:
  virtual ~DeviceApp() = default;
  virtual const protocol::DeviceLayout& layout() const = 0;
  /// Called once before the first tick; may not allocate after this returns.
  virtual void init(hal::Board& board) = 0;
  /// Read and convert every sensor; returns the fault bits of implausible readings found this tick.
  virtual uint16_t sense(float dt_s) = 0;
  /// Run the control loops for a validated command and write the outputs; returns fault bits found
  /// (limits exceeded). Only called while no fault is latched and the mode is not kSafe.
  virtual uint16_t control(const protocol::Command& cmd, float dt_s) = 0;
  /// Outputs to their safe state and controller state reset. The core has already disabled the PWM.
  virtual void safe() = 0;
  /// Fill the telemetry samples (layout().sample_count of them) from the last sense().
  virtual void fillSamples(int16_t* samples) const = 0;
  /// Device parameters (IDs ≥ 0x100). Default: none.
  virtual protocol::ParamStatus getParam(uint16_t /*id*/, float& /*value*/) const {
    return protocol::ParamStatus::kUnknownParam;
  }
  virtual protocol::ParamStatus setParam(uint16_t /*id*/, float /*value*/) {
    return protocol::ParamStatus::kUnknownParam;
  }
};

}  // namespace phalanx::fw
