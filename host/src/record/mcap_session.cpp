#include "phalanx/host/record/mcap_session.h"

#include <cmath>
#include <cstdio>
#include <ctime>

#include "phalanx/host/record/output_file.h"
#include "phalanx/host/record/pen_channels.h"
#include "phalanx/host/record/ros2_msgs.h"
#include "phalanx/host/session.h"
#include "phalanx/host/therapy/device.h"

namespace phalanx::host::record {
namespace {

/// The unit a column name ends with (the project's naming: alpha1_thumb_rad, force_thumb_N, sea_torque_mcp_Nm).
std::string unitOf(const std::string& name) {
  auto ends = [&](const char* s) {
    const std::string suf = s;
    return name.size() > suf.size() && name.compare(name.size() - suf.size(), suf.size(), suf) == 0;
  };
  if (ends("_rad")) return "rad";
  if (ends("_deg")) return "deg";
  if (ends("_Nm")) return "N·m";
  if (ends("_N")) return "N";
  if (ends("_A")) return "A";
  if (ends("_s")) return "s";
  if (name.rfind("duty", 0) == 0) return "PWM duty fraction (−1…1)";
  return "see docs/records.md";
}

nlohmann::json numberSchema(const std::string& title, const std::vector<std::pair<std::string, std::string>>& fixed,
                            const std::vector<std::string>& names) {
  nlohmann::json props = nlohmann::json::object();
  for (const auto& [n, d] : fixed) props[n] = {{"type", "number"}, {"description", d}};
  for (const auto& n : names) props[n] = {{"type", {"number", "null"}}, {"description", unitOf(n)}};
  return {{"title", title}, {"type", "object"}, {"properties", props}};
}

void putNumber(std::string& out, const char* key, double v, bool as_float) {
  char buf[64];
  out += '"';
  out += key;
  out += "\":";
  if (!std::isfinite(v)) {
    out += "null";
    return;
  }
  // %.9g round-trips a float exactly; %.17g a double. A negative zero is written -0.0: JSON readers take "-0"
  // for the integer 0 and would lose its sign (a replay compares commands bit for bit).
  if (v == 0.0 && std::signbit(v)) {
    out += "-0.0";
    return;
  }
  std::snprintf(buf, sizeof buf, as_float ? "%.9g" : "%.17g", v);
  out += buf;
}

uint64_t epochOf(const nlohmann::json& header) {
  if (!header.is_object() || !header.contains("start_utc") || !header["start_utc"].is_string()) return 0;
  std::tm tm{};
  if (strptime(header["start_utc"].get<std::string>().c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm) == nullptr) return 0;
  const time_t t = timegm(&tm);
  return t < 0 ? 0 : static_cast<uint64_t>(t) * 1000000000ull;
}

std::vector<std::string> stringList(const nlohmann::json& h, const char* key) {
  std::vector<std::string> v;
  if (h.is_object() && h.contains(key) && h[key].is_array()) {
    for (const auto& s : h[key]) v.push_back(s.is_string() ? s.get<std::string>() : std::string("?"));
  }
  return v;
}

const char* kindName(protocol::SampleKind k) {
  switch (k) {
    case protocol::SampleKind::kAngle: return "angle";
    case protocol::SampleKind::kForce: return "force";
    case protocol::SampleKind::kTorque: return "torque";
    case protocol::SampleKind::kDuty: return "duty";
    case protocol::SampleKind::kCurrent: return "current";
  }
  return "sample";
}
const char* kindUnit(protocol::SampleKind k) {
  switch (k) {
    case protocol::SampleKind::kAngle: return "_rad";
    case protocol::SampleKind::kForce: return "_N";
    case protocol::SampleKind::kTorque: return "_Nm";
    case protocol::SampleKind::kDuty: return "";
    case protocol::SampleKind::kCurrent: return "_A";
  }
  return "";
}

}  // namespace

std::vector<std::string> sampleColumnNames(const protocol::DeviceLayout& layout) {
  std::string err;
  if (auto dev = therapy::makeTherapyDevice(layout, {}, err)) {
    auto v = dev->sampleNames();
    if (v.size() == layout.sample_count) return v;
  }
  std::vector<std::string> v;
  for (uint8_t i = 0; i < layout.sample_count; ++i) {
    v.push_back(std::string(kindName(layout.sample_kind[i])) + std::to_string(i) + kindUnit(layout.sample_kind[i]));
  }
  return v;
}

std::vector<std::string> setpointColumnNames(const protocol::DeviceLayout& layout) {
  std::string err;
  if (auto dev = therapy::makeTherapyDevice(layout, {}, err)) {
    auto v = dev->setpointNames();
    if (v.size() == layout.setpoint_count) return v;
  }
  // pantograph: six joint torques (N·m); others fall back to a numbered name.
  std::vector<std::string> v;
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) {
    v.push_back(layout.type == protocol::DeviceType::kPantograph ? "setpoint_torque" + std::to_string(i) + "_Nm"
                                                                 : "setpoint" + std::to_string(i));
  }
  return v;
}

