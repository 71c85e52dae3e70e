// Unit tests of the simulated RML glove plant (hal/sim GlovePlant) and of the board constants it shares
// with the firmware (common/include/phalanx/glove/board.h). Expectations are computed here from the
// paper's equations and the datasheet-level constants, never by calling the plant's own helpers.
#include "phalanx/sim/glove_plant.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include "phalanx/glove/board.h"
#include "phalanx/glove/kinematics.h"

#include "../support/counting_allocator.h"  // g_allocations

namespace {

using phalanx::sim::GlovePlant;
using phalanx::sim::GlovePlantConfig;
using phalanx::sim::HandScenario;
using phalanx::sim::SimIo;
using phalanx::sim::TendonLubrication;
namespace board = phalanx::glove::board;
namespace glove = phalanx::glove;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDt = 1e-3;
constexpr int kIndex = 1;

double deg(double rad) { return rad * 180.0 / kPi; }

/// Noise-free, calibration-error-free configuration: the deterministic plant.
GlovePlantConfig idealConfig(HandScenario scenario) {
  GlovePlantConfig c;
  c.scenario = scenario;
  c.noise = false;
  c.calibration_errors = false;
  return c;
}

SimIo poweredIo(double duty) {
  SimIo io;
  io.pwm_enabled = true;
  io.drive_enable = true;
  for (int f = 0; f < board::kFingerCount; ++f) io.pwm_duty[board::motorPwmChannel(f)] = static_cast<float>(duty);
  return io;
}

void run(GlovePlant& plant, SimIo& io, double seconds) {
  const int steps = static_cast<int>(std::lround(seconds / kDt));
  for (int i = 0; i < steps; ++i) plant.step(kDt, io);
}

/// Capstan wrap of the routing, eq 16, written out independently: γ_c = 90° plus, per joint, the part of
/// the joint range the tendon is wrapped over (release: α_max − α; grasp: α − α_min), α clamped to range.
double wrapAngle(const glove::Model<double>& m, bool release, const glove::Vec3<double>& alpha) {
  double gamma = kPi / 2.0;
  for (std::size_t i = 0; i < 3; ++i) {
    const double a = std::fmin(std::fmax(alpha[i], m.mech.alpha_min_rad[i]), m.mech.alpha_max_rad[i]);
    gamma += release ? m.mech.alpha_max_rad[i] - a : a - m.mech.alpha_min_rad[i];
  }
  return gamma;
}

// =========================================================================================================
// board.h: channel map and nominal transfers
// =========================================================================================================

TEST(GloveBoard, ChannelMapFollowsTheDocumentedLayout) {
  EXPECT_EQ(board::motorPwmChannel(0), 0);
  EXPECT_EQ(board::motorPwmChannel(4), 4);
  EXPECT_EQ(board::hallAdcChannel(0, 0), 0);
  EXPECT_EQ(board::hallAdcChannel(2, 1), 7);  // 3·finger + joint
  EXPECT_EQ(board::hallAdcChannel(4, 2), 14);
  EXPECT_EQ(board::strainAdcChannel(0), 15);
  EXPECT_EQ(board::strainAdcChannel(4), 19);
  EXPECT_EQ(board::currentAdcChannel(0), 20);
  EXPECT_EQ(board::currentAdcChannel(4), 24);
  EXPECT_LE(board::kAdcChannelCount, phalanx::sim::kMaxAdc);
  EXPECT_LE(board::kPwmChannelCount, phalanx::sim::kMaxPwm);
}

TEST(GloveBoard, HallTableMatchesTheDocumentedMagnetModelAndIsMonotonic) {
  // counts = 2048 + A·(sin x − h3·sin 3x), A = 40 mT · 30 mV/mT · 4096/3.3 V, x from −67.5° to +67.5°.
  const double amplitude = 0.040 * 30.0 * 4096.0 / 3.3;
  for (int i = 0; i < board::kHallTablePoints; ++i) {
    const double x = (-67.5 + 8.4375 * i) * kPi / 180.0;
    const double counts = 2048.0 + amplitude * (std::sin(x) - 0.04 * std::sin(3.0 * x));
    EXPECT_NEAR(board::kHallTableCounts[i], counts, 0.5) << "point " << i;
    if (i > 0) {
      EXPECT_GT(board::kHallTableCounts[i], board::kHallTableCounts[i - 1]);
    }
  }
  // The table covers every default mechanism's α range (kinematics.h) for each joint.
  for (int f = 0; f < board::kFingerCount; ++f) {
    const auto m = glove::defaultModel<double>(static_cast<glove::FingerId>(f));
    for (int j = 0; j < 3; ++j) {
      EXPECT_LT(board::hallTableAngle_rad(j, 0), m.mech.alpha_min_rad[j]) << "finger " << f << " joint " << j;
      EXPECT_GT(board::hallTableAngle_rad(j, board::kHallTablePoints - 1), m.mech.alpha_max_rad[j]);
    }
  }
}

TEST(GloveBoard, NominalTransfersHaveTheDocumentedScales) {
  EXPECT_NEAR(board::kStrainCountsPerNewton, 1.5 / 20.0 * 4096.0 / 3.3, 1e-3);
  EXPECT_NEAR(board::strainCountsToForce_N(board::kStrainMaxCounts), 20.0, 0.01);
  EXPECT_NEAR(board::strainCountsToForce_N(board::kStrainMinCounts), -20.0, 0.01);
  EXPECT_NEAR(board::kCurrentCountsPerAmp, 0.4 * 4096.0 / 3.3, 1e-3);
  EXPECT_FLOAT_EQ(board::currentCountsToAmps_A(board::kCurrentZeroCounts), 0.0f);
}

// =========================================================================================================
// Worm drive: self-locking, passive limit, efficiency
// =========================================================================================================

TEST(GlovePlantWorm, HoldsAThirtyNewtonPushWithPowerOffWithoutTheSpoolMoving) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 30.0;
  GlovePlant plant(c);
  SimIo io;  // bridges off: firmware safe state
  run(plant, io, 2.0);
  for (int f = 0; f < board::kFingerCount; ++f) {
    const auto& t = plant.truth(f);
    EXPECT_NEAR(t.pad_force_N, 30.0, 0.5) << "finger " << f;
    EXPECT_EQ(t.spool_angle_rad, 0.0) << "finger " << f;  // not even a rounding error of motion
    EXPECT_TRUE(t.worm_locked);
    EXPECT_FALSE(t.worm_slipping);
    EXPECT_EQ(t.motor_current_A, 0.0);  // self-locking: the hold costs no current (§2.2)
  }
}

