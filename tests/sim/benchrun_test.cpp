// The bench runner end to end on the simulated SEA rig and the haptic pen (real time: the reference instrument is
// polled over Modbus as on the bench), with short plans so the suite stays within its time budget.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "phalanx/host/benchrun/report.h"
#include "phalanx/host/benchrun/runner.h"

namespace br = phalanx::host::benchrun;

namespace {

br::Plan plan(const std::string& yaml) {
  br::Plan p;
  const std::string err = br::loadPlanText(yaml, "test-plan", p);
  EXPECT_EQ(err, "");
  return p;
}

const char* kHeader = R"(
version: 1
device: sim:sea_rig
seed: 3
instrument: {type: int32, scale: 1.0e-5, poll_hz: 500, timeout_ms: 30, stale_ms: 50}
max_stale_percent: 5
)";

void noProgress(size_t, size_t, const std::string&, double) {}

}  // namespace

TEST(BenchRun, PlanPassesAgainstTheSimulatedSeaRigAndTheReportIsSelfContained) {
  const br::Plan p = plan(std::string(kHeader) + R"(
steps:
  - name: sine 0.3
    kind: sea-rig-sine
    peak_Nm: 0.3
    hz: 0.5
    seconds: 4
    settle_s: 1
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 11.59, fidelity_percent_min: 97.7}
      estimate_vs_instrument: {nrmse_percent_max: 6.0, rmse_max: 0.02}
  - name: chirp
    kind: sea-rig-chirp
    amplitude_Nm: 0.15
    f0_hz: 0.1
    fmax_hz: 6
    seconds: 6
    limits:
      setpoint_vs_instrument: {bandwidth_hz_min: 2.5}
)");
  size_t progress_calls = 0;
  const br::PlanResult r = br::runPlan(p, [&](size_t, size_t, const std::string&, double) { ++progress_calls; });
  ASSERT_EQ(r.steps.size(), 2u);
  for (const auto& s : r.steps) EXPECT_TRUE(s.pass) << s.name << ": " << s.error << "\n" << br::toJson(r).dump(1);
  EXPECT_TRUE(r.pass);
  EXPECT_GT(progress_calls, 20u);
  const br::StepResult& sine = r.steps[0];
  EXPECT_LT(sine.samples_stale, 150u) << "a shared machine may starve the polling thread briefly, no more";
  EXPECT_GT(sine.instrument.size(), 2900u);
  // The instrument really measures the torque: its amplitude matches the commanded 0.3 N·m within 5 %.
  double peak = 0.0;
  for (double v : sine.instrument) peak = std::max(peak, std::fabs(v));
  EXPECT_NEAR(peak, 0.3, 0.015);
  EXPECT_EQ(r.steps[1].sp.bandwidth_hz >= 2.5, true);
  EXPECT_FALSE(r.steps[1].sp.magnitude_db.empty());

  const std::string html = br::renderHtml(p, r);
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("Magnitude response"), std::string::npos);
  EXPECT_NE(html.find("Error distribution"), std::string::npos);
  EXPECT_EQ(html.find("<script"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos) << "nothing fetched from outside";
  // A bandwidth the sweep never reached −3 dB within is said so, in the check and in the report, not shown as a
  // plain figure (issue 26 item 8).
  const bool beyond = r.steps[1].sp.bandwidth_beyond_band;
  ASSERT_EQ(r.steps[1].checks.size(), 1u);
  EXPECT_EQ(r.steps[1].checks[0].note.find("not reached within the sweep") != std::string::npos, beyond);
  EXPECT_EQ(html.find("not reached within the sweep") != std::string::npos, beyond);
  EXPECT_NE(html.find("on a linear chirp (eq 16)"), std::string::npos) << "the plan has a chirp step";
  EXPECT_NE(html.find("setpoint vs instrument: −3 dB bandwidth, eq 17 (Hz)"), std::string::npos) << "checks by name";
}

TEST(BenchRun, PlanWithLimitsTooTightFailsAndNamesTheCheck) {
  const br::Plan p = plan(std::string(kHeader) + R"(
steps:
  - name: sine 0.15
    kind: sea-rig-sine
    peak_Nm: 0.15
    seconds: 3
    settle_s: 1
    limits:
      setpoint_vs_instrument: {rmse_max: 0.00001, fidelity_percent_min: 99.99999}
)");
  const br::PlanResult r = br::runPlan(p, noProgress);
  ASSERT_EQ(r.steps.size(), 1u);
  EXPECT_FALSE(r.pass);
  EXPECT_TRUE(r.steps[0].error.empty()) << r.steps[0].error;
  ASSERT_EQ(r.steps[0].checks.size(), 2u);
  EXPECT_EQ(r.steps[0].checks[0].what, "setpoint_vs_instrument.rmse");
  EXPECT_FALSE(r.steps[0].checks[0].pass);
  EXPECT_FALSE(r.steps[0].checks[1].pass);
}

