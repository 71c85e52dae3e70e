// The pantograph firmware app on the simulated pen, in lockstep with a host controller that sends fixed torques:
// torque channels, limits, and the safe state on link loss, e-stop and sensor faults.
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/fw_sim/pantograph_sim.h"
#include "phalanx/host/lockstep.h"

using namespace phalanx;

namespace {

class FixedTorque : public host::Controller {
 public:
  const char* name() const override { return "fixed-torque"; }
  void update(const host::TelemetryFrame&, double, double, protocol::Command& cmd) override {
    cmd.mode = protocol::Mode::kSetpoint;
    for (std::size_t i = 0; i < 6; ++i) cmd.setpoint[i] = torque[i];
  }
  std::array<float, 6> torque{};
};

struct PenRig {
  explicit PenRig(sim::PenHandScenario scenario = sim::PenHandScenario::kHold) : device(cfg(scenario)), rig(device, ctl) {}
  static sim::PenPlantConfig cfg(sim::PenHandScenario s) {
    sim::PenPlantConfig c;
    c.scenario = s;
    c.noise = false;
    return c;
  }
  fw_sim::PantographSimDevice device;
  FixedTorque ctl;
  host::LockstepRig rig;
};

TEST(PantographFirmware, SetpointTorquesReachTheMotorsAndTelemetryReportsThem) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {0.1f, -0.2f, 0.3f, -0.4f, 0.5f, -0.6f};
  r.rig.run(0.05);
  const auto& tel = r.rig.session().latest();
  EXPECT_EQ(tel.fault_bits, 0);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_NEAR(r.device.penPlant().truth().motor_torque_Nm[i], r.ctl.torque[i], 1e-5);
    EXPECT_NEAR(tel.value[6 + i], r.ctl.torque[i], 0.01);  // current sense · K_t
  }
  // Joint angles relative to home: the hand holds the pen near home.
  for (std::size_t i = 0; i < 6; ++i) EXPECT_LT(std::fabs(tel.value[i]), 0.2);
}

TEST(PantographFirmware, SetpointBeyondThePeakTorqueIsRejectedAndNeverReachesAMotor) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {0.0f, 0.0f, 2.2f, 0.0f, 0.0f, 0.0f};
  r.rig.run(0.05);
  EXPECT_GT(r.rig.core().counters().commands_rejected, 0u);
  for (double t : r.device.penPlant().truth().motor_torque_Nm) EXPECT_EQ(t, 0.0);
}

TEST(PantographFirmware, LinkLossDrivesTheMotorsOffWithinTheCommandTimeout) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  r.rig.run(0.05);
  ASSERT_TRUE(r.rig.board().io().pwm_enabled);
  r.rig.setHostConnected(false);
  r.rig.run(0.020 + 0.002);  // command timeout 20 ms + two ticks
  EXPECT_FALSE(r.rig.board().io().pwm_enabled);
  r.rig.step();  // the plant sees the bridges off from the next period on
  for (double t : r.device.penPlant().truth().motor_torque_Nm) EXPECT_EQ(t, 0.0);
}

TEST(PantographFirmware, EstopDrivesTheMotorsOffWithinTwoTicks) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {0.5f, 0.5f, 0.5f, 0.5f, 0.5f, 0.5f};
  r.rig.run(0.05);
  r.rig.setIoHook([](sim::SimIo& io) { io.estop_pressed = true; });
  r.rig.run(0.002);
  EXPECT_FALSE(r.rig.board().io().pwm_enabled);
  EXPECT_TRUE(r.rig.core().faultBits() & protocol::fault::kEstop);
}

TEST(PantographFirmware, EncoderGlitchLatchesASensorFaultAndGoesSafe) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {0.2f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  r.rig.run(0.05);
  r.rig.setIoHook([](sim::SimIo& io) { io.encoder[4] += 1000; });
  r.rig.run(0.003);
  EXPECT_TRUE(r.rig.core().faultBits() & protocol::fault::kSensorRange);
  EXPECT_FALSE(r.rig.board().io().pwm_enabled);
}

TEST(PantographFirmware, AmplifierThatDoesNotFollowItsCommandIsAFault) {
  PenRig r;
  ASSERT_EQ(r.rig.handshake(), "");
  r.ctl.torque = {1.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  r.rig.run(0.05);
  ASSERT_EQ(r.rig.core().faultBits(), 0);
  // Current sense of joint 1 stuck at 0 A while 10 A is commanded (broken motor lead).
  r.rig.setIoHook([](sim::SimIo& io) { io.adc[0] = pen::board::kAdcMidCounts; });
  r.rig.run(0.05);
  EXPECT_TRUE(r.rig.core().faultBits() & protocol::fault::kCurrentLimit);
  EXPECT_FALSE(r.rig.board().io().pwm_enabled);
}

}  // namespace
