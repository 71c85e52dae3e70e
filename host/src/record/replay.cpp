#include "phalanx/host/record/replay.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "phalanx/host/command_limits.h"
#include "phalanx/host/controller.h"
#include "phalanx/host/pen/pen_controller.h"
#include "phalanx/host/record/mcap_reader.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host::record {
namespace {

constexpr uint8_t kSourceController = 0, kSourceStop = 3;  // CommandExtras::source

std::string fileText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// The files a recording embeds (geometry, subject), written to a private directory for makeController.
class EmbeddedFiles {
 public:
  ~EmbeddedFiles() {
    for (const auto& f : files_) ::unlink(f.c_str());
    if (!dir_.empty()) ::rmdir(dir_.c_str());
  }
  std::string put(const std::string& name, const std::string& text, std::string& path) {
    if (dir_.empty()) {
      char tmpl[] = "/tmp/phalanx-replay-XXXXXX";
      if (::mkdtemp(tmpl) == nullptr) return std::string("cannot create a temporary directory: ") + std::strerror(errno);
      dir_ = tmpl;
    }
    path = dir_ + "/" + name + ".yaml";
    std::ofstream f(path, std::ios::binary);
    f << text;
    files_.push_back(path);
    return f ? std::string() : "cannot write " + path;
  }

