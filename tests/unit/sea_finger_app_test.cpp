// The sea_finger firmware app on a simulated board without a plant: counts written by the test, so the
// eq 7 estimate, the moving average, the watchdogs, the limits and the parameters are checked in isolation.
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/apps/sea_finger.h"
#include "phalanx/sea/board.h"
#include "phalanx/sim/board.h"

using namespace phalanx;
namespace board = phalanx::sea::board;

namespace {

const double kRm = static_cast<double>(board::kMotorPulleyRadius_m);  // motor pulley radius r_m

struct AppRig {
  AppRig() : sim(board::kPwmChannelCount, board::kAdcChannelCount, board::kEncoderChannelCount, pipe.end(0)),
             app(apps::seaFingerDefaultCalibration(), apps::seaFingerDefaultConfig()) {
    for (auto& a : sim.io().adc) a = board::kAdcMidCounts;
    app.init(sim.board());
  }
  uint16_t sense(int ticks = 1) {
    uint16_t f = 0;
    for (int i = 0; i < ticks; ++i) f |= app.sense(1e-3f);
    return f;
  }
  void zero() {
    while (!app.zeroed()) sense();
  }
  sim::BytePipe pipe;
  sim::SimBoard sim;
  apps::SeaFingerApp app;
};

protocol::Command setpoint(float mcp, float pip) {
  protocol::Command c;
  c.mode = protocol::Mode::kSetpoint;
  c.channel_count = 2;
  c.timeout_ms = 20;
  c.setpoint[0] = mcp;
  c.setpoint[1] = pip;
  for (auto& g : c.gain_scale_permille) g = 1000;
  return c;
}

}  // namespace

TEST(SeaFingerApp, Eq7EstimateFromEncoderAndJointCounts) {
  AppRig r;
  r.zero();
  // Motor 0 turned by 3000 counts, joint 0 by +40 counts; motor 1 by −1000 counts, joint 1 unmoved.
  // Ramped over 300 ticks, so that the motor keeps dragging the cable through the play model.
  for (int i = 1; i <= 300; ++i) {
    r.sim.io().encoder[0] = 10 * i;
    r.sim.io().encoder[1] = -1000 * i / 300;
    r.sim.io().adc[board::kAdcFirstJoint] = board::kAdcMidCounts + 40 * i / 300;
    r.sense(1);
  }
  r.sense(32);  // fill the moving average
  const double th_m0 = 3000.0 * 2.0 * M_PI / (2048.0 * 33.0);
  const double th_j0 = 40.0 / (0.9 * 4096.0 / M_PI);
  const double expect0 = 2.0 * 2816.0 * 0.010 * (kRm * th_m0 - 0.010 * th_j0);
  EXPECT_NEAR(r.app.channel(0).tau_eq7_Nm, expect0, 1e-5);
  const double th_m1 = -1000.0 * 2.0 * M_PI / (2048.0 * 33.0);
  EXPECT_NEAR(r.app.channel(1).tau_eq7_Nm, 2.0 * 744.0 * 0.010 * kRm * th_m1, 1e-6);
  // Dragged forward, the play model's spring side trails the motor side by half the play (b_0 + b_1|τ|)/2.
  const auto& c = r.app.channel(0);
  const double half = 0.5 * (0.4e-3 + 2.0e-3 * std::fabs(static_cast<double>(c.tau_play_Nm)));
  EXPECT_NEAR(c.tau_eq7_Nm - c.tau_play_Nm, 2.0 * 2816.0 * 0.010 * half, 2e-4);
}

TEST(SeaFingerApp, JointSensorsAreMovingAveraged) {
  AppRig r;
  r.zero();
  r.sim.io().adc[board::kAdcFirstJoint + 2] = board::kAdcMidCounts + 80;
  r.sense(1);
  const float step = 80.0f / board::kJointCountsPerRad;
  const float centre = board::kJointCentre_rad[2];
  EXPECT_NEAR(r.app.jointSensor_rad(2), centre + step / 8.0f, 1e-6f) << "one new sample in a window of 8";
  r.sense(7);
  EXPECT_NEAR(r.app.jointSensor_rad(2), centre + step, 1e-6f);
}

TEST(SeaFingerApp, ZeroingTakesTheRestingJointAngleAsThetaJ0) {
  AppRig r;
  r.sim.io().adc[board::kAdcFirstJoint] = board::kAdcMidCounts + 100;
  r.sim.io().encoder[0] = 555;
  r.zero();
  r.sense(1);
  EXPECT_NEAR(r.app.channel(0).joint_rad, 0.0f, 1e-3f);
  EXPECT_NEAR(r.app.channel(0).motor_rad, 0.0f, 1e-9f);
  EXPECT_NEAR(r.app.channel(0).tau_eq7_Nm, 0.0f, 1e-3f);
}

