// The lab engineer's command line (issue 26, items 6-9), through the real phalanx and phalanxd binaries: progress
// with the time left on long runs, a human bench summary with --json for machines and exit 1 on a missed target,
// defaults and every device kind in the help, errors signed by the program that was run, pen-gii-plot's single
// point. Timing is printed, never gated: the progress checks count lines and read the lines' own fields.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

struct Outcome {
  int rc = INT_MIN;
  std::string out, err;
};

Outcome run(const std::string& binary, const std::vector<std::string>& args, int timeout_ms = 60000) {
  std::vector<std::string> argv{binPath(binary)};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv);
  Outcome o;
  o.rc = p.wait(timeout_ms);
  o.out = p.stdoutText();
  o.err = p.stderrText();
  return o;
}

std::vector<std::string> linesWith(const std::string& text, const std::string& needle) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    if (l.find(needle) != std::string::npos) lines.push_back(l);
  }
  return lines;
}

/// Polls p's stderr until `count` lines contain needle, p ends, or limit_s pass (a bound only).
std::vector<std::string> waitForLines(Process& p, const std::string& needle, std::size_t count, double limit_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
  for (;;) {
    std::vector<std::string> lines = linesWith(p.stderrText(), needle);
    if (lines.size() >= count || std::chrono::steady_clock::now() > end || p.wait(0) != INT_MIN) return lines;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

double field(const std::string& line, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(line, m, std::regex(pattern))) return -1.0;
  return std::stod(m[1].str());
}

std::string tmp(const std::string& name) { return "/tmp/phalanx_cli_ux_" + std::to_string(::getpid()) + "_" + name; }

}  // namespace

// ---- 6: progress ------------------------------------------------------------------------------------------------

TEST(CliProgress, PenWallSweepReportsRunsAndTheTimeLeftByDefault) {
  // The default interval (5 s): the first line comes at the first run boundary after it, however slow the
  // machine; the test stops the sweep there (37 runs, ~45 s on an idle machine).
  Process p({binPath("phalanx"), "bench", "pen-wall", "--sweep"});
  const std::vector<std::string> lines = waitForLines(p, "pen-wall --sweep:", 1, 600);
  ASSERT_FALSE(lines.empty()) << "no progress line before the sweep ended:\n" << p.stderrText();
  EXPECT_EQ(p.wait(0), INT_MIN) << "the progress line came before the end of the run";
  const std::string& first = lines.front();
  std::printf("first progress line: %s\n", first.c_str());
  const double elapsed = field(first, R"(([0-9.]+) s elapsed)");
  const double done = field(first, R"(\((\d+)/37 runs\))");
  ASSERT_GT(done, 0.0) << first;
  EXPECT_NE(first.find(" left"), std::string::npos) << first;
  // Reported at the first run boundary after the 5 s interval: at most one run's time (elapsed / done) late.
  EXPECT_GE(elapsed, 5.0) << first;
  EXPECT_LE(elapsed - 5.0, elapsed / done + 0.5) << first;
}

TEST(CliProgress, PenGiiReportsInsideItsFirstPassNotOnlyBetweenRounds) {
  // Table VIII's half-resolution search (2.4 M candidates, ~50 MB; the full Table VII one needs 470 MB): its first
  // pass evaluates every candidate at one sample before any round (1 s on one thread of the development machine).
  // Two reports inside that pass show the progress does not wait for a round; a slower machine only makes the pass
  // longer and the reports more. design_gii_test holds the same without any timing.
  Process p({binPath("phalanx"), "design", "pen-gii", "--distance-cm", "25", "--threads", "1", "--progress-s", "0.1",
             "--l1", "2.4:7.0:0.4", "--l2", "10:36:1", "--l3", "15:40:1", "--l6", "7:11:0.4", "--q1", "0.5:3.0:0.1"});
  const std::vector<std::string> lines = waitForLines(p, "pen-gii culling:", 2, 300);
  ASSERT_GE(lines.size(), 2u) << p.stderrText();
  for (const std::string& l : lines) std::printf("%s\n", l.c_str());
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_NE(lines[i].find("round 0,"), std::string::npos) << lines[i];
    EXPECT_NE(lines[i].find("left in this pass"), std::string::npos) << lines[i];
    EXPECT_LT(field(lines[i], R"(' (\d+) %)"), 100.0) << lines[i];
  }
  EXPECT_LT(field(lines[0], R"(([0-9.]+) s elapsed)"), field(lines[1], R"(([0-9.]+) s elapsed)"));
}

// ---- 7: bench summary, --json, exit codes -----------------------------------------------------------------------

TEST(CliBench, ASingleBenchPrintsAHumanSummaryByDefaultAndJsonOnRequest) {
  const Outcome human = run("phalanx", {"bench", "glove-grasp"});
  EXPECT_EQ(human.rc, 0) << human.out << human.err;
  EXPECT_EQ(human.out.rfind("glove-grasp: PASS\n", 0), 0u) << human.out;
  EXPECT_NE(human.out.find("largest relative force error in the steady window"), std::string::npos) << human.out;
  EXPECT_FALSE(nlohmann::json::accept(human.out));
  const Outcome machine = run("phalanx", {"bench", "glove-grasp", "--json"});
  EXPECT_EQ(machine.rc, 0) << machine.err;
  ASSERT_TRUE(nlohmann::json::accept(machine.out)) << machine.out;
  EXPECT_EQ(nlohmann::json::parse(machine.out)["target"]["relative_error"], 0.1);
}

