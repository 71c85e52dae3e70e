// Closed loop in lockstep: the glove5 firmware app on the simulated glove and hand, the link codec, and the
// host's glove controller, on a virtual clock with the plant's sensor noise.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/glove/board.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/lockstep.h"

using namespace phalanx;
using host::glove::GloveController;
using host::glove::GloveControllerConfig;

namespace {

sim::GlovePlantConfig plantConfig(sim::HandScenario scenario) {
  sim::GlovePlantConfig c;
  c.scenario = scenario;
  c.seed = 5;
  return c;
}

/// The simulated glove, the host's glove controller (rendering or transparent) and the lockstep rig joining them.
struct GloveRig {
  GloveRig(const sim::GlovePlantConfig& plant, bool transparent, const host::LockstepOptions& options = {},
           const apps::Glove5Config& firmware = apps::glove5DefaultConfig())
      : device(plant, apps::glove5DefaultCalibration(), firmware),
        controller(controllerConfig(transparent)),
        rig(device, controller, options) {}
  static GloveControllerConfig controllerConfig(bool transparent) {
    GloveControllerConfig c;
    c.transparent = transparent;
    return c;
  }
  fw_sim::Glove5SimDevice device;
  GloveController controller;
  host::LockstepRig rig;
};

}  // namespace

