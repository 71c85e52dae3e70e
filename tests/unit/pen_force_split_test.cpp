// Twin-Pantograph force split (phalanx/host/pen/force_split.h, seeds/004 §VI Fig. 18).
#include "phalanx/host/pen/force_split.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <random>

#include "../support/counting_allocator.h"  // g_allocations

namespace {

using namespace phalanx::host::pen;
namespace pp = phalanx::pen;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

pp::PenPose<double> randomWorkspacePose(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  pp::PenPose<double> p;
  p.centre_m = {0.06 * u(rng), 0.0375 * u(rng), 0.20 + 0.0375 * u(rng)};
  p.theta_x_rad = 45 * kDeg * u(rng);
  p.theta_z_rad = 45 * kDeg * u(rng);
  return p;
}

PenWrench randomWrench(std::mt19937& rng, double force_N, double torque_Nm) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PenWrench w;
  for (int i = 0; i < 3; ++i) {
    w.force_N[i] = force_N * u(rng);
    w.torque_Nm[i] = torque_Nm * u(rng);
  }
  return w;
}

// Random workspace configuration seen through quantised encoders (what the host gets).
pp::Data<double> randomKinematics(const pp::Model<double>& m, std::mt19937& rng) {
  pp::JointVec<double> q;
  EXPECT_EQ(pp::computeInverse(m, randomWorkspacePose(rng), q), pp::Status::kOk);
  pp::Data<double> d;
  EXPECT_EQ(pp::computeForward(m, pp::anglesFromCounts(m, pp::countsFromAngles(m, q)), d), pp::Status::kOk);
  return d;
}

Vec3d perpendicularPart(const Vec3d& v, const Vec3d& a) {
  const double k = pp::dot(v, a);
  return {v[0] - k * a[0], v[1] - k * a[1], v[2] - k * a[2]};
}

// The wrench the six torques actually produce: f = J⁻ᵀτ per pantograph, then statics at the centre.
PenWrench wrenchFromTorques(const pp::Data<double>& d, const JointVecd& tau) {
  Vec3d fb{}, ft{};
  EXPECT_TRUE(tipForceFromTorques(d.pantograph[pp::kBottom].J, {tau[0], tau[1], tau[2]}, fb));
  EXPECT_TRUE(tipForceFromTorques(d.pantograph[pp::kTop].J, {tau[3], tau[4], tau[5]}, ft));
  PenWrench w;
  endForcesToWrench(d, fb, ft, w);
  return w;
}

void expectWrenchNear(const PenWrench& got, const PenWrench& want, const Vec3d& axis, double scale, double tol) {
  const Vec3d m_want = perpendicularPart(want.torque_Nm, axis);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(got.force_N[i], scale * want.force_N[i], tol) << "force " << i;
    EXPECT_NEAR(got.torque_Nm[i], scale * m_want[i], tol) << "torque " << i;
  }
}

TEST(PenForceSplit, SixTorquesReproduceTheWrenchExactlyWhenUnsaturated) {
  const pp::Model<double> m = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  std::mt19937 rng(11);
  SplitResult r;
  for (int k = 0; k < 3000; ++k) {
    const pp::Data<double> d = randomKinematics(m, rng);
    const PenWrench w = randomWrench(rng, 5.0, 0.1);  // Table X continuous range: ~5 N, ~0.4 N·m
    ASSERT_EQ(splitter.split(d, w, r), SplitStatus::kOk);
    EXPECT_EQ(r.limit_active_mask, 0);
    EXPECT_DOUBLE_EQ(r.scale, 1.0);
    expectWrenchNear(wrenchFromTorques(d, r.tau_Nm), w, d.B_axis, 1.0, 1e-9);
    // The end forces it reports are the ones the torques produce (τ = Jᵀ f per pantograph).
    const Vec3d tb = pp::mulTransposed(d.pantograph[pp::kBottom].J, r.f_bottom_N);
    const Vec3d tt = pp::mulTransposed(d.pantograph[pp::kTop].J, r.f_top_N);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(tb[i], r.tau_Nm[i], 1e-12);
      EXPECT_NEAR(tt[i], r.tau_Nm[3 + i], 1e-12);
    }
    EXPECT_NEAR(r.dropped_roll_torque_Nm, pp::dot(w.torque_Nm, d.B_axis), 1e-15);
  }
}

