// The `modbus` key of phalanxd's configuration, the shipped config file and the shipped bench plans.
#include <gtest/gtest.h>

#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/config.h"

using phalanx::host::RunOptions;

namespace {
std::string repoPath(const std::string& rel) { return std::string(PHALANX_SOURCE_DIR) + "/" + rel; }
}  // namespace

TEST(ModbusConfig, OffAndLoopbackReadOnlyByDefault) {
  RunOptions opt;
  EXPECT_FALSE(opt.modbus.enabled);
  EXPECT_EQ(opt.modbus.address, "127.0.0.1");
  EXPECT_FALSE(opt.modbus.writes_enabled);
  ASSERT_EQ(phalanx::host::loadConfigText("modbus: {enabled: true}\n", "t", opt), "");
  EXPECT_TRUE(opt.modbus.enabled);
  EXPECT_EQ(opt.modbus.address, "127.0.0.1");
  EXPECT_FALSE(opt.modbus.writes_enabled);
}

TEST(ModbusConfig, KeysAreReadAndBadValuesNamed) {
  RunOptions opt;
  ASSERT_EQ(phalanx::host::loadConfigText(
                "modbus: {enabled: true, address: 0.0.0.0, port: 5020, writes_enabled: true, setpoint_limit: 0.2,"
                " max_clients: 8, command_timeout_ms: 250}\n",
                "t", opt),
            "");
  EXPECT_EQ(opt.modbus.port, 5020u);
  EXPECT_EQ(opt.modbus.address, "0.0.0.0");
  EXPECT_DOUBLE_EQ(opt.modbus.setpoint_limit, 0.2);
  EXPECT_EQ(opt.modbus.max_clients, 8u);
  EXPECT_EQ(opt.modbus.command_timeout_ms, 250u);
  RunOptions o2;
  EXPECT_NE(phalanx::host::loadConfigText("modbus: {writes: true}\n", "t", o2).find("modbus.writes: unknown key"),
            std::string::npos);
  EXPECT_NE(phalanx::host::loadConfigText("modbus: {port: 70000}\n", "t", o2).find("modbus.port"), std::string::npos);
  EXPECT_NE(phalanx::host::loadConfigText("modbus: {address: localhost}\n", "t", o2).find("modbus.address"),
            std::string::npos);
  EXPECT_NE(phalanx::host::loadConfigText("modbus: {setpoint_limit: -1}\n", "t", o2).find("modbus.setpoint_limit"),
            std::string::npos);
  EXPECT_NE(phalanx::host::loadConfigText("modbus: {max_clients: 0}\n", "t", o2).find("modbus.max_clients"),
            std::string::npos);
  EXPECT_FALSE(o2.modbus.enabled) << "a rejected file changes nothing";
}

TEST(ModbusConfig, ShippedConfigurationLoadsWithModbusOff) {
  RunOptions opt;
  ASSERT_EQ(phalanx::host::loadConfigFile(repoPath("config/phalanxd.yaml"), opt), "");
  EXPECT_FALSE(opt.modbus.enabled);
}

TEST(ModbusConfig, ShippedBenchPlansLoad) {
  for (const char* plan : {"bench/sea-rig.yaml", "bench/glove-free-motion.yaml", "bench/glove-grasp.yaml", "bench/pen-wall.yaml"}) {
    phalanx::host::benchrun::Plan p;
    EXPECT_EQ(phalanx::host::benchrun::loadPlanFile(repoPath(plan), p), "") << plan;
    EXPECT_FALSE(p.steps.empty()) << plan;
  }
}
