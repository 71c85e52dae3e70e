#include "phalanx/host/sea/sea_calibrate.h"

#include <ceres/ceres.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>

#include "phalanx/host/yaml_keys.h"

namespace phalanx::host::sea {

namespace ps = phalanx::sea;

namespace {

/// A chain that does not close at P (the least-squares fallback, eq 4) is impossible for the device that produced
/// the recording: its closure error is a residual too, scaled so 0.1 mm weighs like one sensor σ (0.05°).
constexpr double kClosureWeight = 0.05 * M_PI / 180.0 / 1e-4;  // rad per metre of closure error

/// θ7r − y_m(P, θ1, θ6) wrapped to (−π, π], and the chain closure error. With `both_branches` y_m is taken on
/// whichever assembly branch of the PIP four-bar is nearer to θ7r: the (θ6r, θ7r) locus of the mechanism is the
/// whole coupler curve, and a recording whose motion passes through the dead point (F, H, C collinear) continues
/// on the other branch (docs/sea-model.md §Both branches).
double redundantError(const SubjectParams& sp, const FixedGeometry& fixed, double theta1, double theta6,
                      double theta7r, bool both_branches, double& closure_m) {
  const double e = std::remainder(theta7r - ps::predictRedundant(sp, fixed, theta1, theta6, &closure_m), 2.0 * M_PI);
  if (!both_branches) return e;
  double closure_other = 0.0;
  const double e_other =
      std::remainder(theta7r - ps::predictRedundant(sp, fixed, theta1, theta6, &closure_other, true), 2.0 * M_PI);
  if (std::fabs(e_other) < std::fabs(e)) {
    closure_m = closure_other;
    return e_other;
  }
  return e;
}

/// y_k − y_m,k(P) (eq 12), wrapped to (−π, π], plus the chain-closure residual: the multistart's cheap objective.
struct RedundantResidual {
  CalibrationSample s;
  FixedGeometry fixed;
  bool both_branches;
  bool operator()(const double* p, double* r) const {
    const SubjectParams sp{p[0], p[1], p[2], p[3], p[4], p[5], p[6]};
    double closure_m = 0.0;
    r[0] = redundantError(sp, fixed, s.theta1r_rad, s.theta6r_rad, s.theta7r_rad, both_branches, closure_m);
    r[1] = kClosureWeight * closure_m;
    return std::isfinite(r[0]) && std::isfinite(r[1]);
  }
};

/// Errors in variables done exactly (orthogonal distance regression): every sample gets latent true inputs
/// z = (θ1, θ6), and its residuals are the three sensor errors θ1r − θ1, θ6r − θ6, θ7r − y_m(P, θ1, θ6), all of
/// the same σ; plus the chain-closure residual at z. Minimising over P and all z is the Gaussian maximum
/// likelihood of eq 12's model when all three sensors are noisy, without linearising the prediction (near a
/// PIP dead point y_m has a vertical tangent and the effective-variance weights fail).
struct OdrResidual {
  CalibrationSample s;
  FixedGeometry fixed;
  bool both_branches;
  bool operator()(const double* p, const double* z, double* r) const {
    const SubjectParams sp{p[0], p[1], p[2], p[3], p[4], p[5], p[6]};
    double closure_m = 0.0;
    r[0] = s.theta1r_rad - z[0];
    r[1] = s.theta6r_rad - z[1];
    r[2] = redundantError(sp, fixed, z[0], z[1], s.theta7r_rad, both_branches, closure_m);
    r[3] = kClosureWeight * closure_m;
    return std::isfinite(r[2]) && std::isfinite(r[3]);
  }
};

struct Stats {
  double rms = 0.0;
  double max_abs = 0.0;
  std::size_t least_squares = 0;
};

Stats residualStats(const std::vector<CalibrationSample>& samples, const SubjectParams& p,
                    const FixedGeometry& fixed) {
  Stats st;
  double sq = 0.0;
  for (const CalibrationSample& s : samples) {
    double chain_res = 0.0;
    const double y_m = ps::predictRedundant(p, fixed, s.theta1r_rad, s.theta6r_rad, &chain_res);
    const double e = std::remainder(s.theta7r_rad - y_m, 2.0 * M_PI);
    sq += e * e;
    st.max_abs = std::fmax(st.max_abs, std::fabs(e));
    if (chain_res > 0.0) ++st.least_squares;
  }
  st.rms = samples.empty() ? 0.0 : std::sqrt(sq / static_cast<double>(samples.size()));
  return st;
}

/// Weight of the centred quadratic Savitzky–Golay filter over 2h+1 rows at offset d ∈ [−h, h]:
/// (3(3h²+3h−1) − 15 d²) / ((2h−1)(2h+1)(2h+3)).
double sgWeight(std::size_t h, double d) {
  const double m = static_cast<double>(h);
  return (3.0 * (3 * m * m + 3 * m - 1) - 15.0 * d * d) / ((2 * m - 1) * (2 * m + 1) * (2 * m + 3));
}

/// The quadratic Savitzky–Golay value of row i over rows i−h … i+h (h ≥ 2, all inside `rows`).
CalibrationSample savitzkyGolay(const std::vector<CalibrationSample>& rows, std::size_t i, std::size_t h) {
  CalibrationSample acc{0.0, 0.0, 0.0};
  for (std::size_t j = i - h; j <= i + h; ++j) {
    const double w = sgWeight(h, static_cast<double>(j) - static_cast<double>(i));
    acc.theta1r_rad += w * rows[j].theta1r_rad;
    acc.theta6r_rad += w * rows[j].theta6r_rad;
    acc.theta7r_rad += w * rows[j].theta7r_rad;
  }
  return acc;
}

bool finite(const CalibrationSample& s) {
  return std::isfinite(s.theta1r_rad) && std::isfinite(s.theta6r_rad) && std::isfinite(s.theta7r_rad);
}

}  // namespace

std::string calibrate(const std::vector<CalibrationSample>& all, const CalibrationOptions& opt,
                      CalibrationResult& result) {
  result = CalibrationResult{};
  if (opt.stride < 1) return "stride must be ≥ 1";
  if (opt.max_iterations < 1) return "max_iterations must be ≥ 1";
  if (opt.smooth_samples < 1) return "smooth_samples must be ≥ 1";
  if (opt.restarts < 0 || opt.valley_steps < 0) return "restarts and valley_steps must be ≥ 0";
  if (opt.polished < 1 || opt.refined < 1) return "polished and refined must be ≥ 1";
  if (!(opt.robust_sigmas >= 0.0)) return "robust_sigmas must be ≥ 0";
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (!finite(all[i])) return "sample " + std::to_string(i) + " is not finite";
  }
  // Centred quadratic Savitzky–Golay smoothing (least-squares parabola over the window, evaluated at its centre):
  // unlike a moving average it has no curvature bias (a 25-row average of a 38° sine at 0.8 Hz is 0.025° low at
  // the turning points, which is itself a bias of eq 12's fit). Near the ends the window shrinks symmetrically.
  std::vector<CalibrationSample> smooth = all;
  if (opt.smooth_samples > 1) {
    const std::size_t half = static_cast<std::size_t>(opt.smooth_samples / 2);
    for (std::size_t i = 0; i < all.size(); ++i) {
      const std::size_t h = std::min({half, i, all.size() - 1 - i});
      if (h < 2) continue;  // a parabola through ≤ 3 points is the data itself
      smooth[i] = savitzkyGolay(all, i, h);
    }
  }
  // Sensor noise σ of the fitted samples, from the data alone (no model): the raw rows minus their quadratic
  // Savitzky–Golay fit over the smoothing window (11 rows when not smoothing) have variance σ_raw²(1 − w0), w0 the
  // filter's centre weight (= Σ w², the variance ratio of the filter); the smoothed samples have σ_raw·√w0.
  double noise_rad = 0.0;
  {
    const std::size_t half = static_cast<std::size_t>((opt.smooth_samples > 1 ? opt.smooth_samples : 11) / 2);
    const double w0 = sgWeight(half, 0);
    double sq = 0.0;
    std::size_t n = 0;
    for (std::size_t i = half; i + half < all.size(); ++i) {
      const CalibrationSample fit = savitzkyGolay(all, i, half);
      for (const double e : {all[i].theta1r_rad - fit.theta1r_rad, all[i].theta6r_rad - fit.theta6r_rad,
                             all[i].theta7r_rad - fit.theta7r_rad}) {
        sq += e * e;
        ++n;
      }
    }
    const double sigma_raw = n > 0 ? std::sqrt(sq / static_cast<double>(n) / (1.0 - w0)) : 0.0;
    noise_rad = opt.smooth_samples > 1 ? sigma_raw * std::sqrt(w0) : sigma_raw;
  }
  // Both objectives use a Huber loss with its corner at robust_sigmas·σ (0 = plain least squares): the Gaussian
  // model of eq 12 fails near a PIP dead point, where the model curve y_m(θ6r) ends with a vertical tangent and a
  // few recorded samples sit 5–15 σ off any P near the truth; squared, they outweighed the rest and moved the
  // optimum 1–1.5 mm along the weak direction (docs/sea-model.md §Robust loss).
  const double huber_rad = opt.robust_sigmas > 0.0 ? opt.robust_sigmas * noise_rad : 0.0;
  auto robustLoss = [huber_rad]() -> ceres::LossFunction* {
    return huber_rad > 0.0 ? new ceres::HuberLoss(huber_rad) : nullptr;
  };
  std::vector<CalibrationSample> samples;
  samples.reserve(all.size() / static_cast<std::size_t>(opt.stride) + 1);
  for (std::size_t i = 0; i < smooth.size(); i += static_cast<std::size_t>(opt.stride)) samples.push_back(smooth[i]);
  if (samples.size() < 20) return "need at least 20 samples over the range of motion, got " + std::to_string(samples.size());
  const auto lo = ps::toArray(opt.lower);
  const auto hi = ps::toArray(opt.upper);
  const auto p0 = ps::toArray(opt.initial);
  for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
    if (!(lo[i] < hi[i])) return std::string("bounds of ") + ps::kSubjectParamNames[i] + " are empty";
    if (!(p0[i] >= lo[i] && p0[i] <= hi[i])) {
      return std::string("initial ") + ps::kSubjectParamNames[i] + " is outside its bounds";
    }
  }

  // Eq 12 from one redundant angle has local minima (docs/sea-model.md §Parameter estimation): a multistart.
  // Phase 1: P0 and `restarts` points of a Halton sequence over the box, each solved on a thinned subset
  // (≈ 200 samples); then the valley scan and phase 2 (below).
  std::vector<std::array<double, ps::kNumSubjectParams>> starts{p0};
  static constexpr unsigned kPrimes[ps::kNumSubjectParams] = {2, 3, 5, 7, 11, 13, 17};
  for (int k = 1; k <= opt.restarts; ++k) {
    std::array<double, ps::kNumSubjectParams> s{};
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
      double f = 1.0;
      double h = 0.0;
      for (unsigned n = static_cast<unsigned>(k); n > 0; n /= kPrimes[i]) {
        f /= kPrimes[i];
        h += f * static_cast<double>(n % kPrimes[i]);
      }
      s[i] = lo[i] + (0.05 + 0.9 * h) * (hi[i] - lo[i]);
    }
    starts.push_back(s);
  }
  std::vector<CalibrationSample> thin;
  const std::size_t thin_stride = std::max<std::size_t>(1, samples.size() / 200);
  for (std::size_t i = 0; i < samples.size(); i += thin_stride) thin.push_back(samples[i]);

  // Phase 1 and the valley scan fit eq 12 as printed (θ1r, θ6r taken as exact), forward differences, on the thinned
  // samples: they only have to land in the right basin.
  using Params = std::array<double, ps::kNumSubjectParams>;
  // `frozen` ≥ 0 holds that parameter at its start value (the valley scan below).
  auto solve = [&](const std::vector<CalibrationSample>& data, Params& p, int max_iterations,
                   ceres::Solver::Summary& summary, int frozen = -1) {
    ceres::Problem problem;
    for (const CalibrationSample& s : data) {
      problem.AddResidualBlock(
          new ceres::NumericDiffCostFunction<RedundantResidual, ceres::FORWARD, 2, ps::kNumSubjectParams>(
              new RedundantResidual{s, opt.fixed, opt.both_branches}),
          robustLoss(), p.data());
    }
    if (frozen >= 0) {
      problem.SetManifold(p.data(), new ceres::SubsetManifold(ps::kNumSubjectParams, {frozen}));
    }
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
      if (static_cast<int>(i) == frozen) continue;
      problem.SetParameterLowerBound(p.data(), static_cast<int>(i), lo[i]);
      problem.SetParameterUpperBound(p.data(), static_cast<int>(i), hi[i]);
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = max_iterations;
    so.function_tolerance = 1e-12;
    so.gradient_tolerance = 1e-14;
    so.parameter_tolerance = 1e-12;
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    so.num_threads = 1;
    ceres::Solve(so, &problem, &summary);
  };
  // Eq 12 with errors in variables (OdrResidual): returns the final cost ½Σr², P updated.
  auto solveOdr = [&](const std::vector<CalibrationSample>& data, Params& p, int max_iterations,
                      ceres::Solver::Summary& summary) {
    std::vector<std::array<double, 2>> z(data.size());
    ceres::Problem problem;
    for (std::size_t k = 0; k < data.size(); ++k) {
      z[k] = {data[k].theta1r_rad, data[k].theta6r_rad};
      problem.AddResidualBlock(
          new ceres::NumericDiffCostFunction<OdrResidual, ceres::CENTRAL, 4, ps::kNumSubjectParams, 2>(
              new OdrResidual{data[k], opt.fixed, opt.both_branches}),
          robustLoss(), p.data(), z[k].data());
    }
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
      problem.SetParameterLowerBound(p.data(), static_cast<int>(i), lo[i]);
      problem.SetParameterUpperBound(p.data(), static_cast<int>(i), hi[i]);
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_SCHUR;
    so.max_num_iterations = max_iterations;
    so.function_tolerance = 1e-10;
    so.gradient_tolerance = 1e-14;
    so.parameter_tolerance = 1e-9;  // relative: ≈ 0.04 µm on a 40 mm length
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    so.num_threads = 1;
    ceres::Solve(so, &problem, &summary);
    return summary.final_cost;
  };
  // restarts = 0 and valley_steps = 0: a local refinement from P0 only (phase 2 alone).
  const bool local_only = opt.restarts == 0 && opt.valley_steps == 0;
  std::vector<std::pair<double, Params>> phase1;
  for (auto p : starts) {
    ceres::Solver::Summary summary;
    if (!local_only) solve(thin, p, std::min(opt.max_iterations, 40), summary);
    phase1.push_back({summary.final_cost, p});
  }
  std::sort(phase1.begin(), phase1.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

  // Valley scan. Eq 12 sees the MCP chain only through x3(θ1r) over a ≈ 36° arc, so (x_A, y_A, l_BC) has one
  // weakly observed direction, dominated by l_BC (docs/sea-model.md §Identifiability), and along it the cost is
  // rugged: samples near a chain's dead point open and close as P moves, and the solver stalls on either side of
  // the minimum. Starting from the best phase-1 point, l_BC is stepped across its bounds (held fixed, the other
  // six solved on the thinned data, each step starting from the previous one: continuation along the valley).
  std::vector<std::pair<double, Params>> candidates = phase1;
  if (opt.valley_steps > 0 && !phase1.empty()) {
    constexpr int kScan = 2;  // l_BC
    const Params seed = phase1.front().second;
    const double step = (hi[kScan] - lo[kScan]) / opt.valley_steps;
    for (int dir : {+1, -1}) {
      Params p = seed;
      for (int k = 1; k <= opt.valley_steps; ++k) {
        const double v = seed[kScan] + dir * k * step;
        if (v < lo[kScan] || v > hi[kScan]) break;
        p[kScan] = v;
        ceres::Solver::Summary summary;
        solve(thin, p, std::min(opt.max_iterations, 40), summary, kScan);
        candidates.push_back({summary.final_cost, p});
      }
    }
  }

  // Phase 2: the `polished` cheapest candidates refitted with errors in variables (OdrResidual) on the thinned
  // samples and ranked by that cost; the best `refined` distinct ones (≥ 0.3 mm apart) refitted on all samples;
  // the lowest cost wins. (Replaces effective-variance weights 1/√(1 + g1² + g6²): minimised directly they were
  // gamed — a wrong P that puts recorded samples near a dead point, where g → ∞, down-weights them and won
  // with a higher unweighted residual; docs/sea-model.md.)
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (candidates.size() > static_cast<std::size_t>(opt.polished)) candidates.resize(static_cast<std::size_t>(opt.polished));
  std::vector<std::pair<double, Params>> ranked;
  for (const auto& candidate : candidates) {
    Params c = candidate.second;
    ceres::Solver::Summary summary;
    const double cost = solveOdr(thin, c, std::min(opt.max_iterations, 30), summary);
    ranked.push_back({cost, c});
  }
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Params> chosen;
  for (const auto& c : ranked) {
    if (chosen.size() >= static_cast<std::size_t>(opt.refined)) break;
    bool distinct = true;
    for (const Params& q : chosen) {
      double d = 0.0;
      for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) d = std::fmax(d, std::fabs(c.second[i] - q[i]));
      distinct = distinct && d > 3e-4;
    }
    if (distinct) chosen.push_back(c.second);
  }
  double best_cost = std::numeric_limits<double>::infinity();
  Params best = p0;
  ceres::Solver::Summary best_summary;
  for (Params p : chosen) {
    ceres::Solver::Summary summary;
    const double cost = solveOdr(samples, p, opt.max_iterations, summary);
    if (cost < best_cost) {
      best_cost = cost;
      best = p;
      best_summary = summary;
    }
  }

  result.estimate = ps::fromArray(best);
  result.errors_in_variables_rms_rad = std::sqrt(2.0 * best_cost / (3.0 * static_cast<double>(samples.size())));
  result.noise_rad = noise_rad;
  result.fit_to_noise = noise_rad > 0.0 ? result.errors_in_variables_rms_rad / (noise_rad / std::sqrt(3.0)) : 0.0;
  const Stats before = residualStats(samples, opt.initial, opt.fixed);
  const Stats after = residualStats(samples, result.estimate, opt.fixed);
  result.initial_rms_rad = before.rms;
  result.final_rms_rad = after.rms;
  result.max_abs_residual_rad = after.max_abs;
  result.least_squares_samples = after.least_squares;
  result.samples_used = samples.size();
  result.iterations = static_cast<int>(best_summary.iterations.size());
  result.converged = best_summary.termination_type == ceres::CONVERGENCE;
  result.solver_report = best_summary.BriefReport();
  for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
    const double tol = 1e-6 * (hi[i] - lo[i]);
    result.at_bound[i] = best[i] <= lo[i] + tol || best[i] >= hi[i] - tol;
  }
  return {};
}

