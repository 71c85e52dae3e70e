// Physics sanity of the simulated Bowden-cable SEA plant (hal/sim SeaPlant): the spring law of eq 2, the cable
// going slack beyond its pretension, the load-dependent play, the rig's load cell, the drive and the sensors.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "phalanx/sea/board.h"
#include "phalanx/sea/kinematics.h"
#include "phalanx/sim/sea_plant.h"

using namespace phalanx;
namespace board = phalanx::sea::board;

namespace {

const double kRm = static_cast<double>(board::kMotorPulleyRadius_m);  // motor pulley radius r_m

sim::SeaPlantConfig quietConfig() {
  sim::SeaPlantConfig c;
  c.noise = false;
  return c;
}

/// Drives both motors with `duty` for `seconds` (bridge on).
void drive(sim::SeaPlant& plant, sim::SimIo& io, double duty0, double duty1, double seconds) {
  io.pwm_enabled = true;
  io.drive_enable = true;
  io.pwm_duty[0] = static_cast<float>(duty0);
  io.pwm_duty[1] = static_cast<float>(duty1);
  const int steps = static_cast<int>(std::lround(seconds * 1000.0));
  for (int i = 0; i < steps; ++i) plant.step(1e-3, io);
}

/// Closed-loop helper on the truth: a stiff P loop on the motor angle (duty), to place the motor.
void moveMotorTo(sim::SeaPlant& plant, sim::SimIo& io, int sea, double target_rad, double seconds = 1.0) {
  io.pwm_enabled = true;
  io.drive_enable = true;
  const int steps = static_cast<int>(std::lround(seconds * 1000.0));
  for (int i = 0; i < steps; ++i) {
    const auto& t = plant.truth(sea);
    const double duty = 2.0 * (target_rad - t.motor_angle_rad) - 0.02 * t.motor_speed_rad_s;
    io.pwm_duty[static_cast<size_t>(sea)] = static_cast<float>(std::fmax(-0.5, std::fmin(0.5, duty)));
    plant.step(1e-3, io);
  }
}

}  // namespace

TEST(SeaPlant, SpringTorqueFollowsEq2WhileBothCablesAreTaut) {
  auto cfg = quietConfig();
  for (auto& ch : cfg.params.channel) {
    ch.backlash_base_m = 0.0;
    ch.backlash_per_Nm_m = 0.0;
  }
  sim::SeaPlant plant(cfg);
  sim::SimIo io;
  for (double target : {0.3, -0.5, 0.6}) {
    moveMotorTo(plant, io, 0, target);
    const auto& t = plant.truth(0);
    const auto& ch = cfg.params.channel[0];
    const double k = ch.spring_stiffness_N_per_m, rj = ch.joint_pulley_radius_m, rm = ch.motor_pulley_radius_m;
    ASSERT_EQ(k, 2816.0);
    ASSERT_NEAR(rj, 0.010, 1e-9);
    ASSERT_NEAR(rm, 0.015, 1e-9);
    const double eq2 = 2.0 * k * (rm * t.motor_angle_rad - rj * t.joint_angle_rad) * rj;
    EXPECT_NEAR(t.joint_torque_Nm, eq2, 1e-12) << target;
    EXPECT_NEAR(plant.idealSeaTorque_Nm(0), eq2, 1e-12);
    EXPECT_GT(t.tension1_N, 0.0);
    EXPECT_GT(t.tension2_N, 0.0);
    EXPECT_NEAR(t.tension1_N + t.tension2_N, 2.0 * 20.0, 1e-9) << "the pretension is shared while both are taut";
    // Joint held by the clamp: the load cell carries exactly the SEA torque (quasi-static joint).
    EXPECT_NEAR(t.load_cell_torque_Nm, t.joint_torque_Nm, 1e-12);
    EXPECT_NEAR(t.joint_angle_rad, t.joint_torque_Nm / 30.0, 1e-12);
  }
}

TEST(SeaPlant, OneCableGoesSlackBeyondThePretension) {
  auto cfg = quietConfig();
  cfg.params.channel[0].pretension_N = 5.0;
  cfg.params.channel[0].backlash_base_m = 0.0;
  cfg.params.channel[0].backlash_per_Nm_m = 0.0;
  sim::SeaPlant plant(cfg);
  sim::SimIo io;
  moveMotorTo(plant, io, 0, 0.6);  // k d ≈ 12 N > T_0 = 5 N
  const auto& t = plant.truth(0);
  EXPECT_EQ(t.tension1_N, 0.0);
  EXPECT_NEAR(t.joint_torque_Nm, (5.0 + 2816.0 * t.spring_deflection_m) * cfg.params.channel[0].joint_pulley_radius_m, 1e-12);
  EXPECT_LT(t.joint_torque_Nm, plant.idealSeaTorque_Nm(0)) << "eq 2 over-estimates once a cable is slack";
}

