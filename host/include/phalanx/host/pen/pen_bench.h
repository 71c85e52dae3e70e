#pragma once
/// Pen bench scenarios (`phalanx bench pen-split|pen-wall`).
#include <cstdint>

#include <nlohmann/json.hpp>

#include "phalanx/host/pen/force_split.h"

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
/// Table X's geometry-dependent rows at home for a model and a splitter's torque limits: peak force/torque per
/// axis, spatial resolution (translations and rotations); with the paper's values alongside.
nlohmann::json homeCapabilities(const phalanx::pen::Model<double>& model, const PenForceSplitter& splitter);

struct PenWallBenchOptions {
  double stiffness_N_per_cm = 3.0;  ///< horizontal walls; the floor gets 0.7× (the paper's 2.1 / 3 N/cm)
  double damping_scale = 1.0;       ///< × the paper's box damping (0.05 / 0.02 N·s/cm)
  bool braking = true;              ///< braking pulse (6 / 3 N·s/cm) at contact onset
  bool brake_momentum_cap = true;   ///< cap the pulse at the impulse that stops the end (PenSceneConfig)
  double velocity_filter_hz = 0.0;  ///< end-velocity low-pass cutoff (0: the scene default)
  uint32_t seed = 1;
  bool noise = true;
  bool sweep = false;               ///< also sweep K with and without braking: largest stable stiffness
};

/// The pencil tip pressed by the simulated hand into the box's x wall, floor, far wall and their corners, then
/// thrown at the x wall hands-off (Fig. 19–20), in lockstep at 1 kHz. Per press: penetration, force, tip speed
/// RMS, contact breaks over the last second; impact: contact onsets, kinetic energy; run: ∫F_wall·v dt (energy
/// the walls generated, must be ≤ 0), faults, and `stable` (no sustained oscillation, passive).
nlohmann::json benchWall(const PenWallBenchOptions& options);
struct PenSceneConfig;
/// The scene the wall bench renders (for tests that reuse its gains).
PenSceneConfig wallBenchScene(const PenWallBenchOptions& options);

}  // namespace phalanx::host::pen
