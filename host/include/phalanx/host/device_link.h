#pragma once
/// One link to one device, whatever carries it: a serial port (USB CDC-ACM, UART), a pseudo-terminal to the
/// simulated firmware (sim:*), a CAN bus (CAN-FD, compact CAN-FD, classic) or vendor USB bulk. The session runner
/// (host/src/daemon.cpp) sees only this interface: it never asks which transport it drives.
#include <poll.h>

#include <cstddef>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/link_recovery.h"
#include "phalanx/host/session.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host {

struct RunOptions;

class DeviceLink : public RecoveryLink {
 public:
  ~DeviceLink() override = default;
  /// A protocol endpoint on this link (the link must outlive it).
  virtual HostSession makeSession() = 0;
  /// The device type to ask for in the Hello (kAny unless the link knows what it runs: sim:*).
  virtual protocol::DeviceType expectedDevice() const { return protocol::DeviceType::kAny; }
  /// The device variant (core parameter 0x0004, protocol::variant::*) the link expects, or -1 for any: sim:sea_rig
  /// and sim:sea_finger are the same device type, told apart by it.
  virtual int expectedVariant() const { return -1; }
  /// Push queued output to the transport. false: a hard error that ends the session (linkError() says which);
  /// an unplug of a link that reconnects is not one (lost() reports it instead).
  virtual bool push() = 0;
  virtual std::string linkError() const = 0;
  /// True when an unplug is survivable: the runner then reconnects through LinkRecovery (usb:, serial:).
  virtual bool reconnects() const { return false; }
  /// False where commands cannot carry per-channel gain scales (classic CAN, docs/protocol.md).
  virtual bool carriesGainScales() const { return true; }
  /// A device that can no longer answer (the simulated firmware's process exited): checked every cycle.
  virtual std::string deviceGone() { return {}; }
  /// True while the transport itself reports an outage it recovers from by itself (a CAN bus off or its
  /// interface down): silence then is that outage, not a lost device, and the telemetry timeout waits for it.
  virtual bool inOutage() const { return false; }
  /// Once per cycle after the command went out: transport state changes worth a log line (CAN bus state).
  virtual void afterCycle(double t_s) { (void)t_s; }
  /// Where it is, for messages (a path, an interface, a USB bus/port).
  virtual std::string where() const = 0;
  /// summary["link"] and the transport's own counters (summary["can"], summary["usb"]).
  virtual nlohmann::json info() const = 0;
  virtual void summarize(nlohmann::json& summary) const { (void)summary; }
  /// Leave: the simulated firmware is stopped; real links just close with the object.
  virtual void close() {}
  /// The descriptors that signal input on this link (at most `max`, written to `fds` with their events): the
  /// runner waits on them to start a cycle as soon as a telemetry frame arrives (docs/session-runner.md, "The
  /// cycle's clock"). 0: nothing to wait on now (an unplugged link): the period timer paces the cycles.
  virtual size_t waitFds(pollfd* fds, size_t max) {
    (void)fds;
    (void)max;
    return 0;
  }

  // RecoveryLink (used by LinkRecovery when reconnects()): defaults for links that never reconnect.
  bool lost() override { return false; }
  void drop() override {}
  std::string reopen() override { return "this link does not reconnect"; }
  void flush() override { push(); }
  std::string describe() override { return where(); }
};

/// Open the link named by opt.device (validated). nullptr and `error` set when it cannot be opened.
std::unique_ptr<DeviceLink> openDeviceLink(const RunOptions& opt, std::string& error);

/// Handshakes on an open link: a Hello for link.expectedDevice() every 500 ms (a backed-up link may lose one) until
/// the device answers or `timeout_s` passes. "" once it succeeded (session.deviceInfo() is the HelloAck), else why
/// not. For the short command-line tools (phalanx param, phalanx update), not the session runner.
std::string handshakeDevice(DeviceLink& link, HostSession& session, double timeout_s);

}  // namespace phalanx::host