TEST(SeaFingerApp, MotorAngleBeyondSixtyDegreesIsAFault) {
  AppRig r;
  r.zero();
  const auto counts_60deg = static_cast<int32_t>(std::lround((M_PI / 3.0) / static_cast<double>(board::kMotorRadPerCount)));
  r.sim.io().encoder[1] = counts_60deg - 5;
  EXPECT_EQ(r.sense() & protocol::fault::kMotorAngle, 0);
  r.sim.io().encoder[1] = counts_60deg + 5;
  EXPECT_NE(r.sense() & protocol::fault::kMotorAngle, 0);
  r.sim.io().encoder[1] = -counts_60deg - 5;
  EXPECT_NE(r.sense() & protocol::fault::kMotorAngle, 0);
}

TEST(SeaFingerApp, OpenOrShortedJointSensorIsARangeFault) {
  AppRig r;
  r.zero();
  r.sim.io().adc[board::kAdcFirstJoint + 4] = 0;
  EXPECT_NE(r.sense() & protocol::fault::kSensorRange, 0);
  r.sim.io().adc[board::kAdcFirstJoint + 4] = 4095;
  EXPECT_NE(r.sense() & protocol::fault::kSensorRange, 0);
}

// A frozen SEA joint sensor (a stuck ADC channel) while the finger moves: the redundant and DIP sensors change
// every tick, the MCP sensor's count does not. sensor-stuck on the 250th unchanged tick, not before.
TEST(SeaFingerApp, FrozenJointSensorWhileTheFingerMovesIsASensorStuckFault) {
  for (int sea = 0; sea < 2; ++sea) {
    AppRig r;
    r.zero();
    auto& adc = r.sim.io().adc;
    uint16_t faults = 0;
    int tick = 0;
    while (tick < 400 && (faults & protocol::fault::kSensorStuck) == 0) {
      ++tick;
      adc[board::kAdcFirstJoint + 2] = board::kAdcMidCounts + tick % 50;        // the finger flexes
      adc[board::kAdcFirstJoint + 3] = board::kAdcMidCounts - tick % 30;
      adc[board::kAdcFirstJoint + 1 - sea] = board::kAdcMidCounts + tick % 20;  // the other SEA's joint too
      faults = r.sense();
    }
    // The watch starts on the first tick after zeroing (the differentiators restart there): unchanged from the
    // second tick on, the 250th unchanged tick is tick 251.
    EXPECT_EQ(tick, 251) << "SEA " << sea;
    EXPECT_EQ(faults & ~protocol::fault::kSensorStuck, 0);
  }
}

// What must not trip it: a still finger on a noise-free board (every count steady), the §7.1 rig (one clamped SEA
// joint driven, the other still, the redundant and DIP sensors on an unmoving fixture), and a live sensor whose
// count changes even rarely while the finger moves.
TEST(SeaFingerApp, StillFingerRigAndLiveSensorAreNotStuck) {
  AppRig r;
  r.zero();
  auto& adc = r.sim.io().adc;
  EXPECT_EQ(r.sense(1000) & protocol::fault::kSensorStuck, 0);  // everything still
  for (int i = 0; i < 1000; ++i) {                                // the rig: MCP joint loaded, PIP still
    adc[board::kAdcFirstJoint] = board::kAdcMidCounts + (i / 5) % 40;
    EXPECT_EQ(r.sense() & protocol::fault::kSensorStuck, 0) << i;
  }
  for (int i = 0; i < 2000; ++i) {  // the finger moves; the SEA sensors change with it, but only every 200 ticks
    adc[board::kAdcFirstJoint + 2] = board::kAdcMidCounts + i % 50;
    adc[board::kAdcFirstJoint + 3] = board::kAdcMidCounts - i % 30;
    adc[board::kAdcFirstJoint + 0] = board::kAdcMidCounts + (i / 200 + 1) % 2;
    adc[board::kAdcFirstJoint + 1] = board::kAdcMidCounts - (i / 200 + 1) % 2;
    EXPECT_EQ(r.sense() & protocol::fault::kSensorStuck, 0) << i;
  }
}

