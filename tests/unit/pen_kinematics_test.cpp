// Twin-Pantograph kinematics (phalanx/pen/kinematics.h, seeds/004 §V–VI).
#include "phalanx/pen/kinematics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace {

using namespace phalanx::pen;
using V3 = Vec3<double>;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

// Random pose inside Table X's workspace: x ±6, y ±3.75, z 20 ± 3.75 cm, θx, θz ±45°.
PenPose<double> randomWorkspacePose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PenPose<double> p;
  p.centre_m = {0.06 * u(rng), 0.0375 * u(rng), 0.20 + 0.0375 * u(rng)};
  p.theta_x_rad = 45 * kDeg * u(rng);
  p.theta_z_rad = 45 * kDeg * u(rng);
  return p;
}

// Independent closed-chain solution of one pantograph: unknown absolute forearm angles (φa, φb) solving
// E_a + l3(cos φa, sin φa) = E_b + l3(cos φb, sin φb) by Newton's method with a finite-difference Jacobian, then
// the tip point rotated about the waist axis with an explicit rotation matrix Rx(q_w).
V3 closedChainTip(const PantographGeometry<double>& g, const V3& q) {
  const double eau = -0.5 * g.l1_m + g.l2_m * std::cos(q[1]), eav = g.l2_m * std::sin(q[1]);
  const double ebu = 0.5 * g.l1_m + g.l2_m * std::cos(q[2]), ebv = g.l2_m * std::sin(q[2]);
  auto residual = [&](double pa, double pb, double& r0, double& r1) {
    r0 = eau + g.l3_m * std::cos(pa) - ebu - g.l3_m * std::cos(pb);
    r1 = eav + g.l3_m * std::sin(pa) - ebv - g.l3_m * std::sin(pb);
  };
  double pa = 60 * kDeg, pb = 120 * kDeg;  // forearms leaning inwards: the assembly used by the device
  for (int it = 0; it < 100; ++it) {
    double r0, r1;
    residual(pa, pb, r0, r1);
    if (std::hypot(r0, r1) < 1e-15) break;
    const double h = 1e-7;
    double a0, a1, b0, b1;
    residual(pa + h, pb, a0, a1);
    residual(pa, pb + h, b0, b1);
    const double j00 = (a0 - r0) / h, j10 = (a1 - r1) / h, j01 = (b0 - r0) / h, j11 = (b1 - r1) / h;
    const double det = j00 * j11 - j01 * j10;
    pa -= (j11 * r0 - j01 * r1) / det;
    pb -= (-j10 * r0 + j00 * r1) / det;
  }
  const double u = eau + g.l3_m * std::cos(pa), v = eav + g.l3_m * std::sin(pa);
  // In-plane point (u along x, v along the plane's reach direction, which is z_B at q_w = 0), turned about x.
  const double c = std::cos(q[0]), s = std::sin(q[0]);
  const V3 local{u, 0.0, v};
  return {local[0], g.y_waist_m + c * local[1] + s * local[2], -s * local[1] + c * local[2]};
}

TEST(PenKinematics, DefaultModelIsTableVIIIAtTwentyCentimetres) {
  const Model<double> m = defaultModel<double>();
  for (const auto& p : m.pantograph) {
    EXPECT_DOUBLE_EQ(p.l1_m, 0.024);
    EXPECT_DOUBLE_EQ(p.l2_m, 0.145);
    EXPECT_DOUBLE_EQ(p.l3_m, 0.200);
  }
  EXPECT_DOUBLE_EQ(m.pantograph[kTop].y_waist_m - m.pantograph[kBottom].y_waist_m, 0.08);  // l4
  // l6 = 7 cm is the distance from the pen centre to each universal joint: the joints are 14 cm apart.
  EXPECT_DOUBLE_EQ(m.l6_m, 0.07);
  EXPECT_DOUBLE_EQ(penLength(m), 0.14);
  EXPECT_DOUBLE_EQ(endOffset(kBottom, m.l6_m), -0.07);
  EXPECT_DOUBLE_EQ(endOffset(kTop, m.l6_m), 0.07);
  // §V: "physically impossible" five-bar singularities need l3 > l1 + l2 (holds) and l2 > l1 (read as such).
  EXPECT_GT(m.pantograph[0].l3_m, m.pantograph[0].l1_m + m.pantograph[0].l2_m);
}

