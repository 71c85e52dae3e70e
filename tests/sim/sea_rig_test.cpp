// Closed loop in lockstep on the simulated §7.1 SEA test rig (seeds/001): the sea_finger firmware app, the
// Bowden-cable SEA plant with sensor noise, the link codec and a host controller streaming the desired torque.
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/apps/sea_finger.h"
#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/sea/board.h"

using namespace phalanx;
using host::sea::SeaBenchOptions;
using host::sea::SeaTrajectoryController;

namespace {

/// Holds a constant torque on the MCP SEA (mode setpoint), or zero torque (transparent).
class HoldController : public host::Controller {
 public:
  HoldController(float torque_Nm, bool transparent) : torque_(torque_Nm), transparent_(transparent) {}
  const char* name() const override { return "hold"; }
  void update(const host::TelemetryFrame&, double, double, protocol::Command& cmd) override {
    cmd.mode = transparent_ ? protocol::Mode::kTransparent : protocol::Mode::kSetpoint;
    for (auto& s : cmd.setpoint) s = 0.0f;
    cmd.setpoint[0] = torque_;
  }
  double startupSettleS() const override { return 0.2; }

 private:
  float torque_;
  bool transparent_;
};

sim::SeaPlantConfig rigConfig() {
  sim::SeaPlantConfig c;
  c.seed = 7;
  return c;
}

}  // namespace

