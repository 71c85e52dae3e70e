#pragma once
/// phalanxd's client channel (docs/sdk.md): a control socket served by its own thread (connect, peer check,
/// negotiate, release) and one shared-memory block per daemon for the per-cycle exchange. The loop's side,
/// ClientPort, has the shape of modbus::LoopPort: overrideCommand() once per cycle, publish() after the send;
/// both only copy into and out of the preallocated mapping (no allocation, no lock, no blocking call - the one
/// system call is a non-blocking futex wake for clients that wait on the state block).
#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "phalanx/host/client/client_options.h"
#include "phalanx/host/client/model_geometry.h"
#include "phalanx/host/client/wire.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::modbus {
class LoopPort;
}

namespace phalanx::host::client {

class DeviceModelStage;
enum class ConvertStatus : uint8_t;

/// What the daemon tells a connecting client about itself.
struct DeviceIdentity {
  const protocol::DeviceLayout* layout = nullptr;
  uint32_t rate_hz = 1000;
  uint32_t firmware_build_id = 0;
};

/// The generation handed from the socket thread to the loop (0: none).
struct Attachment {
  std::atomic<uint32_t> generation{0};     ///< the connected client's generation
  std::atomic<uint32_t> deadline_ms{0};
  std::atomic<uint8_t> fallback{0};
  std::atomic<uint32_t> released{0};       ///< generation that sent Release (a clean hand-back)
  std::atomic<uint32_t> gone{0};           ///< generation whose socket closed
  std::atomic<uint32_t> holding{0};        ///< loop: the generation whose commands drive the device (0: none)
  std::atomic<uint8_t> source{0};          ///< of `generation`: CommandSource
};

/// Where a client's commands come from: the local socket (docs/sdk.md) or DDS (docs/dds.md §"Commands").
enum class CommandSource : uint8_t { kSocket = 0, kDds = 1 };
inline const char* commandSourceName(CommandSource s) { return s == CommandSource::kDds ? "dds" : "socket"; }

struct ServerCounters {
  std::atomic<uint64_t> connections{0};
  std::atomic<uint64_t> refused_credentials{0};  ///< peer not the daemon's user, root or the configured group
  std::atomic<uint64_t> refused_busy{0};         ///< another client was connected
  std::atomic<uint64_t> refused_request{0};      ///< version mismatch or out-of-range request
  std::atomic<uint64_t> releases{0};
  std::atomic<uint64_t> disconnects_without_release{0};
  std::atomic<uint64_t> in_process_attachments{0};  ///< DDS commanders attached (attachInProcess)
};

/// The checks negotiate() applies to a connection request: `got` bytes were received into req (a short read is a
/// bad request); `busy` when a client holds the device. Returns kOk, or the refusal with `why` naming it.
client_wire::ConnectStatus checkConnectRequest(const client_wire::ConnectRequest& req, long got, uint32_t rate_hz,
                                               bool busy, std::string& why);

class Server {
 public:
  Server(const ClientOptions& options, const DeviceIdentity& identity);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Create the directory and socket, the shared memory, and start the thread. "" or the problem. Without a
  /// socket path: the shared memory only (commands come in-process alone, from the DDS bridge).
  std::string start();
  void stop();
  client_wire::SharedChannel& channel() { return *channel_; }
  Attachment& attachment() { return attach_; }
  const ServerCounters& counters() const { return counters_; }
  const std::string& path() const { return opt_.socket_path; }

  /// An in-process command source (the DDS bridge, docs/dds.md §"Commands"), any thread: the checks a socket
  /// client's request gets (deadline, fallback, one commander at a time) and the same attachment. Returns its
  /// generation, or 0 with `why` (counted like a socket refusal).
  uint32_t attachInProcess(uint32_t deadline_ms, client_wire::Fallback fallback, CommandSource source, std::string& why);
  /// Its command, into the command block (its one writer while it is attached): the loop reads it like a socket
  /// client's. p.generation and p.command_seq are the caller's.
  void writeInProcess(const client_wire::CommandPayload& p);
  /// A clean hand-back (the built-in controller commands again) / the source vanished (its deadline decides).
  void releaseInProcess(uint32_t generation);
  void goneInProcess(uint32_t generation);

 private:
  std::string prepareDirectory();
  std::string createSharedMemory();
  void serve();
  void accept();
  void negotiate(int fd);
  void watchClient();
  bool peerAllowed(int fd);

