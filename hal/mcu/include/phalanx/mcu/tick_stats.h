#pragma once
/// Duration statistics of the control tick for the board diagnostics: count, worst case and a histogram
/// median, in whatever unit the board measures (instructions under QEMU -icount, CPU cycles on silicon).
/// Fixed memory (kBins 16-bit bins), O(1) per sample. A quantile query (a ParamGet, answered inside the measured
/// tick) walks only the bins between the best or worst sample and the quantile: from the bottom for q ≤ 0.5, from
/// the top above (measured on the QEMU board: a p99 query cost ~10 000 instructions when it summed and walked all
/// 2048 bins, which made reading the statistics the most expensive tick of a session).
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
    if (hist_[bin] != 0xFFFFu) {
      ++hist_[bin];
      ++binned_;
    } else {
      saturated_ = true;
    }
  }

  void reset() { *this = TickStats{}; }

  uint32_t count() const { return count_; }
  uint32_t worst() const { return worst_; }
  uint32_t best() const { return count_ == 0 ? 0 : best_; }
  /// True once a bin reached 65535 samples; the median is then approximate (over a minute at 1 kHz in one bin).
  bool saturated() const { return saturated_; }

  /// Value below which a fraction q of the samples lie, to one bin width (bin centre, clamped to [best, worst]).
  uint32_t quantile(float q) const {
    const uint32_t total = binned_;  // = the sum of the bins (a saturated bin stops counting)
    if (total == 0) return 0;
    if (q < 0.0f) q = 0.0f;
    if (q > 1.0f) q = 1.0f;
    const auto rank = static_cast<uint32_t>(q * static_cast<float>(total - 1u));
    // The answer is the smallest bin i with (samples in bins ≤ i) > rank. Every sample lies in the bins from
    // best_'s to worst_'s, so the walk starts at one of them.
    const size_t bottom = binOf(best_), top = binOf(worst_);
    size_t found = top;
    if (rank < total / 2u) {
      uint32_t seen = 0;
      for (size_t i = bottom; i <= top; ++i) {
        seen += hist_[i];
        if (seen > rank) {
          found = i;
          break;
        }
      }
    } else {
      uint32_t at_or_above = 0;
      for (size_t i = top + 1u; i-- > bottom;) {
        at_or_above += hist_[i];
        if (total - at_or_above <= rank) {  // samples in bins < i do not exceed the rank: i is the answer
          found = i;
          break;
        }
      }
    }
    uint32_t v = static_cast<uint32_t>(found) * kBinWidth + kBinWidth / 2u;
    if (v > worst_) v = worst_;
    if (v < best_) v = best_;
    return v;
  }
  uint32_t median() const { return quantile(0.5f); }

 private:
  static size_t binOf(uint32_t value) {
    const size_t bin = value / kBinWidth;
    return bin >= kBins ? kBins - 1 : bin;
  }

  uint16_t hist_[kBins] = {};
  uint32_t binned_ = 0;
  uint32_t count_ = 0;
  uint32_t worst_ = 0;
  uint32_t best_ = 0;
  bool saturated_ = false;
};

}  // namespace phalanx::mcu
