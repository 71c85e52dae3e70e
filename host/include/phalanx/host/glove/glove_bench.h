#pragma once
/// Glove bench scenarios (`phalanx bench glove-free-motion|glove-grasp`), run on the simulated glove in
/// lockstep: the firmware app, the plant with its sensor noise, the link codec and the host controller.
/// Every metric is computed from what the host sees in telemetry (so the same code can score a real glove);
/// the plant's ground truth is reported beside it under "truth".
#include <cstdint>

#include <nlohmann/json.hpp>

namespace phalanx::host::glove {

struct GloveBenchOptions {
  double seconds = 0.0;  ///< 0: the scenario's default length
  uint32_t seed = 1;
  bool noise = true;
  bool drift = true;  ///< false: the simulated strain gauges' thermal zero drift is off (noise stays)
  double worn_s = -1.0;  ///< how long the glove was worn before the start (s); < 0: the plant's default
};

/// Free motion (000 §4.3): close/open maneuvers of 1 s with zero commanded force, with and without cables.
/// Peak contact force per finger and Pearson r of each mechanism angle trajectory (000 Table 4).
nlohmann::json benchFreeMotion(const GloveBenchOptions& options);

/// Grasp of the rigid virtual ball: steady-contact rendered force vs measured pad force (eq 1).
nlohmann::json benchGrasp(const GloveBenchOptions& options);

}  // namespace phalanx::host::glove
