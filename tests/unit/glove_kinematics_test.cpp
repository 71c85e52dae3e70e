// Invariants of the RML glove kinematics (phalanx/glove/kinematics.h, seeds/000 eq 3–12, 18, 24).
#include "phalanx/glove/kinematics.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

namespace {

using namespace phalanx::glove;
using V = Vec3<double>;
using M3 = Mat3<double>;

constexpr double kDeg = 3.14159265358979323846 / 180.0;

const char* kFingerNames[kNumFingers] = {"thumb", "index", "middle", "ring", "little"};

Model<double> fingerModel(std::size_t i) { return defaultModel<double>(static_cast<FingerId>(i)); }

// Angular difference in (-π, π].
double angleDiff(double a, double b) { return std::remainder(a - b, 2.0 * 3.14159265358979323846); }

// θ grid over Table 2's ranges (bounds included): MCP [-90, 30]°, PIP [-120, 0]°, DIP [-80, 0]°.
std::vector<V> table2Grid(int n1, int n2, int n3) {
  std::vector<V> g;
  for (int i = 0; i < n1; ++i) {
    for (int j = 0; j < n2; ++j) {
      for (int k = 0; k < n3; ++k) {
        g.push_back({(-90.0 + 120.0 * i / (n1 - 1)) * kDeg, (-120.0 + 120.0 * j / (n2 - 1)) * kDeg,
                     (-80.0 + 80.0 * k / (n3 - 1)) * kDeg});
      }
    }
  }
  return g;
}

// Central-difference Jacobian of a pose function u(q) = (x, y, φ); φ differences are wrapped.
M3 numericJacobian(const std::function<V(const V&)>& f, const V& q, double h) {
  M3 J{};
  for (std::size_t c = 0; c < 3; ++c) {
    V qp = q, qm = q;
    qp[c] += h;
    qm[c] -= h;
    const V up = f(qp), um = f(qm);
    J[0][c] = (up[0] - um[0]) / (2 * h);
    J[1][c] = (up[1] - um[1]) / (2 * h);
    J[2][c] = angleDiff(up[2], um[2]) / (2 * h);
  }
  return J;
}

double maxAbsDiff(const M3& a, const M3& b) {
  double m = 0;
  for (std::size_t r = 0; r < 3; ++r)
    for (std::size_t c = 0; c < 3; ++c) m = std::fmax(m, std::fabs(a[r][c] - b[r][c]));
  return m;
}

double det3(const M3& a) {  // rule of Sarrus, independent of the library's adjugate
  return a[0][0] * a[1][1] * a[2][2] + a[0][1] * a[1][2] * a[2][0] + a[0][2] * a[1][0] * a[2][1] -
         a[0][2] * a[1][1] * a[2][0] - a[0][0] * a[1][2] * a[2][1] - a[0][1] * a[1][0] * a[2][2];
}

bool anyNaN(const Data<double>& d) {
  auto bad = [](const V& v) { return std::isnan(v[0]) || std::isnan(v[1]) || std::isnan(v[2]); };
  bool b = bad(d.alpha_rad) || bad(d.theta_rad) || bad(d.O_u_tip) || std::isnan(d.det_J_alpha_u) ||
           std::isnan(d.det_J_theta_u);
  for (std::size_t r = 0; r < 3; ++r) b = b || bad(d.J_alpha_u[r]) || bad(d.J_theta_u[r]) || bad(d.J_alpha_theta[r]);
  return b;
}

TEST(GloveKinematics, FingerJacobianMatchesCentralDifferencesOfTheFingertipPose) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    for (const V& th : table2Grid(7, 7, 5)) {
      const M3 num = numericJacobian([&](const V& q) { return tipPoseFromTheta(m.finger, q); }, th, 1e-6);
      EXPECT_LT(maxAbsDiff(jacobianThetaU(m.finger, th), num), 1e-9) << kFingerNames[f];
    }
  }
}

