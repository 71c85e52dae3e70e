#include <arpa/inet.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>

#include "phalanx/host/modbus/server_options.h"

namespace phalanx::host::modbus {
namespace {

struct Bad {
  std::string what;
};

template <class T>
T get(const YAML::Node& n, const std::string& key, const char* type) {
  if (!n.IsScalar()) throw Bad{key + ": expected a " + type};
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    throw Bad{key + ": expected a " + type + ", got '" + n.Scalar() + "'"};
  }
}

}  // namespace

std::string loadServerOptions(const YAML::Node& node, ServerOptions& o) {
  try {
    if (!node.IsMap()) throw Bad{"modbus: expected a mapping"};
    const std::set<std::string> allowed = {"enabled",       "address",        "port",
                                           "max_clients",   "writes_enabled", "setpoint_limit",
                                           "command_timeout_ms", "byte_timeout_ms"};
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      if (allowed.count(key) == 0) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        throw Bad{"modbus." + key + ": unknown key (allowed: " + list + ")"};
      }
    }
    if (node["enabled"]) o.enabled = get<bool>(node["enabled"], "modbus.enabled", "boolean");
    if (node["address"]) o.address = get<std::string>(node["address"], "modbus.address", "IPv4 address");
    if (node["port"]) o.port = get<unsigned>(node["port"], "modbus.port", "port number");
    if (node["max_clients"]) o.max_clients = get<unsigned>(node["max_clients"], "modbus.max_clients", "positive integer");
    if (node["writes_enabled"]) o.writes_enabled = get<bool>(node["writes_enabled"], "modbus.writes_enabled", "boolean");
    if (node["setpoint_limit"]) o.setpoint_limit = get<double>(node["setpoint_limit"], "modbus.setpoint_limit", "number");
    if (node["command_timeout_ms"]) {
      o.command_timeout_ms = get<unsigned>(node["command_timeout_ms"], "modbus.command_timeout_ms", "non-negative integer");
    }
    if (node["byte_timeout_ms"]) {
      o.byte_timeout_ms = get<unsigned>(node["byte_timeout_ms"], "modbus.byte_timeout_ms", "positive integer");
    }
  } catch (const Bad& b) {
    return b.what;
  }
  return validateServerOptions(o);
}

std::string validateServerOptions(const ServerOptions& o) {
  if (o.port > 65535) return "modbus.port: must be in [0, 65535]";
  if (o.max_clients < 1 || o.max_clients > 256) return "modbus.max_clients: must be in [1, 256]";
  if (!std::isfinite(o.setpoint_limit) || o.setpoint_limit < 0.0) {
    return "modbus.setpoint_limit: must be ≥ 0 (0: the device's own limit)";
  }
  if (o.command_timeout_ms > 60000) return "modbus.command_timeout_ms: must be in [0, 60000]";
  if (o.byte_timeout_ms < 1 || o.byte_timeout_ms > 1000) return "modbus.byte_timeout_ms: must be in [1, 1000]";
  in_addr a{};
  if (o.address != "*" && inet_pton(AF_INET, o.address.c_str(), &a) != 1) {
    return "modbus.address: '" + o.address + "' is not an IPv4 address (127.0.0.1 for loopback, 0.0.0.0 for all)";
  }
  return {};
}

}  // namespace phalanx::host::modbus