double redundantResidualRms(const std::vector<CalibrationSample>& samples, const SubjectParams& p,
                            const FixedGeometry& fixed) {
  return residualStats(samples, p, fixed).rms;
}

std::string readCalibrationCsv(const std::string& path, std::vector<CalibrationSample>& samples) {
  samples.clear();
  std::ifstream in(path);
  if (!in) return "cannot read " + path;
  std::string line;
  if (!std::getline(in, line)) return path + ": empty file (no header row)";
  std::vector<std::string> names;
  {
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) {
      while (!cell.empty() && (cell.back() == '\r' || cell.back() == ' ')) cell.pop_back();
      names.push_back(cell);
    }
  }
  // Column names of phalanx run --record (named since issue 23; sample<i> before), or θ names.
  auto find = [&](const char* a, const char* b, const char* named) -> int {
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] == a || names[i] == b || names[i] == named) return static_cast<int>(i);
    }
    return -1;
  };
  const int c1 = find("sample0", "theta1r_rad", "sensor0_exo_mcp_rad");
  const int c6 = find("sample1", "theta6r_rad", "sensor1_exo_pip_rad");
  const int c5 = find("sample2", "theta7r_rad", "sensor2_rad");
  if (c1 < 0 || c6 < 0 || c5 < 0) {
    return path + ": header needs columns sensor0_exo_mcp_rad,sensor1_exo_pip_rad,sensor2_rad (phalanx run --record "
                  "of sea_finger; sample0,sample1,sample2 in older recordings) or theta1r_rad,theta6r_rad,theta7r_rad";
  }
  std::size_t line_no = 1;
  std::vector<double> v(names.size());
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r") continue;
    std::stringstream ss(line);
    std::string cell;
    std::size_t col = 0;
    bool ok = true;
    while (std::getline(ss, cell, ',') && col < names.size()) {
      if (static_cast<int>(col) == c1 || static_cast<int>(col) == c6 || static_cast<int>(col) == c5) {
        char* end = nullptr;
        const double x = std::strtod(cell.c_str(), &end);
        if (end == cell.c_str()) {
          return path + ":" + std::to_string(line_no) + ": column " + names[col] + ": '" + cell + "' is not a number";
        }
        v[col] = x;
        if (!std::isfinite(x)) ok = false;
      }
      ++col;
    }
    if (col <= static_cast<std::size_t>(std::max(c1, std::max(c5, c6)))) {
      return path + ":" + std::to_string(line_no) + ": row has " + std::to_string(col) + " columns, header has " +
             std::to_string(names.size());
    }
    if (ok) samples.push_back({v[static_cast<std::size_t>(c1)], v[static_cast<std::size_t>(c6)], v[static_cast<std::size_t>(c5)]});
  }
  return {};
}

