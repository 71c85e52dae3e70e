// firmware-sim and the host daemon as separate processes over a real pseudo-terminal.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <thread>
#include <utility>

#include "phalanx/host/session.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/realtime.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string startFirmware(Process& fw) {
  const std::string line = fw.readStdoutLine(5000);
  EXPECT_EQ(line.rfind("PTY ", 0), 0u) << "firmware-sim said: " << line << fw.stderrText();
  return line.size() > 4 ? line.substr(4) : "";
}

}  // namespace

TEST(PtySession, QuietLinkRunsSeveralSecondsAt1kHzWithZeroLostFrames) {
  // The link under test, with the hand moving and the glove in transparent mode (grasp-force quality is the
  // closed-loop suites' business, not this one's).
  Process run({binPath("phalanx"), "run", "--device", "sim:glove5", "--seconds", "4", "--json", "--no-realtime",
               "--mode", "transparent", "--scenario", "close-open"});
  ASSERT_EQ(run.wait(30000), 0) << run.stderrText();
  const auto j = nlohmann::json::parse(run.stdoutText());
  EXPECT_EQ(j["device_type"], "glove5");
  EXPECT_GE(j["cycles"].get<int>(), 3990);
  EXPECT_EQ(j["telemetry"]["lost"].get<int>(), 0);
  EXPECT_GE(j["telemetry"]["received"].get<int>(), 3900);
  EXPECT_EQ(j["commands"]["lost_seen_by_device"].get<int>(), 0);
  EXPECT_EQ(j["commands"]["rejected_by_device"].get<int>(), 0);
  EXPECT_EQ(j["host_rx_errors"]["crc"].get<int>(), 0);
  EXPECT_EQ(j["host_rx_errors"]["framing"].get<int>(), 0);
  EXPECT_GE(j["round_trip"]["count"].get<int>(), 3000);
  EXPECT_EQ(j["faults_seen"], "none");
  EXPECT_EQ(j["final_mode"], "safe") << "the daemon must leave the device in its safe state";
  // The default cycle starts on a frame's arrival, the timer as fallback (docs/session-runner.md "The cycle's
  // clock"); a command is applied one device tick (1000 us of device time) after its sample at the earliest.
  EXPECT_EQ(j["cycle"]["mode"], "telemetry");
  EXPECT_GT(j["cycle"]["started_by_telemetry"].get<int>(), 0) << j["cycle"].dump(2);
  EXPECT_EQ(j["cycle"]["started_by_telemetry"].get<int>() + j["cycle"]["started_by_timer"].get<int>(),
            j["cycles"].get<int>());
  EXPECT_GE(j["sensor_to_actuation"]["count"].get<int>(), 3000);
  EXPECT_GE(j["sensor_to_actuation"]["p50_us"].get<double>(), 1000.0);
}

// Issue #20: `--cycle timer` is the period timer alone: every cycle started by it.
TEST(PtySession, TheTimerCycleStartsEveryCycleByTheTimer) {
  Process run({binPath("phalanx"), "run", "--device", "sim:glove5", "--seconds", "1", "--json", "--no-realtime",
               "--mode", "transparent", "--scenario", "still", "--cycle", "timer"});
  ASSERT_EQ(run.wait(30000), 0) << run.stderrText();
  const auto j = nlohmann::json::parse(run.stdoutText());
  EXPECT_EQ(j["cycle"]["mode"], "timer");
  EXPECT_EQ(j["cycle"]["started_by_telemetry"].get<int>(), 0);
  EXPECT_EQ(j["cycle"]["started_by_timer"].get<int>(), j["cycles"].get<int>());
  EXPECT_EQ(j["cycles"].get<int>(), 1000);
  EXPECT_EQ(j["telemetry"]["lost"].get<int>(), 0);
  EXPECT_GE(j["sensor_to_actuation"]["p50_us"].get<double>(), 1000.0);
  EXPECT_EQ(j["faults_seen"], "none");
}

