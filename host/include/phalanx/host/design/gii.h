#pragma once
/// Global Isotropy Index and the culling algorithm (Stocco, Salcudean & Sassani, seeds/004 §IV, eq 10–16).
///
///   GII(p) = min_{x0, x1 ∈ W} σ_min(S_J J(p, x0) S_T⁻¹) / σ_max(S_J J(p, x1) S_T⁻¹)        (eq 11)
///          = (min_x σ_min) / (max_x σ_max)
///   p* = argmax_{p ∈ P} GII(p)                                                              (eq 10)
///
/// A design problem is a finite set of candidates p (grouped: the members of a group share one Jacobian per
/// workspace sample and differ only in a scale factor of S_J, e.g. Q1) and a finite workspace W. The culling
/// search returns exactly the exhaustive optimum (ties → smallest candidate index) while evaluating far fewer
/// (candidate, sample) pairs: docs/design-tools.md §"Culling" states the bound it relies on.
#include <Eigen/Dense>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace phalanx::host::design {

// -------------------------------------------------------------------------------------------------------------
// Axis-angle orientation sampling, eq 14–16
// -------------------------------------------------------------------------------------------------------------

/// One orientation sample of a 2-rotation (tilt) workspace: the pen/tool axis is tilted by `tip_rad` (θ1, the
/// angle from its home direction) about the horizontal axis at azimuth `azimuth_rad` (θ2 ∈ [0, 2π)).
struct TiltSample {
  double tip_rad = 0;
  double azimuth_rad = 0;
};

/// K_r of eq 16: 1 + Σ_{n=1..N} floor(2πN/θ̄1 · sin(nθ̄1/N)), the number of orientation samples with N rings
/// of constant Δθ1 = θ̄1/N and ring spacing Δθ2,n = Δθ1 / sin(nΔθ1) (eq 14).
std::size_t axisAngleSampleCount(double tip_max_rad, std::size_t rings);

/// The samples counted by axisAngleSampleCount(), ring by ring (n = 0: the home orientation).
std::vector<TiltSample> axisAngleSamples(double tip_max_rad, std::size_t rings);

/// Eq 15: k_r = (k_i k_j k_k)^(d_r/d_t); then the N (≥ 1) whose K_r (eq 16) is closest to k_r.
std::size_t ringsForTranslationalSamples(double tip_max_rad, double translational_samples, double d_r, double d_t);

// -------------------------------------------------------------------------------------------------------------
// Isotropy of one matrix
// -------------------------------------------------------------------------------------------------------------

/// Extreme singular values of a matrix (σ_min is 0 for a rank-deficient one).
struct SigmaPair {
  double min = 0;
  double max = 0;
};

/// σ_min, σ_max of M (any shape; of the min(rows, cols) singular values), by Jacobi SVD.
SigmaPair sigmaBounds(const Eigen::MatrixXd& M);

/// σ_min, σ_max of A from the Gram matrix G = AᵀA (n×n, n ≤ rows of A): sqrt of its extreme eigenvalues.
SigmaPair sigmaBoundsFromGram(const Eigen::Matrix<double, 5, 5>& G);

/// Eq 11 over a list of per-sample σ bounds: (min σ_min)/(max σ_max); 0 for an empty list or σ_max = 0.
double giiFromSigmas(const std::vector<SigmaPair>& s);

/// Eq 11 for a Jacobian function over a sample list: scaled = S_J · J(x) · S_T⁻¹ (S_J, S_T diagonal, given as
/// vectors of their diagonals).
double gii(const std::function<Eigen::MatrixXd(std::size_t)>& jacobian, std::size_t samples,
           const Eigen::VectorXd& S_J, const Eigen::VectorXd& S_T);

// -------------------------------------------------------------------------------------------------------------
// Discrete minimax problem (eq 10 with eq 11) and its solvers
// -------------------------------------------------------------------------------------------------------------

/// candidates = numGroups() × groupSize(); candidate id = group · groupSize() + member.
class MinimaxProblem {
 public:
  virtual ~MinimaxProblem() = default;
  virtual std::size_t numGroups() const = 0;
  virtual std::size_t groupSize() const = 0;
  virtual std::size_t numSamples() const = 0;
  /// Sample at which culling starts (e.g. the workspace centre).
  virtual std::size_t seedSample() const { return 0; }
  /// σ bounds of the scaled Jacobian for candidates (group, members[0..n)) at workspace sample `sample`: ONE
  /// Jacobian evaluation shared by the members. An unreachable or singular pose gives σ_min = 0. Must be
  /// thread-safe and deterministic (the same inputs give bit-identical outputs).
  virtual void evaluate(std::size_t group, std::size_t sample, const std::uint32_t* members, std::size_t n,
                        SigmaPair* out) const = 0;
  std::size_t numCandidates() const { return numGroups() * groupSize(); }
};

struct SearchResult {
  std::size_t best = 0;          ///< candidate id of the optimum (ties → smallest id)
  double gii = 0;                ///< its GII
  std::uint64_t jacobian_evals = 0;  ///< evaluate() calls (one Jacobian each)
  std::uint64_t sigma_evals = 0;     ///< (candidate, sample) pairs whose σ bounds were computed
  // culling only
  std::size_t rounds = 0;            ///< leaders fully evaluated or culled while being evaluated
  std::size_t critical_samples = 0;  ///< samples at which all survivors were evaluated
  double seconds = 0;
};

/// A search's state while it runs (SearchOptions::progress).
struct SearchProgress {
  const char* search = "";          ///< "exhaustive" | "culling"
  double elapsed_s = 0;
  double pass_elapsed_s = 0;        ///< since the current pass began (exhaustive: the search is one pass)
  /// Exhaustive: share of all (group, sample) Jacobians done. Culling: share of the current pass done (the total
  /// is not known in advance: it depends on how fast the bounds cull).
  double fraction = -1;
  const char* pass = "";            ///< culling: "all alive at a sample" | "leader over every sample"
  std::size_t round = 0;            ///< culling rounds started
  std::size_t alive = 0;            ///< culling: candidates still alive (exhaustive: all)
  std::size_t candidates = 0;
  double best_gii = -1;             ///< best exact GII so far (-1: none yet; exhaustive: known only at the end)
  std::uint64_t jacobian_evals = 0;
};

struct SearchOptions {
  unsigned threads = 2;
  /// Called every progress_s seconds of the search, from a thread of its own (also inside a round or a pass),
  /// never after the search returns. progress_s <= 0 or no callback: quiet.
  double progress_s = 0;
  std::function<void(const SearchProgress&)> progress;
};

/// Evaluates every candidate at every sample (the reference the culling must equal).
SearchResult exhaustiveSearch(const MinimaxProblem& problem, const SearchOptions& opt = {});

/// Culling (004 §IV, ref [24]): exact minimax search by upper bounds. For candidate p and evaluated samples E,
/// UB(p) = min_E σ_min / max_E σ_max ≥ GII(p). Repeat: fully evaluate the alive candidate with the highest UB
/// (the leader), stopping early once its UB falls below the best exact GII found; evaluate every alive candidate
/// at the leader's critical samples (its arg-min σ_min and arg-max σ_max); cull every candidate whose UB is
/// below the best (or equal with a larger id). Returns the same optimum as exhaustiveSearch().
SearchResult cullingSearch(const MinimaxProblem& problem, const SearchOptions& opt = {});

/// Runs fn(begin, end) over [0, n) split into contiguous chunks on `threads` std::threads.
void parallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t, std::size_t)>& fn);

}  // namespace phalanx::host::design
