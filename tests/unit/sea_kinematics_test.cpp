// SEA finger exoskeleton kinematics and statics (phalanx/sea/kinematics.h, seeds/001 eq 3–6, 9, 10, 19, 20).
#include "phalanx/sea/kinematics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace {

using namespace phalanx::sea;
using D = Data<double>;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

Model<double> model() { return defaultModel<double>(); }

FingerAngles<double> finger(double mcp_deg, double pip_deg, double dip_deg) {
  return {mcp_deg * kDeg, pip_deg * kDeg, dip_deg * kDeg, 0.0};
}

/// Calls f(finger) over a grid of the model's finger workspace.
template <class F>
void forWorkspace(const Model<double>& m, F f) {
  for (int i = 0; i <= 6; ++i) {
    for (int j = 0; j <= 8; ++j) {
      for (int k = 0; k <= 3; ++k) {
        const double mcp = m.mcp_range_rad[0] + (m.mcp_range_rad[1] - m.mcp_range_rad[0]) * i / 6.0;
        const double pip = m.pip_range_rad[0] + (m.pip_range_rad[1] - m.pip_range_rad[0]) * j / 8.0;
        const double dip = m.dip_range_rad[0] + (m.dip_range_rad[1] - m.dip_range_rad[0]) * k / 3.0;
        f(FingerAngles<double>{mcp, pip, dip, 0.0});
      }
    }
  }
}

/// X = [x3 θ4 θ5 θ8] of a solved pose.
std::array<double, 4> X(const D& d) { return {d.x3_m, d.theta4_rad, d.theta5_rad, d.theta8_rad}; }

/// |loop-closure error| (m) of the MCP and PIP loops for a pose, evaluated from the loop equations themselves
/// (eq 3 and the PIP loop written in {B}), not from the solver's internals.
std::array<double, 2> loopErrors(const Model<double>& m, double t1, double x3, double t4, double t5, double t6r,
                                 double t8) {
  const SubjectParams<double>& p = m.subject;
  const double t2 = t4 - kDeg * 90.0;
  // eq 3: l_BC e^{iθ1} + l_CD e^{iθ2} + x3 e^{i(θ4−π)} − (x_A + i y_A)
  const double ex = p.l_BC_m * std::cos(t1) + p.l_CD_m * std::cos(t2) - x3 * std::cos(t4) - p.x_A_m;
  const double ey = p.l_BC_m * std::sin(t1) + p.l_CD_m * std::sin(t2) - x3 * std::sin(t4) - p.y_A_m;
  // PIP loop in {B}: C + l_CE e^{i(θ4+θ5)} + l_EF e^{i(θ4+θ5+π+θ6r)} − F, F = H + l_FH e^{i(θ4+θ8+π/2−θ_HFG)}.
  const double cx = p.l_BC_m * std::cos(t1);
  const double cy = p.l_BC_m * std::sin(t1);
  const double hx = p.x_A_m + p.l_AH_m * std::cos(t4);
  const double hy = p.y_A_m + p.l_AH_m * std::sin(t4);
  const double lfh = std::hypot(p.l_FG_m, p.l_GH_m);
  const double hfg = std::atan2(p.l_GH_m, p.l_FG_m);
  const double fx = hx + lfh * std::cos(t4 + t8 + kDeg * 90.0 - hfg);
  const double fy = hy + lfh * std::sin(t4 + t8 + kDeg * 90.0 - hfg);
  const double gx = cx + m.fixed.l_CE_m * std::cos(t4 + t5) - m.fixed.l_EF_m * std::cos(t4 + t5 + t6r) - fx;
  const double gy = cy + m.fixed.l_CE_m * std::sin(t4 + t5) - m.fixed.l_EF_m * std::sin(t4 + t5 + t6r) - fy;
  return {std::hypot(ex, ey), std::hypot(gx, gy)};
}

}  // namespace

