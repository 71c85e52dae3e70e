#include "phalanx/host/therapy/therapy_session.h"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>

#include "phalanx/host/record/write_failure.h"
#include "phalanx/host/therapy/guidance.h"
#include "phalanx/host/therapy/records_dir.h"
#include "phalanx/host/therapy/report.h"

namespace phalanx::host::therapy {

TherapySession::TherapySession(TherapySessionConfig config)
    : config_(std::move(config)), writer_(config_.writer) {}

TherapySession::~TherapySession() {
  writer_.close();
  delete plan_handover_;
}

namespace {
/// runSession owns its controller; the session shares this one with the API, so a status request can never
/// reach a destroyed controller whatever way runSession ends.
class SharedController : public Controller {
 public:
  explicit SharedController(std::shared_ptr<TherapyController> c) : c_(std::move(c)) {}
  const char* name() const override { return c_->name(); }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override {
    c_->update(tel, t_s, dt_s, cmd);
  }
  void summarize(nlohmann::json& out) const override { c_->summarize(out); }
  std::vector<std::pair<uint16_t, float>> startupParams() const override { return c_->startupParams(); }
  double startupSettleS() const override { return c_->startupSettleS(); }
  std::vector<uint16_t> startupReadback() const override { return c_->startupReadback(); }
  std::string startupWarning(uint16_t id, float value) const override { return c_->startupWarning(id, value); }

