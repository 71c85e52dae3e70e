// phalanx: the user's command-line entry point.
//   phalanx run     start a session (the simulated firmware too, for sim:* devices) and print a summary
//   phalanx version protocol and build information
#include <cstdio>
#include <iostream>

#include "common_options.h"
#include "phalanx/host/config.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/protocol/messages.h"
#include "therapy_cli.h"

int main(int argc, char** argv) {
  using namespace phalanx::host;
  CLI::App app{"phalanx - Phalanx haptic control stack"};
  app.require_subcommand(1);

  RunOptions opt;
  std::string config_path;
  bool no_rt = false;
  bool json = false;
  CLI::App* run = app.add_subcommand("run", "run a device session (default device: sim:glove5)");
  addRunOptions(*run, opt, config_path, no_rt, json);

  CLI::App* version = app.add_subcommand("version", "print version information");

  CLI::App* bench = app.add_subcommand("bench", "run a bench scenario and print its metrics");
  bench->require_subcommand(1);
  phalanx::host::glove::GloveBenchOptions bench_opt;
  bool bench_no_noise = false;
  auto add_bench_options = [&](CLI::App* sc) {
    sc->add_option("--seconds", bench_opt.seconds, "scenario length (0: its default)")->check(CLI::Range(0.0, 600.0));
    sc->add_option("--seed", bench_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", bench_no_noise, "simulated sensors without noise");
    sc->add_flag("--json", json, "JSON output (the default; kept for scripts)");
  };
  CLI::App* free_motion = bench->add_subcommand("glove-free-motion", "close/open maneuvers at zero force (000 §4.3)");
  add_bench_options(free_motion);
  CLI::App* grasp = bench->add_subcommand("glove-grasp", "grasp the rigid virtual ball (000 eq 1)");
  add_bench_options(grasp);

  phalanx::host::cli::TherapyCli therapy_cli;
  phalanx::host::cli::addTherapyCommands(app, therapy_cli);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (const int rc = phalanx::host::cli::runTherapyCommands(therapy_cli); rc >= 0) return rc;
  if (bench->parsed()) {
    bench_opt.noise = !bench_no_noise;
    const nlohmann::json result = free_motion->parsed() ? phalanx::host::glove::benchFreeMotion(bench_opt)
                                                        : phalanx::host::glove::benchGrasp(bench_opt);
    std::cout << result.dump(2) << std::endl;
    return 0;
  }
  if (version->parsed()) {
    std::printf("phalanx %s, wire protocol v%u\n", PHALANX_VERSION, phalanx::protocol::kProtocolVersion);
    return 0;
  }
  if (!config_path.empty()) {
    RunOptions from_file;
    if (const std::string err = loadConfigFile(config_path, from_file); !err.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
      return 2;
    }
    opt = from_file;
    app.parse(argc, argv);
  }
  if (no_rt) opt.realtime = false;
  if (opt.seconds == 0.0 && json) opt.seconds = 10.0;
  installStopSignals();
  nlohmann::json summary;
  const int rc = runSession(opt, summary);
  printSummary(summary, json);
  return rc;
}
