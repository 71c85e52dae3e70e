#pragma once
/// Twin-Pantograph force split (seeds/004 §VI, Fig. 18): desired pen wrench at its centre → a force at each pen
/// end → τ = Jᵀ f per pantograph → six joint torques, including the redundant waist actuator.
///
/// Decoupled control as in Fig. 18, with the one freedom the paper leaves unused made explicit: the two end
/// forces are fixed by the wrench up to an internal force μ along the pen axis (tension μ > 0), which no wrench
/// sees. μ is chosen to minimise the limit-normalised actuator effort Σ(τ_i/τmax_i)², then — beyond the paper —
/// used first to pull a saturating actuator back inside its limit; only if no μ can, the whole wrench is scaled
/// uniformly (its direction is kept) to the largest feasible fraction. No torque ever exceeds its limit.
///
/// All per-cycle work is on fixed-size arrays: no allocation (tests/unit/pen_force_split_test.cpp counts).
#include <array>
#include <cstdint>

#include "phalanx/pen/kinematics.h"

namespace phalanx::host::pen {

using Vec3d = phalanx::pen::Vec3<double>;
using JointVecd = phalanx::pen::JointVec<double>;

/// Desired wrench on the pen, at its centre, in the base frame {B}.
struct PenWrench {
  Vec3d force_N{};
  /// Moment about the centre. Only the part perpendicular to the pen axis can be exerted (roll is passive,
  /// §VI); at home these are the two controlled torques about x and z of Table X. The axial part is dropped
  /// and reported in SplitResult::dropped_roll_torque_Nm.
  Vec3d torque_Nm{};
};

struct SplitConfig {
  /// Per-joint torque limit (N·m), order q1..q6. Default 2.1 N·m each: the peak forces of Table X at home
  /// through this model's Jacobians (docs/pen-model.md §"Torque limits").
  JointVecd torque_limit_Nm{2.1, 2.1, 2.1, 2.1, 2.1, 2.1};
  /// false: μ = 0 (the paper's plain decoupled split, no internal force) unless a limit needs it.
  bool minimise_effort = true;
};

enum class SplitStatus : std::uint8_t {
  kOk = 0,                       ///< wrench reproduced exactly, no limit active
  kNonFiniteInput = 1,           ///< NaN/Inf wrench: all torques 0
  kKinematicsUnusable = 2,       ///< the kinematic data passed in is not usable: all torques 0
  kBadConfig = 3,                ///< a torque limit is not finite and > 0: all torques 0
  kInternalForceRedistributed = 16,  ///< wrench exact; μ moved off its optimum to respect a limit
  kScaled = 17,                  ///< wrench scaled by `scale` < 1 (direction kept) to respect the limits
};

struct SplitResult {
  JointVecd tau_Nm{};             ///< joint torques q1..q6
  Vec3d f_bottom_N{}, f_top_N{};  ///< force applied by each pantograph on its pen end (tip, eraser)
  double internal_force_N = 0.0;  ///< μ: tension along the pen axis
  double optimal_internal_force_N = 0.0;  ///< μ* of the unconstrained effort optimum (for the same scale)
  double scale = 1.0;             ///< fraction of the desired wrench delivered (1 unless kScaled)
  double effort = 0.0;            ///< Σ (τ_i / τmax_i)²
  double dropped_roll_torque_Nm = 0.0;  ///< axial moment that cannot be exerted
  std::uint8_t limit_active_mask = 0;   ///< bit i: |τ_i| at its limit
  SplitStatus status = SplitStatus::kNonFiniteInput;
};

class PenForceSplitter {
 public:
  explicit PenForceSplitter(const SplitConfig& config = {});
  const SplitConfig& config() const { return config_; }
  /// Split `wrench` for the configuration in `kin` (from phalanx::pen::computeForward; uses both tips, the
  /// measured axis and both Jacobians). The moment arm is the MEASURED half-length |p_top − p_bottom|/2, so the
  /// statics are exact for the configuration the kinematics describe.
  SplitStatus split(const phalanx::pen::Data<double>& kin, const PenWrench& wrench, SplitResult& out) const;

 private:
  SplitConfig config_;
  bool config_ok_ = false;
};

/// Net wrench on the pen (at the measured centre, {B}) that the two end forces exert: F = f_b + f_t,
/// M = (p_b − c) × f_b + (p_t − c) × f_t. Statics, used by tests and the bench to check the split.
void endForcesToWrench(const phalanx::pen::Data<double>& kin, const Vec3d& f_bottom_N, const Vec3d& f_top_N,
                       PenWrench& out);

/// f = J⁻ᵀ τ for one pantograph (Cramer's rule on the 3×3). Returns false when J is singular.
bool tipForceFromTorques(const phalanx::pen::Mat3<double>& J, const Vec3d& tau_Nm, Vec3d& f_N);

}  // namespace phalanx::host::pen