 private:
  std::shared_ptr<TherapyController> c_;
};
}  // namespace

std::shared_ptr<TherapyController> TherapySession::controller() const {
  std::lock_guard<std::mutex> lock(ctl_mutex_);
  return ctl_;
}

std::unique_ptr<Controller> TherapySession::makeController(const protocol::DeviceLayout& layout, std::string& error) {
  layout_ = &layout;
  if (config_.have_profile && config_.profile.device != layout.name) {
    error = "profile " + config_.profile.source + " is for a " + config_.profile.device + ", the connected device is a " +
            layout.name;
    return nullptr;
  }
  // The patient's limits hold on every command the session sends, with or without an exercise.
  if (config_.have_profile) {
    auto guard_device = makeTherapyDevice(layout, config_.profile.kinematics, error);
    if (!guard_device) return nullptr;
    auto guard = std::make_shared<PatientGuard>(std::move(guard_device), config_.profile.limits);
    loop_guard_ = guard.get();
    std::lock_guard<std::mutex> lock(ctl_mutex_);
    guard_ = guard;
  }
  if (config_.exercise.empty()) return nullptr;  // recording only, the default controller
  auto device = makeTherapyDevice(layout, config_.profile.kinematics, error);
  if (!device) return nullptr;
  const PatientLimits limits = config_.have_profile ? config_.profile.limits : PatientLimits::deviceDefaults(*device);
  pattern_ = std::make_shared<Pattern>(device->channelCount());
  std::unique_ptr<Exercise> first =
      makeExercise(config_.exercise, config_.exercise_params, *device, config_.profile, pattern_, error);
  if (!first) return nullptr;
  if (!config_.plan.empty()) {
    // Every later step's exercise is built now, so the loop only hands a ready object over when a step ends.
    std::vector<std::unique_ptr<Exercise>> later(config_.plan.steps.size());
    for (std::size_t i = 1; i < later.size(); ++i) {
      const PlanStep& st = config_.plan.steps[i];
      later[i] = makeExercise(st.exercise, st.params, *device, config_.profile, pattern_, error);
      if (!later[i]) return nullptr;
    }
    plan_ = std::make_unique<PlanRunner>(config_.plan, std::move(later));
  }
  auto ctl = std::make_shared<TherapyController>(std::move(device), limits, std::move(first),
                                                 config_.record_path.empty() ? nullptr : &writer_);
  loop_ctl_ = ctl.get();
  {
    std::lock_guard<std::mutex> lock(ctl_mutex_);
    ctl_ = ctl;
  }
  return std::make_unique<SharedController>(ctl);
}

std::string TherapySession::createRecord() {
  if (config_.record_path.empty() || writer_.isOpen()) return {};
  return writer_.create(config_.record_path);
}

std::string TherapySession::createRecordIn(const std::string& dir, const std::string& patient, std::time_t when) {
  RecordName name = nextRecordName(dir, patient, when);
  for (int attempt = 0; attempt < 1000; ++attempt, ++name.seq) {
    const std::string path = dir + "/" + recordFileName(name);
    int err_no = 0;
    const std::string err = writer_.create(path, &err_no);
    if (err_no == EEXIST) continue;  // made meanwhile (by another process): the next sequence number
    if (!err.empty()) {
      return "the records directory " + dir + " cannot take a new record: " + err;
    }
    config_.record_path = path;
    config_.report_path = path.substr(0, path.size() - 6) + ".html";
    return {};
  }
  return "the records directory " + dir + ": no free record name for " + patient + " at " + name.stamp;
}

std::string TherapySession::onStart(const protocol::DeviceLayout& layout, const nlohmann::json& info) {
  phase_.store(1);
  if (config_.record_path.empty()) return {};
  nlohmann::json h;
  h["format"] = "phalanx-session-record";
  h["format_version"] = config_.writer.cycle_blocks ? 2 : 1;  // 2: cycles in compressed blocks (docs/records.md)
  const auto now = std::chrono::system_clock::now();
  const std::time_t tt = std::chrono::system_clock::to_time_t(now);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&tt));
  h["start_utc"] = buf;
  h["device"] = layout.name;
  h["info"] = info;
  h["sample_count"] = layout.sample_count;
  h["setpoint_count"] = layout.setpoint_count;
  std::string err;
  KinematicParams kp = config_.profile.kinematics;
  if (auto dev = makeTherapyDevice(layout, kp, err)) {
    h["samples"] = dev->sampleNames();
    h["setpoints"] = dev->setpointNames();
    nlohmann::json ch = nlohmann::json::array(), joints = nlohmann::json::array();
    for (std::size_t c = 0; c < dev->channelCount(); ++c) ch.push_back(dev->channelName(c));
    for (std::size_t j = 0; j < dev->jointCount(); ++j) {
      joints.push_back({{"name", dev->jointName(j)}, {"channel", dev->jointChannel(j)}});
    }
    h["channels"] = ch;
    h["joints"] = joints;
    h["effort_unit"] = dev->effortUnit();
  }
  nlohmann::json kin = nlohmann::json::object();
  for (const auto& [ch, l] : kp.segment_lengths_mm) kin[ch] = {{"p1_mm", l[0]}, {"p2_mm", l[1]}, {"p3_mm", l[2]}};
  h["kinematics"] = kin;
  if (loop_ctl_ != nullptr) {
    h["aux"] = loop_ctl_->auxNames();
    h["limits"] = limitsJson();
  }
  if (config_.have_profile) {
    h["patient"] = config_.profile.patient;
    h["profile"] = config_.profile.source;
  }
  h["exercise"] = config_.exercise.empty() ? "none (device default controller)" : config_.exercise;
  h["exercise_params"] = config_.exercise_params;
  if (plan_ && loop_ctl_ != nullptr) h["plan"] = config_.plan.toJson(loop_ctl_->device());
  if (plan_ && !config_.plan.name.empty()) h["plan_name"] = config_.plan.name;
  if (config_.self_training) h["self_training"] = {{"max_session_s", config_.profile.self_training.max_session_s},
                                                  {"effort_scale", config_.profile.self_training.effort_scale}};
  if (!writer_.isOpen()) {
    if (std::string create_err = writer_.create(config_.record_path); !create_err.empty()) return create_err;
  }
  return writer_.start(h);
}

void TherapySession::onCycle(uint64_t wake_ns, double t_s, const TelemetryFrame& tel, const protocol::Command& cmd) {
  runPlanCycle(t_s - last_t_s_, tel, cmd);
  last_t_s_ = t_s;
  if (!writer_.isOpen()) return;
  record::CycleRecord r;
  r.host_ns = wake_ns;
  r.t_s = t_s;
  r.device_time_us = tel.device_time_us;
  r.tel_seq = tel.seq;
  r.cmd_seq_echo = tel.cmd_seq_echo;
  r.cmd_seq = cmd.seq;
  r.fault_bits = tel.fault_bits;
  r.tel_mode = static_cast<uint8_t>(tel.mode);
  r.cmd_mode = static_cast<uint8_t>(cmd.mode);
  r.state_flags = tel.state_flags;
  r.sample_count = tel.sample_count;
  for (std::size_t i = 0; i < tel.sample_count && i < r.sample.size(); ++i) r.sample[i] = tel.value[i];
  r.setpoint_count = layout_ != nullptr ? layout_->setpoint_count : 0;
  for (std::size_t i = 0; i < r.setpoint_count; ++i) r.setpoint[i] = cmd.setpoint[i];
  if (TherapyController* c = loop_ctl_) {
    c->fillAux(aux_);
    r.aux_count = static_cast<uint8_t>(c->auxCount());
    r.aux = aux_;
  }
  writer_.pushCycle(r);
}

