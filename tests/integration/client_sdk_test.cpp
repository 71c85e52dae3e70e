// The client channel end to end through the real binaries: phalanxd (sim:glove5) serving libphalanx clients -
// the examples in examples/ - over its control socket and shared memory. Assertions come from the daemon's
// --record CSV (mode column: what the firmware reported) and its --json summary.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <vector>

#include "process.h"
#include "record_csv.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string tmpDir() {
  static const std::string d = "/tmp/phalanx_client_" + std::to_string(getpid());
  mkdir(d.c_str(), 0700);
  return d;
}
std::string tmpPath(const std::string& name) { return tmpDir() + "/" + name; }

using Csv = phalanx::test::RecordCsv;  // the --record CSV by column name (record_csv.h)
Csv readCsv(const std::string& path) { return phalanx::test::readRecordCsv(path); }

/// phalanxd on sim:glove5 with the client channel and a transparent built-in controller. The simulated hand
/// keeps "still" (a pull against a closing hand - the "grasp" scenario - saturates the motor and trips its current
/// limit when the machine is loaded and the simulated firmware starved: a device fault, which forces the client off,
/// not what these tests are about).
std::unique_ptr<Process> startDaemon(const std::string& sock, const std::string& csv, const std::string& seconds,
                                     const std::string& scenario = "still", const std::string& truth = "") {
  std::vector<std::string> args{binPath("phalanxd"), "--device", "sim:glove5", "--seconds", seconds, "--no-realtime",
                                "--mode", "transparent", "--scene", "none", "--scenario", scenario,
                                "--client-socket", sock, "--record", csv, "--json"};
  if (!truth.empty()) args.insert(args.end(), {"--sim-truth", truth});
  auto d = std::make_unique<Process>(args);
  for (int i = 0; i < 400; ++i) {
    if (d->stderrText().find("client: serving on") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  return d;
}

nlohmann::json finish(Process& daemon) {
  const int rc = daemon.wait(30000);
  EXPECT_EQ(rc, 0) << daemon.stderrText();
  auto j = nlohmann::json::parse(daemon.stdoutText(), nullptr, false);
  EXPECT_FALSE(j.is_discarded()) << daemon.stdoutText();
  return j;
}

/// The example's log: telemetry_seq → the forces it computed from that state.
std::multimap<int, double> readSpringLog(const std::string& path) {
  std::multimap<int, double> m;
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line)) {
    const auto comma = line.find(',');
    if (comma != std::string::npos) m.emplace(std::stoi(line.substr(0, comma)), std::stod(line.substr(comma + 1)));
  }
  return m;
}

constexpr double kGloveLimitN = 10.0;  // kGlove5Layout.setpoint_limit
// The tests' clients connect with a 250 ms deadline: they run without real-time priority beside other builds,
// and a stall of tens of ms is then ordinary (a shorter deadline would force them off before the test's point).
constexpr double kDeadlineS = 0.250;
constexpr int kDeadlineCycles = 250;  // at 1 kHz
const std::string kDeadlineMs = "250";

/// A starved firmware-sim (this machine runs builds beside the tests, without real-time priority) can latch a
/// current-limit fault; the daemon then forces the client off with cause device-fault - correct, but not the point
/// of the tests below, which then run again (at most kAttempts times).
bool deviceFaulted(const nlohmann::json& j) {
  for (const auto& r : j["client"]["force_off_records"]) {
    if (r["cause"] == "device-fault") return true;
  }
  return false;
}
constexpr int kAttempts = 3;

// How far the plant's true pad force may be from the glove's own measurement of it (GlovePlantParams, whose
// per-part errors are drawn clipped at 3 sigma): the gauge's gain error (3 x 2 %), its zero drift since the tare
// (3 x 0.012 N/K x 10 K x (1 - exp(-6 s / 120 s)) = 0.018 N within a 6 s session) and the tare's own noise
// (4 sigma of one sample: sqrt(0.56^2 + (0.67/2)^2) counts / 93.09 counts/N = 0.007 N; 0.028 N).
constexpr double kGaugeGain = 0.06, kGaugeDriftN = 0.018, kGaugeNoiseN = 0.007;
double gaugeBound(double force_N, double samples) {
  return kGaugeGain * std::fabs(force_N) + kGaugeDriftN + 4.0 * kGaugeNoiseN * (1.0 + 1.0 / std::sqrt(samples));
}

