// Simulated Twin-Pantograph plant (phalanx/sim/pen_plant.h, seeds/004 eq 28–29, Table X).
#include "phalanx/sim/pen_plant.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "phalanx/host/pen/force_split.h"

namespace {

using namespace phalanx;
namespace pp = phalanx::pen;

sim::SimIo bridgeOn() {
  sim::SimIo io;
  io.pwm_enabled = true;
  io.drive_enable = true;
  return io;
}

TEST(PenPlant, MassMatrixIsEq29InSIUnits) {
  sim::PenPlant plant;
  const auto& D = plant.massMatrix();
  EXPECT_NEAR(D[0][0], 0.190, 1e-12);     // Table X effective mass x: 190 g
  EXPECT_NEAR(D[1][1], 0.226, 1e-12);
  EXPECT_NEAR(D[2][2], 0.156, 1e-12);
  EXPECT_NEAR(D[3][3], 10300e-7, 1e-15);  // 10300 g·cm² = 1.03e-3 kg·m²
  EXPECT_NEAR(D[4][4], 12600e-7, 1e-15);
  EXPECT_NEAR(D[1][3], -346e-5, 1e-15);   // N per rad/s² (= kg·m)
  EXPECT_NEAR(D[3][1], D[1][3], 1e-18);
}

TEST(PenPlant, EncodersStartAtZeroAndReportQuantisedJointAngles) {
  sim::PenPlantConfig cfg;
  cfg.scenario = sim::PenHandScenario::kRandom;
  sim::PenPlant plant(cfg);
  sim::SimIo io;
  plant.step(1e-3, io);
  for (int i = 0; i < 6; ++i) EXPECT_LE(std::abs(io.encoder[i]), 1);
  for (int k = 0; k < 2000; ++k) plant.step(1e-3, io);
  const auto counts = pp::countsFromAngles(plant.model(), plant.truth().q_rad);
  int moved = 0;
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(io.encoder[i], counts[i]);
    moved += std::abs(counts[i]) > 20 ? 1 : 0;
  }
  EXPECT_GE(moved, 4) << "the random hand should move most joints";
}

TEST(PenPlant, ReleasedPenFallsUnderItsUnbalancedWeight) {
  sim::PenPlantConfig cfg;
  cfg.scenario = sim::PenHandScenario::kReleased;
  cfg.noise = false;
  sim::PenPlant plant(cfg);
  sim::SimIo io;
  plant.step(2e-3, io);
  // From rest friction is zero: v_y(t) ≈ −(D⁻¹)_yy·w(z)·g·t (D's y row couples to θx; D⁻¹ accounts for it).
  const double w = plant.weightKg(0.20);
  EXPECT_NEAR(w, 0.070 + 0.060 * (0.0375 / 0.075), 1e-12);
  const auto& D = plant.massMatrix();
  // (D⁻¹)_yy from the 2×2 (y, θx) block; the other couplings are < 1e-3 of the diagonal.
  const double dyy_inv = D[3][3] / (D[1][1] * D[3][3] - D[1][3] * D[3][1]);
  EXPECT_NEAR(plant.truth().x_dot[1], -dyy_inv * w * 9.81 * 2e-3, 0.05 * dyy_inv * w * 9.81 * 2e-3);
}

TEST(PenPlant, SplitTorquesAccelerateThePenAsTheWrenchSays) {
  // The force split (τ = Jᵀf) and the plant (Q = Σ (∂p/∂x)ᵀ J⁻ᵀτ) must agree: a 1 N force along x at the centre
  // gives ẍ = D⁻¹·(1, 0, 0, 0, 0) from rest (no friction at rest, no gravity, no hand).
  sim::PenPlantConfig cfg;
  cfg.scenario = sim::PenHandScenario::kReleased;
  cfg.gravity = false;
  sim::PenPlant plant(cfg);
  sim::SimIo io = bridgeOn();
  pp::Data<double> kin;
  ASSERT_EQ(pp::computeForward(plant.model(), plant.model().q_home_rad, kin), pp::Status::kOk);
  host::pen::PenForceSplitter splitter;
  host::pen::PenWrench w;
  w.force_N = {1.0, 0.0, 0.0};
  host::pen::SplitResult r;
  ASSERT_EQ(splitter.split(kin, w, r), host::pen::SplitStatus::kOk);
  for (std::size_t i = 0; i < 6; ++i) io.pwm_duty[i] = pen::board::dutyFromTorque(static_cast<float>(r.tau_Nm[i]));
  const double dt = 1e-4;
  plant.step(dt, io);
  const auto& D = plant.massMatrix();
  // Solve D·a = e_x by the plant-independent route: D is nearly diagonal in x, check the dominant term.
  EXPECT_NEAR(plant.truth().x_dot[0] / dt, 1.0 / D[0][0], 0.02 / D[0][0]);
  EXPECT_LT(std::fabs(plant.truth().x_dot[1] / dt), 0.05 / D[0][0]);
  EXPECT_LT(std::fabs(plant.truth().x_dot[2] / dt), 0.05 / D[0][0]);
}

