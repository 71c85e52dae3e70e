// The instrumented assessments' exercises (tardieu, passive-rom, max-force) and their analysis
// (host/therapy/assessment_analysis.h) on synthetic series with a known answer.
#include <gtest/gtest.h>

#include <cmath>

#include "../support/counting_allocator.h"  // g_allocations
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/sea_device.h"

using namespace phalanx::host::therapy;

namespace {

constexpr double kDeg = M_PI / 180.0;

struct Series {
  std::vector<double> t, q, effort, target;
  std::vector<char> in;
};

// A perfectly tracked tardieu schedule (q = target) on a finger whose resistance is a linear passive torque,
// a viscous term and the reflex model: effort = 0.1·(q − 0.5) + b·v + G·(v − v_th)⁺·[q < φ_c].
Series synthetic(double gain, double threshold_deg_s, double catch_deg) {
  TardieuPlan plan;
  plan.count = 4;
  plan.velocity_rad_s = {15 * kDeg, 90 * kDeg, 150 * kDeg, 210 * kDeg};
  plan.from_rad = 50 * kDeg;
  plan.to_rad = 5 * kDeg;
  plan.hold_s = 1.0;
  const double q0 = 28 * kDeg, b = 0.002;
  Series s;
  for (double t = 0.0; t < plan.durationS(q0) + 0.5; t += 1e-3) {
    double q = 0.0, q_dot = 0.0;
    plan.targetAt(t, q0, q, q_dot);
    const double v = -q_dot;
    const double reflex = q < catch_deg * kDeg ? gain * std::max(0.0, v - threshold_deg_s * kDeg) : 0.0;
    s.t.push_back(t);
    s.q.push_back(q);
    s.target.push_back(q);
    s.effort.push_back(0.1 * (q - 0.5) + b * v + reflex);
    s.in.push_back(1);
  }
  return s;
}

}  // namespace

TEST(TardieuPlan, ApproachesHoldsAndStretchesAtEachVelocity) {
  TardieuPlan plan;
  plan.count = 2;
  plan.velocity_rad_s = {0.5, 2.0};
  plan.from_rad = 1.0;
  plan.to_rad = 0.0;
  plan.hold_s = 1.0;
  double q = 0, qd = 0;
  plan.targetAt(0.0, 0.5, q, qd);  // from q0 = 0.5 up to 1.0 at the approach rate
  EXPECT_NEAR(q, 0.5, 1e-12);
  EXPECT_NEAR(qd, TardieuPlan::kApproach_rad_s, 1e-12);
  plan.targetAt(1.5, 0.5, q, qd);  // approach took 1 s; holding
  EXPECT_NEAR(q, 1.0, 1e-12);
  EXPECT_EQ(qd, 0.0);
  plan.targetAt(2.5, 0.5, q, qd);  // 0.5 s into the first stretch at 0.5 rad/s
  EXPECT_NEAR(q, 0.75, 1e-12);
  EXPECT_NEAR(qd, -0.5, 1e-12);
  // 1 + 1 + 2 + 0.5, then 2 + 1 + 0.5 + 0.5
  EXPECT_NEAR(plan.durationS(0.5), 8.5, 1e-12);
  plan.targetAt(8.0, 0.5, q, qd);  // second stretch's final hold
  EXPECT_NEAR(q, 0.0, 1e-12);
}

TEST(TardieuAnalysis, RecoversTheModelOfASyntheticFinger) {
  const Series s = synthetic(0.05, 60.0, 20.0);
  TardieuFigures f;
  ASSERT_EQ(analyseTardieu(s.t, s.q, s.effort, s.target, s.in, f), "");
  ASSERT_EQ(f.stretches.size(), 4u);
  EXPECT_NEAR(f.catch_rad / kDeg, 20.0, 0.3);  // the grid's 0.25°
  EXPECT_NEAR(f.threshold_rad_s / kDeg, 60.0, 1.5);
  EXPECT_NEAR(f.gain_per_rad_s, 0.05, 0.002);
  EXPECT_TRUE(std::isnan(f.stretches[0].catch_rad));  // 15°/s: the reference, below the threshold
  EXPECT_NEAR(f.stretches[3].velocity_rad_s / kDeg, 210.0, 2.0);
  EXPECT_NEAR(f.stretches[3].reflex, 0.05 * (210.0 - 60.0) * kDeg, 0.005);
  EXPECT_NEAR(f.stretches[1].nominal_rad_s / kDeg, 90.0, 0.5);  // one 1 ms cycle of 500: 0.2 %
}

