// phalanx: the user's command-line entry point.
//   phalanx run     start a session (the simulated firmware too, for sim:* devices) and print a summary
//   phalanx version protocol and build information
#include <cstdio>
#include <iostream>

#include "common_options.h"
#include "design_cli.h"
#include "phalanx/host/config.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/host/pen/pen_bench.h"
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

  phalanx::host::pen::PenSplitBenchOptions pen_split_opt;
  CLI::App* pen_split = bench->add_subcommand("pen-split", "pen force split over the workspace: accuracy, effort, saturation (004 Fig. 18)");
  pen_split->add_option("--seed", pen_split_opt.seed, "random-wrench seed");
  pen_split->add_option("--grid", pen_split_opt.grid, "samples per workspace axis (grid^5 poses)")->check(CLI::Range(2, 15));
  pen_split->add_option("--wrenches-per-pose", pen_split_opt.wrenches_per_pose, "random wrenches per pose and class")
      ->check(CLI::Range(1, 1000));
  pen_split->add_flag("--json", json, "JSON output (the default; kept for scripts)");

  phalanx::host::sea::SeaBenchOptions sea_opt;
  auto add_sea_options = [&](CLI::App* sc) {
    sc->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    sc->add_option("--seconds", sea_opt.seconds, "scenario length (0: its default)")->check(CLI::Range(0.0, 600.0));
    sc->add_option("--seed", sea_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", bench_no_noise, "simulated sensors without noise");
    sc->add_flag("--json", json, "JSON output (the default; kept for scripts)");
    sc->add_option("--controller", sea_opt.controller, "both | paper (001 plain PID, eq 7-8) | ours")
        ->check(CLI::IsMember({"both", "paper", "ours"}));
    sc->add_option("--plant-backlash-scale", sea_opt.plant_backlash_scale,
                   "scale the simulated cable play (model mismatch)")->check(CLI::Range(0.0, 5.0));
  };
  CLI::App* sea_sine = bench->add_subcommand("sea-rig-sine", "SEA test rig, sinusoidal torque (001 §7.1.1-7.1.2, eq 15)");
  add_sea_options(sea_sine);
  sea_sine->add_option("--peak-Nm", sea_opt.peak_Nm, "peak torque (paper: 0.15 or 0.3)")->check(CLI::Range(0.0, 0.4));
  sea_sine->add_option("--hz", sea_opt.hz, "frequency (paper: 0.5)")->check(CLI::Range(0.01, 20.0));
  CLI::App* sea_chirp = bench->add_subcommand("sea-rig-chirp", "SEA test rig, linear chirp, -3 dB bandwidth (001 §7.1.3, eq 16-17)");
  add_sea_options(sea_chirp);
  sea_chirp->add_option("--amplitude-Nm", sea_opt.chirp_amplitude_Nm, "chirp amplitude tau_A")->check(CLI::Range(0.01, 0.4));
  sea_chirp->add_option("--fmax-hz", sea_opt.chirp_fmax_hz, "frequency at the end of the sweep")->check(CLI::Range(2.0, 50.0));

  DesignCommands design_cmds(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (design_cmds.parsed()) return design_cmds.run();
  if (sea_sine->parsed() || sea_chirp->parsed()) {
    sea_opt.noise = !bench_no_noise;
    const nlohmann::json result = sea_sine->parsed() ? phalanx::host::sea::benchRigSine(sea_opt)
                                                     : phalanx::host::sea::benchRigChirp(sea_opt);
    std::cout << result.dump(2) << std::endl;
    return 0;
  }
  if (pen_split->parsed()) {
    std::cout << phalanx::host::pen::benchSplit(pen_split_opt).dump(2) << std::endl;
    return 0;
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
