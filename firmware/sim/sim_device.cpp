#include "phalanx/fw_sim/sim_device.h"

#include <stdexcept>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/fw_sim/sea_finger_sim.h"

namespace phalanx::fw_sim {
bool parseHandScenario(const std::string& name, sim::HandScenario& out) {
  if (name == "still") out = sim::HandScenario::kStill;
  else if (name == "close-open") out = sim::HandScenario::kCloseOpen;
  else if (name == "grasp") out = sim::HandScenario::kGrasp;
  else if (name == "random") out = sim::HandScenario::kRandom;
  else return false;
  return true;
}

bool parseSeaUserMotion(const std::string& name, sim::SeaUserMotion& out) {
  // The exoskeleton has no virtual objects to grasp: "grasp" (the CLI's default) is the relaxed finger too.
  if (name == "still" || name == "grasp") out = sim::SeaUserMotion::kRelaxed;
  else if (name == "random") out = sim::SeaUserMotion::kRandom;
  else if (name == "close-open") out = sim::SeaUserMotion::kCloseOpen;
  else if (name == "hold") out = sim::SeaUserMotion::kHold;
  else return false;
  return true;
}

std::unique_ptr<SimDevice> makeSimDevice(const std::string& name, const SimDeviceOptions& options, std::string& error) {
  if (name == "glove5") {
    sim::GlovePlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    if (!parseHandScenario(options.scenario, cfg.scenario)) {
      error = "unknown scenario '" + options.scenario + "' (still, close-open, grasp, random)";
      return nullptr;
    }
    try {
      return std::make_unique<Glove5SimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("glove plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "sea_rig" || name == "sea_finger") {
    sim::SeaPlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    cfg.variant = name == "sea_rig" ? sim::SeaVariant::kRig : sim::SeaVariant::kFinger;
    if (!parseSeaUserMotion(options.scenario, cfg.motion)) {
      error = "unknown scenario '" + options.scenario + "' (still, close-open, grasp, random)";
      return nullptr;
    }
    try {
      return std::make_unique<SeaFingerSimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("SEA plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "pantograph") {
    error = "the simulated " + name + " is not built yet (only glove5 is available)";
    return nullptr;
  }
  error = "unknown device '" + name + "' (glove5, sea_finger, sea_rig, pantograph)";
  return nullptr;
}

}  // namespace phalanx::fw_sim