// The plant's truth against the force the client commanded, over 100-cycle windows of the commanded rows: the
// spring's command is as noisy as the Hall angles it comes from (k x 0.3 mm ~ 0.1 N from cycle to cycle), which no
// force loop follows, but the glove's loop is type 1 (the self-locking worm integrates duty; glove5_defaults.cpp),
// so a window's mean force is the window's mean command within the gauge's bound and the loop's lag behind the
// command's own change from the window before (from no force, for the first). The same truth against the telemetry's measured pad force, row by
// row, is within the gauge's bound (one sample's noise) in >= 99 % of the rows.
void checkAgainstTruth(const Csv& rec, const std::vector<size_t>& commanded_rows, const std::string& truth_path) {
  const phalanx::test::TruthCsv truth = phalanx::test::readTruthCsv(truth_path);
  constexpr size_t kWindow = 100;
  size_t joined = 0, measured_within = 0, windows = 0, windows_within = 0;
  // Before the first commanded row the device held no force (safe until the client's first command): the first
  // window's lag is the loop's rise from 0 to the command (under load that rise spans part of the window).
  double sum_cmd = 0, sum_truth = 0, previous_mean_cmd = 0.0, worst = 0;
  for (size_t i : commanded_rows) {
    size_t t = 0;
    if (!truth.find(rec.at("device_time_us", i), t)) continue;
    const double f_true = truth.at("truth_pad_force_index_N", t);
    ++joined;
    measured_within += std::fabs(f_true - rec.at("force_index_N", i)) <= gaugeBound(f_true, 1.0) ? 1 : 0;
    sum_cmd += rec.at("setpoint1", i);
    sum_truth += f_true;
    if (joined % kWindow != 0) continue;
    const double mean_cmd = sum_cmd / kWindow, mean_truth = sum_truth / kWindow;
    const double lag = std::fabs(mean_cmd - previous_mean_cmd);
    const double tolerance = gaugeBound(mean_cmd, kWindow) + lag;
    ++windows;
    windows_within += std::fabs(mean_truth - mean_cmd) <= tolerance ? 1 : 0;
    EXPECT_LE(std::fabs(mean_truth - mean_cmd), tolerance) << "window " << windows << ": command " << mean_cmd
                                                           << " N, true pad force " << mean_truth << " N";
    worst = std::fmax(worst, std::fabs(mean_truth - mean_cmd));
    previous_mean_cmd = mean_cmd;
    sum_cmd = sum_truth = 0;
  }
  std::printf("client command vs plant truth: %zu rows joined, measured within the gauge's bound in %zu; %zu of %zu windows "
              "within tolerance, worst |mean truth - mean command| %.4f N\n", joined, measured_within, windows_within,
              windows, worst);
  EXPECT_GE(joined, commanded_rows.size() * 9 / 10) << "the plant's truth is missing for the commanded rows";
  EXPECT_GE(windows, 10u);
  EXPECT_GE(static_cast<double>(measured_within), 0.99 * static_cast<double>(joined));
}

