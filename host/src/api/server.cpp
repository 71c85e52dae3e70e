#include "phalanx/host/api/server.h"

#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <ctime>
#include <functional>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <thread>
#include <tuple>
#include <vector>

#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/api/socket_access.h"
#include "phalanx/host/config.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/records_dir.h"
#include "phalanx/host/therapy/session_plan.h"
#include "phalanx/host/therapy/therapy_session.h"

namespace phalanx::host::api {
namespace {

volatile std::sig_atomic_t g_api_stop = 0;
void onApiStop(int) { g_api_stop = 1; }

/// 64 KiB: far above any valid request (the largest, "start" with parameters, is < 1 KiB).
constexpr std::size_t kMaxRequestBytes = 64 * 1024;
constexpr int kMaxClients = 16;
/// A request line must be complete this long after its first byte arrived.
constexpr int kLineTimeoutMs = 10000;
/// A connection that sends no request for this long is closed (the CLI's connections last one request).
constexpr int kIdleTimeoutMs = 300000;
/// A client that does not take its answer within this time is dropped.
constexpr int kSendTimeoutMs = 5000;

const char* kApiVersion = "1";

struct RequestError {
  std::string message;
};

/// The hooks runSession polls: the therapy session's, and SIGINT/SIGTERM of the API daemon, so that a signal
/// ends a running session at the loop's next cycle whatever the request threads are doing.
class SignalAwareHooks final : public SessionHooks {
 public:
  explicit SignalAwareHooks(therapy::TherapySession& s) : s_(s) {}
  std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, std::string& error) override {
    return s_.makeController(layout, error);
  }
  std::string onStart(const protocol::DeviceLayout& layout, const nlohmann::json& info) override {
    return s_.onStart(layout, info);
  }
  void onCycle(uint64_t wake_ns, double t_s, const TelemetryFrame& tel, const protocol::Command& cmd) override {
    s_.onCycle(wake_ns, t_s, tel, cmd);
  }
  void onDeviceEvent(const protocol::Event& event) override { s_.onDeviceEvent(event); }
  bool stopRequested() override { return g_api_stop != 0 || s_.stopRequested(); }
  bool takeClearFaultsRequest() override { return s_.takeClearFaultsRequest(); }
  void onEnd(const nlohmann::json& summary) override { s_.onEnd(summary); }

 private:
  therapy::TherapySession& s_;
};

/// lstat: a regular file (never a FIFO, device or symlink, whose open could wait or lead elsewhere).
bool isRegularFile(const std::string& path, struct stat& st) { return ::lstat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode); }

/// Field checks: unknown fields and wrong types are errors naming the field.
void allowFields(const nlohmann::json& req, const std::set<std::string>& allowed) {
  for (const auto& [k, v] : req.items()) {
    if (k == "cmd" || k == "id") continue;
    if (allowed.count(k) == 0) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw RequestError{"field '" + k + "' is not accepted by '" + req["cmd"].get<std::string>() + "'" +
                         (list.empty() ? " (it takes no fields)" : " (accepted: " + list + ")")};
    }
  }
}
std::string strField(const nlohmann::json& req, const char* key, const std::string& def) {
  if (!req.contains(key)) return def;
  if (!req[key].is_string()) throw RequestError{std::string("field '") + key + "': expected a string"};
  return req[key].get<std::string>();
}

std::vector<std::string> listDir(const std::string& dir, const std::string& suffix) {
  std::vector<std::string> out;
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) return out;
  while (dirent* e = ::readdir(d)) {
    const std::string n = e->d_name;
    if (n.size() > suffix.size() && n.compare(n.size() - suffix.size(), suffix.size(), suffix) == 0) out.push_back(n);
  }
  ::closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

class Daemon {
 public:
  explicit Daemon(const ServerConfig& cfg) : cfg_(cfg) {}
  ~Daemon() { stopSession(); }

  nlohmann::json handle(const std::string& line) {
    nlohmann::json req = nlohmann::json::parse(line, nullptr, false);
    nlohmann::json resp;
    try {
      if (req.is_discarded()) throw RequestError{"request is not valid JSON (one JSON object per line)"};
      if (!req.is_object()) throw RequestError{"request must be a JSON object"};
      if (req.contains("id")) resp["id"] = req["id"];
      if (!req.contains("cmd") || !req["cmd"].is_string()) throw RequestError{"missing string field 'cmd'"};
      const std::string cmd = req["cmd"].get<std::string>();
      resp["result"] = dispatch(cmd, req);
      resp["ok"] = true;
    } catch (const RequestError& e) {
      resp["ok"] = false;
      resp["error"] = e.message;
    } catch (const std::exception& e) {  // a request the checks above missed must not end the daemon
      resp["ok"] = false;
      resp["error"] = std::string("request refused: ") + e.what();
    }
    return resp;
  }

