#include "phalanx/host/config.h"

#include <yaml-cpp/yaml.h>

#include <fstream>
#include <set>
#include <sstream>

#include "phalanx/host/yaml_keys.h"

namespace phalanx::host {
namespace {

struct ConfigError {
  std::string message;
};

template <class T>
T scalar(const YAML::Node& node, const std::string& key, const char* type_name) {
  if (!node.IsScalar()) throw ConfigError{key + ": expected a " + type_name};
  try {
    return node.as<T>();
  } catch (const YAML::Exception&) {
    throw ConfigError{key + ": expected a " + type_name + ", got '" + node.Scalar() + "'"};
  }
}

void requireKeys(const YAML::Node& map, const std::string& where, const std::set<std::string>& allowed) {
  if (!map.IsMap()) throw ConfigError{(where.empty() ? std::string("top level") : where) + ": expected a mapping"};
  for (const auto& kv : map) {
    const std::string key = kv.first.as<std::string>();
    if (allowed.count(key) == 0) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw ConfigError{(where.empty() ? "" : where + ".") + key + ": unknown key (allowed: " + list + ")"};
    }
  }
}

void apply(const YAML::Node& root, RunOptions& opt) {
  if (root.IsNull()) return;
  requireKeys(root, "", {"version", "device", "seconds", "rate_hz", "command_timeout_ms", "telemetry_timeout_ms", "realtime", "record",
                         "seed", "clear_faults", "glove", "pen", "modbus", "gpio", "dashboard", "client", "dds",
                         "cycle"});
  if (root["version"] && scalar<int>(root["version"], "version", "integer") != 1) {
    throw ConfigError{"version: only version 1 is understood by this phalanxd"};
  }
  if (root["device"]) opt.device = scalar<std::string>(root["device"], "device", "string");
  if (root["seconds"]) opt.seconds = scalar<double>(root["seconds"], "seconds", "number");
  if (root["rate_hz"]) opt.rate_hz = scalar<unsigned>(root["rate_hz"], "rate_hz", "positive integer");
  if (root["command_timeout_ms"]) {
    opt.command_timeout_ms = scalar<unsigned>(root["command_timeout_ms"], "command_timeout_ms", "positive integer");
  }
  if (root["telemetry_timeout_ms"]) {
    opt.telemetry_timeout_ms =
        scalar<unsigned>(root["telemetry_timeout_ms"], "telemetry_timeout_ms", "positive integer");
  }
  if (root["cycle"]) opt.cycle = scalar<std::string>(root["cycle"], "cycle", "telemetry or timer");
  if (root["record"]) opt.record_csv = scalar<std::string>(root["record"], "record", "path");
  if (root["seed"]) opt.seed = scalar<uint32_t>(root["seed"], "seed", "non-negative integer");
  if (root["clear_faults"]) opt.clear_faults = scalar<bool>(root["clear_faults"], "clear_faults", "boolean");
  if (const YAML::Node rt = root["realtime"]) {
    requireKeys(rt, "realtime", {"enabled", "priority"});
    if (rt["enabled"]) opt.realtime = scalar<bool>(rt["enabled"], "realtime.enabled", "boolean");
    if (rt["priority"]) opt.rt_priority = scalar<int>(rt["priority"], "realtime.priority", "integer");
  }
  if (const YAML::Node pn = root["pen"]) {
    requireKeys(pn, "pen", {"geometry", "wall_stiffness_N_per_cm", "floor_mm"});
    if (pn["geometry"]) opt.pen_geometry = scalar<std::string>(pn["geometry"], "pen.geometry", "path");
    if (pn["wall_stiffness_N_per_cm"]) {
      opt.pen_wall_stiffness_N_per_cm = scalar<double>(pn["wall_stiffness_N_per_cm"], "pen.wall_stiffness_N_per_cm", "number");
    }
    if (pn["floor_mm"]) opt.pen_floor_mm = scalar<double>(pn["floor_mm"], "pen.floor_mm", "number");
  }
  if (const YAML::Node mb = root["modbus"]) {
    if (std::string err = modbus::loadServerOptions(mb, opt.modbus); !err.empty()) throw ConfigError{err};
  }
  if (const YAML::Node cl = root["client"]) {
    if (std::string err = client::loadClientOptions(cl, opt.client); !err.empty()) throw ConfigError{err};
  }
  if (const YAML::Node dd = root["dds"]) {
    if (std::string err = dds::loadDdsOptions(dd, opt.dds); !err.empty()) throw ConfigError{err};
  }
  if (const YAML::Node io = root["gpio"]) {
    requireKeys(io, "gpio", {"estop", "enable", "sync", "estop_release_ms"});
    if (io["estop"]) opt.gpio.estop = scalar<std::string>(io["estop"], "gpio.estop", "string");
    if (io["enable"]) opt.gpio.enable = scalar<std::string>(io["enable"], "gpio.enable", "string");
    if (io["sync"]) opt.gpio.sync = scalar<std::string>(io["sync"], "gpio.sync", "string");
    if (io["estop_release_ms"]) {
      opt.gpio.estop_release_ms = scalar<double>(io["estop_release_ms"], "gpio.estop_release_ms", "number");
    }
    if (std::string err = validateGpio(opt.gpio); !err.empty()) throw ConfigError{err};
  }
  if (const YAML::Node d = root["dashboard"]) {
    requireKeys(d, "dashboard", {"enabled", "listen", "allow_remote"});
    // allow_remote first: it decides whether a non-loopback listen address is acceptable.
    if (d["allow_remote"]) {
      opt.dashboard.allow_remote = scalar<bool>(d["allow_remote"], "dashboard.allow_remote", "boolean");
    }
    if (d["listen"]) {
      const std::string spec = scalar<std::string>(d["listen"], "dashboard.listen", "ADDRESS:PORT string");
      if (std::string err = api::parseDashboardSpec(spec, opt.dashboard); !err.empty()) {
        throw ConfigError{"dashboard.listen: " + err};
      }
    }
    opt.dashboard.enabled = d["enabled"] ? scalar<bool>(d["enabled"], "dashboard.enabled", "boolean") : true;
    if (std::string err = api::validateDashboardOptions(opt.dashboard); !err.empty()) {
      throw ConfigError{"dashboard: " + err};
    }
  }
  if (const YAML::Node g = root["glove"]) {
    requireKeys(g, "glove", {"scene", "scenario", "mode", "geometry"});
    if (const YAML::Node geo = g["geometry"]) {
      // finger → geometry file written by `phalanx design glove-* --yaml` (validated with the options).
      requireKeys(geo, "glove.geometry", {"thumb", "index", "middle", "ring", "little"});
      for (const auto& kv : geo) {
        const std::string finger = kv.first.as<std::string>();
        opt.glove_geometry[finger] = scalar<std::string>(kv.second, "glove.geometry." + finger, "path");
      }
    }
    if (g["scene"]) opt.scene = scalar<std::string>(g["scene"], "glove.scene", "string");
    if (g["scenario"]) opt.scenario = scalar<std::string>(g["scenario"], "glove.scenario", "string");
    if (g["mode"]) opt.mode = scalar<std::string>(g["mode"], "glove.mode", "string");
  }
}

}  // namespace

