#pragma once
/// phalanxd's DDS bridge settings (YAML section `dds`, options --dds-*; docs/dds.md). Off by default.
#include <cstdint>
#include <string>
#include <vector>

namespace YAML {
class Node;
}

namespace phalanx::host::dds {

struct DdsOptions {
  bool enabled = false;
  uint32_t domain_id = 0;        ///< DDS domain (ROS_DOMAIN_ID), 0..232
  std::string interface;         ///< network interface name or address for Cyclone (empty: Cyclone's choice)
  std::string ns;                ///< topic namespace (empty: phalanx/<device type>); topics rt/<ns>/...
  double state_rate_hz = 100.0;  ///< joint_states, poses, wrenches: 1..device rate (a divisor is kept exactly)
  double diagnostics_rate_hz = 1.0;  ///< diagnostics: 0.1..10 (and at once on a fault change)
  bool joint_states = true, poses = true, wrenches = true, diagnostics = true;  ///< topic enable flags
  bool announce = true;  ///< topics.announce: this device on rt/phalanx/devices (`phalanx devices`)
  std::string state_reliability = "best_effort";  ///< best_effort | reliable
  uint32_t state_depth = 1;                       ///< keep-last depth of the state topics, 1..100
  uint32_t diagnostics_depth = 10;                ///< keep-last depth of diagnostics (reliable), 1..100
  uint32_t queue_slots = 256;                     ///< loop → bridge ring, 16..65536 (full: the sample is dropped, counted)
  /// `commands`: rt/<ns>/command read into the client channel's command path (docs/dds.md §"Commands").
  bool commands = false;                  ///< commands.enabled (off by default)
  uint32_t command_deadline_ms = 250;     ///< commands.deadline_ms: a local client's deadline, [2 periods, 1000]
  std::string command_fallback = "safe";  ///< commands.fallback: safe | transparent (after a force-off)
  uint32_t command_depth = 64;            ///< commands.depth: reader keep-last depth (reliable), 1..1000
};

/// Read the `dds` mapping into o (unknown keys, wrong types are errors naming the key). "" or "dds.<key>: …".
std::string loadDdsOptions(const YAML::Node& node, DdsOptions& o);
/// Ranges (rate against the session's rate_hz). "" or the first problem, naming the key.
std::string validateDdsOptions(const DdsOptions& o, unsigned rate_hz);

}  // namespace phalanx::host::dds