TEST(SeaKinematics, DefaultModelIsTable4EstimateWithinTable4Bounds) {
  const auto p = toArray(table4Estimate<double>());
  const auto lo = toArray(table4Lower<double>());
  const auto hi = toArray(table4Upper<double>());
  for (std::size_t i = 0; i < kNumSubjectParams; ++i) {
    EXPECT_LT(lo[i], hi[i]) << kSubjectParamNames[i];
    EXPECT_GE(p[i], lo[i]) << kSubjectParamNames[i];
    EXPECT_LE(p[i], hi[i]) << kSubjectParamNames[i];
  }
  EXPECT_DOUBLE_EQ(model().subject.l_BC_m, 0.042);
}

TEST(SeaKinematics, FingerToSensorsToFingerIsIdentityOverTheWorkspace) {
  const Model<double> m = model();
  int n = 0;
  forWorkspace(m, [&](const FingerAngles<double>& f) {
    D plant;
    ASSERT_EQ(computeFromFinger(m, f, plant), Status::kOk);
    D est;
    ASSERT_EQ(computeFromSensors(m, plant.sensors_rad, est), Status::kOk);
    EXPECT_NEAR(est.theta4_rad, f.mcp_rad, 1e-12);
    EXPECT_NEAR(est.theta8_rad, f.pip_rad, 1e-12);
    EXPECT_NEAR(est.theta_dip_rad, f.dip_rad, 1e-12);
    EXPECT_NEAR(est.x3_m, plant.x3_m, 1e-14);
    EXPECT_NEAR(est.theta5_rad, plant.theta5_rad, 1e-12);
    EXPECT_NEAR(est.theta7r_rad, plant.sensors_rad[kSensorRedundant], 1e-12);
    EXPECT_NEAR(est.theta7r_rad, est.theta5_rad + est.theta6r_rad - est.theta8_rad - 90 * kDeg, 1e-12);
    // The solved pose satisfies the loop equations (checked independently of the solver).
    const auto err = loopErrors(m, est.theta1_rad, est.x3_m, est.theta4_rad, est.theta5_rad, est.theta6r_rad,
                                est.theta8_rad);
    EXPECT_LT(err[0], 1e-14);
    EXPECT_LT(err[1], 1e-14);
    // Design envelope: the exo PIP interior angle stays in (0, π), the sliders stay on the phalanges.
    EXPECT_GT(plant.theta6r_rad, 10 * kDeg);
    EXPECT_LT(plant.theta6r_rad, 170 * kDeg);
    EXPECT_GT(plant.x3_m, 0.005);
    EXPECT_LT(plant.x3_m, 0.045);
    EXPECT_GT(plant.x_dip_m, 0.005);
    EXPECT_LT(plant.x_dip_m, 0.025);
    ++n;
  });
  EXPECT_EQ(n, 7 * 9 * 4);
}

TEST(SeaKinematics, JacobianMatchesCentralFiniteDifferencesOfTheEstimator) {
  const Model<double> m = model();
  forWorkspace(m, [&](const FingerAngles<double>& f) {
    D plant;
    ASSERT_EQ(computeFromFinger(m, f, plant), Status::kOk);
    D d;
    ASSERT_EQ(computeFromSensors(m, plant.sensors_rad, d), Status::kOk);
    ASSERT_TRUE(d.J_valid);
    const double h = 1e-6;
    const std::size_t channel[2] = {kSensorExoMcp, kSensorExoPip};
    for (std::size_t c = 0; c < 2; ++c) {
      Sensors<double> sp = plant.sensors_rad;
      Sensors<double> sm = plant.sensors_rad;
      sp[channel[c]] += h;
      sm[channel[c]] -= h;
      D a;
      D b;
      computeFromSensors(m, sp, a);
      computeFromSensors(m, sm, b);
      const auto xa = X(a);
      const auto xb = X(b);
      for (std::size_t r = 0; r < 4; ++r) {
        const double fd = (xa[r] - xb[r]) / (2 * h);
        EXPECT_NEAR(d.J[r][c], fd, 1e-6 * (1.0 + std::fabs(fd))) << "J" << r + 1 << c + 1;
      }
    }
    // DIP chain rate.
    Sensors<double> sp = plant.sensors_rad;
    Sensors<double> sm = plant.sensors_rad;
    sp[kSensorDip] += h;
    sm[kSensorDip] -= h;
    D a;
    D b;
    computeFromSensors(m, sp, a);
    computeFromSensors(m, sm, b);
    EXPECT_NEAR(d.J_dip, (a.theta_dip_rad - b.theta_dip_rad) / (2 * h), 1e-6);
    // J_n is rows 2 and 4 of J (eq 10).
    EXPECT_EQ(d.J_n[0][0], d.J[1][0]);
    EXPECT_EQ(d.J_n[0][1], d.J[1][1]);
    EXPECT_EQ(d.J_n[1][0], d.J[3][0]);
    EXPECT_EQ(d.J_n[1][1], d.J[3][1]);
  });
}

