#pragma once
// Command-line options shared by `phalanxd` and `phalanx run` (one definition, two front ends).
#include <CLI/CLI.hpp>

#include "phalanx/host/daemon.h"

namespace phalanx::host {

inline void addRunOptions(CLI::App& app, RunOptions& opt, std::string& config_path, bool& no_rt, bool& json) {
  app.add_option("--config", config_path, "YAML configuration file (command-line options override it)")
      ->check(CLI::ExistingFile);
  app.add_option("--device", opt.device, "sim:glove5 | sim:sea_finger | sim:pantograph | serial:/dev/ttyACM0[@baud]");
  app.add_option("--seconds", opt.seconds, "session length in seconds (0: until Ctrl-C)")->check(CLI::Range(0.0, 86400.0));
  app.add_option("--rate-hz", opt.rate_hz, "host loop rate")->check(CLI::Range(100u, 4000u));
  app.add_option("--command-timeout-ms", opt.command_timeout_ms, "timeout carried by every command")
      ->check(CLI::Range(2u, 1000u));
  app.add_option("--record", opt.record_csv, "record every cycle to this CSV file");
  app.add_option("--scenario", opt.scenario, "simulated hand: still|close-open|grasp|random")
      ->check(CLI::IsMember({"still", "close-open", "grasp", "random"}));
  app.add_option("--scene", opt.scene, "glove virtual scene: none|rigid-ball|soft-ball|wall")
      ->check(CLI::IsMember({"none", "rigid-ball", "soft-ball", "wall"}));
  app.add_option("--mode", opt.mode, "glove: render (virtual scene) | transparent (zero force)")
      ->check(CLI::IsMember({"render", "transparent"}));
  app.add_option("--seed", opt.seed, "simulation seed");
  app.add_option("--firmware-sim", opt.firmware_sim, "path of the firmware-sim executable");
  app.add_flag("--no-realtime", no_rt, "do not try SCHED_FIFO / mlockall");
  app.add_flag("--live", opt.live_view, "live per-finger view on the terminal");
  app.add_flag("--json", json, "print the end-of-session summary as JSON on stdout");
}

}  // namespace phalanx::host
