#pragma once
/// A simulated device: one firmware app together with the physical plant it drives, and the board size.
/// Used by firmware-sim (real time, over a pty) and by the lockstep rig (in-process, virtual time).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "phalanx/fw/app.h"
#include "phalanx/fw_sim/fault_injection.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/sim/plant.h"

namespace phalanx::fw_sim {

struct SimDeviceOptions {
  uint32_t seed = 1;
  std::string scenario = "grasp";  ///< simulated user's motion: still|close-open|grasp|random
  bool noise = true;
};

class SimDevice {
 public:
  virtual ~SimDevice() = default;
  virtual fw::DeviceApp& app() = 0;
  virtual sim::Plant& plant() = 0;
  virtual uint8_t pwmCount() const = 0;
  virtual uint8_t adcCount() const = 0;
  virtual uint8_t encoderCount() const = 0;
  /// protocol::variant::* the firmware reports (core parameter kDeviceVariant): what the app is mounted on.
  virtual uint8_t variant() const { return protocol::variant::kStandard; }
  /// The plant's ground truth (firmware-sim --truth, docs/sdk.md "Plant truth"): the column names with their
  /// units, then after each plant step the values in the same order (truthValues writes truthColumns().size()).
  virtual std::vector<std::string> truthColumns() const = 0;
  virtual void truthValues(double* out) const = 0;
  /// The truth column a reference instrument on this device measures (firmware-sim --instrument's default signal;
  /// docs/modbus.md "firmware-sim's instrument"): one of truthColumns().
  virtual std::string instrumentSignal() const = 0;
  /// The sensor input firmware-sim --inject fails (fault_injection.h): the device's first joint sensor.
  virtual InjectableSensor injectableSensor() const = 0;
};

/// name: glove5 | sea_finger | sea_rig | pantograph. Returns nullptr and sets error for an unknown or unbuilt device.
std::unique_ptr<SimDevice> makeSimDevice(const std::string& name, const SimDeviceOptions& options, std::string& error);

}  // namespace phalanx::fw_sim
