// firmware-sim's reference instrument (--instrument, docs/modbus.md "firmware-sim's instrument") read by an
// independent client, Debian's mbpoll (tools/setup.sh), over Modbus TCP on loopback and RTU on a pseudo-terminal.
//
// The rig (sea_rig) is driven by this test as its host: SEA 0 tracks a 0.5 Hz, 0.25 N·m sine, so the MCP load cell
// the instrument serves is nonzero, of both signs, and moving. Each mbpoll read is bracketed in device ticks with no
// timing assumption: it starts after the telemetry of tick `lower` has arrived (firmware-sim serves a tick's truth
// before it sends that tick's telemetry), and its answer came before a command this test sent afterwards, which the
// device applied in tick `upper` (the first telemetry echoing it). The value read must lie within the range of the
// truth (--truth, the same values firmware-sim serves) over ticks lower..upper, widened by the register map's
// quantisation: half a count (0.5e-5 N·m) for int32, mbpoll's six printed digits for float32.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <climits>
#include <cmath>
#include <mutex>
#include <regex>
#include <thread>

#include "phalanx/host/modbus/instrument.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/realtime.h"
#include "process.h"
#include "record_csv.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

bool haveMbpoll() { return access("/usr/bin/mbpoll", X_OK) == 0; }

std::string tmpPath(const std::string& what) { return "/tmp/phalanx_instrument_" + std::to_string(getpid()) + "_" + what; }

