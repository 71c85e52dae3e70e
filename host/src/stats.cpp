#include "phalanx/host/stats.h"

#include <algorithm>
#include <cmath>

namespace phalanx::host {

void Histogram::add(double value_us) {
  if (!std::isfinite(value_us)) return;
  const double v = std::max(0.0, value_us);
  const auto bin = static_cast<uint64_t>(v);
  if (bin < bins_.size()) {
    ++bins_[bin];
  } else {
    ++overflow_;
  }
  ++count_;
  sum_ += v;
  max_ = std::max(max_, v);
  min_ = std::min(min_, v);
}

double Histogram::percentile(double p) const {
  if (count_ == 0) return 0.0;
  const auto rank = static_cast<uint64_t>(std::ceil(std::clamp(p, 0.0, 1.0) * static_cast<double>(count_)));
  uint64_t seen = 0;
  for (size_t i = 0; i < bins_.size(); ++i) {
    seen += bins_[i];
    if (seen >= std::max<uint64_t>(rank, 1)) return static_cast<double>(i + 1);
  }
  return max_;
}

}  // namespace phalanx::host
