#pragma once
// The `phalanx` CLI as a client of phalanxd's control API (docs/api.md), and the session-record tools.
//   phalanx status | start | stop | exercise | mode | reset | limits | profiles | profile | recordings
//   phalanx record export FILE [--csv|--mcap] [--out PATH] | record info FILE | record report FILE [--previous F] --out F
#include <CLI/CLI.hpp>
#include <cstdio>
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
#include "phalanx/host/therapy/report.h"

namespace phalanx::host::cli {

struct TherapyCli {
  std::string socket = api::defaultSocketPath();
  long daemon_uid = -1;  ///< a daemon account to trust besides root and the caller (socket_access.h)
  bool json = false;
  std::map<std::string, CLI::App*> cmds;
  // start
  std::string patient, exercise = "assessment", params, device, scenario;
  double seconds = -1.0;
  long seed = -1;
  std::vector<std::string> effort_max;  // channel=value
  std::string raw;
  // record
  CLI::App* record = nullptr;
  CLI::App* rec_export = nullptr;
  CLI::App* rec_info = nullptr;
  CLI::App* rec_report = nullptr;
  std::string rec_file, rec_out, rec_previous, rec_reference;
  bool csv = false;
  bool mcap = false;
};

inline void addTherapyCommands(CLI::App& app, TherapyCli& t) {
  auto client = [&](const char* name, const char* help) {
    CLI::App* sc = app.add_subcommand(name, help);
    sc->add_option("--socket", t.socket, "phalanxd's API socket");
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
  client("stop", "stop the session (device left safe; record closed; report written)");
  for (const char* name : {"exercise", "mode"}) {
    CLI::App* sc = client(name, "switch the running session's exercise");
    sc->add_option("name", t.exercise, "idle|assessment|resistance|assistance|record-pattern|playback|grasp")->required();
    sc->add_option("--params", t.params, "exercise parameters (JSON object)");
  }
  client("reset", "clear latched faults (e-stop reset) on the device");
  CLI::App* limits = client("limits", "show, or lower, the running session's limits");
  limits->add_option("--effort-max", t.effort_max, "channel=value (e.g. index=2.5), may repeat");
  client("profiles", "list patient profiles and whether each is valid");
  client("profile", "show one patient profile")->add_option("patient", t.patient)->required();
  client("recordings", "list session records")->add_option("--patient", t.patient);
  client("api", "send one raw JSON request line (for scripts)")->add_option("request", t.raw)->required();

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
}

inline void printSessionStatus(const nlohmann::json& s) {
  std::printf("session %s", s.value("phase", "?").c_str());
  if (s.contains("patient")) std::printf(", patient %s", s["patient"].get<std::string>().c_str());
  if (s.contains("exercise")) std::printf(", exercise %s", s["exercise"].get<std::string>().c_str());
  if (s.contains("t_s")) {
    std::printf(", %.1f s, device %s, faults %s%s", s["t_s"].get<double>(), s["device_mode"].get<std::string>().c_str(),
                s["faults"].get<std::string>().c_str(), s["estop"].get<bool>() ? ", E-STOP" : "");
  }
  std::printf("\n");
  if (s.contains("record_error")) std::printf("  RECORD FAILED: %s\n", s["record_error"].get<std::string>().c_str());
  if (s.contains("channels")) {
    for (const auto& [name, c] : s["channels"].items()) {
      auto f = [&](const char* k) { return c[k].is_number() ? c[k].get<double>() : 0.0; };
      std::printf("  %-8s q %6.1f deg  effort %6.2f (cmd %6.2f, max %.2f) %s\n", name.c_str(), f("q_deg"),
                  f("effort_measured"), f("effort_command"), f("effort_max"), s["effort_unit"].get<std::string>().c_str());
    }
  }
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
  std::cout << r.dump(2) << std::endl;
}

/// path with the extension of its file name (not of a directory's) replaced by ext.
inline std::string withExtension(const std::string& path, const std::string& ext) {
  const auto slash = path.rfind('/');
  const auto dot = path.rfind('.');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash + 1);
  return (has_ext ? path.substr(0, dot) : path) + ext;
}

/// Runs the parsed therapy/record subcommand; returns -1 if none of them was given.
inline int runTherapyCommands(TherapyCli& t) {
  if (t.record->parsed()) {
    record::SessionRecord rec;
    auto progress = [](uint64_t done, uint64_t total) {
      if (total > 0) std::fprintf(stderr, "\r%3.0f %%", 100.0 * static_cast<double>(done) / static_cast<double>(total));
    };
    if (t.rec_report->parsed()) {
      const std::string out = t.rec_out.empty() ? withExtension(t.rec_file, ".html") : t.rec_out;
      const std::string err = therapy::writeReport(t.rec_file, t.rec_previous, out,
                                                   [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); },
                                                   t.rec_reference);
      if (!err.empty()) {
        std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
        return 1;
      }
      std::printf("report: %s\n", out.c_str());
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
        req["exercise"] = t.exercise;
        if (!t.device.empty()) req["device"] = t.device;
        if (!t.scenario.empty()) req["scenario"] = t.scenario;
        if (t.seconds >= 0) req["seconds"] = t.seconds;
        if (t.seed >= 0) req["seed"] = t.seed;
      }
      if (name == "exercise" || name == "mode") req["exercise"] = t.exercise;
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
    return 0;
  }
  return -1;
}

}  // namespace phalanx::host::cli
