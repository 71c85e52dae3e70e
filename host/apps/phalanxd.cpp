// phalanxd: the Phalanx host daemon. Runs one device session at the configured rate until stopped, or, with
// --api, serves the therapist's control API on a UNIX socket and runs the sessions it is asked to start.
#include <cstdio>
#include <iostream>

#include "common_options.h"
#include "phalanx/host/api/server.h"
#include "phalanx/host/config.h"
#include "phalanx/host/therapy/therapy_session.h"

int main(int argc, char** argv) {
  using namespace phalanx::host;
  CLI::App app{"phalanxd - Phalanx host daemon"};
  RunOptions opt;
  std::string config_path;
  bool no_rt = false;
  bool json = false;
  addRunOptions(app, opt, config_path, no_rt, json);
  therapy::TherapySessionConfig tcfg;
  std::string profile_path;
  std::string exercise_params;
  api::ServerConfig api_cfg;
  app.add_option("--session-record", tcfg.record_path,
                 "crash-safe session record (.phrec) of every cycle, setpoint and event (must not exist)");
  app.add_option("--profile", profile_path, "patient profile (YAML); its limits are enforced")->check(CLI::ExistingFile);
  app.add_option("--exercise", tcfg.exercise,
                 "therapy exercise: idle|assessment|resistance|assistance|record-pattern|playback|grasp");
  app.add_option("--exercise-params", exercise_params, "exercise parameters as a JSON object");
  app.add_option("--report", tcfg.report_path, "HTML report written at session end (needs --session-record)");
  app.add_option("--previous-record", tcfg.previous_record, "previous session's record, for the report's comparison");
  app.add_option("--api", api_cfg.socket_path, "serve the control API on this UNIX socket (docs/api.md)");
  app.add_option("--records-dir", api_cfg.records_dir, "API mode: directory for session records and reports");
  app.add_option("--profiles-dir", api_cfg.profiles_dir, "API mode: directory of patient profiles");
  std::string dashboard_spec;
  app.add_option("--dashboard", dashboard_spec,
                 "API mode: serve the live dashboard on ADDRESS:PORT (loopback; docs/dashboard.md; port 0: any free)");
  // Parse twice: first to find --config, then apply the file, then let the command line override it.
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (!config_path.empty()) {
    RunOptions from_file;
    if (const std::string err = loadConfigFile(config_path, from_file); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: %s\n", err.c_str());
      return 2;
    }
    opt = from_file;
    app.parse(argc, argv);
  }
  if (no_rt) opt.realtime = false;
  installStopSignals();
  if (!dashboard_spec.empty()) {
    if (const std::string err = api::parseDashboardSpec(dashboard_spec, opt.dashboard); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: %s\n", err.c_str());
      return 2;
    }
  }
  if (opt.dashboard.enabled && api_cfg.socket_path.empty()) {
    std::fprintf(stderr, "phalanxd: error: the dashboard needs --api (its controls are control-API requests)\n");
    return 2;
  }
  if (!api_cfg.socket_path.empty()) {
    api_cfg.defaults = opt;
    api_cfg.dashboard = opt.dashboard;
    return api::serve(api_cfg);
  }
  if (!profile_path.empty()) {
    if (const std::string err = therapy::loadProfileFile(profile_path, tcfg.profile); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: profile refused: %s\n", err.c_str());
      return 2;
    }
    tcfg.have_profile = true;
  }
  if (!exercise_params.empty()) {
    tcfg.exercise_params = nlohmann::json::parse(exercise_params, nullptr, false);
    if (tcfg.exercise_params.is_discarded() || !tcfg.exercise_params.is_object()) {
      std::fprintf(stderr, "phalanxd: error: --exercise-params: not a JSON object\n");
      return 2;
    }
  }
  if (!tcfg.report_path.empty() && tcfg.record_path.empty()) {
    std::fprintf(stderr, "phalanxd: error: --report needs --session-record\n");
    return 2;
  }
  if (tcfg.have_profile && tcfg.exercise.empty()) tcfg.exercise = "idle";  // profile limits need the therapy layer
  nlohmann::json summary;
  int rc = 0;
  if (tcfg.record_path.empty() && tcfg.exercise.empty()) {
    rc = runSession(opt, summary);
  } else {
    therapy::TherapySession session(tcfg);
    // The record file first: a path that cannot be created refuses the session before the device is touched.
    if (const std::string err = session.createRecord(); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: --session-record: %s\n", err.c_str());
      return 2;
    }
    opt.hooks = &session;
    rc = runSession(opt, summary);
    rc = session.finish(summary, rc);
    summary = session.endSummary();
  }
  printSummary(summary, json);
  return rc;
}