TEST(SeaPlant, CablePlayDelaysTheSpringByItsLoadDependentWidthOnReversal) {
  auto cfg = quietConfig();
  cfg.params.channel[0].backlash_base_m = 1.0e-3;
  cfg.params.channel[0].backlash_per_Nm_m = 2.0e-3;
  sim::SeaPlant plant(cfg);
  sim::SimIo io;
  moveMotorTo(plant, io, 0, 0.5);
  const auto& t = plant.truth(0);
  // Dragged forward: the spring side trails the motor side by half the play.
  const double b = 1.0e-3 + 2.0e-3 * std::fabs(t.joint_torque_Nm);
  EXPECT_NEAR(t.backlash_m, b, 1e-9);
  EXPECT_NEAR(t.cable_motor_m - t.cable_spring_m, 0.5 * b, 1e-6);
  // Reverse by less than the play: the spring side (and the torque) does not move.
  const double x_e = t.cable_spring_m;
  const double tau = t.joint_torque_Nm;
  moveMotorTo(plant, io, 0, 0.5 - 0.8 * b / kRm);
  EXPECT_NEAR(plant.truth(0).cable_spring_m, x_e, 1e-12);
  EXPECT_NEAR(plant.truth(0).joint_torque_Nm, tau, 1e-12);
  // Reverse past it: now the spring follows, leading the motor by half the play.
  moveMotorTo(plant, io, 0, 0.5 - 3.0 * b / kRm);
  const auto& t2 = plant.truth(0);
  EXPECT_LT(t2.cable_spring_m, x_e - 1e-4);
  EXPECT_NEAR(t2.cable_spring_m - t2.cable_motor_m, 0.5 * t2.backlash_m, 1e-6);
}

TEST(SeaPlant, LoadCellAndJointSensorCountsDecodeToTheTruth) {
  sim::SeaPlant plant(quietConfig());
  sim::SimIo io;
  moveMotorTo(plant, io, 0, 0.4);
  plant.step(1e-3, io);
  const auto& t = plant.truth(0);
  const double lc = (io.adc[board::kAdcFirstLoadCell] - board::kAdcMidCounts) / static_cast<double>(board::kLoadCellCountsPerNm);
  EXPECT_NEAR(lc, t.load_cell_torque_Nm, 0.6 / static_cast<double>(board::kLoadCellCountsPerNm));
  EXPECT_GT(t.load_cell_torque_Nm, 0.1);
  const double joint = (io.adc[board::kAdcFirstJoint] - board::kAdcMidCounts) / static_cast<double>(board::kJointCountsPerRad);
  EXPECT_NEAR(joint, t.joint_angle_rad, 0.6 / static_cast<double>(board::kJointCountsPerRad));
  const double motor = io.encoder[0] * static_cast<double>(board::kMotorRadPerCount);
  EXPECT_LE(motor, t.motor_angle_rad + 1e-12);
  EXPECT_GT(motor, t.motor_angle_rad - static_cast<double>(board::kMotorRadPerCount));
}

TEST(SeaPlant, SensorNoiseHasTheConfiguredSpreadAndIsSeeded) {
  sim::SeaPlantConfig cfg;  // noise on
  sim::SeaPlant a(cfg), b(cfg);
  sim::SimIo io_a, io_b;
  double sum = 0.0, sum2 = 0.0;
  const int n = 4000;
  for (int i = 0; i < n; ++i) {
    a.step(1e-3, io_a);
    b.step(1e-3, io_b);
    ASSERT_EQ(io_a.adc, io_b.adc) << "same seed, same counts";
    const double x = io_a.adc[board::kAdcFirstJoint] - board::kAdcMidCounts;
    sum += x;
    sum2 += x * x;
  }
  const double sd = std::sqrt(sum2 / n - (sum / n) * (sum / n));
  EXPECT_NEAR(sd, 2.0, 0.2);  // 2 counts (plus rounding, ≈ 0.29 counts)
}

