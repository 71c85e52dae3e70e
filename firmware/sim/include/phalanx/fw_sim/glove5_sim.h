#pragma once
/// The simulated glove5: the firmware's Glove5App together with the glove + hand plant.
#include "phalanx/apps/glove5.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/glove/board.h"
#include "phalanx/sim/glove_plant.h"

namespace phalanx::fw_sim {

class Glove5SimDevice : public SimDevice {
 public:
  /// Throws std::invalid_argument for a bad plant configuration (GlovePlant's contract).
  Glove5SimDevice(const sim::GlovePlantConfig& plant_config,
                  const apps::Glove5Calibration& calibration = apps::glove5DefaultCalibration(),
                  const apps::Glove5Config& config = apps::glove5DefaultConfig())
      : app_(calibration, config), plant_(plant_config) {}
  fw::DeviceApp& app() override { return app_; }
  std::vector<std::string> truthColumns() const override;
  void truthValues(double* out) const override;
  std::string instrumentSignal() const override;
  /// The index finger's MCP Hall sensor; open: 0 counts, below kHallPlausibleMinCounts.
  InjectableSensor injectableSensor() const override { return {false, static_cast<uint8_t>(glove::board::hallAdcChannel(1, 0)), 0, 0}; }
  sim::Plant& plant() override { return plant_; }
  uint8_t pwmCount() const override { return glove::board::kPwmChannelCount; }
  uint8_t adcCount() const override { return glove::board::kAdcChannelCount; }
  uint8_t encoderCount() const override { return 0; }
  sim::GlovePlant& glovePlant() { return plant_; }
  apps::Glove5App& gloveApp() { return app_; }

 private:
  apps::Glove5App app_;
  sim::GlovePlant plant_;
};

/// "still" | "close-open" | "grasp" | "random" → scenario; false for anything else.
bool parseHandScenario(const std::string& name, sim::HandScenario& out);

}  // namespace phalanx::fw_sim
