#include "phalanx/host/therapy/profile.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "phalanx/host/yaml_keys.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/records_dir.h"
#include "phalanx/host/therapy/session_plan.h"

namespace phalanx::host::therapy {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
/// Far above any real profile (a few hundred bytes); bounds what a wrong path (a log, a device file) can cost.

struct ProfileError {
  std::string message;
};

void requireKeys(const YAML::Node& map, const std::string& where, const std::set<std::string>& allowed) {
  if (!map.IsMap()) throw ProfileError{(where.empty() ? std::string("top level") : where) + ": expected a mapping"};
  for (const auto& kv : map) {
    const std::string key = kv.first.as<std::string>();
    if (allowed.count(key) == 0) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw ProfileError{(where.empty() ? "" : where + ".") + key + ": unknown key (allowed: " + list + ")"};
    }
  }
}

double number(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw ProfileError{key + ": expected a number"};
  double v = 0.0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw ProfileError{key + ": expected a number, got '" + n.Scalar() + "'"};
  }
  if (!std::isfinite(v)) throw ProfileError{key + ": must be finite"};
  return v;
}

std::string text(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw ProfileError{key + ": expected a string"};
  return n.Scalar();
}

std::pair<double, double> degRange(const YAML::Node& n, const std::string& key) {
  if (!n.IsSequence() || n.size() != 2) throw ProfileError{key + ": expected [min_deg, max_deg]"};
  const double lo = number(n[0], key + "[0]");
  const double hi = number(n[1], key + "[1]");
  if (!(lo < hi)) throw ProfileError{key + ": min must be below max"};
  return {lo * kDegToRad, hi * kDegToRad};
}

std::set<std::string> jointNames(const TherapyDevice& d) {
  std::set<std::string> s;
  for (std::size_t j = 0; j < d.jointCount(); ++j) s.insert(d.jointName(j));
  return s;
}

/// A YAML scalar as JSON: a number when it reads as one, else the string (exercise parameters are numbers, the
/// grasp scene a string; makeExercise checks which).
nlohmann::json scalarJson(const YAML::Node& n, const std::string& key) {
  if (!n.IsScalar()) throw ProfileError{key + ": expected a number or a string"};
  double v = 0.0;
  if (YAML::convert<double>::decode(n, v)) {
    if (!std::isfinite(v)) throw ProfileError{key + ": must be finite"};
    return v;
  }
  return n.Scalar();
}

/// A preset's or plan's name: 1-32 letters, digits, '-' or '_' (what: "preset" or "plan").
void requireName(const std::string& name, const std::string& where, const char* what) {
  static const std::regex kName("[A-Za-z0-9_-]{1,32}");
  if (!std::regex_match(name, kName)) throw ProfileError{where + ": a " + what + " name is 1-32 letters, digits, '-' or '_'"};
}

/// presets: {<name>: {exercise: <name>, params: {<param>: value}}}: each built once against the device so a bad
/// parameter is refused here, naming it (presets.gentle.params.stiffness_per_rad: …).
void parsePresets(const YAML::Node& node, const TherapyDevice& device, Profile& p) {
  if (!node) return;
  if (!node.IsMap()) throw ProfileError{"presets: expected a mapping <name>: {exercise, params}"};
  for (const auto& kv : node) {
    Preset preset;
    preset.name = kv.first.as<std::string>();
    const std::string where = "presets." + preset.name;
    requireName(preset.name, where, "preset");
    requireKeys(kv.second, where, {"exercise", "params"});
    if (!kv.second["exercise"]) throw ProfileError{where + ".exercise: missing"};
    preset.exercise = text(kv.second["exercise"], where + ".exercise");
    if (const YAML::Node params = kv.second["params"]) {
      if (!params.IsMap()) throw ProfileError{where + ".params: expected a mapping <parameter>: value"};
      for (const auto& pv : params) {
        const std::string k = pv.first.as<std::string>();
        preset.params[k] = scalarJson(pv.second, where + ".params." + k);
      }
    }
    if (preset.exercise == "playback") throw ProfileError{where + ".exercise: playback needs a pattern recorded in the session; it cannot be a preset"};
    std::string err;
    auto pattern = std::make_shared<Pattern>(device.channelCount());
    if (!makeExercise(preset.exercise, preset.params, device, p, pattern, err)) throw ProfileError{where + "." + err};
    p.presets.push_back(std::move(preset));
  }
}