 private:
  std::string dir_;
  std::vector<std::string> files_;
};

std::string applySet(const std::string& kv, RunOptions& opt) {
  const auto eq = kv.find('=');
  const std::string key = kv.substr(0, eq), value = eq == std::string::npos ? "" : kv.substr(eq + 1);
  if (eq == std::string::npos || value.empty()) return "--set " + kv + ": expected KEY=VALUE";
  try {
    if (key == "mode") opt.mode = value;
    else if (key == "scene") opt.scene = value;
    else if (key == "pen_wall_stiffness_N_per_cm") opt.pen_wall_stiffness_N_per_cm = std::stod(value);
    else if (key == "pen_floor_mm") opt.pen_floor_mm = std::stod(value);
    else return "--set " + key + ": not a replay setting (mode, scene, pen_wall_stiffness_N_per_cm, pen_floor_mm)";
  } catch (const std::exception&) {
    return "--set " + kv + ": not a number";
  }
  return {};
}

/// RunOptions of the recorded session from the header's "replay" object, then the --set changes.
std::string optionsFrom(const nlohmann::json& r, const ReplayOptions& ro, EmbeddedFiles& files, RunOptions& opt) {
  try {
    opt.rate_hz = r.at("rate_hz").get<unsigned>();
    opt.mode = r.at("mode").get<std::string>();
    opt.scene = r.at("scene").get<std::string>();
    opt.pen_wall_stiffness_N_per_cm = r.at("pen_wall_stiffness_N_per_cm").get<double>();
    opt.pen_floor_mm = r.at("pen_floor_mm").get<double>();
    std::string err;
    for (const auto& [finger, text] : r.at("glove_geometry").items()) {
      if (err = files.put("glove-" + finger, text.get<std::string>(), opt.glove_geometry[finger]); !err.empty()) return err;
    }
    if (const std::string t = r.at("pen_geometry").get<std::string>(); !t.empty()) {
      if (err = files.put("pen", t, opt.pen_geometry); !err.empty()) return err;
    }
    if (const std::string t = r.at("sea_subject").get<std::string>(); !t.empty()) {
      if (err = files.put("subject", t, opt.sea_subject); !err.empty()) return err;
    }
  } catch (const nlohmann::json::exception& e) {
    return std::string("the recording's replay configuration is incomplete: ") + e.what();
  }
  if (opt.rate_hz == 0) return "the recording's replay configuration has rate_hz 0";
  for (const auto& kv : ro.set) {
    if (std::string err = applySet(kv, opt); !err.empty()) return err;
  }
  return {};
}

/// One recorded cycle as the loop saw it.
struct Recorded {
  double t_s = 0.0;
  TelemetryFrame tel;
  uint8_t mode = 0, source = 0;
  std::array<float, protocol::kMaxSetpoints> setpoint{};
  std::array<uint16_t, protocol::kMaxSetpoints> gain{};
};

struct Names {
  std::vector<std::string> samples, setpoints;
};

float f32(const nlohmann::json& v) {
  return v.is_null() ? std::nanf("") : static_cast<float>(v.get<double>());
}

std::string parseCycle(const std::string& tel_text, const std::string& cmd_text, const Names& n, Recorded& out) {
  try {
    const nlohmann::json tel = nlohmann::json::parse(tel_text), cmd = nlohmann::json::parse(cmd_text);
    out.t_s = tel.at("t_s").get<double>();
    if (cmd.at("t_s").get<double>() != out.t_s) return "its telemetry and command messages are of different cycles";
    out.tel.device_time_us = tel.at("device_time_us").get<uint64_t>();
    out.tel.seq = tel.at("seq").get<uint16_t>();
    out.tel.cmd_seq_echo = tel.at("cmd_seq_echo").get<uint16_t>();
    out.tel.mode = static_cast<protocol::Mode>(tel.at("mode").get<uint8_t>());
    out.tel.state_flags = tel.at("state_flags").get<uint8_t>();
    out.tel.fault_bits = tel.at("fault_bits").get<uint16_t>();
    out.tel.sample_count = static_cast<uint8_t>(n.samples.size());
    for (std::size_t i = 0; i < n.samples.size(); ++i) out.tel.value[i] = f32(tel.at(n.samples[i]));
    out.mode = cmd.at("mode").get<uint8_t>();
    out.source = cmd.at("source").get<uint8_t>();
    const auto& gain = cmd.at("gain_permille");
    if (!gain.is_array() || gain.size() != n.setpoints.size()) return "gain_permille has not one value per setpoint";
    for (std::size_t i = 0; i < n.setpoints.size(); ++i) {
      out.setpoint[i] = f32(cmd.at(n.setpoints[i]));
      out.gain[i] = gain[i].get<uint16_t>();
    }
  } catch (const nlohmann::json::exception& e) {
    return e.what();
  }
  return {};
}

uint32_t bitsOf(float f) {
  uint32_t u = 0;
  std::memcpy(&u, &f, 4);
  return u;
}

/// Bit-for-bit comparison of the replayed command with the recorded one; the first mismatching cycle's
/// differences (every channel of it) are kept.
void compare(const Recorded& rec, const protocol::Command& cmd, uint64_t cycle, const Names& n, ReplayResult& r) {
  std::vector<ReplayMismatch> d;
  if (static_cast<uint8_t>(cmd.mode) != rec.mode) d.push_back({cycle, rec.t_s, "mode", double(rec.mode), double(cmd.mode), 0, 0});
  for (std::size_t i = 0; i < n.setpoints.size(); ++i) {
    const uint32_t want = bitsOf(rec.setpoint[i]), got = bitsOf(cmd.setpoint[i]);
    if (want != got) d.push_back({cycle, rec.t_s, n.setpoints[i], rec.setpoint[i], cmd.setpoint[i], want, got});
    if (cmd.gain_scale_permille[i] != rec.gain[i]) {
      d.push_back({cycle, rec.t_s, "gain_permille[" + n.setpoints[i] + "]", double(rec.gain[i]),
                   double(cmd.gain_scale_permille[i]), 0, 0});
    }
  }
  if (d.empty()) return;
  ++r.mismatched_cycles;
  r.mismatched_values += d.size();
  if (r.first.empty()) r.first = std::move(d);
}

/// The session's header (metadata phalanx_session) and the ids of its telemetry and command channels.
std::string sessionOf(const McapContents& m, const std::string& path, nlohmann::json& header, uint16_t& tel,
                      uint16_t& cmd) {
  const auto meta = m.metadata.find("phalanx_session");
  if (meta == m.metadata.end() || meta->second.count("header") == 0) {
    return path + ": not a Phalanx recording (no phalanx_session metadata)";
  }
  header = nlohmann::json::parse(meta->second.at("header"), nullptr, false);
  if (header.is_discarded() || !header.is_object()) return path + ": the phalanx_session header is not JSON";
  if (!header.contains("replay")) {
    return path + ": cannot be replayed: it holds no replay configuration (an MCAP export of a session record, or "
                  "recorded before replay existed); record it with `phalanxd --record FILE.mcap`";
  }
  const int v = header["replay"].value("format_version", 0);
  if (v < 1 || v > kReplayFormatVersion) {
    return path + ": replay configuration version " + std::to_string(v) + " (this build reads 1.." +
           std::to_string(kReplayFormatVersion) + ")";
  }
  int found = 0;
  for (const auto& [id, topic] : m.topics) {
    if (topic == "/phalanx/telemetry") tel = id, found |= 1;
    if (topic == "/phalanx/command") cmd = id, found |= 2;
  }
  return found == 3 ? std::string() : path + ": no /phalanx/telemetry or /phalanx/command channel";
}

std::string namesOf(const nlohmann::json& h, const protocol::DeviceLayout& l, Names& n) {
  try {
    n.samples = h.at("samples").get<std::vector<std::string>>();
    n.setpoints = h.at("setpoints").get<std::vector<std::string>>();
  } catch (const nlohmann::json::exception& e) {
    return std::string("the header's column names: ") + e.what();
  }
  if (n.samples.size() != l.sample_count || n.setpoints.size() != l.setpoint_count) {
    return "the header's column names do not fit a " + std::string(l.name);
  }
  return {};
}

/// The loop's cycle, offline: the command source as recorded, the controller, then the one limits stage.
void replayCycle(Controller& ctl, CommandLimits& limits, const Recorded& rec, double dt_s, protocol::Command& cmd) {
  if (rec.source == kSourceStop) {
    makeSafe(cmd);  // the daemon runs no controller while stopped
  } else {
    ctl.update(rec.tel, rec.t_s, dt_s, cmd);
  }
  limits.apply(rec.tel, cmd);
}

}  // namespace

