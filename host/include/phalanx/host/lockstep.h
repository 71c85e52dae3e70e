#pragma once
/// Lockstep simulation: firmware core + device app + plant + host session + host controller in one process on a
/// virtual clock. Deterministic for a seed and far faster than real time; the link is an in-memory byte pipe
/// carrying the same COBS frames as the real link, so the protocol path is exercised too.
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "phalanx/fw/core.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/host/controller.h"
#include "phalanx/host/session.h"
#include "phalanx/sim/board.h"

namespace phalanx::host {

struct LockstepOptions {
  uint16_t tick_hz = 1000;        ///< firmware tick rate
  /// The host polls, runs its controller and sends a command every this many ticks (≥ 1): a host slower than
  /// its device, as a 100 Hz host with a 1 kHz board.
  unsigned host_every_ticks = 1;
  unsigned substeps = 10;         ///< plant integration steps per tick
  uint16_t command_timeout_ms = 20;
};

/// Every lockstep rig of this process so far, counted when each is destroyed: the virtual time it stepped
/// and the wall-clock time it lived (construction to destruction). Benches print the ratio, the simulation's
/// speed in multiples of real time (docs/bench-runner.md "Lockstep speed").
struct LockstepTally {
  uint64_t rigs = 0;
  uint64_t simulated_us = 0;
  uint64_t wall_ns = 0;
};
LockstepTally lockstepTally();

class LockstepRig {
 public:
  /// The rig does not own device or controller; both must outlive it.
  LockstepRig(fw_sim::SimDevice& device, Controller& controller, const LockstepOptions& options = {});
  ~LockstepRig();
  LockstepRig(const LockstepRig&) = delete;
  LockstepRig& operator=(const LockstepRig&) = delete;

  /// Open the session (Hello/HelloAck over the pipe), set the controller's start-up parameters and wait its
  /// settle time; only then does step() send commands. Returns an error text or "".
  std::string handshake();
  /// One period: plant substeps, firmware tick, host poll + controller + command.
  void step();
  /// Run for a duration of virtual time.
  void run(double seconds);

  double timeS() const { return static_cast<double>(board_.clock().nowUs()) * 1e-6; }
  sim::SimBoard& board() { return board_; }
  fw::FirmwareCore& core() { return core_; }
  HostSession& session() { return session_; }
  const protocol::Command& lastCommand() const { return cmd_; }
  /// Stop: from the next step on, the host commands the safe state (makeSafe, command_limits.h) instead of
  /// running the controller, as the daemon does while stopped (no controller update: no integrator wind-up).
  void setStopped(bool stopped) { stopped_ = stopped; }
  bool stopped() const { return stopped_; }
  /// Drop the host: stop sending commands (link loss seen from the device).
  void setHostConnected(bool connected) { host_connected_ = connected; }
  /// Called after the plant wrote the sensors and before the firmware tick: fault injection (a stuck or
  /// disconnected sensor, an e-stop press) on the board's I/O image.
  void setIoHook(std::function<void(sim::SimIo&)> hook) { io_hook_ = std::move(hook); }

 private:
  fw_sim::SimDevice& device_;
  Controller& controller_;
  LockstepOptions opt_;
  sim::BytePipe pipe_;
  sim::SimBoard board_;
  fw::FirmwareCore core_;
  HostSession session_;
  protocol::Command cmd_{};
  bool host_connected_ = true;
  bool stopped_ = false;
  unsigned host_every_ = 1;  ///< options.host_every_ticks, at least 1
  uint64_t ticks_ = 0;
  bool started_ = false;  ///< commands flow only once handshake() finished the start-up sequence
  std::function<void(sim::SimIo&)> io_hook_;
  std::chrono::steady_clock::time_point born_ = std::chrono::steady_clock::now();
};

}  // namespace phalanx::host