TEST(GloveKinematics, MechanismJacobianMatchesCentralDifferencesOfTheFingertipPose) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    for (const V& th : table2Grid(7, 7, 5)) {
      V a{};
      ASSERT_EQ(alphaFromTheta(m, th, a), Status::kOk);
      const M3 num = numericJacobian([&](const V& q) { return tipPoseFromAlpha(m.mech, q); }, a, 1e-6);
      EXPECT_LT(maxAbsDiff(jacobianAlphaU(m.mech, a), num), 1e-9) << kFingerNames[f];
    }
  }
}

TEST(GloveKinematics, PrintedA22WithItsDuplicatedLpTermDisagreesWithTheDerivative) {
  // The paper prints a22 = l2 c12 + l3 c123 − l_p s123 − l_p s123; ∂y/∂α2 has the l_p term once.
  const Model<double> m = defaultIndexModel<double>();
  V a{};
  ASSERT_EQ(alphaFromTheta(m, V{-30 * kDeg, -45 * kDeg, -20 * kDeg}, a), Status::kOk);
  const M3 num = numericJacobian([&](const V& q) { return tipPoseFromAlpha(m.mech, q); }, a, 1e-6);
  const double a12 = a[0] + a[1], a123 = a12 + a[2];
  const double printed = m.mech.l2_m * std::cos(a12) + m.mech.l3_m * std::cos(a123) -
                         2.0 * m.mech.l_p_m * std::sin(a123);
  EXPECT_GT(std::fabs(printed - num[1][1]), 1e-3);  // l_p·|sin α123| is millimetres here
  EXPECT_NEAR(jacobianAlphaU(m.mech, a)[1][1], num[1][1], 1e-9);
}

TEST(GloveKinematics, AlphaToThetaJacobianMatchesCentralDifferencesOfTheInverseKinematics) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    int checked = 0;
    for (const V& th : table2Grid(7, 7, 5)) {
      // Away from the straight-PIP singularity (J_α^θ ∝ 1/sin θ2) and the reach boundary it implies.
      if (std::fabs(std::sin(th[1])) < 0.1) continue;
      Data<double> d;
      V a{};
      ASSERT_EQ(alphaFromTheta(m, th, a), Status::kOk);
      ASSERT_EQ(computeFromAlpha(m, a, d), Status::kOk);
      ASSERT_TRUE(d.J_alpha_theta_valid);
      const M3 num = numericJacobian(
          [&](const V& q) {
            V t{};
            EXPECT_TRUE(isUsable(thetaFromAlpha(m, q, t)));
            return t;
          },
          a, 1e-7);
      EXPECT_LT(maxAbsDiff(d.J_alpha_theta, num), 1e-6 * (1.0 + maxAbsDiff(num, M3{})))
          << kFingerNames[f];
      ++checked;
    }
    EXPECT_GT(checked, 100);
  }
}

TEST(GloveKinematics, ThetaToAlphaToThetaIsIdentityOverTable2ForAllFingers) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    for (const V& th : table2Grid(13, 13, 9)) {
      V a{}, back{};
      ASSERT_EQ(alphaFromTheta(m, th, a), Status::kOk) << kFingerNames[f];
      ASSERT_EQ(thetaFromAlpha(m, a, back), Status::kOk) << kFingerNames[f];
      // θ2 = 0 is the PIP singularity: there θ2 = −acos(1 − δ) ≈ −√(2δ) turns rounding δ into ~1e-8 rad.
      for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(back[j], th[j], 1e-7) << kFingerNames[f] << " joint " << j;
      // and both routes give the same fingertip pose (eq 3–5 left = right)
      const V u_theta = tipPoseFromTheta(m.finger, th), u_alpha = tipPoseFromAlpha(m.mech, a);
      EXPECT_NEAR(u_theta[0], u_alpha[0], 1e-12);
      EXPECT_NEAR(u_theta[1], u_alpha[1], 1e-12);
      EXPECT_NEAR(angleDiff(u_theta[2], u_alpha[2]), 0.0, 1e-12);
    }
  }
}

