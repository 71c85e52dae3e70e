#include "phalanx/host/record/replay_stream.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <thread>

#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/record/mcap_session.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/session.h"
#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/guidance.h"

namespace phalanx::host::record {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

std::string baseName(const std::string& path) {
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

/// Channels and joints of one cycle through the device's therapy adapter (as phalanxd's status shows them).
void adapterValues(therapy::TherapyDevice& dev, const ReplayedCycle& c, nlohmann::json& s) {
  therapy::Observation obs{};
  dev.observe(c.tel, obs);
  std::array<double, therapy::kMaxChannels> commanded{};
  std::array<float, therapy::kMaxChannels> setpoint{};
  for (std::size_t i = 0; i < dev.channelCount(); ++i) setpoint[i] = c.command.setpoint[i];
  dev.effortFromCommand(setpoint, commanded);
  s["effort_unit"] = dev.effortUnit();
  for (std::size_t ch = 0; ch < dev.channelCount(); ++ch) {
    s["channels"][dev.channelName(ch)] = {{"q_deg", obs.channel_valid[ch] ? num(obs.q_rad[ch] * kRadToDeg) : nullptr},
                                          {"target_deg", nullptr},
                                          {"effort_measured", num(obs.effort[ch])},
                                          {"effort_command", num(commanded[ch])},
                                          {"effort_max", num(dev.effortLimit(ch))}};
  }
  for (std::size_t j = 0; j < dev.jointCount(); ++j) {
    s["joints"][dev.jointName(j)] = {{"channel", dev.channelName(dev.jointChannel(j))},
                                     {"flexion_deg", obs.joint_valid[j] ? num(obs.flexion_rad[j] * kRadToDeg) : nullptr}};
  }
}

/// A device without a therapy adapter (the pantograph): its measured angles as joints, its setpoints as the
/// commanded efforts (no measured effort, no coordinate).
void rawValues(const protocol::DeviceLayout& layout, const ReplayedCycle& c, nlohmann::json& s) {
  const std::vector<std::string> samples = sampleColumnNames(layout), setpoints = setpointColumnNames(layout);
  s["effort_unit"] = layout.type == protocol::DeviceType::kPantograph ? "N·m" : "";
  for (std::size_t i = 0; i < layout.setpoint_count; ++i) {
    s["channels"][setpoints[i]] = {{"q_deg", nullptr}, {"target_deg", nullptr}, {"effort_measured", nullptr},
                                   {"effort_command", num(c.command.setpoint[i])}, {"effort_max", nullptr}};
  }
  for (std::size_t i = 0; i < layout.sample_count; ++i) {
    if (layout.sample_kind[i] != protocol::SampleKind::kAngle) continue;
    s["joints"][samples[i]] = {{"channel", ""}, {"flexion_deg", num(double(c.tel.value[i]) * kRadToDeg)}};
  }
}

/// The session object of a status answer at one replayed cycle.
nlohmann::json frameOf(const protocol::DeviceLayout& layout, therapy::TherapyDevice* dev, const std::string& file,
                       const ReplayedCycle& c) {
  nlohmann::json s{{"phase", "replay"},
                   {"record", file},
                   {"device", layout.name},
                   {"t_s", c.t_s},
                   {"cycles", c.cycle + 1},
                   {"device_mode", modeName(c.tel.mode)},
                   {"faults", faultList(c.tel.fault_bits)},
                   {"estop", (c.tel.state_flags & protocol::state::kEstopPressed) != 0}};
  if (c.tel.fault_bits != 0) s["fault_guidance"] = therapy::faultGuidanceJson(c.tel.fault_bits);
  if (dev != nullptr) {
    adapterValues(*dev, c, s);
  } else {
    rawValues(layout, c, s);
  }
  return s;
}

/// The first cycle of each 1/50 s of session time (the dashboard's sample rate).
class FrameSlots {
 public:
  bool take(double t_s) {
    const double slot = std::floor(t_s * api::Dashboard::kSampleRateHz);
    if (slot <= last_) return false;
    last_ = slot;
    return true;
  }

 private:
  double last_ = -1.0;
};

}  // namespace

bool isSessionRecord(const std::string& path) {
  char head[8] = {};
  std::FILE* f = std::fopen(path.c_str(), "rb");
  const std::size_t n = f != nullptr ? std::fread(head, 1, sizeof head, f) : 0;
  if (f != nullptr) std::fclose(f);
  return n == 8 && std::memcmp(head, "PHXREC1\n", 8) == 0;
}

namespace {

float auxAt(const CycleRecord& c, int index) {
  return index >= 0 && index < c.aux_count ? c.aux[static_cast<std::size_t>(index)] : std::nanf("");
}

/// A therapy session record (.phrec) as frames: its recorded values (telemetry through the therapy adapter with
/// the patient's kinematics, the sent command, the exercise and its targets); no controller is run (its exercise
/// and limit changes are not tied to the cycles that took them), so nothing is compared.
std::string recordFrames(const std::string& path, ReplayFrames& out) {
  SessionRecord rec;
  if (std::string err = readRecord(path, rec); !err.empty()) return path + ": " + err;
  if (rec.header.is_null()) return path + ": its header record is missing or damaged";
  const std::string device = rec.header.value("device", "");
  const protocol::DeviceLayout* layout = layoutNamed(device);
  std::string err;
  std::shared_ptr<therapy::TherapyDevice> dev = layout != nullptr ? therapy::makeTherapyDevice(*layout, kinematicsFromHeader(rec.header), err) : nullptr;
  if (!dev) return path + ": device '" + device + "' " + (err.empty() ? "is unknown" : err);
  out.result.device = device;
  out.result.controller = "therapy (recorded values; no controller run)";
  out.result.file_complete = rec.complete();
  const int exercise = rec.auxIndex("exercise_id");
  std::vector<int> target(std::min<std::size_t>(dev->channelCount(), protocol::kMaxSetpoints));
  for (std::size_t ch = 0; ch < target.size(); ++ch) target[ch] = rec.auxIndex("target_" + dev->channelName(ch) + "_rad");
  out.layout = layout;
  out.device = std::move(dev);
  out.session_record = true;
  if (rec.header.contains("patient")) out.patient = rec.header["patient"];
  FrameSlots slots;
  for (const CycleRecord& c : rec.cycles) {
    ++out.result.cycles;
    if (!slots.take(c.t_s)) continue;
    ReplayFrame f;
    f.t_s = c.t_s;
    f.cycle = out.result.cycles - 1;
    f.tel.device_time_us = c.device_time_us;
    f.tel.mode = static_cast<protocol::Mode>(c.tel_mode);
    f.tel.state_flags = c.state_flags;
    f.tel.fault_bits = c.fault_bits;
    f.tel.sample_count = c.sample_count;
    for (std::size_t i = 0; i < c.sample_count; ++i) f.tel.value[i] = c.sample[i];
    f.command.mode = static_cast<protocol::Mode>(c.cmd_mode);
    f.command.channel_count = c.setpoint_count;
    for (std::size_t i = 0; i < c.setpoint_count; ++i) f.command.setpoint[i] = c.setpoint[i];
    f.exercise_id = auxAt(c, exercise);
    for (std::size_t ch = 0; ch < target.size(); ++ch) f.target_rad[ch] = auxAt(c, target[ch]);
    out.frames.push_back(f);
  }
  if (out.frames.empty()) return path + ": holds no cycle to replay";
  return {};
}

}  // namespace

std::string replayFrames(const std::string& path, const ReplayOptions& options, ReplayFrames& out) {
  out = ReplayFrames{};
  out.file = baseName(path);
  out.result.file = path;
  if (isSessionRecord(path)) {
    if (!options.set.empty()) return path + ": --set changes a replayed controller; a session record is shown as recorded";
    return recordFrames(path, out);
  }
  bool first = true;
  FrameSlots slots;
  auto observe = [&](const protocol::DeviceLayout& layout, const ReplayedCycle& c) {
    if (first) {
      std::string err;  // no adapter (pantograph): the raw channels
      out.layout = &layout;
      out.device = therapy::makeTherapyDevice(layout, {}, err);
      first = false;
    }
    if (!slots.take(c.t_s)) return;
    ReplayFrame f;
    f.t_s = c.t_s;
    f.cycle = c.cycle;
    f.tel = c.tel;
    f.command = c.command;
    f.target_rad.fill(std::nanf(""));
    out.frames.push_back(f);
  };
  if (std::string err = replayRecording(path, options, out.result, observe); !err.empty()) return err;
  if (out.frames.empty()) return path + ": holds no cycle to replay";
  return {};
}

nlohmann::json ReplayFrames::session(std::size_t i) const {
  const ReplayFrame& f = frames[i];
  nlohmann::json s = frameOf(*layout, device.get(), file, ReplayedCycle{f.cycle, f.t_s, f.tel, f.command});
  if (!patient.is_null()) s["patient"] = patient;
  if (std::isfinite(f.exercise_id)) {
    s["exercise"] = therapy::exerciseName(static_cast<therapy::ExerciseId>(static_cast<int>(f.exercise_id)));
  }
  if (session_record && device != nullptr) {  // the recorded targets
    for (std::size_t ch = 0; ch < device->channelCount() && ch < f.target_rad.size(); ++ch) {
      s["channels"][device->channelName(ch)]["target_deg"] = num(double(f.target_rad[ch]) * kRadToDeg);
    }
  }
  const double t0 = frames.front().t_s;
  s["replay"] = {{"file", file}, {"speed", 1.0}, {"t_s", f.t_s - t0}, {"total_s", frames.back().t_s - t0},
                 {"finished", false}, {"mismatched_cycles", result.mismatched_cycles}};
  return s;
}

ReplayStatus::ReplayStatus(const ReplayFrames& frames, double speed)
    : frames_(frames), speed_(speed) {}

void ReplayStatus::show(std::size_t i, bool finished) {
  nlohmann::json s = frames_.session(std::min(i, frames_.frames.size() - 1));  // outside the lock
  s["replay"]["speed"] = speed_;
  s["replay"]["finished"] = finished;
  std::lock_guard<std::mutex> lock(mutex_);
  session_ = std::move(s);
  finished_ = finished;
  started_ = true;
}

nlohmann::json ReplayStatus::statusAnswer() const {
  std::lock_guard<std::mutex> lock(mutex_);
  nlohmann::json result{{"session_running", started_ && !finished_}};
  if (started_) result["session"] = session_;  // before the first frame: no session yet
  return {{"ok", true}, {"result", result}};
}

nlohmann::json ReplayStatus::handle(const std::string& line) const {
  const nlohmann::json req = nlohmann::json::parse(line, nullptr, false);
  if (req.is_discarded() || !req.is_object() || !req.contains("cmd") || !req["cmd"].is_string()) {
    return {{"ok", false}, {"error", "expected one JSON object with a string \"cmd\""}};
  }
  const std::string cmd = req["cmd"].get<std::string>();
  if (cmd == "status") return statusAnswer();
  if (cmd == "profiles") return {{"ok", true}, {"result", nlohmann::json::array()}};
  return {{"ok", false}, {"error", "this is a replay of " + frames_.file + ": there is no device to control"}};
}

namespace {

/// Sleeps until `until` or stop, in steps short enough for a signal to end the replay within 50 ms.
bool sleepUntil(std::chrono::steady_clock::time_point until, const std::atomic<bool>& stop) {
  while (!stop.load()) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= until) return true;
    std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(until - now, std::chrono::milliseconds(50)));
  }
  return false;
}

