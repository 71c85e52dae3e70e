// The therapist's daemon as a process: crash-safe session records under kill -9, and the control API over its
// UNIX socket (every request type, malformed and unauthorised requests refused).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "phalanx/host/api/client.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/linux/realtime.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;
namespace record = phalanx::host::record;

namespace {

std::string tempDir() {
  char tmpl[] = "/tmp/phalanx-therapy-XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d == nullptr ? std::string("/tmp") : std::string(d);
}

}  // namespace

// Issue target: a kill -9 of the daemon loses at most the last 100 ms and leaves a readable file. Three kills
// at different points of a session; the newest recorded cycle must be within 100 ms of the kill.
TEST(SessionRecordCrash, KillNineLosesAtMostTheLast100Milliseconds) {
  const std::string dir = tempDir();
  for (int run = 0; run < 3; ++run) {
    const std::string path = dir + "/kill" + std::to_string(run) + ".phrec";
    Process d({binPath("phalanxd"), "--device", "sim:glove5", "--scenario", "close-open", "--no-realtime",
               "--session-record", path, "--exercise", "assessment", "--seed", std::to_string(run + 1)});
    std::this_thread::sleep_for(std::chrono::milliseconds(1500 + 370 * run));
    ASSERT_EQ(d.wait(0), INT_MIN) << "daemon exited early: " << d.stderrText();
    const uint64_t kill_ns = phalanx::linux_hal::monotonicNs();
    d.signal(SIGKILL);
    EXPECT_EQ(d.wait(5000), -SIGKILL);

    record::SessionRecord rec;
    ASSERT_EQ(record::readRecord(path, rec), "");
    EXPECT_FALSE(rec.complete()) << "no footer after kill -9";
    EXPECT_EQ(rec.bad_records, 0u) << "only the tail may be torn";
    ASSERT_GE(rec.cycles.size(), 500u);
    ASSERT_TRUE(rec.header.is_object());
    EXPECT_EQ(rec.header["device"], "glove5");
    for (size_t i = 1; i < rec.cycles.size(); ++i) {
      ASSERT_GT(rec.cycles[i].host_ns, rec.cycles[i - 1].host_ns) << "cycles in order, none twice";
    }
    const double lost_ms = (static_cast<double>(kill_ns) - static_cast<double>(rec.cycles.back().host_ns)) * 1e-6;
    std::printf("kill %d: %zu cycles recorded, newest %.1f ms before the kill, torn tail: %s\n", run,
                rec.cycles.size(), lost_ms, rec.torn_tail ? "yes" : "no");
    EXPECT_LE(lost_ms, 100.0);
    unlink(path.c_str());
  }
  rmdir(dir.c_str());
}

namespace {

/// phalanxd --api in a temporary directory with one valid and one invalid profile.
class ApiDaemon {
 public:
  ApiDaemon() : dir_(tempDir()), socket_(dir_ + "/api.sock") {
    std::ofstream(dir_ + "/p-ok.yaml") << "version: 1\npatient: p-ok\ndevice: glove5\n"
                                          "rom_deg: {index_mcp: [0, 70]}\n"
                                          "limits:\n  effort_max: {default: 3.0, thumb: 2.0}\n"
                                          "  range_deg: {index_pip: [0, 90]}\n";
    std::ofstream(dir_ + "/p-bad.yaml") << "version: 1\npatient: p-bad\ndevice: glove5\n"
                                           "limits:\n  effort_max: {default: 30.0}\n";
    proc_ = std::make_unique<Process>(std::vector<std::string>{
        binPath("phalanxd"), "--api", socket_, "--records-dir", dir_, "--profiles-dir", dir_, "--no-realtime",
        "--scenario", "close-open"});
    const std::string line = proc_->readStdoutLine(5000);
    EXPECT_EQ(line, "API " + socket_) << proc_->stderrText();
  }
  ~ApiDaemon() {
    proc_->signal(SIGTERM);
    proc_->wait(10000);
    std::system(("rm -rf " + dir_).c_str());
  }
  nlohmann::json call(const nlohmann::json& req) {
    nlohmann::json resp;
    const std::string err = phalanx::host::api::call(socket_, req, resp);
    EXPECT_EQ(err, "") << req.dump();
    return resp;
  }
  std::string raw(const std::string& line) {
    std::string resp;
    EXPECT_EQ(phalanx::host::api::callRaw(socket_, line, resp), "");
    return resp;
  }
  /// Asserts a refusal and returns its message.
  std::string refused(const nlohmann::json& req) {
    const nlohmann::json r = call(req);
    EXPECT_EQ(r.value("ok", true), false) << req.dump() << " → " << r.dump();
    return r.value("error", std::string());
  }
  nlohmann::json ok(const nlohmann::json& req) {
    const nlohmann::json r = call(req);
    EXPECT_EQ(r.value("ok", false), true) << req.dump() << " → " << r.dump();
    return r.value("result", nlohmann::json());
  }
  const std::string& dir() const { return dir_; }
  const std::string& socket() const { return socket_; }
  Process& process() { return *proc_; }

