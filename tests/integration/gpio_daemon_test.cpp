// phalanxd with an e-stop line that cannot be opened (this machine, like any CI runner, has no such GPIO chip):
// the real libgpiod open fails, which counts as pressed - the daemon runs stopped, the device is never driven,
// resets are refused and the line is retried. The kernel-backed e-stop/enable/sync test is tests/vm/gpio_test.sh.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

TEST(GpioDaemon, AnEstopLineThatCannotBeOpenedKeepsTheDeviceSafeAndRefusesResets) {
  Process fw({binPath("firmware-sim"), "--device", "glove5", "--scenario", "still", "--seconds", "30"});
  const std::string line = fw.readStdoutLine(5000);
  ASSERT_EQ(line.rfind("PTY ", 0), 0u) << fw.stderrText();
  Process daemon({binPath("phalanxd"), "--device", "serial:" + line.substr(4), "--mode", "transparent",
                  "--no-realtime", "--seconds", "2.5", "--json", "--estop", "no-such-gpio-chip-phalanx:0"});
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  daemon.signal(SIGUSR1);  // an explicit reset: refused, the line is lost
  ASSERT_EQ(daemon.wait(30000), 0) << daemon.stderrText();
  fw.signal(SIGTERM);
  fw.wait(5000);
  const auto j = nlohmann::json::parse(daemon.stdoutText());
  const auto& e = j["gpio"]["estop"];
  EXPECT_EQ(e["state"], "stopped");
  EXPECT_EQ(e["cause"], "estop-line-lost");
  EXPECT_FALSE(e["line_ok"].get<bool>());
  EXPECT_NE(e["open_error"].get<std::string>(), "");
  EXPECT_EQ(e["resets"].get<int>(), 0);
  EXPECT_GE(e["resets_refused"].get<int>(), 1);
  EXPECT_GE(e["reopen_attempts"].get<int>(), 1) << "the lost line is retried (once per second)";
  EXPECT_NE(daemon.stderrText().find("reset refused"), std::string::npos);
  EXPECT_EQ(j["final_mode"], "safe");
  // The device's power stage was never switched on: firmware-sim logs each on->off transition as SAFE.
  EXPECT_EQ(fw.stderrText().find("firmware-sim: SAFE"), std::string::npos) << fw.stderrText();
  EXPECT_GE(j["commands"]["sent"].get<int>(), 500) << "the loop kept commanding (safe) while stopped";
}
