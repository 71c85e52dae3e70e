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
  // Joint angles relative to home: the hand holds the pen near home (these arbitrary torques tilt it by up to
  // ≈ 15° against the grip's 0.5 N·m/rad within the 50 ms; the firmware windows are ≥ 40°).
  for (std::size_t i = 0; i < 6; ++i) EXPECT_LT(std::fabs(tel.value[i]), 0.35);
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

// A frozen encoder (its count held, as firmware-sim's sensor-stuck injects it) while the hand moves the pen: the
// other five encoders move the pen's ends apart from one pen length and the rigid-pen watch latches kSensorStuck.
// Each of the six joints, the hand moving the pen through the workspace (random, seeded).
TEST(PantographFirmware, AFrozenEncoderWhileThePenMovesLatchesSensorStuckAndGoesSafe) {
  for (int joint = 0; joint < 6; ++joint) {
    PenRig r(sim::PenHandScenario::kRandom);
    ASSERT_EQ(r.rig.handshake(), "");
    r.rig.run(0.5);
    ASSERT_EQ(r.rig.core().faultBits(), 0) << "joint " << joint;
    int32_t held = 0;
    bool first = true;
    r.rig.setIoHook([&](sim::SimIo& io) {
      if (first) held = io.encoder[joint];
      first = false;
      io.encoder[joint] = held;
    });
    long ticks = 0;
    while (!(r.rig.core().faultBits() & protocol::fault::kSensorStuck) && ticks < 3000) {
      r.rig.step();
      ++ticks;
    }
    EXPECT_EQ(r.rig.core().faultBits(), protocol::fault::kSensorStuck) << "joint " << joint << " after " << ticks << " ticks";
    EXPECT_GE(ticks, static_cast<long>(apps::pantographDefaultConfig().ends_inconsistent_ticks)) << "joint " << joint;
    EXPECT_FALSE(r.rig.board().io().pwm_enabled) << "joint " << joint;
    std::printf("joint %d frozen: sensor-stuck after %ld ticks\n", joint, ticks);
  }
}

// The same encoder frozen while the hand holds the pen still: nothing it should have seen has happened, so no
// fault (an encoder's count is legitimately constant on a still pen).
TEST(PantographFirmware, AFrozenEncoderOnAStillPenIsNoFault) {
  PenRig r(sim::PenHandScenario::kHold);
  ASSERT_EQ(r.rig.handshake(), "");
  r.rig.run(0.2);
  r.rig.setIoHook([held = r.rig.board().io().encoder[1]](sim::SimIo& io) { io.encoder[1] = held; });
  r.rig.run(2.0);
  EXPECT_EQ(r.rig.core().faultBits(), 0);
}

/// The joint angles of every pose of a 7⁵ grid over the plant's soft-stop workspace (pen::computeInverse).
template <class Fn>
void forEachSoftStopPose(const pen::Model<double>& model, Fn fn) {
  const sim::PenPlantParams p;
  const int n = 7;
  auto lerp = [&](std::size_t k, int i) { return p.stop_lo[k] + (p.stop_hi[k] - p.stop_lo[k]) * i / (n - 1); };
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      for (int c = 0; c < n; ++c)
        for (int d = 0; d < n; ++d)
          for (int e = 0; e < n; ++e) {
            const pen::PenPose<double> pose{{lerp(0, a), lerp(1, b), lerp(2, c)}, lerp(3, d), lerp(4, e)};
            pen::JointVec<double> q;
            ASSERT_EQ(pen::computeInverse(model, pose, q), pen::Status::kOk);
            fn(q);
          }
}

}  // namespace

// The rigid-pen watch must never trip on a sound pen: at every pose of the soft-stop workspace grid, the encoder
// counts of the true joint angles place the pen's ends (in the firmware's single precision) within half the
// tolerance of one pen length.
TEST(PantographFirmware, SoundEncodersDescribeOneRigidPenAcrossTheSoftStopWorkspace) {
  const auto model = pen::defaultModel<double>();
  const auto model_f = pen::defaultModel<float>();
  double worst = 0.0;
  forEachSoftStopPose(model, [&](const pen::JointVec<double>& q) {
    const auto counts = pen::countsFromAngles(model, q);
    pen::JointVec<float> qf{};
    for (std::size_t i = 0; i < 6; ++i) qf[i] = model_f.q_home_rad[i] + static_cast<float>(counts[i]) * 6.28318530718f / 4000.0f;
    pen::Data<float> kin{};
    const pen::Status s = pen::computeEnds(model_f, qf, kin);
    EXPECT_TRUE(s == pen::Status::kOk || s == pen::Status::kSingular) << static_cast<int>(s);
    if (s == pen::Status::kOk) worst = std::max(worst, std::fabs(static_cast<double>(kin.length_m) - pen::penLength(model)));
  });
  EXPECT_LT(worst, 0.5 * model.ends_tolerance_m);
  std::printf("worst pen-length error from quantised encoders, float: %.3f mm\n", worst * 1e3);
}

// The firmware's joint windows are compile-time constants; they must contain every joint angle the default
// geometry (pen::defaultModel, the one the plant and the host use) reaches inside the plant's soft stops, with
// margin. A geometry change that invalidates them fails here.
TEST(PantographFirmware, JointWindowsContainTheSoftStopWorkspace) {
  const auto model = pen::defaultModel<double>();
  const apps::PantographConfig fw = apps::pantographDefaultConfig();
  const double margin = 10.0 * 3.14159265358979323846 / 180.0;
  forEachSoftStopPose(model, [&](const pen::JointVec<double>& q) {
    for (std::size_t i = 0; i < 6; ++i) {
      const double rel = q[i] - model.q_home_rad[i];
      EXPECT_GT(rel, static_cast<double>(fw.joint_min_rad[i]) + margin) << "joint " << i;
      EXPECT_LT(rel, static_cast<double>(fw.joint_max_rad[i]) - margin) << "joint " << i;
    }
  });
}
