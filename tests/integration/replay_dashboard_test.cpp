// `phalanx record replay FILE --dashboard ADDRESS:PORT --speed X` (issue #23 item 3; docs/dashboard.md "Replay
// mode"), without a browser: a short simulated session recorded by `phalanxd --record X.mcap`, replayed to the
// dashboard, its /api/samples polled until the end. Checked by counting, not timing: every cycle the recording
// holds at the dashboard's 50 Hz sampling (the first cycle of each 1/50 s of session time) arrives once, in
// order, with the recording's own values (joint flexion from /phalanx/joint_states, measured effort from
// /phalanx/effort/<channel>; the pantograph's angles from /phalanx/mechanism/joint_states, decoded here from
// their CDR); control requests are refused; the process exits 0. The achieved speed is printed, not gated.
// Also: SIGINT with keep-alive connections open ends it promptly; bad arguments exit 2 naming the option.
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <thread>

#include <nlohmann/json.hpp>

#include "../support/http_client.h"
#include "phalanx/host/record/mcap_reader.h"
#include "phalanx/host/record/record_reader.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::http;
using phalanx::test::HttpAnswer;
using phalanx::test::KeepAlive;
using phalanx::test::Process;

namespace {

std::string tempDir() {
  char tmpl[] = "/tmp/phalanx-replay-dash-XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d == nullptr ? std::string("/tmp") : std::string(d);
}

/// The test's own reader of the CDR (XCDR1, little-endian) the recordings' ROS 2 messages use.
class Cdr {
 public:
  explicit Cdr(const std::string& data) : d_(data) {}
  uint32_t u32() {
    align(4);
    uint32_t v = 0;
    take(&v, 4);
    return v;
  }
  double f64() {
    align(8);
    double v = 0;
    take(&v, 8);
    return v;
  }
  std::string str() {
    const uint32_t n = u32();  // with its NUL
    std::string s = at_ + n <= d_.size() && n > 0 ? d_.substr(at_, n - 1) : std::string();
    at_ += n;
    return s;
  }
  void header() {
    u32();  // stamp.sec
    u32();  // stamp.nanosec
    str();  // frame_id
  }
  bool ok() const { return at_ <= d_.size(); }

