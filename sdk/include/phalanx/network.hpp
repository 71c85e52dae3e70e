#pragma once
/// libphalanx on the lab network (docs/sdk.md §"Devices on the network"): find the devices that phalanxd daemons
/// announce over DDS (rt/phalanx/devices) and command one by its name from any machine on the network, through
/// its rt/<name>/command topic (docs/dds.md §"Commands"). The daemon treats such a commander as it treats a local
/// client: the same checks, the one limits stage (the device's limits, then the patient's), the deadline it was
/// configured with (dds.commands.deadline_ms) and the force-off records.
///
/// Present when libphalanx was built with Cyclone DDS (CMake: phalanx_NETWORK is TRUE; the macro
/// PHALANX_NETWORK is defined for users of phalanx::phalanx). The per-cycle servo channel (client.hpp) stays
/// local: shared memory does not cross machines, and a network round trip is not a servo cycle.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "phalanx/client.hpp"

namespace phalanx {

struct NetworkOptions {
  unsigned domain = 0;        ///< DDS domain id (the daemon's dds.domain_id), 0..232
  std::string interface;      ///< network interface name or IPv4 address; empty: Cyclone's default choice
  double discovery_s = 2.0;   ///< how long to listen for announcements
  std::string host;           ///< RemoteDevice: the announcing host, when several hosts announce the same name
};

/// One device as its daemon announced it (the newest announcement of each host and name).
struct NetworkDevice {
  std::string host, name, type, spec, state;
  double rate_hz = 0.0;
  uint32_t firmware_build_id = 0;
  bool commands = false;  ///< the daemon reads rt/<name>/command (dds.commands.enabled)
  double age_s = 0.0;     ///< of the announcement, when the listing ended
};

/// Every device announced within options.discovery_s. Throws Error (PHALANX_ECONNECT) when DDS cannot start.
std::vector<NetworkDevice> listNetworkDevices(const NetworkOptions& options = {});

/// The newest rt/<name>/joint_states sample (sensor_msgs/JointState; names and units: docs/dds.md §"Topics").
struct RemoteJoints {
  std::vector<std::string> name;
  std::vector<double> position, velocity, effort;
  int64_t stamp_ns = 0;   ///< the daemon's stamp (telemetry arrival, wall clock)
  uint64_t received = 0;  ///< samples received so far
};

class RemoteDevice {
 public:
  /// Finds the device announced as `name` (e.g. "lab/glove_left") and opens its command and state topics.
  /// Throws Error naming what is wrong: PHALANX_ECONNECT when no daemon announced that name within
  /// discovery_s, PHALANX_EREFUSED when it announced it stopped, with commands off, or from several hosts
  /// (set options.host), PHALANX_EARG for a bad option.
  explicit RemoteDevice(const std::string& name, const NetworkOptions& options = {});
  ~RemoteDevice();  ///< releases the device
  RemoteDevice(const RemoteDevice&) = delete;
  RemoteDevice& operator=(const RemoteDevice&) = delete;

  const NetworkDevice& device() const;
  /// The device type's number of raw setpoints (glove5 5, sea_finger 2, pantograph 6).
  size_t setpointCount() const;
  /// Send a command: kind kRaw carries setpoint[0 .. the device's setpoint count), a model-level kind its
  /// values in model[] (docs/dds.md's Command table). false, nothing sent: a kind that is not this device's,
  /// a mode other than transparent or setpoint, or a DDS write error (lastError()). Keep sending within the
  /// daemon's deadline (dds.commands.deadline_ms, 250 ms by default) or it forces the device off.
  bool send(const Command& cmd);
  /// The next joint_states sample newer than the last one read, waiting up to timeout_ms; false on timeout.
  bool waitJoints(RemoteJoints& out, int timeout_ms);
  /// Hand the device back (the writer's instance disposed): the daemon's built-in controller resumes at once.
  void release();
  const std::string& lastError() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phalanx
