#pragma once
/// `phalanx record replay FILE` (docs/records.md, "Replay"): a `--record FILE.mcap` recording fed back through
/// the host's controller and the limits stage offline, cycle by cycle, with the recorded telemetry, session time
/// and configuration; every replayed command is compared bit for bit with the recorded one. The same build gives
/// the same commands, so a control change shows as the first cycle and channel where they part.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/daemon.h"
#include "phalanx/pen/kinematics.h"

namespace phalanx::host::record {

/// Version of the header's "replay" object; a newer one is refused by name, an older one read.
inline constexpr int kReplayFormatVersion = 1;

/// The header's "replay" object of a live MCAP recording: everything besides the telemetry that decides the
/// commands (the controller's options, with the contents of its geometry/subject files; the loop rate; whether a
/// patient limits stage or a therapy controller ran). controller: Controller::name().
nlohmann::json replayConfig(const RunOptions& opt, const std::string& controller, bool patient_limits);

/// The layout of a device a recording names ("glove5", "sea_finger", "pantograph"); null for another name.
const protocol::DeviceLayout* layoutNamed(const std::string& name);

/// The pen model a pantograph controller runs (its geometry), for the recordings' pen channels; null otherwise.
const phalanx::pen::Model<double>* penModelOf(const Controller& controller);

struct ReplayOptions {
  /// Configuration changed for the replay ("key=value": mode, scene, pen_wall_stiffness_N_per_cm, pen_floor_mm):
  /// the regression check of a control change, and what makes a replay differ on purpose.
  std::vector<std::string> set;
};

struct ReplayMismatch {
  uint64_t cycle = 0;  ///< 0-based index of the recorded cycle
  double t_s = 0.0;
  std::string channel;  ///< "mode", a setpoint's name, or "gain_permille[<setpoint>]"
  double recorded = 0.0, replayed = 0.0;
  uint32_t recorded_bits = 0, replayed_bits = 0;  ///< float bits (setpoints)
};

struct ReplayResult {
  std::string file, device, controller;
  uint64_t cycles = 0;              ///< cycles in the file
  uint64_t compared = 0;            ///< cycles whose command the replay computed and compared
  uint64_t external = 0;            ///< cycles a Modbus / client-channel client commanded (controller run, not compared)
  uint64_t mismatched_cycles = 0;   ///< compared cycles with any difference
  uint64_t mismatched_values = 0;
  std::vector<ReplayMismatch> first;  ///< the first cycle's differences (every channel of it)
  bool file_complete = false;
  nlohmann::json toJson() const;
};

/// One replayed cycle: its 0-based index, the recorded session time and telemetry, and the command the replay
/// computed (after the limits stage).
struct ReplayedCycle {
  uint64_t cycle = 0;
  double t_s = 0.0;
  const TelemetryFrame& tel;
  const protocol::Command& command;
};
/// Called for every replayed cycle, in order (the dashboard stream builds its status frames from them).
using ReplayObserver = std::function<void(const protocol::DeviceLayout& layout, const ReplayedCycle& cycle)>;

/// "" (the replay ran; result says whether it matched) or why the file cannot be replayed (naming the file).
std::string replayRecording(const std::string& path, const ReplayOptions& options, ReplayResult& result,
                            const ReplayObserver& observer = {});

}  // namespace phalanx::host::record