std::string loadConfigText(const std::string& yaml_text, const std::string& source, RunOptions& opt) {
  RunOptions candidate = opt;  // nothing changes unless the whole file is valid
  try {
    const YAML::Node root = YAML::Load(yaml_text);
    if (std::string dup = findDuplicateKey(root); !dup.empty()) throw ConfigError{dup};
    apply(root, candidate);
  } catch (const ConfigError& e) {
    return source + ": " + e.message;
  } catch (const YAML::Exception& e) {
    return source + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
  }
  const std::string problem = validate(candidate);
  if (!problem.empty()) return source + ": " + problem;
  if (const std::string err = checkSessionLength(candidate.seconds, candidate.rate_hz); !err.empty()) {
    return source + ": seconds: " + err;
  }
  opt = candidate;
  return {};
}

std::string checkSessionLength(double seconds_s, unsigned rate_hz) {
  if (!(seconds_s > 0.0) || rate_hz == 0) return {};  // 0 means until stopped; the range is validate()'s
  // 1e-9: a length of exactly one period (0.001 s at 1 kHz) is one cycle, whatever its binary rounding.
  if (seconds_s * rate_hz >= 1.0 - 1e-9) return {};
  std::ostringstream os;
  os << seconds_s << " s is shorter than one host period (" << 1.0 / rate_hz << " s at " << rate_hz
     << " Hz); give 0 to run until stopped";
  return os.str();
}

std::string loadConfigFile(const std::string& path, RunOptions& opt) {
  std::ifstream in(path);
  if (!in) return path + ": cannot read configuration file";
  std::stringstream ss;
  ss << in.rdbuf();
  return loadConfigText(ss.str(), path, opt);
}

}  // namespace phalanx::host