/// plans: {<name>: {steps: [...]}}: each step as an inline plan's (docs/therapy.md "Session plan"), checked by the
/// plan parser against the device and this profile's presets and ranges, so errors read
/// "plans.warmup.steps[1].duration_s: …". Runs after parsePresets (steps may name presets).
void parsePlans(const YAML::Node& node, const TherapyDevice& device, Profile& p) {
  if (!node) return;
  if (!node.IsMap()) throw ProfileError{"plans: expected a mapping <name>: {steps: [...]}"};
  for (const auto& kv : node) {
    NamedPlan named;
    named.name = kv.first.as<std::string>();
    const std::string where = "plans." + named.name;
    requireName(named.name, where, "plan");
    named.plan = yamlToJson(kv.second);
    SessionPlan plan;
    if (std::string err = parsePlan(named.plan, device, p, nullptr, plan, where); !err.empty()) throw ProfileError{err};
    named.step_count = plan.steps.size();
    named.total_s = plan.totalS();
    p.plans.push_back(std::move(named));
  }
}

/// self_training: {allowed: [<preset or exercise>...], max_session_s, effort_scale}.
void parseSelfTraining(const YAML::Node& node, Profile& p) {
  if (!node) return;
  requireKeys(node, "self_training", {"allowed", "max_session_s", "effort_scale"});
  SelfTraining st;
  st.allowed = true;
  const YAML::Node allowed = node["allowed"];
  if (!allowed || !allowed.IsSequence() || allowed.size() == 0) {
    throw ProfileError{"self_training.allowed: expected a non-empty list of presets or exercises"};
  }
  for (std::size_t i = 0; i < allowed.size(); ++i) {
    const std::string key = "self_training.allowed[" + std::to_string(i) + "]";
    const std::string name = text(allowed[i], key);
    const bool preset = std::any_of(p.presets.begin(), p.presets.end(), [&](const Preset& x) { return x.name == name; });
    if (!preset && !isExerciseName(name)) {
      throw ProfileError{key + ": '" + name + "' is neither a preset of this profile nor an exercise"};
    }
    if (name == "playback") throw ProfileError{key + ": playback cannot be run alone (it needs a recorded pattern)"};
    st.steps.insert(name);
  }
  if (!node["max_session_s"]) throw ProfileError{"self_training.max_session_s: missing (how long the patient may train alone)"};
  st.max_session_s = number(node["max_session_s"], "self_training.max_session_s");
  if (!(st.max_session_s > 0.0 && st.max_session_s <= 7200.0)) {
    throw ProfileError{"self_training.max_session_s: must be in (0, 7200] s"};
  }
  if (node["effort_scale"]) {
    st.effort_scale = number(node["effort_scale"], "self_training.effort_scale");
    if (!(st.effort_scale > 0.0 && st.effort_scale <= 1.0)) {
      throw ProfileError{"self_training.effort_scale: must be in (0, 1] (it can only lower the profile's effort_max)"};
    }
  }
  p.self_training = std::move(st);
}