TEST(GlovePlantWorm, HoldsAPushWithPowerOnAtZeroDuty) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 20.0;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.0);  // bridge on, braking
  run(plant, io, 1.5);
  EXPECT_NEAR(plant.padForce_N(kIndex), 20.0, 0.5);
  EXPECT_EQ(plant.spoolAngle_rad(kIndex), 0.0);
  EXPECT_EQ(plant.motorCurrent_A(kIndex), 0.0);  // no back-EMF: the load cannot turn the motor
}

TEST(GlovePlantWorm, SlipsWhenTheFingerPushesBeyondThePassiveLimit) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 40.0;
  GlovePlant plant(c);
  SimIo io;
  double max_pad = 0.0;
  bool slipped = false;
  for (int i = 0; i < 2000; ++i) {
    plant.step(kDt, io);
    max_pad = std::fmax(max_pad, plant.padForce_N(kIndex));
    slipped = slipped || plant.truth(kIndex).worm_slipping;
  }
  EXPECT_TRUE(slipped);
  // The finger pushes the release tendon out: the spool turns the negative way, by far more than play.
  EXPECT_LT(plant.spoolAngle_rad(kIndex), -0.5);
  // It gave way at about the §2.2 passive limit of 35 N, well short of the 40 N push.
  EXPECT_GT(max_pad, 33.0);
  EXPECT_LT(max_pad, 37.5);
}

TEST(GlovePlantWorm, SlipTorqueIsTheSpoolTorqueOfA35NewtonPushAtTheReferencePose) {
  const GlovePlantConfig c = idealConfig(HandScenario::kStill);
  GlovePlant plant(c);
  for (int f = 0; f < board::kFingerCount; ++f) {
    const auto m = glove::defaultModel<double>(static_cast<glove::FingerId>(f));
    const glove::Vec3<double> theta_ref = {-45.0 * kPi / 180.0, -65.0 * kPi / 180.0, -45.0 * kPi / 180.0};
    glove::Vec3<double> alpha_ref{};
    ASSERT_EQ(glove::alphaFromTheta(m, theta_ref, alpha_ref), glove::Status::kOk);
    // 35 N on the pad = 35/c N at the tip; the finger pulls the tendon out, so the spool sees e^{-μγ} of it.
    const double spool_tension = 35.0 / 0.3 / std::exp(0.053 * wrapAngle(m, true, alpha_ref));
    EXPECT_NEAR(plant.constants(f).slip_torque_Nm, spool_tension * 0.005, 1e-6) << "finger " << f;  // float board constants
  }
}

TEST(GlovePlantWorm, IsSelfLockingWithAForwardEfficiencyBelowOneHalf) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  const double lead = 4.0 * kPi / 180.0;
  const double rho = std::atan(0.08);
  EXPECT_NEAR(plant.wormForwardEfficiency(), std::tan(lead) / std::tan(lead + rho), 1e-9);
  EXPECT_LT(plant.wormForwardEfficiency(), 0.5);
  EXPECT_LT(plant.wormBackEfficiency(), 0.0);  // negative back-efficiency: the load cannot drive the worm
}