/// The plan's clock counts a cycle when the device is in the mode commanded (not latched safe or locked by a
/// fault), no fault is latched, and the session is not paused. O(1), no allocation.
void TherapySession::runPlanCycle(double dt_s, const TelemetryFrame& tel, const protocol::Command& cmd) {
  PlanRunner* plan = plan_.get();
  TherapyController* c = loop_ctl_;
  if (plan == nullptr || c == nullptr) return;
  if (plan_handover_ != nullptr && c->offerExerciseFromLoop(plan_handover_)) plan_handover_ = nullptr;
  const bool counts = !c->heldPaused() && tel.fault_bits == 0 && tel.mode == cmd.mode;
  const PlanRunner::Ended ended = plan->cycle(c->observation(), dt_s, counts);
  if (ended == PlanRunner::Ended::kNo) return;
  if (writer_.isOpen()) {
    const PlanRunner::StepResult& r = plan->result(plan->endedStep());
    record::LoopEvent e;
    e.kind = record::LoopEvent::Kind::kPlanStepEnded;
    e.t_s = last_t_s_ + dt_s;
    e.code = static_cast<uint16_t>(plan->endedStep());
    e.detail = static_cast<uint8_t>(ended);
    e.value = static_cast<float>(static_cast<double>(r.elapsed_us.load()) * 1e-6);
    e.count = r.repetitions.load();
    writer_.pushLoopEvent(e);
  }
  if (Exercise* next = plan->takeNextExercise()) {
    if (!c->offerExerciseFromLoop(next)) plan_handover_ = next;
  }
}

nlohmann::json TherapySession::planJson() const {
  const PlanRunner* plan = plan_.get();
  if (plan == nullptr) return nullptr;
  const auto& steps = plan->plan().steps;
  const std::size_t i = plan->step();
  const bool finished = plan->finished();
  nlohmann::json list = nlohmann::json::array();
  for (std::size_t k = 0; k < steps.size(); ++k) {
    const PlanStep& st = steps[k];
    const bool done = k < i || finished;
    nlohmann::json e{{"exercise", st.exercise}, {"duration_s", st.duration_s}, {"target_repetitions", st.repetitions},
                     {"state", done ? "done" : k == i ? "running" : "to do"}};
    if (!st.preset.empty()) e["preset"] = st.preset;
    if (done) {
      const PlanRunner::StepResult& r = plan->result(k);
      e["repetitions"] = r.repetitions.load();
      e["counted_s"] = static_cast<double>(r.elapsed_us.load()) * 1e-6;
      e["ended_by"] = r.ended.load() == static_cast<uint8_t>(PlanRunner::Ended::kRepetitions) ? "repetitions" : "duration";
    }
    list.push_back(std::move(e));
  }
  const PlanStep& cur = steps[std::min(i, steps.size() - 1)];
  const double elapsed = finished ? cur.duration_s : plan->elapsedS();
  nlohmann::json j{{"step", std::min(i, steps.size() - 1) + 1}, {"steps", steps.size()}, {"finished", finished},
                   {"exercise", cur.exercise}, {"duration_s", cur.duration_s}, {"elapsed_s", elapsed},
                   {"remaining_s", std::max(0.0, cur.duration_s - elapsed)},
                   {"repetitions", finished ? plan->result(steps.size() - 1).repetitions.load() : plan->repetitions()},
                   {"target_repetitions", cur.repetitions}, {"list", list}};
  if (!cur.preset.empty()) j["preset"] = cur.preset;
  if (!plan->plan().name.empty()) j["name"] = plan->plan().name;
  return j;
}

std::string TherapySession::pause() {
  const auto c = controller();
  if (c == nullptr) return "the session has no therapy controller (started without an exercise)";
  if (phase_.load() == 2) return "the session has ended";
  if (c->paused()) return "the session is already paused (resume continues it)";
  c->setPaused(true);
  if (writer_.isOpen()) writer_.pushEvent(statusJson().value("t_s", 0.0), "api-pause");
  return {};
}

std::string TherapySession::resume() {
  const auto c = controller();
  if (c == nullptr) return "the session has no therapy controller (started without an exercise)";
  if (phase_.load() == 2) return "the session has ended";
  if (!c->paused()) return "the session is not paused";
  c->setPaused(false);
  if (writer_.isOpen()) writer_.pushEvent(statusJson().value("t_s", 0.0), "api-resume");
  return {};
}