/// This test as the rig's host: its own thread commands SEA 0 to tau(t) = 0.25 sin(2π 0.5 t) N·m every 2 ms and
/// keeps the newest telemetry's device time and command echo. (The load cell follows in stairs: the Bowden cable's
/// play holds it for 10-20 ms at a time, docs/sea-plant.md; a read often equals the last stair of its bracket.)
class RigHost {
 public:
  ~RigHost() { stop(); }
  std::string start(const std::string& pty) {
    using namespace phalanx;
    if (std::string err = link_.open(pty, 0); !err.empty()) return err;
    session_ = std::make_unique<host::HostSession>(link_);
    session_->sendHello(26, protocol::DeviceType::kSeaFinger);
    link_.flush();
    for (int i = 0; i < 2500 && session_->handshake() == host::HandshakeResult::kPending; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
      session_->poll(linux_hal::monotonicNs());
    }
    if (session_->handshake() != host::HandshakeResult::kOk) return "handshake: " + session_->handshakeError();
    running_ = true;
    thread_ = std::thread([this] { loop(); });
    return {};
  }
  void stop() {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }
  uint64_t newestDeviceTimeUs() {
    std::lock_guard<std::mutex> g(m_);
    return newest_us_;
  }
  /// Every command from this sequence number on is sent after this call returns.
  uint16_t nextSeq() {
    std::lock_guard<std::mutex> g(m_);
    return static_cast<uint16_t>(last_seq_ + 1);
  }
  /// Device time of a telemetry frame that echoes seq or a later command (0: none within timeout_ms).
  uint64_t deviceTimeEchoing(uint16_t seq, int timeout_ms) {
    for (int i = 0; i < timeout_ms; ++i) {
      {
        std::lock_guard<std::mutex> g(m_);
        if (have_ && static_cast<int16_t>(echo_ - seq) >= 0) return newest_us_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return 0;
  }
  uint16_t faultBits() {
    std::lock_guard<std::mutex> g(m_);
    return faults_;
  }

 private:
  void loop() {
    using namespace phalanx;
    protocol::Command cmd;
    cmd.mode = protocol::Mode::kSetpoint;
    cmd.channel_count = 2;
    cmd.timeout_ms = 1000;  // the longest the protocol allows: a starved test thread must not fault the rig
    for (auto& g : cmd.gain_scale_permille) g = 1000;
    const uint64_t t0 = linux_hal::monotonicNs();
    while (running_) {
      {
        const uint64_t now = linux_hal::monotonicNs();
        std::lock_guard<std::mutex> g(m_);
        session_->poll(now);
        if (session_->hasTelemetry()) {
          have_ = true;
          newest_us_ = session_->latest().device_time_us;
          echo_ = session_->latest().cmd_seq_echo;
          faults_ = session_->latest().fault_bits;
        }
        cmd.setpoint[0] = static_cast<float>(0.25 * std::sin(2.0 * M_PI * 0.5 * static_cast<double>(now - t0) * 1e-9));
        session_->sendCommand(cmd, now);
        last_seq_ = cmd.seq;
        link_.flush();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    cmd.mode = protocol::Mode::kSafe;
    cmd.setpoint[0] = 0.0f;
    std::lock_guard<std::mutex> g(m_);
    session_->sendCommand(cmd, linux_hal::monotonicNs());
    link_.flush();
  }

  phalanx::linux_hal::SerialLink link_;
  std::unique_ptr<phalanx::host::HostSession> session_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  std::mutex m_;
  bool have_ = false;
  uint64_t newest_us_ = 0;
  uint16_t echo_ = 0;
  uint16_t last_seq_ = 0;
  uint16_t faults_ = 0;
};

struct Read {
  uint64_t lower_us = 0, upper_us = 0;
  double value = 0.0;
  std::string out;  // mbpoll's output, for failure messages
};

/// One mbpoll read of register `reg` (type "int" or "float"), bracketed in device ticks; false if mbpoll failed.
bool readBracketed(RigHost& host, std::vector<std::string> transport, const std::string& table_type, unsigned reg,
                   bool big_endian_words, Read& r) {
  r.lower_us = host.newestDeviceTimeUs();
  std::vector<std::string> argv = {"/usr/bin/mbpoll"};
  argv.insert(argv.end(), transport.begin(), transport.end() - 1);
  argv.insert(argv.end(), {"-0", "-1", "-o", "2", "-t", table_type, "-r", std::to_string(reg)});
  if (big_endian_words) argv.push_back("-B");
  argv.push_back(transport.back());
  Process p(argv);
  const int status = p.wait(10000);
  const uint16_t after = host.nextSeq();
  r.out = p.stdoutText() + p.stderrText();
  r.upper_us = host.deviceTimeEchoing(after, 5000);
  std::smatch m;
  const std::regex value("\\[" + std::to_string(reg) + "\\]:\\s+(-?[0-9.eE+-]+)");
  if (status != 0 || !std::regex_search(r.out, m, value) || r.upper_us == 0) return false;
  r.value = std::stod(m[1]);
  return true;
}

/// The start-up lines: "PTY <path>", then "instrument: modbus ...".
bool startLines(Process& fw, std::string& pty, std::string& instrument) {
  const std::string a = fw.readStdoutLine(5000);
  instrument = fw.readStdoutLine(5000);
  if (a.rfind("PTY ", 0) != 0) return false;
  pty = a.substr(4);
  return instrument.rfind("instrument: modbus ", 0) == 0;
}

/// Run the rig with the instrument at `where`, read it `reads` times, and check every read against the truth.
void checkAgainstTruth(const std::string& where, const std::string& map, const std::string& table_type, unsigned reg,
                       bool big_endian_words, double scale, double tolerance) {
  const std::string truth_path = tmpPath(where.substr(0, 3) + ".truth.csv");
  std::vector<std::string> args = {binPath("firmware-sim"), "--device", "sea_rig", "--seconds", "60", "--truth",
                                   truth_path, "--instrument", where};
  if (!map.empty()) args.insert(args.end(), {"--instrument-map", map});
  Process fw(args);
  std::string pty, line;
  ASSERT_TRUE(startLines(fw, pty, line)) << line << fw.stderrText();
  std::vector<std::string> transport;
  std::smatch m;
  if (where == "rtu") {
    ASSERT_TRUE(std::regex_search(line, m, std::regex("^instrument: modbus rtu (/dev/pts/[0-9]+) "))) << line;
    transport = {"-m", "rtu", "-b", "115200", "-P", "none", m[1]};
  } else {
    ASSERT_TRUE(std::regex_search(line, m, std::regex("^instrument: modbus tcp 127\\.0\\.0\\.1:([0-9]+) "))) << line;
    transport = {"-m", "tcp", "-p", m[1], "127.0.0.1"};
  }
  EXPECT_NE(line.find(" N*m signal load_cell_mcp_Nm noise 0"), std::string::npos) << line;

  RigHost host;
  ASSERT_EQ(host.start(pty), "");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the SEA torque loop settles on the sine
  std::vector<Read> reads;
  for (int i = 0; i < 12; ++i) {
    Read r;
    ASSERT_TRUE(readBracketed(host, transport, table_type, reg, big_endian_words, r)) << r.out;
    r.value *= scale;
    reads.push_back(r);
    std::this_thread::sleep_for(std::chrono::milliseconds(150));  // 12 reads over more than a period of the sine
  }
  EXPECT_EQ(host.faultBits(), 0) << "the rig faulted while the test commanded it";
  host.stop();
  fw.signal(SIGTERM);
  ASSERT_EQ(fw.wait(10000), 0) << fw.stderrText();
  std::smatch rq;
  const std::string err = fw.stderrText();
  ASSERT_TRUE(std::regex_search(err, rq, std::regex("instrument requests=([0-9]+)"))) << err;
  EXPECT_GE(std::stoi(rq[1]), 12) << "every read reached the instrument: " << err;

  const phalanx::test::TruthCsv truth = phalanx::test::readTruthCsv(truth_path);
  ASSERT_GT(truth.rows(), 1000u) << truth_path;
  double largest = 0.0;
  bool positive = false, negative = false;
  for (const Read& r : reads) {
    size_t lo = 0, hi = 0;
    ASSERT_TRUE(truth.find(static_cast<double>(r.lower_us), lo)) << r.lower_us;
    ASSERT_TRUE(truth.find(static_cast<double>(r.upper_us), hi)) << r.upper_us;
    ASSERT_LE(lo, hi);
    double tmin = INFINITY, tmax = -INFINITY;
    for (size_t k = lo; k <= hi; ++k) {
      tmin = std::min(tmin, truth.at("truth_load_cell_mcp_Nm", k));
      tmax = std::max(tmax, truth.at("truth_load_cell_mcp_Nm", k));
    }
    std::printf("%s read %.6f N*m; truth over ticks %llu..%llu us (%zu rows): %.6f .. %.6f\n", where.c_str(), r.value,
                static_cast<unsigned long long>(r.lower_us), static_cast<unsigned long long>(r.upper_us), hi - lo + 1,
                tmin, tmax);
    EXPECT_GE(r.value, tmin - tolerance) << "ticks " << r.lower_us << ".." << r.upper_us;
    EXPECT_LE(r.value, tmax + tolerance) << "ticks " << r.lower_us << ".." << r.upper_us;
    largest = std::max(largest, std::fabs(r.value));
    positive = positive || r.value > 0.02;
    negative = negative || r.value < -0.02;
  }
  EXPECT_GT(largest, 0.1) << "the commanded sine should load the cell to well over 0.1 N*m";
  EXPECT_TRUE(positive && negative) << "reads over a period of the sine see both signs";
  unlink(truth_path.c_str());
}

}  // namespace

TEST(FirmwareInstrument, TcpServesTheRigLoadCellAsTheTruthSaysWithinHalfACount) {
  if (!haveMbpoll()) GTEST_SKIP() << "mbpoll is not installed (tools/setup.sh installs it)";
  // The default map: input register 0, int32, big-endian words, 1e-5 N·m per count.
  checkAgainstTruth("tcp:0", "", "3:int", 0, true, 1e-5, 0.5e-5 + 1e-8);
}

TEST(FirmwareInstrument, RtuOnAPseudoTerminalServesTheRigLoadCellThroughAnotherRegisterMap) {
  if (!haveMbpoll()) GTEST_SKIP() << "mbpoll is not installed (tools/setup.sh installs it)";
  // float32 in holding registers 7-8, low word first (mbpoll's default order); mbpoll prints six digits.
  checkAgainstTruth("rtu", "table=holding,address=7,type=float32,word_order=little,scale=1", "4:float", 7, false, 1.0,
                    1e-6);
}

// --instrument-noise on the rig at rest (no host: the load cell's truth is exactly 0), read by the project's own
// client (InstrumentClient, the bench's) at 500 Hz: the served values scatter with the standard deviation asked for.
// Bounds, for n >= 200 samples: the sample deviation within 20 % of sigma (4 relative standard errors 1/sqrt(2n))
// and the mean within 3 mN·m of the truth (4 standard errors sigma/sqrt(n)).
TEST(FirmwareInstrument, NoiseOnTheServedValueHasTheRequestedStandardDeviation) {
  namespace mb = phalanx::host::modbus;
  const std::string truth_path = tmpPath("noise.truth.csv");
  Process fw({binPath("firmware-sim"), "--device", "sea_rig", "--seconds", "60", "--seed", "7", "--truth", truth_path,
              "--instrument", "tcp:0", "--instrument-noise", "0.01"});
  std::string pty, line;
  ASSERT_TRUE(startLines(fw, pty, line)) << line << fw.stderrText();
  EXPECT_NE(line.find(" noise 0.01"), std::string::npos) << line;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(line, m, std::regex("^instrument: modbus tcp 127\\.0\\.0\\.1:([0-9]+) "))) << line;
  mb::InstrumentConfig cfg;
  cfg.port = static_cast<unsigned>(std::stoul(m[1]));
  cfg.scale = 1e-5;
  cfg.poll_hz = 500;
  mb::InstrumentClient client(cfg);
  ASSERT_EQ(client.start(), "");
  std::vector<double> v;
  uint64_t last_ns = 0;
  for (int i = 0; i < 5000 && v.size() < 300; ++i) {
    const mb::InstrumentReading r = client.latest(phalanx::linux_hal::monotonicNs());
    if (r.valid && r.sample_ns != last_ns) {
      v.push_back(r.value);
      last_ns = r.sample_ns;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  client.stop();
  fw.signal(SIGTERM);
  ASSERT_EQ(fw.wait(10000), 0) << fw.stderrText();
  ASSERT_GE(v.size(), 200u) << client.statsJson(phalanx::linux_hal::monotonicNs()).dump();
  double mean = 0.0, ss = 0.0;
  for (double x : v) mean += x / static_cast<double>(v.size());
  for (double x : v) ss += (x - mean) * (x - mean);
  const double sd = std::sqrt(ss / static_cast<double>(v.size() - 1));
  std::printf("noise: %zu samples, mean %.5f N*m, sd %.5f N*m\n", v.size(), mean, sd);
  const phalanx::test::TruthCsv truth = phalanx::test::readTruthCsv(truth_path);
  ASSERT_GT(truth.rows(), 100u);
  for (size_t k = 0; k < truth.rows(); ++k) ASSERT_EQ(truth.at("truth_load_cell_mcp_Nm", k), 0.0) << "row " << k;
  EXPECT_NEAR(sd, 0.01, 0.002);
  EXPECT_NEAR(mean, 0.0, 0.003);
  unlink(truth_path.c_str());
}

TEST(FirmwareInstrument, BadInstrumentArgumentsExit2NamingTheProblem) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--instrument", "udp:502"}, "--instrument 'udp:502': unknown transport"},
      {{"--instrument", "tcp:65536"}, "--instrument 'tcp:65536': the port must be an integer in [0, 65535]"},
      {{"--instrument", "tcp:0", "--instrument-signal", "pad_force_index_N"},
       "--instrument-signal 'pad_force_index_N': sea_rig's truth has no such quantity (sea_torque_mcp_Nm, load_cell_mcp_Nm"},
      {{"--instrument", "rtu", "--instrument-map", "type=int64"}, "--instrument-map.type: 'int64' is not int16"},
      {{"--instrument", "rtu", "--instrument-noise", "-0.1"}, "--instrument-noise: must be a finite standard deviation"},
      {{"--instrument-signal", "load_cell_mcp_Nm"},
       "--instrument-signal, --instrument-noise, --instrument-delay-ms and --instrument-map need --instrument"},
  };
  for (const auto& [extra, message] : cases) {
    std::vector<std::string> args = {binPath("firmware-sim"), "--device", "sea_rig", "--seconds", "5"};
    args.insert(args.end(), extra.begin(), extra.end());
    Process fw(args);
    EXPECT_EQ(fw.wait(10000), 2) << extra.back();
    EXPECT_NE(fw.stderrText().find("firmware-sim: error: " + message), std::string::npos) << fw.stderrText();
    EXPECT_EQ(fw.stdoutText().find("PTY"), std::string::npos) << "refused before the link opened: " << fw.stdoutText();
  }
}
