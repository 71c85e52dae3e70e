#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/glove/scene.h"
#include "phalanx/host/pen/pen_bench.h"
#include "phalanx/host/pen/pen_controller.h"
#include "phalanx/host/pen/pen_scene.h"
#include "phalanx/host/yaml_keys.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::benchrun {
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

void onlyKeys(const YAML::Node& m, const std::string& where, const std::set<std::string>& allowed) {
  if (!m.IsMap()) throw Bad{where + ": expected a mapping"};
  for (const auto& kv : m) {
    const std::string key = kv.first.as<std::string>();
    if (allowed.count(key) == 0) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw Bad{(where.empty() ? "" : where + ".") + key + ": unknown key (allowed: " + list + ")"};
    }
  }
}

double number(const YAML::Node& n, const std::string& key, double lo, double hi) {
  const double v = get<double>(n, key, "number");
  if (!std::isfinite(v) || v < lo || v > hi) {
    throw Bad{key + ": " + n.Scalar() + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]"};
  }
  return v;
}

PairLimits limitsOf(const YAML::Node& n, const std::string& where) {
  PairLimits l;
  onlyKeys(n, where, {"rmse_max", "nrmse_percent_max", "fidelity_percent_min", "bandwidth_hz_min"});
  if (n["rmse_max"]) l.rmse_max = number(n["rmse_max"], where + ".rmse_max", 0.0, 1e6);
  if (n["nrmse_percent_max"]) l.nrmse_percent_max = number(n["nrmse_percent_max"], where + ".nrmse_percent_max", 0.0, 1e6);
  if (n["fidelity_percent_min"]) {
    l.fidelity_percent_min = number(n["fidelity_percent_min"], where + ".fidelity_percent_min", -1e6, 100.0);
  }
  if (n["bandwidth_hz_min"]) l.bandwidth_hz_min = number(n["bandwidth_hz_min"], where + ".bandwidth_hz_min", 0.0, 500.0);
  return l;
}

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

constexpr const char* kSafetyKeys = "effort_max, instrument_silence_ms, disagreement_max, disagreement_ms";

/// A device string the daemon accepts and, for sim:, the bench device it is ("" for a real device); "" or the problem.
std::string benchDevice(const std::string& device, std::string& sim_type) {
  sim_type.clear();
  if (device.rfind("sim:", 0) == 0) {
    sim_type = device.substr(4);
    if (sim_type == "sea_rig" || sim_type == "glove5" || sim_type == "pantograph") return {};
    return "'" + device + "' is not a bench device (sim:sea_rig, sim:glove5, sim:pantograph, or a real one: serial:PATH, "
           "can:IF[:node][@mapping], usb:VID:PID with device_type)";
  }
  if (device.rfind("serial:", 0) == 0 || device.rfind("can:", 0) == 0 || device.rfind("usb:", 0) == 0) return {};
  return "'" + device + "' is not a device (sim:sea_rig, sim:glove5, sim:pantograph, serial:PATH, can:IF[:node][@mapping] or usb:VID:PID)";
}

/// `device:` (any device string the daemon accepts) and what the steps run on (`device_type:`, implied by sim:).
void deviceOf(const YAML::Node& root, Plan& p) {
  std::string sim_type;
  if (std::string err = benchDevice(p.device, sim_type); !err.empty()) throw Bad{"device: " + err};
  const bool sim = !sim_type.empty();
  if (sim) p.device_type = sim_type;
  if (root["device_type"]) {
    const std::string t = get<std::string>(root["device_type"], "device_type", "string");
    if (t != "sea_rig" && t != "glove5" && t != "pantograph") {
      throw Bad{"device_type: '" + t + "' is not sea_rig, glove5 or pantograph"};
    }
    if (sim && t != p.device_type) throw Bad{"device_type: " + t + " contradicts device " + p.device};
    p.device_type = t;
  } else if (!sim) {
    throw Bad{"device_type: required for " + p.device + " (sea_rig, glove5 or pantograph: what the steps run on)"};
  }
}