TEST(GlovePlantWorm, StalledMotorTorqueReachesTheSpoolThroughTheForwardEfficiency) {
  GlovePlantConfig c = idealConfig(HandScenario::kStill);
  c.params.tendon_damping_N_s_per_m = 0.0;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.1);
  run(plant, io, 4.0);
  const auto& t = plant.truth(kIndex);
  ASSERT_LT(std::fabs(t.motor_speed_rad_s), 0.01);  // stalled (approached exponentially)
  // Stall current from Ohm's law: duty · 9 V over motor + bridge resistance.
  const double current = 0.1 * 9.0 / (0.68 + 0.2);
  EXPECT_NEAR(t.motor_current_A, current, 1e-4);
  // The worm came to rest where the mesh load equals the forward-transmitted torque (Coulomb friction of
  // the motor, 0.2 mN·m, subtracted): T·r_s = η_w·N·η_spur·(K·I − τ_c). Net spool tension, both tendons.
  const double torque = 0.464 * 101.0 * 0.87 * (1.37e-3 * current - 2.0e-4);
  const double net_tension = t.tension_release_spool_N - t.tension_grasp_spool_N;
  EXPECT_NEAR(net_tension * 0.005, torque, 0.02 * torque);
}

// =========================================================================================================
// Motor direction and sign conventions (board.h)
// =========================================================================================================

TEST(GlovePlantMotor, PositiveDutyWindsTheReleaseTendonAndPushesThePadTowardsExtension) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io = poweredIo(0.1);
  run(plant, io, 0.5);
  for (int f = 0; f < board::kFingerCount; ++f) {
    const auto& t = plant.truth(f);
    EXPECT_GT(t.spool_angle_rad, 0.01) << "finger " << f;
    EXPECT_GT(t.tension_release_spool_N, t.tension_grasp_spool_N);
    EXPECT_GT(t.pad_force_N, 0.5);
    EXPECT_GT(t.motor_current_A, 0.3);
    // The glove opens the finger: each joint angle grows (flexion is negative, kinematics.h).
    for (int j = 0; j < 3; ++j) EXPECT_GT(t.theta_rad[j], t.theta_d_rad[j]) << "finger " << f << " joint " << j;
    // Along glove::padNormal: dorsal, towards extension.
    const glove::Vec3<double> n = glove::padNormal(t.O_u_tip[2]);
    EXPECT_NEAR(n[0] * t.O_F_tip[0] + n[1] * t.O_F_tip[1], t.pad_force_N, 1e-9);
    EXPECT_GT(io.adc[board::strainAdcChannel(f)], board::kStrainZeroCounts);
    EXPECT_GT(io.adc[board::currentAdcChannel(f)], board::kCurrentZeroCounts);
  }
}

TEST(GlovePlantMotor, NegativeDutyWindsTheGraspTendonAndPullsTheFingerClosed) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io = poweredIo(-0.1);
  run(plant, io, 0.5);
  const auto& t = plant.truth(kIndex);
  EXPECT_LT(t.spool_angle_rad, -0.01);
  EXPECT_GT(t.tension_grasp_spool_N, t.tension_release_spool_N);
  EXPECT_LT(t.pad_force_N, -0.5);
  EXPECT_LT(t.motor_current_A, -0.3);
  EXPECT_LT(io.adc[board::strainAdcChannel(kIndex)], board::kStrainZeroCounts);
  EXPECT_LT(io.adc[board::currentAdcChannel(kIndex)], board::kCurrentZeroCounts);
}

TEST(GlovePlantMotor, DisabledDriveOrPressedEstopLeavesTheMotorWithoutCurrent) {
  for (int variant = 0; variant < 3; ++variant) {
    GlovePlant plant(idealConfig(HandScenario::kStill));
    SimIo io = poweredIo(0.5);
    if (variant == 0) io.pwm_enabled = false;
    if (variant == 1) io.drive_enable = false;
    if (variant == 2) io.estop_pressed = true;
    run(plant, io, 0.3);
    EXPECT_EQ(plant.motorCurrent_A(kIndex), 0.0) << "variant " << variant;
    EXPECT_EQ(plant.spoolAngle_rad(kIndex), 0.0) << "variant " << variant;
    EXPECT_FALSE(plant.truth(kIndex).bridge_on);
  }
}

TEST(GlovePlantMotor, CurrentIsLimitedByTheBridgeRegulation) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io = poweredIo(1.0);
  plant.step(kDt, io);
  EXPECT_NEAR(plant.motorCurrent_A(kIndex), 4.0, 1e-9);  // 9 V / 0.88 Ω would be 10 A
}

// =========================================================================================================
// Capstan friction (eq 15–16), direction-dependent
// =========================================================================================================

