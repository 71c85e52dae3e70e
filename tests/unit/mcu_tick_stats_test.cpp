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
