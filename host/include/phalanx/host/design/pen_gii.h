#pragma once
/// GII design problem of the 5-DOF Twin-Pantograph haptic pen (seeds/004 §V–VI, Tables VI–IX, eq 17–19,
/// 22–27), on the pantograph kinematics the controller runs (common/include/phalanx/pen/kinematics.h).
///
/// Units: lengths in cm (Table I gives the torque ratios in cm; the pen kinematics are scale-free), angles in
/// rad. Task coordinates ẋ = (v_i, v_j, v_k, ω_i, ω_k) in the pen (end-effector) frame, j along the pen axis
/// (roll about it is passive); joints q = (q1 waist, q2, q3 shoulders | q4 waist, q5, q6 shoulders).
/// J (6×5): q̇ = J ẋ (eq 23), f = Jᵀτ (eq 22).
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "phalanx/host/design/gii.h"

namespace phalanx::host::design {

/// min, min + step, …, max (both ends included; count rounded).
struct GridRange {
  double min = 0, max = 0, step = 1;
  std::size_t count() const;
  double value(std::size_t i) const { return min + step * static_cast<double>(i); }
};

enum class PenGiiMode {
  kForce,     ///< eq 17–19, 22: S_J = diag(Q, 1, 1, Q, 1, 1), S_T = diag(1, 1, 1.5, 3.6, 3.9) (Table I, no M_j)
  kVelocity,  ///< eq 23–27: S_J = diag(Q, 1, 1, Q, 1, 1) with Q = R_w/R_s, S_T = diag(1, 1, 1, 0.06, 0.06),
              ///< matrix S_J J S_T (q̇ = J ẋ maps task → joint; see docs/design-tools.md)
};

/// Table VII parameter space and Table VI workspace (defaults are the paper's).
struct PenGiiSpec {
  GridRange l1{2.4, 7.0, 0.2};   ///< shoulder spacing (cm)
  GridRange l2{10.0, 30.0, 0.5}; ///< upper arm (cm)
  GridRange l3{15.0, 35.0, 0.5}; ///< forearm (cm)
  GridRange l6{7.0, 11.0, 0.2};  ///< pen centre → each universal joint (cm; pen length 2·l6, pen::endOffset)
  GridRange q1{0.5, 3.0, 0.1};   ///< waist/shoulder scale factor Q1
  double l4_cm = 8.0;            ///< waist-axis spacing, fixed (§VI)
  double distance_cm = 25.0;     ///< workspace centre along k from the base origin (Table VII: 25)
  GridRange wi{0.0, 8.0, 0.5};   ///< Table VI (quarter workspace: i ≥ 0, j ≥ 0 by symmetry)
  GridRange wj{0.0, 5.0, 0.5};
  GridRange wk{-5.0, 5.0, 0.5};
  double tilt_max_deg = 45.0;
  /// Rings N of eq 16; 0: from eq 15 with the full (un-quartered) translational grid, which gives Table VI's
  /// 617 orientations (N = 14).
  std::size_t rings = 0;
  PenGiiMode mode = PenGiiMode::kForce;
  /// Velocity mode only: use eq 11's S_T⁻¹ literally (S_J J S_T⁻¹ with eq 27's S_T) instead of S_J J S_T.
  bool velocity_literal_inverse = false;
};

/// One design: lengths (cm) and Q1.
struct PenDesign {
  double l1 = 0, l2 = 0, l3 = 0, l6 = 0, q1 = 0;
};

class TwinPantographGii final : public MinimaxProblem {
 public:
  explicit TwinPantographGii(const PenGiiSpec& spec);
  std::size_t numGroups() const override { return groups_; }
  std::size_t groupSize() const override { return nq_; }
  std::size_t numSamples() const override { return positions_.size() * tilts_.size(); }
  std::size_t seedSample() const override { return seed_; }
  void evaluate(std::size_t group, std::size_t sample, const std::uint32_t* members, std::size_t n,
                SigmaPair* out) const override;

  PenDesign design(std::size_t candidate) const;
  std::size_t numOrientations() const { return tilts_.size(); }
  std::size_t numPositions() const { return positions_.size(); }
  std::size_t rings() const { return rings_; }
  /// Scaled 6×5 matrix S_J J S_T⁻¹ of one design at one sample; false when unreachable/singular.
  bool scaledJacobian(const PenDesign& d, std::size_t sample, Eigen::Matrix<double, 6, 5>& out) const;

 private:
  bool jacobian(double l1, double l2, double l3, double l6, std::size_t sample, Eigen::Matrix<double, 6, 5>& J) const;
  PenGiiSpec spec_;
  std::array<std::size_t, 4> n_{};  // l1, l2, l3, l6 counts
  std::size_t nq_ = 0, groups_ = 0, rings_ = 0, seed_ = 0;
  std::vector<std::array<double, 3>> positions_;  // cm, in {B}
  std::vector<Eigen::Matrix3d> tilts_;            // end-effector frames
  Eigen::Matrix<double, 5, 1> st_inv_;
};

/// Exact GII of one design (every workspace sample), eq 11.
double penGii(const TwinPantographGii& problem, const PenDesign& d);

}  // namespace phalanx::host::design
