// Glove design tools (000 §3.2–3.7, §4.1): workspace sweep, eq 13–14 ranges, §3.6 collisions, eq 24 margin,
// the eq 17–23 optimisation and the YAML geometry.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>

#include "phalanx/host/design/glove_design.h"

namespace d = phalanx::host::design;
namespace glove = phalanx::glove;

TEST(DesignGlove, SegmentCrossingDepthIsZeroUnlessTheSegmentsCross) {
  EXPECT_EQ(d::segmentCrossingDepth({0, 0}, {1, 0}, {0, 1}, {1, 1}), 0.0);      // parallel, apart
  EXPECT_EQ(d::segmentCrossingDepth({0, 0}, {1, 0}, {2, -1}, {2, 1}), 0.0);     // would cross if extended
  EXPECT_EQ(d::segmentCrossingDepth({0, 0}, {1, 0}, {0.5, 0}, {0.5, 1}), 0.0);  // touching (T): not crossing
  // A cross: the shallowest way out is the short arm, 0.2 long.
  EXPECT_NEAR(d::segmentCrossingDepth({0, 0}, {1, 0}, {0.5, -0.2}, {0.5, 1}), 0.2, 1e-12);
  // Symmetric in the two segments.
  EXPECT_NEAR(d::segmentCrossingDepth({0.5, -0.2}, {0.5, 1}, {0, 0}, {1, 0}), 0.2, 1e-12);
}

TEST(DesignGlove, SweptAlphaRangesContainEveryRandomFingerPoseAndThePaperSingularityMargin) {
  const d::GloveModel m = glove::defaultIndexModel<double>();
  const d::GloveAnalysis a = d::analyseGlove(m, d::SweepGrid{{31, 31, 21}}, true);
  EXPECT_EQ(a.poses, 31u * 31 * 21);
  EXPECT_EQ(a.unreachable, 0u);
  EXPECT_TRUE(a.finger_inside_mechanism);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    d::Vec3d th{}, al{};
    for (std::size_t k = 0; k < 3; ++k)
      th[k] = m.finger.theta_min_rad[k] + u(rng) * (m.finger.theta_max_rad[k] - m.finger.theta_min_rad[k]);
    ASSERT_TRUE(glove::isUsable(glove::alphaFromTheta(m, th, al)));
    for (std::size_t k = 0; k < 3; ++k) {
      // The grid brackets the random pose within one grid step of α (≤ ~6°/step here).
      EXPECT_GE(glove::radToDeg(al[k]), a.alpha_min_deg[k] - 3.0);
      EXPECT_LE(glove::radToDeg(al[k]), a.alpha_max_deg[k] + 3.0);
    }
    EXPECT_GE(std::fabs(std::sin(al[1])), a.min_abs_sin_alpha2 - 0.02);
  }
  // Eq 14 and eq 17 from the ranges.
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(a.alpha_var_deg[k], a.alpha_max_deg[k] - a.alpha_min_deg[k], 1e-12);
  EXPECT_NEAR(a.z1_deg, std::sqrt(a.alpha_var_deg[0] * a.alpha_var_deg[0] + a.alpha_var_deg[1] * a.alpha_var_deg[1] +
                                  a.alpha_var_deg[2] * a.alpha_var_deg[2]), 1e-9);
  // §3.7: "the working range of α2 is [−130, −50], which will avoid all calculated singularities" (eq 24).
  EXPECT_GT(a.min_abs_sin_alpha2, 0.5);
}

TEST(DesignGlove, UnreachablePosesAreCountedAndMeasured) {
  d::GloveModel m = glove::defaultIndexModel<double>();
  m.mech.l1_m = 0.040;  // far too short for this finger
  m.mech.l2_m = 0.030;
  const d::GloveAnalysis a = d::analyseGlove(m, d::SweepGrid{{9, 9, 7}});
  EXPECT_GT(a.unreachable, 0u);
  EXPECT_GT(a.reach_violation_mm, 0.0);
  EXPECT_FALSE(a.finger_inside_mechanism);
}