// The spring example renders f = k (p0 - p).n on the index finger; every cycle the client commanded, the pad force
// the daemon sent (setpoint1) is what the example computed from a state the daemon published in the cycles before
// (at most the deadline: until then a late client's last command is repeated) - within 1e-3 N: the daemon passes
// the client's float unchanged below the 10 N limit, the CSV prints 5 significant digits (≤ 5e-4 N below 10 N)
// and the example's log 9 (exact); beyond 10 N the limit is what is sent.
bool springForcesMatch(int attempt) {
  const std::string n = std::to_string(attempt);
  const std::string sock = tmpPath("spring" + n + ".sock"), csv = tmpPath("spring" + n + ".csv"),
                    log = tmpPath("spring" + n + ".log"), truth = tmpPath("spring" + n + ".truth.csv");
  auto daemon = startDaemon(sock, csv, "4", "still", truth);
  Process spring({binPath("glove_spring"), "--socket", sock, "--finger", "1", "--k", "300", "--offset", "0,-10",
                  "--seconds", "2", "--deadline-ms", kDeadlineMs, "--log", log});
  const int spring_rc = spring.wait(20000);
  const nlohmann::json j = finish(*daemon);
  if (deviceFaulted(j)) return false;
  EXPECT_EQ(spring_rc, 0) << spring.stdoutText() << spring.stderrText() << daemon->stderrText();
  const Csv rec = readCsv(csv);
  const std::multimap<int, double> computed = readSpringLog(log);
  EXPECT_GT(computed.size(), 1000u);
  size_t commanded = 0, matched = 0;
  std::vector<size_t> commanded_rows;
  double peak = 0.0;
  // Rows after the client's last command are the built-in controller's again (the client released): the mode
  // the firmware reports lags the command by one or two cycles, so those rows are cut by telemetry sequence.
  const int last_seq = computed.empty() ? 0 : computed.rbegin()->first;
  for (size_t i = kDeadlineCycles; i + 1 < rec.rows() && rec.at("seq", i) <= last_seq + 1; ++i) {
    // A row holds the telemetry the cycle read (the firmware's mode, answering earlier commands) and the command
    // it sent: the client commanded row i when the firmware still tracked setpoints after it.
    if (rec.at("mode", i) != 2 || rec.at("mode", i + 1) != 2) continue;
    ++commanded;
    commanded_rows.push_back(i);
    const double sent = rec.at("setpoint1", i);
    peak = std::fmax(peak, std::fabs(sent));
    bool found = false;
    for (size_t back = 1; back <= kDeadlineCycles && !found; ++back) {
      const auto range = computed.equal_range(static_cast<int>(rec.at("seq", i - back)));
      for (auto it = range.first; it != range.second && !found; ++it) {
        found = std::fabs(std::clamp(it->second, -kGloveLimitN, kGloveLimitN) - sent) <= 1e-3;
      }
    }
    if (found) {
      ++matched;
    } else {
      ADD_FAILURE() << "row " << i << " t=" << rec.at("t_s", i) << " sent " << sent;
    }
    for (int other : {0, 2, 3, 4}) EXPECT_EQ(rec.at("setpoint" + std::to_string(other), i), 0.0) << "row " << i;
  }
  EXPECT_GT(commanded, 1000u) << j.dump(2);
  EXPECT_EQ(matched, commanded) << "rows whose sent force is no force the example computed";
  // The pad-normal part of a 3 N pull is 0.4-1 N here, depending on the still finger's posture: 200x the 1e-3 N match.
  EXPECT_GT(peak, 0.2) << "the spring never pulled (the comparison would be vacuous)";
  checkAgainstTruth(rec, commanded_rows, truth);
  EXPECT_EQ(j["client"]["cycles_commanded"].get<uint64_t>(), j["command_sources"]["client"].get<uint64_t>());
  EXPECT_EQ(j["client"]["releases"], 1) << j.dump(2);
  return true;
}

// kill -9 mid-render: the daemon sends the safe state in the first cycle past the client's deadline and the
// firmware reports safe within two further cycles of new telemetry; the cause is in the summary.
bool killedClientGoesSafe(int attempt) {
  const std::string n = std::to_string(attempt);
  const std::string sock = tmpPath("kill" + n + ".sock"), csv = tmpPath("kill" + n + ".csv");
  auto daemon = startDaemon(sock, csv, "4");
  Process spring({binPath("glove_spring"), "--socket", sock, "--finger", "1", "--k", "300", "--offset", "0,-10",
                  "--deadline-ms", kDeadlineMs});
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  spring.signal(SIGKILL);
  spring.wait(5000);
  const nlohmann::json j = finish(*daemon);
  if (deviceFaulted(j)) return false;
  const nlohmann::json& offs = j["client"]["force_off_records"];
  EXPECT_EQ(offs.size(), 1u) << j.dump(2);
  if (offs.size() != 1u) return true;
  EXPECT_EQ(offs[0]["cause"], "client-timeout");
  EXPECT_EQ(j["client"]["disconnects_without_release"], 1);
  const Csv rec = readCsv(csv);
  const size_t last = rec.rowAt(offs[0]["last_command_at_s"].get<double>());
  const size_t forced = rec.rowAt(offs[0]["at_s"].get<double>());
  EXPECT_LT(forced + 3, rec.rows());
  if (forced + 3 >= rec.rows()) return true;
  EXPECT_EQ(rec.at("mode", last), 2) << "the client was not rendering when it was killed";
  // The daemon: the first cycle whose wake time is past the deadline, not later.
  EXPECT_GT(rec.at("t_s", forced) - rec.at("t_s", last), kDeadlineS);
  EXPECT_LE(rec.at("t_s", forced - 1) - rec.at("t_s", last), kDeadlineS);
  // The firmware: safe (mode 0) within two new telemetry frames after that cycle, and safe from then on.
  size_t fresh = 0, safe_row = 0;
  for (size_t i = forced + 1; i < rec.rows() && safe_row == 0; ++i) {
    if (rec.at("seq", i) != rec.at("seq", i - 1)) ++fresh;
    if (rec.at("mode", i) == 0) safe_row = i;
  }
  EXPECT_NE(safe_row, 0u) << "the device never reported safe";
  EXPECT_LE(fresh, 2u) << "device reported safe " << fresh << " telemetry frames after the forced cycle";
  for (size_t i = safe_row; i < rec.rows(); ++i) EXPECT_EQ(rec.at("mode", i), 0) << "row " << i;
  for (size_t i = forced; i < rec.rows(); ++i) EXPECT_EQ(rec.at("setpoint1", i), 0.0) << "row " << i;
  return true;
}