TEST(SeaPlant, UnloadedMotorReachesItsNoLoadSpeed) {
  auto cfg = quietConfig();
  for (auto& ch : cfg.params.channel) {
    ch.spring_stiffness_N_per_m = 1e-6;  // springs practically absent
    ch.pretension_N = 0.0;
    ch.sheath_friction = 0.0;
  }
  sim::SeaPlant plant(cfg);
  sim::SimIo io;
  drive(plant, io, 0.5, 0.0, 0.3);
  const auto& p = cfg.params;
  const double nkt = p.gear_ratio * p.torque_constant_Nm_per_A;
  const double r = p.motor_resistance_Ohm + p.bridge_on_resistance_Ohm;
  const double coulomb = nkt * p.no_load_current_A;
  // Steady state: N k_t (V − N k_t ω)/R = Coulomb friction (+ the gear loss on that torque).
  const double tau_m = coulomb / p.gear_efficiency;
  const double omega = (0.5 * p.supply_V - tau_m * r / nkt) / nkt;
  EXPECT_NEAR(plant.truth(0).motor_speed_rad_s, omega, 0.01 * omega);
  EXPECT_NEAR(plant.truth(0).motor_current_A, tau_m / nkt, 0.005);
}

TEST(SeaPlant, DisabledBridgeCarriesNoCurrentAndTheSpringBackDrivesTheMotor) {
  sim::SeaPlant plant(quietConfig());
  sim::SimIo io;
  moveMotorTo(plant, io, 0, 0.7);
  const double tau_loaded = plant.truth(0).joint_torque_Nm;
  ASSERT_GT(tau_loaded, 0.2);
  io.pwm_enabled = false;
  for (int i = 0; i < 2000; ++i) plant.step(1e-3, io);
  const auto& t = plant.truth(0);
  EXPECT_EQ(t.motor_current_A, 0.0);
  EXPECT_FALSE(t.bridge_on);
  // The drive stops where the spring torque at the pulley no longer beats the friction (motor + sheath).
  const auto& p = quietConfig().params;
  const double hold_pulley = p.gear_ratio * p.torque_constant_Nm_per_A * p.no_load_current_A +
                             kRm * 0.2 * (t.tension1_N + t.tension2_N);
  EXPECT_LT(std::fabs(t.joint_torque_Nm), hold_pulley * 0.010 / kRm + 1e-9);
  EXPECT_LT(t.joint_torque_Nm, 0.5 * tau_loaded);
}

TEST(SeaPlant, RejectsBadConfigurationAndBadSteps) {
  auto cfg = quietConfig();
  cfg.params.channel[1].spring_stiffness_N_per_m = -1.0;
  EXPECT_THROW(sim::SeaPlant{cfg}, std::invalid_argument);
  cfg = quietConfig();
  cfg.params.gear_efficiency = 1.5;
  EXPECT_THROW(sim::SeaPlant{cfg}, std::invalid_argument);
  cfg = quietConfig();
  cfg.params.supply_V = std::nan("");
  EXPECT_THROW(sim::SeaPlant{cfg}, std::invalid_argument);
  sim::SeaPlant plant(quietConfig());
  sim::SimIo io;
  EXPECT_THROW(plant.step(0.0, io), std::invalid_argument);
  EXPECT_THROW(plant.step(std::nan(""), io), std::invalid_argument);
  EXPECT_THROW((void)plant.truth(2), std::out_of_range);
}

// ---- Finger variant (eq 13–14) ------------------------------------------------------------------------------

namespace {

sim::SeaPlantConfig fingerConfig(sim::SeaUserMotion motion = sim::SeaUserMotion::kRelaxed) {
  sim::SeaPlantConfig c;
  c.noise = false;
  c.variant = sim::SeaVariant::kFinger;
  c.motion = motion;
  return c;
}

}  // namespace

TEST(SeaPlantFinger, PassiveTorqueIsTheDoubleExponentialOfEq14) {
  sim::SeaPlant plant(fingerConfig());
  const auto& f = fingerConfig().params.finger;
  for (int j = 0; j < 2; ++j) {
    const auto jj = static_cast<size_t>(j);
    for (double deg : {-80.0, -45.0, -20.0, 0.0, 10.0}) {
      const double theta = deg * M_PI / 180.0;
      const double phi = -theta;  // eq 14's flexion-positive angle
      const double eq14 = f.A_Nm[jj] * (std::exp(-f.B_per_rad[jj] * (phi - f.E_rad[jj])) - 1.0) -
                          f.C_Nm[jj] * (std::exp(f.D_per_rad[jj] * (phi - f.F_rad[jj])) - 1.0);
      EXPECT_NEAR(plant.passiveTorque_Nm(j, theta), -eq14, 1e-12) << j << " " << deg;
    }
    // Restoring: extension beyond the rest pose is pushed back towards flexion (−θ) and vice versa.
    EXPECT_LT(plant.passiveTorque_Nm(j, 0.2), 0.0);
    EXPECT_GT(plant.passiveTorque_Nm(j, -1.4), 0.0);
  }
}

