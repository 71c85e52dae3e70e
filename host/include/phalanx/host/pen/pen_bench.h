#pragma once
/// Pen bench scenarios (`phalanx bench pen-split|pen-wall`).
#include <cstdint>

#include <nlohmann/json.hpp>

namespace phalanx::host::pen {

struct PenSplitBenchOptions {
  uint32_t seed = 1;
  int grid = 5;                  ///< samples per workspace axis (x, y, z, θx, θz): grid⁵ poses
  int wrenches_per_pose = 8;     ///< random wrenches per pose and magnitude class
};

/// Accuracy and cost of the force split over Table X's workspace, seen through 4000-count encoders: wrench error
/// of the six torques (J⁻ᵀτ + statics vs the desired wrench), normalised effort (effort-optimal μ vs the paper's
/// μ = 0), how often the saturation redistribution is active, and the mean wall-clock cost of FK + split.
nlohmann::json benchSplit(const PenSplitBenchOptions& options);

}  // namespace phalanx::host::pen