 private:
  void align(std::size_t n) { at_ = 4 + ((at_ - 4 + n - 1) / n) * n; }  // relative to the body (after 4 bytes)
  void take(void* out, std::size_t n) {
    if (at_ + n <= d_.size()) std::memcpy(out, d_.data() + at_, n);
    at_ += n;
  }
  const std::string& d_;
  std::size_t at_ = 4;  // after the encapsulation header
};

/// sensor_msgs/JointState → name → position.
std::map<std::string, double> jointPositions(const std::string& data) {
  Cdr c(data);
  c.header();
  std::vector<std::string> names(c.u32());
  for (auto& n : names) n = c.str();
  std::map<std::string, double> out;
  const uint32_t n = c.u32();
  for (uint32_t i = 0; i < n && i < names.size(); ++i) out[names[i]] = c.f64();
  return out;
}

/// geometry_msgs/WrenchStamped → {force.z, torque.z}.
std::pair<double, double> wrenchZ(const std::string& data) {
  Cdr c(data);
  c.header();
  double v[6];
  for (double& x : v) x = c.f64();
  return {v[2], v[5]};
}

/// One expected dashboard sample: the first recorded cycle of a 1/50 s of session time.
struct Expected {
  double t_s = 0.0;
  std::map<std::string, double> joint_deg;   ///< flexion (or a pantograph angle) in degrees
  /// Measured effort per channel (adapter devices): force.z (a pad force, N) and torque.z (a joint torque, N·m).
  std::map<std::string, std::pair<double, double>> effort;
};

/// The expected samples of a --record file, from its own messages.
std::vector<Expected> expectedSamples(const std::string& path, bool& ok) {
  phalanx::host::record::McapContents m;
  ok = phalanx::host::record::readMcap(path, m).empty();
  std::map<uint16_t, std::string> topic = m.topics;
  std::vector<double> t;
  std::vector<std::map<std::string, double>> joints;
  std::map<std::string, std::vector<std::pair<double, double>>> efforts;
  bool adapter = false;
  for (const auto& [id, name] : topic) adapter = adapter || name == "/phalanx/joint_states";
  const std::string joint_topic = adapter ? "/phalanx/joint_states" : "/phalanx/mechanism/joint_states";
  for (const auto& msg : m.messages) {
    const std::string& name = topic[msg.channel];
    if (name == "/phalanx/telemetry") {
      t.push_back(nlohmann::json::parse(msg.data)["t_s"].get<double>());
    } else if (name == joint_topic) {
      joints.push_back(jointPositions(msg.data));
    } else if (name.rfind("/phalanx/effort/", 0) == 0) {
      efforts[name.substr(16)].push_back(wrenchZ(msg.data));
    }
  }
  ok = ok && !t.empty() && joints.size() == t.size();
  for (const auto& [ch, v] : efforts) ok = ok && v.size() == t.size();
  std::vector<Expected> out;
  double last_slot = -1.0;
  for (std::size_t i = 0; ok && i < t.size(); ++i) {
    const double slot = std::floor(t[i] * 50.0);
    if (slot <= last_slot) continue;
    last_slot = slot;
    Expected e;
    e.t_s = t[i];
    for (const auto& [name, rad] : joints[i]) e.joint_deg[name] = rad * 180.0 / M_PI;
    for (const auto& [ch, v] : efforts) e.effort[ch] = v[i];
    out.push_back(std::move(e));
  }
  return out;
}

std::string recordSession(const std::string& dir, const std::string& device, const std::string& seconds) {
  const std::string path = dir + "/" + device + ".mcap";
  Process d({binPath("phalanxd"), "--no-realtime", "--device", "sim:" + device, "--scenario", "close-open",
             "--record", path, "--seconds", seconds, "--command-timeout-ms", "200"});
  const int rc = d.wait(60000);
  EXPECT_EQ(rc, 0) << d.stderrText();
  return path;
}

struct Replay {
  std::unique_ptr<Process> proc;
  int port = 0;
  std::string token, host;
};

Replay startReplay(const std::vector<std::string>& extra) {
  Replay r;
  std::vector<std::string> argv{binPath("phalanx"), "record", "replay"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  r.proc = std::make_unique<Process>(argv);
  const std::string line = r.proc->readStdoutLine(30000);
  EXPECT_EQ(line.rfind("DASHBOARD http://127.0.0.1:", 0), 0u) << line << r.proc->stderrText();
  if (line.size() < 30) return r;
  const std::string url = line.substr(10);
  r.port = std::atoi(url.c_str() + url.find(':', 7) + 1);
  r.token = url.substr(url.find("#token=") + 7);
  r.host = "127.0.0.1:" + std::to_string(r.port);
  return r;
}

bool near(double a, double b) { return std::fabs(a - b) <= 1e-9 * std::max(1.0, std::fabs(b)); }

/// Replays `path` at `speed`, polls until the end and checks every sample against the recording.
void replayAndCheck(const std::string& path, const std::string& speed, const std::string& label) {
  bool ok = false;
  const std::vector<Expected> want = expectedSamples(path, ok);
  ASSERT_TRUE(ok) << path;
  ASSERT_GT(want.size(), 50u) << path;
  Replay r = startReplay({path, "--dashboard", "127.0.0.1:0", "--speed", speed});
  ASSERT_GT(r.port, 0);
  const std::string tok = "X-Phalanx-Token: " + r.token + "\r\n";
  // Control requests are refused with the reason; the patient list is empty.
  for (const char* cmd : {R"({"cmd":"stop"})", R"({"cmd":"start","exercise":"assessment"})", R"({"cmd":"reset"})",
                          R"({"cmd":"exercise","exercise":"idle"})", R"({"cmd":"limits","effort_max":{"index":1}})"}) {
    const auto a = nlohmann::json::parse(http(r.port, "POST", "/api/request", r.host, tok, cmd).body, nullptr, false);
    EXPECT_FALSE(a.value("ok", true)) << cmd;
    const std::string file = path.substr(path.rfind('/') + 1);
    EXPECT_NE(a.value("error", "").find("this is a replay of " + file + ": there is no device to control"),
              std::string::npos) << cmd << " → " << a.dump();
  }
  const auto prof = nlohmann::json::parse(http(r.port, "POST", "/api/request", r.host, tok, R"({"cmd":"profiles"})").body);
  EXPECT_TRUE(prof.value("ok", false));
  EXPECT_EQ(prof["result"], nlohmann::json::array());

  // Poll as the page does (one keep-alive connection), until the replay says it finished and nothing is left.
  KeepAlive conn(r.port);
  ASSERT_TRUE(conn.connected());
  std::vector<nlohmann::json> got;
  nlohmann::json meta, status;
  uint64_t after = 0;
  const auto t_first = std::chrono::steady_clock::now();
  double wall_s = 0.0;
  for (int i = 0; i < 6000; ++i) {  // 6000 × 20 ms: 2 min at most
    const HttpAnswer a = conn.request("GET", "/api/samples?after=" + std::to_string(after), r.host, tok);
    ASSERT_EQ(a.status, 200) << "poll " << i;
    const auto j = nlohmann::json::parse(a.body);
    status = j["status"];
    if (j["meta"].is_object() && j["meta"].contains("joints")) meta = j["meta"];
    for (const auto& s : j["samples"]) {
      got.push_back(s);
      after = s["seq"].get<uint64_t>();
    }
    const bool finished = status.contains("replay") && status["replay"].value("finished", false);
    if (finished && after == j["last_seq"].get<uint64_t>()) {
      wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_first).count();
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const int rc = r.proc->wait(30000);
  EXPECT_EQ(rc, 0) << r.proc->stderrText();
  ASSERT_TRUE(status.contains("replay")) << status.dump();
  EXPECT_EQ(status.value("phase", ""), "replay");
  EXPECT_EQ(status["replay"].value("speed", 0.0), std::atof(speed.c_str()));

  // Every expected sample once, in order, with the recording's values.
  ASSERT_EQ(got.size(), want.size()) << label;
  const auto joints = meta["joints"], channels = meta["channels"];
  const bool force = meta.value("effort_unit", "") == "N";  // else a torque (N·m)
  ASSERT_FALSE(joints.empty());
  std::size_t values = 0, bad = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto& s = got[i];
    EXPECT_EQ(s["seq"].get<uint64_t>(), i + 1);
    if (s["t"].get<double>() != want[i].t_s) {
      ADD_FAILURE() << label << " sample " << i << ": t " << s["t"] << " expected " << want[i].t_s;
      break;
    }
    for (std::size_t k = 0; k < joints.size(); ++k) {
      const auto w = want[i].joint_deg.find(joints[k].get<std::string>());
      ASSERT_NE(w, want[i].joint_deg.end()) << joints[k];
      const auto& v = s["j"][k];
      ++values;
      if (std::isnan(w->second) ? !v.is_null() : (!v.is_number() || !near(v.get<double>(), w->second))) ++bad;
    }
    for (std::size_t k = 0; k < channels.size(); ++k) {
      const auto w = want[i].effort.find(channels[k].get<std::string>());
      if (w == want[i].effort.end()) continue;  // the pantograph: no measured effort
      const auto& v = s["em"][k];
      ++values;
      const double recorded = force ? w->second.first : w->second.second;
      if (!v.is_number() || !near(v.get<double>(), recorded)) ++bad;
    }
  }
  EXPECT_EQ(bad, 0u) << label << ": " << bad << " of " << values << " values differ from the recording";
  EXPECT_GT(values, got.size() * 3);
  // The achieved speed (printed, not gated: it depends on the machine's load).
  const double replay_s = want.back().t_s - want.front().t_s;
  std::printf("%s: %zu samples (%zu values) at --speed %s: %.2f s of session in %.2f s polled: %.2f×\n", label.c_str(),
              got.size(), values, speed.c_str(), replay_s, wall_s, wall_s > 0 ? replay_s / wall_s : 0.0);
  const std::string out = r.proc->stdoutText();
  const auto summary = nlohmann::json::parse(out.substr(out.find('{')), nullptr, false);
  ASSERT_TRUE(summary.is_object()) << out;
  EXPECT_EQ(summary["mismatched_cycles"], 0);
  EXPECT_EQ(summary["stream"]["frames"].get<std::size_t>(), want.size());
  EXPECT_EQ(summary["stream"]["samples_fetched"].get<std::size_t>(), want.size());
  std::printf("%s: the replay's own figure: %.2f×\n", label.c_str(), summary["stream"]["achieved_speed"].get<double>());
}

class ReplayDashboard : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(tempDir());
    glove_ = new std::string(recordSession(*dir_, "glove5", "3"));
  }
  static void TearDownTestSuite() {
    std::system(("rm -rf " + *dir_).c_str());
    delete dir_;
    delete glove_;
  }
  static std::string* dir_;
  static std::string* glove_;
};
std::string* ReplayDashboard::dir_ = nullptr;
std::string* ReplayDashboard::glove_ = nullptr;