TEST(PtySession, KillNineOfTheDaemonDrivesTheFirmwareSafeWithinTwoTicks) {
  Process fw({binPath("firmware-sim"), "--device", "glove5", "--scenario", "still", "--seconds", "60"});
  const std::string pty = startFirmware(fw);
  ASSERT_FALSE(pty.empty());
  Process daemon({binPath("phalanxd"), "--device", "serial:" + pty, "--mode", "transparent", "--no-realtime"});
  // Let the session run with the motors driven, then kill the daemon without any chance to clean up.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_EQ(daemon.wait(0), INT_MIN) << "daemon exited early: " << daemon.stderrText();
  const size_t log_before_kill = fw.stderrText().size();
  daemon.signal(SIGKILL);
  daemon.wait(5000);

  const std::regex safe_re(R"(SAFE t_us=(\d+) deadline_us=(\d+) period_us=(\d+) faults=0x([0-9a-f]+))");
  std::smatch m;
  std::string log;
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < end) {
    log = fw.stderrText().substr(log_before_kill);
    if (std::regex_search(log, m, safe_re)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_FALSE(m.empty()) << "firmware never reported its outputs going safe:\n" << log;
  const long t_us = std::stol(m[1]);
  const long deadline_us = std::stol(m[2]);
  const long period_us = std::stol(m[3]);
  const unsigned faults = static_cast<unsigned>(std::stoul(m[4], nullptr, 16));
  EXPECT_GT(t_us, deadline_us) << "outputs went safe before the command expired: not the watchdog";
  EXPECT_LE(t_us - deadline_us, 2 * period_us) << "safe state later than two ticks after the timeout";
  EXPECT_TRUE(faults & phalanx::protocol::fault::kCommandTimeout);
  fw.signal(SIGTERM);
  EXPECT_EQ(fw.wait(5000), 0);
}

TEST(PtySession, InjectedLineNoiseIsRejectedCountedAndTheSessionGoesOn) {
  using namespace phalanx;
  Process fw({binPath("firmware-sim"), "--device", "glove5", "--scenario", "still", "--seconds", "60"});
  const std::string pty = startFirmware(fw);
  ASSERT_FALSE(pty.empty());
  linux_hal::SerialLink link;
  ASSERT_EQ(link.open(pty, 0), "");
  host::HostSession session(link);
  session.sendHello(77, protocol::DeviceType::kGlove5);
  link.flush();
  for (int i = 0; i < 500 && session.handshake() == host::HandshakeResult::kPending; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    session.poll(linux_hal::monotonicNs());
  }
  ASSERT_EQ(session.handshake(), host::HandshakeResult::kOk) << session.handshakeError();

  std::mt19937 rng(3);
  protocol::Command cmd;
  cmd.mode = protocol::Mode::kTransparent;
  cmd.channel_count = 5;
  cmd.timeout_ms = 50;
  int noise_bursts = 0;
  linux_hal::PeriodicTimer timer(1000000);
  for (int cycle = 0; cycle < 2000; ++cycle) {
    timer.wait();
    session.poll(linux_hal::monotonicNs());
    session.sendCommand(cmd, linux_hal::monotonicNs());
    if (cycle % 20 == 10) {
      // A burst of line noise between two frames, terminated by a delimiter like a glitch would be.
      uint8_t noise[24];
      for (auto& b : noise) b = static_cast<uint8_t>(1 + rng() % 255);
      noise[23] = 0;
      link.write(noise, sizeof noise);
      ++noise_bursts;
    }
    link.flush();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  session.poll(linux_hal::monotonicNs());
  EXPECT_EQ(session.stats().device_rx_errors, static_cast<uint64_t>(noise_bursts))
      << "every noise burst must be rejected and counted, and no valid frame lost with it";
  EXPECT_EQ(session.stats().device_cmd_lost, 0u);
  EXPECT_EQ(session.latest().fault_bits, 0) << "noise between valid frames must not fault the device";
  EXPECT_EQ(session.latest().mode, protocol::Mode::kTransparent);
  EXPECT_EQ(session.stats().telemetry_lost, 0u);
  fw.signal(SIGTERM);
  fw.wait(5000);
}

TEST(Daemon, RefusesABadConfigurationNamingTheKey) {
  char path[] = "/tmp/phalanx-bad-XXXXXX.yaml";
  const int fd = mkstemps(path, 5);
  ASSERT_GE(fd, 0);
  const std::string text = "device: sim:glove5\nrate_hz: 99999\n";
  ASSERT_EQ(write(fd, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  close(fd);
  Process d({binPath("phalanxd"), "--config", path});
  EXPECT_EQ(d.wait(10000), 2);
  EXPECT_NE(d.stderrText().find("rate_hz"), std::string::npos) << d.stderrText();
  unlink(path);
}

TEST(Daemon, ReportsAMissingSerialDeviceClearly) {
  Process d({binPath("phalanxd"), "--device", "serial:/dev/does-not-exist", "--no-realtime"});
  EXPECT_EQ(d.wait(10000), 3);
  EXPECT_NE(d.stderrText().find("/dev/does-not-exist"), std::string::npos) << d.stderrText();
}

TEST(Daemon, ReportsADeviceThatNeverAnswersTheHandshake) {
  phalanx::linux_hal::PtyMaster silent;  // a tty nobody answers on
  ASSERT_EQ(silent.open(), "");
  Process d({binPath("phalanxd"), "--device", "serial:" + silent.slavePath(), "--no-realtime"});
  EXPECT_EQ(d.wait(10000), 4);
  EXPECT_NE(d.stderrText().find("handshake"), std::string::npos) << d.stderrText();
}

// Every simulated device the daemon offers answers its handshake (sim:sea_rig is the sea_finger firmware on the
// test-rig plant; it used to be expected as a pantograph and was refused).
TEST(Daemon, EverySimulatedDeviceCompletesItsHandshake) {
  for (const char* device : {"sim:glove5", "sim:sea_finger", "sim:sea_rig", "sim:pantograph"}) {
    Process d({binPath("phalanxd"), "--device", device, "--seconds", "0.5", "--no-realtime"});
    EXPECT_EQ(d.wait(20000), 0) << device << ": " << d.stderrText();
    EXPECT_EQ(d.stderrText().find("mismatch"), std::string::npos) << device << ": " << d.stderrText();
  }
}

// firmware-sim --device sea_rig answers as a sea_finger (the same firmware) and names its variant in the core
// parameter 0x0004, so a host can tell the rig from the exoskeleton on a finger.
TEST(PtySession, TheSeaRigAndTheSeaFingerTellTheirVariantApart) {
  using namespace phalanx;
  for (const auto& [device, variant] : {std::pair<const char*, uint8_t>{"sea_rig", protocol::variant::kSeaTestRig},
                                        std::pair<const char*, uint8_t>{"sea_finger", protocol::variant::kStandard}}) {
    Process fw({binPath("firmware-sim"), "--device", device, "--scenario", "still", "--seconds", "30"});
    const std::string pty = startFirmware(fw);
    ASSERT_FALSE(pty.empty());
    linux_hal::SerialLink link;
    ASSERT_EQ(link.open(pty, 0), "");
    host::HostSession session(link);
    session.sendHello(5, protocol::DeviceType::kSeaFinger);
    link.flush();
    for (int i = 0; i < 2500 && session.handshake() == host::HandshakeResult::kPending; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      session.poll(linux_hal::monotonicNs());
    }
    ASSERT_EQ(session.handshake(), host::HandshakeResult::kOk) << device << ": " << session.handshakeError();
    session.sendParamGet(protocol::core_param::kDeviceVariant);
    link.flush();
    for (int i = 0; i < 2500 && !session.lastParamValid(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      session.poll(linux_hal::monotonicNs());
    }
    ASSERT_TRUE(session.lastParamValid()) << device << ": no answer to ParamGet 0x0004";
    EXPECT_EQ(session.lastParam().status, protocol::ParamStatus::kOk) << device;
    EXPECT_EQ(session.lastParam().value, static_cast<float>(variant)) << device;
    fw.signal(SIGTERM);
    fw.wait(5000);
  }
}