TEST(TardieuAnalysis, ReportsNoReflexWhenThereIsNone) {
  const Series s = synthetic(0.0, 60.0, 20.0);
  TardieuFigures f;
  ASSERT_EQ(analyseTardieu(s.t, s.q, s.effort, s.target, s.in, f), "");
  EXPECT_TRUE(std::isnan(f.catch_rad));
  EXPECT_TRUE(std::isnan(f.threshold_rad_s));
  for (const auto& st : f.stretches) EXPECT_TRUE(std::isnan(st.catch_rad));
}

TEST(TardieuAnalysis, RefusesTooFewStretchesAndMismatchedSeries) {
  Series s = synthetic(0.05, 60.0, 20.0);
  TardieuFigures f;
  std::vector<double> short_q(s.q.begin(), s.q.end() - 1);
  EXPECT_NE(analyseTardieu(s.t, short_q, s.effort, s.target, s.in, f).find("length"), std::string::npos);
  std::vector<char> none(s.t.size(), 0);
  EXPECT_NE(analyseTardieu(s.t, s.q, s.effort, s.target, none, f).find("0 stretches"), std::string::npos);
}

TEST(PassiveRomAnalysis, TakesTheSettledAngleOfEachHold) {
  std::vector<double> flex, cmd;
  std::vector<char> in;
  for (int i = 0; i < 400; ++i) {  // extend: settles at 0.1 rad; flex: settles at 0.9 rad
    const bool ext = i < 200;
    flex.push_back(ext ? 0.1 + 0.3 * std::exp(-i / 20.0) : 0.9 - 0.5 * std::exp(-(i - 200) / 20.0));
    cmd.push_back(ext ? 0.05 : -0.05);
    in.push_back(1);
  }
  const PassiveRomFigures f = analysePassiveRom(flex, cmd, in);
  EXPECT_NEAR(f.extension_rad, 0.1, 1e-3);
  EXPECT_NEAR(f.flexion_rad, 0.9, 1e-3);
}

TEST(MaxForceAnalysis, PeakAboveTheRelaxedBaseline) {
  std::vector<double> t, e;
  std::vector<char> in;
  for (int i = 0; i < 3000; ++i) {  // baseline 0.02 for 0.5 s, then a plateau of 0.02 + 0.1
    t.push_back(i * 1e-3);
    e.push_back(0.02 + (i >= 500 ? 0.1 : 0.0));
    in.push_back(1);
  }
  EXPECT_NEAR(analyseMaxForce(t, e, in), 0.1, 1e-4);
}

// The three exercises on the SEA finger: refused parameters name the key; update() never allocates.
TEST(InstrumentedExercises, ValidateTheirParametersAndRunAllocationFree) {
  std::string err;
  auto dev = SeaTherapyDevice::make({}, err);
  ASSERT_TRUE(dev) << err;
  Profile profile;
  auto pattern = std::make_shared<Pattern>(2);
  EXPECT_FALSE(makeExercise("tardieu", {{"channel", 5}}, *dev, profile, pattern, err));
  EXPECT_NE(err.find("params.channel"), std::string::npos) << err;
  EXPECT_FALSE(makeExercise("tardieu", {{"from_deg", 10}, {"to_deg", 5}}, *dev, profile, pattern, err));
  EXPECT_NE(err.find("from_deg"), std::string::npos) << err;
  EXPECT_FALSE(makeExercise("passive-rom", {{"effort", 1.0}}, *dev, profile, pattern, err));
  EXPECT_NE(err.find("params.effort"), std::string::npos) << err;
  EXPECT_FALSE(makeExercise("max-force", {{"speed", 1}}, *dev, profile, pattern, err));
  EXPECT_NE(err.find("unknown parameter"), std::string::npos) << err;
  for (const char* name : {"tardieu", "passive-rom", "max-force"}) {
    auto ex = makeExercise(name, nullptr, *dev, profile, pattern, err);
    ASSERT_TRUE(ex) << name << ": " << err;
    Observation obs{};
    obs.channel_valid[0] = obs.channel_valid[1] = true;
    obs.q_rad[0] = 0.5;
    phalanx::host::TelemetryFrame tel{};
    ExerciseOutput out;
    ex->start(obs, 0.0);
    const long before = g_allocations.load();
    for (int i = 0; i < 20000; ++i) {
      out.clear();
      obs.q_rad[0] = 0.5 + 0.3 * std::sin(i * 1e-3);
      ex->update(tel, obs, i * 1e-3, 1e-3, out);
    }
    EXPECT_EQ(g_allocations.load() - before, 0) << name;
    EXPECT_EQ(out.mode, phalanx::protocol::Mode::kSetpoint) << name;
  }
}
