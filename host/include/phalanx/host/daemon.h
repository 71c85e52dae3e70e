#pragma once
/// The host daemon's session runner, shared by `phalanxd` and `phalanx run`: open the device (spawning the
/// simulated firmware for sim:* devices), handshake, run the 1 kHz loop, record, and summarise.
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/modbus/server_options.h"

namespace phalanx::host {

struct RunOptions {
  std::string device = "sim:glove5";  ///< sim:<glove5|sea_finger|pantograph> or serial:<path>[@baud]
  double seconds = 0.0;               ///< 0: until SIGINT/SIGTERM
  unsigned rate_hz = 1000;
  unsigned command_timeout_ms = 20;   ///< each command's own timeout: the device goes safe if the next is late
  bool realtime = true;               ///< try SCHED_FIFO + mlockall
  int rt_priority = 80;
  std::string record_csv;             ///< one row per cycle; empty: no recording
  std::string scenario = "grasp";     ///< simulated hand (sim:glove5): still|close-open|grasp|random
  std::string scene = "rigid-ball";   ///< glove virtual scene: none|rigid-ball|soft-ball|wall
  std::string mode = "render";        ///< glove: render|transparent
  uint32_t seed = 1;
  bool live_view = false;             ///< per-finger terminal view at 10 Hz on stderr
  bool clear_faults = true;           ///< clear faults latched before this session (logged)
  std::string firmware_sim;           ///< path of firmware-sim (default: next to this executable)
  double handshake_timeout_s = 2.0;
  modbus::ServerOptions modbus;       ///< optional Modbus TCP server (docs/modbus.md); off by default
};

/// Validate options; returns an empty string or the first problem, naming the option.
std::string validate(const RunOptions& opt);

/// Run one session. Returns the process exit code (0 ok); summary is filled in either case, with
/// summary["error"] set on failure.
int runSession(const RunOptions& opt, nlohmann::json& summary);

/// Install SIGINT/SIGTERM handlers that ask runSession to stop cleanly.
void installStopSignals();

}  // namespace phalanx::host
