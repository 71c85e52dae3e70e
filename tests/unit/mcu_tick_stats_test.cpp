// Tick-duration statistics reported by the MCU boards' diagnostics (hal/mcu/include/phalanx/mcu/tick_stats.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "../../hal/mcu/include/phalanx/mcu/tick_stats.h"

using Stats = phalanx::mcu::TickStats<1024, 16>;

TEST(McuTickStats, WorstIsExactAndMedianWithinOneBinOfTheSortedMedian) {
  Stats s;
  std::mt19937 rng(5);
  std::normal_distribution<double> d(9000.0, 400.0);
  std::vector<uint32_t> v;
  for (int i = 0; i < 5001; ++i) {
    const auto x = static_cast<uint32_t>(std::max(0.0, d(rng)));
    v.push_back(x);
    s.add(x);
  }
  std::sort(v.begin(), v.end());
  EXPECT_EQ(s.worst(), v.back());
  EXPECT_EQ(s.best(), v.front());
  EXPECT_EQ(s.count(), 5001u);
  EXPECT_NEAR(static_cast<double>(s.median()), static_cast<double>(v[2500]), 16.0);
  EXPECT_NEAR(static_cast<double>(s.quantile(0.99f)), static_cast<double>(v[4950]), 16.0);
}

TEST(McuTickStats, SamplesBeyondTheRangeLandInTheLastBinButKeepTheExactWorst) {
  Stats s;
  s.add(100);
  s.add(Stats::range() * 3);
  EXPECT_EQ(s.worst(), Stats::range() * 3);
  EXPECT_LE(s.quantile(1.0f), s.worst());
}

TEST(McuTickStats, EmptyStatsReportZeroAndResetForgetsEverything) {
  Stats s;
  EXPECT_EQ(s.median(), 0u);
  s.add(42);
  s.reset();
  EXPECT_EQ(s.count(), 0u);
  EXPECT_EQ(s.worst(), 0u);
  EXPECT_EQ(s.median(), 0u);
}

TEST(McuTickStats, EveryQuantileIsTheBinOfTheSortedSampleAtItsRankWalkingFromEitherEnd) {
  // Reference: sort the samples, take the one at rank floor(q·(n−1)), report its bin's centre clamped to
  // [best, worst]. Quantiles below and above 0.5 are found by walks from opposite ends of the histogram.
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    phalanx::mcu::TickStats<256, 16> st;
    std::vector<uint32_t> v;
    const int n = 1 + static_cast<int>(rng() % 3000);
    std::uniform_int_distribution<uint32_t> base(0, 1000), spike(0, 6000);
    for (int i = 0; i < n; ++i) {
      const uint32_t x = (rng() % 50 == 0) ? spike(rng) : 2000 + base(rng);  // a bulk and rare spikes (beyond range)
      v.push_back(x);
      st.add(x);
    }
    std::sort(v.begin(), v.end());
    for (float q : {0.0f, 0.01f, 0.25f, 0.49f, 0.5f, 0.51f, 0.75f, 0.9f, 0.99f, 1.0f}) {
      const auto rank = static_cast<size_t>(q * static_cast<float>(v.size() - 1));
      size_t bin = v[rank] / 16u;
      if (bin >= 256) bin = 255;
      uint32_t expected = static_cast<uint32_t>(bin) * 16u + 8u;
      expected = std::min(std::max(expected, v.front()), v.back());
      ASSERT_EQ(st.quantile(q), expected) << "trial " << trial << " q " << q << " n " << n;
    }
  }
}