const protocol::DeviceLayout* layoutNamed(const std::string& name) {
  for (auto t : {protocol::DeviceType::kGlove5, protocol::DeviceType::kSeaFinger, protocol::DeviceType::kPantograph}) {
    const protocol::DeviceLayout* l = protocol::layoutFor(t);
    if (l != nullptr && name == l->name) return l;
  }
  return nullptr;
}

const phalanx::pen::Model<double>* penModelOf(const Controller& controller) {
  const auto* p = dynamic_cast<const pen::PenController*>(&controller);
  return p != nullptr ? &p->model() : nullptr;
}

nlohmann::json replayConfig(const RunOptions& opt, const std::string& controller, bool patient_limits) {
  nlohmann::json glove = nlohmann::json::object();
  for (const auto& [finger, path] : opt.glove_geometry) glove[finger] = fileText(path);
  return {{"format_version", kReplayFormatVersion},
          {"controller", controller},
          {"patient_limits", patient_limits},
          {"rate_hz", opt.rate_hz},
          {"mode", opt.mode},
          {"scene", opt.scene},
          {"pen_wall_stiffness_N_per_cm", opt.pen_wall_stiffness_N_per_cm},
          {"pen_floor_mm", opt.pen_floor_mm},
          {"glove_geometry", glove},
          {"pen_geometry", opt.pen_geometry.empty() ? "" : fileText(opt.pen_geometry)},
          {"sea_subject", opt.sea_subject.empty() ? "" : fileText(opt.sea_subject)},
          {"compiler", __VERSION__},
          {"scenario", opt.scenario},
          {"seed", opt.seed}};
}

nlohmann::json ReplayResult::toJson() const {
  nlohmann::json first_j = nlohmann::json::array();
  for (const auto& m : first) {
    first_j.push_back({{"cycle", m.cycle}, {"t_s", m.t_s}, {"channel", m.channel}, {"recorded", m.recorded},
                       {"replayed", m.replayed}, {"recorded_bits", m.recorded_bits}, {"replayed_bits", m.replayed_bits}});
  }
  return {{"file", file},         {"device", device},     {"controller", controller},
          {"cycles", cycles},     {"compared", compared}, {"external_cycles", external},
          {"mismatched_cycles", mismatched_cycles},       {"mismatched_values", mismatched_values},
          {"first_mismatch", first_j}, {"file_complete", file_complete}};
}