TEST(PenKinematics, HomeJointAnglesPutThePenAtHome) {
  const Model<double> m = defaultModel<double>();
  Data<double> d;
  ASSERT_EQ(computeForward(m, m.q_home_rad, d), Status::kOk);
  EXPECT_NEAR(d.B_p_centre[0], 0.0, 1e-12);
  EXPECT_NEAR(d.B_p_centre[1], 0.0, 1e-12);
  EXPECT_NEAR(d.B_p_centre[2], 0.20, 1e-12);
  EXPECT_NEAR(d.B_axis[1], 1.0, 1e-12);
  EXPECT_NEAR(d.pose.theta_x_rad, 0.0, 1e-12);
  EXPECT_NEAR(d.pose.theta_z_rad, 0.0, 1e-12);
  EXPECT_NEAR(d.length_m, 0.14, 1e-12);
  // Tip 7 cm below the centre, 3 cm below its waist axis (y = −4 cm): the waists sit at ∓atan(3/20) at home.
  EXPECT_NEAR(d.pantograph[kBottom].B_p_tip[1], -0.07, 1e-12);
  EXPECT_NEAR(d.pantograph[kTop].B_p_tip[1], 0.07, 1e-12);
  EXPECT_NEAR(m.q_home_rad[0], -std::atan2(0.03, 0.20), 1e-12);
  EXPECT_NEAR(m.q_home_rad[3], std::atan2(0.03, 0.20), 1e-12);
}

TEST(PenKinematics, MakeModelRefusesGeometriesThatAreNotAPen) {
  Model<double> m = defaultModel<double>();
  const Model<double> before = m;
  Geometry<double> g = defaultGeometry<double>();
  g.l2_m = -0.1;
  EXPECT_EQ(makeModel(g, m), Status::kNonFiniteInput);
  g = defaultGeometry<double>();
  g.l6_m = std::nan("");
  EXPECT_EQ(makeModel(g, m), Status::kNonFiniteInput);
  g = defaultGeometry<double>();
  g.home_z_m = 0.40;  // beyond l2 + l3 = 34.5 cm
  EXPECT_EQ(makeModel(g, m), Status::kUnreachable);
  EXPECT_EQ(m.l6_m, before.l6_m);  // untouched on failure
  EXPECT_EQ(m.q_home_rad, before.q_home_rad);
  g = defaultGeometry<double>();
  g.l2_m = 0.17;
  g.l3_m = 0.23;
  g.home_z_m = 0.25;  // Table VII's 25 cm design
  ASSERT_EQ(makeModel(g, m), Status::kOk);
  Data<double> d;
  ASSERT_EQ(computeForward(m, m.q_home_rad, d), Status::kOk);
  EXPECT_NEAR(d.B_p_centre[2], 0.25, 1e-12);
}

TEST(PenKinematics, WaistCountMovesThePenByTableXResolutionAlongY) {
  // Table X: spatial resolution along y is 314 µm = 20 cm · 2π/4000: one waist count at the 20 cm reach.
  const Model<double> m = defaultModel<double>();
  Data<double> d;
  ASSERT_EQ(computeForward(m, m.q_home_rad, d), Status::kOk);
  const double rad_per_count = 2 * 3.14159265358979323846 / 4000.0;
  EXPECT_NEAR(d.pantograph[kBottom].J[1][0] * rad_per_count * 1e6, 314.0, 1.0);
  // x and z per shoulder count: Table X gives 142 and 175 µm; this geometry gives ~148 and ~153 µm.
  EXPECT_NEAR(std::fabs(d.pantograph[kBottom].J[0][1]) * rad_per_count * 1e6, 142.0, 0.1 * 142.0);
  EXPECT_NEAR(std::fabs(d.pantograph[kBottom].J[2][1]) * rad_per_count * 1e6, 175.0, 0.15 * 175.0);
}