// Issue target: ≤ 50 mN per finger at 1 kHz, in the plant with its sensor noise (and the gauge's thermal drift since
// the start-up tare); the paper measured ≈ 100 mN at 300 Hz. Seeds 1–15: 0.036–0.047 N true (docs/glove-firmware.md).
TEST(GloveFreeMotion, PeakContactForceIsWithinFiftyMillinewtonsWithSensorNoiseAndDrift) {
  const auto r = host::glove::benchFreeMotion({});
  ASSERT_TRUE(r["noise"].get<bool>() && r["drift"].get<bool>());
  EXPECT_EQ(r["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_LE(r["peak_contact_force_N_max"].get<double>(), 0.050) << r.dump(2);
  for (const auto& [name, finger] : r["fingers"].items()) {
    EXPECT_LE(finger["truth"]["peak_contact_force_N"].get<double>(), 0.050) << name;
  }
}

// The loop's own share, without any sensor noise: 0.032–0.037 N (seeds 1–5).
TEST(GloveFreeMotion, WithoutSensorNoiseThePeakIsWithinFortyMillinewtons) {
  host::glove::GloveBenchOptions o;
  o.noise = false;
  const auto r = host::glove::benchFreeMotion(o);
  EXPECT_EQ(r["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_LE(r["peak_contact_force_N_max"].get<double>(), 0.040) << r.dump(2);
  for (const auto& [name, finger] : r["fingers"].items()) {
    EXPECT_LE(finger["truth"]["peak_contact_force_N"].get<double>(), 0.040) << name;
  }
}

TEST(GloveFreeMotion, JointTrajectoriesCorrelateWithTheCablesRemovedRun) {
  const auto r = host::glove::benchFreeMotion({});
  // 000 Table 4, all users: 0.94 / 0.80 / 0.87. The simulated glove must do at least as well.
  const auto& mean = r["pearson_r_alpha_mean"];
  EXPECT_GE(mean[0].get<double>(), 0.9417) << r.dump(2);
  EXPECT_GE(mean[1].get<double>(), 0.7981) << r.dump(2);
  EXPECT_GE(mean[2].get<double>(), 0.8692) << r.dump(2);
}

TEST(GloveGrasp, RenderedForceIsWithinTenPercentOfKxAtSteadyContact) {
  const auto r = host::glove::benchGrasp({});
  EXPECT_EQ(r["faults"].get<int>(), 0) << r.dump(2);
  EXPECT_GE(r["fingers_in_steady_contact"].get<int>(), 3) << r.dump(2);
  EXPECT_LE(r["relative_error_max"].get<double>(), 0.10) << r.dump(2);
  // Holding a rigid object costs little current: the worm holds it (with the full loop gain in contact the
  // loop limit-cycled at 3.3–3.7 A RMS, glove-firmware.md).
  for (const auto& [name, finger] : r["fingers"].items()) {
    if (!finger.contains("truth")) continue;
    EXPECT_LE(finger["truth"]["motor_current_rms_A"].get<double>(), 2.0) << name;
  }
}

// The main job (`phalanx run --device sim:glove5`: 10 s, grasp, rigid ball) in lockstep, so the counts do not depend on
// the machine's load: every finger, thumb included, reaches the ball pad first and holds it to the end. Before the
// ball was moved (docs/glove-model.md) the little finger never touched it and the thumb's pad met it nail side first
// and was pulled through it (contact 0.08 s). The force figures are printed, not judged (see the report of issue 20:
// the RMS targets are not met yet).
TEST(GloveGrasp, TheMainJobGraspsWithEveryFingerAndHoldsTheBallToTheEnd) {
  GloveRig g(plantConfig(sim::HandScenario::kGrasp), false);
  ASSERT_EQ(g.rig.handshake(), "");
  constexpr int kTicks = 10000;  // 10 s at 1 kHz
  std::array<int, 5> first{-1, -1, -1, -1, -1}, losses_after_onset{}, contact{};
  std::array<double, 5> setpoint_sum{}, force_sum{};
  std::array<int, 5> late{};
  for (int i = 0; i < kTicks; ++i) {
    g.rig.step();
    for (int f = 0; f < 5; ++f) {
      const bool in = g.controller.lastRender()[static_cast<size_t>(f)].in_contact;
      if (in && first[f] < 0) first[f] = i;
      if (in) ++contact[f];
      // Held: once the onset is over (0.5 s after first contact) the finger never leaves the ball.
      if (!in && first[f] >= 0 && i > first[f] + 500) ++losses_after_onset[f];
      if (i >= kTicks / 2) {
        setpoint_sum[f] += static_cast<double>(g.rig.lastCommand().setpoint[f]);
        force_sum[f] += static_cast<double>(g.rig.session().latest().value[15 + f]);
        ++late[f];
      }
    }
  }
  EXPECT_EQ(g.rig.core().faultBits(), 0u);
  for (int f = 0; f < 5; ++f) {
    const auto& st = g.controller.stats(f);
    std::printf("%-6s first contact %.3f s, contact %d cycles; RMS error in contact %.3f N, free RMS %.3f N\n",
                host::glove::kFingerNames[f], first[f] * 1e-3, contact[f],
                std::sqrt(st.sq_error_contact / static_cast<double>(std::max(1L, st.contact_cycles))),
                std::sqrt(st.sq_force_free / static_cast<double>(std::max(1L, st.free_cycles))));
    EXPECT_GE(first[f], 0) << host::glove::kFingerNames[f] << " never touched the ball";
    EXPECT_LT(first[f], 1500) << host::glove::kFingerNames[f] << ": the reach ends at 1.2 s";
    EXPECT_GT(contact[f], 8000) << host::glove::kFingerNames[f];
    EXPECT_EQ(losses_after_onset[f], 0) << host::glove::kFingerNames[f] << " let go of the ball";
    // Pad first: the rendered pad-normal force resists the closing (a nail-side contact renders it negative),
    // and the gauge reads the finger's squeeze (5 N effort) within 20 %.
    EXPECT_GT(setpoint_sum[f] / late[f], 4.0) << host::glove::kFingerNames[f];
    EXPECT_NEAR(force_sum[f] / late[f], 5.0, 1.0) << host::glove::kFingerNames[f];
  }
}

// A 100 Hz host (the emulated boards' sessions, a loaded PC) with the 1 kHz firmware, the hand still and resting in
// the rigid ball: rendered at 2000 N/m the setpoint k·x jumped between 0 and 7–10 N from one host period to the
// next and the loop latched current-limit (6 of 6 daemon sessions). The controller limits k·T
// (GloveControllerConfig::max_stiffness_period_N_s_per_m): 200 N/m at 100 Hz.
TEST(GloveGrasp, AHundredHertzHostRendersTheRigidBallWithoutOscillating) {
  host::LockstepOptions slow_host;
  slow_host.host_every_ticks = 10;
  slow_host.command_timeout_ms = 200;
  GloveRig g(plantConfig(sim::HandScenario::kStill), false, slow_host);
  // A 70 mm ball the relaxed middle fingertip rests in (the demo ball is placed for the grasp, docs/glove-model.md).
  g.controller.scene().clearObjects();
  ASSERT_TRUE(g.controller.scene().addObject(host::glove::rigidBall({0.034, -0.067, 0.0}, 0.035)));
  ASSERT_EQ(g.rig.handshake(), "");
  constexpr int kTicks = 10000;  // 10 s
  double i2[5] = {};
  for (int i = 0; i < kTicks; ++i) {
    g.rig.step();
    for (int f = 0; f < 5; ++f) i2[f] += g.device.glovePlant().motorCurrent_A(f) * g.device.glovePlant().motorCurrent_A(f);
  }
  EXPECT_EQ(g.rig.core().faultBits(), 0u);
  double contact_s = 0.0;
  for (int f = 0; f < 5; ++f) contact_s = std::fmax(contact_s, g.controller.stats(f).contact_s);
  EXPECT_GT(contact_s, 8.0) << "a finger must rest in the ball for this to test anything";
  for (int f = 0; f < 5; ++f) EXPECT_LT(std::sqrt(i2[f] / kTicks), 1.0) << "motor current RMS, finger " << f;
}

// A tare with a hand pressing the pad (the hand squeezing when a session starts or a link comes back) would zero
// that force, and the glove would later push it into the relaxed finger. The firmware keeps such a finger's zero.
TEST(GloveTare, AFingerPressingThePadKeepsItsZeroAndTheRelaxedOnesAreTared) {
  auto cfg = plantConfig(sim::HandScenario::kPush);
  cfg.push_force_N = 3.0;
  cfg.push_ramp_s = 0.3;
  GloveRig g(cfg, true);
  auto& rig = g.rig;
  auto& app = g.device.gloveApp();
  ASSERT_EQ(rig.handshake(), "");  // tare at t ≈ 0, before the push ramps up
  float tare = 1.0f;
  ASSERT_EQ(app.getParam(apps::glove5_param::kTare, tare), protocol::ParamStatus::kOk);
  EXPECT_EQ(tare, 0.0f) << "the start-up tare of a relaxed hand is accepted";
  rig.setHostConnected(false);  // the link is lost: the device goes safe, the worm holds, the finger presses
  rig.run(1.5);
  ASSERT_FALSE(rig.board().io().pwm_enabled);
  int pressing = 0;
  for (int f = 0; f < 5; ++f) pressing |= (g.device.glovePlant().padForce_N(f) > 2.0 ? 1 : 0) << f;
  ASSERT_NE(pressing, 0) << "some finger must press the pad for this to test anything";
  rig.session().sendParamSet(apps::glove5_param::kTare, 1.0f);  // what a reconnecting host sends
  rig.setHostConnected(true);
  for (int i = 0; i < 100; ++i) rig.step();
  ASSERT_EQ(app.getParam(apps::glove5_param::kTare, tare), protocol::ParamStatus::kOk);
  EXPECT_EQ(-tare, static_cast<float>(pressing)) << "exactly the pressing fingers are refused";
  // What phalanxd prints after reading the parameter back (GloveController and the therapy session's glove).
  const std::string warning = host::glove::tareWarning(apps::glove5_param::kTare, tare);
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(warning.find(host::glove::kFingerNames[f]) != std::string::npos, ((pressing >> f) & 1) != 0) << warning;
  }
  for (int f = 0; f < 5; ++f) {
    // Every finger's force still reads the true pad force (the pressing ones with their old zero).
    EXPECT_NEAR(app.finger(f).force_N, g.device.glovePlant().padForce_N(f), 0.5) << "finger " << f;
  }
}

// A hand clenched onto the pads when the session starts: the transparent loop released at full speed, the finger (a
// force source) followed into the fist and the glove overshot, -10 to -12 N on the pad, into current-limit or
// sensor-saturated within 0.5 s (10 of 10 seeds). The firmware holds such a finger (motor off, the worm holds) until
// its pad force is within Glove5Config::engage_max_force_N. The same scenario with the hold disabled must latch, or
// this test shows nothing.
TEST(GloveEngage, AHandClenchedAtTheStartIsHeldAndNeverDriven) {
  for (const bool hold : {true, false}) {
    apps::Glove5Config fw = apps::glove5DefaultConfig();
    if (!hold) fw.engage_max_force_N = 1e9f;
    GloveRig g(plantConfig(sim::HandScenario::kGrasp), true, {}, fw);
    g.rig.run(3.0);  // the hand closes onto the glove before the host connects: the worm holds it
    ASSERT_EQ(g.rig.handshake(), "");
    double worst_pad_N = 0.0;
    for (int i = 0; i < 2000; ++i) {
      g.rig.step();
      for (int f = 0; f < 5; ++f) worst_pad_N = std::fmax(worst_pad_N, std::fabs(g.device.glovePlant().padForce_N(f)));
    }
    if (!hold) {
      EXPECT_NE(g.rig.core().faultBits(), 0u) << "without the hold the clenched start must latch";
      continue;
    }
    EXPECT_EQ(g.rig.core().faultBits(), 0u);
    EXPECT_TRUE(g.rig.board().io().pwm_enabled);
    EXPECT_LT(worst_pad_N, 6.0) << "no more than the hand's own squeeze (5 N)";
    for (int f = 0; f < 5; ++f) {
      EXPECT_FALSE(g.device.gloveApp().finger(f).engaged) << "finger " << f;
      EXPECT_EQ(g.rig.board().io().pwm_duty[static_cast<size_t>(f)], 0.0f) << "finger " << f;
    }
  }
}

// The hand presses when the link comes back, then relaxes: the pressing fingers are held (the worm does not move)
// while the others follow the hand; once the pads are relieved every finger engages and the glove is transparent.
TEST(GloveEngage, APressingFingerEngagesOnceItRelaxes) {
  auto cfg = plantConfig(sim::HandScenario::kPush);
  cfg.push_force_N = 5.0;
  cfg.push_ramp_s = 0.3;
  cfg.push_until_s = 3.0;
  GloveRig g(cfg, true);
  auto& rig = g.rig;
  const auto& plant = g.device.glovePlant();
  ASSERT_EQ(rig.handshake(), "");  // tare at t ≈ 0, relaxed
  rig.setHostConnected(false);
  rig.run(1.5);  // safe: the worm holds while the push ramps up
  int pressing = 0;
  double spool[5];
  for (int f = 0; f < 5; ++f) {
    pressing |= (plant.padForce_N(f) > 2.0 ? 1 : 0) << f;
    spool[f] = plant.spoolAngle_rad(f);
  }
  ASSERT_NE(pressing, 0) << "some finger must press the pad for this to test anything";
  rig.setHostConnected(true);
  while (rig.timeS() < 2.9) rig.step();
  ASSERT_EQ(rig.core().faultBits(), 0u);
  for (int f = 0; f < 5; ++f) {
    const bool pressed = ((pressing >> f) & 1) != 0;
    EXPECT_EQ(g.device.gloveApp().finger(f).engaged, !pressed) << "finger " << f;
    if (pressed) {
      EXPECT_NEAR(plant.spoolAngle_rad(f), spool[f], 1e-6) << "held finger " << f << " moved";
    }
  }
  double least_pad_N = 0.0;  // the hand lets go from t = 3 s: no overshoot into the relaxing finger as it engages
  double late_peak_N = 0.0;
  while (rig.timeS() < 5.0) {
    rig.step();
    for (int f = 0; f < 5; ++f) {
      least_pad_N = std::fmin(least_pad_N, plant.padForce_N(f));
      if (rig.timeS() > 4.0) late_peak_N = std::fmax(late_peak_N, std::fabs(plant.padForce_N(f)));
    }
  }
  EXPECT_EQ(rig.core().faultBits(), 0u);
  for (int f = 0; f < 5; ++f) EXPECT_TRUE(g.device.gloveApp().finger(f).engaged) << "finger " << f;
  EXPECT_GT(least_pad_N, -0.5);  // seeds 1-10: -0.11 to -0.13 N
  EXPECT_LT(late_peak_N, 0.15) << "transparent once engaged (seeds 1-10: 0.09-0.10 N)";
}

TEST(GlovePowerOff, TheWormHoldsAgainst35NWithTheMotorsOff) {
  auto cfg = plantConfig(sim::HandScenario::kPush);
  cfg.push_force_N = 33.0;
  GloveRig g(cfg, true);
  auto& device = g.device;
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.setHostConnected(false);  // no commands: outputs stay off
  const double spool0 = device.glovePlant().spoolAngle_rad(1);
  rig.run(2.0);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_NEAR(device.glovePlant().spoolAngle_rad(1), spool0, 1e-6) << "the worm was back-driven";
  EXPECT_GT(device.glovePlant().padForce_N(1), 20.0) << "the finger must actually be pushing";
}

TEST(GloveFaults, LinkLossGoesSafeAndNoForceLimitIsExceeded) {
  GloveRig g(plantConfig(sim::HandScenario::kCloseOpen), true);
  auto& device = g.device;
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.run(1.5);
  ASSERT_TRUE(rig.board().io().pwm_enabled) << "faults " << rig.core().faultBits();
  rig.setHostConnected(false);
  int ticks = 0;
  while (rig.board().io().pwm_enabled && ticks < 100) {
    rig.step();
    ++ticks;
  }
  EXPECT_LE(ticks, 20 + 2) << "command timeout 20 ms + two ticks";
  EXPECT_TRUE(rig.core().faultBits() & protocol::fault::kCommandTimeout);
  for (int f = 0; f < 5; ++f) EXPECT_LE(std::fabs(device.gloveApp().finger(f).duty), 1.0f);
}

TEST(GloveFaults, AStuckHallSensorIsDetectedAndDrivesTheOutputsSafe) {
  GloveRig g(plantConfig(sim::HandScenario::kCloseOpen), true);
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.5);
  ASSERT_TRUE(rig.board().io().pwm_enabled);
  const int ch = glove::board::hallAdcChannel(1, 1);
  const int32_t frozen = rig.board().io().adc[static_cast<size_t>(ch)];
  rig.setIoHook([&](sim::SimIo& io) { io.adc[static_cast<size_t>(ch)] = frozen; });
  rig.run(1.5);
  EXPECT_TRUE(rig.core().faultBits() & protocol::fault::kSensorStuck);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_TRUE(rig.session().latest().fault_bits & protocol::fault::kSensorStuck);
}

TEST(GloveFaults, ADisconnectedHallSensorIsARangeFault) {
  GloveRig g(plantConfig(sim::HandScenario::kStill), false);
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.2);
  rig.setIoHook([](sim::SimIo& io) { io.adc[4] = 0; });  // pulled to ground
  rig.run(0.01);
  EXPECT_TRUE(rig.core().faultBits() & protocol::fault::kSensorRange);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
}

TEST(GloveFaults, StrainGaugeSaturationGoesSafe) {
  GloveRig g(plantConfig(sim::HandScenario::kStill), false);
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.run(0.2);
  rig.setIoHook([](sim::SimIo& io) { io.adc[static_cast<size_t>(glove::board::strainAdcChannel(2))] = glove::board::kStrainMaxCounts; });
  rig.run(0.01);
  EXPECT_TRUE(rig.core().faultBits() & protocol::fault::kSensorSaturated);
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  for (int f = 0; f < 5; ++f) EXPECT_EQ(rig.board().io().pwm_duty[static_cast<size_t>(f)], 0.0f);
}

TEST(GloveFaults, AnEstopPressLatchesAndStopsTheMotors) {
  GloveRig g(plantConfig(sim::HandScenario::kGrasp), false);
  auto& rig = g.rig;
  ASSERT_EQ(rig.handshake(), "");
  rig.run(1.0);
  rig.board().io().estop_pressed = true;
  rig.step();
  EXPECT_FALSE(rig.board().io().pwm_enabled);
  EXPECT_TRUE(rig.core().faultBits() & protocol::fault::kEstop);
}

// The grasp (the main job) at a 100 Hz host: the 200 N/m the ball is rendered with there lets the fingers, squeezing
// with 5 N, pass into it while the contact gain is small; the force left behind then met the full free-motion gain at
// once when contact ended, and the loop limit-cycled at the bridge's ±4 A into current-limit (seeds 2 and 7 here; 9 of
// 20 seeds over 10 s). The firmware now raises a finger's gain scale at most Glove5Config::gain_scale_rise_per_s
// (0 of 20).
TEST(GloveGrasp, AHundredHertzHostGraspEndsContactWithoutLatching) {
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    host::LockstepOptions slow_host;
    slow_host.host_every_ticks = 10;
    slow_host.command_timeout_ms = 200;
    sim::GlovePlantConfig pc = plantConfig(sim::HandScenario::kGrasp);
    pc.seed = seed;
    GloveRig g(pc, false, slow_host);
    ASSERT_EQ(g.rig.handshake(), "");
    for (int i = 0; i < 3000; ++i) g.rig.step();  // the reach (0.3–1.1 s) and two seconds of squeezing
    EXPECT_EQ(g.rig.core().faultBits(), 0u) << "seed " << seed;
  }
}