// One client commands a device: a second one is refused while the first holds it (counted, with the reason).
bool secondClientRefused(int attempt) {
  const std::string n = std::to_string(attempt);
  const std::string sock = tmpPath("busy" + n + ".sock"), csv = tmpPath("busy" + n + ".csv"),
                    truth = tmpPath("busy" + n + ".truth.csv");
  auto daemon = startDaemon(sock, csv, "3", "still", truth);
  Process first({binPath("glove_press"), sock, "1", "1", "2000", kDeadlineMs});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  Process second({binPath("glove_press"), sock, "1", "5", "100", kDeadlineMs});
  const int second_rc = second.wait(10000);
  const int first_rc = first.wait(20000);
  const nlohmann::json j = finish(*daemon);
  if (deviceFaulted(j)) return false;
  EXPECT_EQ(second_rc, 3);
  EXPECT_NE(second.stderrText().find("another client"), std::string::npos) << second.stderrText();
  EXPECT_EQ(first_rc, 0) << first.stdoutText() << first.stderrText();
  EXPECT_EQ(j["client"]["refused_busy"], 1) << j.dump(2);
  EXPECT_EQ(j["client"]["connections"], 1) << j.dump(2);
  const Csv rec = readCsv(csv);
  std::vector<size_t> commanded_rows;  // the C example (glove_press) against the plant: 1 N on the index pad
  for (size_t i = 0; i < rec.rows(); ++i) {
    EXPECT_LE(rec.at("setpoint1", i), 1.0) << "the second client commanded";
    if (i >= kDeadlineCycles && i + 1 < rec.rows() && rec.at("mode", i) == 2 && rec.at("mode", i + 1) == 2 &&
        rec.at("setpoint1", i) == 1.0) {
      commanded_rows.push_back(i);
    }
  }
  checkAgainstTruth(rec, commanded_rows, truth);
  return true;
}

template <class Run>
void withoutDeviceFault(Run run) {
  for (int attempt = 0; attempt < kAttempts; ++attempt) {
    if (run(attempt)) return;
    std::fprintf(stderr, "attempt %d: the simulated device faulted (current limit); once more\n", attempt);
  }
  FAIL() << "the simulated device faulted in all " << kAttempts << " attempts";
}

}  // namespace

TEST(ClientSdk, TheGloveSpringsForcesAreWhatTheDaemonSent) { withoutDeviceFault(springForcesMatch); }

TEST(ClientSdk, AKilledClientIsForcedSafeWithinTwoCyclesOfItsDeadline) { withoutDeviceFault(killedClientGoesSafe); }

TEST(ClientSdk, ASecondClientIsRefusedWhileTheFirstHoldsTheDevice) { withoutDeviceFault(secondClientRefused); }

// NaN from a client: refused and counted, never sent; the device is held safe those cycles (the client's fallback).
TEST(ClientSdk, ANonFiniteCommandIsRefusedAndCounted) {
  const std::string sock = tmpPath("nan.sock"), csv = tmpPath("nan.csv");
  auto daemon = startDaemon(sock, csv, "2.5", "still");
  Process press({binPath("glove_press"), sock, "1", "nan", "500", kDeadlineMs});
  EXPECT_EQ(press.wait(20000), 0) << press.stdoutText() << press.stderrText();
  const nlohmann::json j = finish(*daemon);
  EXPECT_GE(j["client"]["refused_invalid"].get<int>(), 400) << j.dump(2);
  EXPECT_EQ(j["client"]["cycles_commanded"], 0) << j.dump(2);
  const Csv rec = readCsv(csv);
  for (size_t i = 0; i < rec.rows(); ++i) ASSERT_TRUE(std::isfinite(rec.at("setpoint1", i))) << "row " << i;
  size_t safe = 0;
  for (size_t i = 0; i < rec.rows(); ++i) safe += rec.at("mode", i) == 0 ? 1 : 0;
  EXPECT_GE(safe, 300u) << "the refused cycles did not hold the device safe";
}