TEST(SeaPlantFinger, RelaxedFingerStaysAtItsRestPoseWithTheBridgesOff) {
  sim::SeaPlant plant(fingerConfig());
  sim::SimIo io;
  const auto rest = plant.finger().theta_rad;
  EXPECT_NEAR(plant.passiveTorque_Nm(0, rest[0]), 0.0, 1e-9);
  EXPECT_NEAR(plant.passiveTorque_Nm(1, rest[1]), 0.0, 1e-9);
  for (int i = 0; i < 1000; ++i) plant.step(1e-3, io);
  EXPECT_NEAR(plant.finger().theta_rad[0], rest[0], 1e-9);
  EXPECT_NEAR(plant.finger().theta_rad[1], rest[1], 1e-9);
  EXPECT_NEAR(plant.truth(0).joint_torque_Nm, 0.0, 1e-12);
}

TEST(SeaPlantFinger, SensorAnglesReproduceTheFingerThroughTheKinematicsEstimator) {
  sim::SeaPlant plant(fingerConfig(sim::SeaUserMotion::kRandom));
  sim::SimIo io;
  const auto model = sea::defaultModel<double>();
  for (int k = 0; k < 5; ++k) {
    for (int i = 0; i < 400; ++i) plant.step(1e-3, io);
    const auto& f = plant.finger();
    sea::Data<double> d;
    const sea::Status st = sea::computeFromSensors(model, f.sensors_rad, d);
    ASSERT_TRUE(sea::isUsable(st));
    EXPECT_NEAR(d.theta4_rad, f.theta_rad[0], 1e-9);
    EXPECT_NEAR(d.theta8_rad, f.theta_rad[1], 1e-9);
    EXPECT_NEAR(d.theta_dip_rad, f.theta_rad[2], 1e-6);
    // The redundant sensor agrees with the model prediction from the two SEA joints (eq 12's y_m).
    EXPECT_NEAR(f.sensors_rad[sea::kSensorRedundant],
                sea::predictRedundant(model.subject, model.fixed, f.sensors_rad[0], f.sensors_rad[1]), 1e-9);
    // Counts decode to the sensor angles within one count.
    for (int s = 0; s < 5; ++s) {
      const double angle = static_cast<double>(board::kJointCentre_rad[static_cast<size_t>(s)]) +
                           (io.adc[static_cast<size_t>(s)] - board::kAdcMidCounts) / static_cast<double>(board::kJointCountsPerRad);
      EXPECT_NEAR(angle, f.sensors_rad[static_cast<size_t>(s)], 0.6 / static_cast<double>(board::kJointCountsPerRad)) << s;
    }
  }
  EXPECT_EQ(io.adc[board::kAdcFirstLoadCell], board::kAdcMidCounts) << "no load cell on the finger";
}

TEST(SeaPlantFinger, AppliedFingerTorqueIsEq9OfTheSeaTorques) {
  sim::SeaPlant plant(fingerConfig());
  sim::SimIo io;
  io.pwm_enabled = true;
  io.drive_enable = true;
  io.pwm_duty[0] = 0.15f;
  io.pwm_duty[1] = -0.1f;
  for (int i = 0; i < 200; ++i) plant.step(1e-3, io);
  const auto& f = plant.finger();
  ASSERT_GT(std::fabs(plant.truth(0).joint_torque_Nm), 0.01);
  // Virtual work: τ_jᵀ Θ̇_r = τ_fᵀ θ̇_f for any Θ̇_r, with θ̇_f = J_n Θ̇_r.
  for (const auto& w : {std::array<double, 2>{1.0, 0.0}, std::array<double, 2>{0.3, -0.7}}) {
    const double p_exo = plant.truth(0).joint_torque_Nm * w[0] + plant.truth(1).joint_torque_Nm * w[1];
    const double wf0 = f.J_n[0][0] * w[0] + f.J_n[0][1] * w[1];
    const double wf1 = f.J_n[1][0] * w[0] + f.J_n[1][1] * w[1];
    EXPECT_NEAR(f.applied_Nm[0] * wf0 + f.applied_Nm[1] * wf1, p_exo, 1e-9);
  }
  // The finger flexes or extends under it: it left the rest pose.
  EXPECT_GT(std::fabs(f.theta_rad[0] - f.intent_rad[0]) + std::fabs(f.theta_rad[1] - f.intent_rad[1]), 0.01);
}

