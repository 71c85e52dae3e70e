#include "phalanx/host/params.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "phalanx/apps/glove5.h"
#include "phalanx/apps/pantograph.h"
#include "phalanx/apps/sea_finger.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::params {

namespace {

/// The ids one settings layout of the firmware persists (phalanx/apps/*.h kSettingsLayouts).
struct Persisted {
  const uint16_t* ids = nullptr;
  uint8_t count = 0;
  bool has(uint16_t id) const { return std::find(ids, ids + count, id) != ids + count; }
};

template <size_t N>
Persisted layoutOf(const fw::SettingsLayout (&history)[N], uint16_t version) {
  const fw::SettingsLayout& l = version >= 1 && version <= N ? history[version - 1] : history[N - 1];
  return {l.ids, l.id_count};
}

void addDevice(std::vector<ParamInfo>& t, const Persisted& p, uint16_t id, const std::string& name, Access access) {
  t.push_back({id, name, access, p.has(id)});
}

void addCore(std::vector<ParamInfo>& t) {
  namespace c = protocol::core_param;
  t.push_back({c::kTickRate, "tick_rate_hz", Access::kReadOnly, false});
  t.push_back({c::kBuildIdLow, "build_id_low", Access::kReadOnly, false});
  t.push_back({c::kBuildIdHigh, "build_id_high", Access::kReadOnly, false});
  t.push_back({c::kDeviceVariant, "device_variant", Access::kReadOnly, false});
  // Written by `param save` (value 1), not by `param set`: a save is its own command.
  t.push_back({c::kSettingsSave, "settings_sequence", Access::kReadOnly, false});
  t.push_back({c::kSettingsLoad, "settings_load", Access::kReadOnly, false});
  t.push_back({c::kSettingsLayout, "settings_layout", Access::kReadOnly, false});
  t.push_back({c::kSettingsRefused, "settings_refused", Access::kReadOnly, false});
  // 1 while the running image is on trial after an update; writing 1 confirms it (docs/firmware-update.md).
  t.push_back({c::kUpdateTrial, "update_trial", Access::kAction, false});
}

void addGlove(std::vector<ParamInfo>& t, uint16_t version) {
  namespace g = apps::glove5_param;
  const Persisted p = layoutOf(g::kSettingsLayouts, version);
  addDevice(t, p, g::kForceKp, "force_kp", Access::kSettable);
  addDevice(t, p, g::kForceKi, "force_ki", Access::kSettable);
  addDevice(t, p, g::kForceKd, "force_kd", Access::kSettable);
  addDevice(t, p, g::kFeedForwardScale, "feed_forward_scale", Access::kSettable);
  addDevice(t, p, g::kTare, "tare", Access::kAction);
  const char* fingers[] = {"thumb", "index", "middle", "ring", "little"};  // glove::FingerId order
  for (uint16_t f = 0; f < 5; ++f) {
    addDevice(t, p, static_cast<uint16_t>(g::kGeometryFingerprintBase + f), std::string("geometry_fingerprint_") + fingers[f],
              Access::kReadOnly);
  }
}

void addSea(std::vector<ParamInfo>& t, uint16_t version) {
  namespace s = apps::sea_param;
  const Persisted p = layoutOf(s::kSettingsLayouts, version);
  addDevice(t, p, s::kController, "controller", Access::kSettable);
  addDevice(t, p, s::kBacklashCompensation, "backlash_compensation", Access::kSettable);
  addDevice(t, p, s::kJointMovingAverage, "joint_moving_average", Access::kSettable);
  addDevice(t, p, s::kZero, "zero", Access::kAction);
  const char* joints[] = {"mcp", "pip"};  // SEA index order
  for (uint16_t j = 0; j < 2; ++j) {
    addDevice(t, p, static_cast<uint16_t>(s::kKp + j), std::string("kp_") + joints[j], Access::kSettable);
    addDevice(t, p, static_cast<uint16_t>(s::kKi + j), std::string("ki_") + joints[j], Access::kSettable);
    addDevice(t, p, static_cast<uint16_t>(s::kKd + j), std::string("kd_") + joints[j], Access::kSettable);
  }
}

void addPen(std::vector<ParamInfo>& t, uint16_t version) {
  namespace pp = apps::pantograph_param;
  const Persisted p = layoutOf(pp::kSettingsLayouts, version);
  for (uint16_t j = 0; j < 6; ++j) {
    addDevice(t, p, static_cast<uint16_t>(pp::kTorqueLimitBase + j), "torque_limit_j" + std::to_string(j) + "_Nm",
              Access::kSettable);
  }
  addDevice(t, p, pp::kGeometryFingerprint, "geometry_fingerprint", Access::kReadOnly);
}

}  // namespace