/// Ratio T_tip / T_spool of the release tendon while it slides, and the wrap γ seen then.
struct SlidingSample {
  double ratio = 0;
  double gamma = 0;
  bool found = false;
};

SlidingSample releaseWhileSliding(GlovePlant& plant, SimIo& io, int direction, int max_steps) {
  SlidingSample s;
  const auto m = glove::defaultModel<double>(glove::FingerId::kIndex);
  for (int i = 0; i < max_steps && !s.found; ++i) {
    plant.step(kDt, io);
    const auto& t = plant.truth(kIndex);
    if (t.release_sliding == direction && t.tension_release_spool_N > 2.0) {
      s.ratio = t.tension_release_tip_N / t.tension_release_spool_N;
      s.gamma = wrapAngle(m, true, t.alpha_rad);
      s.found = true;
    }
  }
  return s;
}

TEST(GlovePlantCapstan, TipTensionIsLowerThanSpoolTensionWhenTheMotorPulls) {
  GlovePlantConfig c = idealConfig(HandScenario::kStill);
  c.params.tendon_damping_N_s_per_m = 0.0;  // pure eq 15 between the two ends
  GlovePlant plant(c);
  SimIo io = poweredIo(0.1);
  const SlidingSample s = releaseWhileSliding(plant, io, +1, 1000);
  ASSERT_TRUE(s.found);
  EXPECT_NEAR(s.ratio, std::exp(-0.053 * s.gamma), 1e-9);  // F1 = spool side (eq 15)
  EXPECT_LT(s.ratio, 0.9);                                  // a real loss: γ is several radians
}

TEST(GlovePlantCapstan, TipTensionIsHigherThanSpoolTensionWhenTheFingerPulls) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 10.0;
  c.params.tendon_damping_N_s_per_m = 0.0;
  GlovePlant plant(c);
  SimIo io;  // locked spool: the finger drags the tendon over the pulleys
  const SlidingSample s = releaseWhileSliding(plant, io, -1, 1000);
  ASSERT_TRUE(s.found);
  EXPECT_NEAR(s.ratio, std::exp(0.053 * s.gamma), 1e-9);  // F1 = tip side
  EXPECT_GT(s.ratio, 1.1);
}

TEST(GlovePlantCapstan, DryTendonsLoseMoreThanLubricatedOnes) {
  GlovePlantConfig c = idealConfig(HandScenario::kStill);
  c.params.tendon_damping_N_s_per_m = 0.0;
  c.lubrication = TendonLubrication::kDry;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.1);
  const SlidingSample s = releaseWhileSliding(plant, io, +1, 1000);
  ASSERT_TRUE(s.found);
  EXPECT_NEAR(s.ratio, std::exp(-0.0631 * s.gamma), 1e-9);
}

TEST(GlovePlantCapstan, ContactSticksWhileNeitherEndOutpullsTheFriction) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io;  // nothing moves
  run(plant, io, 0.2);
  const auto& t = plant.truth(kIndex);
  EXPECT_EQ(t.release_sliding, 0);
  EXPECT_EQ(t.grasp_sliding, 0);
  EXPECT_NEAR(t.tension_release_tip_N, 1.0, 1e-9);  // the 1 N pretension, undisturbed
  EXPECT_NEAR(t.pad_force_N, 0.0, 1e-9);
}

// =========================================================================================================
// Finger ↔ glove coupling
// =========================================================================================================

TEST(GlovePlantCables, RemovedCablesGiveZeroPadForceWhileTheFingerFollowsItsIntent) {
  GlovePlantConfig c = idealConfig(HandScenario::kCloseOpen);
  c.cables_removed.fill(true);
  GlovePlant plant(c);
  SimIo io = poweredIo(0.3);  // the motor spins, unloaded
  double max_error = 0.0;
  double travel = 0.0;
  for (int i = 0; i < 3000; ++i) {
    plant.step(kDt, io);
    for (int f = 0; f < board::kFingerCount; ++f) {
      const auto& t = plant.truth(f);
      ASSERT_EQ(t.pad_force_N, 0.0);
      ASSERT_EQ(io.adc[board::strainAdcChannel(f)], board::kStrainZeroCounts);
      for (int j = 0; j < 3; ++j) max_error = std::fmax(max_error, std::fabs(t.theta_rad[j] - t.theta_d_rad[j]));
    }
    travel = std::fmax(travel, std::fabs(plant.theta_rad(kIndex)[0] - plant.fingerIntent(kIndex)[0]) +
                                   std::fabs(plant.theta_rad(kIndex)[0]));
  }
  EXPECT_LT(deg(max_error), 3.0);  // only the finger's own dynamics lag its intent
  EXPECT_GT(deg(travel), 60.0);    // and it really moved through a close/open maneuver
  EXPECT_GT(plant.spoolAngle_rad(kIndex), 10.0);
}