TEST(SeaPlantFinger, RandomUserMotionSpansTheConfiguredRange) {
  sim::SeaPlant plant(fingerConfig(sim::SeaUserMotion::kRandom));
  sim::SimIo io;  // bridges off: the user back-drives the SEAs
  double lo[2] = {1e9, 1e9}, hi[2] = {-1e9, -1e9};
  for (int i = 0; i < 10000; ++i) {
    plant.step(1e-3, io);
    for (int j = 0; j < 2; ++j) {
      lo[j] = std::fmin(lo[j], plant.finger().theta_rad[static_cast<size_t>(j)]);
      hi[j] = std::fmax(hi[j], plant.finger().theta_rad[static_cast<size_t>(j)]);
    }
  }
  EXPECT_GT(hi[0] - lo[0], 0.3);
  EXPECT_GT(hi[1] - lo[1], 0.3);
  EXPECT_LT(hi[0] - lo[0], 2.0 * 0.30 + 0.1);
  EXPECT_TRUE(plant.finger().kinematics_ok);
}

// Plant::advance (what the lockstep rig and firmware-sim call once per tick) is `steps` step() calls bit for bit:
// the same state, truth and final sensor counts, the skipped samples' noise draws skipped in the stream.
TEST(SeaPlant, AdvanceIsBitIdenticalToSteppingEachSubstep) {
  for (const auto variant : {sim::SeaVariant::kRig, sim::SeaVariant::kFinger}) {
    sim::SeaPlantConfig cfg;  // noise on
    cfg.variant = variant;
    cfg.motion = sim::SeaUserMotion::kRandom;
    sim::SeaPlant a(cfg), b(cfg);
    sim::SimIo io_a, io_b;
    for (sim::SimIo* io : {&io_a, &io_b}) {
      io->pwm_enabled = true;
      io->drive_enable = true;
    }
    for (int tick = 0; tick < 500; ++tick) {
      const auto duty = static_cast<float>(0.3 * std::sin(0.02 * tick));
      io_a.pwm_duty[0] = io_b.pwm_duty[0] = duty;
      io_a.pwm_duty[1] = io_b.pwm_duty[1] = -duty;
      for (int k = 0; k < 10; ++k) a.step(1e-4, io_a);
      b.advance(1e-4, 10, io_b);
      ASSERT_EQ(io_a.adc, io_b.adc) << "tick " << tick;
      ASSERT_EQ(io_a.encoder, io_b.encoder) << "tick " << tick;
      for (int s = 0; s < 2; ++s) {
        ASSERT_EQ(a.truth(s).motor_angle_rad, b.truth(s).motor_angle_rad) << "tick " << tick;
        ASSERT_EQ(a.truth(s).joint_torque_Nm, b.truth(s).joint_torque_Nm) << "tick " << tick;
      }
    }
  }
}

// ---- Stretch reflex, maximal effort, donning variation (instrumented assessments, docs/sea-plant.md) ---------

TEST(SeaPlantFinger, StretchReflexIsOffByDefault) {
  sim::SeaPlant plant(fingerConfig());
  for (double rate : {0.0, 2.0, 10.0}) EXPECT_EQ(plant.reflexTorque_Nm(0, 0.0, rate), 0.0);
  for (double off : plant.donningOffsets()) EXPECT_EQ(off, 0.0);
}

