#pragma once
/// Glove design tools (Ma & Ben-Tzvi 2015, seeds/000 §3.2–3.7, §4.1): workspace analysis by joint-angle sweep,
/// mechanism joint ranges over the finger's range (eq 13–14), finger/glove segment collisions (§3.6), the
/// singularity margin (eq 24), the objectives z1 (eq 17) and z2 (eq 19), constraints g1–g3 (eq 20–22) and the
/// link-length optimisation (eq 23) with NLopt. Host only (double, heap allowed). The kinematics are the ones
/// the controller runs: common/include/phalanx/glove/kinematics.h. docs/design-tools.md documents every choice.
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "phalanx/glove/kinematics.h"

namespace phalanx::host::design {

using GloveModel = glove::Model<double>;
using GloveFinger = glove::FingerGeometry<double>;
using Vec3d = glove::Vec3<double>;

/// Joint-angle sweep grid over the finger's Table 2 box: n[i] evenly spaced values of θ_i from theta_min to
/// theta_max, both ends included (n[i] ≥ 2).
struct SweepGrid {
  std::array<std::size_t, 3> n{25, 25, 17};
};

/// Result of sweeping the finger through its range for one mechanism geometry.
struct GloveAnalysis {
  std::size_t poses = 0;          ///< finger poses swept
  std::size_t unreachable = 0;    ///< poses with no elbow-up mechanism solution (eq 6–8)
  std::size_t outside_limits = 0; ///< reachable poses whose α is outside the mechanism's declared range
  std::array<std::size_t, 3> colliding{};  ///< poses where segment B_{i-1}B_i crosses A_{i-1}A_i (§3.6)
  std::size_t colliding_any = 0;
  Vec3d alpha_min_deg{}, alpha_max_deg{};  ///< over the reachable poses (eq 13)
  Vec3d alpha_var_deg{};                   ///< eq 14
  double z1_deg = 0;        ///< eq 17: ‖α_var‖ (deg)
  double z2_rms_mm = 0;     ///< eq 19: ‖(a21, a22, a23)‖ (mm), RMS over the reachable poses
  double z2_max_mm = 0;     ///< eq 19, worst pose
  double reach_violation_mm = 0;     ///< Σ over poses of the distance B2 is beyond the (l1, l2) annulus
  double collision_depth_mm = 0;     ///< Σ over poses and pairs of the crossing depth (0 when collision-free)
  double min_abs_sin_alpha2 = 0;     ///< eq 24 margin over the reachable poses (1: far, 0: singular)
  double alpha2_at_min_margin_deg = 0;
  /// Finger workspace inside the mechanism's (§4.1): every pose reachable and, when the mechanism declares
  /// α limits, inside them.
  bool finger_inside_mechanism = false;
};

/// Shape of mechanism link 1 for the §3.6 collision test. §3.6 examines the straight segments B0B1, but §3.2
/// makes link 1 "two perpendicular segments, resulting in an L shape" to enlarge the collision-free workspace.
/// corner_deg = 0: the straight chord B0B1 (the literal §3.6 test). corner_deg = β > 0: an L with its corner K
/// on the dorsal side of the chord, first leg B0K = l1 cos β at +β from the chord, second leg KB1 = l1 sin β;
/// both legs are tested against A0A1. The paper gives no leg lengths (docs/design-tools.md).
struct Link1Shape {
  double corner_deg = 45.0;
};

/// Sweeps the finger of `model` through its θ box (grid `g`) and evaluates everything above. When
/// `check_mech_limits` is set, α outside model.mech.alpha_{min,max}_rad counts as outside_limits.
GloveAnalysis analyseGlove(const GloveModel& model, const SweepGrid& g, bool check_mech_limits = false,
                           const Link1Shape& link1 = {});

/// Length (m) by which two planar segments PQ and RS must be moved apart to stop crossing: 0 when they do
/// not cross, else the smallest distance of an endpoint to the other segment (continuous, 0 at touching).
double segmentCrossingDepth(const std::array<double, 2>& p, const std::array<double, 2>& q,
                            const std::array<double, 2>& r, const std::array<double, 2>& s);

/// Point clouds of Fig. 6: fingertip positions (mm) from a θ sweep of the finger and from an α sweep of the
/// mechanism over [alpha_lo, alpha_hi] (deg).
struct WorkspaceClouds {
  std::vector<std::array<double, 2>> finger_mm;
  std::vector<std::array<double, 2>> mechanism_mm;
};
WorkspaceClouds sweepWorkspaces(const GloveModel& model, const SweepGrid& finger_grid, const Vec3d& alpha_lo_deg,
                                const Vec3d& alpha_hi_deg, std::size_t mech_steps_per_joint);

/// Writes Fig. 6 as SVG (mechanism cloud grey, finger cloud blue). Returns an error message or "".
std::string writeWorkspaceSvg(const WorkspaceClouds& clouds, const std::string& title, const std::string& path);

/// The link-length optimisation problem (eq 17–23, §3.7).
struct GloveOptOptions {
  /// Fingers the design must fit (one: per-user design; several: §3.3's population of hand sizes — the
  /// objective is the mean over fingers, every constraint must hold for every finger).
  std::vector<GloveFinger> fingers;
  /// Mechanism placement not optimised by the paper (l_p, x_B0, y_B0); taken from the controller's default
  /// index-finger model (docs/glove-model.md) unless set.
  double l_p_m = 0, x_B0_m = 0, y_B0_m = 0;
  SweepGrid grid{13, 13, 9};
  double w1 = 1.0, w2 = 1.0;     ///< eq 23 weights (§3.7: all 1)
  double max_joint_range_deg = 150.0;  ///< g3, eq 22
  bool collision_constraint = true;    ///< §3.6
  Link1Shape link1{};                  ///< link-1 shape in the collision test
  bool use_slsqp = false;        ///< false: COBYLA (derivative-free); true: SLSQP with central differences
  std::size_t starts = 6;        ///< first start = §3.7's initial guess 1.5·p; the others quasi-random in bounds
  double xtol_rel = 1e-5;
  std::size_t max_evals = 3000;
  unsigned seed = 1;
};

/// One finished local solve.
struct GloveOptStart {
  Vec3d l0_mm{};
  Vec3d l_mm{};
  double Z = 0;
  bool feasible = false;
  int nlopt_result = 0;
  std::size_t evals = 0;
};

struct GloveOptResult {
  Vec3d l_mm{};            ///< best feasible (l1, l2, l3)
  bool feasible = false;
  double Z = 0, z1_deg = 0, z2_mm = 0;
  std::vector<GloveOptStart> starts;
  GloveAnalysis analysis;  ///< of the first finger at the optimum, on the options' grid
  std::vector<double> constraint_values;  ///< at the optimum, every entry ≤ 0 means satisfied (see names)
  std::vector<std::string> constraint_names;
};

/// Builds a model from a finger, mechanism lengths (mm) and the placement in `opt`.
GloveModel makeGloveModel(const GloveFinger& finger, const Vec3d& l_mm, const GloveOptOptions& opt);

/// Objective Z (eq 23) and constraint values c_k (≤ 0 satisfied) of a design `l_mm` under `opt`. Constraints:
/// g1 (eq 20), g2 (eq 21), g3 ×3 (eq 22), reachability, collision (§3.6) — names via constraintNames().
double gloveObjective(const Vec3d& l_mm, const GloveOptOptions& opt, std::vector<double>* constraints,
                      double* z1_deg = nullptr, double* z2_mm = nullptr);
std::vector<std::string> gloveConstraintNames();

/// Default options: Table 2 index finger, placement of glove::defaultIndexModel().
GloveOptOptions defaultGloveOptOptions();

/// Multi-start constrained optimisation (§3.7): bounds p ≤ l ≤ 2p, start 1.5·p.
GloveOptResult optimiseGlove(const GloveOptOptions& opt);

/// YAML device geometry (mm, deg) of one finger's glove mechanism; loadable by loadGloveGeometryYaml.
std::string gloveGeometryYaml(const GloveModel& model, const GloveAnalysis& a, const std::string& comment);
/// Reads a geometry written by gloveGeometryYaml into a glove::Model<double>. Returns an error or "".
std::string loadGloveGeometryYaml(const std::string& path, GloveModel& out);
/// The same from YAML text; `path` names the source in errors.
std::string loadGloveGeometryText(const std::string& yaml_text, const std::string& path, GloveModel& out);

}  // namespace phalanx::host::design