namespace {
constexpr std::array<const char*, 7> kFixedNames{"l_CE_m", "l_EF_m", "l_HI_m", "x_K_m", "y_K_m", "l_KL_m", "l_LM_m"};
std::array<double*, 7> fixedRefs(FixedGeometry& f) {
  return {&f.l_CE_m, &f.l_EF_m, &f.l_HI_m, &f.x_K_m, &f.y_K_m, &f.l_KL_m, &f.l_LM_m};
}
}  // namespace

std::string loadSubjectYaml(const std::string& path, SubjectParams& subject, FixedGeometry& fixed) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return path + ": " + e.what();
  }
  if (std::string dup = findDuplicateKey(root); !dup.empty()) return path + ": " + dup;
  const YAML::Node s = root["sea_subject"];
  if (!s) return path + ": no 'sea_subject' mapping";
  if (!s.IsMap()) return path + ": sea_subject: must be a mapping";
  auto p = ps::toArray(subject);
  auto refs = fixedRefs(fixed);
  for (const auto& kv : s) {
    const std::string key = kv.first.as<std::string>();
    double value = 0.0;
    try {
      value = kv.second.as<double>();
    } catch (const YAML::Exception&) {
      return path + ": sea_subject." + key + ": not a number";
    }
    if (!std::isfinite(value)) return path + ": sea_subject." + key + ": not finite";
    bool known = false;
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
      if (key == ps::kSubjectParamNames[i]) {
        if (i >= 2 && !(value > 0.0)) return path + ": sea_subject." + key + ": must be > 0";  // lengths
        p[i] = value;
        known = true;
      }
    }
    for (std::size_t i = 0; i < kFixedNames.size(); ++i) {
      if (key == kFixedNames[i]) {
        if (!(value > 0.0) && key != "x_K_m" && key != "y_K_m") return path + ": sea_subject." + key + ": must be > 0";
        *refs[i] = value;
        known = true;
      }
    }
    if (!known) return path + ": sea_subject." + key + ": unknown key";
  }
  subject = ps::fromArray(p);
  return {};
}

