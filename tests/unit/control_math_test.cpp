// The firmware's own math on its 1 kHz path: control::sinCos (control/sincos.h) against the exact values
// (double), over every angle a device joint reaches and far beyond; control::minNum / maxNum (control/pid.h)
// against std::fmin / std::fmax, NaN and signed zeros included.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "phalanx/control/pid.h"
#include "phalanx/control/sincos.h"

namespace {

using phalanx::control::sinCos;

TEST(SinCos, WithinTwoAndAHalfTenMillionthsOfTheExactValues) {
  double worst = 0.0;
  float worst_x = 0.0f;
  // Every float step of 1e-4 rad over ±4π (all joint angles), then coarser out to ±1e4.
  for (double x = -4.0 * M_PI; x <= 4.0 * M_PI; x += 1e-4) {
    const float xf = static_cast<float>(x);
    const auto sc = sinCos(xf);
    const double e = std::fmax(std::fabs(static_cast<double>(sc.s) - std::sin(static_cast<double>(xf))),
                               std::fabs(static_cast<double>(sc.c) - std::cos(static_cast<double>(xf))));
    if (e > worst) worst = e, worst_x = xf;
  }
  EXPECT_LT(worst, 2.5e-7) << "at x = " << static_cast<double>(worst_x);
  for (double x = -1e4; x <= 1e4; x += 0.37) {
    const float xf = static_cast<float>(x);
    const auto sc = sinCos(xf);
    // Far out the float argument itself carries the error; the reduction adds at most a few ulp of k·π/2.
    EXPECT_NEAR(static_cast<double>(sc.s), std::sin(static_cast<double>(xf)), 2e-6) << static_cast<double>(xf);
    EXPECT_NEAR(static_cast<double>(sc.c), std::cos(static_cast<double>(xf)), 2e-6) << static_cast<double>(xf);
  }
}

TEST(SinCos, QuadrantEdgesAndSpecialValues) {
  for (int k = -8; k <= 8; ++k) {
    for (const double d : {-1e-6, 0.0, 1e-6}) {  // around each multiple of π/4 (the reduction's rounding edges)
      const float xf = static_cast<float>(k * M_PI / 4 + d);
      const auto sc = sinCos(xf);
      EXPECT_NEAR(static_cast<double>(sc.s), std::sin(static_cast<double>(xf)), 2.5e-7) << static_cast<double>(xf);
      EXPECT_NEAR(static_cast<double>(sc.c), std::cos(static_cast<double>(xf)), 2.5e-7) << static_cast<double>(xf);
    }
  }
  EXPECT_EQ(sinCos(0.0f).s, 0.0f);
  EXPECT_EQ(sinCos(0.0f).c, 1.0f);
  for (const float bad : {NAN, INFINITY, -INFINITY, 1.1e4f, -2e9f}) {
    EXPECT_TRUE(std::isnan(sinCos(bad).s)) << static_cast<double>(bad);
    EXPECT_TRUE(std::isnan(sinCos(bad).c)) << static_cast<double>(bad);
  }
}

TEST(MinMax, AsStdFminAndFmaxBitForBit) {
  const float values[] = {-INFINITY, -1e30f, -2.5f, -1.0f, -0.0f, 0.0f, 1e-40f, 1.0f, 2.5f, 1e30f, INFINITY, NAN};
  auto same = [](float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0 || (std::isnan(a) && std::isnan(b)); };
  for (const float a : values) {
    for (const float b : values) {
      EXPECT_TRUE(same(phalanx::control::minNum(a, b), std::fmin(a, b))) << static_cast<double>(a) << " " << static_cast<double>(b);
      EXPECT_TRUE(same(phalanx::control::maxNum(a, b), std::fmax(a, b))) << static_cast<double>(a) << " " << static_cast<double>(b);
    }
  }
}

}  // namespace