TEST(GloveKinematics, AlphaToThetaToAlphaIsIdentityWhereverTheFingerReachesAndUnreachableElsewhere) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    const V& lo = m.mech.alpha_min_rad;
    const V& hi = m.mech.alpha_max_rad;
    const double p1 = m.finger.p1_m, p2 = m.finger.p2_m;
    int ok = 0, unreachable = 0;
    const int n = 15;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        for (int k = 0; k < n; ++k) {
          const V a{lo[0] + (hi[0] - lo[0]) * i / (n - 1), lo[1] + (hi[1] - lo[1]) * j / (n - 1),
                    lo[2] + (hi[2] - lo[2]) * k / (n - 1)};
          V th{};
          const Status s = thetaFromAlpha(m, a, th);
          // Independent reach test: distance MCP → DIP joint must lie in [|p1 − p2|, p1 + p2].
          const V u = tipPoseFromAlpha(m.mech, a);
          const double dx = u[0] - m.finger.p3_m * std::cos(u[2]), dy = u[1] - m.finger.p3_m * std::sin(u[2]);
          const double r = std::hypot(dx, dy);
          const double over = std::fmax(r - (p1 + p2), std::fabs(p1 - p2) - r);
          if (s == Status::kOk) {
            ++ok;
            EXPECT_LE(over, 1e-9);
            V back{};
            ASSERT_EQ(alphaFromTheta(m, th, back), Status::kOk);
            for (std::size_t q = 0; q < 3; ++q) EXPECT_NEAR(angleDiff(back[q], a[q]), 0.0, 1e-9);
            EXPECT_LE(th[1], 0.0);  // anatomical branch: the PIP joint flexes, never hyper-extends
          } else if (s == Status::kReachClamped) {
            EXPECT_GT(over, 0.0);
            EXPECT_LE(over, m.reach_tolerance_m + 1e-12);
          } else {
            ASSERT_EQ(s, Status::kUnreachable);
            ++unreachable;
            EXPECT_GT(over, m.reach_tolerance_m);
            EXPECT_EQ(th, (V{0, 0, 0}));
          }
        }
      }
    }
    EXPECT_GT(ok, n * n * n / 5) << kFingerNames[f];
    EXPECT_GT(unreachable, 0) << kFingerNames[f];
  }
}

TEST(GloveKinematics, MechanismAnglesOverTable2StayInDeclaredRangesElbowUpAndSatisfyG3) {
  const std::array<std::array<double, 2>, 3> table3 = {{{-79.86, 59.98}, {-127.8, -58.3}, {-82.3, 81.6}}};
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    V mn{1e9, 1e9, 1e9}, mx{-1e9, -1e9, -1e9};
    double min_sin_a2 = 1.0;
    for (const V& th : table2Grid(61, 61, 41)) {
      V a{};
      ASSERT_EQ(alphaFromTheta(m, th, a), Status::kOk) << kFingerNames[f];
      ASSERT_LT(a[1], 0.0);  // elbow up
      for (std::size_t q = 0; q < 3; ++q) {
        mn[q] = std::fmin(mn[q], a[q]);
        mx[q] = std::fmax(mx[q], a[q]);
      }
      min_sin_a2 = std::fmin(min_sin_a2, std::fabs(std::sin(a[1])));
    }
    std::printf("  %-6s alpha1 [%7.2f, %6.2f] alpha2 [%7.2f, %6.2f] alpha3 [%7.2f, %6.2f] deg; "
                "var %6.2f %6.2f %6.2f; min|sin a2| %.3f\n",
                kFingerNames[f], mn[0] / kDeg, mx[0] / kDeg, mn[1] / kDeg, mx[1] / kDeg, mn[2] / kDeg, mx[2] / kDeg,
                (mx[0] - mn[0]) / kDeg, (mx[1] - mn[1]) / kDeg, (mx[2] - mn[2]) / kDeg, min_sin_a2);
    for (std::size_t q = 0; q < 3; ++q) {
      EXPECT_GE(mn[q], m.mech.alpha_min_rad[q]) << kFingerNames[f] << " joint " << q;
      EXPECT_LE(mx[q], m.mech.alpha_max_rad[q]) << kFingerNames[f] << " joint " << q;
      EXPECT_LT(mx[q] - mn[q], 150.0 * kDeg) << "g3 (eq 22) " << kFingerNames[f] << " joint " << q;
      EXPECT_LT(m.mech.alpha_max_rad[q] - m.mech.alpha_min_rad[q], 150.0 * kDeg);
    }
    EXPECT_GT(min_sin_a2, m.near_singular_sin);  // eq 24: never near the singularity in the working range
    if (f == static_cast<std::size_t>(FingerId::kIndex)) {
      // Close to Table 3. α3 cannot match exactly: Table 3's own α3 range (163.9°) violates g3.
      for (std::size_t q = 0; q < 3; ++q) {
        EXPECT_NEAR(mn[q] / kDeg, table3[q][0], 12.0) << "joint " << q;
        EXPECT_NEAR(mx[q] / kDeg, table3[q][1], 12.0) << "joint " << q;
      }
    }
  }
}

