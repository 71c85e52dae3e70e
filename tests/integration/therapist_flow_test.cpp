// Issue #25 item 1 and 6: the stumbles a therapist hit following the README and docs/therapy.md, each as a
// regression test against the real processes (phalanxd --api, the phalanx CLI, firmware-sim), and the FHIR export
// validated by an independent implementation of the FHIR schema (fhir.resources, PyPI, tools/fhir-validate.py).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "phalanx/host/api/client.h"
#include "phalanx/host/record/record_reader.h"
#include "process.h"

using phalanx::test::binPath;
using phalanx::test::Process;

namespace {

std::string tempDir() {
  char tmpl[] = "/tmp/phalanx-flow-XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d == nullptr ? std::string("/tmp") : std::string(d);
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> linesOf(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

/// A number printed as negative zero: "-0", "-0.0", "-0.00" … not followed by another digit.
bool hasNegativeZero(const std::string& text) {
  for (std::size_t p = text.find("-0"); p != std::string::npos; p = text.find("-0", p + 1)) {
    // A number starts a word ("p-ok-0a…" in a path is none).
    if (p > 0 && std::string(" \t(=[,:/").find(text[p - 1]) == std::string::npos) continue;
    std::size_t q = p + 2;
    if (q < text.size() && text[q] == '.') {
      ++q;
      while (q < text.size() && text[q] == '0') ++q;
    }
    if (q >= text.size() || !std::isalnum(static_cast<unsigned char>(text[q]))) return true;
  }
  return false;
}

/// Position of `needle` in `text` (npos → INT_MAX so an order check on a missing word fails).
long at(const std::string& text, const std::string& needle) {
  const auto p = text.find(needle);
  return p == std::string::npos ? LONG_MAX : static_cast<long>(p);
}

const char* kGloveProfile =
    "version: 1\npatient: p-ok\ndevice: glove5\n"
    "rom_deg: {thumb_mcp: [0, 50], index_pip: [0, 90], index_mcp: [0, 70], little_dip: [0, 40]}\n"
    "limits:\n  effort_max: {default: 3.0, thumb: 2.0}\n  range_deg: {index_pip: [0, 90]}\n";

/// phalanxd --api on a simulated glove, profiles in its temporary directory, records where given.
class Daemon {
 public:
  explicit Daemon(const std::string& records_sub = "records", std::vector<std::string> extra = {})
      : dir_(tempDir()), socket_(dir_ + "/api.sock"), records_(dir_ + "/" + records_sub) {
    std::ofstream(dir_ + "/p-ok.yaml") << kGloveProfile;
    std::vector<std::string> argv = {binPath("phalanxd"), "--api", socket_, "--records-dir", records_,
                                     "--profiles-dir", dir_, "--no-realtime", "--device", "sim:glove5",
                                     "--scenario", "close-open",
                                     // causeCommandTimeout() stops the daemon for 400 ms: the telemetry timeout
                                     // (default 500 ms) gets a wide margin on a loaded machine.
                                     "--telemetry-timeout-ms", "3000",
                                     // and a 100 ms command timeout: a loaded machine's stalls do not latch
                                     // faults of their own before the one the test causes.
                                     "--command-timeout-ms", "100"};
    // An option of `extra` that is already above replaces its value (e.g. a longer --command-timeout-ms).
    for (std::size_t i = 0; i < extra.size(); ++i) {
      const auto at = extra[i].rfind("--", 0) == 0 ? std::find(argv.begin(), argv.end(), extra[i]) : argv.end();
      if (at != argv.end() && at + 1 != argv.end() && i + 1 < extra.size()) {
        *(at + 1) = extra[++i];
      } else {
        argv.push_back(extra[i]);
      }
    }
    proc_ = std::make_unique<Process>(argv);
    EXPECT_EQ(proc_->readStdoutLine(10000), "API " + socket_) << proc_->stderrText();
  }
  ~Daemon() {
    proc_->signal(SIGCONT);
    proc_->signal(SIGTERM);
    proc_->wait(15000);
    std::system(("rm -rf " + dir_).c_str());
  }
  /// The phalanx CLI with PHALANX_SOCKET naming this daemon (no --socket needed); waits for its exit.
  Process& cli(std::vector<std::string> args, int* rc) {
    std::vector<std::string> argv = {"/usr/bin/env", "PHALANX_SOCKET=" + socket_, "PHALANX_CLIENT_CONFIG=/nonexistent-ok",
                                     binPath("phalanx")};
    argv.insert(argv.end(), args.begin(), args.end());
    // PHALANX_SOCKET wins over the config file, so the config path above is never read.
    clis_.push_back(std::make_unique<Process>(argv));
    *rc = clis_.back()->wait(60000);
    return *clis_.back();
  }
  nlohmann::json api(const nlohmann::json& req) {
    nlohmann::json resp;
    EXPECT_EQ(phalanx::host::api::call(socket_, req, resp), "") << req.dump();
    return resp.value("result", nlohmann::json());
  }
  const std::string& dir() const { return dir_; }
  const std::string& socket() const { return socket_; }
  const std::string& records() const { return records_; }
  Process& process() { return *proc_; }

 private:
  std::string dir_, socket_, records_;
  std::unique_ptr<Process> proc_;
  std::vector<std::unique_ptr<Process>> clis_;
};

/// Waits (bounded) until status satisfies pred; returns the last status.
template <typename Pred>
nlohmann::json waitFor(Daemon& d, Pred pred, int timeout_ms = 20000) {
  nlohmann::json s;
  for (int waited = 0; waited < timeout_ms; waited += 50) {
    s = d.api({{"cmd", "status"}});
    if (pred(s)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return s;
}

/// A real fault, caused the way a busy computer causes it: phalanxd stopped (SIGSTOP) for 400 ms, beyond the
/// 100 ms command timeout and well inside the daemon's 3 s telemetry timeout: firmware-sim, a separate process, latches
/// command-timeout and goes safe. Returns the status that shows it.
nlohmann::json causeCommandTimeout(Daemon& d) {
  d.process().signal(SIGSTOP);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  d.process().signal(SIGCONT);
  return waitFor(d, [](const nlohmann::json& s) {
    return s.contains("session") && s["session"].value("faults", "none").find("command-timeout") != std::string::npos;
  });
}

}  // namespace

// Issue: `--records-dir records` with no records/ directory: `phalanx start` printed the paths and exited 0, the
// session failed two seconds later, the cause only on the daemon's stderr.
TEST(TherapistFlow, AMissingRecordsDirectoryIsCreatedAndAStartThatFailsExitsNonZero) {
  Daemon d("new/records");
  struct stat st {};
  ASSERT_EQ(stat(d.records().c_str(), &st), 0) << "created at daemon start: " << d.process().stderrText();
  EXPECT_TRUE(S_ISDIR(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0750u) << "patient data: not world-readable";
  int rc = 0;
  Process& start = d.cli({"start", "--patient", "p-ok", "--seed", "2"}, &rc);
  EXPECT_EQ(rc, 0) << start.stdoutText() << start.stderrText();
  EXPECT_NE(start.stdoutText().find("record: " + d.records() + "/p-ok-"), std::string::npos) << start.stdoutText();
  EXPECT_TRUE(d.api({{"cmd", "status"}})["session"].contains("t_s")) << "start returned once the session ran";
  Process& stop = d.cli({"stop"}, &rc);
  EXPECT_EQ(rc, 0) << stop.stderrText();

  // A records directory that cannot be created: the daemon says which and why, before serving anything.
  const std::string dir = tempDir();
  std::ofstream(dir + "/afile") << "x";
  Process bad({binPath("phalanxd"), "--api", dir + "/s.sock", "--records-dir", dir + "/afile/records",
               "--profiles-dir", dir, "--no-realtime"});
  EXPECT_EQ(bad.wait(10000), 2);
  EXPECT_NE(bad.stderrText().find("--records-dir " + dir + "/afile/records: cannot create " + dir + "/afile/records: Not a directory"),
            std::string::npos) << bad.stderrText();

  // A session that fails after `start` answered (here: no firmware-sim to run): `phalanx start` says why, exit 4.
  Daemon broken("records", {"--firmware-sim", "/nonexistent/firmware-sim"});
  Process& failed = broken.cli({"start", "--patient", "p-ok"}, &rc);
  EXPECT_EQ(rc, 4) << failed.stdoutText() << failed.stderrText();
  EXPECT_NE(failed.stderrText().find("the session did not start: "), std::string::npos) << failed.stderrText();
  std::printf("start of a failing session: %s", failed.stderrText().c_str());
  std::system(("rm -rf " + dir).c_str());
}

// Issue: every client command needed --socket repeated.
TEST(TherapistFlow, TheClientFindsTheSocketInPhalanxSocketOrItsConfigFile) {
  Daemon d;
  const std::string cfg = d.dir() + "/client.yaml";
  std::ofstream(cfg) << "socket: " << d.socket() << "\n";
  auto run = [&](std::vector<std::string> env, std::vector<std::string> args) {
    std::vector<std::string> argv = {"/usr/bin/env", "-u", "PHALANX_SOCKET"};
    argv.insert(argv.end(), env.begin(), env.end());
    argv.push_back(binPath("phalanx"));
    argv.insert(argv.end(), args.begin(), args.end());
    auto p = std::make_unique<Process>(argv);
    p->wait(20000);
    return p;
  };
  auto viaConfig = run({"PHALANX_CLIENT_CONFIG=" + cfg}, {"profiles"});
  EXPECT_EQ(viaConfig->wait(0), 0) << viaConfig->stderrText();
  EXPECT_NE(viaConfig->stdoutText().find("p-ok.yaml"), std::string::npos) << viaConfig->stdoutText();
  auto viaEnv = run({"PHALANX_SOCKET=" + d.socket(), "PHALANX_CLIENT_CONFIG=/nonexistent"}, {"profiles"});
  EXPECT_EQ(viaEnv->wait(0), 0) << viaEnv->stderrText();
  // --socket wins over both; PHALANX_SOCKET over the config.
  auto flagWins = run({"PHALANX_SOCKET=/nonexistent.sock"}, {"profiles", "--socket", d.socket()});
  EXPECT_EQ(flagWins->wait(0), 0) << flagWins->stderrText();
  auto envWins = run({"PHALANX_SOCKET=" + d.dir() + "/nothing.sock", "PHALANX_CLIENT_CONFIG=" + cfg}, {"profiles"});
  EXPECT_EQ(envWins->wait(0), 3);
  EXPECT_NE(envWins->stderrText().find(d.dir() + "/nothing.sock"), std::string::npos) << envWins->stderrText();
  // A config file with an unknown key is refused, naming the file and the key.
  std::ofstream(d.dir() + "/bad.yaml") << "sockett: /x\n";
  auto bad = run({"PHALANX_CLIENT_CONFIG=" + d.dir() + "/bad.yaml"}, {"status"});
  EXPECT_EQ(bad->wait(0), 2);
  EXPECT_NE(bad->stderrText().find(d.dir() + "/bad.yaml: sockett: unknown key"), std::string::npos) << bad->stderrText();
}

// Issue: profile, limits, reset and stop printed raw JSON (-29.999999999999996, -0.0, ~70 lines on stop); fingers
// alphabetical; a missing profile said only "cannot read profile".
TEST(TherapistFlow, ClientOutputIsForPeopleInAnatomicalOrderAndJsonOnlyWithJson) {
  Daemon d;
  int rc = 0;
  auto noJsonNoise = [](const std::string& out) {
    EXPECT_EQ(out.find('{'), std::string::npos) << out;
    EXPECT_EQ(out.find("99999"), std::string::npos) << out;
    EXPECT_EQ(out.find("00000"), std::string::npos) << out;
    EXPECT_FALSE(hasNegativeZero(out)) << out;
  };
  const std::string profile = d.cli({"profile", "p-ok"}, &rc).stdoutText();
  EXPECT_EQ(rc, 0);
  noJsonNoise(profile);
  std::printf("--- phalanx profile p-ok\n%s", profile.c_str());
  EXPECT_LT(at(profile, "thumb_mcp"), at(profile, "index_mcp"));
  EXPECT_LT(at(profile, "index_mcp"), at(profile, "index_pip"));
  EXPECT_LT(at(profile, "index_pip"), at(profile, "little_dip"));
  const std::string missing = d.cli({"profile", "nobody"}, &rc).stderrText();
  EXPECT_EQ(rc, 1);
  EXPECT_NE(missing.find("no profile for patient 'nobody': cannot read " + d.dir() + "/nobody.yaml: it does not exist"),
            std::string::npos) << missing;
  EXPECT_NE(missing.find("profiles in " + d.dir() + ": p-ok"), std::string::npos) << missing;
  const std::string no_start = d.cli({"start", "--patient", "nobody"}, &rc).stderrText();
  EXPECT_EQ(rc, 1);
  EXPECT_NE(no_start.find(d.dir() + "/nobody.yaml: it does not exist"), std::string::npos) << no_start;

  Process& start = d.cli({"start", "--patient", "p-ok", "--seed", "4"}, &rc);
  ASSERT_EQ(rc, 0) << start.stderrText();
  const std::string limits = d.cli({"limits", "--effort-max", "index=1.5"}, &rc).stdoutText();
  EXPECT_EQ(rc, 0);
  noJsonNoise(limits);
  std::printf("--- phalanx limits --effort-max index=1.5\n%s", limits.c_str());
  EXPECT_LT(at(limits, "thumb"), at(limits, "index"));
  EXPECT_LT(at(limits, "index"), at(limits, "middle"));
  EXPECT_LT(at(limits, "ring"), at(limits, "little"));
  EXPECT_NE(limits.find("index    1.5\n"), std::string::npos) << limits;
  EXPECT_LT(at(limits, "thumb_cmc"), at(limits, "index_mcp"));
  EXPECT_LT(at(limits, "index_mcp"), at(limits, "index_pip"));
  EXPECT_LT(at(limits, "index_pip"), at(limits, "index_dip"));
  const std::string limits_json = d.cli({"limits", "--json"}, &rc).stdoutText();
  EXPECT_FALSE(nlohmann::json::parse(limits_json, nullptr, false).is_discarded()) << "--json is JSON";
  const std::string status = d.cli({"status"}, &rc).stdoutText();
  noJsonNoise(status);
  EXPECT_LT(at(status, "  thumb"), at(status, "  index"));
  EXPECT_LT(at(status, "  ring"), at(status, "  little"));
  const std::string reset = d.cli({"reset"}, &rc).stdoutText();
  EXPECT_EQ(rc, 0);
  EXPECT_NE(reset.find("reset sent"), std::string::npos) << reset;
  const std::string stop = d.cli({"stop"}, &rc).stdoutText();
  EXPECT_EQ(rc, 0);
  std::printf("--- phalanx stop\n%s", stop.c_str());
  noJsonNoise(stop);
  EXPECT_LE(linesOf(stop).size(), 5u) << "a short summary: " << stop;
  EXPECT_NE(stop.find("session ended: "), std::string::npos);
  EXPECT_NE(stop.find("report: " + d.records() + "/p-ok-"), std::string::npos) << stop;
}

// Issue: the --live view was one ~186-column line that wrapped below ~190 columns, its symbols explained nowhere.
TEST(TherapistFlow, TheLiveViewFitsEightyColumnsAndExplainsItself) {
  for (const std::string device : {"sim:glove5", "sim:sea_finger"}) {
    Process p({binPath("phalanxd"), "--device", device, "--scenario", "close-open", "--no-realtime", "--seconds",
               "1.5", "--live"});
    ASSERT_EQ(p.wait(30000), 0) << p.stderrText();
    const std::string err = p.stderrText();
    std::size_t widest = 0, drawn = 0;
    for (std::string line : linesOf(err)) {
      // What the terminal shows: escape sequences take no column; a carriage return starts the line again.
      std::string shown;
      for (std::size_t i = 0; i < line.size(); ++i) {
        if (line[i] == '\033') {
          while (i < line.size() && !std::isalpha(static_cast<unsigned char>(line[i]))) ++i;
          continue;
        }
        if (line[i] == '\r') {
          shown.clear();
          continue;
        }
        shown += line[i];
      }
      // Only the live view's own lines (the legend and the redrawn block), not the daemon's messages.
      if (shown.rfind("phalanxd", 0) == 0 || shown.rfind("firmware-sim", 0) == 0 || shown.rfind("WARNING", 0) == 0 ||
          shown.empty()) {
        continue;
      }
      std::size_t cols = 0;
      for (unsigned char c : shown) cols += (c & 0xC0) != 0x80 ? 1 : 0;  // UTF-8: count code points
      widest = std::max(widest, cols);
      if (shown.find("  t ") == 0) ++drawn;
    }
    std::printf("%s: live view widest line %zu columns, %zu updates\n", device.c_str(), widest, drawn);
    EXPECT_LE(widest, 80u) << err;
    EXPECT_GE(drawn, 3u) << "the view was drawn: " << err;
    EXPECT_NE(err.find("Live view, every 0.1 s"), std::string::npos) << "a legend: " << err;
    EXPECT_NE(err.find("device = the mode the device reports"), std::string::npos);
    if (device == "sim:glove5") {
      EXPECT_NE(err.find("force = measured fingertip pad force"), std::string::npos);
      EXPECT_NE(err.find("  thumb "), std::string::npos);
      EXPECT_LT(at(err, "  thumb "), at(err, "  index "));
      EXPECT_FALSE(hasNegativeZero(err)) << "no negative zero";
    } else {
      EXPECT_NE(err.find("finger torque = "), std::string::npos);
      EXPECT_FALSE(hasNegativeZero(err)) << "no negative zero";
    }
  }
}

// Issue: a red command-timeout badge with no word on what it means or what to do; the report counted time the
// glove was locked after a fault as exercise; its change column was not marked better or worse; the request
// table was raw JSON.
TEST(TherapistFlow, AFaultIsExplainedAndTheLockedTimeIsLeftOutOfTheReport) {
  Daemon d;
  int rc = 0;
  std::string first_record;
  for (int run = 0; run < 2; ++run) {
    ASSERT_EQ((d.cli({"start", "--patient", "p-ok", "--seed", std::to_string(run + 7)}, &rc), rc), 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));
    if (run == 1) {
      d.cli({"exercise", "resistance", "--params", "{\"stiffness_per_rad\": 1.5}"}, &rc);
      EXPECT_EQ(rc, 0);
      d.cli({"limits", "--effort-max", "index=1.5"}, &rc);
      const nlohmann::json faulted = causeCommandTimeout(d);
      ASSERT_NE(faulted["session"].value("faults", ""), "none") << faulted.dump();
      ASSERT_TRUE(faulted["session"].contains("fault_guidance")) << faulted.dump();
      const std::string status = d.cli({"status"}, &rc).stdoutText();
      std::printf("--- phalanx status with a fault\n%s", status.c_str());
      EXPECT_NE(status.find("FAULT command-timeout"), std::string::npos) << status;
      EXPECT_NE(status.find("what happened: The device stopped receiving commands"), std::string::npos) << status;
      EXPECT_NE(status.find("patient safe:  Yes"), std::string::npos) << status;
      EXPECT_NE(status.find("what to do:    Check the cable"), std::string::npos) << status;
      std::this_thread::sleep_for(std::chrono::milliseconds(800));  // locked: not exercise
      d.cli({"reset"}, &rc);
      waitFor(d, [](const nlohmann::json& s) { return s.contains("session") && s["session"].value("faults", "") == "none"; });
      std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    }
    const std::string stop = d.cli({"stop"}, &rc).stdoutText();
    ASSERT_EQ(rc, 0) << stop;
  }
  const nlohmann::json recs = d.api({{"cmd", "recordings"}, {"patient", "p-ok"}});
  ASSERT_EQ(recs.size(), 2u) << recs.dump();
  const std::string html = slurp(d.records() + "/" + recs[1]["report"].get<std::string>());
  ASSERT_FALSE(html.empty());
  std::ofstream(binPath("") + "/../therapist-flow-report.html") << html;  // a test artefact under build/
  const auto m0 = html.find("<script type='application/json' id='metrics'>");
  ASSERT_NE(m0, std::string::npos);
  std::string mj = html.substr(m0 + 45, html.find("</script>", m0) - m0 - 45);
  for (auto [from, to] : {std::pair<std::string, std::string>{"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
    for (std::size_t p; (p = mj.find(from)) != std::string::npos;) mj.replace(p, from.size(), to);
  }
  const nlohmann::json m = nlohmann::json::parse(mj, nullptr, false);
  ASSERT_TRUE(m.is_object()) << mj.substr(0, 200);
  const double excluded = m["excluded_s"].get<double>();
  std::printf("report: %.2f s excluded in %zu period(s): %s\n", excluded, m["excluded_periods"].size(),
              m["excluded_periods"].dump().c_str());
  EXPECT_GT(excluded, 0.5) << "the 0.8 s locked after the fault, at least";
  EXPECT_LT(excluded, m["duration_s"].get<double>() - 2.0);
  EXPECT_NE(m["excluded_periods"][0]["faults"].get<std::string>().find("command-timeout"), std::string::npos);
  EXPECT_NE(html.find("excluded from every exercise metric below"), std::string::npos);
  EXPECT_NE(html.find("<h3>What the faults mean</h3>"), std::string::npos);
  EXPECT_NE(html.find("The device stopped receiving commands"), std::string::npos);
  // Anatomical order in the range-of-motion table, and the change marked.
  EXPECT_LT(at(html, "<tr><td>thumb_cmc</td>"), at(html, "<tr><td>thumb_mcp</td>"));
  EXPECT_LT(at(html, "<tr><td>thumb_ip</td>"), at(html, "<tr><td>index_mcp</td>"));
  EXPECT_LT(at(html, "<tr><td>index_mcp</td>"), at(html, "<tr><td>index_pip</td>"));
  EXPECT_LT(at(html, "<tr><td>index_pip</td>"), at(html, "<tr><td>index_dip</td>"));
  EXPECT_LT(at(html, "<tr><td>ring_dip</td>"), at(html, "<tr><td>little_mcp</td>"));
  int marked = 0;
  for (const char* w : {"▲ better", "▼ worse", "(no change)"}) {
    for (std::size_t p = 0; (p = html.find(w, p)) != std::string::npos; ++p) ++marked;
  }
  EXPECT_EQ(marked, 15) << "every joint's change is marked better, worse or no change";
  // The therapist's requests in words, not JSON.
  EXPECT_NE(html.find("exercise changed to resistance</td><td class='text'>"), std::string::npos);
  EXPECT_NE(html.find("stiffness_per_rad 1.5"), std::string::npos);
  EXPECT_NE(html.find("effort limit lowered</td><td class='text'>index 1.5 N"), std::string::npos);
  EXPECT_NE(html.find("reset faults (ClearFaults sent)"), std::string::npos);
  EXPECT_GT(at(html, "{&quot;"), static_cast<long>(m0)) << "no raw JSON before the embedded metrics";

  // FHIR export of the faulted session (item 6), validated by fhir.resources.
  const std::string rec = d.records() + "/" + recs[1]["file"].get<std::string>();
  const std::string fhir = d.dir() + "/session.fhir.json";
  Process& ex = d.cli({"record", "fhir", rec, "--out", fhir}, &rc);
  ASSERT_EQ(rc, 0) << ex.stderrText();
  const nlohmann::json bundle = nlohmann::json::parse(slurp(fhir), nullptr, false);
  ASSERT_TRUE(bundle.is_object());
  EXPECT_EQ(bundle["type"], "collection");
  EXPECT_EQ(bundle["entry"][0]["resource"]["subject"]["reference"], "Patient/p-ok");
  EXPECT_EQ(bundle["entry"][0]["resource"]["bodySite"]["text"], "thumb CMC joint") << "anatomical order";
  std::ofstream(binPath("") + "/../therapist-flow.fhir.json") << bundle.dump(2);  // artefact
  Process validate({"/usr/bin/env", "python3", std::string(PHALANX_SOURCE_DIR) + "/tools/fhir-validate.py", fhir});
  const int vrc = validate.wait(60000);
  if (vrc == 2 && std::getenv("CI") == nullptr) {
    GTEST_SKIP() << "fhir.resources is not installed (tools/setup.sh --test installs it): " << validate.stderrText();
  }
  std::printf("%s", validate.stdoutText().c_str());
  EXPECT_EQ(vrc, 0) << validate.stdoutText() << validate.stderrText();
  // The validator can fail: the same bundle with an Observation missing its required status is refused.
  nlohmann::json broken = bundle;
  broken["entry"][1]["resource"].erase("status");
  std::ofstream(d.dir() + "/broken.json") << broken.dump();
  Process refuse({"/usr/bin/env", "python3", std::string(PHALANX_SOURCE_DIR) + "/tools/fhir-validate.py", d.dir() + "/broken.json"});
  EXPECT_EQ(refuse.wait(60000), 1) << refuse.stdoutText();
  EXPECT_NE(refuse.stdoutText().find("status"), std::string::npos) << refuse.stdoutText();
}

// ---- Issue #25 item 2: session plans, presets, pause/resume, self-training (docs/therapy.md "Session plan") ----
namespace {

const char* kPlanProfile =
    "version: 1\npatient: p-plan\ndevice: glove5\n"
    "rom_deg: {index_mcp: [0, 70], index_pip: [0, 90], index_dip: [0, 40]}\n"
    "limits:\n  effort_max: {default: 3.0}\n"
    "presets:\n  gentle: {exercise: resistance, params: {stiffness_per_rad: 0.5}}\n"
    "  strong: {exercise: resistance, params: {stiffness_per_rad: 8}}\n"
    "self_training:\n  allowed: [strong, assessment]\n  max_session_s: 4\n  effort_scale: 0.5\n"
    "plans:\n  warmup: {steps: [{exercise: assessment, duration_s: 60, repetitions: 3}, {preset: gentle, duration_s: 2}]}\n"
    "  short: {steps: [{exercise: assessment, duration_s: 5}]}\n"
    "  alone: {steps: [{preset: strong, duration_s: 2}]}\n";

/// A daemon whose profiles directory also holds p-plan (presets, self-training). A 1 s command timeout: these
/// tests count session time, and a loaded machine's stalls must not latch faults that stop the plan's clock.
struct PlanDaemon : Daemon {
  PlanDaemon() : Daemon("records", {"--command-timeout-ms", "1000"}) { std::ofstream(dir() + "/p-plan.yaml") << kPlanProfile; }
  /// The refusal of a request ("" when it was accepted).
  std::string refusal(const nlohmann::json& req) {
    nlohmann::json resp;
    EXPECT_EQ(phalanx::host::api::call(socket(), req, resp), "");
    return resp.value("ok", false) ? "" : resp.value("error", std::string("?"));
  }
  nlohmann::json plan() { return api({{"cmd", "status"}})["session"].value("plan", nlohmann::json()); }
};

bool ended(const nlohmann::json& s) { return !s.value("session_running", true) && s.contains("last_session"); }

/// The record of the last session, read with the project's reader.
phalanx::host::record::SessionRecord lastRecord(Daemon& d) {
  const nlohmann::json st = d.api({{"cmd", "status"}});
  phalanx::host::record::SessionRecord rec;
  const std::string path = st["last_session"]["session_record"].value("path", std::string());
  EXPECT_EQ(phalanx::host::record::readRecord(path, rec), "") << path;
  return rec;
}

std::size_t auxIndex(const phalanx::host::record::SessionRecord& rec, const std::string& name) {
  const auto& names = rec.header["aux"];
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return i;
  }
  ADD_FAILURE() << "no aux " << name;
  return 0;
}

std::vector<nlohmann::json> eventsOf(const phalanx::host::record::SessionRecord& rec, const std::string& kind) {
  std::vector<nlohmann::json> out;
  for (const auto& e : rec.events) {
    if (e.value("kind", std::string()) == kind) out.push_back(e);
  }
  return out;
}

}  // namespace

TEST(SessionPlanFlow, ABadPlanIsRefusedNamingTheFieldAndChangesNothing) {
  PlanDaemon d;
  const nlohmann::json ok_step = {{"exercise", "assessment"}, {"duration_s", 5}};
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", {{"steps", {ok_step, {{"exercise", "resistence"}, {"duration_s", 5}}}}}}},
       "plan.steps[1].exercise: 'resistence' is not one of idle, assessment, resistance, assistance, record-pattern, "
       "playback, grasp, tardieu, passive-rom, max-force"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", {{"steps", {{{"exercise", "assessment"}, {"duration_s", 0}}}}}}},
       "plan.steps[0].duration_s: must be in (0, 3600] s, got 0"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", {{"steps", {{{"preset", "gentel"}, {"duration_s", 5}}}}}}},
       "plan.steps[0].preset: 'gentel' is not a preset of patient p-plan (presets: gentle, strong)"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"exercise", "assessment"}, {"plan", {{"steps", {ok_step}}}}},
       "field 'plan': a plan names each step's exercise (leave out exercise, preset and params)"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"preset", "gentle"}, {"params", nlohmann::json::object()}},
       "field 'preset': give a preset or an exercise with params, not both"},
      {{{"cmd", "start"}, {"preset", "gentle"}}, "field 'preset': 'gentle' is not a preset of this session (no patient profile)"},
      {{{"cmd", "start"}, {"patient", "p-ok"}, {"self_training", true}},
       "field 'self_training': the profile of patient p-ok does not allow self-training (it has no self_training section)"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"self_training", true}, {"plan", {{"steps", {{{"preset", "gentle"}, {"duration_s", 5}}}}}}},
       "plan.steps[0]: 'gentle' is not allowed in self-training for patient p-plan (allowed: assessment, strong)"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"self_training", true}, {"exercise", "resistance"}},
       "self-training: 'resistance' is not allowed for patient p-plan (allowed: assessment, strong)"},
      {{{"cmd", "start"}, {"self_training", "yes"}}, "field 'self_training': expected true or false"},
      {{{"cmd", "pause"}}, "no session is running (nothing to pause)"},
      {{{"cmd", "resume"}}, "no session is running (nothing to resume)"},
      {{{"cmd", "pause"}, {"now", true}}, "field 'now' is not accepted by 'pause' (it takes no fields)"},
  };
  for (const auto& [req, error] : cases) {
    EXPECT_EQ(d.refusal(req), error) << req.dump();
    EXPECT_FALSE(d.api({{"cmd", "status"}})["session_running"].get<bool>()) << req.dump();
  }
  EXPECT_TRUE(d.api({{"cmd", "recordings"}}).empty()) << "a refused start creates no record";
  // The CLI passes a plan file through; a bad one is refused by the daemon word for word, exit 1.
  std::ofstream(d.dir() + "/bad-plan.yaml") << "steps:\n  - {exercise: assessment, duration_s: 5, repetitions: 2.5}\n";
  int rc = 0;
  Process& bad = d.cli({"start", "--patient", "p-plan", "--plan", d.dir() + "/bad-plan.yaml"}, &rc);
  EXPECT_EQ(rc, 1);
  EXPECT_EQ(bad.stderrText(), "phalanx: refused: plan.steps[0].repetitions: expected a whole number from 0 to 1000\n");
  std::ofstream(d.dir() + "/dup-plan.yaml") << "steps: []\nsteps: []\n";
  Process& dup = d.cli({"start", "--patient", "p-plan", "--plan", d.dir() + "/dup-plan.yaml"}, &rc);
  EXPECT_EQ(rc, 2);
  EXPECT_NE(dup.stderrText().find("dup-plan.yaml: steps: duplicate key (line 2; first at line 1)"), std::string::npos)
      << dup.stderrText();
  // The profiles listing carries the presets for the dashboard's exercise choice.
  bool listed = false;
  for (const auto& p : d.api({{"cmd", "profiles"}})) {
    if (p.value("patient", "") != "p-plan") continue;
    listed = true;
    EXPECT_EQ(p["presets"]["strong"]["exercise"], "resistance");
    EXPECT_EQ(p["presets"]["strong"]["params"]["stiffness_per_rad"], 8);
    EXPECT_TRUE(p["self_training"].get<bool>());
  }
  EXPECT_TRUE(listed);
}

