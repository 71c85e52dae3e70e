#pragma once
/// Pen bench scenarios (`phalanx bench pen-split|pen-wall`).
#include <cstdint>
#include <functional>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/pen/force_split.h"
#include "phalanx/sim/pen_plant.h"

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
  /// Called after each run of a sweep (runs done, runs in all); not called for a single run.
  std::function<void(std::size_t, std::size_t)> progress;
};

/// The pencil tip pressed by the simulated hand into the box's x wall, floor, far wall and their corners, then
/// thrown at the x wall hands-off (Fig. 19–20), in lockstep at 1 kHz. Per press: penetration, force, tip speed
/// RMS, contact breaks over the last second; impact: contact onsets, kinetic energy; run: ∫F_wall·v dt (energy
/// the walls generated, must be ≤ 0), faults, and `stable` (no sustained oscillation, passive).
nlohmann::json benchWall(const PenWallBenchOptions& options);
struct PenSceneConfig;
/// The scene the wall bench renders (for tests that reuse its gains).
PenSceneConfig wallBenchScene(const PenWallBenchOptions& options);

/// One phase of the wall bench's hand schedule (shared with the bench runner's `pen-wall` step).
struct PenWallPhase {
  const char* name;
  sim::PenVec5 target;   ///< hand target (centre m, angles rad)
  double move_s;         ///< raised-cosine move from the previous target
  double hold_s;
  bool press;            ///< a pressing phase: metrics over the last second of the hold
  bool release = false;  ///< hands-off: the hand lets go 0.15 s before the end of the move
};
/// The schedule: free, x wall, floor, far wall, three corners, then a hands-off throw at the x wall.
std::vector<PenWallPhase> wallBenchSchedule(const PenSceneConfig& scene);
/// Hand target and its rate at time t_s into `phase`, moving from `prev` (the previous phase's target).
void wallBenchHandTarget(const PenWallPhase& phase, const sim::PenVec5& prev, double t_s, sim::PenVec5& target,
                         sim::PenVec5& target_dot);
/// Deepest true penetration of a point into the box's walls (m, ≥ 0).
double wallPenetration(const PenSceneConfig& scene, const Vec3d& p);
/// Potential energy the box's springs hold for an end at p (J): ½Kδ² per penetrated wall.
double wallStoredEnergy(const PenSceneConfig& scene, const Vec3d& p);

}  // namespace phalanx::host::pen