TEST(GloveKinematics, CorrectedEq6ReproducesTheFingertipWhileThePrintedEq6DoesNot) {
  const Model<double> m = defaultIndexModel<double>();
  const double l1 = m.mech.l1_m, l2 = m.mech.l2_m, l3 = m.mech.l3_m, lp = m.mech.l_p_m;
  const double p1 = m.finger.p1_m, p2 = m.finger.p2_m, p3 = m.finger.p3_m;
  const double xb = m.mech.x_B0_m, yb = m.mech.y_B0_m;
  int printed_wrong = 0, total = 0;
  for (const V& th : table2Grid(7, 7, 5)) {
    const double c1 = std::cos(th[0]), s1 = std::sin(th[0]);
    const double c12 = std::cos(th[0] + th[1]), s12 = std::sin(th[0] + th[1]);
    const double phi = th[0] + th[1] + th[2], c = std::cos(phi), s = std::sin(phi);
    const V u = tipPoseFromTheta(m.finger, th);
    // Corrected eq 6–8 (arccos form, as in the paper but with the mechanism links l1, l2).
    {
      const double M = -xb + p1 * c1 + p2 * c12 + (p3 - l3) * c + lp * s;
      const double N = -yb + p1 * s1 + p2 * s12 + (p3 - l3) * s - lp * c;
      const double r2 = M * M + N * N;
      const double a1 = std::atan2(N, M) + std::acos((l1 * l1 - l2 * l2 + r2) / (2 * l1 * std::sqrt(r2)));
      const double a2 = -std::acos((r2 - l1 * l1 - l2 * l2) / (2 * l1 * l2));
      const V a{a1, a2, phi - a1 - a2};
      const V ua = tipPoseFromAlpha(m.mech, a);
      EXPECT_NEAR(ua[0], u[0], 1e-12);
      EXPECT_NEAR(ua[1], u[1], 1e-12);
      V lib{};
      ASSERT_EQ(alphaFromTheta(m, th, lib), Status::kOk);
      for (std::size_t q = 0; q < 3; ++q) EXPECT_NEAR(angleDiff(lib[q], a[q]), 0.0, 1e-9);
    }
    // Eq 6–7 and M, N exactly as printed.
    {
      const double M = -xb + l1 * c1 + l2 * c12 + (l3 - p3) * c + lp * s;
      const double N = -yb + l1 * s1 + l2 * s12 + (l3 - p3) * s + lp * c;
      const double r = std::sqrt(M * M + N * N);
      const double arg1 = (p1 * p1 + p2 * p2 + N * N - M * M) / (2 * p1 * r);
      const double arg2 = (M * M + N * N - p1 * p1 - p2 * p2) / (2 * p1 * p2);
      ++total;
      if (std::fabs(arg1) > 1 || std::fabs(arg2) > 1) {
        ++printed_wrong;  // no solution at all
        continue;
      }
      const double a1 = std::atan2(N, M) + std::acos(arg1), a2 = std::acos(arg2);
      const V ua = tipPoseFromAlpha(m.mech, V{a1, a2, phi - a1 - a2});
      if (std::hypot(ua[0] - u[0], ua[1] - u[1]) > 1e-3) ++printed_wrong;
    }
  }
  EXPECT_EQ(printed_wrong, total);
}