TEST(GlovePlantCables, ALockedGloveResistsTheClosingFinger) {
  GlovePlant plant(idealConfig(HandScenario::kCloseOpen));
  SimIo io;  // power off: the worm holds the tendons
  double max_pad = 0.0;
  for (int i = 0; i < 1100; ++i) {
    plant.step(kDt, io);
    max_pad = std::fmax(max_pad, plant.padForce_N(kIndex));
  }
  EXPECT_GT(max_pad, 5.0);  // closing against the locked release tendon: the pad pushes back (+)
}

TEST(GlovePlantFinger, AFingertipForceDeflectsTheFingerInProportionToItsImpedance) {
  // Steady force from a constant small duty; the finger yields by K⁻¹·J_θᵀ·n·F (joint stiffness = muscle +
  // passive, whose feed-forward at θ_d makes the whole K act about θ_d).
  const glove::Vec3<double> km = {1.0, 0.5, 0.2};
  const glove::Vec3<double> kp = {0.05, 0.03, 0.01};
  for (double duty : {0.05, 0.1}) {
    GlovePlant plant(idealConfig(HandScenario::kStill));
    SimIo io = poweredIo(duty);
    run(plant, io, 3.0);
    const auto& t = plant.truth(kIndex);
    const auto m = glove::defaultModel<double>(glove::FingerId::kIndex);
    const auto J = glove::jacobianThetaU(m.finger, t.theta_rad);
    const auto tau = glove::mulTransposed(J, glove::padNormal(t.O_u_tip[2]));
    for (int j = 0; j < 3; ++j) {
      const double expected = tau[j] * t.pad_force_N / (km[j] + kp[j]);
      EXPECT_NEAR(t.theta_rad[j] - t.theta_d_rad[j], expected, 0.02 * std::fabs(expected) + 1e-4)
          << "duty " << duty << " joint " << j;
    }
  }
}

TEST(GlovePlantScenarios, GraspSqueezeAgainstALockedGloveIsBoundedByTheSqueezeEffort) {
  GlovePlantConfig c = idealConfig(HandScenario::kGrasp);
  c.squeeze_force_N = 4.0;
  GlovePlant plant(c);
  SimIo io;
  run(plant, io, 2.0);
  for (int f = 0; f < board::kFingerCount; ++f) {
    const double pad = plant.padForce_N(f);
    EXPECT_GT(pad, 1.0) << "finger " << f;  // the finger squeezes into the locked glove …
    EXPECT_LT(pad, 6.0) << "finger " << f;  // … but no harder than its effort allows
  }
}

TEST(GlovePlantScenarios, APushThatEndsLetsTheLockedPadGo) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 5.0;
  c.push_ramp_s = 0.3;
  c.push_until_s = 1.5;
  GlovePlant plant(c);
  SimIo io;  // outputs off: the worm holds the glove
  run(plant, io, 1.4);
  EXPECT_NEAR(plant.padForce_N(kIndex), 5.0, 0.5);
  run(plant, io, 1.0);  // let go at 1.5 s, over 0.3 s
  EXPECT_LT(std::fabs(plant.padForce_N(kIndex)), 0.2);
}

TEST(GlovePlantScenarios, CloseOpenManeuverClosesAndReopensInAboutOneSecond) {
  GlovePlant plant(idealConfig(HandScenario::kCloseOpen));
  SimIo io;
  double start = plant.fingerIntent(kIndex)[0];
  double most_closed = start;
  double t_most_closed = 0.0;
  for (int i = 0; i < 1550; ++i) {
    plant.step(kDt, io);
    if (plant.fingerIntent(kIndex)[0] < most_closed) {
      most_closed = plant.fingerIntent(kIndex)[0];
      t_most_closed = plant.time_s();
    }
  }
  EXPECT_NEAR(t_most_closed, 0.5 + 0.02 + 0.5, 0.01);  // lead-in + index delay + half a maneuver
  EXPECT_LT(deg(most_closed - start), -60.0);             // a real fist closure at the MCP
  EXPECT_NEAR(plant.fingerIntent(kIndex)[0], start, 1e-9);  // back open 1 s after it started
}

TEST(GlovePlantScenarios, RandomMotionStaysWithinTableTwoRanges) {
  GlovePlantConfig c = idealConfig(HandScenario::kRandom);
  c.seed = 11;
  GlovePlant plant(c);
  SimIo io;
  const glove::Vec3<double> lo = {-90.0, -120.0, -80.0};
  const glove::Vec3<double> hi = {30.0, 0.0, 0.0};
  for (int i = 0; i < 5000; ++i) {
    plant.step(kDt, io);
    for (int f = 0; f < board::kFingerCount; ++f) {
      for (int j = 0; j < 3; ++j) {
        ASSERT_GE(deg(plant.fingerIntent(f)[j]), lo[j] - 1e-9);
        ASSERT_LE(deg(plant.fingerIntent(f)[j]), hi[j] + 1e-9);
      }
    }
  }
}

