#pragma once
/// The simulated Twin-Pantograph pen: the firmware's PantographApp together with the pen + hand plant.
#include "phalanx/apps/pantograph.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/pen/board.h"
#include "phalanx/sim/pen_plant.h"

namespace phalanx::fw_sim {

class PantographSimDevice : public SimDevice {
 public:
  /// Throws std::invalid_argument for a bad plant configuration (PenPlant's contract).
  explicit PantographSimDevice(const sim::PenPlantConfig& plant_config,
                               const apps::PantographConfig& config = apps::pantographDefaultConfig())
      : app_(config), plant_(plant_config) {}
  fw::DeviceApp& app() override { return app_; }
  std::vector<std::string> truthColumns() const override;
  void truthValues(double* out) const override;
  std::string instrumentSignal() const override;
  /// The first joint encoder; garbage: 4 × the firmware's largest plausible step per tick, every tick.
  InjectableSensor injectableSensor() const override { return {true, 0, 0, 4 * app_.config().max_counts_per_tick}; }
  sim::Plant& plant() override { return plant_; }
  uint8_t pwmCount() const override { return pen::board::kPwmChannelCount; }
  uint8_t adcCount() const override { return pen::board::kAdcChannelCount; }
  uint8_t encoderCount() const override { return pen::board::kEncoderChannelCount; }
  sim::PenPlant& penPlant() { return plant_; }
  apps::PantographApp& penApp() { return app_; }

 private:
  apps::PantographApp app_;
  sim::PenPlant plant_;
};

}  // namespace phalanx::fw_sim