TEST(SessionPlanFlow, APlanStepsOnAtItsRepetitionsOrItsDurationCountedFromTheHandsMotion) {
  PlanDaemon d;
  // Index channel: the profile's range 0…200° (70 + 90 + 40), thresholds 50° / 150°; the simulated hand closes and
  // opens every 1.5 s (glove_plant.cpp kCloseOpen: q_index ≈ 13° … 234°).
  std::ofstream(d.dir() + "/plan.yaml") << "steps:\n  - {exercise: assessment, duration_s: 60, repetitions: 3}\n"
                                           "  - {preset: gentle, duration_s: 2}\n";
  int rc = 0;
  Process& start = d.cli({"start", "--patient", "p-plan", "--plan", d.dir() + "/plan.yaml"}, &rc);
  ASSERT_EQ(rc, 0) << start.stdoutText() << start.stderrText();
  const std::string status = d.cli({"status"}, &rc).stdoutText();
  std::printf("--- phalanx status during a plan\n%s", status.c_str());
  EXPECT_NE(status.find("  plan: step 1 of 2, assessment, "), std::string::npos) << status;
  EXPECT_NE(status.find("    1. assessment, 60 s, 3 repetitions: running"), std::string::npos) << status;
  EXPECT_NE(status.find("    2. resistance (preset gentle), 2 s: to do"), std::string::npos) << status;
  // The exercise shown is the one the step runs.
  const nlohmann::json second = waitFor(d, [](const nlohmann::json& s) {
    return !s.value("session_running", false) ||
           (s["session"]["plan"].value("step", 0) == 2 && s["session"].value("exercise", "") == "resistance");
  });
  ASSERT_TRUE(second["session_running"].get<bool>()) << "the session ended before step 2 showed: " << second.dump();
  EXPECT_EQ(second["session"]["plan"]["preset"], "gentle");
  EXPECT_EQ(second["session"]["plan"]["list"][0]["repetitions"], 3);
  // The last step's end ends the session by itself.
  const nlohmann::json end = waitFor(d, ended, 30000);
  ASSERT_TRUE(ended(end)) << end.dump();
  const nlohmann::json& list = end["last_session"]["plan"]["list"];
  EXPECT_EQ(list[0]["ended_by"], "repetitions");
  EXPECT_EQ(list[0]["repetitions"], 3);
  EXPECT_EQ(list[1]["ended_by"], "duration");
  EXPECT_GE(list[1]["counted_s"].get<double>(), 2.0);
  EXPECT_LT(list[1]["counted_s"].get<double>(), 2.01);

  const auto rec = lastRecord(d);
  const auto steps = eventsOf(rec, "plan-step-ended");
  ASSERT_EQ(steps.size(), 2u);
  const double t_end0 = steps[0]["t_s"].get<double>();
  // Nothing paused or faulted: the step's counted time is its session time.
  EXPECT_NEAR(steps[0]["counted_s"].get<double>(), t_end0 - rec.cycles.front().t_s, 0.05);
  // The hand's maneuvers in the recorded index coordinate up to step 0's end, counted independently: a close
  // through the range's middle (100°) and back. The counter needs an extended start (≤ 50°) before its first, so
  // the hand completed 3 maneuvers, or 4 when the session began on the way up.
  const std::size_t q = auxIndex(rec, "q_index_rad");
  int maneuvers = 0;
  bool above = static_cast<double>(rec.cycles.front().aux[q]) * 180.0 / M_PI > 100.0, closed = false;
  for (const auto& c : rec.cycles) {
    if (c.t_s > t_end0) break;
    const bool now_above = static_cast<double>(c.aux[q]) * 180.0 / M_PI > 100.0;
    if (now_above && !above) closed = true;
    if (!now_above && above && closed) ++maneuvers;
    above = now_above;
  }
  EXPECT_GE(maneuvers, 3);
  EXPECT_LE(maneuvers, 4);
  // 3 maneuvers of the 1.5 s cycle take at least 2 periods, and at most 4 plus the 0.5 s lead-in.
  EXPECT_GE(steps[0]["counted_s"].get<double>(), 3.0);
  EXPECT_LE(steps[0]["counted_s"].get<double>(), 6.5);
  // The next exercise started where step 0 ended (the loop took it from the plan at its next cycle).
  bool resistance_started = false;
  for (const auto& e : eventsOf(rec, "exercise-started")) {
    if (e["exercise_id"] == 2) {
      resistance_started = true;
      EXPECT_NEAR(e["t_s"].get<double>(), t_end0, 0.01);
    }
  }
  EXPECT_TRUE(resistance_started);
  const std::string report = slurp(end["last_session"]["report"]["path"].get<std::string>());
  EXPECT_NE(report.find("<h2>Session plan</h2>"), std::string::npos);
  EXPECT_NE(report.find("done: 3 repetitions in "), std::string::npos);
  EXPECT_NE(report.find("resistance (preset gentle)"), std::string::npos);
}