TEST(BenchRun, InstrumentThatStopsAnsweringFailsTheStepWithATimeoutNotAScore) {
  const br::Plan p = plan(std::string(kHeader) + R"(
steps:
  - name: hung amplifier
    kind: sea-rig-sine
    peak_Nm: 0.15
    seconds: 3
    settle_s: 0.5
    instrument_hang_at_s: 1.5
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 50}
)");
  const br::PlanResult r = br::runPlan(p, noProgress);
  ASSERT_EQ(r.steps.size(), 1u);
  const br::StepResult& s = r.steps[0];
  EXPECT_FALSE(s.pass);
  EXPECT_NE(s.error.find("no fresh reading"), std::string::npos) << s.error;
  EXPECT_NE(s.error.find("timed out"), std::string::npos) << s.error;
  EXPECT_GT(s.samples_stale, 1000u);
  EXPECT_GT(s.instrument_stats["timeouts"].get<int>(), 0);
  EXPECT_LT(s.instrument.size(), 1100u) << "stale samples are never scored";
}

namespace {

// The pen pressed into the stiff box's x wall: 0.5 s free, 0.5 s move, first 1.5 s of the press (pen-wall schedule).
const char* kPenHeader = R"(
version: 1
device: sim:pantograph
seed: 2
instrument: {type: int32, scale: 1.0e-5, unit: N, poll_hz: 1000, timeout_ms: 30, stale_ms: 50}
max_stale_percent: 20
)";

double meanOf(const std::vector<double>& v, size_t from) {
  double s = 0.0;
  for (size_t i = from; i < v.size(); ++i) s += v[i];
  return s / static_cast<double>(v.size() - from);
}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

}  // namespace

TEST(BenchRun, PenWallPlanPassesOnTheSimulatedPantographWithExitZero) {
  // NRMSE bounds: measured 13–15 % (setpoint) and 7–12 % (estimate) on the loaded development machine, where the
  // instrument alignment dominates (docs/bench-runner.md); the mean-force checks below are the sharp ones.
  const std::string text = std::string(kPenHeader) + R"(
steps:
  - name: x wall 16 N/cm
    kind: pen-wall
    stiffness_N_per_cm: 16
    seconds: 2.5
    settle_s: 0.5
    limits:
      penetration_mm_max: 2.0
      wall_energy_generated_mJ_max: 0.1
      setpoint_vs_instrument: {nrmse_percent_max: 40}
      estimate_vs_instrument: {nrmse_percent_max: 30}
)";
  const br::Plan p = plan(text);
  const br::PlanResult r = br::runPlan(p, noProgress);
  ASSERT_EQ(r.steps.size(), 1u);
  const br::StepResult& s = r.steps[0];
  EXPECT_TRUE(s.pass) << s.error << "\n" << br::toJson(r).dump(1);
  EXPECT_EQ(s.checks.size(), 4u);
  EXPECT_EQ(s.faults, 0u);
  // The instrument really measures the wall force: near 0 in free space, the pressed force over the last 0.5 s
  // (the hand target is 1.5 cm beyond the wall: ≈ 2–3 N), on average what the scene commanded and what the device
  // estimates (the held tip dithers by an encoder count at ≈ 50 Hz, so single samples differ by tenths of a N).
  ASSERT_GT(s.instrument.size(), 1500u);
  EXPECT_LT(std::fabs(s.instrument.front()), 0.05) << "free space at 0.5 s";
  const size_t last = s.instrument.size() - 400;
  const double inst = meanOf(s.instrument, last), sp = meanOf(s.setpoint, last), est = meanOf(s.estimate, last);
  EXPECT_GT(inst, 1.0);
  EXPECT_NEAR(inst, sp, 0.1 * sp);
  EXPECT_NEAR(est, inst, 0.1 * inst);
  EXPECT_GT(s.step_metrics["peak_tip_penetration_mm"].get<double>(), 0.05) << "the tip did reach the wall";
  // The same plan from a file through the command: exit 0, a report with the pen figures.
  const std::string plan_path = writeTemp("pen-pass.yaml", text), report = ::testing::TempDir() + "pen-pass.html";
  EXPECT_EQ(br::benchRunMain(plan_path, report), 0);
  std::stringstream html;
  html << std::ifstream(report).rdbuf();
  // Step figures by their names, not the JSON keys; no chirp paragraph and no empty bandwidth column on a plan
  // without a chirp step (issue 26 item 8).
  EXPECT_NE(html.str().find("deepest true tip penetration (mm)"), std::string::npos);
  EXPECT_NE(html.str().find("peak commanded wall force (N)"), std::string::npos);
  EXPECT_EQ(html.str().find("peak_commanded_wall_force_N"), std::string::npos);
  EXPECT_EQ(html.str().find("linear chirp"), std::string::npos);
  EXPECT_EQ(html.str().find("bandwidth"), std::string::npos);
}