TEST(CliBench, AMissedTargetExitsOneWithTheFigureNamedAndTheJsonStillPrinted) {
  // Five times the cable play the controller was tuned for: NRMSE ~23 % against the 3 % target.
  const std::vector<std::string> args{"bench", "sea-rig-sine", "--controller", "ours", "--plant-backlash-scale", "5"};
  const Outcome human = run("phalanx", args);
  EXPECT_EQ(human.rc, 1) << human.out;
  EXPECT_NE(human.out.find("sea-rig-sine: FAIL"), std::string::npos) << human.out;
  EXPECT_NE(human.out.find("MISSED ours: NRMSE"), std::string::npos) << human.out;
  std::vector<std::string> json_args = args;
  json_args.push_back("--json");
  const Outcome machine = run("phalanx", json_args);
  EXPECT_EQ(machine.rc, 1);
  EXPECT_TRUE(nlohmann::json::accept(machine.out)) << machine.out;
}

TEST(CliBench, AChirpThatNeverReachesMinusThreeDbSaysSo) {
  const Outcome o = run("phalanx", {"bench", "sea-rig-chirp", "--controller", "ours", "--fmax-hz", "2"});
  EXPECT_EQ(o.rc, 1) << "a sweep ending below the 5 Hz target cannot show it:\n" << o.out;
  EXPECT_NE(o.out.find("not reached within the sweep"), std::string::npos) << o.out;
}

// ---- 8: pen-gii-plot ---------------------------------------------------------------------------------------------

TEST(CliDesign, PenGiiPlotDrawsASingleFinishedResultAsAVisiblePoint) {
  const std::string json = tmp("gii.json"), svg = tmp("gii.svg");
  const Outcome gii = run("phalanx", {"design", "pen-gii", "--l1", "2.4:2.4:1", "--l2", "14.5:14.5:1", "--l3", "20:20:1",
                                      "--l6", "7:7:1", "--q1", "1.6:1.6:1", "--wi", "0:0:1", "--wj", "0:0:1", "--wk",
                                      "0:0:1", "--rings", "1"});
  ASSERT_EQ(gii.rc, 0) << gii.err;
  std::ofstream(json) << gii.out;
  const Outcome plot = run("phalanx", {"design", "pen-gii-plot", json, "--svg", svg});
  ASSERT_EQ(plot.rc, 0) << plot.err;
  std::stringstream text;
  text << std::ifstream(svg).rdbuf();
  const std::string s = text.str();
  const auto group = s.find("<g fill=\"#1f5fbf\">");
  ASSERT_NE(group, std::string::npos) << "the model's series has dots";
  EXPECT_EQ(s.compare(s.find('\n', group) + 1, 7, "<circle"), 0) << s.substr(group, 200);
  std::remove(json.c_str());
  std::remove(svg.c_str());
}

// ---- 9: help and errors ------------------------------------------------------------------------------------------

TEST(CliHelp, DeviceHelpListsUsbAndDefaultsAreShown) {
  for (const auto& [binary, args] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"phalanx", {"run", "--help"}}, {"phalanxd", {"--help"}}}) {
    const Outcome o = run(binary, args);
    EXPECT_EQ(o.rc, 0);
    EXPECT_NE(o.out.find("usb:VID:PID[:serial]"), std::string::npos) << binary;
    EXPECT_NE(o.out.find("--rate-hz UINT:[100, 4000]=1000"), std::string::npos) << binary << "\n" << o.out;
    EXPECT_NE(o.out.find("--device TEXT=sim:glove5"), std::string::npos) << binary;
  }
  const Outcome worn = run("phalanx", {"bench", "glove-grasp", "--help"});
  EXPECT_EQ(worn.out.find("=-1"), std::string::npos) << "a 'not given' marker is not shown as a default\n" << worn.out;
}

TEST(CliHelp, EveryOptionAndPositionalHasADescription) {
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"profile", "--help"}, {"recordings", "--help"}, {"api", "--help"}}) {
    const Outcome o = run("phalanx", args);
    EXPECT_EQ(o.rc, 0);
    std::vector<std::string> lines;
    std::istringstream in(o.out);
    for (std::string l; std::getline(in, l);) lines.push_back(l.substr(0, l.find_last_not_of(' ') + 1));
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const std::string& l = lines[i];
      // An entry is "  name TYPE   description", or its description on the next, indented line.
      if (l.rfind("  ", 0) != 0 || l.rfind("   ", 0) == 0 || l.find("  ", 2) != std::string::npos) continue;
      const bool continued = i + 1 < lines.size() && lines[i + 1].rfind("          ", 0) == 0;
      EXPECT_TRUE(continued) << args[0] << ": no description: '" << l << "'";
    }
  }
}

TEST(CliErrors, PhalanxRunErrorsAreSignedPhalanx) {
  const Outcome o = run("phalanx", {"run", "--device", "nonsense:x", "--seconds", "0.3", "--no-realtime"});
  EXPECT_EQ(o.rc, 2) << o.err;
  EXPECT_EQ(o.err.rfind("phalanx: error: device: 'nonsense:x' is not a device", 0), 0u) << o.err;
  EXPECT_EQ(o.err.find("phalanxd:"), std::string::npos) << o.err;
  const Outcome d = run("phalanxd", {"--device", "nonsense:x", "--seconds", "0.3", "--no-realtime"});
  EXPECT_EQ(d.err.rfind("phalanxd: error: device:", 0), 0u) << d.err;
}