void TherapySession::onDeviceEvent(const protocol::Event& event) {
  if (!writer_.isOpen()) return;
  record::LoopEvent e;
  e.kind = record::LoopEvent::Kind::kDeviceEvent;
  e.t_s = last_t_s_;  // events arrive in the cycle's poll, before that cycle's onCycle: the previous cycle's time
  e.code = static_cast<uint16_t>(event.code);
  e.channel = event.channel;
  e.detail = event.detail;
  e.value = event.value;
  writer_.pushLoopEvent(e);
}

void TherapySession::requestClearFaults() {
  clear_faults_.store(true);
  if (writer_.isOpen()) writer_.pushEvent(statusJson().value("t_s", 0.0), "api-clear-faults");
}

std::string TherapySession::setExercise(const std::string& name, const nlohmann::json& params) {
  const auto c = controller();
  if (c == nullptr) return "the session has no therapy controller (started without an exercise)";
  if (phase_.load() == 2) return "the session has ended";
  if (plan_ && !plan_->finished()) {
    return "the session follows a plan (step " + std::to_string(plan_->step() + 1) + " of " +
           std::to_string(plan_->plan().steps.size()) + "): its steps change the exercise";
  }
  std::string error;
  std::unique_ptr<Exercise> ex = makeExercise(name, params, c->device(), config_.profile, pattern_, error);
  if (!ex) return error;
  if (writer_.isOpen()) {
    writer_.pushEvent(statusJson().value("t_s", 0.0), "api-exercise", {{"exercise", name}, {"params", ex->params()}});
  }
  c->offerExercise(std::move(ex));
  return {};
}

std::string TherapySession::setLimits(const nlohmann::json& request) {
  const auto c = controller();
  if (c == nullptr) return "the session has no therapy controller";
  if (phase_.load() == 2) return "the session has ended";
  if (!request.is_object() || !request.contains("effort_max") || !request["effort_max"].is_object() ||
      request.size() != 1) {
    return "limits: expected {\"effort_max\": {\"<channel>\": number, ...}}";
  }
  const TherapyDevice& d = c->device();
  PatientLimits ceiling = config_.have_profile ? config_.profile.limits : PatientLimits::deviceDefaults(d);
  PatientLimits next = c->limits();
  for (const auto& [ch, v] : request["effort_max"].items()) {
    const int i = d.channelIndex(ch);
    if (i < 0) return "limits.effort_max." + ch + ": unknown channel for " + d.name();
    if (!v.is_number() || !std::isfinite(v.get<double>())) return "limits.effort_max." + ch + ": expected a number";
    const double x = v.get<double>();
    const double cap = ceiling.effort_max[static_cast<std::size_t>(i)];
    if (x <= 0.0 || x > cap) {
      return "limits.effort_max." + ch + ": must be in (0, " + std::to_string(cap) + "] " + d.effortUnit() +
             " (the patient profile's limit; edit the profile to raise it)";
    }
    next.effort_max[static_cast<std::size_t>(i)] = x;
  }
  c->offerLimits(next);
  {
    std::lock_guard<std::mutex> lock(ctl_mutex_);
    if (guard_) guard_->offerLimits(next);
  }
  if (writer_.isOpen()) writer_.pushEvent(statusJson().value("t_s", 0.0), "api-limits", request);
  return {};
}

nlohmann::json TherapySession::limitsJson() const {
  const auto c = controller();
  if (c == nullptr) return nullptr;
  const PatientLimits l = c->limits();
  const TherapyDevice& d = c->device();
  nlohmann::json j;
  j["effort_unit"] = d.effortUnit();
  for (std::size_t ch = 0; ch < d.channelCount(); ++ch) j["effort_max"][d.channelName(ch)] = l.effort_max[ch];
  for (std::size_t jt = 0; jt < d.jointCount(); ++jt) {
    j["range_deg"][d.jointName(jt)] = {l.flexion_min_rad[jt] * 180.0 / M_PI, l.flexion_max_rad[jt] * 180.0 / M_PI};
  }
  return j;
}

std::string TherapySession::phase() const {
  switch (phase_.load()) {
    case 0: return "starting";
    case 1: return "running";
    default: return "ended";
  }
}