TEST(PenForceSplit, VirtualWorkOfTheTorquesEqualsThatOfTheWrench) {
  // A rigid pen motion (centre velocity v, angular velocity ω ⊥ a) needs q̇ = J⁻¹ ṗ_end per pantograph;
  // then τ·q̇ = F·v + M·ω must hold for any split (f·ẋ = τ·q̇, STYLE.md).
  const pp::Model<double> m = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  SplitResult r;
  for (int k = 0; k < 2000; ++k) {
    const pp::Data<double> d = randomKinematics(m, rng);
    const PenWrench w = randomWrench(rng, 5.0, 0.1);
    ASSERT_EQ(splitter.split(d, w, r), SplitStatus::kOk);
    const Vec3d v{u(rng), u(rng), u(rng)};
    const Vec3d omega = perpendicularPart({u(rng), u(rng), u(rng)}, d.B_axis);
    double tau_qdot = 0.0;
    for (std::size_t p = 0; p < 2; ++p) {
      const Vec3d& tip = d.pantograph[p].B_p_tip;
      const Vec3d r_c{tip[0] - d.B_p_centre[0], tip[1] - d.B_p_centre[1], tip[2] - d.B_p_centre[2]};
      const Vec3d wxr = pp::cross(omega, r_c);
      const Vec3d pdot{v[0] + wxr[0], v[1] + wxr[1], v[2] + wxr[2]};
      // q̇ = J⁻¹ ṗ: solve J q̇ = ṗ via the transposed solver on Jᵀ.
      pp::Mat3<double> Jt{};
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) Jt[a][b] = d.pantograph[p].J[b][a];
      Vec3d qdot{};
      ASSERT_TRUE(tipForceFromTorques(Jt, pdot, qdot));
      for (int i = 0; i < 3; ++i) tau_qdot += r.tau_Nm[3 * p + i] * qdot[i];
    }
    const double power = pp::dot(w.force_N, v) + pp::dot(w.torque_Nm, omega);
    EXPECT_NEAR(tau_qdot, power, 1e-9 * (1.0 + std::fabs(power)));
  }
}

TEST(PenForceSplit, InternalForceMinimisesTheNormalisedEffort) {
  const pp::Model<double> m = pp::defaultModel<double>();
  SplitConfig cfg;
  cfg.torque_limit_Nm = {3.5, 2.0, 2.0, 3.5, 2.0, 2.0};  // unequal limits: the weighting matters
  const PenForceSplitter splitter(cfg);
  SplitConfig plain_cfg = cfg;
  plain_cfg.minimise_effort = false;
  const PenForceSplitter plain(plain_cfg);
  std::mt19937 rng(13);
  SplitResult r, r0;
  int strictly_better = 0;
  for (int k = 0; k < 500; ++k) {
    const pp::Data<double> d = randomKinematics(m, rng);
    const PenWrench w = randomWrench(rng, 5.0, 0.1);
    ASSERT_EQ(splitter.split(d, w, r), SplitStatus::kOk);
    ASSERT_EQ(plain.split(d, w, r0), SplitStatus::kOk);
    EXPECT_DOUBLE_EQ(r0.internal_force_N, 0.0);  // the paper's decoupled split: no internal force
    EXPECT_LE(r.effort, r0.effort + 1e-15);
    if (r.effort < 0.99 * r0.effort) ++strictly_better;
    // Perturbing μ either way increases the effort (first-order optimality of the closed form).
    for (double dmu : {-0.05, 0.05}) {
      double e = 0.0;
      JointVecd tau = r.tau_Nm;
      const Vec3d gb = pp::mulTransposed(d.pantograph[pp::kBottom].J, d.B_axis);
      const Vec3d gt = pp::mulTransposed(d.pantograph[pp::kTop].J, d.B_axis);
      for (int i = 0; i < 3; ++i) {
        tau[i] -= dmu * gb[i];
        tau[3 + i] += dmu * gt[i];
      }
      for (int i = 0; i < 6; ++i) e += (tau[i] / cfg.torque_limit_Nm[i]) * (tau[i] / cfg.torque_limit_Nm[i]);
      EXPECT_GT(e, r.effort);
      // and the perturbed torques still produce the same wrench: μ is internal.
      expectWrenchNear(wrenchFromTorques(d, tau), w, d.B_axis, 1.0, 1e-9);
    }
  }
  EXPECT_GT(strictly_better, 50);  // the free μ is worth something somewhere in the workspace
}