// τ_reflex = −G·(θ̇ − v_th)⁺ while the flexion is below the catch angle; nothing above it or below v_th.
TEST(SeaPlantFinger, StretchReflexGrowsWithVelocityAboveTheThresholdBeyondTheCatchAngle) {
  sim::SeaPlantConfig c = fingerConfig();
  c.params.finger = sim::withStretchReflex(c.params.finger);
  sim::SeaPlant plant(c);
  const auto& f = c.params.finger;
  const double v_th = f.reflex_threshold_rad_s[0], catch_flexion = f.reflex_catch_flexion_rad[0];
  const double stretched = -(catch_flexion - 0.05);  // θ: 0.05 rad less flexed than the catch angle
  EXPECT_EQ(plant.reflexTorque_Nm(0, stretched, 0.9 * v_th), 0.0);
  EXPECT_NEAR(plant.reflexTorque_Nm(0, stretched, v_th + 1.0), -f.reflex_gain_Nm_s_per_rad[0] * 1.0, 1e-12);
  EXPECT_NEAR(plant.reflexTorque_Nm(0, stretched, v_th + 2.0), -f.reflex_gain_Nm_s_per_rad[0] * 2.0, 1e-12);
  EXPECT_EQ(plant.reflexTorque_Nm(0, -(catch_flexion + 0.05), v_th + 2.0), 0.0);  // not yet at the catch
  EXPECT_EQ(plant.reflexTorque_Nm(0, stretched, -(v_th + 2.0)), 0.0);             // flexing: no stretch
}

TEST(SeaPlantFinger, ReflexAndMaximalEffortParametersAreValidated) {
  sim::SeaPlantConfig c = fingerConfig();
  c.params.finger.reflex_gain_Nm_s_per_rad[1] = -0.1;
  EXPECT_THROW(sim::SeaPlant{c}, std::invalid_argument);
  c = fingerConfig();
  c.params.finger.reflex_catch_flexion_rad[0] = NAN;
  EXPECT_THROW(sim::SeaPlant{c}, std::invalid_argument);
  c = fingerConfig();
  c.params.finger.max_voluntary_Nm[0] = -1.0;
  EXPECT_THROW(sim::SeaPlant{c}, std::invalid_argument);
  c = fingerConfig();
  c.params.donning_offset_sd_rad = INFINITY;
  EXPECT_THROW(sim::SeaPlant{c}, std::invalid_argument);
}

// A maximal effort scheduled at 0.2 s: no muscle torque before, −max_voluntary_Nm (flexing) once risen.
TEST(SeaPlantFinger, MaximalEffortRisesToTheMaximalVoluntaryTorque) {
  sim::SeaPlantConfig c = fingerConfig();
  c.params.finger.max_effort_start_s = 0.2;
  c.params.finger.max_effort_duration_s = 2.0;
  sim::SeaPlant plant(c);
  sim::SimIo io{};
  for (int i = 0; i < 150; ++i) plant.step(1e-3, io);
  EXPECT_EQ(plant.finger().muscle_Nm[0], 0.0);
  for (int i = 0; i < 700; ++i) plant.step(1e-3, io);
  EXPECT_NEAR(plant.finger().muscle_Nm[0], -c.params.finger.max_voluntary_Nm[0], 1e-9);
  EXPECT_NEAR(plant.finger().muscle_Nm[1], -c.params.finger.max_voluntary_Nm[1], 1e-9);
}

// Donning offsets: fixed per seed, different between seeds, of the configured size, and on their own stream
// (the noise-free sensor readings shift by exactly the offset).
TEST(SeaPlantFinger, DonningOffsetsAreSeededAndShiftTheSensors) {
  sim::SeaPlantConfig c = fingerConfig();
  c.params.donning_offset_sd_rad = 0.02;
  c.seed = 5;
  sim::SeaPlant a(c), a2(c);
  c.seed = 6;
  sim::SeaPlant b(c);
  double sq = 0.0;
  for (size_t s = 0; s < 5; ++s) {
    EXPECT_EQ(a.donningOffsets()[s], a2.donningOffsets()[s]);
    EXPECT_NE(a.donningOffsets()[s], b.donningOffsets()[s]);
    sq += a.donningOffsets()[s] * a.donningOffsets()[s];
  }
  EXPECT_LT(std::sqrt(sq / 5.0), 0.06);  // 3σ
  sim::SeaPlantConfig none = fingerConfig();
  none.seed = 5;
  sim::SeaPlant plain(none);
  sim::SimIo io_a{}, io_p{};
  a.step(1e-3, io_a);
  plain.step(1e-3, io_p);
  const double counts_per_rad = static_cast<double>(board::kJointCountsPerRad);
  for (int s = 0; s < board::kJointSensorCount; ++s) {
    const auto i = static_cast<size_t>(board::kAdcFirstJoint + s);
    EXPECT_NEAR(io_a.adc[i] - io_p.adc[i], a.donningOffsets()[static_cast<size_t>(s)] * counts_per_rad, 1.0) << s;
  }
}
