// Capstan friction of the glove tendons (phalanx/glove/capstan.h, seeds/000 eq 15–16, §4.2).
#include "phalanx/glove/capstan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace {

using namespace phalanx::glove;
using V = Vec3<double>;

constexpr double kPiD = 3.14159265358979323846;
constexpr double kDeg = kPiD / 180.0;

std::vector<V> alphaGrid(const CapstanModel<double>& c, int n) {
  std::vector<V> g;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const double s[3] = {double(i) / (n - 1), double(j) / (n - 1), double(k) / (n - 1)};
        V a{};
        for (std::size_t q = 0; q < 3; ++q) a[q] = c.alpha_min_rad[q] + s[q] * (c.alpha_max_rad[q] - c.alpha_min_rad[q]);
        g.push_back(a);
      }
  return g;
}

TEST(GloveCapstan, RatioMatchesTheCapstanEquationAtKnownFrictionAndWrap) {
  // Reference values evaluated independently (Python math.exp).
  EXPECT_NEAR(capstanRatio(kMuLubricated<double>, kPiD), 1.1811687455693065, 1e-15);            // 180°, lubricated
  EXPECT_NEAR(capstanRatio(kMuDry<double>, 315 * kDeg), 1.4146899192938396, 1e-15);              // 315°, dry
  EXPECT_NEAR(capstanRatio(kMuLubricated<double>, kPiD / 2), 1.0868158747319192, 1e-15);         // 90°
  EXPECT_DOUBLE_EQ(capstanRatio(kMuDry<double>, 0.0), 1.0);
  // §4.2 rig: lifting 1 kg over a 180° lubricated wrap needs 11.59 N at the load cell.
  EXPECT_NEAR(9.81 * capstanRatio(kMuLubricated<double>, kPiD), 11.587265394034898, 1e-12);
}

TEST(GloveCapstan, FrictionCoefficientsAreThePapersFits) {
  EXPECT_DOUBLE_EQ(kMuLubricated<double>, 0.0530);
  EXPECT_DOUBLE_EQ(kMuDry<double>, 0.0631);
  EXPECT_FLOAT_EQ(kMuLubricated<float>, 0.0530f);
}

TEST(GloveCapstan, WrapOfEachTendonSpansGammaCToGammaCPlusTheSumOfJointRanges) {
  const Model<double> m = defaultIndexModel<double>();
  const CapstanModel<double> c = makeCapstanModel(m.mech);
  double sum_var = 0;
  for (std::size_t q = 0; q < 3; ++q) sum_var += m.mech.alpha_max_rad[q] - m.mech.alpha_min_rad[q];
  EXPECT_NEAR(wrapAngle_rad(c, Tendon::kGrasp, m.mech.alpha_min_rad), c.gamma_c_rad, 1e-15);
  EXPECT_NEAR(wrapAngle_rad(c, Tendon::kGrasp, m.mech.alpha_max_rad), c.gamma_c_rad + sum_var, 1e-12);
  EXPECT_NEAR(wrapAngle_rad(c, Tendon::kRelease, m.mech.alpha_max_rad), c.gamma_c_rad, 1e-15);
  EXPECT_NEAR(wrapAngle_rad(c, Tendon::kRelease, m.mech.alpha_min_rad), c.gamma_c_rad + sum_var, 1e-12);
  // Anywhere in the range the two tendons' variable wraps are complementary (eq 16, Δγ_i ≤ α_i,var).
  for (const V& a : alphaGrid(c, 5)) {
    EXPECT_NEAR(wrapAngle_rad(c, Tendon::kGrasp, a) + wrapAngle_rad(c, Tendon::kRelease, a),
                2 * c.gamma_c_rad + sum_var, 1e-12);
    EXPECT_GE(wrapAngle_rad(c, Tendon::kGrasp, a), 90 * kDeg);  // §4.2: the model holds for wraps ≥ 90°
  }
}

TEST(GloveCapstan, WrapGrowsOneToOneWhenAJointOpensForGraspAndClosesForRelease) {
  const CapstanModel<double> c = makeCapstanModel(defaultIndexModel<double>().mech);
  V a{};
  for (std::size_t q = 0; q < 3; ++q) a[q] = 0.5 * (c.alpha_min_rad[q] + c.alpha_max_rad[q]);
  for (std::size_t q = 0; q < 3; ++q) {
    V b = a;
    b[q] += 0.1;  // open joint q by 0.1 rad
    EXPECT_NEAR(wrapAngle_rad(c, Tendon::kGrasp, b) - wrapAngle_rad(c, Tendon::kGrasp, a), 0.1, 1e-12);
    EXPECT_NEAR(wrapAngle_rad(c, Tendon::kRelease, b) - wrapAngle_rad(c, Tendon::kRelease, a), -0.1, 1e-12);
  }
}

TEST(GloveCapstan, AnglesOutsideTheJointRangeAreClampedIntoIt) {
  const CapstanModel<double> c = makeCapstanModel(defaultIndexModel<double>().mech);
  V beyond = c.alpha_max_rad;
  for (double& v : beyond) v += 1.0;
  EXPECT_DOUBLE_EQ(wrapAngle_rad(c, Tendon::kGrasp, beyond), wrapAngle_rad(c, Tendon::kGrasp, c.alpha_max_rad));
  EXPECT_DOUBLE_EQ(wrapAngle_rad(c, Tendon::kRelease, beyond), c.gamma_c_rad);
}