  ClientOptions opt_;
  DeviceIdentity id_;
  gid_t group_gid_ = 0;
  bool have_group_ = false;
  int listen_fd_ = -1, memfd_ = -1, client_fd_ = -1;
  uint32_t client_generation_ = 0, next_generation_ = 1;
  std::mutex attach_mutex_;                 ///< negotiate() and attachInProcess(): one decision at a time
  std::atomic<bool> socket_client_{false};  ///< a socket client is connected
  uint32_t in_process_generation_ = 0;      ///< an attached in-process source (under attach_mutex_)
  client_wire::SharedChannel* channel_ = nullptr;
  std::atomic<bool> running_{false};
  std::thread thread_;
  Attachment attach_;
  ServerCounters counters_;
};

/// One force-off, for the summary.
struct ForceOffRecord {
  client_wire::ForceOffCause cause = client_wire::ForceOffCause::kNone;
  uint32_t generation = 0;
  CommandSource source = CommandSource::kSocket;
  uint64_t at_ns = 0;            ///< the cycle (wake time) that sent the fallback first
  uint64_t last_command_ns = 0;  ///< the cycle that last read a fresh command from this client
};

class ClientPort {
 public:
  /// modbus: the session's Modbus port, or nullptr (exactly one of them commands; the other is refused).
  /// geometry: the device models' geometry (the daemon's geometry files, else the defaults).
  ClientPort(Server& server, const protocol::DeviceLayout& layout, uint32_t rate_hz, modbus::LoopPort* modbus,
             const ModelGeometry& geometry = {});
  ~ClientPort();

  /// After the controller and Modbus: true when the client commands this cycle - its newest command (mode,
  /// setpoints, nominal gains), or its fallback state (safe or transparent) once force went off. The limits stage
  /// applies to the result like to any command.
  bool overrideCommand(const TelemetryFrame& tel, protocol::Command& cmd, uint64_t now_ns);
  /// After the command was sent: the state block, then a futex wake.
  void publish(const TelemetryFrame& tel, const protocol::Command& sent, uint64_t now_ns, uint64_t cycle);
  /// The session ends: the last state block carries the cause (daemon stop or link loss).
  void finish(client_wire::ForceOffCause cause);
  nlohmann::json summaryJson(uint64_t start_ns) const;
  uint64_t cyclesCommanded() const { return cycles_commanded_; }

 private:
  enum class Phase : uint8_t { kIdle, kConnected, kHolding, kForcedOff };
  bool overrideCommandAt(const TelemetryFrame& tel, protocol::Command& cmd, uint64_t now_ns);
  void countMissed(uint64_t now_ns);
  void followAttachment();
  void attach(uint32_t generation);
  void detach();
  bool readFreshCommand(uint64_t now_ns);
  bool commandIsValid() const;
  void forceOff(client_wire::ForceOffCause cause, uint64_t now_ns);
  void fallbackCommand(protocol::Command& cmd) const;
  void clientCommand(protocol::Command& cmd);
  void springFallback(protocol::Command& cmd);
  void noteConversion(ConvertStatus st, float scale);
  void observeOnce(const TelemetryFrame& tel);
  void holdControl(bool hold);
  void noteSentCommand(const protocol::Command& sent, uint64_t now_ns);
  void updateRate(uint64_t now_ns);
  void writeState();

  static constexpr size_t kMaxForceOffRecords = 64;  // fixed: later ones are counted only

  Server& server_;
  const protocol::DeviceLayout& layout_;
  modbus::LoopPort* modbus_;
  uint64_t period_ns_;
  Phase phase_ = Phase::kIdle;
  uint32_t generation_ = 0;
  CommandSource source_ = CommandSource::kSocket;
  uint64_t deadline_ns_ = 0;
  client_wire::Fallback fallback_ = client_wire::Fallback::kSafe;
  client_wire::CommandPayload command_{};
  std::unique_ptr<DeviceModelStage> model_;  ///< allocated once, at construction
  std::array<float, protocol::kMaxSetpoints> intended_{};  ///< the client's setpoints before the limits stage
  bool observed_this_cycle_ = false;
  client_wire::Rendered rendered_ = client_wire::Rendered::kNothing;
  float model_scale_ = 1.0f;
  uint64_t model_saturated_ = 0, fallback_cycles_ = 0;
  uint64_t cycles_without_fresh_ = 0;  ///< held cycles without a fresh command (fallback or repeat): missed cycles
  /// Of those, the ones off the daemon's schedule: the client was woken for the last state less than half a period
  /// before this cycle read its command (the daemon's cycle ran late or is catching up), or this cycle woke more
  /// than one and a half periods after the one before (the machine kept the daemon, and the client, off the CPU).
  /// Either way the client had no ordinary period to answer in; the rest are the client's own misses.
  uint64_t missed_off_schedule_ = 0;
  uint64_t previous_cycle_ns_ = 0;  ///< the last cycle's wake time
  uint64_t woken_ns_ = 0;           ///< when the last state was written and the client woken
  uint32_t last_command_seq_ = 0;
  uint64_t last_fresh_ns_ = 0;
  bool commanded_this_cycle_ = false, offered_this_cycle_ = false, invalid_this_cycle_ = false;
  client_wire::Control control_ = client_wire::Control::kNotYet;
  client_wire::ForceOffCause cause_ = client_wire::ForceOffCause::kNone;
  client_wire::StatePayload state_{};
  uint64_t rate_window_start_ns_ = 0;
  uint32_t rate_window_commands_ = 0;
  std::array<ForceOffRecord, kMaxForceOffRecords> records_{};
  size_t record_count_ = 0;
  uint64_t force_offs_ = 0, cycles_commanded_ = 0, refused_invalid_ = 0, refused_other_source_ = 0, limited_ = 0;
  uint64_t clients_seen_ = 0;
};

}  // namespace phalanx::host::client