TEST(DesignGlove, StraightLink1CollidesWithTheFlexedProximalPhalanxAndTheLShapeClearsIt) {
  const d::GloveModel m = glove::defaultIndexModel<double>();
  const d::GloveAnalysis chord = d::analyseGlove(m, d::SweepGrid{{13, 13, 9}}, false, d::Link1Shape{0.0});
  const d::GloveAnalysis ell = d::analyseGlove(m, d::SweepGrid{{13, 13, 9}}, false, d::Link1Shape{45.0});
  EXPECT_GT(chord.colliding[0], 0u);  // docs/glove-model.md: the chord crosses for MCP flexion beyond ≈ −60°
  EXPECT_LT(ell.colliding[0], chord.colliding[0]);
  EXPECT_EQ(chord.colliding[2], 0u);  // link 3 runs parallel to the distal phalanx, |l_p| apart
}

namespace {
d::GloveOptOptions fastOptions() {
  d::GloveOptOptions o = d::defaultGloveOptOptions();
  o.grid = d::SweepGrid{{9, 9, 7}};
  o.starts = 2;
  o.max_evals = 600;
  return o;
}

void expectAllConstraintsHold(const d::GloveOptOptions& o, const d::GloveOptResult& r) {
  ASSERT_TRUE(r.feasible);
  ASSERT_EQ(r.constraint_values.size(), d::gloveConstraintNames().size());
  for (std::size_t k = 0; k < r.constraint_values.size(); ++k)
    EXPECT_LE(r.constraint_values[k], 1e-6) << d::gloveConstraintNames()[k];
  // Independently of gloveObjective: bounds (§3.7), g1, g2 (eq 20–21), g3 (eq 22) and reach/collision (§3.6)
  // re-derived from a fresh sweep on the same grid, for every finger.
  for (const d::GloveFinger& f : o.fingers) {
    const double p[3] = {f.p1_m * 1e3, f.p2_m * 1e3, f.p3_m * 1e3};
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(r.l_mm[i], p[i] - 1e-9);
      EXPECT_LE(r.l_mm[i], 2 * p[i] + 1e-9);
    }
    EXPECT_GE(r.l_mm[0] + r.l_mm[1] + r.l_mm[2], p[0] + p[1] + p[2]);
    EXPECT_GE(r.l_mm[0], p[0]);
    const d::GloveAnalysis a = d::analyseGlove(d::makeGloveModel(f, r.l_mm, o), o.grid, false, o.link1);
    EXPECT_EQ(a.unreachable, 0u);
    for (int i = 0; i < 3; ++i) EXPECT_LE(a.alpha_var_deg[i], o.max_joint_range_deg + 1e-6);
    EXPECT_LE(a.collision_depth_mm, 1e-6);
  }
}
}  // namespace

TEST(DesignGlove, OptimiserRespectsEveryConstraintAndLink3ConvergesToTheDistalPhalanx) {
  const d::GloveOptOptions o = fastOptions();
  const d::GloveOptResult r = d::optimiseGlove(o);
  expectAllConstraintsHold(o, r);
  // §3.7: "The optimal length of link 3 quickly converges to 19.1 mm" (= p3, its lower bound).
  EXPECT_NEAR(r.l_mm[2], 19.1, 0.05);
  // The optimum is no worse than the §3.7 initial guess 1.5·p (which is itself feasible here).
  EXPECT_LE(r.Z, d::gloveObjective({72.45, 42.3, 28.65}, o, nullptr) + 1e-9);
}

TEST(DesignGlove, SlsqpAlsoRespectsEveryConstraint) {
  d::GloveOptOptions o = fastOptions();
  o.use_slsqp = true;
  o.starts = 1;
  expectAllConstraintsHold(o, d::optimiseGlove(o));
}