TEST(GloveKinematics, VirtualWorkOfTheFingertipWrenchEqualsMechanismAndFingerJointWork) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double h = 1e-5;  // s
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> m = fingerModel(f);
    for (const V& th : table2Grid(5, 5, 3)) {
      if (std::fabs(std::sin(th[1])) < 0.1) continue;  // J_α^θ needs the finger off the PIP singularity
      V a{};
      ASSERT_EQ(alphaFromTheta(m, th, a), Status::kOk);
      Data<double> d;
      ASSERT_EQ(computeFromAlpha(m, a, d), Status::kOk);
      const V F{10 * unit(rng), 10 * unit(rng), 0.2 * unit(rng)};  // N, N, N·m
      const V a_dot{unit(rng), unit(rng), unit(rng)};             // rad/s
      // u̇ and θ̇ by central differences along the motion α(t) = α + t·α̇ — no Jacobian involved.
      V ap{}, am{}, tp{}, tm{};
      for (std::size_t q = 0; q < 3; ++q) {
        ap[q] = a[q] + h * a_dot[q];
        am[q] = a[q] - h * a_dot[q];
      }
      const V up = tipPoseFromAlpha(m.mech, ap), um = tipPoseFromAlpha(m.mech, am);
      ASSERT_EQ(thetaFromAlpha(m, ap, tp), Status::kOk);
      ASSERT_EQ(thetaFromAlpha(m, am, tm), Status::kOk);
      const V u_dot{(up[0] - um[0]) / (2 * h), (up[1] - um[1]) / (2 * h), angleDiff(up[2], um[2]) / (2 * h)};
      V th_dot{};
      for (std::size_t q = 0; q < 3; ++q) th_dot[q] = angleDiff(tp[q], tm[q]) / (2 * h);
      const double P_tip = F[0] * u_dot[0] + F[1] * u_dot[1] + F[2] * u_dot[2];

      const V tau_alpha = mechanismTorqueFromWrench(d.J_alpha_u, F);  // eq 18
      const V tau_theta = fingerTorqueFromWrench(d.J_theta_u, F);
      const V tau_alpha_12 = mechanismTorqueFromFingerTorque(d.J_alpha_theta, tau_theta);  // eq 12
      const double P_alpha = tau_alpha[0] * a_dot[0] + tau_alpha[1] * a_dot[1] + tau_alpha[2] * a_dot[2];
      const double P_theta = tau_theta[0] * th_dot[0] + tau_theta[1] * th_dot[1] + tau_theta[2] * th_dot[2];
      EXPECT_NEAR(P_alpha, P_tip, 1e-9) << kFingerNames[f];
      EXPECT_NEAR(P_theta, P_tip, 1e-7) << kFingerNames[f];  // θ̇ is a difference of an inverse: looser
      for (std::size_t q = 0; q < 3; ++q) EXPECT_NEAR(tau_alpha_12[q], tau_alpha[q], 1e-9) << kFingerNames[f];
    }
  }
}

TEST(GloveKinematics, Eq24DeterminantIsL1L2SinAlpha2AndSingularPosesAreFlagged) {
  const Model<double> m = defaultIndexModel<double>();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ang(-3.0, 3.0);
  for (int i = 0; i < 200; ++i) {
    const V a{ang(rng), ang(rng), ang(rng)};
    EXPECT_NEAR(det3(jacobianAlphaU(m.mech, a)), m.mech.l1_m * m.mech.l2_m * std::sin(a[1]), 1e-15);
  }
  for (double a2 : {0.0, 180 * kDeg, -180 * kDeg}) {
    Data<double> d;
    computeFromAlpha(m, V{30 * kDeg, a2, -20 * kDeg}, d);  // finger status irrelevant: the flag must be set
    EXPECT_TRUE(d.alpha_near_singular) << a2;
    EXPECT_NEAR(d.det_J_alpha_u, 0.0, 1e-15);
    EXPECT_NEAR(det3(d.J_alpha_u), 0.0, 1e-15);
    EXPECT_FALSE(anyNaN(d));
  }
  Data<double> d;
  ASSERT_EQ(computeFromTheta(m, V{-30 * kDeg, -45 * kDeg, -20 * kDeg}, d), Status::kOk);
  EXPECT_FALSE(d.alpha_near_singular);
  EXPECT_GT(std::fabs(d.det_J_alpha_u), 0.5 * m.mech.l1_m * m.mech.l2_m);
}