std::vector<ParamInfo> known(protocol::DeviceType type, uint16_t layout_version) {
  std::vector<ParamInfo> t;
  addCore(t);
  switch (type) {
    case protocol::DeviceType::kGlove5: addGlove(t, layout_version); break;
    case protocol::DeviceType::kSeaFinger: addSea(t, layout_version); break;
    case protocol::DeviceType::kPantograph: addPen(t, layout_version); break;
    default: break;
  }
  return t;
}

const ParamInfo* lookup(const std::vector<ParamInfo>& table, const std::string& key, std::string& error) {
  for (const ParamInfo& p : table) {
    if (p.name == key) return &p;
  }
  if (!key.empty() && key.find_first_not_of("0123456789abcdefABCDEFx") == std::string::npos) {
    char* end = nullptr;
    const unsigned long id = std::strtoul(key.c_str(), &end, 0);
    if (*end == 0) {
      for (const ParamInfo& p : table) {
        if (p.id == id) return &p;
      }
    }
  }
  error = "unknown parameter '" + key + "' (phalanx param list shows the device's)";
  return nullptr;
}

std::string toYaml(const Backup& b) {
  YAML::Emitter out;
  out << YAML::Comment("phalanx param backup (docs/params.md); restore with: phalanx param load FILE --device DEV");
  out << YAML::BeginMap;
  out << YAML::Key << "device_type" << YAML::Value << b.device_type;
  out << YAML::Key << "firmware_build_id" << YAML::Value << YAML::DoubleQuoted << b.build_id;
  out << YAML::Key << "params" << YAML::Value << YAML::BeginMap;
  for (const auto& [name, v] : b.values) {
    char text[32];
    std::snprintf(text, sizeof text, "%.9g", static_cast<double>(v));  // 9 significant digits: the exact f32
    out << YAML::Key << name << YAML::Value << text;
  }
  out << YAML::EndMap << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

std::string readBackup(const std::string& path, protocol::DeviceType type, Backup& out, uint16_t layout_version) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return path + ": " + e.what();
  }
  if (!root.IsMap()) return path + ": not a parameter backup (expected a map with device_type and params)";
  for (const auto& kv : root) {
    const std::string k = kv.first.as<std::string>();
    if (k != "device_type" && k != "firmware_build_id" && k != "params") return path + ": unknown key '" + k + "'";
  }
  const protocol::DeviceLayout* layout = protocol::layoutFor(type);
  const std::string want = layout != nullptr ? layout->name : "?";
  if (!root["device_type"] || !root["device_type"].IsScalar()) return path + ": device_type missing";
  Backup b;
  b.device_type = root["device_type"].as<std::string>();
  if (b.device_type != want) return path + ": device_type is " + b.device_type + ", the device is a " + want;
  if (root["firmware_build_id"]) b.build_id = root["firmware_build_id"].as<std::string>();
  const YAML::Node ps = root["params"];
  if (!ps || !ps.IsMap()) return path + ": params missing (a map of name: value)";
  const std::vector<ParamInfo> table = known(type, layout_version);
  for (const auto& kv : ps) {
    const std::string name = kv.first.as<std::string>();
    std::string err;
    const ParamInfo* p = lookup(table, name, err);
    if (p == nullptr || p->name != name) return path + ": params: unknown parameter '" + name + "' for a " + want;
    if (!p->persisted) {
      return path + ": params: " + name + " is not a setting the device keeps" +
             (layout_version != 0 ? " (settings layout " + std::to_string(layout_version) + ")" : std::string());
    }
    double v = 0.0;
    try {
      v = kv.second.as<double>();
    } catch (const YAML::Exception&) {
      return path + ": params: " + name + ": not a number";
    }
    if (!std::isfinite(v) || std::fabs(v) > 3.4e38) return path + ": params: " + name + ": not a finite f32 value";
    b.values[name] = static_cast<float>(v);
  }
  out = b;
  return {};
}

std::vector<Difference> diff(const std::map<std::string, float>& device, const std::map<std::string, float>& file) {
  std::vector<Difference> d;
  for (const auto& [name, v] : device) {
    const auto it = file.find(name);
    if (it == file.end()) {
      d.push_back({name, true, false, v, 0.0f});
    } else if (it->second != v) {
      d.push_back({name, true, true, v, it->second});
    }
  }
  for (const auto& [name, v] : file) {
    if (device.count(name) == 0) d.push_back({name, false, true, 0.0f, v});
  }
  return d;
}

}  // namespace phalanx::host::params
