#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/host/metrics.h"

using phalanx::host::pearson;
using phalanx::host::rmse;

TEST(Metrics, PearsonIsOneForAnAffineCopyAndMinusOneForAMirror) {
  std::vector<double> a, b, c;
  for (int i = 0; i < 100; ++i) {
    a.push_back(std::sin(0.1 * i));
    b.push_back(3.0 * std::sin(0.1 * i) + 7.0);
    c.push_back(-std::sin(0.1 * i));
  }
  EXPECT_NEAR(pearson(a, b), 1.0, 1e-12);
  EXPECT_NEAR(pearson(a, c), -1.0, 1e-12);
}

TEST(Metrics, PearsonMatchesAHandComputedValue) {
  // x = 1..5, y = 2,4,5,4,5: r = 6 / sqrt(10 · 6) = 0.7745967
  EXPECT_NEAR(pearson({1, 2, 3, 4, 5}, {2, 4, 5, 4, 5}), 0.7745967, 1e-6);
}

TEST(Metrics, PearsonOfAConstantSeriesIsUndefined) { EXPECT_TRUE(std::isnan(pearson({1, 1, 1}, {1, 2, 3}))); }

TEST(Metrics, RmseOfKnownSeries) { EXPECT_NEAR(rmse({0, 0, 0, 0}, {1, -1, 1, -1}), 1.0, 1e-12); }
