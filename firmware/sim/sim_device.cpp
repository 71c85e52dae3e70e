#include "phalanx/fw_sim/sim_device.h"

#include <stdexcept>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/fw_sim/pantograph_sim.h"

namespace phalanx::fw_sim {
bool parseHandScenario(const std::string& name, sim::HandScenario& out) {
  if (name == "still") out = sim::HandScenario::kStill;
  else if (name == "close-open") out = sim::HandScenario::kCloseOpen;
  else if (name == "grasp") out = sim::HandScenario::kGrasp;
  else if (name == "random") out = sim::HandScenario::kRandom;
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
  if (name == "sea_rig") {
    sim::SeaPlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    cfg.variant = sim::SeaVariant::kRig;
    try {
      return std::make_unique<SeaFingerSimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("SEA plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "pantograph") {
    sim::PenPlantConfig cfg;
    cfg.seed = options.seed;
    cfg.noise = options.noise;
    // The pen's hand: "still" and "grasp" hold the pen at home; "random" and "close-open" move it about.
    if (options.scenario == "still" || options.scenario == "grasp") cfg.scenario = sim::PenHandScenario::kHold;
    else if (options.scenario == "random" || options.scenario == "close-open") cfg.scenario = sim::PenHandScenario::kRandom;
    else {
      error = "unknown scenario '" + options.scenario + "' (still, grasp: hold the pen; random, close-open: move it)";
      return nullptr;
    }
    try {
      return std::make_unique<PantographSimDevice>(cfg);
    } catch (const std::invalid_argument& e) {
      error = std::string("pen plant configuration: ") + e.what();
      return nullptr;
    }
  }
  if (name == "sea_finger") {
    error = "the simulated " + name + " is not built yet (glove5, sea_rig and pantograph are available)";
    return nullptr;
  }
  error = "unknown device '" + name + "' (glove5, sea_finger, sea_rig, pantograph)";
  return nullptr;
}

}  // namespace phalanx::fw_sim
