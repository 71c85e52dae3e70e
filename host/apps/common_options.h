#pragma once
// Command-line options shared by `phalanxd` and `phalanx run` (one definition, two front ends).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "cli_args.h"
#include "phalanx/host/daemon.h"

namespace phalanx::host {

inline void addRunOptions(CLI::App& app, RunOptions& opt, std::string& config_path, bool& no_rt, bool& json) {
  // The last occurrence wins, so wrapper scripts' defaults can be overridden (tools/run-glove.sh --seconds 30).
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  app.option_defaults()->always_capture_default();  // help shows every default ("[1000]")
  app.add_option("--config", config_path, "YAML configuration file (command-line options override it)")
      ->check(CLI::ExistingFile);
  app.add_option("--device", opt.device,
                 "sim:glove5 | sim:sea_finger | sim:sea_rig | sim:pantograph | serial:/dev/ttyACM0[@baud] | "
                 "can:can0[:node][@fd|@fd-compact|@classic] | usb:VID:PID[:serial]");
  app.add_option("--seconds", opt.seconds, "session length in seconds (0: until Ctrl-C)")->check(cli::inRange(0.0, 86400.0));
  app.add_option("--rate-hz", opt.rate_hz, "host loop rate")->check(cli::inRange(100u, 4000u));
  app.add_option("--command-timeout-ms", opt.command_timeout_ms, "timeout carried by every command")
      ->check(cli::inRange(2u, 1000u));
  app.add_option("--telemetry-timeout-ms", opt.telemetry_timeout_ms,
                 "no new telemetry for this long ends the session as a lost link (exit 6)")
      ->check(cli::inRange(10u, 10000u));
  app.add_option("--record", opt.record_csv, "record every cycle to this file: CSV with named columns, or MCAP for a name ending in .mcap (docs/records.md)");
  app.add_option("--cycle", opt.cycle, "what starts a host cycle: telemetry (a frame's arrival, locked to the device, the timer as "
                 "fallback; the default) | timer (the period timer alone; docs/session-runner.md)")
      ->check(CLI::IsMember({"telemetry", "timer"}));
  app.add_option("--pen-wall-stiffness", opt.pen_wall_stiffness_N_per_cm,
                 "pantograph: stiffness of every box wall and the floor, N/cm (0: the scene's, 3 and 2.1 N/cm)")
      ->check(cli::inRange(0.0, 1000.0));
  app.add_option("--pen-floor-mm", opt.pen_floor_mm,
                 "pantograph: height of the box floor in {B}, mm (default -90: 2 cm below the tip at home, -70)")
      ->check(cli::inRange(-120.0, -40.0));
  app.add_option("--scenario", opt.scenario, "simulated hand: still|close-open|grasp|random|spastic (sea_finger: a stretch reflex)|press (pantograph: push along +x)")
      ->check(CLI::IsMember({"still", "close-open", "grasp", "random", "spastic", "press"}));
  app.add_option("--scene", opt.scene, "glove virtual scene: none|rigid-ball|soft-ball|wall")
      ->check(CLI::IsMember({"none", "rigid-ball", "soft-ball", "wall"}));
  app.add_option("--mode", opt.mode, "glove: render (virtual scene) | transparent (zero force)")
      ->check(CLI::IsMember({"render", "transparent"}));
  app.add_option("--sea-subject", opt.sea_subject, "sea_finger: subject YAML written by phalanx sea-calibrate")
      ->check(CLI::ExistingFile);
  app.add_option("--pen-geometry", opt.pen_geometry,
                 "pantograph: pen geometry YAML written by phalanx design pen-gii --yaml (must match the firmware)");
  app.add_option_function<std::vector<std::string>>(
         "--glove-geometry",
         [&opt](const std::vector<std::string>& v) {
           for (const std::string& s : v) {
             const auto eq = s.find('=');
             if (eq == std::string::npos) throw CLI::ValidationError("--glove-geometry", "expected FINGER=PATH, got '" + s + "'");
             opt.glove_geometry[s.substr(0, eq)] = s.substr(eq + 1);
           }
         },
         "glove5: FINGER=PATH geometry YAML written by phalanx design glove-optimize --yaml (repeatable; must match the firmware)")
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("--seed", opt.seed, "simulation seed");
  app.add_option("--firmware-sim", opt.firmware_sim, "path of the firmware-sim executable");
  app.add_option("--sim-truth", opt.sim_truth,
                 "sim: devices: the simulated plant's ground truth, one CSV row per device tick (docs/sdk.md \"Plant truth\")");
  app.add_option("--sim-settings", opt.sim_settings,
                 "sim: devices: the simulated board's settings flash file, kept between runs as a board keeps them "
                 "(phalanx param --sim-settings writes the same file; docs/params.md)");
  app.add_option("--sim-settings-layout", opt.sim_settings_layout,
                 "sim: devices: play the firmware that writes this settings layout version (0: the newest)")
      ->check(cli::inRange(0u, 255u));
  app.add_option("--estop", opt.gpio.estop,
                 "e-stop input CHIP:LINE[:active-low] (a press, a lost line or a read error stops the daemon until a reset)");
  app.add_option("--enable", opt.gpio.enable, "drive-enable output CHIP:LINE[:active-low] (dropped on an e-stop)");
  app.add_option("--sync", opt.gpio.sync, "motion-capture sync pulse output CHIP:LINE@HZ (e.g. gpiochip0:2@480)");
  app.add_option("--estop-release-ms", opt.gpio.estop_release_ms,
                 "the e-stop must stay released this long before a reset is accepted")
      ->check(cli::inRange(1.0, 1000.0));
  app.add_option("--client-socket", opt.client.socket_path,
                 "serve libphalanx clients on this UNIX socket (its directory is private; docs/sdk.md)");
  app.add_option("--client-group", opt.client.group, "members of this group may connect as clients too");
  app.add_flag("--dds", opt.dds.enabled, "publish ROS 2-compatible topics over Cyclone DDS (docs/dds.md)");
  app.add_option("--dds-domain", opt.dds.domain_id, "DDS domain id (ROS_DOMAIN_ID) for --dds")->check(cli::inRange<uint32_t>(0, 232));
  app.add_option("--dds-interface", opt.dds.interface, "network interface (name or IPv4 address) for --dds");
  app.add_option("--dds-namespace", opt.dds.ns, "topic namespace for --dds (default phalanx/<device type>)");
  app.add_option("--dds-state-rate", opt.dds.state_rate_hz, "joint_states/pose/wrench rate in Hz for --dds (1..rate)");
  app.add_flag("--no-realtime", no_rt, "do not try SCHED_FIFO / mlockall");
  app.add_flag("--live", opt.live_view, "live per-finger view on the terminal");
  app.add_flag("--json", json, "print the end-of-session summary as JSON on stdout");
}

/// End-of-session summary: the whole JSON with --json, else the lines a person reads first.
inline void printSummary(const nlohmann::json& s, bool json) {
  if (json) {
    std::cout << s.dump(2) << std::endl;
    return;
  }
  if (s.contains("error")) return;  // already reported on stderr
  const auto num = [&](const char* a, const char* b) { return s[a][b].get<double>(); };
  std::printf("session: %s (%s), %s, %.1f s, %llu cycles, %llu overruns\n", s["device"].get<std::string>().c_str(),
              s["device_type"].get<std::string>().c_str(), s["controller"].get<std::string>().c_str(),
              s["seconds"].get<double>(), s["cycles"].get<unsigned long long>(), s["overruns"].get<unsigned long long>());
  std::printf("link: telemetry %llu received, %llu lost; round trip p50 %.0f us, p99 %.0f us, p99.9 %.0f us\n",
              s["telemetry"]["received"].get<unsigned long long>(), s["telemetry"]["lost"].get<unsigned long long>(),
              num("round_trip", "p50_us"), num("round_trip", "p99_us"), num("round_trip", "p999_us"));
  std::printf("loop: period jitter p50 %.0f us, p99 %.0f us; faults seen: %s; final mode: %s\n",
              num("period_jitter", "p50_us"), num("period_jitter", "p99_us"),
              s["faults_seen"].get<std::string>().c_str(), s["final_mode"].get<std::string>().c_str());
  if (s.contains("glove5") && s["glove5"].contains("fingers")) {
    // The grasp's figures per finger (docs/session-runner.md "Glove main job").
    for (const auto& [name, f] : s["glove5"]["fingers"].items()) {
      std::printf("%-6s contact %.2f s; in contact force RMS error %.3f N (%.1f %% of the rendered); free force RMS %.3f N\n",
                  name.c_str(), f.value("contact_s", 0.0), f.value("force_rms_error_in_contact_N", 0.0),
                  f.value("force_rms_error_in_contact_percent", 0.0), f.value("force_rms_free_N", 0.0));
    }
  }
  if (s.contains("recording")) {
    const auto& r = s["recording"];
    std::printf("recorded %llu rows to %s", r["rows"].get<unsigned long long>(), r["path"].get<std::string>().c_str());
    if (r.value("dropped_rows", 0ull) > 0) std::printf(", %llu rows lost", r["dropped_rows"].get<unsigned long long>());
    std::printf("\n");
    if (r.contains("error")) std::printf("RECORDING FAILED: %s\n", r["error"].get<std::string>().c_str());
  }
}

}  // namespace phalanx::host
