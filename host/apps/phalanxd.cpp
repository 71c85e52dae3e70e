// phalanxd: the Phalanx host daemon. Runs one device session at the configured rate until stopped.
#include <cstdio>
#include <iostream>

#include "common_options.h"
#include "phalanx/host/config.h"

int main(int argc, char** argv) {
  using namespace phalanx::host;
  CLI::App app{"phalanxd - Phalanx host daemon"};
  RunOptions opt;
  std::string config_path;
  bool no_rt = false;
  bool json = false;
  addRunOptions(app, opt, config_path, no_rt, json);
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
  nlohmann::json summary;
  const int rc = runSession(opt, summary);
  printSummary(summary, json);
  return rc;
}
