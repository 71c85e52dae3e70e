// The real phalanxd and phalanx binaries given bad arguments: every one is refused before any device is opened,
// with exit code 2 (README "Exit codes") and a message naming the option; --help still exits 0. Cases that ran a
// session before they were refused carry --seconds 0.3, so that against an unfixed build they end (exit 0) and
// fail the test instead of running until killed.
#include <gtest/gtest.h>
#include <unistd.h>

#include <climits>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

struct Outcome {
  int rc = INT_MIN;
  std::string out;
  std::string err;
};

Outcome run(const std::string& binary, const std::vector<std::string>& args) {
  std::vector<std::string> argv{binPath(binary)};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv);
  Outcome o;
  o.rc = p.wait(30000);  // a bound only: a refusal takes milliseconds
  o.out = p.stdoutText();
  o.err = p.stderrText();
  return o;
}

std::string shown(const std::vector<std::string>& args) {
  std::string s;
  for (const std::string& a : args) s += (s.empty() ? "" : " ") + (a.empty() ? std::string("\"\"") : a);
  return s;
}

struct Case {
  std::vector<std::string> args;
  std::string needle;  // must appear in stderr
};

void expectRefused(const std::string& binary, const std::vector<Case>& cases) {
  for (const Case& c : cases) {
    const Outcome o = run(binary, c.args);
    EXPECT_EQ(o.rc, 2) << binary << " " << shown(c.args) << "\n" << o.err;
    EXPECT_NE(o.err.find(c.needle), std::string::npos) << binary << " " << shown(c.args) << "\nstderr: " << o.err
                                                       << "\nlacks: " << c.needle;
  }
}

std::string tmp(const std::string& name) { return "/tmp/phalanx_cli_args_" + std::to_string(::getpid()) + "_" + name; }

const std::vector<std::string> kShort{"--seconds", "0.3", "--no-realtime"};

std::vector<std::string> with(std::vector<std::string> args, const std::vector<std::string>& more) {
  args.insert(args.end(), more.begin(), more.end());
  return args;
}

}  // namespace

TEST(CliArgs, PhalanxdRefusesAnEmptyPathOrAddressNamingTheOption) {
  std::vector<Case> cases;
  for (const char* opt : {"--api", "--records-dir", "--profiles-dir", "--dashboard", "--record", "--config",
                          "--session-record", "--profile", "--report", "--previous-record", "--device",
                          "--pen-geometry", "--sea-subject", "--firmware-sim", "--sim-truth", "--sim-settings", "--estop", "--exercise-params"}) {
    cases.push_back({with({opt, ""}, kShort), std::string(opt) + ": must not be empty"});
  }
  expectRefused("phalanxd", cases);
}

TEST(CliArgs, PhalanxdRangeConversionAndUnknownOptionErrorsExitTwoNamingTheOption) {
  expectRefused("phalanxd", {
      {{"--seconds", "-1"}, "--seconds: expected a number in [0, 86400], got '-1'"},
      {{"--rate-hz", "abc"}, "--rate-hz: expected an integer in [100, 4000], got 'abc'"},
      {{"--rate-hz", "99"}, "--rate-hz"},
      {{"--command-timeout-ms", "1"}, "--command-timeout-ms"},
      {{"--seed", "abc"}, "--seed: expected a non-negative integer, got 'abc'"},
      {{"--scenario", "dance"}, "--scenario"},
      {{"--device", "sim:glove5", "--scenario", "spastic"},
       "scenario: 'spastic' (a finger with a stretch reflex) is for sim:sea_finger only, not sim:glove5"},
      {{"--secnds", "1"}, "unknown option --secnds; did you mean --seconds?"},
      {{"--rate", "500"}, "unknown option --rate; did you mean --rate-hz?"},
      {{"--device"}, "--device"},
      {{"stray"}, "unexpected argument 'stray'"},
      {{"--device", "serial:/dev/null", "--sim-truth", "/tmp/t.csv"},
       "--sim-truth: the plant's truth exists for sim: devices only, not 'serial:/dev/null'"},
  });
}