void parse(const YAML::Node& root, Profile& p) {
  requireKeys(root, "", {"version", "patient", "device", "size", "handedness", "kinematics", "rom_deg", "limits",
                          "presets", "plans", "self_training"});
  if (!root["version"]) throw ProfileError{"version: missing (this daemon reads version 1)"};
  if (number(root["version"], "version") != 1.0) throw ProfileError{"version: only version 1 is understood"};
  if (!root["patient"]) throw ProfileError{"patient: missing"};
  p.patient = text(root["patient"], "patient");
  if (!std::regex_match(p.patient, std::regex("[A-Za-z0-9_-]{1,64}"))) {
    throw ProfileError{"patient: '" + p.patient + "' must be 1-64 letters, digits, '-' or '_' (an id, not a name)"};
  }
  if (p.patient == kAnonymousPatient) {
    throw ProfileError{"patient: '" + p.patient + "' is reserved (the records of sessions without a profile)"};
  }
  if (!root["device"]) throw ProfileError{"device: missing"};
  p.device = text(root["device"], "device");
  p.size = root["size"] ? text(root["size"], "size") : "M";
  if (p.size != "S" && p.size != "M" && p.size != "L") throw ProfileError{"size: must be S, M or L"};
  p.handedness = root["handedness"] ? text(root["handedness"], "handedness") : "left";
  if (p.handedness != "left" && p.handedness != "right") throw ProfileError{"handedness: must be left or right"};

  if (const YAML::Node k = root["kinematics"]) {
    if (!k.IsMap()) throw ProfileError{"kinematics: expected a mapping"};
    for (const auto& kv : k) {
      const std::string ch = kv.first.as<std::string>();
      const std::string where = "kinematics." + ch;
      requireKeys(kv.second, where, {"p1_mm", "p2_mm", "p3_mm"});
      std::array<double, 3> l{};
      const char* keys[3] = {"p1_mm", "p2_mm", "p3_mm"};
      for (std::size_t i = 0; i < 3; ++i) {
        if (!kv.second[keys[i]]) throw ProfileError{where + "." + keys[i] + ": missing"};
        l[i] = number(kv.second[keys[i]], where + "." + keys[i]);
      }
      p.kinematics.segment_lengths_mm.emplace_back(ch, l);
    }
  }
  std::string err;
  const auto device = makeTherapyDevice(p.device, p.kinematics, err);
  if (!device) throw ProfileError{err.rfind("kinematics", 0) == 0 ? err : "device: " + err};
  const auto joints = jointNames(*device);
  auto checkJoint = [&](const std::string& name, const std::string& where) {
    if (joints.count(name) == 0) {
      std::string list;
      for (const auto& j : joints) list += (list.empty() ? "" : ", ") + j;
      throw ProfileError{where + ": unknown joint for " + p.device + " (joints: " + list + ")"};
    }
  };
  if (const YAML::Node rom = root["rom_deg"]) {
    if (!rom.IsMap()) throw ProfileError{"rom_deg: expected a mapping joint: [min_deg, max_deg]"};
    for (const auto& kv : rom) {
      const std::string j = kv.first.as<std::string>();
      checkJoint(j, "rom_deg." + j);
      p.rom_rad.emplace_back(j, degRange(kv.second, "rom_deg." + j));
    }
  }
  p.limits = PatientLimits::deviceDefaults(*device);
  if (!root["limits"]) throw ProfileError{"limits: missing (a profile must state the patient's limits)"};
  const YAML::Node lim = root["limits"];
  requireKeys(lim, "limits", {"effort_max", "range_deg"});
  if (!lim["effort_max"]) throw ProfileError{"limits.effort_max: missing"};
  const YAML::Node em = lim["effort_max"];
  const std::string unit = device->effortUnit();
  auto setEffort = [&](std::size_t c, const YAML::Node& n, const std::string& key) {
    const double v = number(n, key);
    if (v <= 0.0 || v > device->effortLimit(c)) {
      std::ostringstream os;
      os << key << ": must be in (0, " << device->effortLimit(c) << "] " << unit << " (the device's own limit)";
      throw ProfileError{os.str()};
    }
    p.limits.effort_max[c] = v;
  };
  if (em.IsScalar()) {
    for (std::size_t c = 0; c < device->channelCount(); ++c) setEffort(c, em, "limits.effort_max");
  } else if (em.IsMap()) {
    if (const YAML::Node def = em["default"]) {
      for (std::size_t c = 0; c < device->channelCount(); ++c) setEffort(c, def, "limits.effort_max.default");
    } else {
      // Every channel must be stated when there is no default: an omitted finger must not silently get 10 N.
      for (std::size_t c = 0; c < device->channelCount(); ++c) {
        if (!em[device->channelName(c)]) {
          throw ProfileError{"limits.effort_max." + device->channelName(c) + ": missing (or give a default)"};
        }
      }
    }
    for (const auto& kv : em) {
      const std::string ch = kv.first.as<std::string>();
      if (ch == "default") continue;
      const int c = device->channelIndex(ch);
      if (c < 0) throw ProfileError{"limits.effort_max." + ch + ": unknown channel for " + p.device};
      setEffort(static_cast<std::size_t>(c), kv.second, "limits.effort_max." + ch);
    }
  } else {
    throw ProfileError{"limits.effort_max: expected a number or a mapping channel: number"};
  }
  if (const YAML::Node rd = lim["range_deg"]) {
    if (!rd.IsMap()) throw ProfileError{"limits.range_deg: expected a mapping joint: [min_deg, max_deg]"};
    for (const auto& kv : rd) {
      const std::string j = kv.first.as<std::string>();
      const std::string key = "limits.range_deg." + j;
      checkJoint(j, key);
      const auto r = degRange(kv.second, key);
      const auto idx = static_cast<std::size_t>(device->jointIndex(j));
      const auto b = device->jointBounds(idx);
      if (r.first < b.first - 1e-9 || r.second > b.second + 1e-9) {
        std::ostringstream os;
        os << key << ": must lie within the joint's range [" << std::lround(b.first / kDegToRad) << ", "
           << std::lround(b.second / kDegToRad) << "] deg";
        throw ProfileError{os.str()};
      }
      p.limits.flexion_min_rad[idx] = r.first;
      p.limits.flexion_max_rad[idx] = r.second;
    }
  }
  parsePresets(root["presets"], *device, p);
  parsePlans(root["plans"], *device, p);
  parseSelfTraining(root["self_training"], p);
}

}  // namespace