// =========================================================================================================
// Sensors: counts decode (through board.h) to the truth
// =========================================================================================================

TEST(GlovePlantSensors, HallCountsDecodeToTheTrueMechanismAngle) {
  GlovePlantConfig c = idealConfig(HandScenario::kRandom);
  c.noise = true;  // noise and quantisation on, per-part calibration errors off
  GlovePlant plant(c);
  SimIo io;
  double max_error = 0.0, sum_error = 0.0;
  int samples = 0;
  for (int i = 0; i < 3000; ++i) {
    plant.step(kDt, io);
    for (int f = 0; f < board::kFingerCount; ++f) {
      for (int j = 0; j < 3; ++j) {
        const double decoded = board::hallCountsToAngle_rad(j, static_cast<float>(io.adc[board::hallAdcChannel(f, j)]));
        const double error = std::fabs(decoded - plant.alpha_rad(f)[j]);
        max_error = std::fmax(max_error, error);
        sum_error += error;
        ++samples;
      }
    }
  }
  // Budget: table interpolation ≤ 0.6°, noise 2 counts (3σ) over the flattest slope (≈ 550 counts/rad).
  EXPECT_LT(deg(max_error), 1.5);
  EXPECT_LT(deg(sum_error / samples), 0.3);
}

TEST(GlovePlantSensors, HallCalibrationErrorsStayWithinTheirBudget) {
  GlovePlantConfig c = idealConfig(HandScenario::kRandom);
  c.calibration_errors = true;
  GlovePlant plant(c);
  SimIo io;
  double max_error = 0.0;
  double sum_error = 0.0;
  int samples = 0;
  for (int i = 0; i < 2000; ++i) {
    plant.step(kDt, io);
    for (int f = 0; f < board::kFingerCount; ++f) {
      for (int j = 0; j < 3; ++j) {
        const double decoded = board::hallCountsToAngle_rad(j, static_cast<float>(io.adc[board::hallAdcChannel(f, j)]));
        const double error = std::fabs(decoded - plant.alpha_rad(f)[j]);
        max_error = std::fmax(max_error, error);
        sum_error += error;
        ++samples;
      }
    }
  }
  EXPECT_GT(deg(max_error), 0.2);  // the parts really differ from nominal …
  EXPECT_LT(deg(max_error), 8.0);  // … within 3σ of gain 1.5 %, offset 6 counts, mounting 0.5°
  EXPECT_LT(deg(sum_error / samples), 2.0);
}

TEST(GlovePlantSensors, StrainCountsDecodeToTheTruePadForce) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 10.0;
  c.noise = true;
  GlovePlant plant(c);
  SimIo io;
  double max_error = 0.0;
  for (int i = 0; i < 2000; ++i) {
    plant.step(kDt, io);
    for (int f = 0; f < board::kFingerCount; ++f) {
      const double decoded = board::strainCountsToForce_N(io.adc[board::strainAdcChannel(f)]);
      max_error = std::fmax(max_error, std::fabs(decoded - plant.padForce_N(f)));
    }
  }
  // 0.65 counts of noise (7 mN; 10 000 samples reach ≈ 4σ = 28 mN) and ½ count of quantisation (5.4 mN); no
  // calibration errors, so no thermal drift.
  EXPECT_LT(max_error, 0.045);
  EXPECT_GT(max_error, 0.01);  // and it is not noise-free
}

// The gauge's zero follows the pad's temperature, warming with the time constant since the glove was put on; the
// coefficient is a per-part error (3σ 36 mN/K). docs/glove-plant.md "Sensors".
TEST(GlovePlantSensors, StrainZeroDriftsWithThePadWarmingUp) {
  GlovePlantConfig c = idealConfig(HandScenario::kStill);
  c.noise = true;
  c.calibration_errors = true;
  c.worn_before_start_s = 0.0;
  GlovePlant plant(c);
  SimIo io;
  for (int f = 0; f < board::kFingerCount; ++f) EXPECT_EQ(plant.strainDrift_N(f), 0.0) << "room temperature at donning";
  std::array<double, board::kFingerCount> at6{};
  for (int i = 0; i < 12; ++i) {
    plant.step(1.0, io);
    if (i == 5) {
      for (int f = 0; f < board::kFingerCount; ++f) at6[f] = plant.strainDrift_N(f);
    }
  }
  const double tau = c.params.pad_thermal_time_s;
  const double expected_ratio = (1.0 - std::exp(-12.0 / tau)) / (1.0 - std::exp(-6.0 / tau));  // 1.95
  int drifting = 0;
  for (int f = 0; f < board::kFingerCount; ++f) {
    const double d12 = plant.strainDrift_N(f);
    EXPECT_LE(std::fabs(d12), 3.0 * c.params.strain_zero_tc_N_per_K * c.params.pad_warmup_K * (1.0 - std::exp(-12.0 / tau)))
        << "finger " << f;
    if (std::fabs(at6[f]) > 1e-6) {
      ++drifting;
      EXPECT_NEAR(d12 / at6[f], expected_ratio, 1e-9) << "finger " << f;
    }
  }
  EXPECT_GE(drifting, 4) << "per-part coefficients are drawn for every finger";

  c.noise = false;
  GlovePlant quiet(c);
  for (int i = 0; i < 3; ++i) quiet.step(1.0, io);
  for (int f = 0; f < board::kFingerCount; ++f) EXPECT_EQ(quiet.strainDrift_N(f), 0.0) << "noise off: no drift";
}