  /// From the accept loop: never waits for a request that holds the lock (a stop writing its report).
  void housekeeping() {
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) return;
    if (session_) session_->housekeeping();
    if (session_ && session_done_.load() && thread_.joinable()) {
      thread_.join();
      last_summary_ = session_->endSummary();
    }
  }

  void stopSession() {
    requestStopNow();
    std::lock_guard<std::mutex> lock(mutex_);
    stopLocked();
  }

  /// STOP's first step, for every transport: sets the running session's stop flag, which its loop polls every
  /// cycle. Takes only stop_mutex_, which nothing holds across I/O, so it never waits behind another request.
  /// Returns whether a session was running.
  bool requestStopNow() {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    if (stoppable_ == nullptr || session_done_.load()) return false;
    stoppable_->requestStop();
    return true;
  }

 private:
  nlohmann::json dispatch(const std::string& cmd, const nlohmann::json& req) {
    if (cmd == "version") {
      allowFields(req, {});
      return {{"api_version", kApiVersion}, {"commands", {"version", "status", "start", "stop", "pause", "resume",
                                                          "exercise", "reset", "limits", "profiles", "profile",
                                                          "recordings"}}};
    }
    if (cmd == "status") {
      allowFields(req, {});
      return status();
    }
    if (cmd == "start") return start(req);
    if (cmd == "stop") {
      allowFields(req, {});
      const bool was_running = requestStopNow();  // the loop ends at its next cycle, whatever holds mutex_
      std::lock_guard<std::mutex> lock(mutex_);
      if (!was_running) throw RequestError{"no session is running"};
      return stopLocked();  // waits for the session's end: record closed, report written
    }
    if (cmd == "pause" || cmd == "resume") {
      allowFields(req, {});
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running (nothing to " + cmd + ")"};
      const std::string err = cmd == "pause" ? session_->pause() : session_->resume();
      if (!err.empty()) throw RequestError{err};
      return {{"paused", cmd == "pause"}};
    }
    if (cmd == "exercise" || cmd == "mode") {
      allowFields(req, {"exercise", "params", "preset"});
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running"};
      const auto [name, params] = exerciseOrPreset(req, session_->config().profile, session_->config().have_profile);
      if (session_->config().self_training) checkSelfTrainingStep(session_->config().profile, req.contains("preset") ? strField(req, "preset", "") : name);
      const std::string err = session_->setExercise(name, params);
      if (!err.empty()) throw RequestError{err};
      return {{"exercise", name}};
    }
    if (cmd == "reset") {
      allowFields(req, {});
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running"};
      session_->requestClearFaults();
      return {{"clear_faults", "sent"}};
    }
    if (cmd == "limits") {
      allowFields(req, {"effort_max"});
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running"};
      if (req.contains("effort_max")) {
        const std::string err = session_->setLimits({{"effort_max", req["effort_max"]}});
        if (!err.empty()) throw RequestError{err};
      }
      return session_->limitsJson();
    }
    if (cmd == "profiles") {
      allowFields(req, {});
      nlohmann::json out = nlohmann::json::array();
      for (const auto& f : listDir(cfg_.profiles_dir, ".yaml")) {
        therapy::Profile p;
        const std::string err = therapy::loadProfileFile(cfg_.profiles_dir + "/" + f, p);
        out.push_back(err.empty() ? nlohmann::json{{"file", f}, {"patient", p.patient}, {"device", p.device}, {"valid", true},
                                                   {"presets", therapy::presetsJson(p)},
                                                   {"plans", therapy::plansJson(p)},
                                                   {"self_training", p.self_training.allowed}}
                                  : nlohmann::json{{"file", f}, {"valid", false}, {"error", err}});
      }
      return out;
    }
    if (cmd == "profile") {
      allowFields(req, {"patient"});
      therapy::Profile p;
      loadPatient(strField(req, "patient", ""), p);
      nlohmann::json rom = nlohmann::json::object();
      for (const auto& [j, r] : p.rom_rad) rom[j] = {r.first * 180.0 / M_PI, r.second * 180.0 / M_PI};
      nlohmann::json j{{"patient", p.patient}, {"device", p.device}, {"size", p.size}, {"handedness", p.handedness},
                       {"rom_deg", rom}, {"file", p.source}, {"presets", therapy::presetsJson(p)},
                       {"plans", therapy::plansJson(p)}};
      if (p.self_training.allowed) {
        j["self_training"] = {{"allowed", p.self_training.steps}, {"max_session_s", p.self_training.max_session_s},
                              {"effort_scale", p.self_training.effort_scale}};
      }
      return j;
    }
    if (cmd == "recordings") {
      allowFields(req, {"patient"});
      const std::string patient = strField(req, "patient", "");
      nlohmann::json out = nlohmann::json::array();
      // A patient's records by their parsed name (never a prefix: demo-001's are not demo's), oldest first.
      const auto files = patient.empty() ? listDir(cfg_.records_dir, ".phrec") : therapy::patientRecords(cfg_.records_dir, patient);
      for (const auto& f : files) {
        struct stat st {};
        if (!isRegularFile(cfg_.records_dir + "/" + f, st)) continue;
        const std::string html = f.substr(0, f.size() - 6) + ".html";
        out.push_back({{"file", f}, {"bytes", st.st_size},
                       {"report", ::access((cfg_.records_dir + "/" + html).c_str(), R_OK) == 0 ? html : ""}});
      }
      return out;
    }
    throw RequestError{"unknown command '" + cmd +
                       "' (commands: version, status, start, stop, pause, resume, exercise, reset, limits, profiles, "
                       "profile, recordings)"};
  }

  void loadPatient(const std::string& patient, therapy::Profile& p) {
    if (!std::regex_match(patient, std::regex("[A-Za-z0-9_-]{1,64}"))) {
      throw RequestError{"field 'patient': expected a patient id (1-64 letters, digits, '-' or '_')"};
    }
    const std::string path = cfg_.profiles_dir + "/" + patient + ".yaml";
    struct stat st {};
    if (::lstat(path.c_str(), &st) != 0 && errno == ENOENT) {
      std::string known;
      for (const auto& f : listDir(cfg_.profiles_dir, ".yaml")) known += (known.empty() ? "" : ", ") + f.substr(0, f.size() - 5);
      throw RequestError{"no profile for patient '" + patient + "': cannot read " + path + ": it does not exist (profiles are " +
                         "<profiles-dir>/<patient>.yaml; " +
                         (known.empty() ? "the profiles directory " + cfg_.profiles_dir + " has none"
                                        : "profiles in " + cfg_.profiles_dir + ": " + known) + ")"};
    }
    const std::string err = therapy::loadProfileFile(path, p);
    if (!err.empty()) throw RequestError{"profile refused: " + err};
  }

  bool running() const { return session_ && !session_done_.load(); }

  /// A request's exercise: `preset` (one of the profile's) or `exercise` with `params`, never both.
  static std::pair<std::string, nlohmann::json> exerciseOrPreset(const nlohmann::json& req, const therapy::Profile& p,
                                                                 bool have_profile, const std::string& def = "") {
    if (req.contains("preset")) {
      if (req.contains("exercise") || req.contains("params")) {
        throw RequestError{"field 'preset': give a preset or an exercise with params, not both"};
      }
      const std::string name = strField(req, "preset", "");
      for (const auto& x : p.presets) {
        if (x.name == name) return {x.exercise, x.params};
      }
      std::string list;
      for (const auto& x : p.presets) list += (list.empty() ? "" : ", ") + x.name;
      throw RequestError{"field 'preset': '" + name + "' is not a preset of " +
                         (have_profile ? "patient " + p.patient + " (presets: " + (list.empty() ? "none" : list) + ")"
                                       : "this session (no patient profile)")};
    }
    if (def.empty() && (!req.contains("exercise") || !req["exercise"].is_string())) {
      throw RequestError{"missing string field 'exercise' (or 'preset')"};
    }
    nlohmann::json params;
    if (req.contains("params")) {
      if (!req["params"].is_object()) throw RequestError{"field 'params': expected an object"};
      params = req["params"];
    }
    return {strField(req, "exercise", def), params};
  }

  /// The plan a start asks for: an inline {"steps": [...]}, or the name of a plan of the patient's profile (then
  /// `where` becomes "plans.<name>", so the parser's errors name the profile's plan).
  static const nlohmann::json& requestedPlan(const nlohmann::json& field, const therapy::TherapySessionConfig& tcfg,
                                             std::string& where) {
    if (field.is_object()) return field;
    if (!field.is_string()) {
      throw RequestError{"field 'plan': expected a plan {\"steps\": [...]} or the name of a plan of the patient's profile"};
    }
    const std::string name = field.get<std::string>();
    if (!tcfg.have_profile) {
      throw RequestError{"field 'plan': '" + name + "' names a plan of a patient's profile: give the patient"};
    }
    const therapy::NamedPlan* named = therapy::findPlan(tcfg.profile, name);
    if (named == nullptr) {
      throw RequestError{"field 'plan': '" + name + "' is not a plan of patient " + tcfg.profile.patient +
                         " (plans: " + therapy::planList(tcfg.profile) + ")"};
    }
    where = "plans." + name;
    return named->plan;
  }

  /// Self-training: only what the profile's self_training.allowed lists.
  static void checkSelfTrainingStep(const therapy::Profile& p, const std::string& name) {
    if (p.self_training.steps.count(name) != 0) return;
    std::string list;
    for (const auto& a : p.self_training.steps) list += (list.empty() ? "" : ", ") + a;
    throw RequestError{"self-training: '" + name + "' is not allowed for patient " + p.patient + " (allowed: " + list + ")"};
  }

  /// self_training: true — the profile must allow it; its effort scale lowers the patient's limits (the same
  /// limits stage) and its max_session_s bounds the session.
  static void applySelfTraining(therapy::TherapySessionConfig& tcfg, RunOptions& opt) {
    if (!tcfg.have_profile) throw RequestError{"field 'self_training': needs a patient whose profile allows self-training"};
    const therapy::SelfTraining& st = tcfg.profile.self_training;
    if (!st.allowed) {
      throw RequestError{"field 'self_training': the profile of patient " + tcfg.profile.patient +
                         " does not allow self-training (it has no self_training section)"};
    }
    for (std::size_t c = 0; c < tcfg.profile.limits.channel_count; ++c) tcfg.profile.limits.effort_max[c] *= st.effort_scale;
    if (opt.seconds <= 0.0 || opt.seconds > st.max_session_s) opt.seconds = st.max_session_s;
    tcfg.self_training = true;
  }

  nlohmann::json status() {
    std::lock_guard<std::mutex> lock(mutex_);
    nlohmann::json j{{"api_version", kApiVersion}, {"session_running", running()}};
    if (session_) j["session"] = session_->statusJson();
    if (!last_summary_.is_null()) j["last_session"] = last_summary_;
    return j;
  }

  nlohmann::json start(const nlohmann::json& req) {
    allowFields(req, {"patient", "exercise", "params", "preset", "plan", "self_training", "device", "scenario", "seconds",
                      "seed"});
    std::lock_guard<std::mutex> lock(mutex_);
    if (running()) throw RequestError{"a session is already running (stop it first)"};
    if (thread_.joinable()) thread_.join();
    therapy::TherapySessionConfig tcfg;
    const std::string patient = strField(req, "patient", "");
    if (!patient.empty()) {
      loadPatient(patient, tcfg.profile);
      tcfg.have_profile = true;
    }
    if (req.contains("plan") && (req.contains("exercise") || req.contains("preset") || req.contains("params"))) {
      throw RequestError{"field 'plan': a plan names each step's exercise (leave out exercise, preset and params)"};
    }
    std::string plan_where = "plan";
    const nlohmann::json plan_json = req.contains("plan") ? requestedPlan(req["plan"], tcfg, plan_where) : nlohmann::json();
    std::tie(tcfg.exercise, tcfg.exercise_params) = exerciseOrPreset(req, tcfg.profile, tcfg.have_profile, "assessment");
    if (req.contains("self_training") && !req["self_training"].is_boolean()) {
      throw RequestError{"field 'self_training': expected true or false"};
    }
    const bool self_training = req.value("self_training", false);
    RunOptions opt = cfg_.defaults;
    opt.device = strField(req, "device", opt.device);
    if (req.contains("device")) {
      if (const std::string err = deviceRefusal(opt.device); !err.empty()) throw RequestError{err};
    }
    opt.scenario = strField(req, "scenario", opt.scenario);
    if (req.contains("seconds")) {
      if (!req["seconds"].is_number()) throw RequestError{"field 'seconds': expected a number"};
      opt.seconds = req["seconds"].get<double>();
    }
    if (req.contains("seed")) {
      if (!req["seed"].is_number_unsigned()) throw RequestError{"field 'seed': expected a non-negative integer"};
      opt.seed = req["seed"].get<uint32_t>();
    }
    opt.record_csv.clear();
    opt.live_view = false;
    if (const std::string err = checkSessionLength(opt.seconds, opt.rate_hz); !err.empty()) {
      throw RequestError{(req.contains("seconds") ? "field 'seconds': " : "seconds: ") + err};
    }
    if (const std::string err = validate(opt); !err.empty()) throw RequestError{err};
    if (self_training) applySelfTraining(tcfg, opt);
    // Validate the exercise (or plan) before anything starts: a refused request changes nothing.
    {
      std::string err;
      const std::string dev_name = opt.device.substr(opt.device.find(':') + 1);
      auto device = therapy::makeTherapyDevice(tcfg.have_profile ? tcfg.profile.device : dev_name,
                                               tcfg.profile.kinematics, err);
      if (device) {
        if (tcfg.have_profile && opt.device.rfind("sim:", 0) == 0 && dev_name != tcfg.profile.device) {
          throw RequestError{"profile is for a " + tcfg.profile.device + ", the device is " + opt.device};
        }
        if (req.contains("plan")) {
          const std::set<std::string>* allowed = self_training ? &tcfg.profile.self_training.steps : nullptr;
          if (const std::string perr = therapy::parsePlan(plan_json, *device, tcfg.profile, allowed, tcfg.plan, plan_where);
              !perr.empty()) {
            throw RequestError{perr};
          }
          if (req["plan"].is_string()) tcfg.plan.name = req["plan"].get<std::string>();
          tcfg.exercise = tcfg.plan.steps[0].exercise;
          tcfg.exercise_params = tcfg.plan.steps[0].params;
        } else if (self_training) {
          checkSelfTrainingStep(tcfg.profile, req.contains("preset") ? strField(req, "preset", "") : tcfg.exercise);
        }
        auto pattern = std::make_shared<therapy::Pattern>(device->channelCount());
        if (!therapy::makeExercise(tcfg.exercise, tcfg.exercise_params, *device, tcfg.profile, pattern, err)) {
          throw RequestError{err};
        }
      } else if (opt.device.rfind("sim:", 0) == 0) {
        throw RequestError{err};
      } else if (req.contains("plan") || self_training) {
        throw RequestError{std::string(req.contains("plan") ? "field 'plan'" : "field 'self_training'") +
                           ": cannot be checked before the device is known (give a patient: the profile names the device)"};
      }
    }
    // The previous session of this patient (its newest record), for the report's range-of-motion comparison;
    // sessions without a profile are nobody's, so they have none.
    if (!patient.empty()) tcfg.previous_record = therapy::newestRecord(cfg_.records_dir, patient);
    auto session = std::make_unique<therapy::TherapySession>(tcfg);
    // The record file is created now: a records directory that cannot take it refuses the start.
    if (const std::string err = session->createRecordIn(
            cfg_.records_dir, patient.empty() ? therapy::kAnonymousPatient : patient, std::time(nullptr));
        !err.empty()) {
      throw RequestError{err};
    }
    {
      std::lock_guard<std::mutex> stop_lock(stop_mutex_);
      stoppable_ = nullptr;
    }
    const std::string record = session->config().record_path;
    tcfg.report_path = session->config().report_path;
    session_ = std::move(session);
    session_done_ = false;
    {
      std::lock_guard<std::mutex> stop_lock(stop_mutex_);
      stoppable_ = session_.get();
    }
    therapy::TherapySession* s = session_.get();
    thread_ = std::thread([this, s, opt]() mutable {
      SignalAwareHooks hooks(*s);
      opt.hooks = &hooks;
      nlohmann::json summary;
      const int rc = runSession(opt, summary);
      s->finish(summary, rc);
      session_done_ = true;
    });
    nlohmann::json answer{{"record", record}, {"report", tcfg.report_path}, {"exercise", tcfg.exercise},
                          {"previous_record", tcfg.previous_record}};
    if (!tcfg.plan.empty()) answer["plan_steps"] = tcfg.plan.steps.size();
    if (!tcfg.plan.name.empty()) answer["plan"] = tcfg.plan.name;
    if (self_training) answer["self_training"] = {{"max_session_s", opt.seconds}, {"effort_scale", tcfg.profile.self_training.effort_scale}};
    return answer;
  }

  nlohmann::json stopLocked() {
    if (!session_) return nullptr;
    session_->requestStop();
    if (thread_.joinable()) thread_.join();
    last_summary_ = session_->endSummary();
    return last_summary_;
  }

  /// "" when a client may name `device` in a start request: it is the daemon's own device or on its
  /// --allow-device list, and a serial device is a character device.
  std::string deviceRefusal(const std::string& device) const {
    const auto& allowed = cfg_.allowed_devices;
    if (device != cfg_.defaults.device && std::find(allowed.begin(), allowed.end(), device) == allowed.end()) {
      std::string list = cfg_.defaults.device;
      for (const auto& a : allowed) list += ", " + a;
      return "field 'device': '" + device + "' is not a device this daemon may open (allowed: " + list +
             "; the daemon's --device and --allow-device name them)";
    }
    if (device.rfind("serial:", 0) != 0) return {};
    const std::string path = device.substr(7, device.find('@') == std::string::npos ? std::string::npos : device.find('@') - 7);
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) return "field 'device': " + path + ": " + std::strerror(errno);
    if (!S_ISCHR(st.st_mode)) return "field 'device': " + path + " is not a character device";
    return {};
  }

  ServerConfig cfg_;
  std::mutex mutex_;
  std::mutex stop_mutex_;                      // guards stoppable_ only; never held across I/O
  therapy::TherapySession* stoppable_ = nullptr;  // session_.get() for requestStopNow()
  std::unique_ptr<therapy::TherapySession> session_;
  std::atomic<bool> session_done_{true};
  std::thread thread_;
  nlohmann::json last_summary_;
};