TEST(PenPlant, MotorTorqueIsClampedAndOffWithoutTheBridgeOrWithTheEstop) {
  sim::PenPlantConfig cfg;
  cfg.noise = false;
  sim::PenPlant plant(cfg);
  sim::SimIo io = bridgeOn();
  io.pwm_duty[0] = 3.0f;
  io.pwm_duty[1] = -0.5f;
  plant.step(1e-3, io);
  EXPECT_NEAR(plant.truth().motor_torque_Nm[0], 2.1, 1e-6);
  EXPECT_NEAR(plant.truth().motor_torque_Nm[1], -1.05, 1e-6);
  // Current sense: −0.5 duty = −10.5 A.
  EXPECT_NEAR(static_cast<double>(io.adc[1] - pen::board::kAdcMidCounts) * static_cast<double>(pen::board::kAmpsPerCount), -10.5, 0.02);
  io.estop_pressed = true;
  plant.step(1e-3, io);
  EXPECT_EQ(plant.truth().motor_torque_Nm[0], 0.0);
  io.estop_pressed = false;
  io.pwm_enabled = false;
  plant.step(1e-3, io);
  EXPECT_EQ(plant.truth().motor_torque_Nm[1], 0.0);
  EXPECT_EQ(io.adc[1], pen::board::kAdcMidCounts);
}

TEST(PenPlant, EnergyBalanceCloses) {
  // ΔKE = W_motor + W_friction + W_hand + W_gravity + W_stop over a random run with random motor torques.
  sim::PenPlantConfig cfg;
  cfg.scenario = sim::PenHandScenario::kRandom;
  sim::PenPlant plant(cfg);
  sim::SimIo io = bridgeOn();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  const double ke0 = plant.truth().kinetic_energy_J;
  double work_scale = 0.0;
  for (int k = 0; k < 3000; ++k) {
    if (k % 50 == 0)
      for (int i = 0; i < 6; ++i) io.pwm_duty[static_cast<std::size_t>(i)] = u(rng);
    plant.step(1e-3, io);
    const auto& t = plant.truth();
    work_scale = std::fmax(work_scale, std::fabs(t.motor_work_J) + std::fabs(t.hand_work_J) + std::fabs(t.friction_work_J));
  }
  const auto& t = plant.truth();
  const double balance = t.kinetic_energy_J - ke0 -
                         (t.motor_work_J + t.friction_work_J + t.hand_work_J + t.gravity_work_J + t.stop_work_J);
  EXPECT_LT(std::fabs(balance), 0.01 * work_scale) << "ΔKE " << t.kinetic_energy_J - ke0 << " motor " << t.motor_work_J
                                                   << " hand " << t.hand_work_J << " fric " << t.friction_work_J;
  EXPECT_LT(t.friction_work_J, 0.0);
  EXPECT_GT(work_scale, 1e-3);
}

TEST(PenPlant, BadConfigurationIsRefused) {
  sim::PenPlantConfig cfg;
  cfg.start.centre_m = {0.0, 0.0, 0.6};
  EXPECT_THROW(sim::PenPlant{cfg}, std::invalid_argument);
  cfg = {};
  cfg.params.D_paper[3][3] = -1.0;
  EXPECT_THROW(sim::PenPlant{cfg}, std::invalid_argument);
  cfg = {};
  cfg.params.hand_mass_kg = std::nan("");
  EXPECT_THROW(sim::PenPlant{cfg}, std::invalid_argument);
  sim::PenPlant plant;
  sim::SimIo io;
  EXPECT_THROW(plant.step(-1.0, io), std::invalid_argument);
}

}  // namespace
