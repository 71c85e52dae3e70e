#pragma once
/// What phalanxd does when the link to a device goes away mid-session (USB unplug, a CDC-ACM tty hung up) and
/// comes back (docs/usb.md "phalanxd: unplug, safe state, reconnect"):
///   kUp --link lost--> kDown: report; send nothing (the device's own command timeout takes it to its safe state)
///   kDown --every reopen period--> reopen(); on success a new Hello (new session id) --> kHandshake
///   kHandshake --no answer within the handshake timeout--> drop() and back to kDown, reopening at once (what was
///     opened by the device's name may not be the device: another tty briefly took the freed name)
///   kHandshake --HelloAck ok, same device type--> kParams (start-up parameters again: a re-plugged board may have
///     rebooted) --all acknowledged--> kFirstTelemetry --telemetry of the new session--> faults latched during the
///     outage cleared (logged), control resumed --> kUp
/// A link lost again in any phase goes back to kDown. A different device, a refused handshake or a refused
/// start-up parameter is a hard error (kFailed). No command from before the outage is ever resent: the caller
/// sends commands only in cycles where step() returns kControl.
/// The link is reached through RecoveryLink (the seam; tests/unit/link_recovery_test.cpp drives it with a cable
/// that can be pulled), the protocol through the real HostSession.
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "phalanx/host/session.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host {

/// The part of a link that can go away.
class RecoveryLink {
 public:
  virtual ~RecoveryLink() = default;
  /// True once the link is gone (USB: no device; serial: hung up or closed).
  virtual bool lost() = 0;
  /// Called once when the loss is seen (serial: close at once, or the re-plugged board gets another tty name).
  virtual void drop() = 0;
  /// Try to open the link again; empty on success, else why not.
  virtual std::string reopen() = 0;
  /// Move queued output and completions; never blocks.
  virtual void flush() = 0;
  /// Why the link went away / where it came back (for the reports).
  virtual std::string describe() = 0;
};

struct LinkRecoveryOptions {
  uint64_t reopen_period_ns = 100000000ull;  ///< 100 ms (docs/usb.md)
  /// A reopened link that does not answer the Hello this long is closed and opened again; a start-up parameter
  /// unanswered this long is sent again.
  uint64_t handshake_timeout_ns = 2000000000ull;
  bool clear_faults = true;                   ///< clear faults latched during the outage (logged)
};

struct LinkRecoveryStats {
  uint64_t outages = 0;         ///< losses seen while controlling
  uint64_t reconnects = 0;      ///< control resumed after an outage
  uint64_t cycles_offline = 0;  ///< step() calls that returned kOffline
  double max_s = 0.0;           ///< longest outage (loss seen → control resumed)
  double total_s = 0.0;
  uint16_t faults_after_reconnect = 0;  ///< fault bits the device reported after a reconnect (latched while offline)
};

class LinkRecovery {
 public:
  enum class Phase : uint8_t { kUp = 0, kDown, kHandshake, kParams, kFirstTelemetry };
  enum class Step : uint8_t {
    kControl = 0,  ///< the link is up and the session ours: run the controller, send a command
    kOffline,      ///< no command this cycle
    kFailed,       ///< hard error (error() says which): end the session
  };
  using Log = std::function<void(const std::string&)>;
  using NewSessionId = std::function<uint32_t()>;

  LinkRecovery(RecoveryLink& link, HostSession& session, protocol::DeviceType type,
               std::vector<std::pair<uint16_t, float>> startup_params, LinkRecoveryOptions opt, NewSessionId new_id,
               Log log, uint64_t start_ns);

  /// Once per control cycle, after session.poll(now_ns).
  Step step(uint64_t now_ns);

  Phase phase() const { return phase_; }
  const LinkRecoveryStats& stats() const { return stats_; }
  const std::string& error() const { return error_; }

 private:
  void sendHello(uint64_t now_ns);
  void sendParam(uint64_t now_ns);
  double since(uint64_t now_ns, uint64_t then_ns) const { return static_cast<double>(now_ns - then_ns) * 1e-9; }

  RecoveryLink& link_;
  HostSession& session_;
  protocol::DeviceType type_;
  std::vector<std::pair<uint16_t, float>> params_;
  LinkRecoveryOptions opt_;
  NewSessionId new_id_;
  Log log_;
  uint64_t start_ns_;
  Phase phase_ = Phase::kUp;
  size_t param_index_ = 0;
  uint64_t phase_ns_ = 0;  ///< when the last Hello / parameter went out
  uint64_t next_reopen_ns_ = 0;
  uint64_t lost_ns_ = 0;
  uint64_t telemetry_at_handshake_ = 0;
  LinkRecoveryStats stats_;
  std::string error_;
};

}  // namespace phalanx::host
