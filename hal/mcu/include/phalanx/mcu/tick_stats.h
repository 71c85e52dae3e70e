#pragma once
/// Duration statistics of the control tick for the board diagnostics: count, worst case and a histogram
/// median, in whatever unit the board measures (instructions under QEMU -icount, CPU cycles on silicon).
/// Fixed memory (kBins 16-bit bins), O(1) per sample, O(kBins) per median query (only on a ParamGet).
/// Freestanding; compiles on the host for the unit tests.
#include <cstddef>
#include <cstdint>

namespace phalanx::mcu {

template <size_t kBins, uint32_t kBinWidth>
class TickStats {
  static_assert(kBins >= 2 && kBinWidth >= 1, "histogram shape");

 public:
  static constexpr uint32_t binWidth() { return kBinWidth; }
  /// Largest value the histogram resolves; longer samples land in the last bin (worst() stays exact).
  static constexpr uint32_t range() { return static_cast<uint32_t>(kBins) * kBinWidth; }

  void add(uint32_t value) {
    ++count_;
    if (value > worst_) worst_ = value;
    if (count_ == 1 || value < best_) best_ = value;
    size_t bin = value / kBinWidth;
    if (bin >= kBins) bin = kBins - 1;
    if (hist_[bin] != 0xFFFFu) ++hist_[bin];
    else saturated_ = true;
  }

  void reset() { *this = TickStats{}; }

  uint32_t count() const { return count_; }
  uint32_t worst() const { return worst_; }
  uint32_t best() const { return count_ == 0 ? 0 : best_; }
  /// True once a bin reached 65535 samples; the median is then approximate (over a minute at 1 kHz in one bin).
  bool saturated() const { return saturated_; }

  /// Value below which a fraction q of the samples lie, to one bin width (bin centre, clamped to [best, worst]).
  uint32_t quantile(float q) const {
    uint32_t total = 0;
    for (size_t i = 0; i < kBins; ++i) total += hist_[i];
    if (total == 0) return 0;
    if (q < 0.0f) q = 0.0f;
    if (q > 1.0f) q = 1.0f;
    const auto rank = static_cast<uint32_t>(q * static_cast<float>(total - 1u));
    uint32_t seen = 0;
    for (size_t i = 0; i < kBins; ++i) {
      seen += hist_[i];
      if (seen > rank) {
        uint32_t v = static_cast<uint32_t>(i) * kBinWidth + kBinWidth / 2u;
        if (v > worst_) v = worst_;
        if (v < best_) v = best_;
        return v;
      }
    }
    return worst_;
  }
  uint32_t median() const { return quantile(0.5f); }

 private:
  uint16_t hist_[kBins] = {};
  uint32_t count_ = 0;
  uint32_t worst_ = 0;
  uint32_t best_ = 0;
  bool saturated_ = false;
};

}  // namespace phalanx::mcu
