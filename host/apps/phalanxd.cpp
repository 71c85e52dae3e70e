// phalanxd: the Phalanx host daemon. Runs one device session at the configured rate until stopped, or, with
// --api, serves the therapist's control API on a UNIX socket and runs the sessions it is asked to start.
#include <grp.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "cli_args.h"
#include "common_options.h"
#include "phalanx/host/api/server.h"
#include "phalanx/host/config.h"
#include "phalanx/host/therapy/therapy_session.h"

namespace {

using namespace phalanx::host;

struct DaemonArgs {
  RunOptions opt;
  std::string config_path;
  bool no_rt = false;
  bool json = false;
  therapy::TherapySessionConfig tcfg;
  std::string profile_path;
  std::string exercise_params;
  api::ServerConfig api_cfg;
  std::string api_group;
  std::string dashboard_spec;
};

// Options of one session run by phalanxd itself; with --api every session is started by a request instead.
constexpr const char* kSessionOnlyOptions[] = {"--session-record", "--profile", "--exercise", "--exercise-params",
                                               "--report", "--previous-record", "--record", "--live"};
constexpr const char* kApiOnlyOptions[] = {"--records-dir", "--profiles-dir", "--allow-device", "--api-group"};

void addDaemonOptions(CLI::App& app, DaemonArgs& a) {
  addRunOptions(app, a.opt, a.config_path, a.no_rt, a.json);
  app.add_option("--session-record", a.tcfg.record_path,
                 "crash-safe session record (.phrec) of every cycle, setpoint and event (must not exist)");
  app.add_option("--profile", a.profile_path, "patient profile (YAML); its limits are enforced")->check(CLI::ExistingFile);
  app.add_option("--exercise", a.tcfg.exercise,
                 "therapy exercise: idle|assessment|resistance|assistance|record-pattern|playback|grasp|tardieu|passive-rom|max-force");
  app.add_option("--exercise-params", a.exercise_params, "exercise parameters as a JSON object");
  app.add_option("--report", a.tcfg.report_path, "HTML report written at session end (needs --session-record)");
  app.add_option("--previous-record", a.tcfg.previous_record, "previous session's record, for the report's comparison");
  app.add_option("--api", a.api_cfg.socket_path,
                 "serve the control API on this UNIX socket (docs/api.md); without a path: " + api::defaultSocketPath())
      ->expected(0, 1);
  app.add_option("--allow-device", a.api_cfg.allowed_devices,
                 "API mode: a device a start request may name besides --device (repeatable; docs/security.md)")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--api-group", a.api_group,
                 "API mode: group (name or id) whose members may use the API besides this user and root "
                 "(default: this process's group)");
  app.add_option("--records-dir", a.api_cfg.records_dir, "API mode: directory for session records and reports");
  app.add_option("--profiles-dir", a.api_cfg.profiles_dir, "API mode: directory of patient profiles");
  app.add_option("--dashboard", a.dashboard_spec,
                 "API mode: serve the live dashboard on ADDRESS:PORT (loopback; docs/dashboard.md; port 0: any free)");
  cli::refuseEmptyValues(app);
  cli::hideUnsetDefaults(app);
}

int badArguments(const std::string& message) {
  std::fprintf(stderr, "phalanxd: error: %s\n", message.c_str());
  return cli::kExitBadArguments;
}

/// An option of the other mode would be ignored without a word: refuse it, naming it.
std::string modeConflict(const CLI::App& app) {
  const bool api = app.count("--api") > 0;
  if (api) {
    for (const char* o : kSessionOnlyOptions) {
      if (app.count(o) > 0) return std::string(o) + ": not used with --api (each session comes from a start request)";
    }
  } else {
    for (const char* o : kApiOnlyOptions) {
      if (app.count(o) > 0) return std::string(o) + ": only used with --api";
    }
  }
  return {};
}

