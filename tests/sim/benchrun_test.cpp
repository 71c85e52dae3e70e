// The bench runner end to end on the simulated SEA rig and the haptic pen (real time: the reference instrument is
// polled over Modbus as on the bench), with short plans so the suite stays within its time budget.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <random>
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
safety: {effort_max: 0.4, instrument_silence_ms: 200, disagreement_max: 0.05, disagreement_ms: 100}
)";

void noProgress(size_t, size_t, const std::string&, double) {}

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

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
  // The healthy instrument stayed inside the safety bounds with room to spare (silence 200, disagreement 100 ms).
  EXPECT_LT(sine.longest_silence_ticks, 100);
  EXPECT_LT(sine.longest_disagreement_ticks, 10);
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

std::string withSilenceMs(std::string header, const char* ms) {
  const std::string key = "instrument_silence_ms: 200";
  header.replace(header.find(key), key.size(), std::string("instrument_silence_ms: ") + ms);
  return header;
}

TEST(BenchRun, InstrumentThatStopsAnsweringFailsTheStepWithATimeoutNotAScore) {
  // A silence bound beyond the step: the stale-sample accounting alone fails it (the safety stop is tested below).
  const br::Plan p = plan(withSilenceMs(kHeader, "10000") + R"(
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
  EXPECT_TRUE(s.safety_stop.empty()) << s.safety_stop;
}

namespace {

// Two sine steps; a fault in the first one. Only the first may run.
std::string faultPlan(const std::string& fault) {
  return std::string(kHeader) + R"(
steps:
  - name: faulty instrument
    kind: sea-rig-sine
    peak_Nm: 0.3
    hz: 0.5
    seconds: 3
    settle_s: 0.5
)" + fault + R"(
  - name: must not run
    kind: sea-rig-sine
    peak_Nm: 0.3
    seconds: 2
)";
}

// The stop decision, the device's telemetry at it and after it, the plan's end: what every safety stop must show.
void expectSafetyStop(const br::PlanResult& r, const char* cause, long fault_tick, long bound_ticks) {
  ASSERT_EQ(r.steps.size(), 2u);
  const br::StepResult& s = r.steps[0];
  EXPECT_FALSE(r.pass);
  EXPECT_FALSE(s.pass);
  EXPECT_NE(s.safety_stop.find(cause), std::string::npos) << s.safety_stop;
  EXPECT_EQ(s.error.find(s.safety_stop), 0u) << s.error;
  // Counted in rig ticks: not before the fault, not before the bound has passed after it, and no later than the
  // bound plus a few polls (the last fresh sample may come a few ticks before the fault).
  EXPECT_GE(s.stop_tick, fault_tick + bound_ticks - 10) << br::toJson(r).dump(1);
  EXPECT_LE(s.stop_tick, fault_tick + bound_ticks + 20) << br::toJson(r).dump(1);
  EXPECT_TRUE(s.active_at_stop) << "the device was pushing when the decision fell";
  EXPECT_GE(s.ticks_to_safe, 1);
  EXPECT_LE(s.ticks_to_safe, 2) << "device telemetry: mode safe, outputs off, within two ticks of the decision";
  EXPECT_TRUE(s.t.empty()) << "a stopped step is not scored";
  EXPECT_TRUE(r.steps[1].skipped);
  EXPECT_FALSE(r.steps[1].pass);
  EXPECT_NE(r.steps[1].error.find("not run: safety stop in step 1"), std::string::npos) << r.steps[1].error;
  EXPECT_EQ(r.steps[1].samples_total, 0u);
  const nlohmann::json j = br::toJson(r);
  EXPECT_EQ(j["steps"][0]["ticks_to_safe"].get<long>(), s.ticks_to_safe);
  EXPECT_TRUE(j["steps"][1]["skipped"].get<bool>());
}

}  // namespace

TEST(BenchRun, AHungInstrumentStopsTheStepAndThePlanWithTheDeviceSafeWithinTwoTicks) {
  // Hang at 1.4 s: the 0.3 N·m sine is near its peak (−0.29 N·m) when the 200 ms silence bound passes.
  const br::PlanResult r = br::runPlan(plan(faultPlan("    instrument_hang_at_s: 1.4")), noProgress);
  expectSafetyStop(r, "instrument silent", 1400, 200);
  EXPECT_GT(r.steps[0].longest_silence_ticks, 200);
  EXPECT_NE(r.steps[0].safety_stop.find("safety.instrument_silence_ms 200"), std::string::npos) << r.steps[0].safety_stop;
}

