#include "phalanx/host/therapy/repeatability.h"

#include <algorithm>
#include <cmath>

namespace phalanx::host::therapy {

double mdc95(double sd, double icc) {
  const double sem = sd * std::sqrt(1.0 - std::clamp(icc, 0.0, 1.0));
  return 1.96 * std::sqrt(2.0) * sem;
}

namespace {

std::string checkShape(const std::vector<std::vector<double>>& y) {
  if (y.size() < 2) return "repeatability: need at least 2 subjects";
  const std::size_t k = y[0].size();
  if (k < 2) return "repeatability: need at least 2 sessions per subject";
  for (std::size_t i = 0; i < y.size(); ++i) {
    if (y[i].size() != k) return "repeatability: subject " + std::to_string(i) + " has " + std::to_string(y[i].size()) +
                                 " sessions, subject 0 has " + std::to_string(k);
    for (double v : y[i]) {
      if (!std::isfinite(v)) return "repeatability: subject " + std::to_string(i) + " has a non-finite value";
    }
  }
  return "";
}

}  // namespace

std::string computeRepeatability(const std::vector<std::vector<double>>& y, Repeatability& out) {
  if (std::string e = checkShape(y); !e.empty()) return e;
  const std::size_t n = y.size(), k = y[0].size();
  const double dn = static_cast<double>(n), dk = static_cast<double>(k);
  double grand = 0.0;
  std::vector<double> row(n, 0.0), col(k, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < k; ++j) {
      row[i] += y[i][j] / dk;
      col[j] += y[i][j] / dn;
      grand += y[i][j] / (dn * dk);
    }
  }
  double ss_total = 0.0, ss_rows = 0.0, ss_cols = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < k; ++j) ss_total += (y[i][j] - grand) * (y[i][j] - grand);
    ss_rows += dk * (row[i] - grand) * (row[i] - grand);
  }
  for (std::size_t j = 0; j < k; ++j) ss_cols += dn * (col[j] - grand) * (col[j] - grand);
  const double ss_error = std::max(0.0, ss_total - ss_rows - ss_cols);
  Repeatability r;
  r.subjects = n;
  r.sessions = k;
  r.ms_rows = ss_rows / (dn - 1.0);
  r.ms_cols = ss_cols / (dk - 1.0);
  r.ms_error = ss_error / ((dn - 1.0) * (dk - 1.0));
  const double denom = r.ms_rows + (dk - 1.0) * r.ms_error + dk * (r.ms_cols - r.ms_error) / dn;
  if (!(denom > 0.0)) return "repeatability: no spread at all (every value the same): the ICC is undefined";
  r.icc = (r.ms_rows - r.ms_error) / denom;
  r.sd = std::sqrt(ss_total / (dn * dk - 1.0));
  r.sem = r.sd * std::sqrt(1.0 - std::clamp(r.icc, 0.0, 1.0));
  r.mdc95 = mdc95(r.sd, r.icc);
  out = r;
  return "";
}

}  // namespace phalanx::host::therapy