namespace {

/// What the replay runs: the device, its column names, the controller the recorded configuration makes.
struct Setup {
  const protocol::DeviceLayout* layout = nullptr;
  Names names;
  std::unique_ptr<Controller> controller;
  double dt_s = 0.0;
};

std::string setUp(const nlohmann::json& header, const ReplayOptions& options, EmbeddedFiles& files, Setup& s) {
  const nlohmann::json& rc = header["replay"];
  if (rc.value("patient_limits", false) || rc.value("controller", "") == "therapy") {
    return "recorded with a therapy exercise or patient limits; replaying those is not supported";
  }
  const std::string device = header.value("device", "");
  s.layout = layoutNamed(device);
  if (s.layout == nullptr) return "unknown device '" + device + "'";
  if (std::string err = namesOf(header, *s.layout, s.names); !err.empty()) return err;
  RunOptions opt;
  if (std::string err = optionsFrom(rc, options, files, opt); !err.empty()) return err;
  std::string err;
  s.controller = makeController(*s.layout, opt, err);
  if (!s.controller) return "the recorded controller cannot be built: " + err;
  s.dt_s = 1.0 / opt.rate_hz;  // the daemon's dt
  return {};
}

/// Every recorded cycle through the controller and the limits stage, compared with the recorded command.
std::string runCycles(const McapContents& m, uint16_t ch_tel, uint16_t ch_cmd, Setup& s, ReplayResult& result,
                      const ReplayObserver& observer) {
  std::vector<const McapMessage*> tel, com;
  for (const McapMessage& msg : m.messages) {
    if (msg.channel == ch_tel) tel.push_back(&msg);
    if (msg.channel == ch_cmd) com.push_back(&msg);
  }
  if (tel.size() != com.size()) return "telemetry and command messages do not pair up";
  CommandLimits limits(*s.layout);
  protocol::Command cmd;
  makeSafe(cmd);  // as the daemon's command before its first cycle
  cmd.channel_count = s.layout->setpoint_count;
  for (std::size_t i = 0; i < tel.size(); ++i) {
    Recorded rec;
    if (std::string err = parseCycle(tel[i]->data, com[i]->data, s.names, rec); !err.empty()) {
      return "cycle " + std::to_string(i) + ": " + err;
    }
    replayCycle(*s.controller, limits, rec, s.dt_s, cmd);
    if (observer) observer(*s.layout, ReplayedCycle{i, rec.t_s, rec.tel, cmd});
    ++result.cycles;
    if (rec.source != kSourceController && rec.source != kSourceStop) {
      ++result.external;  // a client's command: the controller ran (its state follows), nothing to compare
      continue;
    }
    ++result.compared;
    compare(rec, cmd, i, s.names, result);
  }
  return {};
}

}  // namespace

std::string replayRecording(const std::string& path, const ReplayOptions& options, ReplayResult& result,
                            const ReplayObserver& observer) {
  result = ReplayResult{};
  result.file = path;
  McapContents m;
  if (std::string err = readMcap(path, m); !err.empty()) return err;
  result.file_complete = m.complete;
  nlohmann::json header;
  uint16_t ch_tel = 0, ch_cmd = 0;
  if (std::string err = sessionOf(m, path, header, ch_tel, ch_cmd); !err.empty()) return err;
  EmbeddedFiles files;
  Setup s;
  if (std::string err = setUp(header, options, files, s); !err.empty()) return path + ": " + err;
  result.device = s.layout->name;
  result.controller = s.controller->name();
  if (std::string err = runCycles(m, ch_tel, ch_cmd, s, result, observer); !err.empty()) return path + ": " + err;
  return {};
}

}  // namespace phalanx::host::record
