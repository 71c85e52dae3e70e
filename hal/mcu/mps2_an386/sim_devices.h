#pragma once
/// The simulated plant the emulated board links in for each device app (the same plant classes firmware-sim
/// runs on Linux), chosen with the app (PHALANX_MCU_APP_<NAME>).
#include <cstdint>

#include "phalanx/fw_mcu/app_registry.h"

#if defined(PHALANX_MCU_APP_GLOVE5)
#include "phalanx/sim/glove_plant.h"
namespace phalanx::mcu::mps2 {
using PlantType = sim::GlovePlant;
struct PlantOptions {
  uint32_t seed = 1;
  uint8_t scenario = 2;  ///< sim::HandScenario (kGrasp, as firmware-sim's default)
  bool noise = true;
  uint32_t substep_us = 0;  ///< plant integration step (0: the plant's default, 100 µs)
};
inline sim::GlovePlantConfig plantConfig(const PlantOptions& o) {
  sim::GlovePlantConfig c;
  c.seed = o.seed;
  c.noise = o.noise;
  c.scenario = static_cast<sim::HandScenario>(o.scenario);
  if (o.substep_us != 0) c.params.max_substep_s = static_cast<double>(o.substep_us) * 1e-6;
  return c;
}
/// "still" | "close-open" | "grasp" | "random" → scenario number, or −1.
inline int scenarioNumber(const char* s, int len) {
  auto is = [&](const char* name) {
    int i = 0;
    for (; i < len && name[i] != 0; ++i) {
      if (name[i] != s[i]) return false;
    }
    return i == len && name[i] == 0;
  };
  if (is("still")) return static_cast<int>(sim::HandScenario::kStill);
  if (is("close-open")) return static_cast<int>(sim::HandScenario::kCloseOpen);
  if (is("grasp")) return static_cast<int>(sim::HandScenario::kGrasp);
  if (is("random")) return static_cast<int>(sim::HandScenario::kRandom);
  return -1;
}
}  // namespace phalanx::mcu::mps2
#endif