/// Sends all of `text` within kSendTimeoutMs; false if the client does not take it.
bool sendAll(int fd, const std::string& text) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(kSendTimeoutMs);
  for (std::size_t done = 0; done < text.size();) {
    const ssize_t n = ::send(fd, text.data() + done, text.size() - done, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
    pollfd p{fd, POLLOUT, 0};
    if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
  }
  return true;
}

std::string errorLine(const std::string& message) {
  return nlohmann::json{{"ok", false}, {"error", message}}.dump() + "\n";
}

using Handler = std::function<nlohmann::json(const std::string&)>;

/// One client connection, on its own thread: reads JSON lines, answers each in order. Bounded: a line of at
/// most kMaxRequestBytes, complete within kLineTimeoutMs; idle connections closed after kIdleTimeoutMs. A slow
/// or blocking request on one connection never delays another connection's STOP (no lock across requests).
void serveClient(int fd, const Handler& handle) {
  std::string in;
  auto line_started = std::chrono::steady_clock::now();
  auto last_activity = line_started;
  for (;;) {
    for (std::size_t nl; (nl = in.find('\n')) != std::string::npos;) {
      if (nl > kMaxRequestBytes) {
        (void)sendAll(fd, errorLine("request longer than " + std::to_string(kMaxRequestBytes) + " bytes"));
        return;
      }
      const std::string line = in.substr(0, nl);
      in.erase(0, nl + 1);
      if (!sendAll(fd, handle(line).dump() + "\n")) return;
      last_activity = line_started = std::chrono::steady_clock::now();
    }
    if (in.size() > kMaxRequestBytes) {
      (void)sendAll(fd, errorLine("request longer than " + std::to_string(kMaxRequestBytes) + " bytes"));
      return;
    }
    const auto now = std::chrono::steady_clock::now();
    const auto deadline = in.empty() ? last_activity + std::chrono::milliseconds(kIdleTimeoutMs)
                                     : line_started + std::chrono::milliseconds(kLineTimeoutMs);
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count();
    if (left <= 0) {
      if (!in.empty()) {
        (void)sendAll(fd, errorLine("request line not completed within " + std::to_string(kLineTimeoutMs / 1000) + " s"));
      }
      return;
    }
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<long>(left, 1000)));
    if (ready < 0 && errno != EINTR) return;
    if (ready <= 0 || (p.revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) continue;
    if (n <= 0) return;
    if (in.empty()) line_started = std::chrono::steady_clock::now();
    in.append(buf, static_cast<std::size_t>(n));
  }
}