TEST(SessionPlanFlow, PauseStopsThePlansClockInSessionTimeAndStopEndsAPausedSession) {
  PlanDaemon d;
  ASSERT_EQ(d.refusal({{"cmd", "start"}, {"patient", "p-plan"},
                       {"plan", {{"steps", {{{"preset", "gentle"}, {"duration_s", 120}}}}}}}),
            "");
  auto t_of = [](const nlohmann::json& s) { return s["session"].value("t_s", 0.0); };
  const nlohmann::json running = waitFor(d, [&](const nlohmann::json& s) { return s.contains("session") && t_of(s) > 1.0; });
  ASSERT_GT(t_of(running), 1.0);
  EXPECT_EQ(d.refusal({{"cmd", "resume"}}), "the session is not paused");
  ASSERT_EQ(d.refusal({{"cmd", "pause"}}), "");
  EXPECT_EQ(d.refusal({{"cmd", "pause"}}), "the session is already paused (resume continues it)");
  EXPECT_EQ(d.refusal({{"cmd", "exercise"}, {"exercise", "assessment"}}),
            "the session follows a plan (step 1 of 1): its steps change the exercise");
  // Held: transparent, zero effort. Then a whole second of session time passes with the plan's clock stopped.
  const nlohmann::json held = waitFor(d, [&](const nlohmann::json& s) { return s["session"].value("device_mode", "") == "transparent"; });
  ASSERT_EQ(held["session"]["device_mode"], "transparent") << held.dump();
  const double t1 = t_of(held);
  const nlohmann::json a = waitFor(d, [&](const nlohmann::json& s) { return t_of(s) > t1 + 0.1; });
  const nlohmann::json b = waitFor(d, [&](const nlohmann::json& s) { return t_of(s) > t_of(a) + 1.0; });
  ASSERT_GT(t_of(b), t_of(a) + 1.0);
  EXPECT_EQ(a["session"]["plan"]["elapsed_s"], b["session"]["plan"]["elapsed_s"]) << "paused: the clock stood still";
  EXPECT_TRUE(b["session"]["paused"].get<bool>());
  int rc = 0;
  const std::string words = d.cli({"status"}, &rc).stdoutText();
  EXPECT_NE(words.find(", PAUSED"), std::string::npos) << words;
  EXPECT_NE(words.find("PAUSED (the clock has stopped; phalanx resume continues)"), std::string::npos) << words;
  const double e_paused = b["session"]["plan"]["elapsed_s"].get<double>();
  d.cli({"resume"}, &rc);
  EXPECT_EQ(rc, 0);
  const nlohmann::json resumed = waitFor(d, [&](const nlohmann::json& s) {
    return s["session"]["plan"].value("elapsed_s", 0.0) > e_paused + 0.5 && s["session"].value("device_mode", "") == "setpoint";
  });
  EXPECT_GT(resumed["session"]["plan"]["elapsed_s"].get<double>(), e_paused + 0.5) << resumed.dump();
  d.cli({"pause"}, &rc);
  EXPECT_EQ(rc, 0);
  waitFor(d, [&](const nlohmann::json& s) { return s["session"].value("device_mode", "") == "transparent"; });
  // STOP of a paused session ends it at once.
  const auto t0 = std::chrono::steady_clock::now();
  Process& stop = d.cli({"stop"}, &rc);
  EXPECT_EQ(rc, 0) << stop.stderrText();
  EXPECT_FALSE(d.api({{"cmd", "status"}})["session_running"].get<bool>());
  std::printf("stop of a paused session answered in %.2f s\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  EXPECT_NE(stop.stdoutText().find("device left safe"), std::string::npos) << stop.stdoutText();

  // The record: both pauses and the resume as events; while held, every command transparent with zero effort;
  // the plan counted exactly the session time outside the pauses.
  const auto rec = lastRecord(d);
  const auto pauses = eventsOf(rec, "api-pause"), resumes = eventsOf(rec, "api-resume");
  ASSERT_EQ(pauses.size(), 2u);
  ASSERT_EQ(resumes.size(), 1u);
  const double p1 = pauses[0]["t_s"].get<double>(), r1 = resumes[0]["t_s"].get<double>(), p2 = pauses[1]["t_s"].get<double>();
  std::vector<std::size_t> cmd_aux;
  for (const char* ch : {"thumb", "index", "middle", "ring", "little"}) cmd_aux.push_back(auxIndex(rec, std::string("effort_cmd_") + ch));
  long held_cycles = 0;
  for (const auto& c : rec.cycles) {
    // The event's time is the status's, up to 20 ms old: the loop holds from the cycle after the request.
    if (!((c.t_s > p1 + 0.05 && c.t_s < r1) || c.t_s > p2 + 0.05)) continue;
    ++held_cycles;
    EXPECT_EQ(c.cmd_mode, 1) << "transparent at t " << c.t_s;
    for (const std::size_t i : cmd_aux) EXPECT_EQ(c.aux[i], 0.0f) << "zero effort at t " << c.t_s;
    if (HasFailure()) break;
  }
  EXPECT_GT(held_cycles, 500);
  // The plan's clock counted exactly the recorded cycles that count: commanded in the exercise's own mode (the
  // resistance preset's setpoint mode, not the held transparent), the device in that mode, no fault latched — each
  // with its recorded session time step. (The pause events' times are the 50 Hz status's, which lags on a loaded
  // machine: the span between them is printed, not compared.)
  const double counted = d.api({{"cmd", "status"}})["last_session"]["plan"]["elapsed_s"].get<double>();
  double from_record = 0.0, prev_t = 0.0;
  for (const auto& c : rec.cycles) {
    if (c.cmd_mode != 1 && c.fault_bits == 0 && c.tel_mode == c.cmd_mode) from_record += c.t_s - prev_t;
    prev_t = c.t_s;
  }
  EXPECT_NEAR(counted, from_record, 0.005) << "the plan's clock counts the recorded cycles outside the pauses";
  std::printf("plan clock %.3f s; recorded counting cycles %.3f s; session time outside the pause events %.3f s\n",
              counted, from_record, (p1 - rec.cycles.front().t_s) + (p2 - r1));
}

TEST(SessionPlanFlow, SelfTrainingRunsWithinItsLimitsAndEndsAtItsMaximumLength) {
  PlanDaemon d;
  int rc = 0;
  Process& start = d.cli({"start", "--patient", "p-plan", "--self-training", "--preset", "strong"}, &rc);
  ASSERT_EQ(rc, 0) << start.stdoutText() << start.stderrText();
  // The profile's 3 N, halved by effort_scale; the limits request can lower it, never raise it again.
  const nlohmann::json limits = d.api({{"cmd", "limits"}});
  EXPECT_DOUBLE_EQ(limits["effort_max"]["index"].get<double>(), 1.5) << limits.dump();
  EXPECT_EQ(d.refusal({{"cmd", "limits"}, {"effort_max", {{"index", 2.0}}}}),
            "limits.effort_max.index: must be in (0, 1.500000] N (the patient profile's limit; edit the profile to raise it)");
  EXPECT_EQ(d.refusal({{"cmd", "exercise"}, {"preset", "gentle"}}),
            "self-training: 'gentle' is not allowed for patient p-plan (allowed: assessment, strong)");
  EXPECT_TRUE(d.api({{"cmd", "status"}})["session"].value("self_training", false));
  // No --seconds: the session ends at the profile's max_session_s (4 s) by itself.
  const nlohmann::json end = waitFor(d, ended, 30000);
  ASSERT_TRUE(ended(end)) << end.dump();
  const auto rec = lastRecord(d);
  const double length = rec.cycles.back().t_s - rec.cycles.front().t_s;
  // As `seconds` does: 4 s = 4000 cycles of the 1 kHz loop (late cycles on a loaded machine stretch t_s a little).
  const long cycles = end["last_session"].value("cycles", 0L);
  EXPECT_LE(cycles, 4000) << end["last_session"].dump();
  EXPECT_GE(cycles, 3990) << end["last_session"].dump();
  EXPECT_EQ(rec.header["self_training"]["effort_scale"], 0.5);
  // Every commanded effort within the self-training limit, which the stiff preset (8 N/rad) reaches.
  double peak = 0.0;
  for (const char* ch : {"thumb", "index", "middle", "ring", "little"}) {
    const std::size_t i = auxIndex(rec, std::string("effort_cmd_") + ch);
    for (const auto& c : rec.cycles) peak = std::max(peak, static_cast<double>(std::fabs(c.aux[i])));
  }
  std::printf("self-training: peak commanded effort %.4f N (limit 1.5 N), %ld cycles, %.3f s\n", peak, cycles, length);
  EXPECT_LE(peak, 1.5 + 1e-6);
  EXPECT_GE(peak, 1.5 - 1e-3) << "the limit was reached (so the check above could fail)";
}

// A plan of the patient's profile (`plans:`) started by its name: over the API ({"plan": "warmup"}) and the CLI
// (--plan NAME); an unknown name is refused naming it and listing the profile's plans; self-training's list applies
// to a named plan as to an inline one; a file of the same name as a plan wins on the CLI.
TEST(SessionPlanFlow, AProfilePlanStartsByNameOverTheApiAndTheCliAndAnUnknownNameIsRefused) {
  PlanDaemon d;
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", "warmpu"}},
       "field 'plan': 'warmpu' is not a plan of patient p-plan (plans: warmup, short, alone)"},
      {{{"cmd", "start"}, {"patient", "p-ok"}, {"plan", "warmup"}},
       "field 'plan': 'warmup' is not a plan of patient p-ok (plans: none)"},
      {{{"cmd", "start"}, {"plan", "warmup"}}, "field 'plan': 'warmup' names a plan of a patient's profile: give the patient"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", 7}},
       "field 'plan': expected a plan {\"steps\": [...]} or the name of a plan of the patient's profile"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", "warmup"}, {"preset", "gentle"}},
       "field 'plan': a plan names each step's exercise (leave out exercise, preset and params)"},
      {{{"cmd", "start"}, {"patient", "p-plan"}, {"plan", "warmup"}, {"self_training", true}},
       "plans.warmup.steps[1]: 'gentle' is not allowed in self-training for patient p-plan (allowed: assessment, strong)"},
  };
  for (const auto& [req, error] : cases) {
    EXPECT_EQ(d.refusal(req), error) << req.dump();
    EXPECT_FALSE(d.api({{"cmd", "status"}})["session_running"].get<bool>()) << req.dump();
  }
  int rc = 0;
  Process& unknown = d.cli({"start", "--patient", "p-plan", "--plan", "warmpu"}, &rc);
  EXPECT_EQ(rc, 1);
  EXPECT_EQ(unknown.stderrText(),
            "phalanx: refused: field 'plan': 'warmpu' is not a plan of patient p-plan (plans: warmup, short, alone)\n");
  Process& typo = d.cli({"start", "--patient", "p-plan", "--plan", "warmup.yaml"}, &rc);
  EXPECT_EQ(rc, 2) << "a YAML name is a file, never sent as a plan name";
  EXPECT_NE(typo.stderrText().find("phalanx: error: --plan warmup.yaml: cannot read: "), std::string::npos) << typo.stderrText();
  EXPECT_TRUE(d.api({{"cmd", "recordings"}}).empty()) << "a refused start creates no record";

  // The profiles listing and the profile carry each plan's step count and length (the dashboard's plan choice).
  for (const auto& p : d.api({{"cmd", "profiles"}})) {
    if (p.value("patient", "") == "p-plan") {
      EXPECT_EQ(p["plans"]["warmup"], nlohmann::json({{"steps", 2}, {"duration_s", 62.0}}));
    }
  }
  EXPECT_EQ(d.api({{"cmd", "profile"}, {"patient", "p-plan"}})["plans"]["short"],
            nlohmann::json({{"steps", 1}, {"duration_s", 5.0}}));
  const std::string shown = d.cli({"profile", "p-plan"}, &rc).stdoutText();
  EXPECT_NE(shown.find("session plans (phalanx start --patient p-plan --plan NAME)\n  alone            1 step, 2 s\n"
                       "  short            1 step, 5 s\n  warmup           2 steps, 62 s\n"),
            std::string::npos)
      << shown;

  // API: started by name, the session runs the profile's steps and says which plan it follows.
  nlohmann::json resp;
  ASSERT_EQ(phalanx::host::api::call(d.socket(), {{"cmd", "start"}, {"patient", "p-plan"}, {"plan", "warmup"}}, resp), "");
  ASSERT_TRUE(resp.value("ok", false)) << resp.dump();
  EXPECT_EQ(resp["result"]["plan"], "warmup");
  EXPECT_EQ(resp["result"]["plan_steps"], 2);
  // The plan shows in the status once the session's loop runs.
  waitFor(d, [](const nlohmann::json& s) { return s.contains("session") && s["session"].contains("plan"); });
  const nlohmann::json plan = d.plan();
  ASSERT_TRUE(plan.is_object()) << d.api({{"cmd", "status"}}).dump();
  EXPECT_EQ(plan.value("name", ""), "warmup");
  EXPECT_EQ(plan["list"][0]["target_repetitions"], 3);
  EXPECT_EQ(plan["list"][1]["preset"], "gentle");
  EXPECT_EQ(plan["list"][1]["duration_s"], 2.0);
  d.api({{"cmd", "stop"}});
  const auto rec = lastRecord(d);
  EXPECT_EQ(rec.header.value("plan_name", ""), "warmup");
  ASSERT_EQ(rec.header["plan"].size(), 2u);
  EXPECT_EQ(rec.header["plan"][1]["preset"], "gentle");

  // CLI: --plan NAME (no such file) is the profile's plan; the short one (5 s) ends by itself at its duration.
  Process& start = d.cli({"start", "--patient", "p-plan", "--plan", "short"}, &rc);
  ASSERT_EQ(rc, 0) << start.stdoutText() << start.stderrText();
  EXPECT_NE(start.stdoutText().find("session plan short: 1 step (phalanx status shows where it is)"), std::string::npos)
      << start.stdoutText();
  waitFor(d, [](const nlohmann::json& s) { return s.contains("session") && s["session"].contains("plan"); });
  const std::string status = d.cli({"status"}, &rc).stdoutText();
  EXPECT_NE(status.find("  plan short: step 1 of 1, assessment, "), std::string::npos) << status;
  const nlohmann::json end = waitFor(d, ended, 30000);
  ASSERT_TRUE(ended(end)) << end.dump();
  EXPECT_EQ(end["last_session"]["plan"]["name"], "short");
  EXPECT_EQ(end["last_session"]["plan"]["list"][0]["ended_by"], "duration");

  // Self-training: a named plan whose steps are all allowed starts, with the self-training limits.
  ASSERT_EQ(phalanx::host::api::call(d.socket(), {{"cmd", "start"}, {"patient", "p-plan"}, {"plan", "alone"},
                                                  {"self_training", true}}, resp), "");
  ASSERT_TRUE(resp.value("ok", false)) << resp.dump();
  EXPECT_EQ(resp["result"]["self_training"]["effort_scale"], 0.5);
  waitFor(d, [](const nlohmann::json& s) { return s.contains("session") && s["session"].contains("plan"); });
  const nlohmann::json limits = d.api({{"cmd", "limits"}});
  ASSERT_TRUE(limits.is_object()) << limits.dump();
  EXPECT_DOUBLE_EQ(limits["effort_max"]["index"].get<double>(), 1.5);
  d.api({{"cmd", "stop"}});

  // A file named like a plan, in the CLI's working directory: the file wins (documented in docs/therapy.md).
  std::ofstream(d.dir() + "/warmup") << "steps:\n  - {exercise: idle, duration_s: 30}\n";
  Process file_wins({"/usr/bin/env", "-C", d.dir(), "PHALANX_SOCKET=" + d.socket(), "PHALANX_CLIENT_CONFIG=/nonexistent-ok",
                     binPath("phalanx"), "start", "--patient", "p-plan", "--plan", "warmup"});
  ASSERT_EQ(file_wins.wait(60000), 0) << file_wins.stdoutText() << file_wins.stderrText();
  waitFor(d, [](const nlohmann::json& s) { return s.contains("session") && s["session"].contains("plan"); });
  const nlohmann::json from_file = d.plan();
  ASSERT_TRUE(from_file.is_object()) << d.api({{"cmd", "status"}}).dump();
  EXPECT_EQ(from_file.value("steps", 0), 1) << from_file.dump();
  EXPECT_EQ(from_file.value("exercise", ""), "idle");
  EXPECT_FALSE(from_file.contains("name"));
  d.api({{"cmd", "stop"}});
}