/// Command line, then the --config file under it, then the command line again over the file. Returns -1 to go on.
int parseArguments(CLI::App& app, DaemonArgs& a, int argc, char** argv) {
  int rc = 0;
  if (!cli::parseArgs(app, argc, argv, "phalanxd", rc)) return rc;
  if (!a.config_path.empty()) {
    RunOptions from_file;
    if (const std::string err = loadConfigFile(a.config_path, from_file); !err.empty()) return badArguments(err);
    a.opt = from_file;
    if (!cli::parseArgs(app, argc, argv, "phalanxd", rc)) return rc;
  }
  if (const std::string err = modeConflict(app); !err.empty()) return badArguments(err);
  if (const std::string err = checkSessionLength(a.opt.seconds, a.opt.rate_hz); !err.empty()) {
    return badArguments((app.count("--seconds") > 0 ? "--seconds: " : a.config_path + ": seconds: ") + err);
  }
  if (a.no_rt) a.opt.realtime = false;
  if (!a.dashboard_spec.empty()) {
    if (const std::string err = api::parseDashboardSpec(a.dashboard_spec, a.opt.dashboard); !err.empty()) {
      return badArguments(err);
    }
  }
  const bool api_mode = app.count("--api") > 0;
  // `--api` alone takes the default path; `--api ""` names an empty one (CLI11 reads both as ""): the words say.
  for (int i = 1; i < argc; ++i) {
    const std::string w = argv[i];
    if (w == "--api=" || (w == "--api" && i + 1 < argc && argv[i + 1][0] == '\0')) {
      return badArguments("--api: must not be empty (give a socket path, or --api alone for the default)");
    }
  }
  if (api_mode && a.api_cfg.socket_path.empty()) a.api_cfg.socket_path = api::defaultSocketPath();
  if (!a.api_group.empty()) {
    if (const group* g = ::getgrnam(a.api_group.c_str()); g != nullptr) {
      a.api_cfg.api_group = static_cast<long>(g->gr_gid);
    } else if (a.api_group.find_first_not_of("0123456789") == std::string::npos && a.api_group.size() < 10) {
      a.api_cfg.api_group = std::atol(a.api_group.c_str());
    } else {
      return badArguments("--api-group: no group '" + a.api_group + "'");
    }
  }
  if (a.opt.dashboard.enabled && a.api_cfg.socket_path.empty()) {
    return badArguments("the dashboard needs --api (its controls are control-API requests)");
  }
  return -1;
}

/// The one-session mode's therapy options. Returns -1 to go on.
int prepareTherapy(DaemonArgs& a) {
  if (!a.profile_path.empty()) {
    if (const std::string err = therapy::loadProfileFile(a.profile_path, a.tcfg.profile); !err.empty()) {
      return badArguments("profile refused: " + err);
    }
    a.tcfg.have_profile = true;
  }
  if (!a.exercise_params.empty()) {
    a.tcfg.exercise_params = nlohmann::json::parse(a.exercise_params, nullptr, false);
    if (a.tcfg.exercise_params.is_discarded() || !a.tcfg.exercise_params.is_object()) {
      return badArguments("--exercise-params: not a JSON object");
    }
  }
  if (!a.tcfg.report_path.empty() && a.tcfg.record_path.empty()) return badArguments("--report needs --session-record");
  if (a.tcfg.have_profile && a.tcfg.exercise.empty()) a.tcfg.exercise = "idle";  // profile limits need the therapy layer
  return -1;
}

int runOneSession(DaemonArgs& a) {
  nlohmann::json summary;
  int rc = 0;
  if (a.tcfg.record_path.empty() && a.tcfg.exercise.empty()) {
    rc = runSession(a.opt, summary);
  } else {
    therapy::TherapySession session(a.tcfg);
    // The record file first: a path that cannot be created refuses the session before the device is touched.
    if (const std::string err = session.createRecord(); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: --session-record: %s\n", err.c_str());
      return 2;
    }
    a.opt.hooks = &session;
    rc = runSession(a.opt, summary);
    rc = session.finish(summary, rc);
    summary = session.endSummary();
  }
  printSummary(summary, a.json);
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"phalanxd - Phalanx host daemon"};
  DaemonArgs a;
  addDaemonOptions(app, a);
  if (const int rc = parseArguments(app, a, argc, argv); rc >= 0) return rc;
  installStopSignals();
  if (!a.api_cfg.socket_path.empty()) {
    a.api_cfg.defaults = a.opt;
    a.api_cfg.dashboard = a.opt.dashboard;
    return api::serve(a.api_cfg);
  }
  if (const int rc = prepareTherapy(a); rc >= 0) return rc;
  return runOneSession(a);
}