 private:
  std::string dir_;
  std::string socket_;
  std::unique_ptr<Process> proc_;
};

/// Waits until the running session reports telemetry (bounded).
nlohmann::json waitRunning(ApiDaemon& d) {
  nlohmann::json s;
  for (int i = 0; i < 300; ++i) {
    s = d.ok({{"cmd", "status"}});
    if (s.contains("session") && s["session"].contains("t_s")) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return s;
}

}  // namespace

TEST(ControlApi, EveryRequestTypeWorksThroughASession) {
  ApiDaemon d;
  EXPECT_EQ(d.ok({{"cmd", "version"}})["api_version"], "1");
  EXPECT_EQ(d.ok({{"cmd", "status"}})["session_running"], false);
  const auto profiles = d.ok({{"cmd", "profiles"}});
  ASSERT_EQ(profiles.size(), 2u);
  EXPECT_EQ(profiles[0]["file"], "p-bad.yaml");
  EXPECT_EQ(profiles[0]["valid"], false);
  EXPECT_NE(profiles[0]["error"].get<std::string>().find("effort_max"), std::string::npos);
  EXPECT_EQ(profiles[1]["valid"], true);
  EXPECT_EQ(d.ok({{"cmd", "profile"}, {"patient", "p-ok"}})["rom_deg"]["index_mcp"][1], 70.0);

  const auto started = d.ok({{"cmd", "start"}, {"patient", "p-ok"}, {"exercise", "assessment"}, {"seed", 3}});
  const std::string record = started["record"];
  auto s = waitRunning(d);
  EXPECT_EQ(s["session_running"], true);
  EXPECT_EQ(s["session"]["exercise"], "assessment");
  EXPECT_EQ(s["session"]["patient"], "p-ok");
  EXPECT_EQ(s["session"]["channels"]["thumb"]["effort_max"], 2.0);

  for (const auto& [name, params] :
       std::vector<std::pair<std::string, nlohmann::json>>{{"resistance", {{"stiffness_per_rad", 1.0}}},
                                                           {"assistance", {{"period_s", 3.0}}},
                                                           {"record-pattern", nlohmann::json::object()},
                                                           {"grasp", {{"scene", "soft-ball"}}},
                                                           {"idle", nlohmann::json::object()},
                                                           {"assessment", nlohmann::json::object()}}) {
    EXPECT_EQ(d.ok({{"cmd", "exercise"}, {"exercise", name}, {"params", params}})["exercise"], name);
    nlohmann::json st;
    for (int i = 0; i < 200; ++i) {  // the loop takes the exercise at its next cycle
      st = d.ok({{"cmd", "status"}});
      if (st["session"]["exercise"] == name) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_EQ(st["session"]["exercise"], name);
    if (name == "record-pattern") std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  }
  // Playback needs the pattern recorded above; "mode" is an alias of "exercise".
  EXPECT_EQ(d.ok({{"cmd", "mode"}, {"exercise", "playback"}})["exercise"], "playback");

  EXPECT_EQ(d.ok({{"cmd", "limits"}})["effort_max"]["index"], 3.0);
  EXPECT_EQ(d.ok({{"cmd", "limits"}, {"effort_max", {{"index", 1.5}}}})["effort_max"]["index"], 1.5);
  EXPECT_EQ(d.ok({{"cmd", "reset"}})["clear_faults"], "sent");
  const auto summary = d.ok({{"cmd", "stop"}});
  EXPECT_EQ(summary["final_mode"], "safe") << summary.dump(2);
  EXPECT_EQ(d.ok({{"cmd", "status"}})["session_running"], false);
  const auto recs = d.ok({{"cmd", "recordings"}, {"patient", "p-ok"}});
  ASSERT_EQ(recs.size(), 1u);
  EXPECT_EQ(d.dir() + "/" + recs[0]["file"].get<std::string>(), record);

  record::SessionRecord rec;
  ASSERT_EQ(record::readRecord(record, rec), "");
  EXPECT_TRUE(rec.complete());
  int api_events = 0;
  for (const auto& e : rec.events) api_events += e["kind"].get<std::string>().rfind("api-", 0) == 0 ? 1 : 0;
  EXPECT_EQ(api_events, 7 + 1 + 1) << "exercise changes, the limit change and the reset are in the record";
}

TEST(ControlApi, MalformedAndInvalidRequestsAreRefusedAndChangeNothing) {
  ApiDaemon d;
  auto err = [](const std::string& line) { return nlohmann::json::parse(line).value("error", std::string()); };
  EXPECT_NE(err(d.raw("this is not json")).find("not valid JSON"), std::string::npos);
  EXPECT_NE(err(d.raw("[1,2]")).find("JSON object"), std::string::npos);
  EXPECT_NE(d.refused({{"nocmd", 1}}).find("'cmd'"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", 5}}).find("'cmd'"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "launch-missiles"}}).find("unknown command"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "status"}, {"verbose", true}}).find("'verbose'"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "stop"}}).find("no session"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "exercise"}, {"exercise", "assessment"}}).find("no session"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "reset"}}).find("no session"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "profile"}, {"patient", "../etc/passwd"}}).find("patient id"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"patient", "p-bad"}}).find("effort_max"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"patient", "nobody"}}).find("cannot read"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"exercise", "dance"}}).find("not one of"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"exercise", "resistance"}, {"params", {{"stiffness_per_rad", -1}}}})
                .find("stiffness_per_rad"),
            std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"device", "tcp:1.2.3.4"}}).find("device"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"seconds", "ten"}}).find("seconds"), std::string::npos);
  // 0.0001 s at 1 kHz would round to zero cycles, i.e. a session that runs until stopped.
  EXPECT_NE(d.refused({{"cmd", "start"}, {"seconds", 0.0001}}).find("field 'seconds': 0.0001 s is shorter than one host period"),
            std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "start"}, {"exercise", "playback"}}).find("no grip/release pattern"), std::string::npos);
  EXPECT_EQ(d.ok({{"cmd", "status"}})["session_running"], false) << "no refused start may start a session";
  EXPECT_EQ(d.ok({{"cmd", "recordings"}}).size(), 0u) << "no refused start may create a record";

  d.ok({{"cmd", "start"}, {"patient", "p-ok"}, {"exercise", "resistance"}});
  waitRunning(d);
  EXPECT_NE(d.refused({{"cmd", "start"}}).find("already running"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "exercise"}, {"exercise", "resistance"}, {"params", {{"stiffness_per_rad", 1e9}}}})
                .find("outside"),
            std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "exercise"}, {"exercise", "assistance"}, {"params", {{"speed", 2}}}}).find("unknown parameter"),
            std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "exercise"}, {"exercise", "grasp"}, {"params", {{"scene", "moon"}}}}).find("scene"),
            std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "exercise"}}).find("'exercise'"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "limits"}, {"effort_max", {{"index", 3.5}}}}).find("profile"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "limits"}, {"effort_max", {{"pinky", 1.0}}}}).find("unknown channel"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "limits"}, {"effort_max", {{"index", -1.0}}}}).find("(0, 3"), std::string::npos);
  EXPECT_NE(d.refused({{"cmd", "limits"}, {"effort_max", {{"index", "lots"}}}}).find("number"), std::string::npos);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto s = d.ok({{"cmd", "status"}});
  EXPECT_EQ(s["session"]["exercise"], "resistance") << "refused requests changed the exercise";
  EXPECT_EQ(d.ok({{"cmd", "limits"}})["effort_max"]["index"], 3.0) << "refused requests changed the limits";
  // An over-long request line is refused and its connection closed.
  const std::string huge = "{\"cmd\":\"status\",\"x\":\"" + std::string(70000, 'a') + "\"}";
  std::string answer;
  EXPECT_EQ(phalanx::host::api::callRaw(d.socket(), huge, answer), "");
  EXPECT_NE(answer.find("longer than"), std::string::npos) << answer.substr(0, 200);
  d.ok({{"cmd", "stop"}});
}

