// SEA finger host controller: estimator, finger-torque mapping (eq 9–11), transparency, no allocation per
// cycle (phalanx/host/sea/sea_finger_controller.h, seeds/001 §5.2, §7.7).
#include "phalanx/host/sea/sea_finger_controller.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>

#include "../support/counting_allocator.h"  // g_allocations

namespace {

using namespace phalanx::host::sea;
using phalanx::host::TelemetryFrame;
using phalanx::protocol::Command;
using phalanx::protocol::Mode;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/// Telemetry of the finger at (mcp, pip, dip) degrees with SEA torques τ̂_j, device clock t_us.
TelemetryFrame telemetry(double mcp, double pip, double dip, Vec2 tau_j, uint64_t t_us, Mode mode) {
  ps::Data<double> d;
  ps::computeFromFinger(ps::defaultModel<double>(), ps::FingerAngles<double>{mcp * kDeg, pip * kDeg, dip * kDeg, 0.0},
                        d);
  TelemetryFrame tel;
  tel.device_time_us = t_us;
  tel.mode = mode;
  tel.sample_count = 11;
  for (size_t i = 0; i < ps::kNumSensors; ++i) tel.value[kSampleSensor0 + i] = static_cast<float>(d.sensors_rad[i]);
  tel.value[kSampleSeaTorque0] = static_cast<float>(tau_j[0]);
  tel.value[kSampleSeaTorque0 + 1] = static_cast<float>(tau_j[1]);
  return tel;
}

SeaFingerControllerConfig constantTorque(double mcp_Nm, double pip_Nm) {
  SeaFingerControllerConfig c;
  c.profile.amplitude_Nm = {0.0, 0.0};
  c.profile.mean_Nm = {mcp_Nm, pip_Nm};
  c.ramp_s = 0.0;
  return c;
}

}  // namespace

TEST(SeaFingerController, TransparentModeCommandsZeroTorqueEverywhere) {
  SeaFingerControllerConfig c;
  c.mode = SeaFingerMode::kTransparent;
  SeaFingerController ctl(c);
  for (double mcp : {0.0, -30.0, -60.0}) {
    for (double pip : {0.0, -40.0, -80.0}) {
      Command cmd;
      cmd.setpoint[0] = cmd.setpoint[1] = 9.0f;
      ctl.update(telemetry(mcp, pip, -10, {0.02, -0.01}, 1000, Mode::kTransparent), 1.0, 0.001, cmd);
      EXPECT_EQ(cmd.mode, Mode::kTransparent);
      EXPECT_EQ(cmd.setpoint[0], 0.0f);
      EXPECT_EQ(cmd.setpoint[1], 0.0f);
    }
  }
}

TEST(SeaFingerController, ZeroFingerTorqueAtRestGivesZeroExoTorque) {
  SeaFingerController ctl(constantTorque(0.0, 0.0));
  Command cmd;
  ctl.update(telemetry(-20, -30, -10, {0.0, 0.0}, 1000, Mode::kSetpoint), 2.0, 0.001, cmd);
  EXPECT_EQ(cmd.mode, Mode::kSetpoint);
  EXPECT_EQ(cmd.setpoint[0], 0.0f);
  EXPECT_EQ(cmd.setpoint[1], 0.0f);
}

TEST(SeaFingerController, FingerTorqueSetpointIsJnTransposeTimesDesiredAndDoesTheSameVirtualWork) {
  const Vec2 y_d{0.1, -0.03};
  SeaFingerController ctl(constantTorque(y_d[0], y_d[1]));
  Command cmd;
  ctl.update(telemetry(-25, -45, -15, {0.0, 0.0}, 1000, Mode::kSetpoint), 2.0, 0.001, cmd);
  ASSERT_EQ(cmd.mode, Mode::kSetpoint);
  ps::Data<double> d;
  ps::computeFromFinger(ps::defaultModel<double>(), ps::FingerAngles<double>{-25 * kDeg, -45 * kDeg, -15 * kDeg, 0.0}, d);
  // Virtual work: τ_j·Θ̇_r = y_d·(θ̇4, θ̇8) for Θ̇_r = (1, 0) and (0, 1) (float setpoints, 1e-4-rad telemetry).
  for (size_t c = 0; c < 2; ++c) {
    const double p_exo = static_cast<double>(cmd.setpoint[c]);
    const double p_finger = y_d[0] * d.J[1][c] + y_d[1] * d.J[3][c];
    EXPECT_NEAR(p_exo, p_finger, 1e-3 * (1.0 + std::fabs(p_finger)));
  }
  EXPECT_GT(std::fabs(cmd.setpoint[0]), 0.01f);
}