TEST(PenKinematics, InverseThenForwardIsIdentityAcrossTheWorkspace) {
  const Model<double> m = defaultModel<double>();
  std::mt19937 rng(1);
  Data<double> d;
  for (int k = 0; k < 5000; ++k) {
    const PenPose<double> pose = randomWorkspacePose(rng);
    JointVec<double> q;
    ASSERT_EQ(computeInverse(m, pose, q), Status::kOk) << "pose " << k << " unreachable";
    const Status s = computeForward(m, q, d);
    ASSERT_TRUE(isUsable(s)) << int(s);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(d.pose.centre_m[i], pose.centre_m[i], 1e-12);
    EXPECT_NEAR(d.pose.theta_x_rad, pose.theta_x_rad, 1e-11);
    EXPECT_NEAR(d.pose.theta_z_rad, pose.theta_z_rad, 1e-11);
    EXPECT_NEAR(d.length_m, penLength(m), 1e-12);
  }
}

TEST(PenKinematics, ForwardMatchesANumericalSolutionOfTheClosedChain) {
  const Model<double> m = defaultModel<double>();
  std::mt19937 rng(2);
  for (int k = 0; k < 2000; ++k) {
    JointVec<double> q;
    ASSERT_EQ(computeInverse(m, randomWorkspacePose(rng), q), Status::kOk);
    for (std::size_t p = 0; p < kNumPantographs; ++p) {
      const V3 qp{q[3 * p], q[3 * p + 1], q[3 * p + 2]};
      PantographData<double> pd;
      ASSERT_EQ(pantographForward(m.pantograph[p], qp, pd), Status::kOk);
      const V3 ref = closedChainTip(m.pantograph[p], qp);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(pd.B_p_tip[i], ref[i], 1e-12);
    }
  }
}

TEST(PenKinematics, TipJacobiansMatchFiniteDifferences) {
  const Model<double> m = defaultModel<double>();
  std::mt19937 rng(3);
  const double h = 1e-6;
  double worst = 0.0;
  for (int k = 0; k < 1000; ++k) {
    JointVec<double> q;
    ASSERT_EQ(computeInverse(m, randomWorkspacePose(rng), q), Status::kOk);
    for (std::size_t p = 0; p < kNumPantographs; ++p) {
      const V3 qp{q[3 * p], q[3 * p + 1], q[3 * p + 2]};
      PantographData<double> pd, plus, minus;
      ASSERT_EQ(pantographForward(m.pantograph[p], qp, pd), Status::kOk);
      for (int c = 0; c < 3; ++c) {
        V3 qa = qp, qb = qp;
        qa[c] += h;
        qb[c] -= h;
        ASSERT_EQ(pantographForward(m.pantograph[p], qa, plus), Status::kOk);
        ASSERT_EQ(pantographForward(m.pantograph[p], qb, minus), Status::kOk);
        for (int r = 0; r < 3; ++r) {
          const double fd = (plus.B_p_tip[r] - minus.B_p_tip[r]) / (2 * h);
          worst = std::fmax(worst, std::fabs(fd - pd.J[r][c]));
          EXPECT_NEAR(pd.J[r][c], fd, 1e-8) << "pantograph " << p << " J[" << r << "][" << c << "]";
        }
      }
      EXPECT_NEAR(pd.det_J, det3(pd.J), 1e-18);
    }
  }
  EXPECT_LT(worst, 1e-8);
}

TEST(PenKinematics, EncoderCountsRoundTripToWithinHalfACount) {
  const Model<double> m = defaultModel<double>();
  std::mt19937 rng(4);
  const double half_count = 3.14159265358979323846 / 4000.0;
  for (int k = 0; k < 500; ++k) {
    JointVec<double> q;
    ASSERT_EQ(computeInverse(m, randomWorkspacePose(rng), q), Status::kOk);
    const JointVec<double> qq = anglesFromCounts(m, countsFromAngles(m, q));
    for (std::size_t i = 0; i < kNumJoints; ++i) EXPECT_LE(std::fabs(qq[i] - q[i]), half_count + 1e-15);
    // Quantised encoders still give a consistent pen (ends one pen length apart within the tolerance).
    Data<double> d;
    EXPECT_TRUE(isUsable(computeForward(m, qq, d)));
    EXPECT_LT(std::fabs(d.length_m - penLength(m)), 0.5e-3);
  }
  const auto zero = countsFromAngles(m, m.q_home_rad);
  for (auto c : zero) EXPECT_EQ(c, 0);
}