/// The plan's `safety:` block: every key required (no silent default stands between a plan and the motors).
Safety safetyOf(const YAML::Node& n, const std::string& device, const std::string& device_type) {
  onlyKeys(n, "safety", {"effort_max", "instrument_silence_ms", "disagreement_max", "disagreement_ms"});
  for (const char* k : {"effort_max", "instrument_silence_ms", "disagreement_max", "disagreement_ms"}) {
    if (!n[k]) throw Bad{std::string("safety.") + k + ": required (safety needs " + kSafetyKeys + ")"};
  }
  Safety s;
  s.effort_max = number(n["effort_max"], "safety.effort_max", 0.0, 1e3);
  const double device_max = deviceEffortLimit(device_type);
  // Compared in the limit's own precision (float): 2.1 is the pantograph's limit, not 2.0999999.
  if (static_cast<float>(s.effort_max) > static_cast<float>(device_max)) {
    throw Bad{"safety.effort_max: " + fmt(s.effort_max) + " exceeds the device's own limit " + fmt(device_max) + " (" +
              device + ", the limits stage's setpoint limit)"};
  }
  // 1 ms: one rig tick, the finest the runner can tell; 60 s: longer than any useful silence on a bench.
  s.instrument_silence_ms = number(n["instrument_silence_ms"], "safety.instrument_silence_ms", 1.0, 60000.0);
  s.disagreement_max = number(n["disagreement_max"], "safety.disagreement_max", 0.0, 1e6);
  s.disagreement_ms = number(n["disagreement_ms"], "safety.disagreement_ms", 1.0, 60000.0);
  return s;
}

/// The plan's top-level keys other than safety and steps.
void topLevelOf(const YAML::Node& root, Plan& p) {
  onlyKeys(root, "", {"version", "device", "device_type", "sim_instrument", "sim_instrument_delay_ms", "controller", "seed", "noise", "report",
                      "instrument", "max_stale_percent", "safety", "steps"});
  if (root["version"] && get<int>(root["version"], "version", "integer") != 1) {
    throw Bad{"version: only version 1 is understood"};
  }
  if (root["device"]) p.device = get<std::string>(root["device"], "device", "string");
  deviceOf(root, p);
  if (root["sim_instrument"]) {
    p.sim_instrument = get<bool>(root["sim_instrument"], "sim_instrument", "boolean");
    if (p.device.rfind("sim:", 0) != 0) throw Bad{"sim_instrument: only for sim: devices (a real device's instrument is the instrument: block)"};
  }
  if (root["sim_instrument_delay_ms"]) {
    p.sim_instrument_delay_ms = number(root["sim_instrument_delay_ms"], "sim_instrument_delay_ms", 0.0, 1000.0);
    if (p.device.rfind("sim:", 0) != 0 || !p.sim_instrument) {
      throw Bad{"sim_instrument_delay_ms: only for the simulated instrument of a sim: device"};
    }
  }
  if (root["controller"]) p.controller = get<std::string>(root["controller"], "controller", "string");
  if (p.controller != "ours" && p.controller != "paper") throw Bad{"controller: must be ours or paper"};
  if (root["seed"]) p.seed = get<uint32_t>(root["seed"], "seed", "non-negative integer");
  if (root["noise"]) p.noise = get<bool>(root["noise"], "noise", "boolean");
  if (root["report"]) p.report = get<std::string>(root["report"], "report", "path");
  if (root["max_stale_percent"]) p.max_stale_percent = number(root["max_stale_percent"], "max_stale_percent", 0.0, 100.0);
  // The simulated amplifier (lockstep's, or firmware-sim's in real time) opens its own pty: no path to give.
  if (p.device.rfind("sim:", 0) == 0 && p.sim_instrument) p.instrument.serial_device = "(the simulated amplifier's pty)";
  if (root["instrument"]) {
    if (std::string err = modbus::loadInstrumentConfig(root["instrument"], "instrument", p.instrument); !err.empty()) {
      throw Bad{err};
    }
  }
}