/// After the last frame: until a page has fetched every sample, or stop. A page seen fetching within the last 5 s
/// is waited for (a loaded machine can stall one for seconds), at most 30 s; with none, 2 s.
void lingerForPages(const api::Dashboard& dash, const std::atomic<bool>& stop) {
  const auto end = std::chrono::steady_clock::now();
  while (!stop.load() && dash.deliveredSeq() < dash.lastSeq()) {
    const auto now = std::chrono::steady_clock::now();
    const bool page_active = now - dash.lastFetch() < std::chrono::seconds(5);
    if (now - end > std::chrono::seconds(30) || (!page_active && now - end > std::chrono::seconds(2))) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace

namespace {

/// Shows each frame at its session time / speed after the first (published to the dashboard: one sample each).
/// Returns how many were shown (fewer when stopped) and the wall time that took.
std::size_t paceFrames(const ReplayFrames& frames, double speed, ReplayStatus& status, api::Dashboard& dash,
                       const std::atomic<bool>& stop, double& wall_s) {
  const double t0 = frames.frames.front().t_s;
  const auto wall0 = std::chrono::steady_clock::now();
  std::size_t shown = 0;
  for (std::size_t i = 0; i < frames.frames.size(); ++i) {
    const auto due = wall0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>((frames.frames[i].t_s - t0) / speed));
    if (!sleepUntil(due, stop)) break;
    status.show(i, i + 1 == frames.frames.size());
    dash.publish(status.statusAnswer());
    shown = i + 1;
  }
  wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return shown;
}

/// The replay's JSON plus "stream" on stdout, one line for people on stderr.
void printSummary(const ReplayFrames& frames, double speed, std::size_t shown, double wall_s, uint64_t delivered,
                  uint64_t samples) {
  const bool finished = shown == frames.frames.size();
  const double replay_s = shown > 0 ? frames.frames[shown - 1].t_s - frames.frames.front().t_s : 0.0;
  const double achieved = wall_s > 0 ? replay_s / wall_s : 0.0;
  nlohmann::json summary = frames.result.toJson();
  summary["stream"] = {{"speed", speed},           {"frames", frames.frames.size()}, {"frames_shown", shown},
                       {"samples", samples},       {"samples_fetched", delivered},   {"finished", finished},
                       {"replay_s", replay_s},     {"wall_s", wall_s},               {"achieved_speed", achieved}};
  std::cout << summary.dump() << std::endl;
  std::fprintf(stderr, "replay %s: %zu of %zu frames shown (%.2f s of session in %.2f s: %.2f×), %llu of %llu samples "
               "fetched by a page; %llu of %llu compared cycles differ\n",
               finished ? "finished" : "stopped", shown, frames.frames.size(), replay_s, wall_s, achieved,
               static_cast<unsigned long long>(delivered), static_cast<unsigned long long>(samples),
               static_cast<unsigned long long>(frames.result.mismatched_cycles),
               static_cast<unsigned long long>(frames.result.compared));
}

}  // namespace

int streamReplay(const std::string& path, const ReplayStreamOptions& options, const std::atomic<bool>& stop) {
  ReplayFrames frames;
  if (std::string err = replayFrames(path, options.replay, frames); !err.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
    return 2;
  }
  ReplayStatus status(frames, options.speed);
  api::Dashboard dash(options.dashboard, [&status](const std::string& line) { return status.handle(line); },
                      api::Dashboard::Sampling::kPublished);
  if (std::string err = dash.start(); !err.empty()) {
    std::fprintf(stderr, "phalanx: error: --dashboard: %s\n", err.c_str());
    return 3;
  }
  std::printf("DASHBOARD %s\n", dash.url().c_str());
  std::fflush(stdout);
  std::fprintf(stderr, "replay %s (%s, %s) on the dashboard at %g×: %zu frames, %.1f s of session\n",
               frames.file.c_str(), frames.result.device.c_str(), frames.result.controller.c_str(), options.speed,
               frames.frames.size(), frames.frames.back().t_s - frames.frames.front().t_s);
  double wall_s = 0.0;
  const std::size_t shown = paceFrames(frames, options.speed, status, dash, stop, wall_s);
  if (shown == frames.frames.size() && options.hold) {
    std::fprintf(stderr, "replay finished; holding the last state until SIGINT/SIGTERM\n");
    while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } else if (shown == frames.frames.size()) {
    lingerForPages(dash, stop);
  }
  const uint64_t delivered = dash.deliveredSeq(), samples = dash.lastSeq();
  dash.stop();
  printSummary(frames, options.speed, shown, wall_s, delivered, samples);
  return frames.result.mismatched_cycles == 0 ? 0 : 1;
}

}  // namespace phalanx::host::record