TEST(PenKinematics, WorkspaceIsFreeOfSingularFlags) {
  const Model<double> m = defaultModel<double>();
  std::mt19937 rng(5);
  Data<double> d;
  double min_margin = 1.0;
  for (int k = 0; k < 5000; ++k) {
    JointVec<double> q;
    ASSERT_EQ(computeInverse(m, randomWorkspacePose(rng), q), Status::kOk);
    EXPECT_EQ(computeForward(m, q, d), Status::kOk);
    EXPECT_EQ(d.near_singular, 0);
    min_margin = std::fmin(min_margin, d.min_margin_sin);
  }
  EXPECT_GT(min_margin, 0.2);  // measured 0.25; documented in docs/pen-model.md
}

TEST(PenKinematics, StretchedArmIsFlaggedAtTheWorkspaceLimit) {
  // (iii) a pantograph at its workspace limit: upper arm a and its forearm (nearly) collinear.
  const Model<double> m = defaultModel<double>();
  const auto& g = m.pantograph[kBottom];
  const double reach = 0.9995 * (g.l2_m + g.l3_m);
  const double dir = 70 * kDeg;
  const V3 tip{-0.5 * g.l1_m + reach * std::cos(dir), g.y_waist_m, reach * std::sin(dir)};
  V3 q;
  ASSERT_EQ(pantographInverse(g, tip, q), Status::kOk);
  PantographData<double> pd;
  ASSERT_EQ(pantographForward(g, q, pd), Status::kOk);
  EXPECT_LT(pd.arm_a_sin, m.near_singular_sin);
  JointVec<double> qq = m.q_home_rad;
  for (int i = 0; i < 3; ++i) qq[i] = q[i];
  Data<double> d;
  computeForward(m, qq, d);  // ends no longer one pen length apart: only the flags matter here
  EXPECT_TRUE(d.near_singular & kArmStretched);
}

TEST(PenKinematics, ForearmsAlignedIsFlaggedAndSingularWhenReachable) {
  // (i) Fig. 12a: impossible with Table VIII's l3 > l1 + l2, so use a pantograph with short forearms.
  PantographGeometry<double> g{0.024, 0.145, 0.08, 0.0};
  // Symmetric shoulders θa = π − θ, θb = θ put the elbows l1 + 2·l2·cos θ apart; forearms collinear at 2·l3.
  const double c_exact = (2 * g.l3_m - g.l1_m) / (2 * g.l2_m);
  const double theta = std::acos(c_exact * 0.9999);
  PantographData<double> pd;
  const Status s = pantographForward(g, {0.0, 3.14159265358979323846 - theta, theta}, pd);
  EXPECT_EQ(s, Status::kOk);
  EXPECT_LT(pd.forearms_sin, 0.1);
  const Status s2 = pantographForward(g, {0.0, 3.14159265358979323846 - std::acos(c_exact), std::acos(c_exact)}, pd);
  EXPECT_TRUE(s2 == Status::kSingular || s2 == Status::kUnreachable);
  // Table VIII geometry: over every tip the outward-elbow assembly reaches in front of the base (u ±12 cm,
  // v 10..30 cm), the forearms stay more than 30° from alignment.
  const Model<double> m = defaultModel<double>();
  double min_sin = 1.0;
  for (double u = -0.12; u <= 0.12; u += 0.005) {
    for (double v = 0.10; v <= 0.30; v += 0.005) {
      V3 qq;
      if (pantographInverse(m.pantograph[0], {u, m.pantograph[0].y_waist_m, v}, qq) != Status::kOk) continue;
      ASSERT_EQ(pantographForward(m.pantograph[0], qq, pd), Status::kOk);
      min_sin = std::fmin(min_sin, pd.forearms_sin);
    }
  }
  EXPECT_GT(min_sin, 0.5);
}

