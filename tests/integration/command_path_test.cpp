// The session runner's command path, end to end through the real binaries: every command source ends in the one
// limits stage (a Modbus write is held to the active patient's limit), and a device that dies mid-session is
// reported as a lost link with its exit code, not run on with stale telemetry.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string tmpPath(const std::string& name) { return "/tmp/phalanx_cmdpath_" + std::to_string(getpid()) + "_" + name; }

std::string mbpoll(unsigned port, std::vector<std::string> args) {
  std::vector<std::string> argv = {"/usr/bin/mbpoll", "-m", "tcp", "-p", std::to_string(port), "-0", "-1", "-o", "2"};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv);
  p.wait(10000);
  return p.stdoutText() + p.stderrText();
}

unsigned modbusPort(Process& daemon) {
  const std::regex serving("modbus: serving on 127\\.0\\.0\\.1:([0-9]+)");
  for (int i = 0; i < 200; ++i) {
    std::smatch m;
    const std::string err = daemon.stderrText();
    if (std::regex_search(err, m, serving)) return static_cast<unsigned>(std::stoul(m[1]));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return 0;
}

/// Column `name` of a CSV file written by --record, every row.
std::vector<double> csvColumn(const std::string& path, const std::string& name) {
  std::ifstream f(path);
  std::string line;
  std::getline(f, line);
  std::stringstream hs(line);
  std::string cell;
  int idx = -1;
  for (int i = 0; std::getline(hs, cell, ','); ++i) {
    if (cell == name) idx = i;
  }
  std::vector<double> v;
  if (idx < 0) return v;
  while (std::getline(f, line)) {
    std::stringstream rs(line);
    for (int i = 0; std::getline(rs, cell, ','); ++i) {
      if (i == idx) v.push_back(std::stod(cell));
    }
  }
  return v;
}

/// The first child process of pid (the spawned firmware-sim), 0 if none yet.
pid_t childOf(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/task/" + std::to_string(pid) + "/children");
  pid_t c = 0;
  f >> c;
  return c;
}

}  // namespace