TEST(GlovePlantSensors, CurrentCountsDecodeToTheTrueMotorCurrent) {
  GlovePlantConfig c = idealConfig(HandScenario::kStill);
  c.noise = true;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.1);
  double max_error = 0.0;
  for (int i = 0; i < 500; ++i) {
    plant.step(kDt, io);
    const double decoded = board::currentCountsToAmps_A(io.adc[board::currentAdcChannel(kIndex)]);
    max_error = std::fmax(max_error, std::fabs(decoded - plant.motorCurrent_A(kIndex)));
  }
  EXPECT_LT(max_error, 0.025);  // 3 counts of noise = 6 mA (σ)
}

TEST(GlovePlantSensors, StrainGaugeSaturatesAtFullScale) {
  GlovePlantConfig c = idealConfig(HandScenario::kPush);
  c.push_force_N = 30.0;
  c.noise = true;
  GlovePlant plant(c);
  SimIo io;
  run(plant, io, 2.0);
  ASSERT_GT(plant.padForce_N(kIndex), 25.0);
  EXPECT_EQ(io.adc[board::strainAdcChannel(kIndex)], board::kStrainMaxCounts);
  EXPECT_FLOAT_EQ(board::strainCountsToForce_N(io.adc[board::strainAdcChannel(kIndex)]),
                  board::strainCountsToForce_N(board::kStrainMaxCounts));
}

TEST(GlovePlantSensors, NoiseFreeCountsAreExactlyTheNominalTransfer) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io;
  plant.step(kDt, io);
  for (int f = 0; f < board::kFingerCount; ++f) {
    EXPECT_EQ(io.adc[board::strainAdcChannel(f)], board::kStrainZeroCounts);
    EXPECT_EQ(io.adc[board::currentAdcChannel(f)], board::kCurrentZeroCounts);
    for (int j = 0; j < 3; ++j) {
      const double half = j == 1 ? 60.0 : 90.0;
      const double centre = j == 0 ? -10.0 : (j == 1 ? -100.0 : 0.0);
      const double x = 67.5 / half * (deg(plant.alpha_rad(f)[j]) - centre) * kPi / 180.0;
      const double counts = 2048.0 + 0.040 * 30.0 * 4096.0 / 3.3 * (std::sin(x) - 0.04 * std::sin(3.0 * x));
      EXPECT_EQ(io.adc[board::hallAdcChannel(f, j)], std::lround(counts)) << "finger " << f << " joint " << j;
    }
  }
}

TEST(GlovePlantSensors, DisabledFingerReadsZeroCounts) {
  GlovePlantConfig c = idealConfig(HandScenario::kCloseOpen);
  c.finger_enabled[3] = false;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.2);
  run(plant, io, 0.1);
  for (int j = 0; j < 3; ++j) EXPECT_EQ(io.adc[board::hallAdcChannel(3, j)], 0);
  EXPECT_EQ(io.adc[board::strainAdcChannel(3)], 0);
  EXPECT_EQ(io.adc[board::currentAdcChannel(3)], 0);
  EXPECT_NE(io.adc[board::hallAdcChannel(2, 0)], 0);
}

// =========================================================================================================
// Determinism, real-time rules, input validation
// =========================================================================================================

std::vector<long long> trace(std::uint32_t seed) {
  GlovePlantConfig c;
  c.seed = seed;
  c.scenario = HandScenario::kRandom;  // noise and calibration errors on (defaults)
  GlovePlant plant(c);
  SimIo io = poweredIo(0.0);
  std::vector<long long> out;
  for (int i = 0; i < 600; ++i) {
    for (int f = 0; f < board::kFingerCount; ++f) io.pwm_duty[f] = static_cast<float>(0.2 * std::sin(0.01 * i + f));
    plant.step(kDt, io);
    for (int ch = 0; ch < board::kAdcChannelCount; ++ch) out.push_back(io.adc[ch]);
    out.push_back(std::llround(plant.theta_rad(kIndex)[1] * 1e12));
    out.push_back(std::llround(plant.spoolAngle_rad(kIndex) * 1e12));
  }
  return out;
}