TEST(PenKinematics, TipOnWaistAxisIsFlagged) {
  // (ii): with Table VIII the tip stays ≥ ~5 cm from its waist axis; shorter forearms (16 cm) with the upper
  // arms folded back below the axis (θa = 240°, θb = −60°) bring it to ~1 cm.
  Model<double> m = defaultModel<double>();
  m.pantograph[kBottom].l3_m = 0.16;
  PantographData<double> pd;
  ASSERT_EQ(pantographForward(m.pantograph[kBottom], {0.0, 240 * kDeg, -60 * kDeg}, pd), Status::kOk);
  EXPECT_LT(pd.tip_to_waist_m, m.near_waist_axis_m);
  JointVec<double> q = m.q_home_rad;
  q[1] = 240 * kDeg;
  q[2] = -60 * kDeg;
  Data<double> d;
  computeForward(m, q, d);  // the ends are no longer one pen length apart: only the flags matter here
  EXPECT_TRUE(d.near_singular & kTipOnWaistAxis);
}

TEST(PenKinematics, PenAlongAForearmIsFlagged) {
  // (iv) spherical-wrist singularity: put the eraser end on the line of the bottom pantograph's forearm a.
  const Model<double> m = defaultModel<double>();
  Data<double> d;
  ASSERT_EQ(computeForward(m, m.q_home_rad, d), Status::kOk);
  const auto& pb = d.pantograph[kBottom];
  const V3 dir = pb.B_forearm_dir[0];
  const double L = penLength(m);
  const V3 top{pb.B_p_tip[0] + L * dir[0], pb.B_p_tip[1] + L * dir[1], pb.B_p_tip[2] + L * dir[2]};
  V3 qt;
  ASSERT_EQ(pantographInverse(m.pantograph[kTop], top, qt), Status::kOk);
  JointVec<double> q = m.q_home_rad;
  for (int i = 0; i < 3; ++i) q[3 + i] = qt[i];
  EXPECT_EQ(computeForward(m, q, d), Status::kNearSingular);
  EXPECT_TRUE(d.near_singular & kPenAlongForearm);
  EXPECT_LT(d.pantograph[kBottom].pen_forearm_sin, 1e-9);
}

TEST(PenKinematics, BadInputsAreRejected) {
  const Model<double> m = defaultModel<double>();
  Data<double> d;
  JointVec<double> q = m.q_home_rad;
  q[4] = std::nan("");
  EXPECT_EQ(computeForward(m, q, d), Status::kNonFiniteInput);
  EXPECT_FALSE(isUsable(d.status));
  // Inconsistent encoders (one waist 10° off: its tip moves along the pen): the ends are no longer one pen
  // length apart. (An error that moves a tip across the 14 cm pen changes the length only to second order —
  // the one redundant measurement cannot see it; the firmware's jump check and joint windows are the guard.)
  q = m.q_home_rad;
  q[0] += 10 * kDeg;
  EXPECT_EQ(computeForward(m, q, d), Status::kEndsInconsistent);
  PenPose<double> far;
  far.centre_m = {0.0, 0.0, 0.60};
  EXPECT_EQ(computeInverse(m, far, q), Status::kUnreachable);
}

TEST(PenKinematics, SinglePrecisionAgreesWithDouble) {
  const Model<double> md = defaultModel<double>();
  const Model<float> mf = defaultModel<float>();
  std::mt19937 rng(6);
  Data<double> dd;
  Data<float> df;
  for (int k = 0; k < 200; ++k) {
    JointVec<double> q;
    ASSERT_EQ(computeInverse(md, randomWorkspacePose(rng), q), Status::kOk);
    JointVec<float> qf;
    for (std::size_t i = 0; i < kNumJoints; ++i) qf[i] = float(q[i]);
    ASSERT_TRUE(isUsable(computeForward(md, q, dd)));
    ASSERT_TRUE(isUsable(computeForward(mf, qf, df)));
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(df.B_p_centre[i], dd.B_p_centre[i], 5e-6);
  }
}

}  // namespace
