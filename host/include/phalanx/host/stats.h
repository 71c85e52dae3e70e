#pragma once
/// Loop statistics: fixed-bin latency histograms (no allocation after construction) and percentiles.
#include <cstdint>
#include <vector>

namespace phalanx::host {

/// Histogram of microsecond values with 1 µs bins up to max_us; larger values land in an overflow bin
/// (and are kept as the max).
class Histogram {
 public:
  explicit Histogram(uint32_t max_us = 20000) : bins_(max_us + 1, 0) {}
  void add(double value_us);
  uint64_t count() const { return count_; }
  double mean() const { return count_ ? sum_ / static_cast<double>(count_) : 0.0; }
  double max() const { return max_; }
  double min() const { return count_ ? min_ : 0.0; }
  /// p in [0, 1]; the upper edge of the bin holding that quantile (1 µs resolution).
  double percentile(double p) const;

 private:
  std::vector<uint64_t> bins_;
  uint64_t overflow_ = 0;
  uint64_t count_ = 0;
  double sum_ = 0.0;
  double max_ = 0.0;
  double min_ = 1e300;
};

}  // namespace phalanx::host