// Independent feasibility check of a wrench fraction s (bisection, no pairwise crossing): is there a μ with
// |s·τ0_i + μ·g_i| ≤ m_i for every joint? τ0 and g come from the kinematics and the paper split (μ = 0).
bool feasible(const JointVecd& tau0, const JointVecd& g, const JointVecd& lim, double s) {
  double lo = -1e18, hi = 1e18;
  for (int i = 0; i < 6; ++i) {
    if (g[i] == 0.0) {
      if (std::fabs(s * tau0[i]) > lim[i]) return false;
      continue;
    }
    const double a = (-lim[i] - s * tau0[i]) / g[i], b = (lim[i] - s * tau0[i]) / g[i];
    lo = std::fmax(lo, std::fmin(a, b));
    hi = std::fmin(hi, std::fmax(a, b));
  }
  return lo <= hi;
}

TEST(PenForceSplit, TorqueLimitsAreNeverExceededAndTheScaleIsMaximal) {
  const pp::Model<double> m = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  SplitConfig huge;
  huge.torque_limit_Nm = {1e9, 1e9, 1e9, 1e9, 1e9, 1e9};
  huge.minimise_effort = false;
  const PenForceSplitter unlimited(huge);
  std::mt19937 rng(14);
  SplitResult r, r0;
  int counts[3] = {0, 0, 0};
  for (int k = 0; k < 20000; ++k) {
    const pp::Data<double> d = randomKinematics(m, rng);
    const double mag = std::exp(std::uniform_real_distribution<double>(std::log(1.0), std::log(300.0))(rng));
    const PenWrench w = randomWrench(rng, mag, mag * 0.05);
    const SplitStatus s = splitter.split(d, w, r);
    ASSERT_TRUE(s == SplitStatus::kOk || s == SplitStatus::kInternalForceRedistributed ||
                s == SplitStatus::kScaled);
    for (int i = 0; i < 6; ++i) {
      ASSERT_LE(std::fabs(r.tau_Nm[i]), splitter.config().torque_limit_Nm[i]) << "joint " << i << " pose " << k;
    }
    // The delivered wrench is the desired one (kOk, kInternalForceRedistributed) or s times it (kScaled).
    const double tol = 1e-9 * (1.0 + mag);
    expectWrenchNear(wrenchFromTorques(d, r.tau_Nm), w, d.B_axis, r.scale, tol);
    if (s == SplitStatus::kOk) {
      ++counts[0];
      EXPECT_EQ(r.limit_active_mask, 0);
    } else {
      EXPECT_NE(r.limit_active_mask, 0) << "a redistributed or scaled split must name its active limit";
      for (int i = 0; i < 6; ++i) {
        if (r.limit_active_mask & (1u << i)) {
          EXPECT_NEAR(std::fabs(r.tau_Nm[i]), splitter.config().torque_limit_Nm[i], 1e-8);
        }
      }
    }
    if (s == SplitStatus::kInternalForceRedistributed) {
      ++counts[1];
      EXPECT_DOUBLE_EQ(r.scale, 1.0);
    }
    if (s == SplitStatus::kScaled) {
      ++counts[2];
      ASSERT_LT(r.scale, 1.0);
      ASSERT_GT(r.scale, 0.0);
      ASSERT_EQ(unlimited.split(d, w, r0), SplitStatus::kOk);
      const Vec3d gb = pp::mulTransposed(d.pantograph[pp::kBottom].J, d.B_axis);
      const Vec3d gt = pp::mulTransposed(d.pantograph[pp::kTop].J, d.B_axis);
      const JointVecd g{-gb[0], -gb[1], -gb[2], gt[0], gt[1], gt[2]};
      const JointVecd& lim = splitter.config().torque_limit_Nm;
      EXPECT_TRUE(feasible(r0.tau_Nm, g, lim, r.scale * (1.0 - 1e-9)));
      EXPECT_FALSE(feasible(r0.tau_Nm, g, lim, r.scale * (1.0 + 1e-6))) << "scale not maximal at pose " << k;
    }
  }
  // The random magnitudes (1..300 N) exercise all three branches.
  EXPECT_GT(counts[0], 1000);
  EXPECT_GT(counts[1], 100);
  EXPECT_GT(counts[2], 1000);
}

