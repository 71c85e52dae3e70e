#pragma once
// The `phalanx` CLI as a client of phalanxd's control API (docs/api.md), and the session-record tools.
//   phalanx status | start | stop | pause | resume | exercise | mode | reset | limits | profiles | profile | recordings
//   phalanx record export FILE [--csv|--mcap] [--out PATH] | record info FILE | record report FILE [--previous F] --out F
//   phalanx record replay FILE [--set K=V] [--dashboard ADDRESS:PORT [--speed X] [--hold] [--allow-remote]]
//   phalanx record progress --patient ID --records-dir DIR [--repeatability REP.json] [--out F.html] [--pdf F.pdf]
#include <CLI/CLI.hpp>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cli_args.h"
#include "phalanx/host/api/client.h"
#include "phalanx/host/api/server.h"
#include "phalanx/host/record/mcap_session.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/record/replay.h"
#include "phalanx/host/record/replay_stream.h"
#include "phalanx/host/therapy/fhir.h"
#include "phalanx/host/therapy/guidance.h"
#include "phalanx/host/therapy/progress.h"
#include "phalanx/host/therapy/report.h"
#include "phalanx/host/yaml_keys.h"

namespace phalanx::host::cli {

struct TherapyCli {
  std::string socket;  ///< --socket; else $PHALANX_SOCKET, the client config's `socket`, the default (resolveSocket)
  long daemon_uid = -1;  ///< a daemon account to trust besides root and the caller (socket_access.h)
  bool json = false;
  std::map<std::string, CLI::App*> cmds;
  // start
  std::string patient, exercise = "assessment", params, device, scenario, preset, plan_file;
  bool self_training = false;
  double seconds = -1.0;
  long seed = -1;
  std::vector<std::string> effort_max;  // channel=value
  std::string raw;
  // record
  CLI::App* record = nullptr;
  CLI::App* rec_export = nullptr;
  CLI::App* rec_info = nullptr;
  CLI::App* rec_report = nullptr;
  CLI::App* rec_fhir = nullptr;
  CLI::App* rec_replay = nullptr;
  std::vector<std::string> replay_set;  // KEY=VALUE
  std::string replay_dashboard;          // --dashboard ADDRESS:PORT
  CLI::Option* replay_dashboard_opt = nullptr;
  double replay_speed = 1.0;
  bool replay_hold = false, replay_allow_remote = false;
  std::string rec_file, rec_out, rec_previous, rec_reference, rec_repeatability;
  CLI::App* rec_repeat = nullptr;
  std::vector<std::string> rec_files;
  CLI::App* rec_progress = nullptr;
  std::string rec_records_dir, rec_pdf;
  bool csv = false;
  bool mcap = false;
};

inline void addTherapyCommands(CLI::App& app, TherapyCli& t) {
  auto client = [&](const char* name, const char* help) {
    CLI::App* sc = app.add_subcommand(name, help);
    sc->add_option("--socket", t.socket,
                   "phalanxd's API socket (default: $PHALANX_SOCKET, else `socket:` in the client config "
                   "$PHALANX_CLIENT_CONFIG or ~/.config/phalanx/client.yaml or /etc/phalanx/client.yaml, else " +
                       api::defaultSocketPath() + ")");
    sc->add_option("--daemon-uid", t.daemon_uid,
                   "also trust a phalanxd running as this uid (default: only root or yourself)");
    sc->add_flag("--json", t.json, "print the daemon's JSON answer");
    t.cmds[name] = sc;
    return sc;
  };
  client("status", "session status from phalanxd");
  CLI::App* start = client("start", "start a therapy session");
  start->add_option("--patient", t.patient, "patient id (profile <id>.yaml in phalanxd's --profiles-dir)");
  start->add_option("--exercise", t.exercise, "first exercise (default assessment)");
  start->add_option("--params", t.params, "exercise parameters (JSON object)");
  start->add_option("--device", t.device, "device (default: the daemon's)");
  start->add_option("--scenario", t.scenario, "simulated hand (sim devices)");
  start->add_option("--seconds", t.seconds, "session length (0: until stop)")->check(inRange(0.0, 86400.0));
  start->add_option("--seed", t.seed, "simulation seed")->check(inRange(0L, 4294967295L));
  start->add_option("--preset", t.preset, "first exercise: a preset of the patient's profile (instead of --exercise)");
  start->add_option("--plan", t.plan_file,
                    "FILE.yaml (steps: [{exercise|preset, duration_s, repetitions}]) or NAME, a plan of the patient's "
                    "profile; an existing file wins over a name");
  start->add_flag("--self-training", t.self_training, "the patient trains alone: the profile's self_training limits");
  client("stop", "stop the session (device left safe; record closed; report written)");
  client("pause", "pause the session: zero effort, the plan's clock stops");
  client("resume", "resume a paused session where it was");
  for (const char* name : {"exercise", "mode"}) {
    CLI::App* sc = client(name, "switch the running session's exercise");
    sc->add_option("name", t.exercise, "idle|assessment|resistance|assistance|record-pattern|playback|grasp|tardieu|passive-rom|max-force");
    sc->add_option("--params", t.params, "exercise parameters (JSON object)");
    sc->add_option("--preset", t.preset, "a preset of the patient's profile (instead of the name)");
  }
  client("reset", "clear latched faults (e-stop reset) on the device");
  CLI::App* limits = client("limits", "show, or lower, the running session's limits");
  limits->add_option("--effort-max", t.effort_max, "channel=value (e.g. index=2.5), may repeat");
  client("profiles", "list patient profiles and whether each is valid");
  client("profile", "show one patient profile")
      ->add_option("patient", t.patient, "patient id (the profile <id>.yaml in phalanxd's --profiles-dir)")
      ->required();
  client("recordings", "list session records")
      ->add_option("--patient", t.patient, "only this patient's records (default: every patient's)");
  client("api", "send one raw JSON request line (for scripts)")
      ->add_option("request", t.raw, "one JSON request object, e.g. '{\"cmd\": \"status\"}' (docs/api.md)")
      ->required();

  t.record = app.add_subcommand("record", "session records (.phrec)");
  t.record->require_subcommand(1);
  t.rec_export = t.record->add_subcommand("export", "export a record to CSV (default) or MCAP");
  t.rec_export->add_option("file", t.rec_file)->required()->check(CLI::ExistingFile);
  CLI::Option* csv = t.rec_export->add_flag("--csv", t.csv, "CSV output (the default)");
  t.rec_export->add_flag("--mcap", t.mcap, "MCAP output (Foxglove, PlotJuggler, rosbag2; also for an --out ending .mcap)")
      ->excludes(csv);
  t.rec_export->add_option("--out", t.rec_out,
                           "output file (default: FILE with .csv or .mcap; never the record itself)");
  t.rec_info = t.record->add_subcommand("info", "header, counts and integrity of a record");
  t.rec_info->add_option("file", t.rec_file)->required()->check(CLI::ExistingFile);
  t.rec_report = t.record->add_subcommand("report", "write the HTML report of a record");
  t.rec_report->add_option("file", t.rec_file)->required()->check(CLI::ExistingFile);
  t.rec_report->add_option("--previous", t.rec_previous, "previous session's record, for comparison");
  t.rec_report->add_option("--out", t.rec_out, "output file (default: FILE with .html; never one of the inputs)");
  t.rec_report->add_option("--reference", t.rec_reference,
                           "device-free recording of the same motion (CSV t_s,<joint>_deg,...): transparency Pearson r")
      ->check(CLI::ExistingFile);
  t.rec_report->add_option("--repeatability", t.rec_repeatability,
                           "repeatability file (phalanx record repeatability): ICC(2,1) and MDC95 beside each figure")
      ->check(CLI::ExistingFile);
  t.rec_repeat = t.record->add_subcommand(
      "repeatability", "ICC(2,1) and MDC95 of every assessment figure from repeated sessions of several patients");
  t.rec_repeat->add_option("files", t.rec_files, "records: the same number of sessions of each patient (2 or more)")
      ->required()->check(CLI::ExistingFile);
  t.rec_repeat->add_option("--out", t.rec_out, "output JSON file")->required();
  t.rec_fhir = t.record->add_subcommand("fhir", "export a record's results as a FHIR R4 Bundle of Observations (JSON)");
  t.rec_fhir->add_option("file", t.rec_file)->required()->check(CLI::ExistingFile);
  t.rec_fhir->add_option("--out", t.rec_out, "output file (default: FILE with .fhir.json; never the record itself)");
  t.rec_fhir->add_option("--repeatability", t.rec_repeatability,
                         "repeatability file (phalanx record repeatability): ICC(2,1) and MDC95 as components")
      ->check(CLI::ExistingFile);
  t.rec_progress = t.record->add_subcommand(
      "progress", "a patient's progress over time: every figure's trend across their session records, printable "
                  "(HTML, and PDF through headless Chromium)");
  t.rec_progress->add_option("--patient", t.patient, "the patient's id (their records' names)")->required();
  t.rec_progress->add_option("--records-dir", t.rec_records_dir, "the directory of the session records")->required();
  t.rec_progress->add_option("--repeatability", t.rec_repeatability,
                             "repeatability file (phalanx record repeatability): the MDC95 band and ICC per figure")
      ->check(CLI::ExistingFile);
  t.rec_progress->add_option("--out", t.rec_out, "HTML output (default: the PDF's name with .html)");
  t.rec_progress->add_option("--pdf", t.rec_pdf, "PDF output, printed from the HTML by headless Chromium");
  t.rec_progress->add_flag("--json", t.json, "print the progress JSON (every session's figures) on stdout");
  t.rec_replay = t.record->add_subcommand(
      "replay", "feed a --record FILE.mcap recording through this build's controller offline and compare every command "
                "bit for bit (exit 0 identical, 1 a mismatch, 2 not replayable); with --dashboard also show it on the "
                "live dashboard (a session record .phrec: its recorded values)");
  t.rec_replay->add_option("file", t.rec_file)->required()->check(CLI::ExistingFile);
  t.rec_replay->add_option("--set", t.replay_set,
                           "change the recorded configuration for the replay, KEY=VALUE (mode, scene, "
                           "pen_wall_stiffness_N_per_cm, pen_floor_mm); repeatable");
  CLI::Option* dash = t.rec_replay->add_option(
      "--dashboard", t.replay_dashboard,
      "stream the replay to the live dashboard on ADDRESS:PORT (loopback; port 0: any free; its URL is printed); "
      "its controls are refused: there is no device (docs/dashboard.md)");
  t.replay_dashboard_opt = dash;
  t.rec_replay->add_option("--speed", t.replay_speed, "with --dashboard: times the recorded speed (default 1)")
      ->check(inRange(record::kReplaySpeedMin, record::kReplaySpeedMax))
      ->needs(dash);
  t.rec_replay->add_flag("--hold", t.replay_hold,
                         "with --dashboard: at the end keep serving the last state until SIGINT/SIGTERM")
      ->needs(dash);
  t.rec_replay->add_flag("--allow-remote", t.replay_allow_remote,
                         "with --dashboard: allow a non-loopback address (plain HTTP, the recording's patient data)")
      ->needs(dash);
}

/// Why FILE is not a replayable recording, from its first bytes ("" for MCAP).
inline std::string replayableKind(const std::string& path) {
  char head[8] = {};
  std::FILE* f = std::fopen(path.c_str(), "rb");
  const std::size_t n = f != nullptr ? std::fread(head, 1, sizeof head, f) : 0;
  if (f != nullptr) std::fclose(f);
  if (n == 8 && std::memcmp(head, "\x89MCAP0\r\n", 8) == 0) return {};
  if (n == 8 && std::memcmp(head, "PHXREC1\n", 8) == 0) {
    return path + " is a session record (.phrec): replaying therapy sessions is not supported (exercise and limit "
                  "changes are not tied to the cycle that took them); replay a `--record FILE.mcap` recording";
  }
  if (n >= 4 && std::memcmp(head, "t_s,", 4) == 0) {
    return path + " is a CSV recording: it rounds values to 5 significant digits and holds no configuration, so "
                  "it cannot reproduce commands bit for bit; record with `--record FILE.mcap`";
  }
  return path + " is not an MCAP recording";
}

/// Set by SIGINT/SIGTERM during `phalanx record replay --dashboard`.
inline std::atomic<bool> g_replay_stop{false};

/// `phalanx record replay FILE --dashboard ...`: the replay streamed to the dashboard (record/replay_stream.h).
inline int runReplayStream(const TherapyCli& t) {
  record::ReplayStreamOptions o;
  o.replay.set = t.replay_set;
  o.speed = t.replay_speed;
  o.hold = t.replay_hold;
  o.dashboard.allow_remote = true;  // the syntax first; loopback below, with this command's own hint
  if (const std::string err = api::parseDashboardSpec(t.replay_dashboard, o.dashboard); !err.empty()) {
    std::fprintf(stderr, "phalanx: error: %s%s\n", err.rfind("--dashboard", 0) == 0 ? "" : "--dashboard: ", err.c_str());
    return 2;
  }
  o.dashboard.allow_remote = t.replay_allow_remote;
  if (!t.replay_allow_remote && !api::isLoopbackAddress(o.dashboard.address)) {
    std::fprintf(stderr,
                 "phalanx: error: --dashboard: %s is not a loopback address: the dashboard serves the recording's "
                 "patient data over plain HTTP; add --allow-remote to serve it on a network\n",
                 o.dashboard.address.c_str());
    return 2;
  }
  if (const std::string why = replayableKind(t.rec_file); !why.empty() && !record::isSessionRecord(t.rec_file)) {
    std::fprintf(stderr, "phalanx: error: %s\n", why.c_str());
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = [](int) { g_replay_stop.store(true); };
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  return record::streamReplay(t.rec_file, o, g_replay_stop);
}

/// `phalanx record replay`: JSON result on stdout, one line for people on stderr.
inline int runReplay(const TherapyCli& t) {
  if (t.replay_dashboard_opt != nullptr && t.replay_dashboard_opt->count() > 0) return runReplayStream(t);
  if (const std::string why = replayableKind(t.rec_file); !why.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", why.c_str());
    return 2;
  }
  record::ReplayOptions o;
  o.set = t.replay_set;
  record::ReplayResult r;
  if (const std::string err = record::replayRecording(t.rec_file, o, r); !err.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
    return 2;
  }
  std::cout << r.toJson().dump(2) << std::endl;
  std::fprintf(stderr, "replay %s (%s, %s): %llu cycles, %llu compared, %llu commanded by a client (not compared)%s\n",
               r.file.c_str(), r.device.c_str(), r.controller.c_str(), static_cast<unsigned long long>(r.cycles),
               static_cast<unsigned long long>(r.compared), static_cast<unsigned long long>(r.external),
               r.file_complete ? "" : "; the file has no end (a killed recording): its whole chunks were replayed");
  if (r.mismatched_cycles == 0) {
    std::fprintf(stderr, "identical: every compared command equals the recorded one bit for bit\n");
    return 0;
  }
  for (const auto& m : r.first) {
    char bits[48] = "";  // a setpoint's float bits; mode and gain scales are integers
    if (m.recorded_bits != m.replayed_bits) std::snprintf(bits, sizeof bits, " (0x%08x → 0x%08x)", m.recorded_bits, m.replayed_bits);
    std::fprintf(stderr, "MISMATCH at cycle %llu (t_s %.6f): %s recorded %.9g, replayed %.9g%s\n",
                 static_cast<unsigned long long>(m.cycle), m.t_s, m.channel.c_str(), m.recorded, m.replayed, bits);
  }
  std::fprintf(stderr, "%llu of %llu compared cycles differ (%llu values)\n",
               static_cast<unsigned long long>(r.mismatched_cycles), static_cast<unsigned long long>(r.compared),
               static_cast<unsigned long long>(r.mismatched_values));
  return 1;
}

using therapy::anatomicalKeys;
using therapy::humanNumber;

inline std::string jstr(const nlohmann::json& j, const char* key, const std::string& def = "–") {
  return j.is_object() && j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : def;
}
inline std::string jnum(const nlohmann::json& j, const char* key, int digits = 2) {
  return j.is_object() && j.contains(key) && j[key].is_number() ? humanNumber(j[key].get<double>(), digits) : "–";
}

/// The fault guidance (what happened, whether the patient is safe, what to do) of a status or summary.
inline void printFaultGuidance(const nlohmann::json& guidance) {
  if (!guidance.is_array()) return;
  for (const auto& g : guidance) {
    std::printf("FAULT %s\n  what happened: %s\n  patient safe:  %s\n  what to do:    %s\n", jstr(g, "fault").c_str(),
                jstr(g, "what").c_str(), jstr(g, "safe").c_str(), jstr(g, "action").c_str());
  }
}

/// One plan step in words: "resistance (preset gentle), 30 s, 10 repetitions".
inline std::string planStepWords(const nlohmann::json& st) {
  std::string w = jstr(st, "exercise");
  if (st.contains("preset")) w += " (preset " + jstr(st, "preset") + ")";
  w += ", " + jnum(st, "duration_s", 1) + " s";
  if (st.value("target_repetitions", 0) > 0) w += ", " + jnum(st, "target_repetitions", 0) + " repetitions";
  return w;
}

/// The session plan of a status or summary: where it is, then every step.
inline void printPlan(const nlohmann::json& p, bool paused) {
  if (!p.is_object()) return;
  if (p.value("finished", false)) {
    std::printf("  plan: all %s steps done\n", jnum(p, "steps", 0).c_str());
  } else {
    std::printf("  plan%s: step %s of %s, %s, %s s of %s s left, repetitions %s",
                p.contains("name") ? (" " + jstr(p, "name")).c_str() : "", jnum(p, "step", 0).c_str(),
                jnum(p, "steps", 0).c_str(), jstr(p, "exercise").c_str(), jnum(p, "remaining_s", 1).c_str(),
                jnum(p, "duration_s", 1).c_str(), jnum(p, "repetitions", 0).c_str());
    if (p.value("target_repetitions", 0) > 0) std::printf(" of %s", jnum(p, "target_repetitions", 0).c_str());
    std::printf("%s\n", paused ? " - PAUSED (the clock has stopped; phalanx resume continues)" : "");
  }
  int i = 0;
  for (const auto& st : p.value("list", nlohmann::json::array())) {
    std::printf("    %d. %s: %s", ++i, planStepWords(st).c_str(), jstr(st, "state").c_str());
    if (jstr(st, "state") == "done") {
      std::printf(", %s repetitions in %s s (%s)", jnum(st, "repetitions", 0).c_str(), jnum(st, "counted_s", 1).c_str(),
                  jstr(st, "ended_by") == "repetitions" ? "target reached" : "its duration");
    }
    std::printf("\n");
  }
}

inline void printSessionStatus(const nlohmann::json& s) {
  std::printf("session %s", s.value("phase", "?").c_str());
  if (s.contains("patient")) std::printf(", patient %s", s["patient"].get<std::string>().c_str());
  if (s.contains("exercise")) std::printf(", exercise %s", s["exercise"].get<std::string>().c_str());
  if (s.value("paused", false)) std::printf(", PAUSED");
  if (s.value("self_training", false)) std::printf(", self-training");
  if (s.contains("t_s")) {
    std::printf(", %s s, device %s, faults %s%s", humanNumber(s["t_s"].get<double>(), 1).c_str(),
                s["device_mode"].get<std::string>().c_str(), s["faults"].get<std::string>().c_str(),
                s["estop"].get<bool>() ? ", E-STOP" : "");
  }
  std::printf("\n");
  if (s.contains("record_error")) std::printf("  RECORD FAILED: %s\n", s["record_error"].get<std::string>().c_str());
  if (s.contains("channels")) {
    const std::string unit = jstr(s, "effort_unit", "");
    std::printf("  %-8s %8s %8s %10s %10s %8s\n", "channel", "q (deg)", "target", ("effort " + unit).c_str(),
                "commanded", "max");
    for (const std::string& name : anatomicalKeys(s["channels"])) {
      const auto& c = s["channels"][name];
      std::printf("  %-8s %8s %8s %10s %10s %8s\n", name.c_str(), jnum(c, "q_deg", 1).c_str(),
                  jnum(c, "target_deg", 1).c_str(), jnum(c, "effort_measured", 3).c_str(),
                  jnum(c, "effort_command", 3).c_str(), jnum(c, "effort_max", 3).c_str());
    }
  }
  printPlan(s.value("plan", nlohmann::json()), s.value("paused", false));
  printFaultGuidance(s.value("fault_guidance", nlohmann::json()));
}

/// `stop`'s end-of-session summary in a few lines (the whole JSON, loop statistics and all, with --json).
inline void printEndSummary(const nlohmann::json& r) {
  if (!r.is_object()) {
    std::printf("no session summary\n");
    return;
  }
  std::printf("session ended: %s s, %s cycles, faults seen: %s, device left %s\n", jnum(r, "seconds", 1).c_str(),
              jnum(r, "cycles", 0).c_str(), jstr(r, "faults_seen", "none").c_str(), jstr(r, "final_mode").c_str());
  if (r.contains("session_record") && r["session_record"].is_object()) {
    const auto& rec = r["session_record"];
    std::printf("record: %s (%s cycles written", jstr(rec, "path").c_str(), jnum(rec, "cycles_written", 0).c_str());
    if (rec.value("cycles_lost", 0) > 0 || rec.value("cycles_dropped", 0) > 0) {
      std::printf(", %s lost, %s dropped", jnum(rec, "cycles_lost", 0).c_str(), jnum(rec, "cycles_dropped", 0).c_str());
    }
    std::printf(")\n");
  }
  if (r.contains("report") && r["report"].is_object()) {
    if (r["report"].contains("path")) std::printf("report: %s\n", jstr(r["report"], "path").c_str());
    else std::printf("report: %s\n", jstr(r["report"], "error").c_str());
  }
  printPlan(r.value("plan", nlohmann::json()), false);
  if (r.contains("error")) std::printf("the session ended with an error: %s\n", jstr(r, "error").c_str());
}

inline void printHuman(const std::string& cmd, const nlohmann::json& r) {
  if (cmd == "status") {
    if (r.contains("session")) printSessionStatus(r["session"]);
    else std::printf("no session%s\n", r.contains("last_session") ? " running (a previous one ended)" : "");
    if (r.contains("last_session") && r["last_session"].contains("error")) {
      std::printf("the last session ended with an error: %s\n", r["last_session"]["error"].get<std::string>().c_str());
    }
    return;
  }
  if (cmd == "start") {
    std::printf("session started, exercise %s\nrecord: %s\nreport (written at stop): %s\n", jstr(r, "exercise").c_str(),
                jstr(r, "record").c_str(), jstr(r, "report").c_str());
    const std::string prev = jstr(r, "previous_record", "");
    std::printf("previous session: %s\n", prev.empty() ? "none" : prev.c_str());
    if (r.contains("plan_steps")) {
      std::printf("session plan%s: %s %s (phalanx status shows where it is)\n",
                  r.contains("plan") ? (" " + jstr(r, "plan")).c_str() : "", jnum(r, "plan_steps", 0).c_str(),
                  r.value("plan_steps", 0) == 1 ? "step" : "steps");
    }
    if (r.contains("self_training")) {
      std::printf("self-training: at most %s s, effort limits x %s\n", jnum(r["self_training"], "max_session_s", 1).c_str(),
                  jnum(r["self_training"], "effort_scale", 2).c_str());
    }
    return;
  }
  if (cmd == "stop") return printEndSummary(r);
  if (cmd == "pause") {
    std::printf("session paused: the device holds no effort and the plan's clock has stopped (phalanx resume continues)\n");
    return;
  }
  if (cmd == "resume") {
    std::printf("session resumed\n");
    return;
  }
  if (cmd == "exercise" || cmd == "mode") {
    std::printf("exercise %s: taken by the session at its next cycle\n", jstr(r, "exercise").c_str());
    return;
  }
  if (cmd == "reset") {
    std::printf("reset sent: the device clears its faults unless their cause is still present (see phalanx status)\n");
    return;
  }
  if (cmd == "limits") {
    const std::string unit = jstr(r, "effort_unit", "");
    std::printf("effort limit (%s)\n", unit.c_str());
    for (const std::string& c : anatomicalKeys(r.value("effort_max", nlohmann::json::object()))) {
      std::printf("  %-8s %s\n", c.c_str(), humanNumber(r["effort_max"][c].get<double>(), 3).c_str());
    }
    std::printf("allowed flexion range (deg)\n");
    for (const std::string& j : anatomicalKeys(r.value("range_deg", nlohmann::json::object()))) {
      const auto& v = r["range_deg"][j];
      std::printf("  %-11s %6s … %s\n", j.c_str(), humanNumber(v[0].get<double>(), 1).c_str(),
                  humanNumber(v[1].get<double>(), 1).c_str());
    }
    return;
  }
  if (cmd == "profile") {
    std::printf("patient %s, device %s, size %s, %s hand\nfile: %s\n", jstr(r, "patient").c_str(),
                jstr(r, "device").c_str(), jstr(r, "size").c_str(), jstr(r, "handedness").c_str(),
                jstr(r, "file").c_str());
    const nlohmann::json rom = r.value("rom_deg", nlohmann::json::object());
    if (rom.empty()) std::printf("measured range of motion: none in the profile\n");
    else std::printf("measured range of motion (deg)\n");
    for (const std::string& j : anatomicalKeys(rom)) {
      std::printf("  %-11s %6s … %s\n", j.c_str(), humanNumber(rom[j][0].get<double>(), 1).c_str(),
                  humanNumber(rom[j][1].get<double>(), 1).c_str());
    }
    const nlohmann::json plans = r.value("plans", nlohmann::json::object());
    if (!plans.empty()) std::printf("session plans (phalanx start --patient %s --plan NAME)\n", jstr(r, "patient").c_str());
    for (const auto& [name, pl] : plans.items()) {
      std::printf("  %-16s %s %s, %s s\n", name.c_str(), jnum(pl, "steps", 0).c_str(),
                  pl.value("steps", 0) == 1 ? "step" : "steps", jnum(pl, "duration_s", 1).c_str());
    }
    return;
  }
  if (cmd == "profiles") {
    if (r.empty()) std::printf("no profiles\n");
    for (const auto& p : r) {
      if (p.value("valid", false)) {
        std::printf("%-24s %s (%s)\n", jstr(p, "file").c_str(), jstr(p, "patient").c_str(), jstr(p, "device").c_str());
      } else {
        std::printf("%-24s INVALID: %s\n", jstr(p, "file").c_str(), jstr(p, "error").c_str());
      }
    }
    return;
  }
  if (cmd == "recordings") {
    if (r.empty()) std::printf("no records\n");
    for (const auto& f : r) {
      const std::string rep = jstr(f, "report", "");
      std::printf("%s  %s bytes  report: %s\n", jstr(f, "file").c_str(), jnum(f, "bytes", 0).c_str(),
                  rep.empty() ? "none" : rep.c_str());
    }
    return;
  }
  std::cout << r.dump(2) << std::endl;
}

/// The client's socket: --socket, else $PHALANX_SOCKET, else `socket:` of the client config file
/// ($PHALANX_CLIENT_CONFIG, else $XDG_CONFIG_HOME or ~/.config /phalanx/client.yaml, else
/// /etc/phalanx/client.yaml; the first that exists), else the default. Returns an error for a bad config file.
inline std::string resolveSocket(TherapyCli& t) {
  if (!t.socket.empty()) return {};
  if (const char* env = std::getenv("PHALANX_SOCKET"); env != nullptr && *env != 0) {
    t.socket = env;
    return {};
  }
  std::vector<std::string> candidates;
  if (const char* c = std::getenv("PHALANX_CLIENT_CONFIG"); c != nullptr && *c != 0) {
    candidates.push_back(c);
  } else {
    if (const char* x = std::getenv("XDG_CONFIG_HOME"); x != nullptr && *x != 0) {
      candidates.push_back(std::string(x) + "/phalanx/client.yaml");
    } else if (const char* h = std::getenv("HOME"); h != nullptr && *h != 0) {
      candidates.push_back(std::string(h) + "/.config/phalanx/client.yaml");
    }
    candidates.push_back("/etc/phalanx/client.yaml");
  }
  for (const std::string& path : candidates) {
    if (::access(path.c_str(), F_OK) != 0) {
      if (std::getenv("PHALANX_CLIENT_CONFIG") != nullptr) return path + ": " + std::strerror(errno);
      continue;
    }
    try {
      const YAML::Node n = YAML::LoadFile(path);
      if (!n.IsMap()) return path + ": expected a mapping with the key `socket`";
      for (const auto& kv : n) {
        const std::string k = kv.first.as<std::string>();
        if (k == "socket") {
          t.socket = kv.second.as<std::string>();
        } else if (k == "daemon_uid") {
          if (t.daemon_uid < 0) t.daemon_uid = kv.second.as<long>();
        } else {
          return path + ": " + k + ": unknown key (known: socket, daemon_uid)";
        }
      }
      if (t.socket.empty()) return path + ": socket: missing or empty";
      return {};
    } catch (const std::exception& e) {
      return path + ": " + e.what();
    }
  }
  t.socket = api::defaultSocketPath();
  return {};
}

/// After `start` answered: waits (bounded) until the session runs, or says why it ended; non-zero if it did not
/// start. The daemon starts the device after answering, so a failure there would otherwise go unnoticed.
inline int waitForSessionStart(TherapyCli& t) {
  for (int i = 0; i < 200; ++i) {  // 20 s: device start-up (firmware-sim start, strain-gauge tare) takes ~1-3 s
    nlohmann::json resp;
    if (const std::string err = api::call(t.socket, {{"cmd", "status"}}, resp, 15000, t.daemon_uid); !err.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
      return 3;
    }
    const nlohmann::json& r = resp["result"];
    if (r.contains("session") && r["session"].contains("t_s")) return 0;
    if (!r.value("session_running", false)) {
      const nlohmann::json last = r.value("last_session", nlohmann::json::object());
      // A short session (--seconds) may have run and ended already: that is a start.
      if (last.value("exit_code", -1) == 0 && last.value("cycles", 0) > 0 && !last.contains("error")) return 0;
      std::string why = jstr(last, "error", "");
      if (why.empty()) why = last.contains("link_error") ? jstr(last, "link_error") : "it ended before its first cycle";
      std::fprintf(stderr, "phalanx: error: the session did not start: %s (exit code %s)\n", why.c_str(),
                   jnum(last, "exit_code", 0).c_str());
      return 4;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::fprintf(stderr, "phalanx: error: the session has not started within 20 s (see phalanx status)\n");
  return 4;
}

/// path with the extension of its file name (not of a directory's) replaced by ext.
inline std::string withExtension(const std::string& path, const std::string& ext) {
  const auto slash = path.rfind('/');
  const auto dot = path.rfind('.');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash + 1);
  return (has_ext ? path.substr(0, dot) : path) + ext;
}

/// `phalanx record progress`: the HTML (and PDF) progress report; a summary (or --json: the progress JSON).
inline int runProgress(TherapyCli& t) {
  if (t.rec_out.empty() && t.rec_pdf.empty()) {
    std::fprintf(stderr, "phalanx: error: record progress: give --pdf FILE.pdf and/or --out FILE.html\n");
    return 2;
  }
  therapy::ProgressRequest r{t.rec_records_dir, t.patient, t.rec_repeatability,
                             t.rec_out.empty() ? withExtension(t.rec_pdf, ".html") : t.rec_out, t.rec_pdf};
  nlohmann::json p;
  const std::string err = therapy::writeProgressReport(r, p, [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); });
  if (!err.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
    return 1;
  }
  if (t.json) {
    std::cout << p.dump(1) << std::endl;
    return 0;
  }
  std::size_t excluded = 0;
  for (const auto& s : p["sessions"]) excluded += s["excluded_cycles"].get<std::size_t>() > 0 ? 1 : 0;
  std::printf("patient %s: %zu sessions (%zu with locked/faulted time excluded), %zu figures, %s\n", t.patient.c_str(),
              p["sessions"].size(), excluded, p["figures"].size(),
              p["mdc_source"].is_string() ? ("MDC95 from " + p["mdc_source"].get<std::string>()).c_str() : "no MDC (no --repeatability)");
  std::printf("report: %s\n", r.html_path.c_str());
  if (!r.pdf_path.empty()) std::printf("PDF: %s (%d pages)\n", r.pdf_path.c_str(), p["pages"].get<int>());
  return 0;
}

/// Runs the parsed therapy/record subcommand; returns -1 if none of them was given.
/// --plan ARG names a file (read here) when a file of that path exists, or when it has a '/' or a YAML/JSON
/// extension (so a mistyped path is refused as unreadable, not sent as a plan name); otherwise it is the name of
/// a plan of the patient's profile. An existing file wins over a profile plan of the same name.
inline bool isPlanFileArgument(const std::string& arg) {
  struct stat st {};
  if (::stat(arg.c_str(), &st) == 0) return true;
  auto ends = [&](const char* ext) {
    const std::string e(ext);
    return arg.size() >= e.size() && arg.compare(arg.size() - e.size(), e.size(), e) == 0;
  };
  return arg.find('/') != std::string::npos || ends(".yaml") || ends(".yml") || ends(".json");
}

/// --plan FILE: a YAML session plan (docs/therapy.md "Session plan") as the JSON of the start request.
inline std::string readPlanFile(const std::string& path, nlohmann::json& out) {
  std::ifstream in(path);
  if (!in) return path + ": cannot read: " + std::strerror(errno);
  std::stringstream ss;
  ss << in.rdbuf();
  if (ss.str().size() > 64 * 1024) return path + ": larger than 64 KiB (a plan is a few hundred bytes)";
  try {
    const YAML::Node root = YAML::Load(ss.str());
    if (std::string dup = findDuplicateKey(root); !dup.empty()) return path + ": " + dup;
    if (!root.IsMap()) return path + ": expected a mapping with steps: [...]";
    out = yamlToJson(root);
  } catch (const YAML::Exception& e) {
    return path + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
  }
  return {};
}

inline int runTherapyCommands(TherapyCli& t) {
  if (t.record->parsed() && t.rec_replay->parsed()) return runReplay(t);
  if (t.record->parsed()) {
    record::SessionRecord rec;
    auto progress = [](uint64_t done, uint64_t total) {
      if (total > 0) std::fprintf(stderr, "\r%3.0f %%", 100.0 * static_cast<double>(done) / static_cast<double>(total));
    };
    if (t.rec_report->parsed()) {
      const std::string out = t.rec_out.empty() ? withExtension(t.rec_file, ".html") : t.rec_out;
      const std::string err = therapy::writeReport(t.rec_file, t.rec_previous, out,
                                                   [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); },
                                                   t.rec_reference, t.rec_repeatability);
      if (!err.empty()) {
        std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
        return 1;
      }
      std::printf("report: %s\n", out.c_str());
      return 0;
    }
    if (t.rec_repeat->parsed()) {
      nlohmann::json rep;
      if (const std::string err = therapy::writeRepeatability(t.rec_files, t.rec_out, rep); !err.empty()) {
        std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
        return 1;
      }
      std::printf("%-36s %9s %9s %9s\n", "figure", "ICC(2,1)", "SEM", "MDC95");
      for (const auto& [name, v] : rep["figures"].items()) {
        std::printf("%-36s %9s %9s %9s\n", name.c_str(), humanNumber(v["icc"].get<double>(), 3).c_str(),
                    humanNumber(v["sem"].get<double>(), 3).c_str(), humanNumber(v["mdc95"].get<double>(), 3).c_str());
      }
      std::printf("repeatability: %s (%s)\n", t.rec_out.c_str(), rep["source"].get<std::string>().c_str());
      return 0;
    }
    if (t.rec_progress->parsed()) return runProgress(t);
    if (t.rec_fhir->parsed()) {
      const std::string out = t.rec_out.empty() ? withExtension(t.rec_file, ".fhir.json") : t.rec_out;
      if (const std::string err = therapy::writeFhirBundle(t.rec_file, out, t.rec_repeatability); !err.empty()) {
        std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
        return 1;
      }
      std::printf("FHIR bundle: %s\n", out.c_str());
      return 0;
    }
    if (const std::string err = record::readRecord(t.rec_file, rec, progress); !err.empty()) {
      std::fprintf(stderr, "\nphalanx: error: %s\n", err.c_str());
      return 1;
    }
    std::fprintf(stderr, "\n");
    if (t.rec_info->parsed()) {
      const nlohmann::json j{{"header", rec.header},         {"cycles", rec.cycles.size()},
                             {"events", rec.events.size()},  {"complete", rec.complete()},
                             {"torn_tail", rec.torn_tail},   {"bad_records", rec.bad_records},
                             {"bytes_skipped", rec.bytes_skipped}, {"footer", rec.footer},
                             {"duration_s", rec.cycles.empty() ? 0.0 : rec.cycles.back().t_s - rec.cycles.front().t_s}};
      std::cout << j.dump(2) << std::endl;
      return 0;
    }
    const bool to_mcap = t.mcap || (!t.csv && t.rec_out.size() > 5 && t.rec_out.compare(t.rec_out.size() - 5, 5, ".mcap") == 0);
    const std::string out = t.rec_out.empty() ? withExtension(t.rec_file, to_mcap ? ".mcap" : ".csv") : t.rec_out;
    if (const std::string err = to_mcap ? record::exportMcap(rec, out) : record::exportCsv(rec, out, progress);
        !err.empty()) {
      std::fprintf(stderr, "\nphalanx: error: %s\n", err.c_str());
      return 1;
    }
    std::fprintf(stderr, "\n");
    std::printf("exported %zu cycles to %s%s\n", rec.cycles.size(), out.c_str(),
                rec.complete() ? "" : " (the record has no end: the daemon stopped without closing it)");
    return 0;
  }
  for (const auto& [name, sc] : t.cmds) {
    if (!sc->parsed()) continue;
    nlohmann::json req{{"cmd", name}};
    std::string line;
    if (name == "api") {
      line = t.raw;
    } else {
      if (name == "start") {
        if (!t.patient.empty()) req["patient"] = t.patient;
        if (t.cmds["start"]->count("--exercise") > 0 || (t.preset.empty() && t.plan_file.empty())) req["exercise"] = t.exercise;
        if (!t.preset.empty()) req["preset"] = t.preset;
        if (t.self_training) req["self_training"] = true;
        if (!t.plan_file.empty() && !isPlanFileArgument(t.plan_file)) {
          req["plan"] = t.plan_file;  // the name of a plan of the patient's profile: the daemon resolves it
        } else if (!t.plan_file.empty()) {
          if (const std::string err = readPlanFile(t.plan_file, req["plan"]); !err.empty()) {
            std::fprintf(stderr, "phalanx: error: --plan %s\n", err.c_str());
            return 2;
          }
        }
        if (!t.device.empty()) req["device"] = t.device;
        if (!t.scenario.empty()) req["scenario"] = t.scenario;
        if (t.seconds >= 0) req["seconds"] = t.seconds;
        if (t.seed >= 0) req["seed"] = t.seed;
      }
      if (name == "exercise" || name == "mode") {
        if (!t.preset.empty()) req["preset"] = t.preset;
        if (t.preset.empty() && t.cmds[name]->count("name") == 0) {
          std::fprintf(stderr, "phalanx: error: %s: give an exercise name or --preset NAME\n", name.c_str());
          return 2;
        }
        if (t.cmds[name]->count("name") > 0) req["exercise"] = t.exercise;
      }
      if ((name == "start" || name == "exercise" || name == "mode") && !t.params.empty()) {
        req["params"] = nlohmann::json::parse(t.params, nullptr, false);
        if (req["params"].is_discarded()) {
          std::fprintf(stderr, "phalanx: error: --params is not valid JSON\n");
          return 2;
        }
      }
      if (name == "limits" && !t.effort_max.empty()) {
        for (const auto& kv : t.effort_max) {
          const auto eq = kv.find('=');
          char* end = nullptr;
          const double v = eq == std::string::npos ? 0.0 : std::strtod(kv.c_str() + eq + 1, &end);
          if (eq == std::string::npos || end == nullptr || *end != 0) {
            std::fprintf(stderr, "phalanx: error: --effort-max %s: expected channel=value\n", kv.c_str());
            return 2;
          }
          req["effort_max"][kv.substr(0, eq)] = v;
        }
      }
      if (name == "profile" || (name == "recordings" && !t.patient.empty())) req["patient"] = t.patient;
      line = req.dump();
    }
    if (const std::string err = resolveSocket(t); !err.empty()) {
      std::fprintf(stderr, "phalanx: error: client config %s\n", err.c_str());
      return 2;
    }
    std::string answer;
    if (const std::string err = api::callRaw(t.socket, line, answer, 15000, t.daemon_uid); !err.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
      return 3;
    }
    const nlohmann::json resp = nlohmann::json::parse(answer, nullptr, false);
    if (resp.is_discarded() || !resp.is_object()) {
      std::fprintf(stderr, "phalanx: error: bad answer: %s\n", answer.c_str());
      return 3;
    }
    if (!resp.value("ok", false)) {
      std::fprintf(stderr, "phalanx: refused: %s\n", resp.value("error", std::string("?")).c_str());
      return 1;
    }
    if (t.json || name == "api") std::cout << resp.dump(2) << std::endl;
    else printHuman(name, resp["result"]);
    if (name == "start") return waitForSessionStart(t);
    if (name == "stop" && resp["result"].is_object() && resp["result"].contains("error")) return 1;
    return 0;
  }
  return -1;
}

}  // namespace phalanx::host::cli