/// The connection threads of the UNIX socket. Only the accept loop's thread touches this object.
class ClientThreads {
 public:
  explicit ClientThreads(Handler handle) : handle_(std::move(handle)) {}
  ~ClientThreads() { closeAll(); }

  std::size_t size() const { return clients_.size(); }

  void add(int fd) {
    auto c = std::make_unique<Client>();
    c->fd = fd;
    Client* raw = c.get();
    c->thread = std::thread([this, raw] {
      serveClient(raw->fd, handle_);
      raw->done = true;
    });
    clients_.push_back(std::move(c));
  }

  /// Joins and closes the connections whose thread has finished.
  void reap() {
    for (auto& c : clients_) {
      if (c->done.load()) finish(*c);
    }
    clients_.erase(std::remove_if(clients_.begin(), clients_.end(), [](const auto& c) { return c->fd < 0; }),
                   clients_.end());
  }

  /// Wakes every connection thread (shutdown of its socket) and joins it.
  void closeAll() {
    for (auto& c : clients_) {
      if (c->fd >= 0) ::shutdown(c->fd, SHUT_RDWR);
    }
    for (auto& c : clients_) finish(*c);
    clients_.clear();
  }

 private:
  struct Client {
    int fd = -1;
    std::thread thread;
    std::atomic<bool> done{false};
  };
  static void finish(Client& c) {
    if (c.thread.joinable()) c.thread.join();
    if (c.fd >= 0) ::close(c.fd);
    c.fd = -1;
  }