TEST(GloveKinematics, StraightPipIsFlaggedAndJAlphaThetaIsNotFormedThere) {
  const Model<double> m = defaultIndexModel<double>();
  Data<double> d;
  ASSERT_EQ(computeFromTheta(m, V{-20 * kDeg, 0.0, -10 * kDeg}, d), Status::kOk);
  EXPECT_TRUE(d.theta_near_singular);
  EXPECT_FALSE(d.J_alpha_theta_valid);
  EXPECT_EQ(maxAbsDiff(d.J_alpha_theta, M3{}), 0.0);
  EXPECT_FALSE(anyNaN(d));
  EXPECT_TRUE(d.theta_within_range);
  M3 inv{};
  EXPECT_EQ(invert(jacobianThetaU(m.finger, V{-20 * kDeg, 0.0, -10 * kDeg}), 1e-12, inv), Status::kSingular);
}

TEST(GloveKinematics, NonFiniteInputsAreRejectedAndLeaveNoNaN) {
  const Model<double> m = defaultIndexModel<double>();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const V& bad : {V{nan, 0, 0}, V{0, inf, 0}, V{0, 0, -inf}}) {
    Data<double> d;
    EXPECT_EQ(computeFromAlpha(m, bad, d), Status::kNonFiniteInput);
    EXPECT_FALSE(anyNaN(d));
    EXPECT_EQ(computeFromTheta(m, bad, d), Status::kNonFiniteInput);
    EXPECT_FALSE(anyNaN(d));
    V out{1, 1, 1};
    EXPECT_EQ(thetaFromAlpha(m, bad, out), Status::kNonFiniteInput);
    EXPECT_EQ(out, (V{0, 0, 0}));
    out = {1, 1, 1};
    EXPECT_EQ(alphaFromTheta(m, bad, out), Status::kNonFiniteInput);
    EXPECT_EQ(out, (V{0, 0, 0}));
  }
}

TEST(GloveKinematics, FingertipSlightlyBeyondReachIsClampedAndFarBeyondIsUnreachable) {
  const Model<double> m = defaultIndexModel<double>();
  V a{};
  ASSERT_EQ(alphaFromTheta(m, V{-10 * kDeg, 0.0, 0.0}, a), Status::kOk);  // straight finger: at full reach
  Model<double> shorter = m;
  shorter.finger.p1_m -= 0.001;  // user's finger 1 mm shorter than the model: 1 mm beyond reach
  V th{};
  EXPECT_EQ(thetaFromAlpha(shorter, a, th), Status::kReachClamped);
  EXPECT_EQ(th[1], 0.0);
  EXPECT_NEAR(th[0] + th[1] + th[2], -10 * kDeg, 1e-12);  // φ is still exact
  shorter.finger.p1_m -= 0.002;  // 3 mm beyond reach > 2 mm tolerance
  EXPECT_EQ(thetaFromAlpha(shorter, a, th), Status::kUnreachable);
  Data<double> d;
  EXPECT_EQ(computeFromAlpha(shorter, a, d), Status::kUnreachable);
  EXPECT_FALSE(anyNaN(d));
  EXPECT_FALSE(isUsable(d.status));
}

