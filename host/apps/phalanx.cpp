// phalanx: the user's command-line entry point.
//   phalanx run     start a session (the simulated firmware too, for sim:* devices) and print a summary
//   phalanx version protocol and build information
//   phalanx sea-calibrate  SEA finger subject parameters from a recording (001 eq 12)
#include <cstdio>
#include <iostream>

#include "cli_args.h"
#include "common_options.h"
#include "design_cli.h"
#include "phalanx/host/can_budget.h"
#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/config.h"
#include "phalanx/host/dds/dds_options.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/host/mcu_diag.h"
#include "phalanx/host/sea/sea_bench.h"
#include "phalanx/host/pen/pen_bench.h"
#include "phalanx/host/sea/sea_calibrate.h"
#include "phalanx/protocol/messages.h"
#include "therapy_cli.h"

namespace {
constexpr double kBenchStep_s = 1e-3;  // the glove and SEA benches step their lockstep loop at 1 kHz
}  // namespace

namespace {

/// `phalanx devices`: a table (or JSON) of every device announced within the listening time.
int listDevicesMain(uint32_t domain, const std::string& interface, double seconds, bool json) {
  std::vector<phalanx::host::dds::DeviceSeen> seen;
  if (const std::string err = phalanx::host::dds::listDevices(domain, interface, seconds, seen); !err.empty()) {
    std::fprintf(stderr, "phalanx devices: %s\n", err.c_str());
    return 3;
  }
  if (json) {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& d : seen) {
      a.push_back({{"host", d.host}, {"name", d.name}, {"type", d.device_type}, {"device", d.device_spec},
                   {"state", d.state}, {"rate_hz", d.rate_hz}, {"firmware_build_id", d.firmware_build_id},
                   {"commands", d.commands}, {"age_s", d.age_s}});
    }
    std::printf("%s\n", a.dump(2).c_str());
    return 0;
  }
  std::printf("%-16s %-24s %-11s %-8s %-9s %s\n", "HOST", "NAME", "TYPE", "RATE_HZ", "COMMANDS", "STATE");
  for (const auto& d : seen) {
    std::printf("%-16s %-24s %-11s %-8.0f %-9s %s\n", d.host.c_str(), d.name.c_str(), d.device_type.c_str(), d.rate_hz,
                d.commands ? "on" : "off", d.state.c_str());
  }
  if (seen.empty()) std::fprintf(stderr, "phalanx devices: none announced on domain %u within %.1f s\n", domain, seconds);
  return 0;
}

}  // namespace

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

  // `phalanx devices`: every device the daemons on the network announce (docs/dds.md §"Devices on the network").
  CLI::App* devices = app.add_subcommand("devices", "list the devices announced over DDS (rt/phalanx/devices)");
  uint32_t dev_domain = 0;
  std::string dev_interface;
  double dev_seconds = 2.0;
  bool dev_json = false;
  devices->add_option("--domain", dev_domain, "DDS domain id (dds.domain_id)")->check(CLI::Range(0, 232));
  devices->add_option("--interface", dev_interface, "network interface name or IPv4 address (dds.interface)");
  devices->add_option("--seconds", dev_seconds, "listen this long")->check(CLI::Range(0.1, 60.0));
  devices->add_flag("--json", dev_json, "one JSON array");

  CLI::App* mcu_diag = app.add_subcommand(
      "mcu-diag", "read an MCU board's control-tick statistics through the protocol (ParamGet 0x0080-0x0089)");
  std::string mcu_diag_device;
  double mcu_diag_timeout_s = 2.0;
  mcu_diag->add_option("--device", mcu_diag_device, "serial:<path> of the board (e.g. the QEMU board's pty)")
      ->required();
  mcu_diag->add_option("--timeout", mcu_diag_timeout_s, "seconds to wait for each answer")
      ->check(cli::inRange(0.1, 60.0));
  CLI::App* can = app.add_subcommand("can", "CAN bus-load budget (computed) and measurement (from candump -L)");
  can->require_subcommand(1);
  double can_rate_hz = 1000, can_bps = 1e6, can_data_bps = 5e6;
  std::string can_log;
  CLI::App* can_budget = can->add_subcommand("budget", "bus load of every device per tick, from the CAN mapping");
  can_budget->add_option("--rate-hz", can_rate_hz, "ticks per second")->check(cli::inRange(1.0, 10000.0));
  can_budget->add_option("--bitrate", can_bps, "nominal bit rate")->check(cli::inRange(1e4, 1e6));
  CLI::App* can_load = can->add_subcommand("load", "bus load measured from a candump -L log");
  can_load->add_option("--log", can_log, "candump -L log file")->required();
  can_load->add_option("--bitrate", can_bps, "nominal bit rate")->check(cli::inRange(1e4, 1e6));
  can_load->add_option("--data-bitrate", can_data_bps, "CAN-FD data-phase bit rate")->check(cli::inRange(1e4, 1.2e7));

  CLI::App* bench = app.add_subcommand("bench", "run a bench scenario and print its metrics");
  bench->require_subcommand(1);
  phalanx::host::glove::GloveBenchOptions bench_opt;
  bool bench_no_noise = false;
  bool bench_no_drift = false;
  auto add_bench_options = [&](CLI::App* sc) {
    sc->add_option("--seconds", bench_opt.seconds, "scenario length (0: its default)")
        ->check(cli::inRange(0.0, 600.0))
        ->check(cli::zeroOrAtLeast(kBenchStep_s, "its default"));
    sc->add_option("--seed", bench_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", bench_no_noise, "simulated sensors without noise");
    sc->add_flag("--no-drift", bench_no_drift, "simulated strain gauges without their thermal zero drift (noise stays)");
    sc->add_option("--worn-s", bench_opt.worn_s,
                   "how long the glove was worn before the start (s; the pad is still warming up; default 60)")
        ->check(cli::inRange(0.0, 86400.0));
    sc->add_flag("--json", json, "JSON output (the default; kept for scripts)");
  };
  CLI::App* free_motion = bench->add_subcommand("glove-free-motion", "close/open maneuvers at zero force (000 §4.3)");
  add_bench_options(free_motion);
  CLI::App* grasp = bench->add_subcommand("glove-grasp", "grasp the rigid virtual ball (000 eq 1)");
  add_bench_options(grasp);

  phalanx::host::sea::SeaBenchOptions sea_opt;
  auto add_sea_options = [&](CLI::App* sc) {
    sc->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    sc->add_option("--seconds", sea_opt.seconds, "scenario length (0: its default)")
        ->check(cli::inRange(0.0, 600.0))
        ->check(cli::zeroOrAtLeast(kBenchStep_s, "its default"));
    sc->add_option("--seed", sea_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", bench_no_noise, "simulated sensors without noise");
    sc->add_flag("--json", json, "JSON output (the default; kept for scripts)");
    sc->add_option("--controller", sea_opt.controller, "both | paper (001 plain PID, eq 7-8) | ours")
        ->check(CLI::IsMember({"both", "paper", "ours"}));
    sc->add_option("--plant-backlash-scale", sea_opt.plant_backlash_scale,
                   "scale the simulated cable play (model mismatch)")->check(cli::inRange(0.0, 5.0));
  };
  CLI::App* sea_sine = bench->add_subcommand("sea-rig-sine", "SEA test rig, sinusoidal torque (001 §7.1.1-7.1.2, eq 15)");
  add_sea_options(sea_sine);
  sea_sine->add_option("--peak-Nm", sea_opt.peak_Nm, "peak torque (paper: 0.15 or 0.3)")->check(cli::inRange(0.0, 0.4));
  sea_sine->add_option("--hz", sea_opt.hz, "frequency (paper: 0.5)")->check(cli::inRange(0.01, 20.0));
  CLI::App* sea_chirp = bench->add_subcommand("sea-rig-chirp", "SEA test rig, linear chirp, -3 dB bandwidth (001 §7.1.3, eq 16-17)");
  add_sea_options(sea_chirp);
  sea_chirp->add_option("--amplitude-Nm", sea_opt.chirp_amplitude_Nm, "chirp amplitude tau_A")->check(cli::inRange(0.01, 0.4));
  sea_chirp->add_option("--fmax-hz", sea_opt.chirp_fmax_hz, "frequency at the end of the sweep")->check(cli::inRange(2.0, 50.0));
  CLI::App* sea_finger_torque =
      bench->add_subcommand("sea-finger-torque", "SEA exoskeleton on the simulated finger: finger MCP/PIP torque tracking (001 §7.6, eq 9-11)");
  add_sea_options(sea_finger_torque);
  sea_finger_torque->add_flag("--user-holds", sea_opt.finger_user_holds,
                              "the simulated user holds the rest posture (default: relaxed finger)");
  CLI::App* sea_transparency =
      bench->add_subcommand("sea-transparency", "SEA exoskeleton: residual torque during random finger motion (001 §7.7)");
  add_sea_options(sea_transparency);
  CLI::App* sea_cal = app.add_subcommand("sea-calibrate", "estimate SEA finger subject parameters (001 eq 12)");
  std::string sea_cal_csv;
  std::string sea_cal_subject;
  int sea_cal_stride = 1;
  sea_cal->add_option("--recording", sea_cal_csv, "CSV over a full range of motion (phalanx run --record; recommended: 60 s at 1 kHz, --smooth 51 --stride 10)")->required();
  sea_cal->add_option("--subject", sea_cal_subject, "subject YAML to update (created if absent)")->required();
  int sea_cal_smooth = 1;
  sea_cal->add_option("--stride", sea_cal_stride, "use every n-th row")->check(cli::inRange(1, 1000));
  sea_cal->add_option("--smooth", sea_cal_smooth, "centred quadratic Savitzky-Golay smoothing over n rows before the fit (1 kHz recording: 51)")
      ->check(cli::inRange(1, 1001));
  sea_cal->add_flag("--json", json, "JSON output");

  phalanx::host::pen::PenSplitBenchOptions pen_split_opt;
  CLI::App* pen_split = bench->add_subcommand("pen-split", "pen force split over the workspace: accuracy, effort, saturation (004 Fig. 18)");
  pen_split->add_option("--seed", pen_split_opt.seed, "random-wrench seed");
  pen_split->add_option("--grid", pen_split_opt.grid, "samples per workspace axis (grid^5 poses)")->check(cli::inRange(2, 15));
  pen_split->add_option("--wrenches-per-pose", pen_split_opt.wrenches_per_pose, "random wrenches per pose and class")
      ->check(cli::inRange(1, 1000));
  pen_split->add_flag("--json", json, "JSON output (the default; kept for scripts)");

  phalanx::host::pen::PenWallBenchOptions pen_wall_opt;
  bool pen_wall_no_braking = false, pen_wall_no_noise = false;
  CLI::App* pen_wall = bench->add_subcommand("pen-wall", "pen tip pressed into the stiff box walls and corners, PD+B in lockstep (004 Fig. 19-20)");
  pen_wall->add_option("--stiffness-N-per-cm", pen_wall_opt.stiffness_N_per_cm, "horizontal wall stiffness (floor: 0.7x)")
      ->check(cli::inRange(0.1, 200.0));
  pen_wall->add_option("--damping-scale", pen_wall_opt.damping_scale, "x the paper's box damping")->check(cli::inRange(0.0, 100.0));
  pen_wall->add_flag("--no-braking", pen_wall_no_braking, "no braking pulse at contact onset");
  bool pen_wall_no_cap = false;
  pen_wall->add_flag("--no-brake-cap", pen_wall_no_cap, "the paper's braking pulse without the momentum cap");
  pen_wall->add_option("--velocity-filter-hz", pen_wall_opt.velocity_filter_hz, "end-velocity low-pass cutoff")
      ->check(cli::inRange(1.0, 500.0));
  pen_wall->add_flag("--sweep", pen_wall_opt.sweep, "also sweep the stiffness with and without braking");
  pen_wall->add_option("--seed", pen_wall_opt.seed, "simulation seed");
  pen_wall->add_flag("--no-noise", pen_wall_no_noise, "simulated sensors without noise");
  pen_wall->add_flag("--json", json, "JSON output (the default; kept for scripts)");
  phalanx::host::cli::TherapyCli therapy_cli;
  phalanx::host::cli::addTherapyCommands(app, therapy_cli);
  std::string plan_path, plan_report;
  CLI::App* plan_run = bench->add_subcommand("run", "run a bench plan (YAML) against a reference instrument; HTML report");
  plan_run->add_option("plan", plan_path, "plan file (docs/bench-runner.md)")->required()->check(CLI::ExistingFile);
  plan_run->add_option("--report", plan_report, "HTML report path (default: the plan's report key, or PLAN.html)");

  DesignCommands design_cmds(app);
  cli::refuseEmptyValues(app);

  if (int rc = 0; !cli::parseArgs(app, argc, argv, "phalanx", rc)) return rc;
  if (devices->parsed()) return listDevicesMain(dev_domain, dev_interface, dev_seconds, dev_json);
  if (design_cmds.parsed()) return design_cmds.run();
  if (plan_run->parsed()) return phalanx::host::benchrun::benchRunMain(plan_path, plan_report);
  if (sea_sine->parsed() || sea_chirp->parsed() || sea_finger_torque->parsed() || sea_transparency->parsed()) {
    sea_opt.noise = !bench_no_noise;
    namespace hs = phalanx::host::sea;
    const nlohmann::json result = sea_sine->parsed()            ? hs::benchRigSine(sea_opt)
                                  : sea_chirp->parsed()         ? hs::benchRigChirp(sea_opt)
                                  : sea_finger_torque->parsed() ? hs::benchFingerTorque(sea_opt)
                                                                : hs::benchTransparency(sea_opt);
    std::cout << result.dump(2) << std::endl;
    return 0;
  }
  if (pen_wall->parsed()) {
    pen_wall_opt.braking = !pen_wall_no_braking;
    pen_wall_opt.noise = !pen_wall_no_noise;
    pen_wall_opt.brake_momentum_cap = !pen_wall_no_cap;
    std::cout << phalanx::host::pen::benchWall(pen_wall_opt).dump(2) << std::endl;
    return 0;
  }
  if (pen_split->parsed()) {
    std::cout << phalanx::host::pen::benchSplit(pen_split_opt).dump(2) << std::endl;
    return 0;
  }
  if (sea_cal->parsed()) {
    return phalanx::host::sea::seaCalibrateCommand(sea_cal_csv, sea_cal_subject, json, sea_cal_stride,
                                                   sea_cal_smooth);
  }
  if (can->parsed()) {
    const nlohmann::json r = can_budget->parsed() ? canBudget(can_rate_hz, can_bps)
                                                  : canLoadFromLog(can_log, can_bps, can_data_bps);
    std::cout << r.dump(2) << std::endl;
    return r.contains("error") ? 1 : 0;
  }
  if (const int rc = phalanx::host::cli::runTherapyCommands(therapy_cli); rc >= 0) return rc;
  if (bench->parsed()) {
    bench_opt.noise = !bench_no_noise;
    bench_opt.drift = !bench_no_drift;
    const nlohmann::json result = free_motion->parsed() ? phalanx::host::glove::benchFreeMotion(bench_opt)
                                                        : phalanx::host::glove::benchGrasp(bench_opt);
    std::cout << result.dump(2) << std::endl;
    return 0;
  }
  if (mcu_diag->parsed()) {
    if (mcu_diag_device.rfind("serial:", 0) != 0) {
      std::fprintf(stderr, "phalanx: error: --device must be serial:<path> (got '%s')\n", mcu_diag_device.c_str());
      return 2;
    }
    std::string error;
    const nlohmann::json result =
        phalanx::host::readMcuDiagnostics(mcu_diag_device.substr(7), mcu_diag_timeout_s, error);
    if (!error.empty()) {
      std::fprintf(stderr, "phalanx: error: %s\n", error.c_str());
      return 4;
    }
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
    if (int rc = 0; !cli::parseArgs(app, argc, argv, "phalanx", rc)) return rc;
  }
  if (const std::string err = checkSessionLength(opt.seconds, opt.rate_hz); !err.empty()) {
    const std::string where = run->count("--seconds") > 0 ? "--seconds" : config_path + ": seconds";
    std::fprintf(stderr, "phalanx: error: %s: %s\n", where.c_str(), err.c_str());
    return cli::kExitBadArguments;
  }
  if (no_rt) opt.realtime = false;
  if (opt.seconds == 0.0 && json) opt.seconds = 10.0;
  installStopSignals();
  nlohmann::json summary;
  const int rc = runSession(opt, summary);
  printSummary(summary, json);
  return rc;
}
