#include "bench_cli.h"

#include <chrono>
#include <cstdio>
#include <functional>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_args.h"
#include "phalanx/host/bench_verdict.h"
#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/glove/glove_bench.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/pen/pen_bench.h"
#include "phalanx/host/progress.h"
#include "phalanx/host/sea/sea_bench.h"

namespace phalanx::host {

namespace {
constexpr double kBenchStep_s = 1e-3;  // the glove and SEA benches step their lockstep loop at 1 kHz
constexpr const char* kJsonHelp = "print every figure as JSON on stdout (default: a short summary)";

/// Runs a lockstep bench and adds how fast its simulation ran (docs/bench-runner.md "Lockstep speed"):
/// virtual time stepped by its rigs over their wall-clock lifetime. Printed, never judged.
nlohmann::json withLockstepSpeed(const std::function<nlohmann::json()>& bench) {
  const LockstepTally before = lockstepTally();
  const auto t0 = std::chrono::steady_clock::now();
  nlohmann::json out = bench();
  const double bench_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const LockstepTally after = lockstepTally();
  const double sim_s = static_cast<double>(after.simulated_us - before.simulated_us) * 1e-6;
  const double wall_s = static_cast<double>(after.wall_ns - before.wall_ns) * 1e-9;
  out["lockstep_speed"] = {{"rigs", after.rigs - before.rigs},
                           {"simulated_s", sim_s},
                           {"rig_wall_s", wall_s},
                           {"x_real_time", wall_s > 0.0 ? sim_s / wall_s : 0.0},
                           {"bench_wall_s", bench_wall_s}};
  return out;
}
}  // namespace

struct BenchCommands::Impl {
  CLI::App* bench = nullptr;
  bool json = false;
  bool no_noise = false, no_drift = false;
  // glove
  CLI::App *free_motion = nullptr, *grasp = nullptr;
  glove::GloveBenchOptions glove_opt;
  // SEA
  CLI::App *sea_sine = nullptr, *sea_chirp = nullptr, *sea_finger_torque = nullptr, *sea_transparency = nullptr;
  sea::SeaBenchOptions sea_opt;
  // pen
  CLI::App *pen_split = nullptr, *pen_wall = nullptr;
  pen::PenSplitBenchOptions split_opt;
  pen::PenWallBenchOptions wall_opt;
  bool no_braking = false, no_brake_cap = false;
  double progress_s = 5.0;
  // plan
  CLI::App* plan_run = nullptr;
  std::string plan_path, plan_report, plan_device;
  bool plan_lockstep = false, plan_no_realtime = false;

  void addGlove();
  void addSea();
  void addPen();
  void addPlan();
  nlohmann::json runGlove();
  nlohmann::json runSea();
  nlohmann::json runPenWall();
  /// The summary (or the JSON) of a single bench, and its exit code.
  int report(const std::string& bench, const nlohmann::json& result) const;
};

BenchCommands::BenchCommands(CLI::App& app) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.bench = app.add_subcommand("bench", "run a bench scenario: a short summary, exit 1 when a target is missed");
  m.bench->require_subcommand(1);
  m.addGlove();
  m.addSea();
  m.addPen();
  m.addPlan();
}

BenchCommands::~BenchCommands() = default;

bool BenchCommands::parsed() const { return impl_->bench->parsed(); }