TEST(SeaFingerController, SaturationScalesBothJointsAndKeepsTheFingerTorqueDirection) {
  SeaFingerControllerConfig c = constantTorque(3.0, -1.0);  // far beyond 0.5 N·m at the exo joints
  SeaFingerController ctl(c);
  Command cmd;
  ctl.update(telemetry(-25, -45, -15, {0.0, 0.0}, 1000, Mode::kSetpoint), 2.0, 0.001, cmd);
  const double t0 = static_cast<double>(cmd.setpoint[0]);
  const double t1 = static_cast<double>(cmd.setpoint[1]);
  EXPECT_LE(std::fmax(std::fabs(t0), std::fabs(t1)), c.limits.max_exo_torque_Nm + 1e-6);
  EXPECT_NEAR(std::fmax(std::fabs(t0), std::fabs(t1)), c.limits.max_exo_torque_Nm, 1e-6);
  // The finger torque these produce (eq 9) points the same way as the request.
  Vec2 f{};
  ASSERT_EQ(ps::fingerTorqueFromExoTorque(ctl.estimator().data().J_n, Vec2{t0, t1}, 1e-9, f), ps::Status::kOk);
  EXPECT_NEAR(f[1] / f[0], -1.0 / 3.0, 1e-4);
  EXPECT_GT(f[0], 0.0);
  EXPECT_LT(ctl.lastMap().scale, 1.0);
  EXPECT_EQ(ctl.stats().saturated, 1);
}

TEST(SeaFingerController, FingerTorqueEstimateIsTheInverseMappingOfTheSeaTorques) {
  // eq 9: with SEA torques τ̂_j = J_nᵀ y the estimate ŷ is y.
  SeaFingerController ctl(constantTorque(0.0, 0.0));
  ps::Data<double> d;
  ps::computeFromFinger(ps::defaultModel<double>(), ps::FingerAngles<double>{-40 * kDeg, -20 * kDeg, -15 * kDeg, 0.0}, d);
  const Vec2 y{0.08, 0.02};
  const Vec2 tau_j = ps::exoTorqueFromFingerTorque(d.J_n, y);
  Command cmd;
  ctl.update(telemetry(-40, -20, -15, tau_j, 1000, Mode::kSetpoint), 2.0, 0.001, cmd);
  ASSERT_TRUE(ctl.lastMap().tau_f_hat_valid);
  EXPECT_NEAR(ctl.lastMap().tau_f_hat_Nm[0], y[0], 2e-3);  // float telemetry (1e-4 rad, float torque)
  EXPECT_NEAR(ctl.lastMap().tau_f_hat_Nm[1], y[1], 2e-3);
}

TEST(SeaFingerController, InvalidSensorsGiveZeroTorqueNeverAStaleSetpoint) {
  SeaFingerController ctl(constantTorque(0.1, 0.02));
  Command cmd;
  ctl.update(telemetry(-25, -45, -15, {0, 0}, 1000, Mode::kSetpoint), 2.0, 0.001, cmd);
  ASSERT_NE(cmd.setpoint[0], 0.0f);
  TelemetryFrame bad = telemetry(-25, -45, -15, {0, 0}, 2000, Mode::kSetpoint);
  bad.value[1] = std::numeric_limits<float>::quiet_NaN();
  ctl.update(bad, 2.001, 0.001, cmd);
  EXPECT_EQ(cmd.mode, Mode::kTransparent);
  EXPECT_EQ(cmd.setpoint[0], 0.0f);
  EXPECT_EQ(cmd.setpoint[1], 0.0f);
  // A reading where the MCP chain cannot close (θ1r pointing at the finger MCP joint): no valid J_n either.
  TelemetryFrame singular = telemetry(-25, -45, -15, {0, 0}, 3000, Mode::kSetpoint);
  singular.value[0] = static_cast<float>(-90 * kDeg);
  ctl.update(singular, 2.002, 0.001, cmd);
  EXPECT_EQ(cmd.mode, Mode::kTransparent);
  EXPECT_EQ(cmd.setpoint[0], 0.0f);
  EXPECT_EQ(ctl.stats().invalid_kinematics, 2);
}