nlohmann::json TherapySession::statusJson() const {
  nlohmann::json j;
  j["phase"] = phase();
  if (config_.have_profile) j["patient"] = config_.profile.patient;
  if (!config_.record_path.empty()) j["record"] = config_.record_path;
  if (writer_.failed()) j["record_error"] = writer_.error();
  const auto c = controller();
  if (c == nullptr) return j;
  const StatusSnapshot s = c->status();
  const TherapyDevice& d = c->device();
  j["device"] = d.name();
  j["exercise"] = exerciseName(s.exercise);
  j["paused"] = c->paused();
  if (config_.self_training) j["self_training"] = true;
  if (plan_) j["plan"] = planJson();
  if (!s.valid) return j;
  j["t_s"] = s.t_s;
  j["cycles"] = s.cycles;
  j["device_mode"] = modeName(static_cast<protocol::Mode>(s.device_mode));
  j["faults"] = faultList(s.fault_bits);
  if (s.fault_bits != 0) j["fault_guidance"] = faultGuidanceJson(s.fault_bits);
  j["estop"] = (s.state_flags & protocol::state::kEstopPressed) != 0;
  j["limited_cycles"] = s.limited_cycles;
  j["effort_unit"] = d.effortUnit();
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  // What was sent, after the limits stage, whichever source commanded (an exercise, Modbus, ...).
  std::array<double, kMaxChannels> sent = s.effort_command;
  {
    std::lock_guard<std::mutex> lock(ctl_mutex_);
    if (guard_) sent = guard_->sentEffort();
  }
  for (std::size_t ch = 0; ch < d.channelCount(); ++ch) {
    j["channels"][d.channelName(ch)] = {{"q_deg", num(s.q_rad[ch] * 180.0 / M_PI)},
                                        {"target_deg", num(s.target_q_rad[ch] * 180.0 / M_PI)},
                                        {"effort_measured", num(s.effort_measured[ch])},
                                        {"effort_command", num(sent[ch])},
                                        {"assist_gain", num(s.assist_gain[ch])},
                                        {"effort_max", num(s.effort_max[ch])}};
  }
  for (std::size_t jt = 0; jt < d.jointCount(); ++jt) {
    j["joints"][d.jointName(jt)] = {{"channel", d.channelName(d.jointChannel(jt))},
                                    {"flexion_deg", num(s.flexion_rad[jt] * 180.0 / M_PI)},
                                    {"rom_deg", {num(s.rom_min_rad[jt] * 180.0 / M_PI), num(s.rom_max_rad[jt] * 180.0 / M_PI)}}};
  }
  return j;
}

void TherapySession::housekeeping() {
  if (const auto c = controller()) c->collectRetired();
}

void TherapySession::onEnd(const nlohmann::json& summary) {
  loop_ctl_ = nullptr;
  loop_guard_ = nullptr;
  (void)summary;
}

int TherapySession::finish(const nlohmann::json& summary, int runner_rc) {
  phase_.store(2);
  const bool recorded = writer_.started();  // a record with its header (not removed by close())
  writer_.close(summary);
  nlohmann::json end = summary;
  int rc = runner_rc;
  if (!config_.record_path.empty()) {
    nlohmann::json r{{"path", config_.record_path},
                     {"cycles_written", writer_.cyclesWritten()},
                     {"cycles_lost", writer_.cyclesLost()},
                     {"cycles_dropped", writer_.cyclesDropped()}};
    if (!recorded) r["removed"] = true;  // ended before its first cycle (or its header failed): no file is left
    if (writer_.failed()) {
      r["error"] = writer_.error();
      if (!end.contains("error")) {
        end["error"] = "the session record could not be written, so the session was stopped (device left safe): " +
                       writer_.error();
      }
      if (rc == 0) rc = record::kExitRecordFailed;
      std::fprintf(stderr, "%s: therapy session stopped: its record %s cannot be written; the device was left safe\n",
                   program_invocation_short_name, config_.record_path.c_str());
    }
    end["session_record"] = r;
  }
  if (!config_.report_path.empty() && !config_.record_path.empty()) {
    if (!recorded || writer_.failed()) {
      end["report"] = {{"error", writer_.failed() ? "not written: the session record failed"
                                                  : "not written: the session ended before its first cycle"}};
    } else {
      const std::string err = writeReport(config_.record_path, config_.previous_record, config_.report_path, nullptr,
                                          config_.transparency_reference);
      end["report"] = err.empty() ? nlohmann::json{{"path", config_.report_path}} : nlohmann::json{{"error", err}};
    }
  }
  if (plan_) end["plan"] = planJson();
  end["exit_code"] = rc;
  std::lock_guard<std::mutex> lock(mutex_);
  end_summary_ = std::move(end);
  finished_ = true;
  return rc;
}

nlohmann::json TherapySession::endSummary() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return end_summary_;
}

}  // namespace phalanx::host::therapy
