#include "phalanx/host/dds/dds_options.h"

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <set>

#include "phalanx/dds_namespace.h"

namespace phalanx::host::dds {
namespace {

struct Bad {
  std::string message;
};

template <class T>
T scalar(const YAML::Node& n, const std::string& key, const char* type_name) {
  if (!n.IsScalar()) throw Bad{"dds." + key + ": expected a " + type_name};
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    throw Bad{"dds." + key + ": expected a " + type_name + ", got '" + n.Scalar() + "'"};
  }
}

}  // namespace

std::string loadDdsOptions(const YAML::Node& node, DdsOptions& o) {
  static const std::set<std::string> kKeys = {"enabled", "domain_id", "interface", "namespace", "state_rate_hz",
                                              "diagnostics_rate_hz", "topics", "state_reliability", "state_depth",
                                              "diagnostics_depth", "queue_slots", "commands"};
  static const std::set<std::string> kCommands = {"enabled", "deadline_ms", "fallback", "depth"};
  static const std::set<std::string> kTopics = {"joint_states", "poses", "wrenches", "diagnostics", "announce"};
  const auto allowed = [](const std::set<std::string>& s) {
    std::string l;
    for (const auto& k : s) l += (l.empty() ? "" : ", ") + k;
    return l;
  };
  try {
    if (!node.IsMap()) throw Bad{"dds: expected a mapping"};
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      if (kKeys.count(key) == 0) throw Bad{"dds." + key + ": unknown key (allowed: " + allowed(kKeys) + ")"};
    }
    // Present without `enabled`: the section is meant to be used (like `dashboard`).
    o.enabled = node["enabled"] ? scalar<bool>(node["enabled"], "enabled", "boolean") : true;
    if (node["domain_id"]) o.domain_id = scalar<uint32_t>(node["domain_id"], "domain_id", "non-negative integer");
    if (node["interface"]) o.interface = scalar<std::string>(node["interface"], "interface", "string");
    if (node["namespace"]) o.ns = scalar<std::string>(node["namespace"], "namespace", "string");
    if (node["state_rate_hz"]) o.state_rate_hz = scalar<double>(node["state_rate_hz"], "state_rate_hz", "number");
    if (node["diagnostics_rate_hz"]) {
      o.diagnostics_rate_hz = scalar<double>(node["diagnostics_rate_hz"], "diagnostics_rate_hz", "number");
    }
    if (node["state_reliability"]) {
      o.state_reliability = scalar<std::string>(node["state_reliability"], "state_reliability", "string");
    }
    if (node["state_depth"]) o.state_depth = scalar<uint32_t>(node["state_depth"], "state_depth", "positive integer");
    if (node["diagnostics_depth"]) {
      o.diagnostics_depth = scalar<uint32_t>(node["diagnostics_depth"], "diagnostics_depth", "positive integer");
    }
    if (node["queue_slots"]) o.queue_slots = scalar<uint32_t>(node["queue_slots"], "queue_slots", "positive integer");
    if (const YAML::Node t = node["topics"]) {
      if (!t.IsMap()) throw Bad{"dds.topics: expected a mapping"};
      for (const auto& kv : t) {
        const std::string key = kv.first.as<std::string>();
        if (kTopics.count(key) == 0) throw Bad{"dds.topics." + key + ": unknown key (allowed: " + allowed(kTopics) + ")"};
        const bool on = scalar<bool>(kv.second, "topics." + key, "boolean");
        if (key == "joint_states") o.joint_states = on;
        if (key == "poses") o.poses = on;
        if (key == "wrenches") o.wrenches = on;
        if (key == "diagnostics") o.diagnostics = on;
        if (key == "announce") o.announce = on;
      }
    }
    if (const YAML::Node c = node["commands"]) {
      if (!c.IsMap()) throw Bad{"dds.commands: expected a mapping"};
      for (const auto& kv : c) {
        const std::string key = kv.first.as<std::string>();
        if (kCommands.count(key) == 0) {
          throw Bad{"dds.commands." + key + ": unknown key (allowed: " + allowed(kCommands) + ")"};
        }
      }
      // Commands reach the motors: unlike the section, they are on only when `enabled: true` is written.
      o.commands = c["enabled"] ? scalar<bool>(c["enabled"], "commands.enabled", "boolean") : false;
      if (c["deadline_ms"]) {
        o.command_deadline_ms = scalar<uint32_t>(c["deadline_ms"], "commands.deadline_ms", "positive integer");
      }
      if (c["fallback"]) o.command_fallback = scalar<std::string>(c["fallback"], "commands.fallback", "string");
      if (c["depth"]) o.command_depth = scalar<uint32_t>(c["depth"], "commands.depth", "positive integer");
    }
  } catch (const Bad& b) {
    return b.message;
  }
  return {};
}

std::string validateDdsOptions(const DdsOptions& o, unsigned rate_hz) {
  if (!o.enabled) return {};
  if (o.domain_id > 232) return "dds.domain_id: must be in [0, 232]";
  if (!o.ns.empty() && !validDdsNamespace(o.ns)) {
    return "dds.namespace: '" + o.ns + "' is not a ROS name (letters, digits, _ and inner /; no leading digit or /)";
  }
  if (!std::isfinite(o.state_rate_hz) || o.state_rate_hz < 1.0 || o.state_rate_hz > rate_hz) {
    return "dds.state_rate_hz: must be in [1, rate_hz = " + std::to_string(rate_hz) + "]";
  }
  if (!std::isfinite(o.diagnostics_rate_hz) || o.diagnostics_rate_hz < 0.1 || o.diagnostics_rate_hz > 10.0) {
    return "dds.diagnostics_rate_hz: must be in [0.1, 10]";
  }
  if (o.state_reliability != "best_effort" && o.state_reliability != "reliable") {
    return "dds.state_reliability: '" + o.state_reliability + "' is not best_effort or reliable";
  }
  if (o.state_depth < 1 || o.state_depth > 100) return "dds.state_depth: must be in [1, 100]";
  if (o.diagnostics_depth < 1 || o.diagnostics_depth > 100) return "dds.diagnostics_depth: must be in [1, 100]";
  if (o.queue_slots < 16 || o.queue_slots > 65536) return "dds.queue_slots: must be in [16, 65536]";
  if (o.interface.size() > 64) return "dds.interface: longer than 64 characters";
  for (const char c : o.interface) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-' || c == ':')) {
      return "dds.interface: '" + o.interface + "' is not an interface name or address";
    }
  }
  if (!o.joint_states && !o.poses && !o.wrenches && !o.diagnostics && !o.commands) {
    return "dds.topics: every topic is off";
  }
  // The deadline a local client may ask for (client channel: at least two daemon periods, at most 1 s).
  const uint32_t min_deadline_ms = 2000 / rate_hz + ((2000 % rate_hz) != 0 ? 1 : 0);
  if (o.command_deadline_ms < min_deadline_ms || o.command_deadline_ms > 1000) {
    return "dds.commands.deadline_ms: must be in [" + std::to_string(min_deadline_ms) +
           ", 1000] (at least two daemon periods)";
  }
  if (o.command_fallback != "safe" && o.command_fallback != "transparent") {
    return "dds.commands.fallback: '" + o.command_fallback + "' is not safe or transparent";
  }
  if (o.command_depth < 1 || o.command_depth > 1000) return "dds.commands.depth: must be in [1, 1000]";
  return {};
}

}  // namespace phalanx::host::dds