TEST(CliArgs, PhalanxdRefusesASessionShorterThanOnePeriodInsteadOfRunningForever) {
  // 0.0004 s at 1 kHz rounded to zero cycles, which the runner reads as "until stopped".
  expectRefused("phalanxd", {
      {{"--seconds", "0.0004", "--no-realtime"}, "--seconds: 0.0004 s is shorter than one host period (0.001 s at 1000 Hz)"},
      {{"--seconds", "0.0004", "--rate-hz", "2000", "--no-realtime"}, "(0.0005 s at 2000 Hz)"},
  });
  const std::string cfg = tmp("short.yaml");
  std::ofstream(cfg) << "seconds: 0.0004\n";
  expectRefused("phalanxd", {{{"--config", cfg, "--no-realtime"}, cfg + ": seconds: 0.0004 s is shorter"}});
  std::remove(cfg.c_str());
}

TEST(CliArgs, PhalanxdRefusesAnOptionOfTheOtherMode) {
  const std::string sock = tmp("api.sock");
  expectRefused("phalanxd", {
      {with({"--records-dir", "/tmp"}, kShort), "--records-dir: only used with --api"},
      {with({"--profiles-dir", "/tmp"}, kShort), "--profiles-dir: only used with --api"},
      {{"--api", sock, "--exercise", "assessment"}, "--exercise: not used with --api"},
      {{"--api", sock, "--record", tmp("x.csv")}, "--record: not used with --api"},
  });
  ::unlink(sock.c_str());
}

TEST(CliArgs, PhalanxdRefusesRepeatedKeysInItsConfigAndProfile) {
  const std::string cfg = tmp("dup.yaml");
  std::ofstream(cfg) << "rate_hz: 100\nrate_hz: 4000\n";
  const std::string profile = tmp("profile.yaml");
  std::ofstream(profile) << "version: 1\npatient: p-1\ndevice: glove5\n"
                            "limits:\n  effort_max: {default: 2, index: 1, index: 9}\n";
  expectRefused("phalanxd", {
      {with({"--config", cfg}, kShort), cfg + ": rate_hz: duplicate key (line 2; first at line 1)"},
      {with({"--profile", profile}, kShort), "limits.effort_max.index: duplicate key"},
  });
  std::remove(cfg.c_str());
  std::remove(profile.c_str());
}

TEST(CliArgs, PhalanxdHelpStillExitsZero) {
  const Outcome o = run("phalanxd", {"--help"});
  EXPECT_EQ(o.rc, 0) << o.err;
  EXPECT_NE(o.out.find("--seconds"), std::string::npos) << o.out;
}