TEST(GloveCapstan, ReelingInLosesTensionTowardsTheTipAndPayingOutGainsIt) {
  const Model<double> m = defaultIndexModel<double>();
  const CapstanModel<double> c = makeCapstanModel(m.mech, kMuDry<double>);
  for (const V& a : alphaGrid(c, 4)) {
    for (Tendon t : {Tendon::kGrasp, Tendon::kRelease}) {
      double in = 0, out = 0;
      ASSERT_EQ(tipTension(c, t, Sliding::kTowardSpool, a, 5.0, in), CapstanStatus::kOk);
      ASSERT_EQ(tipTension(c, t, Sliding::kTowardTip, a, 5.0, out), CapstanStatus::kOk);
      EXPECT_LT(in, 5.0);
      EXPECT_GT(out, 5.0);
      // F1/F2 = e^{μγ} in both directions (eq 15): the pulling side carries the larger tension.
      const double ratio = std::exp(kMuDry<double> * wrapAngle_rad(c, t, a));
      EXPECT_NEAR(5.0 / in, ratio, 1e-12);
      EXPECT_NEAR(out / 5.0, ratio, 1e-12);
    }
  }
}

TEST(GloveCapstan, CompensationComposedWithTransmissionIsIdentity) {
  const Model<double> m = defaultIndexModel<double>();
  for (double mu : {kMuLubricated<double>, kMuDry<double>}) {
    const CapstanModel<double> c = makeCapstanModel(m.mech, mu);
    for (const V& a : alphaGrid(c, 5)) {
      for (Tendon t : {Tendon::kGrasp, Tendon::kRelease}) {
        for (Sliding s : {Sliding::kTowardSpool, Sliding::kTowardTip}) {
          for (double want : {0.0, 0.3, 4.0, 10.0}) {
            double spool = -1, tip = -1;
            ASSERT_EQ(spoolTensionFor(c, t, s, a, want, spool), CapstanStatus::kOk);
            ASSERT_EQ(tipTension(c, t, s, a, spool, tip), CapstanStatus::kOk);
            EXPECT_NEAR(tip, want, 1e-12 * (1 + want));
          }
        }
      }
    }
  }
}

TEST(GloveCapstan, LubricationLowersTheSpoolTensionNeededWhenReelingIn) {
  const Model<double> m = defaultIndexModel<double>();
  const CapstanModel<double> wet = makeCapstanModel(m.mech, kMuLubricated<double>);
  const CapstanModel<double> dry = makeCapstanModel(m.mech, kMuDry<double>);
  const V a{0.0, -90 * kDeg, 0.0};
  double s_wet = 0, s_dry = 0;
  ASSERT_EQ(spoolTensionFor(wet, Tendon::kGrasp, Sliding::kTowardSpool, a, 10.0, s_wet), CapstanStatus::kOk);
  ASSERT_EQ(spoolTensionFor(dry, Tendon::kGrasp, Sliding::kTowardSpool, a, 10.0, s_dry), CapstanStatus::kOk);
  EXPECT_GT(s_wet, 10.0);
  EXPECT_GT(s_dry, s_wet);
}

TEST(GloveCapstan, NegativeAndNonFiniteTensionsAreRejectedWithZeroOutput) {
  const CapstanModel<double> c = makeCapstanModel(defaultIndexModel<double>().mech);
  const V a{0.0, -1.5, 0.0};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  double out = 7;
  EXPECT_EQ(spoolTensionFor(c, Tendon::kGrasp, Sliding::kTowardSpool, a, -1.0, out), CapstanStatus::kNegativeTension);
  EXPECT_EQ(out, 0.0);
  out = 7;
  EXPECT_EQ(tipTension(c, Tendon::kGrasp, Sliding::kTowardSpool, a, nan, out), CapstanStatus::kNonFiniteInput);
  EXPECT_EQ(out, 0.0);
  out = 7;
  EXPECT_EQ(spoolTensionFor(c, Tendon::kRelease, Sliding::kTowardTip, V{nan, 0, 0}, 1.0, out),
            CapstanStatus::kNonFiniteInput);
  EXPECT_EQ(out, 0.0);
  out = 7;
  EXPECT_EQ(tipTension(c, Tendon::kRelease, Sliding::kTowardTip, a,
                       std::numeric_limits<double>::infinity(), out),
            CapstanStatus::kNonFiniteInput);
  EXPECT_EQ(out, 0.0);
}

TEST(GloveCapstan, FloatInstantiationAgreesWithDouble) {
  const CapstanModel<double> cd = makeCapstanModel(defaultIndexModel<double>().mech);
  const CapstanModel<float> cf = makeCapstanModel(defaultIndexModel<float>().mech);
  for (const V& a : alphaGrid(cd, 4)) {
    const Vec3<float> af{float(a[0]), float(a[1]), float(a[2])};
    double sd = 0;
    float sf = 0;
    ASSERT_EQ(spoolTensionFor(cd, Tendon::kGrasp, Sliding::kTowardSpool, a, 8.0, sd), CapstanStatus::kOk);
    ASSERT_EQ(spoolTensionFor(cf, Tendon::kGrasp, Sliding::kTowardSpool, af, 8.0f, sf), CapstanStatus::kOk);
    EXPECT_NEAR(double(sf), sd, 1e-5 * sd);
  }
}

}  // namespace