McapSession::McapSession(McapLayout layout, std::unique_ptr<therapy::TherapyDevice> device,
                         McapWriter::Compression compression)
    : layout_(std::move(layout)), device_(std::move(device)), writer_(compression) {}

McapSession::~McapSession() = default;

std::vector<uint8_t> McapSession::start() {
  std::vector<uint8_t> out = writer_.start("", "phalanx");
  const std::map<std::string, std::string> meta{{"device", layout_.device}};
  writer_.addMetadata("phalanx_session", {{"device", layout_.device}, {"header", layout_.header.dump()}});
  const uint16_t js = writer_.addSchema(ros2::kJointStateName, "ros2msg", ros2::jointStateDefinition());
  auto json = [&](const std::string& topic, const nlohmann::json& schema) {
    const uint16_t id = writer_.addSchema(schema.value("title", topic), "jsonschema", schema.dump());
    return writer_.addChannel(id, topic, "json", meta);
  };
  have_device_ = device_ != nullptr;
  if (have_device_) {
    ch_joints_ = writer_.addChannel(js, "/phalanx/joint_states", "cdr", meta);
    const uint16_t ws = writer_.addSchema(ros2::kWrenchStampedName, "ros2msg", ros2::wrenchStampedDefinition());
    for (std::size_t c = 0; c < device_->channelCount(); ++c) {
      ch_effort_.push_back(writer_.addChannel(ws, "/phalanx/effort/" + device_->channelName(c), "cdr", meta));
    }
  }
  for (std::size_t i = 0; i < layout_.samples.size(); ++i) {
    if (unitOf(layout_.samples[i]) == "rad") angle_samples_.push_back(i);
  }
  ch_mechanism_ = writer_.addChannel(js, "/phalanx/mechanism/joint_states", "cdr", meta);
  std::vector<std::pair<std::string, std::string>> tel_fields{
      {"t_s", "s since the session's first cycle"}, {"device_time_us", "device clock, µs"},
      {"seq", "telemetry sequence number"}, {"mode", "device mode (protocol::Mode)"},
      {"fault_bits", "latched device faults (protocol::fault)"}};
  std::vector<std::pair<std::string, std::string>> cmd_fields{
      {"t_s", "s"}, {"seq", "command sequence number"}, {"mode", "commanded mode (protocol::Mode)"}};
  if (layout_.live) {
    tel_fields.emplace_back("cmd_seq_echo", "seq of the last command the device applied");
    tel_fields.emplace_back("state_flags", "device state flags (protocol::state)");
    cmd_fields.emplace_back("source", "who commanded: 0 controller, 1 Modbus, 2 client channel, 3 e-stop (safe)");
  }
  ch_telemetry_ = json("/phalanx/telemetry", numberSchema("phalanx.Telemetry", tel_fields, layout_.samples));
  nlohmann::json cmd_schema = numberSchema("phalanx.Command", cmd_fields, layout_.setpoints);
  if (layout_.live) {
    cmd_schema["properties"]["gain_permille"] = {
        {"type", "array"}, {"items", {{"type", "integer"}}},
        {"description", "controller gain scale per setpoint, per mille (1000 = nominal)"}};
  }
  ch_command_ = json("/phalanx/command", cmd_schema);
  if (layout_.pen) {
    const uint16_t ps = writer_.addSchema(ros2::kPoseStampedName, "ros2msg", ros2::poseStampedDefinition());
    ch_pen_pose_ = writer_.addChannel(ps, "/phalanx/pen/pose", "cdr", meta);
    const uint16_t ws = writer_.addSchema(ros2::kWrenchStampedName, "ros2msg", ros2::wrenchStampedDefinition());
    ch_pen_wrench_ = writer_.addChannel(ws, "/phalanx/pen/wrench", "cdr", meta);
  }
  if (!layout_.aux.empty()) {
    ch_therapy_ = json("/phalanx/therapy", numberSchema("phalanx.Therapy", {{"t_s", "s"}}, layout_.aux));
  }
  for (std::size_t i = 0; i < layout_.aux.size(); ++i) {
    if (layout_.aux[i] == "limited_bits") limited_aux_ = static_cast<int>(i);
  }
  ch_limits_ = json("/phalanx/limits",
                    numberSchema("phalanx.Limits",
                                 {{"t_s", "s"},
                                  {"limited_bits", "bit per channel whose effort the patient limits reduced"},
                                  {"estop", "1 while the e-stop input is pressed"},
                                  {"state_flags", "device state flags (protocol::state)"}},
                                 {}));
  nlohmann::json faults = numberSchema("phalanx.Faults", {{"t_s", "s"}, {"fault_bits", "protocol::fault bits"}}, {});
  faults["properties"]["faults"] = {{"type", "string"}, {"description", "names of the set bits, or none"}};
  ch_faults_ = json("/phalanx/faults", faults);
  ch_events_ = json("/phalanx/events", {{"title", "phalanx.Event"},
                                        {"type", "object"},
                                        {"properties",
                                         {{"t_s", {{"type", "number"}, {"description", "s"}}},
                                          {"kind", {{"type", "string"}, {"description", "docs/records.md"}}}}}});
  ch_loop_ = json("/phalanx/loop_stats",
                  numberSchema("phalanx.LoopStats",
                               {{"t_s", "s (end of the window)"},
                                {"cycles", "host cycles in the window"},
                                {"period_mean_s", "mean host cycle period, s"},
                                {"period_max_s", "longest host cycle period, s"},
                                {"telemetry_missed", "telemetry frames missing (sequence gaps)"}},
                               {}));
  const uint16_t ds = writer_.addSchema(ros2::kDiagnosticArrayName, "ros2msg", ros2::diagnosticArrayDefinition());
  ch_diag_ = writer_.addChannel(ds, "/diagnostics", "cdr", meta);
  const std::vector<uint8_t> rest = writer_.takePending();
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

uint64_t McapSession::logTime(double t_s) const {
  const long long ns = std::llround(std::max(t_s, 0.0) * 1e9);
  return layout_.start_epoch_ns + static_cast<uint64_t>(ns);
}

std::string McapSession::numbersJson(const std::vector<std::string>& names, const float* values,
                                     std::size_t n) const {
  std::string s;
  for (std::size_t i = 0; i < names.size() && i < n; ++i) {
    s += ',';
    putNumber(s, names[i].c_str(), static_cast<double>(values[i]), true);
  }
  return s;
}

void McapSession::addCycle(const CycleRecord& c, const CommandExtras* extras) {
  const uint64_t t = logTime(c.t_s);
  std::string s = "{";
  putNumber(s, "t_s", c.t_s, false);
  s += ",\"device_time_us\":" + std::to_string(c.device_time_us) + ",\"seq\":" + std::to_string(c.tel_seq) +
       ",\"mode\":" + std::to_string(c.tel_mode) + ",\"fault_bits\":" + std::to_string(c.fault_bits);
  if (layout_.live) {
    s += ",\"cmd_seq_echo\":" + std::to_string(c.cmd_seq_echo) + ",\"state_flags\":" + std::to_string(c.state_flags);
  }
  s += numbersJson(layout_.samples, c.sample.data(), c.sample_count) + "}";
  writer_.addMessage(ch_telemetry_, t, s);
  s = "{";
  putNumber(s, "t_s", c.t_s, false);
  s += ",\"seq\":" + std::to_string(c.cmd_seq) + ",\"mode\":" + std::to_string(c.cmd_mode);
  if (layout_.live && extras != nullptr) {
    s += ",\"source\":" + std::to_string(extras->source) + ",\"gain_permille\":[";
    for (std::size_t i = 0; i < c.setpoint_count; ++i) s += (i ? "," : "") + std::to_string(extras->gain_permille[i]);
    s += ']';
  }
  s += numbersJson(layout_.setpoints, c.setpoint.data(), c.setpoint_count) + "}";
  writer_.addMessage(ch_command_, t, s);
  if (layout_.pen) addPen(t, c);
  if (!layout_.aux.empty() && c.aux_count > 0) {
    s = "{";
    putNumber(s, "t_s", c.t_s, false);
    s += numbersJson(layout_.aux, c.aux.data(), c.aux_count) + "}";
    writer_.addMessage(ch_therapy_, t, s);
  }
  ros2::JointState mech;
  mech.header = ros2::headerAt(t, layout_.device);
  for (std::size_t i : angle_samples_) {
    if (i >= c.sample_count) continue;
    mech.name.push_back(layout_.samples[i]);
    mech.position.push_back(static_cast<double>(c.sample[i]));
  }
  writer_.addMessage(ch_mechanism_, t, ros2::encode(mech));
  if (have_device_) {
    TelemetryFrame tel;
    tel.device_time_us = c.device_time_us;
    tel.mode = static_cast<protocol::Mode>(c.tel_mode);
    tel.fault_bits = c.fault_bits;
    tel.sample_count = c.sample_count;
    for (std::size_t i = 0; i < c.sample_count; ++i) tel.value[i] = c.sample[i];
    therapy::Observation obs{};
    device_->observe(tel, obs);
    ros2::JointState js;
    js.header = ros2::headerAt(t, layout_.device);
    for (std::size_t j = 0; j < device_->jointCount(); ++j) {
      js.name.push_back(device_->jointName(j));
      js.position.push_back(obs.joint_valid[j] ? obs.flexion_rad[j] : std::nan(""));
    }
    writer_.addMessage(ch_joints_, t, ros2::encode(js));
    const bool torque = device_->effortUnit() != "N";
    for (std::size_t ch = 0; ch < ch_effort_.size(); ++ch) {
      ros2::WrenchStamped w;
      w.header = ros2::headerAt(t, device_->channelName(ch));
      (torque ? w.torque : w.force)[2] = obs.effort[ch];
      writer_.addMessage(ch_effort_[ch], t, ros2::encode(w));
    }
  }
  const uint16_t limited =
      limited_aux_ >= 0 && limited_aux_ < c.aux_count ? static_cast<uint16_t>(c.aux[static_cast<std::size_t>(limited_aux_)]) : 0;
  if (first_ || limited != last_limited_ || c.state_flags != last_flags_) {
    s = "{";
    putNumber(s, "t_s", c.t_s, false);
    s += ",\"limited_bits\":" + std::to_string(limited) +
         ",\"estop\":" + std::to_string((c.state_flags & protocol::state::kEstopPressed) != 0 ? 1 : 0) +
         ",\"state_flags\":" + std::to_string(c.state_flags) + "}";
    writer_.addMessage(ch_limits_, t, s);
  }
  if (first_ || c.fault_bits != last_faults_) {
    s = "{";
    putNumber(s, "t_s", c.t_s, false);
    s += ",\"fault_bits\":" + std::to_string(c.fault_bits) + ",\"faults\":\"" + faultList(c.fault_bits) + "\"}";
    writer_.addMessage(ch_faults_, t, s);
  }
  // Loop statistics: host period from the cycles' wake-up times, telemetry gaps from the sequence numbers.
  if (first_) window_start_s_ = c.t_s;
  if (!first_ && c.host_ns > last_host_ns_ && last_host_ns_ != 0) {
    const double p = static_cast<double>(c.host_ns - last_host_ns_) * 1e-9;
    period_sum_s_ += p;
    period_max_s_ = std::max(period_max_s_, p);
  }
  if (!first_) {
    const auto gap = static_cast<uint16_t>(c.tel_seq - last_seq_);
    if (gap > 1 && gap < 1000) window_missed_ += gap - 1u;
  }
  ++window_cycles_;
  last_host_ns_ = c.host_ns;
  last_seq_ = c.tel_seq;
  last_limited_ = limited;
  last_flags_ = c.state_flags;
  last_faults_ = c.fault_bits;
  first_ = false;
  if (c.t_s - window_start_s_ >= 1.0) emitLoopStats(c.t_s);
}

void McapSession::addPen(uint64_t t, const CycleRecord& c) {
  if (c.sample_count < 12) return;
  const PenMeasurement m = measurePen(layout_.pen_model, c.sample.data());
  const double nan = std::nan("");
  ros2::PoseStamped pose;
  pose.header = ros2::headerAt(t, "pen_base");
  for (std::size_t i = 0; i < 3; ++i) pose.position[i] = m.pose_valid ? m.centre_m[i] : nan;
  for (std::size_t i = 0; i < 4; ++i) pose.orientation[i] = m.pose_valid ? m.orientation[i] : nan;
  writer_.addMessage(ch_pen_pose_, t, ros2::encode(pose));
  ros2::WrenchStamped w;
  w.header = ros2::headerAt(t, "pen_base");
  for (std::size_t i = 0; i < 3; ++i) {
    w.force[i] = m.wrench_valid ? m.force_N[i] : nan;
    w.torque[i] = m.wrench_valid ? m.torque_Nm[i] : nan;
  }
  writer_.addMessage(ch_pen_wrench_, t, ros2::encode(w));
}

void McapSession::emitLoopStats(double t_s) {
  if (window_cycles_ == 0) return;
  const uint64_t t = logTime(t_s);
  const double mean = window_cycles_ > 1 ? period_sum_s_ / static_cast<double>(window_cycles_ - 1) : 0.0;
  std::string s = "{";
  putNumber(s, "t_s", t_s, false);
  s += ",\"cycles\":" + std::to_string(window_cycles_) + ",";
  putNumber(s, "period_mean_s", mean, false);
  s += ',';
  putNumber(s, "period_max_s", period_max_s_, false);
  s += ",\"telemetry_missed\":" + std::to_string(window_missed_) + "}";
  writer_.addMessage(ch_loop_, t, s);
  ros2::DiagnosticArray d;
  d.header = ros2::headerAt(t, layout_.device);
  ros2::DiagnosticStatus st;
  st.level = window_missed_ > 0 ? 1 : 0;
  st.name = "phalanx: host loop";
  st.message = window_missed_ > 0 ? "telemetry frames missed" : "ok";
  st.hardware_id = layout_.device;
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", mean);
  st.values = {{"cycles", std::to_string(window_cycles_)}, {"period_mean_s", buf}};
  std::snprintf(buf, sizeof buf, "%.9g", period_max_s_);
  st.values.emplace_back("period_max_s", buf);
  st.values.emplace_back("telemetry_missed", std::to_string(window_missed_));
  d.status.push_back(std::move(st));
  writer_.addMessage(ch_diag_, t, ros2::encode(d));
  // The cycle that closed this window starts the next one (its period is counted in the next).
  window_start_s_ = t_s;
  window_cycles_ = 0;
  window_missed_ = 0;
  period_sum_s_ = 0.0;
  period_max_s_ = 0.0;
}

void McapSession::addEvent(const nlohmann::json& event) {
  const double t_s = event.is_object() && event.contains("t_s") && event["t_s"].is_number() ? event["t_s"].get<double>() : 0.0;
  writer_.addMessage(ch_events_, logTime(t_s), event.dump());
}

std::vector<uint8_t> McapSession::finish(uint64_t file_offset, uint32_t data_crc) {
  return writer_.finish(file_offset, data_crc);
}

std::string exportMcap(const SessionRecord& rec, const std::string& path) {
  if (rec.source_id == fileId(path)) {
    return "refusing to write " + path + ": it is the record being exported (" + rec.source + ", the same file)";
  }
  McapLayout l;
  l.device = rec.header.is_object() ? rec.header.value("device", std::string("?")) : "?";
  l.samples = stringList(rec.header, "samples");
  l.setpoints = stringList(rec.header, "setpoints");
  l.aux = stringList(rec.header, "aux");
  const std::size_t ns = rec.cycles.empty() ? 0 : rec.cycles.front().sample_count;
  const std::size_t nc = rec.cycles.empty() ? 0 : rec.cycles.front().setpoint_count;
  for (std::size_t i = l.samples.size(); i < ns; ++i) l.samples.push_back("sample" + std::to_string(i));
  for (std::size_t i = l.setpoints.size(); i < nc; ++i) l.setpoints.push_back("setpoint" + std::to_string(i));
  l.start_epoch_ns = epochOf(rec.header);
  l.header = rec.header;
  std::string err;
  auto dev = therapy::makeTherapyDevice(l.device, kinematicsFromHeader(rec.header), err);
  McapSession s(l, std::move(dev));
  AtomicOutputFile f;
  if (err = f.open(path); !err.empty()) return err;
  uint64_t offset = 0;
  uint32_t crc = 0;
  auto put = [&](const std::vector<uint8_t>& b) {
    crc = mcapCrc(crc, b.data(), b.size());
    offset += b.size();
    return f.write(b.data(), b.size());
  };
  put(s.start());
  // Events in time order between the cycles; a chunk per 50 ms of session, as a live recording has.
  std::size_t e = 0;
  double chunk_t = rec.cycles.empty() ? 0.0 : rec.cycles.front().t_s;
  auto eventT = [&](std::size_t i) {
    const auto& ev = rec.events[i];
    return ev.is_object() && ev.contains("t_s") && ev["t_s"].is_number() ? ev["t_s"].get<double>() : 0.0;
  };
  bool ok = true;
  for (const CycleRecord& c : rec.cycles) {
    if (c.t_s - chunk_t >= 0.05) {  // closed before the cycle that would take it past 50 ms (as CsvRecorder does)
      if (!(ok = put(s.takeChunk(offset)))) break;
      chunk_t = c.t_s;
    }
    while (e < rec.events.size() && eventT(e) <= c.t_s) s.addEvent(rec.events[e++]);
    s.addCycle(c);
  }
  while (ok && e < rec.events.size()) s.addEvent(rec.events[e++]);
  if (ok) put(s.takeChunk(offset));
  const std::vector<uint8_t> tail = s.finish(offset, crc);
  f.write(tail.data(), tail.size());
  return f.commit();
}

}  // namespace phalanx::host::record