TEST(PenForceSplit, InternalForceAloneRescuesAnActuatorWhenItCan) {
  // At home, a pure y force is carried by the two waists and (through μ) can be shifted between them; with
  // one waist weakened, μ must move to keep it inside its limit while the wrench stays exact.
  const pp::Model<double> m = pp::defaultModel<double>();
  pp::Data<double> d;
  ASSERT_EQ(pp::computeForward(m, m.q_home_rad, d), pp::Status::kOk);
  SplitConfig cfg;
  cfg.torque_limit_Nm = {2.1, 2.1, 2.1, 2.1, 2.1, 2.1};
  const PenForceSplitter splitter(cfg);
  PenWrench w;
  w.force_N = {0.0, 0.0, 30.0};  // 15 N per end at μ = 0: 1.46 N·m per shoulder, fine
  w.torque_Nm = {1.8, 0.0, 0.0};  // adds ±(1.8/0.14) = ±12.9 N along z (ends 14 cm apart): 27.9 N on the top end → 2.7 N·m
  SplitResult r;
  const SplitStatus s = splitter.split(d, w, r);
  // z forces load the shoulders; μ acts along y (the pen axis) which only the waists feel at home, so here μ
  // cannot help and the wrench is scaled; the active limits are the top pantograph's shoulders.
  EXPECT_EQ(s, SplitStatus::kScaled);
  EXPECT_EQ(r.limit_active_mask & 0b110000, 0b110000);
  // Tilted pen (θx = 30°): the axis has a z component, μ now reaches the shoulders and redistributes.
  pp::PenPose<double> tilted;
  tilted.centre_m = {0.0, 0.0, 0.20};
  tilted.theta_x_rad = 30 * kDeg;
  pp::JointVec<double> q;
  ASSERT_EQ(pp::computeInverse(m, tilted, q), pp::Status::kOk);
  ASSERT_EQ(pp::computeForward(m, q, d), pp::Status::kOk);
  w.force_N = {0.0, 0.0, 36.0};
  w.torque_Nm = {0.6, 0.0, 0.0};
  const SplitStatus s2 = splitter.split(d, w, r);
  EXPECT_EQ(s2, SplitStatus::kInternalForceRedistributed);
  EXPECT_NE(r.internal_force_N, r.optimal_internal_force_N);
  expectWrenchNear(wrenchFromTorques(d, r.tau_Nm), w, d.B_axis, 1.0, 1e-9);
}

TEST(PenForceSplit, BadInputsGiveZeroTorque) {
  const pp::Model<double> m = pp::defaultModel<double>();
  pp::Data<double> d;
  ASSERT_EQ(pp::computeForward(m, m.q_home_rad, d), pp::Status::kOk);
  const PenForceSplitter splitter;
  SplitResult r;
  PenWrench w;
  w.force_N = {1.0, std::nan(""), 0.0};
  EXPECT_EQ(splitter.split(d, w, r), SplitStatus::kNonFiniteInput);
  for (double t : r.tau_Nm) EXPECT_EQ(t, 0.0);
  w.force_N = {1.0, 0.0, 0.0};
  w.torque_Nm = {0.0, 0.0, INFINITY};
  EXPECT_EQ(splitter.split(d, w, r), SplitStatus::kNonFiniteInput);
  w.torque_Nm = {};
  pp::Data<double> bad = d;
  bad.status = pp::Status::kEndsInconsistent;
  EXPECT_EQ(splitter.split(bad, w, r), SplitStatus::kKinematicsUnusable);
  for (double t : r.tau_Nm) EXPECT_EQ(t, 0.0);
  SplitConfig cfg;
  cfg.torque_limit_Nm[2] = 0.0;
  EXPECT_EQ(PenForceSplitter(cfg).split(d, w, r), SplitStatus::kBadConfig);
  for (double t : r.tau_Nm) EXPECT_EQ(t, 0.0);
}

TEST(PenForceSplit, PerCyclePathDoesNotAllocate) {
  const pp::Model<double> m = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  std::mt19937 rng(15);
  std::vector<pp::JointVec<double>> qs(200);
  std::vector<PenWrench> ws(200);
  for (std::size_t k = 0; k < qs.size(); ++k) {
    ASSERT_EQ(pp::computeInverse(m, randomWorkspacePose(rng), qs[k]), pp::Status::kOk);
    ws[k] = randomWrench(rng, k % 2 ? 5.0 : 200.0, 0.2);  // unsaturated and saturated cycles
  }
  pp::Data<double> d;
  SplitResult r;
  const long before = g_allocations.load();
  for (std::size_t k = 0; k < qs.size(); ++k) {
    pp::computeForward(m, qs[k], d);
    splitter.split(d, ws[k], r);
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
}

}  // namespace