TEST_F(ReplayDashboard, Glove5AtFourTimesDeliversEverySampleOnceWithTheRecordedValues) {
  replayAndCheck(*glove_, "4", "glove5");
}

TEST_F(ReplayDashboard, SeaFingerAtFourTimesDeliversEverySampleOnce) {
  replayAndCheck(recordSession(*dir_, "sea_finger", "2"), "4", "sea_finger");
}

TEST_F(ReplayDashboard, PantographAtRealSpeedDeliversEverySampleOnce) {
  replayAndCheck(recordSession(*dir_, "pantograph", "2"), "1", "pantograph");
}

// A therapy session record (.phrec) is shown with its recorded values (no controller re-run): every 1/50 s of
// session time once, in order, with the exercise and the targets it recorded.
TEST_F(ReplayDashboard, SessionRecordIsStreamedWithItsRecordedValues) {
  const std::string path = *dir_ + "/resistance.phrec";
  Process d({binPath("phalanxd"), "--no-realtime", "--device", "sim:sea_finger", "--scenario", "close-open",
             "--exercise", "assistance", "--session-record", path, "--seconds", "2", "--command-timeout-ms", "200"});
  ASSERT_EQ(d.wait(60000), 0) << d.stderrText();
  phalanx::host::record::SessionRecord rec;
  ASSERT_EQ(phalanx::host::record::readRecord(path, rec), "");
  const int target_mcp = rec.auxIndex("target_mcp_rad");
  ASSERT_GE(target_mcp, 0);
  std::vector<const phalanx::host::record::CycleRecord*> want;
  double last_slot = -1.0;
  for (const auto& c : rec.cycles) {
    const double slot = std::floor(c.t_s * 50.0);
    if (slot > last_slot) want.push_back(&c);
    last_slot = std::max(last_slot, slot);
  }
  ASSERT_GT(want.size(), 50u);
  Replay r = startReplay({path, "--dashboard", "127.0.0.1:0", "--speed", "8"});
  ASSERT_GT(r.port, 0);
  const std::string tok = "X-Phalanx-Token: " + r.token + "\r\n";
  std::vector<nlohmann::json> got;
  nlohmann::json status, meta;
  uint64_t after = 0;
  for (int i = 0; i < 6000; ++i) {
    const HttpAnswer a = http(r.port, "GET", "/api/samples?after=" + std::to_string(after), r.host, tok);
    ASSERT_EQ(a.status, 200);
    const auto j = nlohmann::json::parse(a.body);
    status = j["status"];
    if (j["meta"].is_object() && j["meta"].contains("channels")) meta = j["meta"];
    for (const auto& s : j["samples"]) got.push_back(s), after = s["seq"].get<uint64_t>();
    if (status.contains("replay") && status["replay"].value("finished", false) && after == j["last_seq"]) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(r.proc->wait(30000), 0) << r.proc->stderrText();
  EXPECT_EQ(status.value("exercise", ""), "assistance");
  ASSERT_EQ(got.size(), want.size());
  const auto channels = meta["channels"];
  const auto mcp = std::find(channels.begin(), channels.end(), "mcp");
  ASSERT_NE(mcp, channels.end());
  const std::size_t k = static_cast<std::size_t>(mcp - channels.begin());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i]["seq"].get<uint64_t>(), i + 1);
    EXPECT_EQ(got[i]["t"].get<double>(), want[i]->t_s) << i;
    const double target = double(want[i]->aux[static_cast<std::size_t>(target_mcp)]) * 180.0 / M_PI;
    if (!got[i]["tg"][k].is_number() || !near(got[i]["tg"][k].get<double>(), target)) ++bad;
  }
  EXPECT_EQ(bad, 0u) << "targets differing from the record's";
  std::printf("session record: %zu samples, exercise %s\n", got.size(), status.value("exercise", "").c_str());
}