TEST(BenchRun, AnInstrumentReadingZeroStopsTheStepWithTheDeviceSafeWithinTwoTicks) {
  // A broken load cell reads 0 while the device pushes ±0.3 N·m (at 1.25 s the sine is at −0.21 N·m).
  const std::string text = faultPlan("    instrument_lie_at_s: 1.25\n    instrument_lie_gain: 0");
  const br::PlanResult r = br::runPlan(plan(text), noProgress);
  expectSafetyStop(r, "instrument disagrees with the device's estimate", 1250, 100);
  EXPECT_GT(r.steps[0].longest_disagreement_ticks, 100);
  EXPECT_NE(r.steps[0].safety_stop.find("safety.disagreement_max 0.05"), std::string::npos) << r.steps[0].safety_stop;
  // The command says so: exit 1, as any failed step.
  const std::string path = writeTemp("lying.yaml", text);
  EXPECT_EQ(br::benchRunMain(path, ::testing::TempDir() + "lying.html", "", true), 1);
}

TEST(BenchRun, AnInstrumentWithAnOffsetStopsTheStepWithTheDeviceSafeWithinTwoTicks) {
  const br::PlanResult r =
      br::runPlan(plan(faultPlan("    instrument_lie_at_s: 1.0\n    instrument_lie_offset: 0.1")), noProgress);
  expectSafetyStop(r, "instrument disagrees with the device's estimate", 1000, 100);
}

TEST(BenchRun, APlanBeyondTheDeviceLimitOrAStepBeyondThePlanLimitIsRefusedAtLoad) {
  const std::string steps = "steps: [{kind: sea-rig-sine, peak_Nm: 0.3}]\n";
  br::Plan p;
  p.source = "untouched";
  std::string err = br::loadPlanText(
      "safety: {effort_max: 1.5, instrument_silence_ms: 100, disagreement_max: 0.05, disagreement_ms: 100}\n" + steps, "p", p);
  EXPECT_NE(err.find("p: safety.effort_max: 1.5 exceeds the device's own limit 1 (sim:sea_rig"), std::string::npos) << err;
  EXPECT_EQ(p.source, "untouched") << "a refused plan changes nothing";
  err = br::loadPlanText(
      "safety: {effort_max: 0.2, instrument_silence_ms: 100, disagreement_max: 0.05, disagreement_ms: 100}\n" + steps, "p", p);
  EXPECT_NE(err.find("p: steps[0].peak_Nm: commands up to 0.3, beyond safety.effort_max 0.2"), std::string::npos) << err;
  err = br::loadPlanText(
      "safety: {effort_max: 0.1, instrument_silence_ms: 100, disagreement_max: 0.05, disagreement_ms: 100}\n"
      "steps: [{kind: sea-rig-chirp, amplitude_Nm: 0.15}]\n", "p", p);
  EXPECT_NE(err.find("steps[0].amplitude_Nm: commands up to 0.15, beyond safety.effort_max 0.1"), std::string::npos) << err;
  err = br::loadPlanText(
      "device: sim:pantograph\nsafety: {effort_max: 1, instrument_silence_ms: 100, disagreement_max: 3, disagreement_ms: 100}\n"
      "steps: [{kind: pen-wall}]\n", "p", p);
  EXPECT_NE(err.find("steps[0].kind: commands up to 2.1 (pen-wall: the force split's joint torque limit), beyond "
                     "safety.effort_max 1"), std::string::npos) << err;
  err = br::loadPlanText(
      "device: sim:glove5\nsafety: {effort_max: 10.5, instrument_silence_ms: 100, disagreement_max: 1, disagreement_ms: 100}\n"
      "steps: [{kind: glove-free-motion}]\n", "p", p);
  EXPECT_NE(err.find("safety.effort_max: 10.5 exceeds the device's own limit 10 (sim:glove5"), std::string::npos) << err;
  // Required, every key.
  err = br::loadPlanText(steps, "p", p);
  EXPECT_NE(err.find("p: safety: required (effort_max, instrument_silence_ms, disagreement_max, disagreement_ms; the "
                     "device's own effort limit is 1"), std::string::npos) << err;
  err = br::loadPlanText("safety: {effort_max: 0.4, instrument_silence_ms: 100, disagreement_max: 0.05}\n" + steps, "p", p);
  EXPECT_NE(err.find("safety.disagreement_ms: required"), std::string::npos) << err;
  err = br::loadPlanText("safety: {effort_max: 0.4, instrument_silence_ms: 0, disagreement_max: 0.05, disagreement_ms: 100}\n" +
                             steps, "p", p);
  EXPECT_NE(err.find("safety.instrument_silence_ms: 0 is outside"), std::string::npos) << err;
  EXPECT_EQ(p.source, "untouched");
  // Exactly at the limits: accepted.
  EXPECT_EQ(br::loadPlanText(
                "safety: {effort_max: 1, instrument_silence_ms: 100, disagreement_max: 0.05, disagreement_ms: 100}\n"
                "steps: [{kind: sea-rig-sine, peak_Nm: 0.4}, {kind: sea-rig-sine, peak_Nm: 0.3}]\n", "p", p),
            "");
  // The command: exit 2, nothing runs (no report written).
  const std::string path = writeTemp("over-limit.yaml",
      "safety: {effort_max: 1.5, instrument_silence_ms: 100, disagreement_max: 0.05, disagreement_ms: 100}\n" + steps);
  const std::string report = ::testing::TempDir() + "over-limit.html";
  std::remove(report.c_str());
  EXPECT_EQ(br::benchRunMain(path, report, "", true), 2);
  EXPECT_FALSE(std::ifstream(report).good()) << "nothing ran";
}

