// Pen virtual environment: PD+B walls per pen end, the braking pulse and its momentum cap, the click button,
// gravity compensation (phalanx/host/pen/pen_scene.h, seeds/004 §VI).
#include "phalanx/host/pen/pen_scene.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "../support/counting_allocator.h"  // g_allocations

namespace {

using namespace phalanx::host::pen;
namespace pp = phalanx::pen;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

pp::Data<double> kinAt(const pp::Model<double>& m, const pp::PenPose<double>& pose) {
  pp::JointVec<double> q;
  EXPECT_EQ(pp::computeInverse(m, pose, q), pp::Status::kOk);
  pp::Data<double> d;
  EXPECT_TRUE(pp::isUsable(pp::computeForward(m, q, d)));
  return d;
}

PenSceneConfig boxOnly() {
  PenSceneConfig c;
  c.button = false;
  c.gravity_compensation = false;
  return c;
}

TEST(PenScene, TheTipFeelsTheFloorWhileTheEraserStaysFree) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenScene scene(boxOnly());
  PenRenderOutput out;
  // Pen tilted 30° about x: the tip 2 mm into the floor, the eraser far above it.
  pp::PenPose<double> pose{{0.0, 0.0, 0.20}, 30 * kDeg, 0.0};
  const double tip_y = pp::endOffset(pp::kBottom, m.l6_m) * std::cos(30 * kDeg);
  pose.centre_m[1] = scene.config().box_min[1] - tip_y - 0.002;
  const pp::Data<double> d = kinAt(m, pose);
  scene.render(d, 1e-3, out);  // first call: no velocity yet, no braking
  scene.render(d, 1e-3, out);  // at rest
  EXPECT_TRUE(out.end[pp::kBottom].in_contact);
  EXPECT_NEAR(out.end[pp::kBottom].force_N[1], scene.config().vertical.stiffness_N_per_m * 0.002, 1e-9);
  EXPECT_NEAR(out.end[pp::kBottom].force_N[0], 0.0, 1e-12);
  EXPECT_FALSE(out.end[pp::kTop].in_contact);
  EXPECT_EQ(out.end[pp::kTop].force_N[1], 0.0);
  // Through the split (either choice of the internal force) the eraser's pantograph applies no force across the
  // pen: only an axial share, which a rigid pen carries to the tip (Fig. 18's decoupling).
  for (bool minimise : {false, true}) {
    SplitConfig sc;
    sc.minimise_effort = minimise;
    SplitResult r;
    ASSERT_EQ(PenForceSplitter(sc).split(d, out.wrench, r), SplitStatus::kOk);
    const Vec3d& a = d.B_axis;
    const double at = pp::dot(r.f_top_N, a), ab = pp::dot(r.f_bottom_N, a);
    const double ar = pp::dot(out.end[pp::kBottom].force_N, a);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_NEAR(r.f_top_N[i] - at * a[i], 0.0, 1e-12) << "eraser feels a lateral force";
      EXPECT_NEAR(r.f_bottom_N[i] - ab * a[i], out.end[pp::kBottom].force_N[i] - ar * a[i], 1e-12);
    }
    EXPECT_NEAR(at + ab, ar, 1e-12);  // the axial force is the tip's, shared along the rigid pen
  }
}

TEST(PenScene, WallsOnlyPushAndDampTheApproach) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenScene scene(boxOnly());
  PenRenderOutput out;
  const double x0 = scene.config().box_max[0] + 0.001;  // both ends 1 mm into the +x wall (upright pen)
  scene.render(kinAt(m, {{x0, 0.0, 0.20}, 0.0, 0.0}), 1e-3, out);
  scene.render(kinAt(m, {{x0, 0.0, 0.20}, 0.0, 0.0}), 1e-3, out);
  EXPECT_NEAR(out.end[pp::kBottom].force_N[0], -300.0 * 0.001, 1e-9);
  EXPECT_NEAR(out.end[pp::kTop].force_N[0], -300.0 * 0.001, 1e-9);
  // Leaving fast: the damper would pull; the wall only pushes.
  scene.render(kinAt(m, {{x0 - 0.0009, 0.0, 0.20}, 0.0, 0.0}), 1e-3, out);
  EXPECT_LE(out.end[pp::kBottom].force_N[0], 0.0);
  EXPECT_GE(out.end[pp::kBottom].force_N[0], -300.0 * 0.0001 - 1e-12);
}

