// Closed loop in lockstep on the simulated index finger wearing the SEA exoskeleton (seeds/001 §6, §7.6–7.7): the
// sea_finger firmware app, the SEA plant's finger variant (eq 13–14) with sensor noise, the link codec and the
// host's SeaFingerController (kinematics estimator, eq 9–11).
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/host/sea/sea_finger_controller.h"

using namespace phalanx;
using host::sea::SeaBenchOptions;

// Issue targets: finger MCP NRMSE ≤ 2 %, PIP ≤ 3 % (paper 1.7 % / 3.4 %), on the host's estimate (what the paper
// reports) and on the true applied finger torque.
TEST(SeaFingerTorque, OurControllerTracksFingerTorquesWithinTheTargets) {
  SeaBenchOptions o;
  o.controller = "ours";
  const auto r = host::sea::benchFingerTorque(o);
  const auto& c = r["controllers"]["ours"];
  EXPECT_EQ(c["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_LE(c["mcp"]["nrmse_percent"].get<double>(), 2.0) << r.dump(2);
  EXPECT_LE(c["pip"]["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
  EXPECT_LE(c["mcp"]["truth"]["nrmse_percent"].get<double>(), 2.0) << r.dump(2);
  EXPECT_LE(c["pip"]["truth"]["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
  EXPECT_LT(c["mcp"]["peak_motor_angle_deg"].get<double>(), 55.0);
  EXPECT_LT(c["pip"]["peak_motor_angle_deg"].get<double>(), 55.0);
}

// The paper's baseline tracks its own eq 7 estimate about as well as the paper reports, but the true finger
// torque is several times worse than ours (the estimate misses the cable play).
TEST(SeaFingerTorque, PaperBaselineIsWorseThanOursOnTheTrueTorque) {
  SeaBenchOptions o;
  const auto r = host::sea::benchFingerTorque(o);
  const auto& paper = r["controllers"]["paper"];
  const auto& ours = r["controllers"]["ours"];
  for (const char* j : {"mcp", "pip"}) {
    EXPECT_GT(paper[j]["truth"]["nrmse_percent"].get<double>(), 2.0 * ours[j]["truth"]["nrmse_percent"].get<double>())
        << j << r.dump(2);
  }
  EXPECT_LT(paper["mcp"]["nrmse_percent"].get<double>(), 3.0) << r.dump(2);
}

// Issue targets: residual torque RMSE ≤ 0.002 N·m MCP, ≤ 0.005 N·m PIP during random finger motion
// (paper 0.0029 / 0.0092).
TEST(SeaTransparency, ResidualTorqueDuringRandomFingerMotionIsWithinTheTargets) {
  SeaBenchOptions o;
  o.controller = "ours";
  const auto r = host::sea::benchTransparency(o);
  const auto& c = r["controllers"]["ours"];
  EXPECT_EQ(c["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_LE(c["mcp"]["residual_rmse_Nm"].get<double>(), 0.002) << r.dump(2);
  EXPECT_LE(c["pip"]["residual_rmse_Nm"].get<double>(), 0.005) << r.dump(2);
  EXPECT_LE(c["mcp"]["truth"]["residual_rmse_Nm"].get<double>(), 0.002) << r.dump(2);
  EXPECT_LE(c["pip"]["truth"]["residual_rmse_Nm"].get<double>(), 0.005) << r.dump(2);
  // The finger really moved (a still finger would pass trivially).
  EXPECT_GT(c["mcp"]["finger_angle_range_deg"].get<double>(), 20.0);
  EXPECT_GT(c["pip"]["finger_angle_range_deg"].get<double>(), 20.0);
  EXPECT_GT(c["mcp"]["finger_peak_speed_deg_s"].get<double>(), 50.0);
}

TEST(SeaFingerSafety, LinkLossDuringTorqueTrackingTurnsTheBridgesOffAndTheFingerRelaxes) {
  sim::SeaPlantConfig plant;
  plant.variant = sim::SeaVariant::kFinger;
  plant.seed = 3;
  fw_sim::SeaFingerSimDevice device(plant);
  host::sea::SeaFingerControllerConfig cfg;
  host::sea::SeaFingerController ctl(cfg);
  host::LockstepRig rig(device, ctl);
  ASSERT_EQ(rig.handshake(), "");
  // Run until the MCP SEA carries a large torque (near a peak of the 0.5 Hz profile).
  rig.run(1.0);
  for (int i = 0; i < 3000 && std::fabs(device.seaPlant().truth(0).joint_torque_Nm) < 0.2; ++i) rig.step();
  ASSERT_GE(std::fabs(device.seaPlant().truth(0).joint_torque_Nm), 0.2);
  rig.setHostConnected(false);
  rig.run(0.022);  // 20 ms command timeout + 2 ticks
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_NE(rig.core().faultBits() & protocol::fault::kCommandTimeout, 0);
  rig.run(1.0);
  EXPECT_EQ(device.seaPlant().truth(0).motor_current_A, 0.0);
  // Unpowered, the passive finger and the springs back-drive the geared motors; only friction is left holding.
  EXPECT_LT(std::fabs(device.seaPlant().truth(0).joint_torque_Nm), 0.1);
  EXPECT_LT(std::fabs(device.seaPlant().truth(1).joint_torque_Nm), 0.1);
  EXPECT_EQ(rig.session().latest().mode, protocol::Mode::kSafe);
}