// Issue targets at 0.3 N·m, 0.5 Hz: fidelity ≥ 99.5 %, NRMSE ≤ 3 % (paper: 97.7 %, 11.6 %).
TEST(SeaRigSine, OurControllerTracks300mNmAt05HzWithinTheTargets) {
  SeaBenchOptions o;
  o.controller = "ours";
  const auto r = host::sea::benchRigSine(o);
  const auto& c = r["controllers"]["ours"];
  EXPECT_EQ(c["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_GE(c["fidelity_percent"].get<double>(), 99.5) << r.dump(2);
  EXPECT_LE(c["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
  EXPECT_LT(c["peak_motor_angle_deg"].get<double>(), 60.0);
}

TEST(SeaRigSine, OurControllerTracks150mNmWithinTheTargets) {
  SeaBenchOptions o;
  o.controller = "ours";
  o.peak_Nm = 0.15;
  const auto r = host::sea::benchRigSine(o);
  const auto& c = r["controllers"]["ours"];
  EXPECT_GE(c["fidelity_percent"].get<double>(), 99.5) << r.dump(2);
  EXPECT_LE(c["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
}

// The paper's plain PID (eq 7–8, 500 Hz) on the same plant: it tracks its own eq 7 estimate, but the estimate
// misses the cable play, so the load cell sees errors of the size the paper reports (Table 1: 9.28 % at 0.15 N·m,
// 11.59 % at 0.3 N·m). It must be clearly worse than ours — otherwise the comparison shows nothing.
TEST(SeaRigSine, PaperBaselineLandsNearTable1AndIsWorseThanOurs) {
  SeaBenchOptions o;
  o.peak_Nm = 0.15;
  const auto r = host::sea::benchRigSine(o);
  const auto& paper = r["controllers"]["paper"];
  const auto& ours = r["controllers"]["ours"];
  EXPECT_EQ(paper["faults"].get<int>(), 0);
  EXPECT_NEAR(paper["nrmse_percent"].get<double>(), 9.28, 3.0) << r.dump(2);
  EXPECT_NEAR(paper["fidelity_percent"].get<double>(), 98.58, 1.5) << r.dump(2);
  EXPECT_GT(paper["nrmse_percent"].get<double>(), 3.0 * ours["nrmse_percent"].get<double>()) << r.dump(2);
  // The baseline's estimate error (not its loop) is what the load cell sees.
  EXPECT_LT(paper["estimate"]["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
}

// Issue target: −3 dB bandwidth ≥ 5 Hz (paper: 2.5 Hz).
TEST(SeaRigChirp, OurControllerHasAtLeastFiveHertzOfTorqueBandwidth) {
  SeaBenchOptions o;
  o.controller = "ours";
  const auto r = host::sea::benchRigChirp(o);
  const auto& c = r["controllers"]["ours"];
  EXPECT_EQ(c["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_GE(c["bandwidth_hz"].get<double>(), 5.0) << r.dump(2);
  // Measured peaking ≈ 2.6 dB near 14 Hz (docs/sea-firmware.md); this bound guards against an under-damped loop.
  EXPECT_LT(c["peak_magnitude_db"].get<double>(), 4.0) << "resonant peaking" << r.dump(2);
}

TEST(SeaRigSafety, WatchdogLatchesAndDisablesTheBridgeWhenTheMotorAngleLeavesSixtyDegrees) {
  fw_sim::SeaFingerSimDevice device(rigConfig());
  HoldController ctl(0.2f, false);
  host::LockstepRig rig(device, ctl);
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.5);
  ASSERT_TRUE(rig.board().io().pwm_enabled);
  ASSERT_EQ(rig.session().latest().fault_bits, 0);
  // A slipping motor coupling, seen as the encoder running past the window: +10° per tick from now on.
  const auto step_counts = static_cast<int32_t>((10.0 * M_PI / 180.0) / static_cast<double>(sea::board::kMotorRadPerCount));
  int32_t offset = 0;
  rig.setIoHook([&](sim::SimIo& io) {
    offset += step_counts;
    io.encoder[0] += offset;
  });
  int ticks = 0;
  while (rig.core().faultBits() == 0 && ticks < 20) {
    rig.step();
    ++ticks;
  }
  EXPECT_NE(rig.core().faultBits() & protocol::fault::kMotorAngle, 0);
  EXPECT_LE(ticks, 8) << "|θ_m| > 60° within 7 ticks of +10° must latch on the tick it is seen";
  EXPECT_FALSE(rig.board().io().pwm_enabled) << "safe state: bridges off";
  rig.run(0.05);
  EXPECT_EQ(rig.session().latest().mode, protocol::Mode::kSafe);
  EXPECT_NE(rig.session().latest().fault_bits & protocol::fault::kMotorAngle, 0);
}

TEST(SeaRigSafety, LinkLossTurnsTheBridgesOffAndTheSeaRelaxes) {
  fw_sim::SeaFingerSimDevice device(rigConfig());
  HoldController ctl(0.25f, false);
  host::LockstepRig rig(device, ctl);
  ASSERT_EQ(rig.handshake(), "");
  rig.run(1.0);
  ASSERT_NEAR(device.seaPlant().truth(0).joint_torque_Nm, 0.25, 0.01);
  rig.setHostConnected(false);
  // Command timeout 20 ms (LockstepOptions): the firmware goes safe on its own within the timeout + 2 ticks.
  rig.run(0.022);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_NE(rig.core().faultBits() & protocol::fault::kCommandTimeout, 0);
  rig.step();
  EXPECT_FALSE(device.seaPlant().truth(0).bridge_on);
  EXPECT_EQ(device.seaPlant().truth(0).motor_current_A, 0.0);
  rig.run(1.0);
  // Unpowered, the spring back-drives the geared motor until the remaining torque is held by friction alone
  // (motor + gearhead + sheath, docs/sea-plant.md: ≤ 0.12 N·m at the joint).
  const auto& t = device.seaPlant().truth(0);
  EXPECT_LT(std::fabs(t.joint_torque_Nm), 0.12);
  EXPECT_LT(std::fabs(t.joint_torque_Nm), 0.5 * 0.25);
}

TEST(SeaRigSafety, LinkLossInTransparentModeLeavesNoTorque) {
  fw_sim::SeaFingerSimDevice device(rigConfig());
  HoldController ctl(0.0f, true);
  host::LockstepRig rig(device, ctl);
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.2);
  double peak = 0.0, sq = 0.0;
  const int n = 500;
  for (int i = 0; i < n; ++i) {
    rig.step();
    const double tau = device.seaPlant().truth(0).joint_torque_Nm;
    peak = std::fmax(peak, std::fabs(tau));
    sq += tau * tau;
  }
  // Transparent on the clamped joint: only sensor noise moves the loop.
  EXPECT_LT(std::sqrt(sq / n), 0.003);
  EXPECT_LT(peak, 0.010);
  rig.setHostConnected(false);
  rig.run(0.5);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  // Unpowered, friction holds at most what was there when the link went.
  EXPECT_LT(std::fabs(device.seaPlant().truth(0).joint_torque_Nm), peak + 1e-3);
  RecordProperty("transparent_rms_Nm", std::to_string(std::sqrt(sq / n)));
  RecordProperty("transparent_peak_Nm", std::to_string(peak));
}

TEST(SeaRigSafety, TorqueSetpointBeyondTheDeviceLimitIsRejectedAndNothingMoves) {
  fw_sim::SeaFingerSimDevice device(rigConfig());
  HoldController ctl(1.5f, false);  // |τ| > 1 N·m: the layout's hard limit
  host::LockstepRig rig(device, ctl);
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.2);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_EQ(rig.session().lastEvent().code, protocol::EventCode::kCommandRejected);
  EXPECT_EQ(rig.session().lastEvent().detail, static_cast<uint8_t>(protocol::RejectReason::kOutOfRange));
  EXPECT_NEAR(device.seaPlant().truth(0).motor_angle_rad, 0.0, 1e-9);
}

// The rig runs the sea_finger firmware and answers its handshake as a sea_finger; the device-variant core
// parameter is how a host tells it from the exoskeleton on a finger (docs/protocol.md, "Core parameters").
TEST(SeaRigIdentity, TheRigAndTheFingerReportTheirVariant) {
  for (const auto variant : {sim::SeaVariant::kRig, sim::SeaVariant::kFinger}) {
    sim::SeaPlantConfig c = rigConfig();
    c.variant = variant;
    fw_sim::SeaFingerSimDevice device(c);
    HoldController ctl(0.0f, true);
    host::LockstepRig rig(device, ctl);
    ASSERT_EQ(rig.handshake(), "");
    EXPECT_EQ(rig.session().deviceInfo().device_type, protocol::DeviceType::kSeaFinger);
    rig.session().sendParamGet(protocol::core_param::kDeviceVariant);
    rig.run(0.01);
    ASSERT_TRUE(rig.session().lastParamValid());
    EXPECT_EQ(rig.session().lastParam().status, protocol::ParamStatus::kOk);
    EXPECT_EQ(rig.session().lastParam().value,
              static_cast<float>(variant == sim::SeaVariant::kRig ? protocol::variant::kSeaTestRig
                                                                  : protocol::variant::kStandard));
  }
}