TEST(PenScene, BrakingPulseFiresOnceAtContactOnsetAndNeverReversesTheEnd) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenSceneConfig cfg = boxOnly();
  cfg.velocity_cutoff_hz = 1e6;  // raw finite differences, to know the velocity exactly
  for (bool cap : {false, true}) {
    cfg.brake_momentum_cap = cap;
    PenScene scene(cfg);
    PenRenderOutput out;
    const double v = 0.1;  // m/s towards the floor, tilted pen: only the tip hits
    pp::PenPose<double> pose{{0.0, 0.0, 0.20}, 30 * kDeg, 0.0};
    const double tip_y = pp::endOffset(pp::kBottom, m.l6_m) * std::cos(30 * kDeg);
    const double y_contact = cfg.box_min[1] - tip_y;
    pose.centre_m[1] = y_contact + 0.0005;
    scene.render(kinAt(m, pose), 1e-3, out);
    pose.centre_m[1] -= v * 1e-3;  // 0.4 mm above: free
    scene.render(kinAt(m, pose), 1e-3, out);
    EXPECT_FALSE(out.end[pp::kBottom].in_contact);
    pose.centre_m[1] -= v * 1e-3;  // 0.2 mm below: onset
    pose.centre_m[1] -= 0.0005;
    const pp::Data<double> d = kinAt(m, pose);
    scene.render(d, 1e-3, out);
    ASSERT_TRUE(out.end[pp::kBottom].brake_applied);
    const double vn = out.v_end_m_s[pp::kBottom][1];
    const double brake = out.end[pp::kBottom].brake_force_N[1];
    if (!cap) {
      EXPECT_NEAR(brake, -cfg.vertical.brake_N_s_per_m * vn, 1e-9);
      EXPECT_DOUBLE_EQ(out.brake_scale, 1.0);
    } else {
      // The capped pulse stops the tip in one period: Δv_n = (G D⁻¹ Gᵀ f)_n·T ≤ |v_n|, with equality when capped.
      const auto D = pp::massMatrixSI<double>();
      pp::Mat5<double> Di;
      ASSERT_TRUE(pp::invertSpd5(D, Di));
      const auto G = pp::endJacobian(m, pp::kBottom, d.pose.theta_x_rad, d.pose.theta_z_rad);
      std::array<double, 5> Q{}, dx{};
      for (std::size_t j = 0; j < 5; ++j) Q[j] = G[1][j] * brake;
      for (std::size_t i = 0; i < 5; ++i)
        for (std::size_t j = 0; j < 5; ++j) dx[i] += Di[i][j] * Q[j] * 1e-3;
      double dv = 0.0;
      for (std::size_t j = 0; j < 5; ++j) dv += G[1][j] * dx[j];
      EXPECT_LT(out.brake_scale, 1.0) << "the paper's 3 N·s/cm over-brakes the bare pen";
      EXPECT_NEAR(dv, -vn, 1e-9);
    }
    // Next cycle, still inside: no second pulse.
    scene.render(d, 1e-3, out);
    EXPECT_FALSE(out.end[pp::kBottom].brake_applied);
  }
}

TEST(PenScene, ButtonClicksOnceAndErasesTheMarks) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenSceneConfig cfg;
  cfg.gravity_compensation = false;
  PenScene scene(cfg);
  PenRenderOutput out;
  const double tip_y = pp::endOffset(pp::kBottom, m.l6_m);
  // Write on the floor first (tip moving along it).
  for (int k = 0; k < 20; ++k) {
    scene.render(kinAt(m, {{0.02 + 0.0001 * k, cfg.box_min[1] - tip_y - 0.001, 0.20}, 0.0, 0.0}), 1e-3, out);
  }
  EXPECT_GT(out.marks, 0u);
  // Press the button cap down in 0.5 mm steps: force rises with depth, drops at the click depth.
  double last_f = 0.0;
  bool dropped = false;
  for (int k = 1; k <= 10; ++k) {
    const double depth = 0.0005 * k;
    const double y = cfg.box_min[1] + cfg.button_travel_m - depth - tip_y;
    scene.render(kinAt(m, {{cfg.button_x_m, y, cfg.button_z_m}, 0.0, 0.0}), 1e-3, out);
    ASSERT_TRUE(out.button_pressed);
    const double f = out.end[pp::kBottom].force_N[1];
    if (depth < cfg.button_click_depth_m - 1e-9) {
      EXPECT_GT(f, last_f);
      EXPECT_EQ(out.clicks, 0u);
    } else if (!dropped) {
      EXPECT_LT(f, last_f) << "the click: the force drops";
      EXPECT_EQ(out.clicks, 1u);
      EXPECT_EQ(out.marks, 0u) << "the click erases the pencil marks";
      dropped = true;
    }
    last_f = f;
  }
  EXPECT_TRUE(dropped);
  EXPECT_EQ(out.clicks, 1u);
}

TEST(PenScene, GravityCompensationLiftsTheUnbalancedWeight) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenSceneConfig cfg;
  cfg.box = false;
  cfg.button = false;
  PenScene scene(cfg);
  PenRenderOutput out;
  scene.render(kinAt(m, {{0.0, 0.0, 0.1625}, 0.0, 0.0}), 1e-3, out);
  EXPECT_NEAR(out.wrench.force_N[1], 0.070 * 9.81, 1e-3);  // Table X: 70 g nearest the base
  scene.render(kinAt(m, {{0.0, 0.0, 0.2375}, 0.0, 0.0}), 1e-3, out);
  EXPECT_NEAR(out.wrench.force_N[1], 0.130 * 9.81, 1e-3);  // 130 g furthest out
  EXPECT_NEAR(out.wrench.force_N[0], 0.0, 1e-12);
}

TEST(PenScene, RenderingDoesNotAllocate) {
  const pp::Model<double> m = pp::defaultModel<double>();
  PenScene scene;
  PenRenderOutput out;
  std::vector<pp::Data<double>> ds;
  for (int k = 0; k < 100; ++k) ds.push_back(kinAt(m, {{0.055 * std::sin(k * 0.1), -0.02, 0.20}, 0.3, 0.1}));
  const long before = g_allocations.load();
  for (const auto& d : ds) scene.render(d, 1e-3, out);
  EXPECT_EQ(g_allocations.load() - before, 0);
}

}  // namespace