TEST(SeaKinematics, JacobianReproducesTheAppendixClosedFormsJ11J21J32J42) {
  // eq 19 with a = θ_HFG + θ5 − θ8 (docs/sea-model.md: angle conventions under which these hold literally).
  const Model<double> m = model();
  const SubjectParams<double>& p = m.subject;
  const double lCE = m.fixed.l_CE_m;
  const double lEF = m.fixed.l_EF_m;
  const double lFH = lengthFH(p);
  const double hfg = angleHFG(p);
  forWorkspace(m, [&](const FingerAngles<double>& f) {
    D d;
    ASSERT_EQ(computeFromFinger(m, f, d), Status::kOk);
    const double phi = d.theta1_rad - d.theta4_rad;
    const double J11 = p.l_BC_m * p.l_CD_m * std::cos(phi) / d.x3_m - p.l_BC_m * std::sin(phi);
    const double J21 = p.l_BC_m * std::cos(phi) / d.x3_m;
    const double a = hfg + d.theta5_rad - d.theta8_rad;
    const double r = d.theta6r_rad;
    const double den = lEF * std::cos(a + r) - lCE * std::cos(a);
    const double J32 = -lEF * std::cos(a + r) / den;
    const double J42 = lCE * lEF * std::sin(r) / (lFH * den);
    EXPECT_NEAR(d.J[0][0], J11, 1e-12);
    EXPECT_NEAR(d.J[1][0], J21, 1e-12);
    EXPECT_NEAR(d.J[2][1], J32, 1e-12);
    EXPECT_NEAR(d.J[3][1], J42, 1e-12);
    EXPECT_EQ(d.J[0][1], 0.0);  // J12 = J22 = 0: the MCP chain ignores θ6r
    EXPECT_EQ(d.J[1][1], 0.0);
  });
}

TEST(SeaStatics, ExoTorqueFromFingerTorqueSatisfiesVirtualWork) {
  // eq 6: τ_j = Jᵀ[0 τ_mcp 0 τ_pip]ᵀ ⇔ τ_j·Θ̇_r = τ_f·(θ̇4, θ̇8) for every Θ̇_r.
  const Model<double> m = model();
  forWorkspace(m, [&](const FingerAngles<double>& f) {
    D d;
    ASSERT_EQ(computeFromFinger(m, f, d), Status::kOk);
    const Vec2<double> tau_f{0.21, -0.07};
    const Vec2<double> tau_j = exoTorqueFromFingerTorque(d.J_n, tau_f);
    for (const Vec2<double> rate : {Vec2<double>{1.0, 0.0}, Vec2<double>{0.0, 1.0}, Vec2<double>{-0.3, 0.8}}) {
      double xdot[4];
      for (std::size_t r = 0; r < 4; ++r) xdot[r] = d.J[r][0] * rate[0] + d.J[r][1] * rate[1];
      const double p_exo = tau_j[0] * rate[0] + tau_j[1] * rate[1];
      const double p_finger = 0.0 * xdot[0] + tau_f[0] * xdot[1] + 0.0 * xdot[2] + tau_f[1] * xdot[3];
      EXPECT_NEAR(p_exo, p_finger, 1e-12);
    }
    // eq 9 inverts eq 6.
    Vec2<double> back{};
    ASSERT_EQ(fingerTorqueFromExoTorque(d.J_n, tau_j, 1e-9, back), Status::kOk);
    EXPECT_NEAR(back[0], tau_f[0], 1e-12);
    EXPECT_NEAR(back[1], tau_f[1], 1e-12);
  });
}