std::string writeSubjectYaml(const std::string& path, const CalibrationResult& r, const FixedGeometry& fixed_in,
                             const std::string& source) {
  YAML::Node root;
  {
    std::ifstream probe(path);
    if (probe) {
      try {
        root = YAML::LoadFile(path);
      } catch (const YAML::Exception& e) {
        return path + ": " + e.what();
      }
      // The file is rewritten with its other keys kept: a repeated one would be written twice again.
      if (std::string dup = findDuplicateKey(root); !dup.empty()) return path + ": " + dup;
    }
  }
  if (!root.IsMap()) root = YAML::Node(YAML::NodeType::Map);
  YAML::Node s(YAML::NodeType::Map);
  const auto p = ps::toArray(r.estimate);
  for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) s[ps::kSubjectParamNames[i]] = p[i];
  FixedGeometry fixed = fixed_in;
  const auto refs = fixedRefs(fixed);
  for (std::size_t i = 0; i < kFixedNames.size(); ++i) s[kFixedNames[i]] = *refs[i];
  root["sea_subject"] = s;
  YAML::Node c(YAML::NodeType::Map);
  c["source"] = source;
  c["samples"] = r.samples_used;
  c["rms_residual_rad"] = r.final_rms_rad;
  c["max_abs_residual_rad"] = r.max_abs_residual_rad;
  c["initial_rms_residual_rad"] = r.initial_rms_rad;
  c["errors_in_variables_rms_rad"] = r.errors_in_variables_rms_rad;
  c["noise_rad"] = r.noise_rad;
  c["fit_to_noise"] = r.fit_to_noise;
  c["converged"] = r.converged;
  root["calibration"] = c;
  YAML::Emitter out;
  out << root;
  std::ofstream f(path);
  if (!f) return "cannot write " + path;
  f << "# SEA finger exoskeleton subject parameters (docs/sea-model.md), written by phalanx sea-calibrate\n";
  f << out.c_str() << "\n";
  if (!f) return "cannot write " + path;
  return {};
}