/// A step's kind (which must run on the plan's device) and the defaults that follow from it.
Step stepKindOf(const YAML::Node& s, const std::string& w, const Plan& p) {
  Step st;
  if (!s["kind"]) throw Bad{w + ".kind: required (sea-rig-sine, sea-rig-chirp, glove-free-motion, glove-grasp, pen-wall)"};
  st.kind = get<std::string>(s["kind"], w + ".kind", "string");
  const bool sea = isSeaStep(st);
  const bool pen = st.kind == "pen-wall";
  if (!sea && !pen && !isGloveStep(st)) {
    throw Bad{w + ".kind: '" + st.kind + "' is not sea-rig-sine, sea-rig-chirp, glove-free-motion, glove-grasp or pen-wall"};
  }
  const std::string runs_on = sea ? "sea_rig" : (pen ? "pantograph" : "glove5");
  if (runs_on != p.device_type) throw Bad{w + ".kind: " + st.kind + " does not run on " + p.device + " (" + p.device_type + ")"};
  st.name = s["name"] ? get<std::string>(s["name"], w + ".name", "string") : st.kind;
  if (st.kind == "sea-rig-chirp") st.seconds = 20.0;
  if (st.kind == "glove-grasp") {
    // As `phalanx bench glove-grasp`: reach and squeeze for 2 s, scored over the last second's steady contact.
    st.seconds = 3.0;
    st.settle_s = 2.0;
  }
  if (pen) {
    if (s["stiffness_N_per_cm"]) {
      // 64 N/cm: the top of `phalanx bench pen-wall --sweep` (docs/pen-plant.md).
      st.stiffness_N_per_cm = number(s["stiffness_N_per_cm"], w + ".stiffness_N_per_cm", 0.1, 64.0);
    }
    if (s["braking"]) st.braking = get<bool>(s["braking"], w + ".braking", "boolean");
    // Default: the whole wall-bench schedule (presses, corners, hands-off impact); a shorter step stops early.
    pen::PenWallBenchOptions o;
    o.stiffness_N_per_cm = st.stiffness_N_per_cm;
    double total = 0.0;
    for (const pen::PenWallPhase& ph : pen::wallBenchSchedule(pen::wallBenchScene(o))) total += ph.move_s + ph.hold_s;
    st.seconds = total;
    st.settle_s = 0.5;  // the first free hold
  } else if (s["stiffness_N_per_cm"] || s["braking"]) {
    throw Bad{w + ": stiffness_N_per_cm and braking are pen-wall keys"};
  }
  return st;
}

/// A step's timing, excitation, finger and lockstep instrument faults.
void stepNumbersOf(const YAML::Node& s, const std::string& w, Step& st) {
  if (s["seconds"]) st.seconds = number(s["seconds"], w + ".seconds", 0.5, 600.0);
  if (s["settle_s"]) st.settle_s = number(s["settle_s"], w + ".settle_s", 0.0, 60.0);
  if (st.kind == "sea-rig-chirp") st.settle_s = s["settle_s"] ? st.settle_s : 0.0;
  if (st.settle_s >= st.seconds) throw Bad{w + ".settle_s: must be shorter than seconds"};
  // 0.4 N·m: the range phalanx bench sea-rig-sine accepts (docs/bench-runner.md, constants).
  if (s["peak_Nm"]) st.peak_Nm = number(s["peak_Nm"], w + ".peak_Nm", 0.001, 0.4);
  if (s["hz"]) st.hz = number(s["hz"], w + ".hz", 0.01, 50.0);
  if (s["amplitude_Nm"]) st.amplitude_Nm = number(s["amplitude_Nm"], w + ".amplitude_Nm", 0.001, 0.4);
  if (s["f0_hz"]) st.f0_hz = number(s["f0_hz"], w + ".f0_hz", 0.0, 50.0);
  if (s["fmax_hz"]) st.fmax_hz = number(s["fmax_hz"], w + ".fmax_hz", 0.5, 200.0);
  if (st.kind == "sea-rig-chirp" && st.fmax_hz <= st.f0_hz + 1.0) throw Bad{w + ".fmax_hz: must exceed f0_hz by 1 Hz or more"};
  if (s["finger"]) st.finger = static_cast<int>(number(s["finger"], w + ".finger", 0.0, 4.0));
  if (s["instrument_hang_at_s"]) {
    st.instrument_hang_at_s = number(s["instrument_hang_at_s"], w + ".instrument_hang_at_s", 0.0, 600.0);
  }
  if (s["instrument_lie_at_s"]) st.instrument_lie_at_s = number(s["instrument_lie_at_s"], w + ".instrument_lie_at_s", 0.0, 600.0);
  if (s["instrument_lie_gain"]) st.instrument_lie_gain = number(s["instrument_lie_gain"], w + ".instrument_lie_gain", -1e3, 1e3);
  if (s["instrument_lie_offset"]) {
    st.instrument_lie_offset = number(s["instrument_lie_offset"], w + ".instrument_lie_offset", -1e6, 1e6);
  }
  if ((s["instrument_lie_gain"] || s["instrument_lie_offset"]) && !s["instrument_lie_at_s"]) {
    throw Bad{w + ".instrument_lie_at_s: required with instrument_lie_gain / instrument_lie_offset"};
  }
}