TEST(SeaStatics, VirtualWorkHoldsForFiniteDisplacementsOfTheMechanism) {
  // Independent of J: move the exo joints by a small δΘ_r, solve positions, and compare τ_j·δΘ_r with
  // τ_f·(δθ4, δθ8) from the position solutions.
  const Model<double> m = model();
  D d;
  ASSERT_EQ(computeFromFinger(m, finger(-35, -45, -20), d), Status::kOk);
  const Vec2<double> tau_f{0.15, 0.05};
  const Vec2<double> tau_j = exoTorqueFromFingerTorque(d.J_n, tau_f);
  const double h = 1e-6;
  Sensors<double> sp = d.sensors_rad;
  Sensors<double> sm = d.sensors_rad;
  sp[kSensorExoMcp] += 0.6 * h;
  sp[kSensorExoPip] -= 0.8 * h;
  sm[kSensorExoMcp] -= 0.6 * h;
  sm[kSensorExoPip] += 0.8 * h;
  D a;
  D b;
  computeFromSensors(m, sp, a);
  computeFromSensors(m, sm, b);
  const double work_exo = tau_j[0] * (2 * 0.6 * h) + tau_j[1] * (-2 * 0.8 * h);
  const double work_finger =
      tau_f[0] * (a.theta4_rad - b.theta4_rad) + tau_f[1] * (a.theta8_rad - b.theta8_rad);
  EXPECT_NEAR(work_exo / h, work_finger / h, 1e-8);
}

TEST(SeaStatics, FingerTorqueFromSingularJnIsRefusedWithZero) {
  const Mat2<double> J_n{{{1.0, 2.0}, {2.0, 4.0}}};
  Vec2<double> tau_f{9.0, 9.0};
  EXPECT_EQ(fingerTorqueFromExoTorque(J_n, Vec2<double>{0.1, 0.1}, 1e-9, tau_f), Status::kSingular);
  EXPECT_EQ(tau_f[0], 0.0);
  EXPECT_EQ(tau_f[1], 0.0);
}

TEST(SeaJacobianRate, Eq20BackwardDifferenceConvergesToTheTimeDerivativeOfJn) {
  // Finger moving along a smooth trajectory; dJ_n/dt by a central difference in time with a tiny step is the
  // reference; eq 20 at Δt = 1 ms (the paper's 500 Hz loop is 2 ms) is first-order accurate.
  const Model<double> m = model();
  auto jn = [&](double t) {
    D d;
    computeFromFinger(m, finger(-30 + 20 * std::sin(2 * t), -40 + 30 * std::sin(3 * t + 0.5), -20), d);
    return d.J_n;
  };
  for (double t : {0.1, 0.7, 1.3}) {
    const double eps = 1e-6;
    const Mat2<double> ref = jacobianNRate(jn(t + eps), jn(t - eps), 2 * eps);
    double scale = 0;
    for (const auto& row : ref) {
      for (double v : row) scale = std::max(scale, std::fabs(v));
    }
    ASSERT_GT(scale, 0.1);  // the trajectory really changes J_n
    for (double dt : {1e-3, 1e-4}) {
      const Mat2<double> r = jacobianNRate(jn(t), jn(t - dt), dt);
      for (std::size_t i = 0; i < 2; ++i) {
        for (std::size_t j = 0; j < 2; ++j) {
          // O(Δt) error: |J̈|·Δt/2; a few units of scale·Δt·10 bound it with margin for this trajectory.
          EXPECT_NEAR(r[i][j], ref[i][j], 20.0 * scale * dt) << "dt " << dt;
        }
      }
    }
  }
}