TEST(BenchRun, PenWallPlanWithLimitsTooTightFailsWithExitOne) {
  const std::string text = std::string(kPenHeader) + R"(
steps:
  - name: x wall, limits too tight
    kind: pen-wall
    stiffness_N_per_cm: 3
    seconds: 2.0
    settle_s: 0.5
    limits:
      penetration_mm_max: 0.01
      setpoint_vs_instrument: {nrmse_percent_max: 0.01}
)";
  const std::string plan_path = writeTemp("pen-fail.yaml", text), report = ::testing::TempDir() + "pen-fail.html";
  EXPECT_EQ(br::benchRunMain(plan_path, report), 1);
  const br::PlanResult r = br::runPlan(plan(text), noProgress);
  ASSERT_EQ(r.steps.size(), 1u);
  const br::StepResult& s = r.steps[0];
  EXPECT_FALSE(s.pass);
  EXPECT_TRUE(s.error.empty()) << s.error << ": it fails on its limits, not on the instrument";
  ASSERT_EQ(s.checks.size(), 2u);
  EXPECT_EQ(s.checks[0].what, "setpoint_vs_instrument.nrmse_percent");
  EXPECT_EQ(s.checks[1].what, "penetration_mm");
  EXPECT_FALSE(s.checks[0].pass);
  EXPECT_FALSE(s.checks[1].pass);
}

TEST(BenchRun, PlanErrorsNameTheKey) {
  br::Plan p;
  EXPECT_NE(br::loadPlanText("version: 1\nsteps: []\n", "p", p).find("steps: expected a non-empty list"), std::string::npos);
  EXPECT_NE(br::loadPlanText("steps: [{kind: sea-rig-sine, peak_Nm: 2}]\n", "p", p).find("steps[0].peak_Nm"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("steps: [{kind: glove-free-motion}]\n", "p", p).find("does not run on sim:sea_rig"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("steps: [{kind: sea-rig-sine, limits: {setpoint_vs_instrument: {bandwidth_hz_min: 2}}}]\n", "p", p)
                .find("needs a sea-rig-chirp"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: serial:/dev/ttyACM0\nsteps: [{kind: sea-rig-sine}]\n", "p", p).find("not supported"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:pantograph\nsteps: [{kind: sea-rig-sine}]\n", "p", p).find("does not run on sim:pantograph"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:glove5\nsteps: [{kind: pen-wall}]\n", "p", p).find("does not run on sim:glove5"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:pantograph\nsteps: [{kind: pen-wall, stiffness_N_per_cm: 100}]\n", "p", p)
                .find("steps[0].stiffness_N_per_cm"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("steps: [{kind: sea-rig-sine, limits: {penetration_mm_max: 1}}]\n", "p", p)
                .find("steps[0].limits.penetration_mm_max: unknown key"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("instrument: {baud_rate: 9600}\nsteps: [{kind: sea-rig-sine}]\n", "p", p).find("instrument.baud_rate"),
            std::string::npos);
}

TEST(BenchRun, APlanWithARepeatedKeyIsRefusedNamingIt) {
  br::Plan p;
  const std::string err = br::loadPlanText("steps:\n  - kind: sea-rig-sine\n    peak_Nm: 0.1\n    peak_Nm: 0.3\n", "p", p);
  EXPECT_NE(err.find("p: steps[0].peak_Nm: duplicate key"), std::string::npos) << err;
}

TEST(BenchRun, MetricsFollowTheirDefinitions) {
  // y = r exactly: zero error, 100 % fidelity, |G| = 0 dB everywhere (bandwidth beyond the band).
  std::vector<double> r(8000), y(8000), half(8000);
  const double f1 = (8.0 - 0.1) / (2.0 * 8.0);
  for (size_t i = 0; i < r.size(); ++i) {
    const double t = static_cast<double>(i) / 1000.0;
    r[i] = 0.15 * std::sin(2.0 * M_PI * (0.1 + f1 * t) * t);  // eq 16
    y[i] = r[i];
    half[i] = 0.5 * r[i];
  }
  br::PairMetrics m = br::comparePair(y, r, 1000.0, true, 0.3, 7.5);
  EXPECT_NEAR(m.rmse, 0.0, 1e-15);
  EXPECT_NEAR(m.fidelity_percent, 100.0, 1e-9);
  EXPECT_TRUE(m.bandwidth_beyond_band);
  // Half amplitude: −6 dB from the first bin, so the −3 dB bandwidth is the band's lower edge; NRMSE 50 %/√2.
  m = br::comparePair(half, r, 1000.0, true, 0.3, 7.5);
  EXPECT_FALSE(m.bandwidth_beyond_band);
  EXPECT_NEAR(m.bandwidth_hz, 0.3, 0.2);
  EXPECT_NEAR(m.magnitude_db[m.magnitude_db.size() / 2], -6.02, 0.3);
  EXPECT_NEAR(m.nrmse_percent, 50.0 / std::sqrt(2.0), 0.5);
}