namespace {

// The pen pressed into the stiff box's x wall: 0.5 s free, 0.5 s move, first 1.5 s of the press (pen-wall schedule).
const char* kPenHeader = R"(
version: 1
device: sim:pantograph
seed: 2
instrument: {type: int32, scale: 1.0e-5, unit: N, poll_hz: 1000, timeout_ms: 30, stale_ms: 50}
max_stale_percent: 20
safety: {effort_max: 2.1, instrument_silence_ms: 200, disagreement_max: 3.0, disagreement_ms: 100}
)";

double meanOf(const std::vector<double>& v, size_t from) {
  double s = 0.0;
  for (size_t i = from; i < v.size(); ++i) s += v[i];
  return s / static_cast<double>(v.size() - from);
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
  EXPECT_EQ(br::benchRunMain(plan_path, report, "", true), 0);
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
  EXPECT_EQ(br::benchRunMain(plan_path, report, "", true), 1);
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

TEST(BenchRun, GloveGraspPlanHoldsTheBallAndScoresTheContactForce) {
  // The step of `phalanx bench glove-grasp` (issue 26 item 4): the hand squeezes the rigid ball; the last second
  // of contact is scored. Defaults: 3 s, 2 s settling.
  const br::Plan p = plan(R"(
version: 1
device: sim:glove5
seed: 1
instrument: {type: int32, scale: 1.0e-5, unit: N, poll_hz: 500, timeout_ms: 30, stale_ms: 50}
max_stale_percent: 5
safety: {effort_max: 10, instrument_silence_ms: 200, disagreement_max: 1.5, disagreement_ms: 100}
steps:
  - kind: glove-grasp
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 10}
      estimate_vs_instrument: {nrmse_percent_max: 10}
)");
  ASSERT_EQ(p.steps.size(), 1u);
  EXPECT_DOUBLE_EQ(p.steps[0].seconds, 3.0);
  EXPECT_DOUBLE_EQ(p.steps[0].settle_s, 2.0);
  EXPECT_DOUBLE_EQ(br::stepEffortMax(p.steps[0]), 10.0);
  const br::PlanResult r = br::runPlan(p, noProgress);
  ASSERT_EQ(r.steps.size(), 1u);
  const br::StepResult& s = r.steps[0];
  EXPECT_TRUE(s.pass) << s.error << "\n" << br::toJson(r).dump(1);
  EXPECT_EQ(s.faults, 0u);
  // In contact the whole scored second: the finger feels a few newtons, close to what the ball commanded.
  ASSERT_GT(s.instrument.size(), 900u);
  const double inst = meanOf(s.instrument, 0), sp = meanOf(s.setpoint, 0);
  EXPECT_GT(inst, 2.0);
  EXPECT_NEAR(inst, sp, 0.1 * sp);
  // Fidelity (eq 15) is the SEA rig's trajectory metric: not reported for a held force.
  EXPECT_FALSE(br::toJson(r)["steps"][0]["setpoint_vs_instrument"].contains("fidelity_percent"));
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
  // A real device: its type is the plan's to say (the steps' kinds are checked against it).
  EXPECT_NE(br::loadPlanText("device: serial:/dev/ttyACM0\nsteps: [{kind: sea-rig-sine}]\n", "p", p)
                .find("device_type: required for serial:/dev/ttyACM0"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: serial:/dev/ttyACM0\ndevice_type: glove5\nsteps: [{kind: sea-rig-sine}]\n", "p", p)
                .find("does not run on serial:/dev/ttyACM0 (glove5)"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: tcp:robot\nsteps: [{kind: sea-rig-sine}]\n", "p", p).find("device: 'tcp:robot' is not a device"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: can:can0\nsim_instrument: false\ndevice_type: sea_rig\nsteps: [{kind: sea-rig-sine}]\n", "p", p)
                .find("sim_instrument: only for sim: devices"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:pantograph\nsteps: [{kind: sea-rig-sine}]\n", "p", p).find("does not run on sim:pantograph"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:glove5\nsteps: [{kind: pen-wall}]\n", "p", p).find("does not run on sim:glove5"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:glove5\nsteps: [{kind: glove-grasp, limits: {setpoint_vs_instrument: "
                             "{fidelity_percent_min: 90}}}]\n", "p", p)
                .find("steps[0].limits: fidelity_percent_min (eq 15, a torque trajectory's tracking) needs a sea-rig-sine"),
            std::string::npos);
  EXPECT_NE(br::loadPlanText("device: sim:glove5\nsafety: {effort_max: 5, instrument_silence_ms: 100, disagreement_max: 1, "
                             "disagreement_ms: 100}\nsteps: [{kind: glove-grasp}]\n", "p", p)
                .find("steps[0].kind: commands up to 10, beyond safety.effort_max 5"),
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

/// An instrument that shows the estimate `delay_ms` late, sampled at 500 Hz between the device's ticks, each side
/// with its own noise. The alignment compares against the estimate held from tick to tick, so it finds the delay
/// to within a tick.
br::Alignment alignSynthetic(const std::function<double(double)>& signal, double delay_ms, double noise) {
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, noise);
  std::vector<double> T, est, s, v;
  for (int k = 0; k < 6000; ++k) {  // 6 s of 1 ms ticks
    T.push_back(k);
    est.push_back(signal(k) + n(rng));
  }
  for (double t = 0.37; t < 6000; t += 2.0) {
    s.push_back(t);
    v.push_back(signal(t - delay_ms) + n(rng));
  }
  return br::alignInstrument(T, est, s, v, 60.0);
}

TEST(BenchRun, TheAlignmentFindsTheDelayAndChecksItOnTheQuartersThatFollowTheEstimate) {
  // Broadband motion (sines from 0.5 to 21 Hz): every quarter follows, and each finds the delay.
  const auto motion = [](double t) {
    double y = 0.0;
    for (const double f : {0.5, 3.1, 7.3, 13.7, 21.1}) y += std::sin(2 * M_PI * f * t / 1000.0 + f);
    return y;
  };
  const br::Alignment moving = alignSynthetic(motion, 3.0, 0.01);
  EXPECT_TRUE(moving.ok) << moving.error;
  EXPECT_NEAR(moving.delay_ms, 3.0, 1.0);
  EXPECT_EQ(moving.quarters_used, 4u);
  // A grasp: the reach (1.0-2.0 s, minimum jerk to 5 N) and the contact's ringing (20 Hz, decaying) span the first
  // two quarters, then the force is held: the held quarters are noise on both sides, left out, and the delay is
  // still found and checked on the two quarters of the reach.
  const auto reach = [](double t) {
    const double x = std::clamp((t - 1000.0) / 1000.0, 0.0, 1.0);
    const double ring = t > 2000.0 ? 0.5 * std::exp(-(t - 2000.0) / 150.0) * std::sin(2 * M_PI * 20.0 * (t - 2000.0) / 1000.0) : 0.0;
    return 5.0 * x * x * x * (10.0 - 15.0 * x + 6.0 * x * x) + ring;
  };
  const br::Alignment grasp = alignSynthetic(reach, 3.0, 0.01);
  EXPECT_TRUE(grasp.ok) << grasp.error;
  EXPECT_NEAR(grasp.delay_ms, 3.0, 1.0);
  EXPECT_EQ(grasp.quarters_used, 2u);
  EXPECT_LT(grasp.quarter_correlation[3], 0.5);
  // A held force only: nothing fixes a delay.
  const br::Alignment held = alignSynthetic([](double) { return 5.0; }, 3.0, 0.01);
  EXPECT_FALSE(held.ok);
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