/// A step's limits: the pair metrics every kind has, pen-wall's own, and which metric needs which kind.
void stepLimitsOf(const YAML::Node& s, const std::string& w, Step& st) {
  const bool pen = st.kind == "pen-wall";
  if (const YAML::Node l = s["limits"]) {
    if (pen) {
      onlyKeys(l, w + ".limits", {"estimate_vs_instrument", "setpoint_vs_instrument", "penetration_mm_max",
                                  "wall_energy_generated_mJ_max"});
      if (l["penetration_mm_max"]) st.penetration_mm_max = number(l["penetration_mm_max"], w + ".limits.penetration_mm_max", 0.0, 1e3);
      if (l["wall_energy_generated_mJ_max"]) {
        st.wall_energy_generated_mJ_max =
            number(l["wall_energy_generated_mJ_max"], w + ".limits.wall_energy_generated_mJ_max", -1e6, 1e6);
      }
    } else {
      onlyKeys(l, w + ".limits", {"estimate_vs_instrument", "setpoint_vs_instrument"});
    }
    if (l["estimate_vs_instrument"]) {
      st.estimate_vs_instrument = limitsOf(l["estimate_vs_instrument"], w + ".limits.estimate_vs_instrument");
    }
    if (l["setpoint_vs_instrument"]) {
      st.setpoint_vs_instrument = limitsOf(l["setpoint_vs_instrument"], w + ".limits.setpoint_vs_instrument");
    }
  }
  if (st.kind != "sea-rig-chirp" &&
      (st.estimate_vs_instrument.bandwidth_hz_min || st.setpoint_vs_instrument.bandwidth_hz_min)) {
    throw Bad{w + ".limits: bandwidth_hz_min needs a sea-rig-chirp step"};
  }
  if (!isSeaStep(st) && (st.estimate_vs_instrument.fidelity_percent_min || st.setpoint_vs_instrument.fidelity_percent_min)) {
    throw Bad{w + ".limits: fidelity_percent_min (eq 15, a torque trajectory's tracking) needs a sea-rig-sine or "
                  "sea-rig-chirp step"};
  }
}