TEST(CliArgs, PhalanxEverySubcommandsArgumentErrorsExitTwoNamingTheOption) {
  // A one-sample pen-gii search: fast, so that an unfixed build, which ignored a short --eval, ends quickly.
  const std::vector<std::string> tiny_gii{"design", "pen-gii", "--l1", "2.4:2.4:1", "--l2", "14.5:14.5:1", "--l3",
                                          "20:20:1", "--l6", "7:7:1", "--q1", "1.6:1.6:1", "--wi", "0:0:1",
                                          "--wj", "0:0:1", "--wk", "0:0:1", "--rings", "1"};
  expectRefused("phalanx", {
      {{}, "a command is required"},
      {{"rnu"}, "unknown command 'rnu'; did you mean run?"},
      {{"run", "--secnds", "3"}, "unknown option --secnds; did you mean --seconds?"},
      {{"run", "--seconds", "0.0004", "--no-realtime"}, "--seconds: 0.0004 s is shorter than one host period"},
      {{"run", "--rate-hz", "abc"}, "--rate-hz: expected an integer in [100, 4000], got 'abc'"},
      {with({"run", "--record", ""}, kShort), "--record: must not be empty"},
      {{"bench", "glove-grasp", "--seconds", "x"}, "--seconds: expected a number in [0, 600], got 'x'"},
      {{"bench", "glove-grasp", "--seconds", "0.0001"}, "--seconds: expected 0 (its default) or at least 0.001 s"},
      {{"bench", "sea-rig-sine", "--seconds", "0.0001"}, "--seconds: expected 0 (its default) or at least 0.001 s"},
      {{"bench", "sea-rig-sine", "--peak-nm", "0.1"}, "unknown option --peak-nm; did you mean --peak-Nm?"},
      {{"bench", "pen-split", "--grid", "1"}, "--grid: expected an integer in [2, 15], got '1'"},
      {{"bench", "run", ""}, "plan: must not be empty"},
      {{"can", "budget", "--rate-hz", "0"}, "--rate-hz: expected a number in [1, 10000], got '0'"},
      {{"mcu-diag"}, "--device is required"},
      {{"param"}, "a command is required (list, get, set, save, load, diff)"},
      {{"param", "get", "force_kp"}, "--device is required"},
      {{"param", "set", "force_kp", "nan", "--device", "sim:glove5"}, "value 'nan' is not a finite number"},
      {{"param", "load", tmp("none.yaml"), "--device", "sim:glove5"}, "file: File does not exist"},
      {{"param", "list", "--device", "sim:glove5", "--sim-settings", ""}, "--sim-settings: must not be empty"},
      {{"param", "list", "--device", "serial:/dev/null", "--sim-settings", tmp("s.bin")},
       "--sim-settings: for sim: devices only, not 'serial:/dev/null'"},
      {{"param", "list", "--device", "sim:glove5", "--sim-settings-layout", "1"}, "--sim-settings-layout needs --sim-settings"},
      {{"mcu-diag", "--device", "serial:/dev/null", "--timeout", "0"}, "--timeout"},
      {{"sea-calibrate", "--recording", "", "--subject", tmp("s.yaml")}, "--recording: must not be empty"},
      {{"status", "--socket", ""}, "--socket: must not be empty"},
      {{"start", "--seconds", "-3", "--socket", tmp("none.sock")}, "--seconds: expected a number in [0, 86400], got '-3'"},
      {{"start", "--seed", "-3", "--socket", tmp("none.sock")}, "--seed: expected an integer in [0, 4294967295]"},
      {{"start", "--device", "", "--socket", tmp("none.sock")}, "--device: must not be empty"},
      {{"profile", "", "--socket", tmp("none.sock")}, "patient: must not be empty"},
      {{"record", "info", tmp("none.phrec")}, "file: File does not exist"},
      {{"design", "glove-workspace", "--grid", "1"}, "--grid: expected an integer in [2, 201], got '1'"},
      {{"design", "glove-optimize", "--svg"}, "--svg: 1 required TEXT missing"},
      {{"design", "glove-optimize", "--foo"}, "unknown option --foo"},
      {{"design", "glove-optimize", "--sarts", "3"}, "unknown option --sarts; did you mean --starts?"},
      {{"design", "glove-workspace", "--geometry", tmp("none.yaml")}, "--geometry: File does not exist"},
      {{"design", "pen-gi"}, "unknown command 'pen-gi'; did you mean pen-gii?"},
      {{"bench", "pen-wal"}, "unknown command 'pen-wal'; did you mean pen-wall?"},
      {{"bench", "pen-wall", "--sweeep"}, "unknown option --sweeep; did you mean --sweep?"},
      {{"bench", "pen-wall", "--progress-s", "-1"}, "--progress-s: expected a number in [0, 3600], got '-1'"},
      {{"design", "pen-gii", "--progress-s", "x"}, "--progress-s: expected a number in [0, 3600], got 'x'"},
      {with(tiny_gii, {"--eval", "1", "2"}), "--eval"},
      {with(tiny_gii, {"--l1", ""}), "--l1: must not be empty"},
  });
}

TEST(CliArgs, PhalanxHelpStillExitsZero) {
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{
           {"--help"}, {"run", "--help"}, {"bench", "glove-grasp", "--help"}, {"design", "pen-gii", "--help"}}) {
    const Outcome o = run("phalanx", args);
    EXPECT_EQ(o.rc, 0) << shown(args) << "\n" << o.err;
    EXPECT_NE(o.out.find("Usage"), std::string::npos) << o.out;
  }
}