TEST(GlovePlantDeterminism, SameSeedGivesIdenticalTrajectoriesAndCounts) {
  EXPECT_EQ(trace(7), trace(7));
  EXPECT_NE(trace(7), trace(8));
}

TEST(GlovePlantRealtime, StepDoesNotAllocate) {
  GlovePlantConfig c;
  c.scenario = HandScenario::kRandom;
  GlovePlant plant(c);
  SimIo io = poweredIo(0.15);
  plant.step(kDt, io);
  const long before = g_allocations.load();
  for (int i = 0; i < 2000; ++i) plant.step(kDt, io);
  const long after = g_allocations.load();
  EXPECT_EQ(after - before, 0);
  // And the counter works: an allocation in this scope is seen.
  auto* probe = new int(3);
  EXPECT_EQ(g_allocations.load() - after, 1);
  delete probe;
}

TEST(GlovePlantStep, RejectsNonPositiveNonFiniteOrOverlongTimeSteps) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io;
  EXPECT_THROW(plant.step(0.0, io), std::invalid_argument);
  EXPECT_THROW(plant.step(-1e-3, io), std::invalid_argument);
  EXPECT_THROW(plant.step(std::nan(""), io), std::invalid_argument);
  EXPECT_THROW(plant.step(INFINITY, io), std::invalid_argument);
  EXPECT_THROW(plant.step(2.0, io), std::invalid_argument);
  EXPECT_NO_THROW(plant.step(0.0123, io));  // any finite step in (0, 1] s, subdivided internally
  EXPECT_NEAR(plant.time_s(), 0.0123, 1e-15);
}

TEST(GlovePlantStep, NonFiniteDutyIsTreatedAsZero) {
  GlovePlant plant(idealConfig(HandScenario::kStill));
  SimIo io = poweredIo(0.0);
  io.pwm_duty[board::motorPwmChannel(kIndex)] = NAN;
  run(plant, io, 0.1);
  EXPECT_EQ(plant.motorCurrent_A(kIndex), 0.0);
  EXPECT_TRUE(std::isfinite(plant.theta_rad(kIndex)[0]));
}

TEST(GlovePlantConfig, RejectsNonsenseParameters) {
  GlovePlantConfig c;
  c.push_force_N = -1.0;
  EXPECT_THROW(GlovePlant{c}, std::invalid_argument);
  c = GlovePlantConfig{};
  c.params.tendon_stiffness_N_per_m = NAN;
  EXPECT_THROW(GlovePlant{c}, std::invalid_argument);
  c = GlovePlantConfig{};
  c.params.worm_lead_rad = 0.2;  // 11.5° lead with μ = 0.08: back-drivable, not the paper's worm
  EXPECT_THROW(GlovePlant{c}, std::invalid_argument);
  EXPECT_THROW(GlovePlant{}.truth(5), std::out_of_range);
}

}  // namespace

// Plant::advance (what the lockstep rig and firmware-sim call once per tick) is `steps` step() calls bit for bit:
// the same state, truth and final sensor counts, the skipped samples' noise draws skipped in the stream.
TEST(GlovePlant, AdvanceIsBitIdenticalToSteppingEachSubstep) {
  GlovePlantConfig cfg;  // noise, drift and calibration errors on
  cfg.scenario = HandScenario::kGrasp;
  cfg.finger_enabled[4] = false;  // a disabled finger draws no noise
  GlovePlant a(cfg), b(cfg);
  SimIo io_a, io_b;
  for (SimIo* io : {&io_a, &io_b}) {
    io->pwm_enabled = true;
    io->drive_enable = true;
  }
  for (int tick = 0; tick < 1500; ++tick) {
    for (std::size_t f = 0; f < 5; ++f) {
      const auto duty = static_cast<float>(0.2 * std::sin(0.01 * tick + static_cast<double>(f)));
      io_a.pwm_duty[f] = io_b.pwm_duty[f] = duty;
    }
    for (int k = 0; k < 10; ++k) a.step(1e-4, io_a);
    b.advance(1e-4, 10, io_b);
    ASSERT_EQ(io_a.adc, io_b.adc) << "tick " << tick;
    for (int f = 0; f < 4; ++f) {
      ASSERT_EQ(a.truth(f).theta_rad, b.truth(f).theta_rad) << "tick " << tick;
      ASSERT_EQ(a.truth(f).pad_force_N, b.truth(f).pad_force_N) << "tick " << tick;
      ASSERT_EQ(a.truth(f).tau_alpha_Nm, b.truth(f).tau_alpha_Nm) << "tick " << tick;
      ASSERT_EQ(a.truth(f).spool_angle_rad, b.truth(f).spool_angle_rad) << "tick " << tick;
    }
  }
}
