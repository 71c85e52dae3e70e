// phalanx: the user's command-line entry point.
//   phalanx run     start a session (the simulated firmware too, for sim:* devices) and print a summary
//   phalanx version protocol and build information
#include <cstdio>
#include <iostream>

#include "common_options.h"
#include "phalanx/host/can_budget.h"
#include "phalanx/host/config.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/protocol/messages.h"

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

  CLI::App* can = app.add_subcommand("can", "CAN bus-load budget (computed) and measurement (from candump -L)");
  can->require_subcommand(1);
  double can_rate_hz = 1000, can_bps = 1e6, can_data_bps = 5e6;
  std::string can_log;
  CLI::App* can_budget = can->add_subcommand("budget", "bus load of every device per tick, from the CAN mapping");
  can_budget->add_option("--rate-hz", can_rate_hz, "ticks per second")->check(CLI::Range(1.0, 10000.0));
  can_budget->add_option("--bitrate", can_bps, "nominal bit rate")->check(CLI::Range(1e4, 1e6));
  CLI::App* can_load = can->add_subcommand("load", "bus load measured from a candump -L log");
  can_load->add_option("--log", can_log, "candump -L log file")->required();
  can_load->add_option("--bitrate", can_bps, "nominal bit rate")->check(CLI::Range(1e4, 1e6));
  can_load->add_option("--data-bitrate", can_data_bps, "CAN-FD data-phase bit rate")->check(CLI::Range(1e4, 1.2e7));

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

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (can->parsed()) {
    const nlohmann::json r = can_budget->parsed() ? canBudget(can_rate_hz, can_bps)
                                                  : canLoadFromLog(can_log, can_bps, can_data_bps);
    std::cout << r.dump(2) << std::endl;
    return r.contains("error") ? 1 : 0;
  }
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