  Handler handle_;
  std::vector<std::unique_ptr<Client>> clients_;
};

}  // namespace

namespace {

/// Binds and listens on config.socket_path (a stale socket of a crashed daemon replaced, a live one or any
/// other file refused). Returns the listening descriptor, or -1 after printing why.
int listenOn(const ServerConfig& config) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (config.socket_path.empty() || config.socket_path.size() >= sizeof addr.sun_path) {
    std::fprintf(stderr, "phalanxd: error: --api: socket path empty or longer than %zu bytes\n", sizeof addr.sun_path - 1);
    return -1;
  }
  if (const std::string err = prepareSocketDirectory(config.socket_path, config.api_group); !err.empty()) {
    std::fprintf(stderr, "phalanxd: error: --api %s: %s\n", config.socket_path.c_str(), err.c_str());
    return -1;
  }
  std::memcpy(addr.sun_path, config.socket_path.c_str(), config.socket_path.size() + 1);
  const int lfd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (lfd < 0) {
    std::fprintf(stderr, "phalanxd: error: socket: %s\n", std::strerror(errno));
    return -1;
  }
  struct stat st {};
  if (::lstat(config.socket_path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      std::fprintf(stderr, "phalanxd: error: %s exists and is not a socket\n", config.socket_path.c_str());
      ::close(lfd);
      return -1;
    }
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live = ::connect(probe, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0;
    ::close(probe);
    if (live) {
      std::fprintf(stderr, "phalanxd: error: another phalanxd already serves %s\n", config.socket_path.c_str());
      ::close(lfd);
      return -1;
    }
    ::unlink(config.socket_path.c_str());
  }
  const mode_t old_umask = ::umask(0777 & ~config.socket_mode);
  const int brc = ::bind(lfd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  ::umask(old_umask);
  if (brc != 0 || ::listen(lfd, kMaxClients) != 0) {
    std::fprintf(stderr, "phalanxd: error: cannot serve %s: %s\n", config.socket_path.c_str(), std::strerror(errno));
    ::close(lfd);
    return -1;
  }
  ::chmod(config.socket_path.c_str(), config.socket_mode);
  return lfd;
}

/// Accepts every pending connection: refused (with a one-line answer) when the peer's credentials are not
/// allowed or kMaxClients are connected, else served on its own thread.
void acceptClients(int lfd, const ServerConfig& config, ClientThreads& clients) {
  for (;;) {
    const int cfd = ::accept4(lfd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (cfd < 0) return;
    std::string refusal = refusePeer(cfd, config.api_group);
    if (refusal.empty() && clients.size() >= static_cast<std::size_t>(kMaxClients)) {
      refusal = "too many clients (" + std::to_string(kMaxClients) + " connected)";
    }
    if (!refusal.empty()) {
      const std::string line = errorLine(refusal);
      (void)!::send(cfd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      ::close(cfd);
      continue;
    }
    clients.add(cfd);
  }
}

void writeDashboardUrlFile(const std::string& url_file, const std::string& url, unsigned mode) {
  ::unlink(url_file.c_str());
  const int ufd = ::open(url_file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (ufd < 0) return;
  const std::string text = url + "\n";
  (void)!::write(ufd, text.data(), text.size());
  ::fchmod(ufd, mode);
  ::close(ufd);
}

}  // namespace

std::function<nlohmann::json(const std::string&)> makeRequestHandler(const ServerConfig& config) {
  auto daemon = std::make_shared<Daemon>(config);
  return [daemon](const std::string& line) { return daemon->handle(line); };
}

/// The records directory is created (with its missing parents, mode 0750: patient data) when it does not exist,
/// so `--records-dir records` works on a fresh machine; a directory that cannot be created ends the daemon with
/// the reason before it serves anything, never a session that fails after `start` answered.
static std::string prepareRecordsDirectory(const std::string& dir) {
  if (dir.empty()) return "--records-dir: must not be empty";
  struct stat st {};
  if (::stat(dir.c_str(), &st) == 0) {
    return S_ISDIR(st.st_mode) ? std::string() : "--records-dir " + dir + ": exists and is not a directory";
  }
  for (std::size_t pos = 1;; ++pos) {
    pos = dir.find('/', pos);
    const std::string part = dir.substr(0, pos);
    if (::mkdir(part.c_str(), 0750) != 0 && errno != EEXIST) {
      return "--records-dir " + dir + ": cannot create " + part + ": " + std::strerror(errno);
    }
    if (pos == std::string::npos) break;
  }
  std::fprintf(stderr, "phalanxd: created the records directory %s\n", dir.c_str());
  return {};
}

int serve(const ServerConfig& config) {
  if (const std::string err = prepareRecordsDirectory(config.records_dir); !err.empty()) {
    std::fprintf(stderr, "phalanxd: error: %s\n", err.c_str());
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = onApiStop;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  const int lfd = listenOn(config);
  if (lfd < 0) return 3;
  std::fprintf(stderr, "phalanxd: control API on %s\n", config.socket_path.c_str());
  std::printf("API %s\n", config.socket_path.c_str());
  std::fflush(stdout);

  Daemon daemon(config);
  // Requests from every connection and from the dashboard run concurrently, each on its own thread: the daemon
  // state they touch is guarded inside Daemon, and STOP never waits behind another request (requestStopNow).
  auto handle = [&daemon](const std::string& line) { return daemon.handle(line); };
  std::unique_ptr<Dashboard> dashboard;
  const std::string url_file = config.socket_path + ".dashboard";
  if (config.dashboard.enabled) {
    dashboard = std::make_unique<Dashboard>(config.dashboard, handle);
    if (const std::string err = dashboard->start(); !err.empty()) {
      std::fprintf(stderr, "phalanxd: error: %s\n", err.c_str());
      ::close(lfd);
      ::unlink(config.socket_path.c_str());
      return 3;
    }
    writeDashboardUrlFile(url_file, dashboard->url(), config.socket_mode);
    std::fprintf(stderr, "phalanxd: dashboard on http://%s:%u/ (URL with its access token in %s)\n",
                 config.dashboard.address.c_str(), dashboard->port(), url_file.c_str());
    std::printf("DASHBOARD %s\n", dashboard->url().c_str());
    std::fflush(stdout);
  }
  ClientThreads clients(handle);
  while (g_api_stop == 0) {
    pollfd p{lfd, POLLIN, 0};
    ::poll(&p, 1, 100);
    daemon.housekeeping();
    clients.reap();
    if (p.revents & POLLIN) acceptClients(lfd, config, clients);
  }
  std::fprintf(stderr, "phalanxd: stopping\n");
  daemon.requestStopNow();
  if (dashboard) {
    dashboard->stop();
    ::unlink(url_file.c_str());
  }
  clients.closeAll();
  daemon.stopSession();
  ::close(lfd);
  ::unlink(config.socket_path.c_str());
  return 0;
}

}  // namespace phalanx::host::api