TEST(GloveKinematics, FloatInstantiationAgreesWithDouble) {
  for (std::size_t f = 0; f < kNumFingers; ++f) {
    const Model<double> md = fingerModel(f);
    const Model<float> mf = defaultModel<float>(static_cast<FingerId>(f));
    double worst_theta = 0, worst_theta_singular = 0, worst_J = 0, worst_alpha = 0;
    for (const V& th : table2Grid(9, 9, 5)) {
      V a{};
      ASSERT_EQ(alphaFromTheta(md, th, a), Status::kOk);
      const Vec3<float> af{static_cast<float>(a[0]), static_cast<float>(a[1]), static_cast<float>(a[2])};
      const Vec3<float> thf{static_cast<float>(th[0]), static_cast<float>(th[1]), static_cast<float>(th[2])};
      Data<double> dd;
      Data<float> df;
      ASSERT_EQ(computeFromAlpha(md, a, dd), Status::kOk);
      ASSERT_TRUE(isUsable(computeFromAlpha(mf, af, df))) << kFingerNames[f];
      Vec3<float> a_back{};
      ASSERT_EQ(alphaFromTheta(mf, thf, a_back), Status::kOk);
      for (std::size_t q = 0; q < 3; ++q) {
        worst_alpha = std::fmax(worst_alpha, std::fabs(angleDiff(double(a_back[q]), a[q])));
        // Near θ2 = 0 the inverse is a square root of rounding: compare only off the singularity there.
        const bool off_singular = std::fabs(std::sin(th[1])) > 0.1;
        const double e_theta = std::fabs(angleDiff(double(df.theta_rad[q]), dd.theta_rad[q]));
        if (off_singular) {
          worst_theta = std::fmax(worst_theta, e_theta);
        } else {
          worst_theta_singular = std::fmax(worst_theta_singular, e_theta);
        }
        for (std::size_t c = 0; c < 3; ++c) {
          worst_J = std::fmax(worst_J, std::fabs(double(df.J_alpha_u[q][c]) - dd.J_alpha_u[q][c]));
          if (off_singular) {  // J_θ^u is evaluated at the float θ, which inherits the √ error above
            worst_J = std::fmax(worst_J, std::fabs(double(df.J_theta_u[q][c]) - dd.J_theta_u[q][c]));
          }
        }
      }
    }
    EXPECT_LT(worst_alpha, 2e-6) << kFingerNames[f];
    EXPECT_LT(worst_theta, 2e-5) << kFingerNames[f];
    EXPECT_LT(worst_theta_singular, 5e-3) << kFingerNames[f];  // |sin θ2| ≤ 0.1, incl. θ2 = 0
    EXPECT_LT(worst_J, 5e-7) << kFingerNames[f];  // m/rad; entries are ~0.1 m
    std::printf("  %-6s float vs double: alpha %.1e rad, theta %.1e rad (%.1e near theta2 = 0), J %.1e m\n",
                kFingerNames[f], worst_alpha, worst_theta, worst_theta_singular, worst_J);
  }
}

TEST(GloveKinematics, JacobianInverseTimesMatrixIsIdentity) {
  const Model<double> m = defaultIndexModel<double>();
  const M3 J = jacobianThetaU(m.finger, V{-40 * kDeg, -60 * kDeg, -30 * kDeg});
  M3 inv{};
  ASSERT_EQ(invert(J, 1e-12, inv), Status::kOk);
  const M3 I = mul(inv, J);
  for (std::size_t r = 0; r < 3; ++r)
    for (std::size_t c = 0; c < 3; ++c) EXPECT_NEAR(I[r][c], r == c ? 1.0 : 0.0, 1e-12);
}

TEST(GloveKinematics, PadNormalIsPerpendicularToTheDistalPhalanxAndPointsDorsallyWhenStraight) {
  const Model<double> m = defaultIndexModel<double>();
  for (const V& th : table2Grid(5, 5, 3)) {
    const V u = tipPoseFromTheta(m.finger, th);
    // distal phalanx direction from a finite step along p3 (θ3 increment moves the tip perpendicular)
    const V n = padNormal(u[2]);
    const double dx = std::cos(th[0] + th[1] + th[2]), dy = std::sin(th[0] + th[1] + th[2]);
    EXPECT_NEAR(n[0] * dx + n[1] * dy, 0.0, 1e-15);
    EXPECT_NEAR(std::hypot(n[0], n[1]), 1.0, 1e-15);
    // +n is the direction the tip moves when the DIP extends (θ3 increases)
    const M3 J = jacobianThetaU(m.finger, th);
    EXPECT_GT(n[0] * J[0][2] + n[1] * J[1][2], 0.0);
  }
  const V n0 = padNormal(0.0);
  EXPECT_NEAR(n0[1], 1.0, 1e-15);  // straight finger: pad normal = y_O = dorsal
}

}  // namespace