TEST(ControlApi, OnlyTheSocketFileGivesAccessAndNothingListensOnANetwork) {
  ApiDaemon d;
  struct stat st {};
  ASSERT_EQ(stat(d.socket().c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0660u) << "owner and group only";
  // Every socket the daemon holds is a UNIX socket: none of its inodes is in the TCP/UDP tables.
  d.ok({{"cmd", "start"}, {"exercise", "assessment"}});
  waitRunning(d);
  auto table = [](const char* path) {
    std::ifstream in(path);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  const std::string inet = table("/proc/net/tcp") + table("/proc/net/tcp6") + table("/proc/net/udp") + table("/proc/net/udp6");
  const std::string unix_table = table("/proc/net/unix");
  int sockets = 0;
  const std::string fd_dir = "/proc/" + std::to_string(d.process().pid()) + "/fd";
  for (int fd = 0; fd < 256; ++fd) {
    char target[128] = {};
    const ssize_t n = readlink((fd_dir + "/" + std::to_string(fd)).c_str(), target, sizeof target - 1);
    if (n <= 0 || std::string(target).rfind("socket:[", 0) != 0) continue;
    const std::string inode = std::string(target).substr(8, static_cast<size_t>(n) - 9);
    ++sockets;
    EXPECT_EQ(inet.find(" " + inode + " "), std::string::npos) << "socket inode " << inode << " is a network socket";
    EXPECT_NE(unix_table.find(" " + inode + " "), std::string::npos) << "socket inode " << inode << " is not UNIX";
  }
  EXPECT_GE(sockets, 1);
  d.ok({{"cmd", "stop"}});
  if (geteuid() != 0) GTEST_SKIP() << "the other-user check needs root to switch user";
  // Another user (nobody, not in our group) cannot connect: the socket file's own permissions refuse it (the
  // directory is opened up so that it is not the directory that refuses).
  ASSERT_EQ(chmod(d.dir().c_str(), 0755), 0);
  const pid_t child = fork();
  if (child == 0) {
    if (setgid(65534) != 0 || setuid(65534) != 0) _exit(3);
    std::string resp;
    const std::string e = phalanx::host::api::callRaw(d.socket(), "{\"cmd\":\"status\"}", resp, 2000);
    _exit(e.find("Permission denied") != std::string::npos ? 0 : (e.empty() ? 1 : 2));
  }
  int status = 0;
  waitpid(child, &status, 0);
  EXPECT_EQ(WEXITSTATUS(status), 0) << "an unauthorised user reached the API (1) or failed otherwise (2/3)";
}

namespace {
nlohmann::json reportMetrics(const std::string& html) {
  const std::string open = "<script type='application/json' id='metrics'>";
  const auto a = html.find(open);
  const auto b = html.find("</script>", a);
  if (a == std::string::npos || b == std::string::npos) return nullptr;
  std::string text = html.substr(a + open.size(), b - a - open.size());
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
    for (size_t p; (p = text.find(from)) != std::string::npos;) text.replace(p, from.size(), to);
  }
  return nlohmann::json::parse(text, nullptr, false);
}
std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
}  // namespace

TEST(SessionReport, WrittenAtSessionEndFromASimulatedSessionAndComparedWithThePreviousOne) {
  const std::string dir = tempDir();
  for (int run = 0; run < 2; ++run) {
    const std::string stem = dir + "/s" + std::to_string(run);
    std::vector<std::string> args = {binPath("phalanxd"), "--device", "sim:glove5", "--scenario", "close-open",
                                     "--no-realtime", "--seconds", "3", "--seed", std::to_string(run + 1),
                                     "--session-record", stem + ".phrec", "--exercise", "assessment",
                                     "--report", stem + ".html", "--json"};
    if (run == 1) {
      args.push_back("--previous-record");
      args.push_back(dir + "/s0.phrec");
    }
    Process d(args);
    ASSERT_EQ(d.wait(30000), 0) << d.stderrText();
    const auto summary = nlohmann::json::parse(d.stdoutText(), nullptr, false);
    ASSERT_FALSE(summary.is_discarded()) << d.stdoutText();
    EXPECT_EQ(summary["report"]["path"], stem + ".html") << summary.dump(2);
  }
  const std::string html = slurp(dir + "/s1.html");
  EXPECT_NE(html.find("<svg"), std::string::npos);
  EXPECT_EQ(html.find("http://"), html.find("http://www.w3.org/2000/svg")) << "no external assets (no CDN)";
  EXPECT_EQ(html.find("https://"), std::string::npos) << "no external assets (no CDN)";
  EXPECT_EQ(html.find("<script src"), std::string::npos);
  EXPECT_NE(html.find("Grey bars: previous session"), std::string::npos);
  const nlohmann::json m = reportMetrics(html);
  ASSERT_TRUE(m.is_object());
  EXPECT_EQ(m["rom_source"], "assessment");
  ASSERT_EQ(m["rom_deg"].size(), 15u);
  // The simulated close/open maneuver moves every index joint through tens of degrees.
  for (const char* j : {"index_mcp", "index_pip", "index_dip"}) {
    const double range = m["rom_deg"][j][1].get<double>() - m["rom_deg"][j][0].get<double>();
    EXPECT_GT(range, 40.0) << j;
    EXPECT_LT(range, 130.0) << j;
  }
  ASSERT_EQ(m["transparency"].size(), 5u);
  EXPECT_LT(m["transparency"]["index"]["interaction_rms"].get<double>(), 0.2);
  EXPECT_GT(m["duration_s"].get<double>(), 2.5);
  EXPECT_TRUE(m["complete"].get<bool>());
  std::system(("rm -rf " + dir).c_str());
}