void apply(const YAML::Node& root, Plan& p) {
  topLevelOf(root, p);
  const bool have_safety = static_cast<bool>(root["safety"]);
  if (have_safety) p.safety = safetyOf(root["safety"], p.device, p.device_type);
  const YAML::Node steps = root["steps"];
  if (!steps || !steps.IsSequence() || steps.size() == 0) throw Bad{"steps: expected a non-empty list"};
  for (size_t i = 0; i < steps.size(); ++i) {
    const std::string w = "steps[" + std::to_string(i) + "]";
    const YAML::Node s = steps[i];
    onlyKeys(s, w, {"name", "kind", "seconds", "settle_s", "peak_Nm", "hz", "amplitude_Nm", "f0_hz", "fmax_hz", "finger",
                    "stiffness_N_per_cm", "braking", "instrument_hang_at_s", "instrument_lie_at_s", "instrument_lie_gain",
                    "instrument_lie_offset", "limits"});
    Step st = stepKindOf(s, w, p);
    stepNumbersOf(s, w, st);
    stepLimitsOf(s, w, st);
    if (have_safety) {
      const double e = stepEffortMax(st);
      if (e > p.safety.effort_max) {
        const std::string key = st.kind == "sea-rig-sine" ? ".peak_Nm" : (st.kind == "sea-rig-chirp" ? ".amplitude_Nm" : ".kind");
        throw Bad{w + key + ": commands up to " + fmt(e) + (st.kind == "pen-wall" ? " (pen-wall: the force split's joint torque limit)" : "") +
                  ", beyond safety.effort_max " + fmt(p.safety.effort_max)};
      }
    }
    p.steps.push_back(st);
  }
  if (!have_safety) {
    throw Bad{std::string("safety: required (") + kSafetyKeys + "; the device's own effort limit is " +
              fmt(deviceEffortLimit(p.device_type)) + "; docs/bench-runner.md \"Safety\")"};
  }
}

}  // namespace

double deviceEffortLimit(const std::string& device_type) {
  const std::string t = device_type.rfind("sim:", 0) == 0 ? device_type.substr(4) : device_type;
  if (t == "sea_rig") return protocol::kSeaFingerLayout.setpoint_limit;
  if (t == "glove5") return protocol::kGlove5Layout.setpoint_limit;
  if (t == "pantograph") return protocol::kPantographLayout.setpoint_limit;
  return 0.0;
}

double stepEffortMax(const Step& step) {
  if (step.kind == "sea-rig-sine") return step.peak_Nm;
  if (step.kind == "sea-rig-chirp") return step.amplitude_Nm;
  if (step.kind == "pen-wall") {
    double m = 0.0;
    for (double t : pen::PenControllerConfig{}.split.torque_limit_Nm) m = std::max(m, t);
    return m;
  }
  if (step.kind == "glove-grasp") return glove::SceneConfig{}.max_force_N;  // the rendered contact force's clamp
  return 0.0;  // glove-free-motion: transparent mode commands 0 N
}

bool isGloveStep(const Step& step) { return step.kind == "glove-free-motion" || step.kind == "glove-grasp"; }
bool isSeaStep(const Step& step) { return step.kind == "sea-rig-sine" || step.kind == "sea-rig-chirp"; }

std::string setPlanDevice(Plan& plan, const std::string& device) {
  std::string sim_type;
  if (std::string err = benchDevice(device, sim_type); !err.empty()) return "--device: " + err;
  if (!sim_type.empty() && sim_type != plan.device_type) {
    return "--device: " + device + " is not a " + plan.device_type + " (the plan's steps run on " + plan.device_type + ")";
  }
  plan.device = device;
  return {};
}

std::string loadPlanText(const std::string& yaml, const std::string& source, Plan& plan) {
  Plan p;
  p.source = source;
  // The simulated amplifier's default map: int32 counts at 10 µN·m per count, input register 0.
  p.instrument.type = "int32";
  p.instrument.scale = 1e-5;
  try {
    const YAML::Node root = YAML::Load(yaml);
    if (std::string dup = findDuplicateKey(root); !dup.empty()) throw Bad{dup};
    apply(root, p);
  } catch (const Bad& b) {
    return source + ": " + b.what;
  } catch (const YAML::Exception& e) {
    return source + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg;
  }
  plan = p;
  return {};
}

std::string loadPlanFile(const std::string& path, Plan& plan) {
  std::ifstream in(path);
  if (!in) return path + ": cannot read the plan";
  std::stringstream ss;
  ss << in.rdbuf();
  return loadPlanText(ss.str(), path, plan);
}

}  // namespace phalanx::host::benchrun
