#include <gtest/gtest.h>

#include "phalanx/host/config.h"

using phalanx::host::loadConfigText;
using phalanx::host::RunOptions;

TEST(Config, AppliesEveryKeyOfAValidFile) {
  RunOptions o;
  const std::string err = loadConfigText(
      "version: 1\ndevice: serial:/dev/ttyACM0@921600\nseconds: 5\nrate_hz: 500\ncommand_timeout_ms: 30\n"
      "realtime: {enabled: false, priority: 50}\nrecord: out.csv\nseed: 9\nclear_faults: false\n"
      "glove: {scene: wall, scenario: random, mode: transparent}\n",
      "test.yaml", o);
  ASSERT_EQ(err, "");
  EXPECT_EQ(o.device, "serial:/dev/ttyACM0@921600");
  EXPECT_EQ(o.seconds, 5.0);
  EXPECT_EQ(o.rate_hz, 500u);
  EXPECT_EQ(o.command_timeout_ms, 30u);
  EXPECT_FALSE(o.realtime);
  EXPECT_EQ(o.rt_priority, 50);
  EXPECT_EQ(o.record_csv, "out.csv");
  EXPECT_EQ(o.seed, 9u);
  EXPECT_FALSE(o.clear_faults);
  EXPECT_EQ(o.scene, "wall");
  EXPECT_EQ(o.scenario, "random");
  EXPECT_EQ(o.mode, "transparent");
}

TEST(Config, NamesAnUnknownKey) {
  RunOptions o;
  const std::string err = loadConfigText("devise: sim:glove5\n", "x.yaml", o);
  EXPECT_NE(err.find("x.yaml: devise: unknown key"), std::string::npos) << err;
}

TEST(Config, NamesAWrongType) {
  RunOptions o;
  const std::string err = loadConfigText("rate_hz: fast\n", "x.yaml", o);
  EXPECT_NE(err.find("rate_hz: expected a positive integer"), std::string::npos) << err;
}

TEST(Config, NamesAnOutOfRangeValueAndChangesNothing) {
  RunOptions o;
  const std::string before = o.device;
  const std::string err = loadConfigText("device: serial:/dev/null\nrate_hz: 50000\n", "x.yaml", o);
  EXPECT_NE(err.find("rate_hz: must be in"), std::string::npos) << err;
  EXPECT_EQ(o.device, before) << "a rejected file must not be half-applied";
}

TEST(Config, RejectsATimeoutShorterThanTwoPeriods) {
  RunOptions o;
  const std::string err = loadConfigText("rate_hz: 500\ncommand_timeout_ms: 3\n", "x.yaml", o);
  EXPECT_NE(err.find("command_timeout_ms"), std::string::npos) << err;
}

TEST(Config, ReportsYamlSyntaxErrorsWithTheLine) {
  RunOptions o;
  const std::string err = loadConfigText("device: [unclosed\n", "x.yaml", o);
  EXPECT_NE(err.find("YAML syntax error at line"), std::string::npos) << err;
}

TEST(Config, RejectsAnUnknownDeviceAndScenario) {
  RunOptions o;
  EXPECT_NE(loadConfigText("device: sim:toaster\n", "x", o).find("unknown simulated device"), std::string::npos);
  EXPECT_NE(loadConfigText("glove: {scenario: dance}\n", "x", o).find("scenario"), std::string::npos);
  EXPECT_NE(loadConfigText("version: 2\n", "x", o).find("version"), std::string::npos);
}

TEST(Config, RefusesARepeatedKeyInsteadOfKeepingTheFirst) {
  RunOptions o;
  const std::string err = loadConfigText("rate_hz: 100\nrate_hz: 4000\n", "x.yaml", o);
  EXPECT_EQ(err, "x.yaml: rate_hz: duplicate key (line 2; first at line 1)");
  EXPECT_EQ(o.rate_hz, RunOptions{}.rate_hz);  // nothing applied
  const std::string nested = loadConfigText("modbus:\n  enabled: false\n  port: 1502\n  port: 502\n", "x.yaml", o);
  EXPECT_NE(nested.find("x.yaml: modbus.port: duplicate key"), std::string::npos) << nested;
}

TEST(Config, RefusesAPositiveLengthShorterThanOneHostPeriod) {
  RunOptions o;
  // 0.0004 s at 1 kHz rounds to zero cycles, which the runner reads as "until stopped".
  const std::string err = loadConfigText("seconds: 0.0004\n", "x.yaml", o);
  EXPECT_NE(err.find("x.yaml: seconds: 0.0004 s is shorter than one host period (0.001 s at 1000 Hz)"),
            std::string::npos)
      << err;
  EXPECT_NE(loadConfigText("seconds: 0.0008\nrate_hz: 1000\n", "x.yaml", o), "");
  EXPECT_EQ(loadConfigText("seconds: 0.0008\nrate_hz: 2000\n", "x.yaml", o), "");  // 1.6 periods: 2 cycles
  EXPECT_EQ(loadConfigText("seconds: 0.001\n", "x.yaml", o), "");                   // exactly one period
  EXPECT_EQ(loadConfigText("seconds: 0\n", "x.yaml", o), "");                       // until stopped
  EXPECT_EQ(phalanx::host::checkSessionLength(0.0025, 400), "");
  EXPECT_NE(phalanx::host::checkSessionLength(0.0024, 400), "");
}
