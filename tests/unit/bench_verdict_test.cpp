// The single benches' verdict (`phalanx bench …` without --json): each declared target judged, a missing figure
// a failure, a bandwidth the sweep never reached said so; and the progress line's estimate of the time left.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "phalanx/host/bench_verdict.h"
#include "phalanx/host/progress.h"

using phalanx::host::benchSummaryText;
using phalanx::host::judgeBench;
using phalanx::host::ProgressLine;

namespace {
nlohmann::json grasp(double rel_err, int fingers) {
  return {{"relative_error_max", rel_err}, {"fingers_in_steady_contact", fingers}, {"faults", 0},
          {"target", {{"relative_error", 0.1}}}};
}

nlohmann::json chirp(double bw_hz, bool beyond) {
  return {{"controllers", {{"ours", {{"bandwidth_hz", bw_hz}, {"bandwidth_beyond_band", beyond}, {"faults", 0}}}}},
          {"target", {{"bandwidth_hz_min", 5.0}}}};
}
}  // namespace

TEST(BenchVerdict, AGraspWithinItsTargetPassesAndOneBeyondItFailsNamingTheFigure) {
  EXPECT_TRUE(judgeBench("glove-grasp", grasp(0.04, 3)).pass());
  const auto miss = judgeBench("glove-grasp", grasp(0.12, 3));
  EXPECT_FALSE(miss.pass());
  const std::string text = benchSummaryText(miss);
  EXPECT_NE(text.find("glove-grasp: FAIL"), std::string::npos) << text;
  EXPECT_NE(text.find("MISSED largest relative force error in the steady window: 0.12 (target <= 0.1)"), std::string::npos)
      << text;
}

TEST(BenchVerdict, AGraspWithNoFingerOnTheBallFailsThoughItsErrorIsZero) {
  EXPECT_FALSE(judgeBench("glove-grasp", grasp(0.0, 0)).pass());
}

TEST(BenchVerdict, AMissingOrNonNumericFigureFailsItsCheck) {
  nlohmann::json r = grasp(0.04, 3);
  r.erase("relative_error_max");
  const auto v = judgeBench("glove-grasp", r);
  EXPECT_FALSE(v.pass());
  EXPECT_NE(benchSummaryText(v).find("not reported"), std::string::npos);
  r = grasp(0.04, 3);
  r["faults"] = "many";
  EXPECT_FALSE(judgeBench("glove-grasp", r).pass());
}

TEST(BenchVerdict, ABandwidthBeyondTheSweepIsSaidSoAndPassesOnlyAboveTheTarget) {
  const auto above = judgeBench("sea-rig-chirp", chirp(9.5, true));
  EXPECT_TRUE(above.pass());
  EXPECT_NE(benchSummaryText(above).find("-3 dB not reached within the sweep"), std::string::npos) << benchSummaryText(above);
  // A sweep that ends below the target cannot show it: a miss, with the reason.
  const auto below = judgeBench("sea-rig-chirp", chirp(1.5, true));
  EXPECT_FALSE(below.pass());
  EXPECT_NE(benchSummaryText(below).find("sweep further (--fmax-hz)"), std::string::npos) << benchSummaryText(below);
  EXPECT_EQ(benchSummaryText(judgeBench("sea-rig-chirp", chirp(16.8, false))).find("not reached"), std::string::npos);
}

TEST(BenchVerdict, TheSeaTargetsJudgeOursAndOnlyAtTheTargetsOperatingPoint) {
  nlohmann::json r = {{"peak_Nm", 0.3}, {"hz", 0.5},
                      {"controllers", {{"ours", {{"fidelity_percent", 99.9}, {"nrmse_percent", 1.1}, {"faults", 0}}},
                                       {"paper", {{"fidelity_percent", 99.0}, {"nrmse_percent", 6.8}, {"faults", 0}}}}},
                      {"target", {{"peak_Nm", 0.3}, {"hz", 0.5}, {"fidelity_percent_min", 99.5}, {"nrmse_percent_max", 3.0}}}};
  const auto v = judgeBench("sea-rig-sine", r);
  EXPECT_TRUE(v.pass()) << "the paper's PID (NRMSE 6.8 %) is the baseline, not judged";
  EXPECT_EQ(v.checks.size(), 3u);
  r["controllers"]["ours"]["nrmse_percent"] = 3.5;
  EXPECT_FALSE(judgeBench("sea-rig-sine", r).pass());
  r["peak_Nm"] = 0.15;
  const auto elsewhere = judgeBench("sea-rig-sine", r);
  EXPECT_TRUE(elsewhere.checks.empty());
  ASSERT_EQ(elsewhere.notes.size(), 1u);
  EXPECT_NE(elsewhere.notes[0].find("not judged"), std::string::npos);
}

TEST(BenchVerdict, APenWallRunMustBeStableAndPassive) {
  nlohmann::json r = {{"stable", true}, {"passive", true}, {"stiffness_N_per_cm", 3.0}};
  EXPECT_TRUE(judgeBench("pen-wall", r).pass());
  r["stable"] = false;
  EXPECT_FALSE(judgeBench("pen-wall", r).pass());
  // The sweep judges the requested stiffness's run.
  EXPECT_FALSE(judgeBench("pen-wall", {{"requested", r}}).pass());
  r["stable"] = true;
  EXPECT_TRUE(judgeBench("pen-wall", {{"requested", r}}).pass());
}

TEST(ProgressLine, TheTimeLeftContinuesTheRateSoFar) {
  EXPECT_EQ(ProgressLine::format("pen-wall --sweep", 10.0, 0.25, "9/36 runs"),
            "pen-wall --sweep: 25 % (9/36 runs), 10.0 s elapsed, ~30 s left");
  EXPECT_EQ(ProgressLine::format("x", 200.0, 0.4, ""), "x: 40 %, 200.0 s elapsed, ~5 min 00 s left");
  EXPECT_EQ(ProgressLine::format("x", 3.0, -1.0, "round 2"), "x: round 2, 3.0 s elapsed") << "no estimate when unknown";
  EXPECT_EQ(ProgressLine::duration(4000.0), "1 h 06 min");
}

TEST(ProgressLine, ARunShorterThanTheIntervalPrintsNothing) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressLine line("quick", 60.0, f);
    for (int i = 0; i <= 10; ++i) line.update(i / 10.0);
  }
  EXPECT_EQ(std::ftell(f), 0L);
  std::fclose(f);
}