TEST(DesignGlove, PerUserAndPopulationDesignsRespectTheirConstraints) {
  d::GloveOptOptions small = fastOptions();
  small.fingers.front().p1_m = 0.044, small.fingers.front().p2_m = 0.026, small.fingers.front().p3_m = 0.017;
  const d::GloveOptResult rs = d::optimiseGlove(small);
  expectAllConstraintsHold(small, rs);
  const d::GloveOptResult ri = d::optimiseGlove(fastOptions());
  EXPECT_LT(rs.l_mm[0] + rs.l_mm[1], ri.l_mm[0] + ri.l_mm[1]);  // a smaller finger gets a shorter glove

  d::GloveOptOptions pop = fastOptions();
  const d::GloveFinger base = pop.fingers.front();
  pop.fingers.clear();
  for (double s : {0.97, 1.0, 1.03}) {
    d::GloveFinger f = base;
    f.p1_m *= s, f.p2_m *= s, f.p3_m *= s;
    pop.fingers.push_back(f);
  }
  expectAllConstraintsHold(pop, d::optimiseGlove(pop));
}

TEST(DesignGlove, GeometryYamlRoundTripsAndBadFilesAreRejectedByName) {
  const d::GloveModel m = glove::defaultIndexModel<double>();
  const d::GloveAnalysis a = d::analyseGlove(m, d::SweepGrid{{9, 9, 7}});
  const std::string path = ::testing::TempDir() + "design_glove_geometry.yaml";
  {
    std::ofstream f(path);
    f << d::gloveGeometryYaml(m, a, "test");
  }
  d::GloveModel back{};
  ASSERT_EQ(d::loadGloveGeometryYaml(path, back), "");
  EXPECT_NEAR(back.mech.l1_m, m.mech.l1_m, 1e-9);
  EXPECT_NEAR(back.mech.l2_m, m.mech.l2_m, 1e-9);
  EXPECT_NEAR(back.mech.l3_m, m.mech.l3_m, 1e-9);
  EXPECT_NEAR(back.mech.l_p_m, m.mech.l_p_m, 1e-9);
  EXPECT_NEAR(back.mech.x_B0_m, m.mech.x_B0_m, 1e-9);
  EXPECT_NEAR(back.finger.p1_m, m.finger.p1_m, 1e-9);
  EXPECT_NEAR(back.finger.theta_min_rad[1], m.finger.theta_min_rad[1], 1e-9);
  // The written α limits contain the swept ranges (rounded outwards).
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_LE(back.mech.alpha_min_rad[k], glove::degToRad(a.alpha_min_deg[k]) + 1e-12);
    EXPECT_GE(back.mech.alpha_max_rad[k], glove::degToRad(a.alpha_max_deg[k]) - 1e-12);
  }
  {
    std::ofstream f(path);
    f << "glove_finger_geometry:\n  finger: {p_mm: [48, 28, -1], theta_min_deg: [-90, -120, -80], "
         "theta_max_deg: [30, 0, 0]}\n  mechanism: {l_mm: [70, 50, 19], l_p_mm: -12, B0_mm: [-10, 14], "
         "alpha_min_deg: [-80, -130, -80], alpha_max_deg: [60, -50, 60]}\n";
  }
  EXPECT_NE(d::loadGloveGeometryYaml(path, back).find("lengths must be > 0"), std::string::npos);
  {
    std::ofstream f(path);
    f << "glove_finger_geometry:\n  finger: {p_mm: [48, 28]}\n";
  }
  EXPECT_NE(d::loadGloveGeometryYaml(path, back).find("finger.p_mm"), std::string::npos);
  {
    std::ofstream f(path);
    f << d::gloveGeometryYaml(m, a, "test") << "  mechanism: {l_mm: [1, 1, 1]}\n";  // a second 'mechanism'
  }
  EXPECT_NE(d::loadGloveGeometryYaml(path, back).find("glove_finger_geometry.mechanism: duplicate key"),
            std::string::npos)
      << d::loadGloveGeometryYaml(path, back);
  std::remove(path.c_str());
}
