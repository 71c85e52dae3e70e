#pragma once
/// SEA finger exoskeleton: subject parameter estimation from the redundant sensor (eq 12, §5.3), the CSV
/// recordings it reads and the subject YAML it writes. Bounded nonlinear least squares with Ceres.
#include <array>
#include <string>
#include <vector>

#include "phalanx/sea/kinematics.h"

namespace phalanx::host::sea {

using SubjectParams = phalanx::sea::SubjectParams<double>;
using FixedGeometry = phalanx::sea::FixedGeometry<double>;

/// One row of a recording: the two actuated joint sensors and the redundant one (rad).
struct CalibrationSample {
  double theta1r_rad = 0.0;  ///< sensor 0 (sample0)
  double theta6r_rad = 0.0;  ///< sensor 1 (sample1)
  double theta7r_rad = 0.0;  ///< sensor 2 (sample2), the redundant θ7r
};

struct CalibrationOptions {
  SubjectParams initial = phalanx::sea::table4Initial<double>();  ///< P0 (Table 4)
  SubjectParams lower = phalanx::sea::table4Lower<double>();      ///< LB (Table 4, y_A corrected)
  SubjectParams upper = phalanx::sea::table4Upper<double>();      ///< UB (Table 4)
  FixedGeometry fixed = phalanx::sea::defaultModel<double>().fixed;
  int max_iterations = 200;
  /// Use every n-th sample (1 = all). A 1 kHz recording over a 2 s range of motion is 2000 rows; more rows
  /// add time, not information (the noise is white, the model smooth).
  int stride = 1;
  /// Centred quadratic Savitzky–Golay smoothing over this many consecutive rows, applied to all three channels
  /// before the fit (1 = none). The fit's inputs θ1r, θ6r are noisy too (errors in variables); a recording at
  /// 1 kHz of a ≤ 1 Hz motion can be smoothed over ~51 rows before the fit (docs/sea-model.md §Parameter
  /// estimation: 60 s, `--smooth 51 --stride 10`). Only for white sensor noise; a recording of already-filtered
  /// sensors gains less.
  int smooth_samples = 1;
  /// Extra starting points (a Halton sequence over the LB–UB box) besides P0: eq 12 from one redundant angle has
  /// local minima (docs/sea-model.md §Parameter estimation).
  int restarts = 24;
  /// Valley scan: l_BC stepped across its bounds in this many steps from the best multistart point (0 = none).
  int valley_steps = 20;
  /// Multistart and valley-scan points (lowest eq 12 cost first) polished by the errors-in-variables fit on the
  /// thinned samples.
  int polished = 12;
  /// Distinct polished candidates refined by the errors-in-variables fit on all samples (the lowest objective
  /// wins). 4, not 2: the thinned samples' ranking of neighbouring valley points is noisy.
  int refined = 4;
  /// Huber loss corner of both objectives in units of the sensor noise σ, which is estimated from the recording
  /// itself (CalibrationResult::noise_rad); 0 = plain least squares. At 2σ the loss keeps 99 % of least squares'
  /// efficiency on Gaussian errors (Huber's textbook 1.345σ keeps 95 %) and turns the 5–15 σ misfits near a PIP
  /// dead point from quadratic to linear. docs/sea-model.md §Robust loss.
  double robust_sigmas = 2.0;
  /// Predict θ7r on whichever assembly branch of the PIP four-bar fits the sample (the mechanism's whole coupler
  /// curve) instead of the estimator's branch only: a recording that passes through the PIP dead point continues
  /// on the other branch. docs/sea-model.md §Both branches.
  bool both_branches = true;
};

struct CalibrationResult {
  SubjectParams estimate{};
  double initial_rms_rad = 0.0;   ///< RMS of y_k − y_m,k at P0
  double final_rms_rad = 0.0;     ///< … at P̂
  double max_abs_residual_rad = 0.0;
  /// The minimised objective (with the Huber loss: √(2·cost/3N)): RMS over the 3·N sensor errors (θ1r, θ6r, θ7r against the fitted true angles, plus
  /// the chain-closure term) of the errors-in-variables fit at P̂. Its noise floor is ≈ σ/√3 for sensor noise σ
  /// (the fitted inputs absorb two of every three errors' degrees of freedom).
  double errors_in_variables_rms_rad = 0.0;
  /// Sensor noise σ of the fitted (smoothed) samples, estimated from the recording (raw rows minus their
  /// Savitzky–Golay fit); the Huber corner is robust_sigmas·noise_rad.
  double noise_rad = 0.0;
  /// Goodness of fit: errors_in_variables_rms_rad / (noise_rad/√3), ≈ 1 when the model explains the recording to
  /// its noise (0.97–1.03 over the sweeps). Well above 1 (the tool warns above 1.5) the recording does not fit
  /// the model: e.g. the mechanism passed through a PIP dead point onto the other assembly branch, or a sensor is
  /// miscalibrated; the estimate is then not trustworthy.
  double fit_to_noise = 0.0;
  int iterations = 0;
  bool converged = false;
  std::size_t samples_used = 0;
  std::size_t least_squares_samples = 0;  ///< samples where a chain needed the least-squares fallback at P̂
  std::array<bool, phalanx::sea::kNumSubjectParams> at_bound{};
  std::string solver_report;      ///< Ceres' one-line summary
};

/// Eq 12: P̂ = argmin Σ (y_k − y_m,k(P))² subject to LB ≤ P ≤ UB, with the model's inputs θ1r, θ6r treated as
/// measurements too (errors in variables: each sample's true inputs are fitted with P, docs/sea-model.md
/// §Parameter estimation). Search: multistart (P0 + `restarts` Halton points) and a valley scan over l_BC on
/// ≈ 200 thinned samples with eq 12 as printed; the `polished` cheapest points refitted with errors in variables
/// on the thinned samples; the `refined` best of those on all samples. Both objectives use a Huber loss at
/// robust_sigmas·σ, σ estimated from the recording. With restarts = valley_steps = 0 only the last step runs,
/// from P0. Returns an empty string or the problem (fewer than 20 samples, non-finite values,
/// inconsistent bounds).
std::string calibrate(const std::vector<CalibrationSample>& samples, const CalibrationOptions& options,
                      CalibrationResult& result);

/// RMS of y_k − y_m,k(P) over `samples` (rad): the eq 12 objective as an RMS.
double redundantResidualRms(const std::vector<CalibrationSample>& samples, const SubjectParams& p,
                            const FixedGeometry& fixed);

/// Reads a CSV with a header row. Columns: `sample0,sample1,sample2` (what `phalanx run --record` writes for
/// sea_finger) or `theta1r_rad,theta6r_rad,theta7r_rad`; other columns are ignored; rows with a non-finite value
/// are skipped. Returns "" or an error naming the file, line and column.
std::string readCalibrationCsv(const std::string& path, std::vector<CalibrationSample>& samples);

/// Subject YAML: a mapping `sea_subject:` with the seven keys of phalanx::sea::kSubjectParamNames and
/// optionally l_CE_m, l_EF_m, l_HI_m, x_K_m, y_K_m, l_KL_m, l_LM_m. Missing keys keep the values passed in.
/// Unknown keys and non-numeric values are errors naming the key.
std::string loadSubjectYaml(const std::string& path, SubjectParams& subject, FixedGeometry& fixed);

/// Writes (creating or updating) the subject YAML: the seven estimated parameters, the fixed geometry used,
/// and a `calibration:` block with the residuals. Other top-level keys of an existing file are kept.
std::string writeSubjectYaml(const std::string& path, const CalibrationResult& result, const FixedGeometry& fixed,
                             const std::string& source);

/// `phalanx sea-calibrate`: read the recording, estimate (eq 12) starting from the subject file's parameters
/// when it exists (else Table 4's P0), write the subject file, print the result (JSON or text) to stdout.
/// Returns the process exit code: 0 ok, 2 bad input (message on stderr).
int seaCalibrateCommand(const std::string& recording_csv, const std::string& subject_yaml, bool json, int stride,
                        int smooth_samples = 1);

}  // namespace phalanx::host::sea