// Before the limits stage a Modbus write went around the patient's limit: 1935 cycles at 6 N under a 1 N profile.
TEST(CommandPath, AModbusWriteIsHeldToTheActivePatientsLimit) {
  if (access("/usr/bin/mbpoll", X_OK) != 0) GTEST_SKIP() << "mbpoll is not installed (tools/setup.sh installs it)";
  // A profile is named after its patient: <dir>/limit-1n.yaml.
  char dir[] = "/tmp/phalanx_cmdpath_XXXXXX";
  ASSERT_NE(mkdtemp(dir), nullptr);
  const std::string profile = std::string(dir) + "/limit-1n.yaml", cfg = tmpPath("cfg.yaml"), csv = tmpPath("rec.csv");
  {
    std::ofstream p(profile);
    p << "version: 1\npatient: limit-1n\ndevice: glove5\nsize: M\nhandedness: left\n"
      << "limits:\n  effort_max:\n    default: 1.0\n";
    std::ofstream c(cfg);
    c << "version: 1\ndevice: sim:glove5\nseconds: 30\nrealtime: {enabled: false}\n"
      << "modbus:\n  enabled: true\n  port: 0\n  writes_enabled: true\n  command_timeout_ms: 5000\n";
  }
  Process daemon({binPath("phalanxd"), "--config", cfg, "--profile", profile, "--scenario", "still", "--scene", "none", "--record", csv,
                  "--json"});
  const unsigned port = modbusPort(daemon);
  ASSERT_NE(port, 0u) << daemon.stderrText();
  // 6 N on the index finger (setpoint 1: registers 4-5), then Modbus control in setpoint mode.
  std::string r = mbpoll(port, {"-B", "-t", "4:float", "-r", "4", "127.0.0.1", "6.0"});
  ASSERT_NE(r.find("Written 1 references"), std::string::npos) << r;
  r = mbpoll(port, {"-t", "4", "-r", "0", "127.0.0.1", "1", "2"});
  ASSERT_NE(r.find("Written 2 references"), std::string::npos) << r;
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  daemon.signal(SIGINT);
  ASSERT_EQ(daemon.wait(20000), 0) << daemon.stderrText();
  const auto j = nlohmann::json::parse(daemon.stdoutText(), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << daemon.stdoutText();
  EXPECT_GT(j["command_sources"]["modbus"].get<int>(), 100) << j.dump(2);
  EXPECT_GT(j["commands"]["limited_by_patient_limits"].get<int>(), 100) << j.dump(2);
  const std::vector<double> sp = csvColumn(csv, "setpoint_index");
  ASSERT_GT(sp.size(), 100u);
  double peak = 0.0;
  for (double v : sp) peak = std::fmax(peak, std::fabs(v));
  EXPECT_LE(peak, 1.0 + 1e-5) << "a setpoint beyond the patient's 1 N limit reached the device";
  EXPECT_GT(peak, 0.99) << "the Modbus write never commanded (the test would pass vacuously)";
  unlink(profile.c_str());
  rmdir(dir);
  unlink(cfg.c_str());
  unlink(csv.c_str());
}

// Before: kill -9 of the spawned firmware-sim left phalanxd running on stale telemetry, exit 0.
TEST(CommandPath, ASimulatedDeviceThatDiesEndsTheSessionAsALostLink) {
  Process daemon({binPath("phalanxd"), "--device", "sim:glove5", "--seconds", "30", "--no-realtime", "--json"});
  // Wait for the loop (the firmware-sim child exists and telemetry flows), then kill the device.
  pid_t sim = 0;
  for (int i = 0; i < 200 && sim == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    sim = childOf(daemon.pid());
  }
  ASSERT_NE(sim, 0) << daemon.stderrText();
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  kill(sim, SIGKILL);
  const int rc = daemon.wait(20000);
  ASSERT_NE(rc, INT_MIN) << "phalanxd ran on after its device died";
  EXPECT_EQ(rc, 6) << daemon.stderrText();
  const auto j = nlohmann::json::parse(daemon.stdoutText(), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << daemon.stdoutText();
  EXPECT_NE(j.value("link_error", "").find("simulated firmware"), std::string::npos) << j.dump(2);
  // Bounded by the telemetry timeout (500 ms = 500 cycles) at most, whatever noticed first.
  EXPECT_LE(j["telemetry"]["cycles_without_new_telemetry"].get<int>(), 600) << j.dump(2);
}

// Before: a positive length shorter than one period rounded to 0 cycles, which means "until stopped".
TEST(CommandPath, ASessionShorterThanOnePeriodIsRefused) {
  Process daemon({binPath("phalanxd"), "--device", "sim:glove5", "--seconds", "0.0004", "--no-realtime"});
  EXPECT_EQ(daemon.wait(20000), 2);
  EXPECT_NE(daemon.stderrText().find("seconds"), std::string::npos) << daemon.stderrText();
}

// Issue #20: the cycle locked to the device falls back to the timer when frames stop (the firmware-sim stopped
// with SIGSTOP): commands keep flowing on the period, stale cycles are counted, and the telemetry timeout still
// ends the session as a lost link.
TEST(CommandPath, WhenFramesStopTheLockedCycleFallsBackToTheTimerAndTheTelemetryTimeoutStillEndsIt) {
  Process daemon({binPath("phalanxd"), "--device", "sim:glove5", "--seconds", "30", "--no-realtime", "--json",
                  "--telemetry-timeout-ms", "300", "--cycle", "telemetry"});
  pid_t sim = 0;
  for (int i = 0; i < 200 && sim == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    sim = childOf(daemon.pid());
  }
  ASSERT_NE(sim, 0) << daemon.stderrText();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  kill(sim, SIGSTOP);
  const int rc = daemon.wait(20000);
  kill(sim, SIGCONT);
  ASSERT_NE(rc, INT_MIN) << "phalanxd ran on after its device stopped answering";
  EXPECT_EQ(rc, 6) << daemon.stderrText();
  const auto j = nlohmann::json::parse(daemon.stdoutText(), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << daemon.stdoutText();
  EXPECT_NE(j.value("link_error", "").find("no telemetry"), std::string::npos) << j.dump(2);
  EXPECT_EQ(j["cycle"]["mode"], "telemetry");
  // 300 ms of silence is about 300 timer-started cycles; 20 leaves room for a starved test machine.
  EXPECT_GE(j["cycle"]["started_by_timer"].get<int>(), 20) << j.dump(2);
  EXPECT_GE(j["telemetry"]["cycles_without_new_telemetry"].get<int>(), 20) << j.dump(2);
  EXPECT_EQ(j["cycle"]["started_by_telemetry"].get<int>() + j["cycle"]["started_by_timer"].get<int>(),
            j["cycles"].get<int>());
}
