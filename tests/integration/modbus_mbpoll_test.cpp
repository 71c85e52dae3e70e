// phalanxd's Modbus server read and written by an independent client: Debian's mbpoll (tools/setup.sh).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

bool haveMbpoll() { return access("/usr/bin/mbpoll", X_OK) == 0; }

struct Mbpoll {
  int status = INT_MIN;
  std::string out;  // stdout + stderr
};

Mbpoll mbpoll(unsigned port, std::vector<std::string> args) {
  std::vector<std::string> argv = {"/usr/bin/mbpoll", "-m", "tcp", "-p", std::to_string(port), "-0", "-1", "-o", "2"};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv);
  Mbpoll r;
  r.status = p.wait(10000);
  r.out = p.stdoutText() + p.stderrText();
  return r;
}

/// phalanxd on sim:sea_finger with the Modbus server on a free port; returns the port (0 on failure).
unsigned startDaemon(std::unique_ptr<Process>& daemon, bool writes, const std::string& cfg_path) {
  std::ofstream cfg(cfg_path);
  cfg << "version: 1\ndevice: sim:sea_finger\nseconds: 30\nrealtime: {enabled: false}\n"
      << "modbus:\n  enabled: true\n  port: 0\n  writes_enabled: " << (writes ? "true" : "false")
      << "\n  setpoint_limit: 0.3\n  command_timeout_ms: 5000\n";
  cfg.close();
  daemon = std::make_unique<Process>(std::vector<std::string>{binPath("phalanxd"), "--config", cfg_path, "--json"});
  const std::regex serving("modbus: serving on 127\\.0\\.0\\.1:([0-9]+)");
  for (int i = 0; i < 100; ++i) {
    std::smatch m;
    const std::string err = daemon->stderrText();
    if (std::regex_search(err, m, serving)) return static_cast<unsigned>(std::stoul(m[1]));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return 0;
}

}  // namespace

TEST(ModbusMbpoll, ReadsTheMapAndWritesWithinLimitsAndGetsExceptionsOtherwise) {
  if (!haveMbpoll()) GTEST_SKIP() << "mbpoll is not installed (tools/setup.sh installs it)";
  std::unique_ptr<Process> daemon;
  const unsigned port = startDaemon(daemon, true, "/tmp/phalanx_modbus_rw_" + std::to_string(getpid()) + ".yaml");
  ASSERT_NE(port, 0u) << daemon->stderrText();

  // Map version 1, device type 2 (sea_finger), loop running, 13 samples, 2 setpoints, writes enabled.
  Mbpoll r = mbpoll(port, {"-t", "3", "-r", "0", "-c", "20", "127.0.0.1"});
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("[0]: \t1\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[1]: \t2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[2]: \t1\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[17]: \t13\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[18]: \t2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[19]: \t1\n"), std::string::npos) << r.out;
  // The active setpoint limit as a float.
  r = mbpoll(port, {"-B", "-t", "3:float", "-r", "26", "127.0.0.1"});
  EXPECT_NE(r.out.find("[26]: \t0.3"), std::string::npos) << r.out;

  // Setpoint 0.2 N·m on SEA 0, then hand control to Modbus in setpoint mode.
  r = mbpoll(port, {"-B", "-t", "4:float", "-r", "2", "127.0.0.1", "0.2"});
  EXPECT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("Written 1 references"), std::string::npos) << r.out;
  r = mbpoll(port, {"-t", "4", "-r", "0", "127.0.0.1", "1", "2"});
  EXPECT_NE(r.out.find("Written 2 references"), std::string::npos) << r.out;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // The loop now sends it: control source 1, device mode 2 (setpoint), setpoint sent 0.2.
  r = mbpoll(port, {"-t", "3", "-r", "3", "-c", "4", "127.0.0.1"});
  EXPECT_NE(r.out.find("[3]: \t2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("[6]: \t1\n"), std::string::npos) << r.out;
  r = mbpoll(port, {"-B", "-t", "3:float", "-r", "96", "127.0.0.1"});
  EXPECT_NE(r.out.find("[96]: \t0.2"), std::string::npos) << r.out;

  // Beyond the limit, not a mode, outside the maps: Modbus exceptions, and nothing changes.
  r = mbpoll(port, {"-B", "-t", "4:float", "-r", "2", "127.0.0.1", "0.5"});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("Illegal data value"), std::string::npos) << r.out;
  r = mbpoll(port, {"-t", "4", "-r", "1", "127.0.0.1", "9"});
  EXPECT_NE(r.out.find("Illegal data value"), std::string::npos) << r.out;
  r = mbpoll(port, {"-t", "3", "-r", "200", "-c", "2", "127.0.0.1"});
  EXPECT_NE(r.out.find("Illegal data address"), std::string::npos) << r.out;
  r = mbpoll(port, {"-t", "4", "-r", "40", "127.0.0.1", "1"});
  EXPECT_NE(r.out.find("Illegal data address"), std::string::npos) << r.out;
  r = mbpoll(port, {"-B", "-t", "3:float", "-r", "96", "127.0.0.1"});
  EXPECT_NE(r.out.find("[96]: \t0.2"), std::string::npos) << "a rejected write changed the setpoint: " << r.out;

  // Back to the controller; the daemon ends cleanly and reports the traffic.
  r = mbpoll(port, {"-t", "4", "-r", "0", "127.0.0.1", "0"});
  EXPECT_EQ(r.status, 0) << r.out;
  daemon->signal(SIGINT);
  EXPECT_EQ(daemon->wait(10000), 0) << daemon->stderrText();
  const auto j = nlohmann::json::parse(daemon->stdoutText(), nullptr, false);
  ASSERT_FALSE(j.is_discarded()) << daemon->stdoutText();
  EXPECT_EQ(j["modbus"]["writes_accepted"].get<int>(), 3);
  EXPECT_GE(j["modbus"]["exceptions"].get<int>(), 4);
  EXPECT_GT(j["modbus"]["cycles_under_modbus_control"].get<int>(), 100);
}

TEST(ModbusMbpoll, ReadOnlyByDefaultConfigurationRejectsWrites) {
  if (!haveMbpoll()) GTEST_SKIP() << "mbpoll is not installed (tools/setup.sh installs it)";
  std::unique_ptr<Process> daemon;
  const unsigned port = startDaemon(daemon, false, "/tmp/phalanx_modbus_ro_" + std::to_string(getpid()) + ".yaml");
  ASSERT_NE(port, 0u) << daemon->stderrText();
  Mbpoll r = mbpoll(port, {"-t", "4", "-r", "0", "127.0.0.1", "1"});
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find("Illegal function"), std::string::npos) << r.out;
  r = mbpoll(port, {"-t", "4", "-r", "0", "-c", "2", "127.0.0.1"});
  EXPECT_EQ(r.status, 0) << "holding registers stay readable: " << r.out;
  daemon->signal(SIGINT);
  EXPECT_EQ(daemon->wait(10000), 0) << daemon->stderrText();
}
