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

namespace phalanx::host::sea {

namespace ps = phalanx::sea;

namespace {

/// y_k − y_m,k(P) (eq 12), wrapped to (−π, π].
struct RedundantResidual {
  CalibrationSample s;
  FixedGeometry fixed;
  bool operator()(const double* p, double* r) const {
    const SubjectParams sp{p[0], p[1], p[2], p[3], p[4], p[5], p[6]};
    const double y_m = ps::predictRedundant(sp, fixed, s.theta1r_rad, s.theta6r_rad);
    r[0] = std::remainder(s.theta7r_rad - y_m, 2.0 * M_PI);
    return std::isfinite(r[0]);
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

bool finite(const CalibrationSample& s) {
  return std::isfinite(s.theta1r_rad) && std::isfinite(s.theta6r_rad) && std::isfinite(s.theta7r_rad);
}

}  // namespace

std::string calibrate(const std::vector<CalibrationSample>& all, const CalibrationOptions& opt,
                      CalibrationResult& result) {
  result = CalibrationResult{};
  if (opt.stride < 1) return "stride must be ≥ 1";
  if (opt.max_iterations < 1) return "max_iterations must be ≥ 1";
  std::vector<CalibrationSample> samples;
  samples.reserve(all.size() / static_cast<std::size_t>(opt.stride) + 1);
  for (std::size_t i = 0; i < all.size(); i += static_cast<std::size_t>(opt.stride)) {
    if (!finite(all[i])) return "sample " + std::to_string(i) + " is not finite";
    samples.push_back(all[i]);
  }
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
  // (≈ 200 samples); phase 2: the best three refined on all samples.
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

  auto solve = [&](const std::vector<CalibrationSample>& data, std::array<double, ps::kNumSubjectParams>& p,
                   int max_iterations, ceres::Solver::Summary& summary) {
    ceres::Problem problem;
    for (const CalibrationSample& s : data) {
      problem.AddResidualBlock(
          new ceres::NumericDiffCostFunction<RedundantResidual, ceres::CENTRAL, 1, ps::kNumSubjectParams>(
              new RedundantResidual{s, opt.fixed}),
          nullptr, p.data());
    }
    for (std::size_t i = 0; i < ps::kNumSubjectParams; ++i) {
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

  std::vector<std::pair<double, std::array<double, ps::kNumSubjectParams>>> phase1;
  for (auto p : starts) {
    ceres::Solver::Summary summary;
    solve(thin, p, std::min(opt.max_iterations, 50), summary);
    phase1.push_back({summary.final_cost, p});
  }
  std::sort(phase1.begin(), phase1.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

  double best_cost = std::numeric_limits<double>::infinity();
  std::array<double, ps::kNumSubjectParams> best = p0;
  ceres::Solver::Summary best_summary;
  for (std::size_t k = 0; k < std::min<std::size_t>(3, phase1.size()); ++k) {
    std::array<double, ps::kNumSubjectParams> p = phase1[k].second;
    ceres::Solver::Summary summary;
    solve(samples, p, opt.max_iterations, summary);
    if (summary.final_cost < best_cost) {
      best_cost = summary.final_cost;
      best = p;
      best_summary = summary;
    }
  }

  result.estimate = ps::fromArray(best);
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
  auto find = [&](const char* a, const char* b) -> int {
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] == a || names[i] == b) return static_cast<int>(i);
    }
    return -1;
  };
  const int c1 = find("sample0", "theta1r_rad");
  const int c6 = find("sample1", "theta6r_rad");
  const int c5 = find("sample2", "theta7r_rad");
  if (c1 < 0 || c6 < 0 || c5 < 0) {
    return path + ": header needs columns sample0,sample1,sample2 (phalanx run --record of sea_finger) or "
                  "theta1r_rad,theta6r_rad,theta7r_rad";
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
  c["converged"] = r.converged;
  root["calibration"] = c;
  YAML::Emitter out;
  out.SetDoublePrecision(6);
  out << root;
  std::ofstream f(path);
  if (!f) return "cannot write " + path;
  f << "# SEA finger exoskeleton subject parameters (docs/sea-model.md), written by phalanx sea-calibrate\n";
  f << out.c_str() << "\n";
  if (!f) return "cannot write " + path;
  return {};
}

int seaCalibrateCommand(const std::string& recording_csv, const std::string& subject_yaml, bool json, int stride) {
  std::vector<CalibrationSample> samples;
  if (std::string err = readCalibrationCsv(recording_csv, samples); !err.empty()) {
    std::fprintf(stderr, "phalanx sea-calibrate: error: %s\n", err.c_str());
    return 2;
  }
  CalibrationOptions opt;
  opt.stride = stride;
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
  if (r.least_squares_samples > 0) {
    std::printf("  warning: %zu samples needed the least-squares fallback at the estimate\n", r.least_squares_samples);
  }
  std::printf("  written to %s\n", subject_yaml.c_str());
  return 0;
}

}  // namespace phalanx::host::sea