TEST_F(ReplayDashboard, SigintEndsItPromptlyWithKeepAliveConnectionsOpen) {
  Replay r = startReplay({*glove_, "--dashboard", "127.0.0.1:0", "--speed", "1", "--hold"});
  ASSERT_GT(r.port, 0);
  const std::string tok = "X-Phalanx-Token: " + r.token + "\r\n";
  // One idle keep-alive connection, one half-sent request, and one polling every 50 ms like a page.
  KeepAlive idle(r.port), half(r.port), polling(r.port);
  ASSERT_EQ(idle.request("GET", "/api/samples", r.host, tok).status, 200);
  ASSERT_TRUE(half.send("GET /api/samples HTTP/1.1\r\nHost: " + r.host + "\r\n"));
  std::atomic<bool> done{false};
  std::atomic<int> polls{0};
  std::thread poller([&] {
    while (!done && polling.request("GET", "/api/samples", r.host, tok).status == 200) {
      ++polls;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  for (int i = 0; i < 500 && polls < 5; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_GE(polls.load(), 5);
  const auto t0 = std::chrono::steady_clock::now();
  r.proc->signal(SIGINT);
  const int rc = r.proc->wait(5000);
  const double exit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  done = true;
  poller.join();
  EXPECT_EQ(rc, 0) << "no exit within 5 s of SIGINT: " << r.proc->stderrText();
  EXPECT_TRUE(idle.closedByServer(1000));
  std::printf("SIGINT with 3 keep-alive connections open (one polling): exit after %.3f s\n", exit_s);
  const std::string out = r.proc->stdoutText();
  const auto summary = nlohmann::json::parse(out.substr(out.find('{')), nullptr, false);
  ASSERT_TRUE(summary.is_object()) << out;
  EXPECT_FALSE(summary["stream"]["finished"].get<bool>());
}

TEST_F(ReplayDashboard, BadArgumentsExit2NamingTheOption) {
  struct Case {
    std::vector<std::string> args;
    std::string says;
  };
  const std::string csv = *dir_ + "/not-a-recording.csv";
  std::ofstream(csv) << "t_s,a\n0,1\n";
  const std::vector<Case> cases = {
      {{*glove_, "--dashboard", "127.0.0.1:0", "--speed", "0"}, "--speed"},
      {{*glove_, "--dashboard", "127.0.0.1:0", "--speed", "-1"}, "--speed"},
      {{*glove_, "--dashboard", "127.0.0.1:0", "--speed", "nan"}, "--speed"},
      {{*glove_, "--dashboard", "127.0.0.1:0", "--speed", "1000"}, "--speed"},
      {{*glove_, "--dashboard", "127.0.0.1:0", "--speed", "inf"}, "--speed"},
      {{*glove_, "--speed", "2"}, "--dashboard"},
      {{*glove_, "--hold"}, "--dashboard"},
      {{*glove_, "--dashboard", "10.1.2.3:8080"}, "--dashboard: 10.1.2.3 is not a loopback address"},
      {{*glove_, "--dashboard", "0.0.0.0:0"}, "--allow-remote"},
      {{*glove_, "--dashboard", "localhost:8080"}, "not an IPv4 or IPv6 address literal"},
      {{*glove_, "--dashboard", "127.0.0.1:99999"}, "--dashboard: port"},
      {{*glove_, "--dashboard", ""}, "--dashboard"},
      {{csv, "--dashboard", "127.0.0.1:0"}, "is a CSV recording"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> argv{binPath("phalanx"), "record", "replay"};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    Process p(argv);
    const int rc = p.wait(30000);
    std::string line;
    for (const auto& a : c.args) line += a + " ";
    EXPECT_EQ(rc, 2) << line << p.stderrText();
    EXPECT_NE(p.stderrText().find(c.says), std::string::npos) << line << "→ " << p.stderrText();
    EXPECT_EQ(p.stdoutText().find("DASHBOARD"), std::string::npos) << line;
  }
}

}  // namespace