int seaCalibrateCommand(const std::string& recording_csv, const std::string& subject_yaml, bool json, int stride,
                        int smooth_samples) {
  std::vector<CalibrationSample> samples;
  if (std::string err = readCalibrationCsv(recording_csv, samples); !err.empty()) {
    std::fprintf(stderr, "phalanx sea-calibrate: error: %s\n", err.c_str());
    return 2;
  }
  CalibrationOptions opt;
  opt.stride = stride;
  opt.smooth_samples = smooth_samples;
  bool from_subject = false;
  if (std::ifstream(subject_yaml).good()) {
    SubjectParams start = opt.initial;
    if (std::string err = loadSubjectYaml(subject_yaml, start, opt.fixed); !err.empty()) {
      std::fprintf(stderr, "phalanx sea-calibrate: error: %s\n", err.c_str());
      return 2;
    }
    const auto s = ps::toArray(start);
    const auto lo = ps::toArray(opt.lower);
    const auto hi = ps::toArray(opt.upper);
    bool inside = true;
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) inside = inside && s[i] >= lo[i] && s[i] <= hi[i];
    if (inside) {
      opt.initial = start;
      from_subject = true;
    }
  }
  CalibrationResult r;
  if (std::string err = calibrate(samples, opt, r); !err.empty()) {
    std::fprintf(stderr, "phalanx sea-calibrate: error: %s: %s\n", recording_csv.c_str(), err.c_str());
    return 2;
  }
  if (std::string err = writeSubjectYaml(subject_yaml, r, opt.fixed, recording_csv); !err.empty()) {
    std::fprintf(stderr, "phalanx sea-calibrate: error: %s\n", err.c_str());
    return 2;
  }
  const auto p0 = ps::toArray(opt.initial);
  const auto pe = ps::toArray(r.estimate);
  const auto lo = ps::toArray(opt.lower);
  const auto hi = ps::toArray(opt.upper);
  nlohmann::json out;
  out["recording"] = recording_csv;
  out["subject"] = subject_yaml;
  out["samples"] = r.samples_used;
  out["initial_from"] = from_subject ? "subject file" : "Table 4 P0";
  for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
    out["parameters"][ps::kSubjectParamNames[i]] = {
        {"initial", p0[i]}, {"estimate", pe[i]}, {"lower", lo[i]}, {"upper", hi[i]}, {"at_bound", r.at_bound[i]}};
  }
  out["rms_residual_rad"] = r.final_rms_rad;
  out["max_abs_residual_rad"] = r.max_abs_residual_rad;
  out["initial_rms_residual_rad"] = r.initial_rms_rad;
  out["errors_in_variables_rms_rad"] = r.errors_in_variables_rms_rad;
  out["noise_rad"] = r.noise_rad;
  out["fit_to_noise"] = r.fit_to_noise;
  out["least_squares_samples"] = r.least_squares_samples;
  out["converged"] = r.converged;
  out["iterations"] = r.iterations;
  out["solver"] = r.solver_report;
  if (json) {
    std::cout << out.dump(2) << std::endl;
    return 0;
  }
  std::printf("sea-calibrate: %zu samples from %s (start: %s)\n", r.samples_used, recording_csv.c_str(),
              from_subject ? "subject file" : "Table 4 P0");
  std::printf("  %-7s %9s %9s   [%s, %s] (mm)\n", "param", "initial", "estimate", "lower", "upper");
  for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
    std::printf("  %-7s %9.2f %9.2f   [%.1f, %.1f]%s\n", ps::kSubjectParamNames[i], p0[i] * 1e3, pe[i] * 1e3,
                lo[i] * 1e3, hi[i] * 1e3, r.at_bound[i] ? "  AT BOUND" : "");
  }
  std::printf("  redundant-sensor residual: RMS %.4f deg (initial %.3f deg), max %.4f deg; %s\n",
              r.final_rms_rad * 57.2957795, r.initial_rms_rad * 57.2957795, r.max_abs_residual_rad * 57.2957795,
              r.converged ? "converged" : "NOT converged");
  std::printf("  sensor noise estimated from the recording: %.4f deg per fitted sample; fit/noise %.2f\n",
              r.noise_rad * 57.2957795, r.fit_to_noise);
  if (r.fit_to_noise > 1.5) {
    std::printf("  warning: the recording does not fit the model to its noise (fit/noise > 1.5): did the mechanism pass "
                "a PIP dead point, or is a sensor offset? The estimate is not trustworthy\n");
  }
  if (r.least_squares_samples > 0) {
    std::printf("  warning: %zu samples needed the least-squares fallback at the estimate\n", r.least_squares_samples);
  }
  std::printf("  written to %s\n", subject_yaml.c_str());
  return 0;
}

}  // namespace phalanx::host::sea