TEST(SeaFingerApp, SetpointsAreClampedToTheTorqueLimitsAndTheMotorCommandToItsWindow) {
  AppRig r;
  r.zero();
  // The PIP joint flexed by −70° since zeroing: eq 8's feed-forward alone asks for (r_j/r_m)·(−70°) = −47°, and
  // −0.15 N·m another −39°: the command stops at −55°.
  r.sim.io().adc[board::kAdcFirstJoint + 1] =
      board::kAdcMidCounts - static_cast<int32_t>(std::lround(70.0 * M_PI / 180.0 * static_cast<double>(board::kJointCountsPerRad)));
  r.sense(32);
  const auto cfg = apps::seaFingerDefaultConfig();
  r.app.control(setpoint(0.9f, -0.9f), 1e-3f);
  EXPECT_FLOAT_EQ(r.app.channel(0).tau_desired_Nm, cfg.max_torque_Nm[0]);
  EXPECT_FLOAT_EQ(r.app.channel(1).tau_desired_Nm, -cfg.max_torque_Nm[1]);
  EXPECT_FALSE(r.app.channel(0).command_limited);
  EXPECT_TRUE(r.app.channel(1).command_limited);
  EXPECT_FLOAT_EQ(r.app.channel(1).u_rad, -cfg.motor_command_limit_rad);
  for (int i = 0; i < 2; ++i) {
    EXPECT_LE(std::fabs(r.sim.io().pwm_duty[static_cast<size_t>(i)]), cfg.max_duty);
  }
}

TEST(SeaFingerApp, TransparentModeTracksZeroTorque) {
  AppRig r;
  r.zero();
  r.sense();
  protocol::Command c = setpoint(0.3f, 0.1f);
  c.mode = protocol::Mode::kTransparent;
  r.app.control(c, 1e-3f);
  EXPECT_EQ(r.app.channel(0).tau_desired_Nm, 0.0f);
  EXPECT_EQ(r.app.channel(1).tau_desired_Nm, 0.0f);
}

TEST(SeaFingerApp, SustainedOvertorqueIsAForceLimitFault) {
  AppRig r;
  r.zero();
  // 0.7 N·m on the MCP SEA (beyond the 0.6 N·m fault level) with the joint held: θ_m = 0.7 / (2 k r_j r_m).
  const double th_m = 0.7 / (2.0 * 2816.0 * 0.010 * kRm);
  r.sim.io().encoder[0] = static_cast<int32_t>(th_m / static_cast<double>(board::kMotorRadPerCount));
  uint16_t faults = 0;
  for (int i = 0; i < 60 && faults == 0; ++i) {
    faults |= static_cast<uint16_t>(r.sense() & ~protocol::fault::kMotorAngle);
    faults |= r.app.control(setpoint(0.0f, 0.0f), 1e-3f);
  }
  EXPECT_NE(faults & protocol::fault::kForceLimit, 0);
}

TEST(SeaFingerApp, ParametersAreValidated) {
  AppRig r;
  float v = -1.0f;
  EXPECT_EQ(r.app.getParam(apps::sea_param::kController, v), protocol::ParamStatus::kOk);
  EXPECT_EQ(v, 0.0f);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kController, 1.0f), protocol::ParamStatus::kOk);
  EXPECT_EQ(r.app.config().controller, apps::SeaControllerKind::kPaper);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kController, 2.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kJointMovingAverage, 0.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kJointMovingAverage, 4.5f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kJointMovingAverage, 33.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kJointMovingAverage, 16.0f), protocol::ParamStatus::kOk);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kKp + 1, 0.7f), protocol::ParamStatus::kOk);
  EXPECT_EQ(r.app.getParam(apps::sea_param::kKp + 1, v), protocol::ParamStatus::kOk);
  EXPECT_FLOAT_EQ(v, 0.7f);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kKp + 2, 0.7f), protocol::ParamStatus::kUnknownParam);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kKi, -1.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kBacklashCompensation, 3.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kZero, 2.0f), protocol::ParamStatus::kOutOfRange);
  EXPECT_EQ(r.app.setParam(apps::sea_param::kZero, 1.0f), protocol::ParamStatus::kOk);
  EXPECT_FALSE(r.app.zeroed());
}

TEST(SeaFingerApp, NothingIsDrivenBeforeZeroingEnds) {
  AppRig r;
  r.sense();
  r.app.control(setpoint(0.3f, 0.1f), 1e-3f);
  EXPECT_EQ(r.sim.io().pwm_duty[0], 0.0f);
  EXPECT_EQ(r.sim.io().pwm_duty[1], 0.0f);
}