PatientLimits PatientLimits::deviceDefaults(const TherapyDevice& d) {
  PatientLimits l;
  l.channel_count = d.channelCount();
  l.joint_count = d.jointCount();
  for (std::size_t c = 0; c < l.channel_count; ++c) l.effort_max[c] = d.effortLimit(c);
  for (std::size_t j = 0; j < l.joint_count; ++j) {
    const auto b = d.jointBounds(j);
    l.flexion_min_rad[j] = b.first;
    l.flexion_max_rad[j] = b.second;
    l.joint_channel[j] = d.jointChannel(j);
  }
  return l;
}

uint32_t PatientLimits::apply(const Observation& obs, std::array<double, kMaxChannels>& effort) const {
  uint32_t limited = 0;
  for (std::size_t c = 0; c < channel_count; ++c) {
    double e = std::isfinite(effort[c]) ? effort[c] : 0.0;
    if (e > effort_max[c]) e = effort_max[c];
    if (e < -effort_max[c]) e = -effort_max[c];
    if (e != effort[c]) limited |= 1u << c;
    effort[c] = e;
  }
  for (std::size_t j = 0; j < joint_count; ++j) {
    if (!obs.joint_valid[j]) continue;
    const std::size_t c = joint_channel[j];
    // Effort < 0 assists flexion: forbidden once the joint is beyond its flexion limit; effort > 0 pushes
    // towards extension: forbidden below its extension limit.
    if (obs.flexion_rad[j] > flexion_max_rad[j] && effort[c] < 0.0) {
      effort[c] = 0.0;
      limited |= 1u << c;
    } else if (obs.flexion_rad[j] < flexion_min_rad[j] && effort[c] > 0.0) {
      effort[c] = 0.0;
      limited |= 1u << c;
    }
  }
  return limited;
}

std::string loadProfileText(const std::string& yaml_text, const std::string& source, Profile& out) {
  Profile p;
  p.source = source;
  try {
    const YAML::Node root = YAML::Load(yaml_text);
    if (!root || root.IsNull()) return source + ": empty profile";
    if (std::string dup = findDuplicateKey(root); !dup.empty()) return source + ": " + dup;
    parse(root, p);
  } catch (const ProfileError& e) {
    return source + ": " + e.message;
  } catch (const YAML::Exception& e) {
    return source + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
  }
  out = std::move(p);
  return {};
}

std::string readProfileFile(const std::string& path, std::string& text) {
  // O_NONBLOCK: opening a FIFO (or a device) must not wait for a writer; O_NOFOLLOW: a symlink planted in the
  // profiles directory cannot make the daemon read a file elsewhere. Only regular files are read, and only
  // up to kMaxProfileBytes, so a request naming a profile is bounded in time and memory.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    if (errno == ELOOP) return path + ": is a symbolic link (profiles are read only from regular files)";
    return path + ": cannot read profile: " + std::strerror(errno);
  }
  struct stat st {};
  std::string err;
  if (::fstat(fd, &st) != 0) {
    err = path + ": cannot read profile: " + std::strerror(errno);
  } else if (!S_ISREG(st.st_mode)) {
    err = path + ": not a regular file (profiles are read only from regular files)";
  } else if (st.st_size > static_cast<off_t>(kMaxProfileBytes)) {
    err = path + ": " + std::to_string(st.st_size) + " bytes, larger than the " + std::to_string(kMaxProfileBytes) +
          "-byte limit of a profile";
  }
  text.clear();
  char buf[8192];
  while (err.empty()) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n == 0) break;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      err = path + ": cannot read profile: " + std::strerror(errno);
    } else if (text.size() + static_cast<std::size_t>(n) > kMaxProfileBytes) {
      err = path + ": larger than the " + std::to_string(kMaxProfileBytes) + "-byte limit of a profile";
    } else {
      text.append(buf, static_cast<std::size_t>(n));
    }
  }
  ::close(fd);
  return err;
}

std::string loadProfileFile(const std::string& path, Profile& out) {
  std::string text;
  if (std::string err = readProfileFile(path, text); !err.empty()) return err;
  Profile p;
  if (std::string err = loadProfileText(text, path, p); !err.empty()) return err;
  // The file name is the patient id (<patient>.yaml): a profile holding another patient's id is refused, so no
  // session can record one patient under another's name.
  const std::string file = path.substr(path.rfind('/') + 1);
  const auto dot = file.rfind('.');
  const std::string stem = dot == std::string::npos ? file : file.substr(0, dot);
  if (stem != p.patient) {
    return path + ": patient: '" + p.patient + "' does not match the file name '" + file + "' (the profile of patient '" +
           p.patient + "' must be " + p.patient + ".yaml)";
  }
  out = std::move(p);
  return {};
}

}  // namespace phalanx::host::therapy
