#pragma once
/// Metrics the papers report, over recorded series.
#include <vector>

namespace phalanx::host {

/// Pearson product-moment correlation r_P (000 Table 4). NaN if either series is constant or sizes differ.
double pearson(const std::vector<double>& a, const std::vector<double>& b);
/// Root mean square of (a − b).
double rmse(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace phalanx::host