TEST(SeaFingerController, ProfileIsEq18WithASmoothRampIn) {
  SeaFingerControllerConfig c;
  c.profile.amplitude_Nm = {0.1, 0.02};
  c.profile.mean_Nm = {0.01, 0.0};
  c.profile.phase_rad = {0.0, 1.0};
  c.profile.frequency_hz = 0.5;
  c.ramp_s = 0.5;
  SeaFingerController ctl(c);
  Vec2 y{};
  Vec2 yr{};
  ctl.desired(0.0, y, yr);
  EXPECT_EQ(y[0], 0.0);
  EXPECT_EQ(y[1], 0.0);
  ctl.desired(1.3, y, yr);
  EXPECT_NEAR(y[0], 0.1 * std::sin(M_PI * 1.3) + 0.01, 1e-12);
  EXPECT_NEAR(y[1], 0.02 * std::sin(M_PI * 1.3 + 1.0), 1e-12);
  // The rate is the derivative of the profile, ramp included.
  for (double t : {0.2, 0.45, 1.3}) {
    Vec2 a{};
    Vec2 b{};
    Vec2 unused{};
    ctl.desired(t + 1e-6, a, unused);
    ctl.desired(t - 1e-6, b, unused);
    ctl.desired(t, y, yr);
    EXPECT_NEAR(yr[0], (a[0] - b[0]) / 2e-6, 1e-6);
    EXPECT_NEAR(yr[1], (a[1] - b[1]) / 2e-6, 1e-6);
  }
}

TEST(SeaEstimatorClass, JnRateFollowsEq20OnTheDeviceClock) {
  SeaEstimator est;
  ps::Data<double> d0;
  ps::Data<double> d1;
  const ps::Model<double> m = ps::defaultModel<double>();
  ps::computeFromFinger(m, ps::FingerAngles<double>{-0.4, -0.6, -0.2, 0.0}, d0);
  ps::computeFromFinger(m, ps::FingerAngles<double>{-0.401, -0.602, -0.2, 0.0}, d1);
  est.update(d0.sensors_rad, 0.0);
  EXPECT_EQ(est.jacobianNRate()[0][0], 0.0);  // one Jacobian: no rate yet
  est.update(d1.sensors_rad, 0.002);
  for (size_t i = 0; i < 2; ++i) {
    for (size_t j = 0; j < 2; ++j) {
      EXPECT_NEAR(est.jacobianNRate()[i][j], (d1.J_n[i][j] - d0.J_n[i][j]) / 0.002, 1e-9);
    }
  }
  // A repeated frame (dt = 0) holds the rate.
  const double held = est.jacobianNRate()[1][1];
  est.update(d1.sensors_rad, 0.0);
  EXPECT_EQ(est.jacobianNRate()[1][1], held);
}

TEST(SeaFingerControllerRealtime, UpdateDoesNotAllocate) {
  SeaFingerController ctl(SeaFingerControllerConfig{});
  TelemetryFrame tel[50];
  for (int k = 0; k < 50; ++k) {
    tel[k] = telemetry(-30 + 20 * std::sin(0.1 * k), -40 + 30 * std::sin(0.13 * k), -20, {0.01, 0.0},
                       1000u * static_cast<unsigned>(k + 1), Mode::kSetpoint);
  }
  Command cmd;
  ctl.update(tel[0], 0.0, 0.001, cmd);
  const long before = g_allocations.load();
  for (int i = 0; i < 2000; ++i) {
    TelemetryFrame t = tel[i % 50];
    t.device_time_us = 1000u * static_cast<unsigned>(i + 2);
    ctl.update(t, 0.001 * i, 0.001, cmd);
  }
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0);
  EXPECT_EQ(ctl.stats().invalid_kinematics, 0);
  // And the counter works: an allocation in this scope is seen.
  auto* probe = new int(3);
  EXPECT_EQ(g_allocations.load() - after, 1);
  delete probe;
}