void BenchCommands::Impl::addGlove() {
  auto add = [this](CLI::App* sc) {
    sc->add_option("--seconds", glove_opt.seconds, "scenario length (0: its default)")
        ->check(cli::inRange(0.0, 600.0))
        ->check(cli::zeroOrAtLeast(kBenchStep_s, "its default"));
    sc->add_option("--seed", glove_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", no_noise, "simulated sensors without noise");
    sc->add_flag("--no-drift", no_drift, "simulated strain gauges without their thermal zero drift (noise stays)");
    sc->add_option("--worn-s", glove_opt.worn_s,
                   "how long the glove was worn before the start (s; the pad is still warming up; default: the plant's, 60)")
        ->check(cli::inRange(0.0, 86400.0));
    sc->add_flag("--json", json, kJsonHelp);
  };
  free_motion = bench->add_subcommand("glove-free-motion", "close/open maneuvers at zero force (000 §4.3)");
  add(free_motion);
  grasp = bench->add_subcommand("glove-grasp", "grasp the rigid virtual ball (000 eq 1)");
  add(grasp);
}

void BenchCommands::Impl::addSea() {
  auto add = [this](CLI::App* sc) {
    sc->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    sc->add_option("--seconds", sea_opt.seconds, "scenario length (0: its default)")
        ->check(cli::inRange(0.0, 600.0))
        ->check(cli::zeroOrAtLeast(kBenchStep_s, "its default"));
    sc->add_option("--seed", sea_opt.seed, "simulation seed");
    sc->add_flag("--no-noise", no_noise, "simulated sensors without noise");
    sc->add_flag("--json", json, kJsonHelp);
    sc->add_option("--controller", sea_opt.controller, "both | paper (001 plain PID, eq 7-8) | ours")
        ->check(CLI::IsMember({"both", "paper", "ours"}));
    sc->add_option("--plant-backlash-scale", sea_opt.plant_backlash_scale,
                   "scale the simulated cable play (model mismatch)")->check(cli::inRange(0.0, 5.0));
  };
  sea_sine = bench->add_subcommand("sea-rig-sine", "SEA test rig, sinusoidal torque (001 §7.1.1-7.1.2, eq 15)");
  add(sea_sine);
  sea_sine->add_option("--peak-Nm", sea_opt.peak_Nm, "peak torque (paper: 0.15 or 0.3)")->check(cli::inRange(0.0, 0.4));
  sea_sine->add_option("--hz", sea_opt.hz, "frequency (paper: 0.5)")->check(cli::inRange(0.01, 20.0));
  sea_chirp = bench->add_subcommand("sea-rig-chirp", "SEA test rig, linear chirp, -3 dB bandwidth (001 §7.1.3, eq 16-17)");
  add(sea_chirp);
  sea_chirp->add_option("--amplitude-Nm", sea_opt.chirp_amplitude_Nm, "chirp amplitude tau_A")->check(cli::inRange(0.01, 0.4));
  sea_chirp->add_option("--fmax-hz", sea_opt.chirp_fmax_hz, "frequency at the end of the sweep")->check(cli::inRange(2.0, 50.0));
  sea_finger_torque = bench->add_subcommand(
      "sea-finger-torque", "SEA exoskeleton on the simulated finger: finger MCP/PIP torque tracking (001 §7.6, eq 9-11)");
  add(sea_finger_torque);
  sea_finger_torque->add_flag("--user-holds", sea_opt.finger_user_holds,
                              "the simulated user holds the rest posture (default: relaxed finger)");
  sea_transparency =
      bench->add_subcommand("sea-transparency", "SEA exoskeleton: residual torque during random finger motion (001 §7.7)");
  add(sea_transparency);
}

void BenchCommands::Impl::addPen() {
  pen_split = bench->add_subcommand("pen-split", "pen force split over the workspace: accuracy, effort, saturation (004 Fig. 18)");
  pen_split->add_option("--seed", split_opt.seed, "random-wrench seed");
  pen_split->add_option("--grid", split_opt.grid, "samples per workspace axis (grid^5 poses)")->check(cli::inRange(2, 15));
  pen_split->add_option("--wrenches-per-pose", split_opt.wrenches_per_pose, "random wrenches per pose and class")
      ->check(cli::inRange(1, 1000));
  pen_split->add_flag("--json", json, kJsonHelp);

  pen_wall = bench->add_subcommand("pen-wall", "pen tip pressed into the stiff box walls and corners, PD+B in lockstep (004 Fig. 19-20)");
  pen_wall->add_option("--stiffness-N-per-cm", wall_opt.stiffness_N_per_cm, "horizontal wall stiffness (floor: 0.7x)")
      ->check(cli::inRange(0.1, 200.0));
  pen_wall->add_option("--damping-scale", wall_opt.damping_scale, "x the paper's box damping")->check(cli::inRange(0.0, 100.0));
  pen_wall->add_flag("--no-braking", no_braking, "no braking pulse at contact onset");
  pen_wall->add_flag("--no-brake-cap", no_brake_cap, "the paper's braking pulse without the momentum cap");
  pen_wall->add_option("--velocity-filter-hz", wall_opt.velocity_filter_hz, "end-velocity low-pass cutoff (default: the scene's)")
      ->check(cli::inRange(1.0, 500.0))
      ->default_str("");
  pen_wall->add_flag("--sweep", wall_opt.sweep, "also sweep the stiffness with and without braking (37 runs)");
  pen_wall->add_option("--progress-s", progress_s, "--sweep: progress with the time left on stderr every N s (0: none)")
      ->check(cli::inRange(0.0, 3600.0));
  pen_wall->add_option("--seed", wall_opt.seed, "simulation seed");
  pen_wall->add_flag("--no-noise", no_noise, "simulated sensors without noise");
  pen_wall->add_flag("--json", json, kJsonHelp);
}

void BenchCommands::Impl::addPlan() {
  plan_run = bench->add_subcommand("run", "run a bench plan (YAML) against a reference instrument; HTML report");
  plan_run->add_option("plan", plan_path, "plan file (docs/bench-runner.md)")->required()->check(CLI::ExistingFile);
  plan_run->add_option("--report", plan_report, "HTML report path (default: the plan's report key, or PLAN.html)");
  plan_run->add_option("--device", plan_device,
                       "run on this device instead of the plan's (sim:sea_rig|sim:glove5, serial:PATH[@baud], "
                       "can:IF[:node][@fd|@fd-compact|@classic], usb:VID:PID[:serial]; the plan's device_type must fit)");
  plan_run->add_flag("--lockstep", plan_lockstep,
                     "sim: devices: step firmware, plant and host in one process (fast, deterministic) instead of a real-time "
                     "session of the daemon's runner over the device's link (the default)");
  plan_run->add_flag("--no-realtime", plan_no_realtime,
                     "real time: do not ask for SCHED_FIFO and locked memory (as phalanxd --no-realtime)");
}

nlohmann::json BenchCommands::Impl::runGlove() {
  glove_opt.noise = !no_noise;
  glove_opt.drift = !no_drift;
  return free_motion->parsed() ? glove::benchFreeMotion(glove_opt) : glove::benchGrasp(glove_opt);
}

nlohmann::json BenchCommands::Impl::runSea() {
  sea_opt.noise = !no_noise;
  if (sea_sine->parsed()) return sea::benchRigSine(sea_opt);
  if (sea_chirp->parsed()) return sea::benchRigChirp(sea_opt);
  if (sea_finger_torque->parsed()) return sea::benchFingerTorque(sea_opt);
  return sea::benchTransparency(sea_opt);
}

nlohmann::json BenchCommands::Impl::runPenWall() {
  wall_opt.braking = !no_braking;
  wall_opt.noise = !no_noise;
  wall_opt.brake_momentum_cap = !no_brake_cap;
  ProgressLine line("pen-wall --sweep", progress_s);
  wall_opt.progress = [&line](std::size_t done, std::size_t total) {
    line.update(static_cast<double>(done) / static_cast<double>(total),
                std::to_string(done) + "/" + std::to_string(total) + " runs");
  };
  nlohmann::json r = pen::benchWall(wall_opt);
  line.finish();
  return r;
}

int BenchCommands::Impl::report(const std::string& name, const nlohmann::json& result) const {
  const BenchVerdict v = judgeBench(name, result);
  if (json) std::cout << result.dump(2) << std::endl;
  else std::cout << benchSummaryText(v) << std::flush;
  return v.pass() ? 0 : 1;
}

int BenchCommands::run() {
  Impl& m = *impl_;
  if (m.plan_run->parsed()) return benchrun::benchRunMain(m.plan_path, m.plan_report, m.plan_device, m.plan_lockstep, !m.plan_no_realtime);
  if (m.free_motion->parsed() || m.grasp->parsed()) {
    return m.report(m.free_motion->parsed() ? "glove-free-motion" : "glove-grasp", withLockstepSpeed([&m] { return m.runGlove(); }));
  }
  for (CLI::App* sc : {m.sea_sine, m.sea_chirp, m.sea_finger_torque, m.sea_transparency}) {
    if (sc->parsed()) return m.report(sc->get_name(), withLockstepSpeed([&m] { return m.runSea(); }));
  }
  if (m.pen_wall->parsed()) return m.report("pen-wall", withLockstepSpeed([&m] { return m.runPenWall(); }));
  if (m.pen_split->parsed()) return m.report("pen-split", pen::benchSplit(m.split_opt));
  return cli::kExitBadArguments;
}

}  // namespace phalanx::host
