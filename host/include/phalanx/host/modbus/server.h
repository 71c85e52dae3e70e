#pragma once
/// phalanxd's Modbus TCP server (libmodbus): one thread of its own serves many clients with select(); the loop
/// hands its state across through a wait-free TripleBuffer and picks up accepted writes the same way, so no
/// client (slow, malformed or many) can make the 1 kHz loop wait. Register map: register_map.h, docs/modbus.md.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "phalanx/host/modbus/register_map.h"
#include "phalanx/host/modbus/server_options.h"
#include "phalanx/host/modbus/triple_buffer.h"
#include "phalanx/host/session.h"

namespace phalanx::host::modbus {

struct ServerStats {
  std::atomic<uint64_t> connections{0};
  std::atomic<uint64_t> refused_connections{0};  ///< beyond max_clients
  std::atomic<uint64_t> requests{0};
  std::atomic<uint64_t> exceptions{0};           ///< requests answered with a Modbus exception
  std::atomic<uint64_t> writes_accepted{0};
  std::atomic<uint64_t> dropped{0};              ///< connections closed on a malformed/incomplete frame or error
};

class Server {
 public:
  Server(const ServerOptions& options, const WriteLimits& limits);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Bind, listen and start the thread. Returns "" or the problem.
  std::string start();
  void stop();
  unsigned port() const { return port_; }
  /// Without the listener (fuzzing, tests): serve the requests of one connected socket as the server thread
  /// serves a client, until the stream ends or fails (where the thread drops the client). "" or the problem.
  std::string serveConnection(int fd);

  /// Loop side (one producer thread).
  void publish(const LoopSnapshot& s) { snapshot_.publish(s); }
  /// Loop side: the latest accepted write block (false before the first write).
  bool latestCommand(RemoteCommand& out) { return command_.read(out); }

  const ServerStats& stats() const { return stats_; }
  nlohmann::json statsJson() const;
  const WriteLimits& limits() const { return limits_; }

 private:
  std::string prepare();
  void serve();
  int serveRequest(int fd, uint8_t* query);
  void handle(int fd, const uint8_t* query, int length);

  ServerOptions opt_;
  WriteLimits limits_;
  void* ctx_ = nullptr;      // modbus_t
  void* mapping_ = nullptr;  // modbus_mapping_t
  int listen_fd_ = -1;
  unsigned port_ = 0;
  std::atomic<bool> running_{false};
  std::thread thread_;
  TripleBuffer<LoopSnapshot> snapshot_;
  TripleBuffer<RemoteCommand> command_;
  RemoteCommand holding_cmd_;  // server-thread owned
  uint16_t holding_[hold::kCount] = {};
  ServerStats stats_;
};

/// The loop's side of the server, per cycle: override the controller's command while Modbus has control, and
/// publish the cycle. Everything here is O(1), allocation-free and lock-free.
class LoopPort {
 public:
  LoopPort(Server& server, const ServerOptions& options, uint16_t device_type, uint16_t sample_count,
           uint16_t setpoint_count);
  /// After the controller filled cmd: if the latest Modbus write selected Modbus control, use its mode and
  /// setpoints (nominal gains), or the safe state when that write is older than command_timeout_ms; true when
  /// Modbus commanded this cycle. The session's limits stage applies to the result like to any command.
  bool overrideCommand(protocol::Command& cmd, uint64_t now_ns);
  /// After the command was sent.
  void publish(const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t cycles, uint64_t overruns,
               double jitter_us, double cycle_us, uint64_t uptime_ns, uint64_t telemetry_lost, LoopState state);
  uint64_t remoteCycles() const { return remote_cycles_; }
  uint64_t remoteTimeouts() const { return remote_timeouts_; }
  /// While another command source (a local client) holds the device, a write selecting Modbus control is
  /// refused: overrideCommand returns false and the cycle is counted (refusedCycles).
  void lockOut(bool locked) { locked_out_ = locked; }
  /// The last overrideCommand commanded the device (Modbus holds control).
  bool commanding() const { return commanding_; }
  uint64_t refusedCycles() const { return refused_cycles_; }

 private:
  bool selectCommand(protocol::Command& cmd, uint64_t now_ns);
  Server& server_;
  uint64_t timeout_ns_;
  LoopSnapshot snap_;
  RemoteCommand remote_;
  bool have_remote_ = false;
  bool timed_out_ = false;
  bool locked_out_ = false, commanding_ = false;
  uint64_t refused_cycles_ = 0;
  float window_max_ = 0.0f, prev_window_max_ = 0.0f;
  uint32_t window_n_ = 0;
  uint64_t remote_cycles_ = 0, remote_timeouts_ = 0;
};

}  // namespace phalanx::host::modbus
