#pragma once
/// The simulated sea_finger: the firmware's SeaFingerApp together with the SEA plant (hal/sim SeaPlant).
/// Variants: "sea_finger" (the exoskeleton on a simulated index finger, eq 13–14) and "sea_rig" (§7.1 test rig,
/// joints clamped to load cells).
#include "phalanx/apps/sea_finger.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/sea/board.h"
#include "phalanx/sim/sea_plant.h"

namespace phalanx::fw_sim {

class SeaFingerSimDevice : public SimDevice {
 public:
  /// Throws std::invalid_argument for a bad plant configuration (SeaPlant's contract).
  explicit SeaFingerSimDevice(const sim::SeaPlantConfig& plant_config,
                              const apps::SeaFingerCalibration& calibration = apps::seaFingerDefaultCalibration(),
                              const apps::SeaFingerConfig& config = apps::seaFingerDefaultConfig())
      : app_(calibration, config), plant_(plant_config) {}
  fw::DeviceApp& app() override { return app_; }
  std::vector<std::string> truthColumns() const override;
  void truthValues(double* out) const override;
  std::string instrumentSignal() const override;
  /// The exoskeleton MCP joint sensor (θ_1r); open: 0 counts, below kJointPlausibleMinCounts.
  InjectableSensor injectableSensor() const override { return {false, sea::board::kAdcFirstJoint, 0, 0}; }
  sim::Plant& plant() override { return plant_; }
  uint8_t pwmCount() const override { return sea::board::kPwmChannelCount; }
  uint8_t adcCount() const override { return sea::board::kAdcChannelCount; }
  uint8_t encoderCount() const override { return sea::board::kEncoderChannelCount; }
  /// The rig answers as a sea_finger (same firmware, same layout); its variant tells the host it is the rig.
  uint8_t variant() const override {
    return plant_.config().variant == sim::SeaVariant::kRig ? protocol::variant::kSeaTestRig : protocol::variant::kStandard;
  }
  sim::SeaPlant& seaPlant() { return plant_; }
  apps::SeaFingerApp& seaApp() { return app_; }

 private:
  apps::SeaFingerApp app_;
  sim::SeaPlant plant_;
};

/// "still" | "grasp" → relaxed finger, "random" → random motion, "close-open" → sinusoidal flexion; false otherwise.
bool parseSeaUserMotion(const std::string& name, sim::SeaUserMotion& out);

}  // namespace phalanx::fw_sim