TEST(SeaEstimator, RecoversFingerAnglesFromNoisySensorsWithinTheNoisePropagatedBound) {
  // 0.05° of sensor error → finger error bounded by |J_n|·0.05° (first order) plus second-order slack.
  const Model<double> m = model();
  forWorkspace(m, [&](const FingerAngles<double>& f) {
    D plant;
    ASSERT_EQ(computeFromFinger(m, f, plant), Status::kOk);
    Sensors<double> s = plant.sensors_rad;
    const double e = 0.05 * kDeg;
    s[kSensorExoMcp] += e;
    s[kSensorExoPip] -= e;
    s[kSensorDip] += e;
    D est;
    ASSERT_EQ(computeFromSensors(m, s, est), Status::kOk);
    const double bound_mcp = std::fabs(plant.J_n[0][0]) * e * 1.2 + 1e-9;
    const double bound_pip = (std::fabs(plant.J_n[1][0]) + std::fabs(plant.J_n[1][1])) * e * 1.2 + 1e-9;
    EXPECT_LE(std::fabs(est.theta4_rad - f.mcp_rad), bound_mcp);
    EXPECT_LE(std::fabs(est.theta8_rad - f.pip_rad), bound_pip);
    EXPECT_LE(std::fabs(est.theta_dip_rad - f.dip_rad), std::fabs(plant.J_dip) * e * 1.2 + 1e-9);
  });
}

TEST(SeaEstimator, McpChainFallsBackToTheLeastSquaresPoseWhenItCannotClose) {
  // θ1 pointing at the finger MCP joint: |C − A| = 6 mm < l_CD = 35 mm, no exact solution of eq 3.
  const Model<double> m = model();
  Sensors<double> s{-90 * kDeg, 60 * kDeg, 0.0, 0.0, 0.0};
  D d;
  const Status st = computeFromSensors(m, s, d);
  EXPECT_TRUE(d.least_squares[0]);
  EXPECT_NE(st, Status::kOk);
  EXPECT_NEAR(d.residual_m[0], 0.035 - 0.006, 1e-12);
  EXPECT_TRUE(std::isfinite(d.theta4_rad));
  // Least squares: no (x3 ≥ 0, θ4) on a fine grid closes eq 3 better than the returned pose.
  const double best = loopErrors(m, s[0], d.x3_m, d.theta4_rad, 0, 0, 0)[0];
  EXPECT_NEAR(best, d.residual_m[0], 1e-12);
  for (double x3 = 0; x3 <= 0.05; x3 += 0.0005) {
    for (double q = -180; q < 180; q += 0.5) {
      EXPECT_GE(loopErrors(m, s[0], x3, q * kDeg, 0, 0, 0)[0], best - 1e-12);
    }
  }
  // And J is refused there (x3 = 0: J21 ∝ 1/x3).
  EXPECT_EQ(st, Status::kSingular);
  EXPECT_FALSE(d.J_valid);
}