// 25 N asked of a 10 N glove: 10 N is sent (the limits stage), the engagements are counted and told to the client.
// (A sustained 10 N press may trip the simulated motor's current limit - 10 N is its peak active force - and the
// device fault then forces the client off with that cause: accepted, and checked.)
TEST(ClientSdk, AnOutOfLimitCommandIsSaturatedToTheDeviceLimit) {
  const std::string sock = tmpPath("lim.sock"), csv = tmpPath("lim.csv");
  auto daemon = startDaemon(sock, csv, "2.5", "still");
  Process press({binPath("glove_press"), sock, "1", "25", "500", kDeadlineMs});
  const int rc = press.wait(20000);
  EXPECT_NE(press.stdoutText().find("sent 10.000 N"), std::string::npos) << press.stdoutText();
  if (rc != 0) {
    EXPECT_NE(press.stdoutText().find("cause device-fault"), std::string::npos) << press.stdoutText();
  }
  const nlohmann::json j = finish(*daemon);
  EXPECT_GE(j["client"]["limited"].get<int>(), 50) << j.dump(2);
  EXPECT_EQ(j["client"]["limited"], j["commands"]["limited_by_device_limits"]) << j.dump(2);
  const Csv rec = readCsv(csv);
  double peak = 0.0;
  for (size_t i = 0; i < rec.rows(); ++i) peak = std::fmax(peak, rec.at("setpoint1", i));
  EXPECT_DOUBLE_EQ(peak, kGloveLimitN);
}

// libphalanx from an installed tree: cmake --install into a temporary prefix, then the examples built against it
// with find_package(phalanx) and the C example with pkg-config.
TEST(ClientSdk, TheInstalledLibraryBuildsTheExamples) {
  const std::string prefix = tmpPath("prefix"), build = tmpPath("examples-build");
  Process install({PHALANX_CMAKE, "--install", PHALANX_BUILD_DIR, "--component", "sdk", "--prefix", prefix});
  ASSERT_EQ(install.wait(60000), 0) << install.stdoutText() << install.stderrText();
  Process configure({PHALANX_CMAKE, "-S", std::string(PHALANX_SOURCE_DIR) + "/examples", "-B", build,
                     "-DCMAKE_PREFIX_PATH=" + prefix});
  ASSERT_EQ(configure.wait(120000), 0) << configure.stdoutText() << configure.stderrText();
  Process make({PHALANX_CMAKE, "--build", build});
  ASSERT_EQ(make.wait(300000), 0) << make.stdoutText() << make.stderrText();
  EXPECT_EQ(access((build + "/glove_spring").c_str(), X_OK), 0);
#ifdef PHALANX_NETWORK  // the installed package says it has the network part (phalanx_NETWORK): its example builds
  EXPECT_EQ(access((build + "/remote_press").c_str(), X_OK), 0);
#endif
  Process pc({"/bin/sh", "-c",
              "PKG_CONFIG_PATH=$(dirname $(find " + prefix + " -name phalanx.pc)) && export PKG_CONFIG_PATH && cc -o " +
                  build + "/glove_press_pc " + PHALANX_SOURCE_DIR + "/examples/glove_press.c $(pkg-config --cflags --libs phalanx)"});
  ASSERT_EQ(pc.wait(60000), 0) << pc.stdoutText() << pc.stderrText();
  // The pkg-config build runs against the installed library (no daemon: it reports the connect failure).
  Process run({"/bin/sh", "-c", "LD_LIBRARY_PATH=$(dirname $(find " + prefix + " -name 'libphalanx.so' | head -1)) " +
                                    build + "/glove_press_pc " + tmpPath("none.sock") + " 1 1 1"});
  EXPECT_EQ(run.wait(10000), 3);
  EXPECT_NE(run.stderrText().find("cannot connect to phalanxd"), std::string::npos) << run.stderrText();
}