TEST(SeaEstimator, PipChainFallsBackToTheLeastSquaresPoseWhenItCannotClose) {
  // Exo PIP sensor reading beyond what the PIP loop can close for this subject (e.g. a sensor offset or a wrong
  // l_FG/l_GH): with the finger MCP straight, |CF| ≤ |HC| + l_FH ≈ 76 mm, but θ6r = 150°…178° asks for
  // |CF| = d(θ6r) up to 90 mm, so the circles |HF| = l_FH and |CF| = d no longer meet.
  const Model<double> m = model();
  D straight;
  ASSERT_EQ(computeFromFinger(m, finger(0, 0, 0), straight), Status::kOk);
  int fallbacks = 0;
  for (double t6 = 150; t6 <= 178; t6 += 4) {
    Sensors<double> s = straight.sensors_rad;
    s[kSensorExoPip] = t6 * kDeg;
    D d;
    computeFromSensors(m, s, d);
    if (!d.least_squares[1]) continue;
    ++fallbacks;
    EXPECT_FALSE(d.least_squares[0]);
    EXPECT_GT(d.residual_m[1], 0.0);
    EXPECT_TRUE(std::isfinite(d.theta5_rad));
    EXPECT_TRUE(std::isfinite(d.theta8_rad));
    // The returned (θ5, θ8) minimise the PIP loop error: evaluated independently it equals the reported
    // residual, and no point of a 0.5° grid does better.
    const double best = loopErrors(m, d.theta1_rad, d.x3_m, d.theta4_rad, d.theta5_rad, d.theta6r_rad,
                                   d.theta8_rad)[1];
    EXPECT_NEAR(best, d.residual_m[1], 1e-12);
    if (fallbacks > 2) continue;  // the grid search is slow: two poses suffice
    double grid_min = std::numeric_limits<double>::infinity();
    for (double t5 = -180; t5 < 180; t5 += 0.5) {
      for (double t8 = -180; t8 < 180; t8 += 0.5) {
        grid_min = std::min(grid_min, loopErrors(m, d.theta1_rad, d.x3_m, d.theta4_rad, t5 * kDeg,
                                                 d.theta6r_rad, t8 * kDeg)[1]);
      }
    }
    EXPECT_GE(grid_min, best - 1e-12);
    EXPECT_LT(grid_min - best, 5e-4);  // the grid comes close: the fallback is the minimum, not just a bound
  }
  EXPECT_GE(fallbacks, 3) << "the readings did not exercise the fallback";
}

TEST(SeaEstimator, NonFiniteSensorIsRejectedWithZeroOutputs) {
  const Model<double> m = model();
  D d;
  Sensors<double> s{0.1, 1.0, 0.5, 0.2, std::numeric_limits<double>::quiet_NaN()};
  EXPECT_EQ(computeFromSensors(m, s, d), Status::kNonFiniteInput);
  EXPECT_EQ(d.theta4_rad, 0.0);
  EXPECT_FALSE(d.J_valid);
  EXPECT_EQ(computeFromFinger(m, FingerAngles<double>{0.0, std::numeric_limits<double>::infinity(), 0.0, 0.0}, d),
            Status::kNonFiniteInput);
}

TEST(SeaKinematics, SinglePrecisionInstantiationAgreesWithDouble) {
  const Model<float> mf = defaultModel<float>();
  const Model<double> md = model();
  Data<float> f;
  D d;
  ASSERT_EQ(computeFromFinger(mf, FingerAngles<float>{-0.5f, -0.7f, -0.3f, 0.0f}, f), Status::kOk);
  ASSERT_EQ(computeFromFinger(md, FingerAngles<double>{-0.5, -0.7, -0.3, 0.0}, d), Status::kOk);
  for (std::size_t i = 0; i < kNumSensors; ++i) {
    EXPECT_NEAR(static_cast<double>(f.sensors_rad[i]), d.sensors_rad[i], 1e-4);
  }
  Data<float> e;
  ASSERT_EQ(computeFromSensors(mf, f.sensors_rad, e), Status::kOk);
  EXPECT_NEAR(static_cast<double>(e.theta8_rad), -0.7, 2e-4);
}

TEST(SeaKinematics, RedundantPredictionEqualsTheRedundantSensorReading) {
  const Model<double> m = model();
  D plant;
  ASSERT_EQ(computeFromFinger(m, finger(-20, -50, -10), plant), Status::kOk);
  double res = -1;
  const double y = predictRedundant(m.subject, m.fixed, plant.sensors_rad[kSensorExoMcp],
                                    plant.sensors_rad[kSensorExoPip], &res);
  EXPECT_NEAR(y, plant.sensors_rad[kSensorRedundant], 1e-12);
  EXPECT_EQ(res, 0.0);
}
