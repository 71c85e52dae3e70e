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
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <thread>
#include <vector>

#include "phalanx/host/api/dashboard.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/records_dir.h"
#include "phalanx/host/therapy/therapy_session.h"

namespace phalanx::host::api {
namespace {

volatile std::sig_atomic_t g_api_stop = 0;
void onApiStop(int) { g_api_stop = 1; }

/// 64 KiB: far above any valid request (the largest, "start" with parameters, is < 1 KiB).
constexpr std::size_t kMaxRequestBytes = 64 * 1024;
constexpr int kMaxClients = 16;

const char* kApiVersion = "1";

struct RequestError {
  std::string message;
};

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
    }
    return resp;
  }

  void housekeeping() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (session_) session_->housekeeping();
    if (session_ && session_done_.load() && thread_.joinable()) {
      thread_.join();
      last_summary_ = session_->endSummary();
    }
  }

  void stopSession() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopLocked();
  }

 private:
  nlohmann::json dispatch(const std::string& cmd, const nlohmann::json& req) {
    if (cmd == "version") {
      allowFields(req, {});
      return {{"api_version", kApiVersion}, {"commands", {"version", "status", "start", "stop", "exercise", "reset",
                                                          "limits", "profiles", "profile", "recordings"}}};
    }
    if (cmd == "status") {
      allowFields(req, {});
      return status();
    }
    if (cmd == "start") return start(req);
    if (cmd == "stop") {
      allowFields(req, {});
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running"};
      return stopLocked();
    }
    if (cmd == "exercise" || cmd == "mode") {
      allowFields(req, {"exercise", "params"});
      if (!req.contains("exercise") || !req["exercise"].is_string()) throw RequestError{"missing string field 'exercise'"};
      std::lock_guard<std::mutex> lock(mutex_);
      if (!running()) throw RequestError{"no session is running"};
      const std::string err = session_->setExercise(req["exercise"].get<std::string>(),
                                                    req.contains("params") ? req["params"] : nlohmann::json());
      if (!err.empty()) throw RequestError{err};
      return {{"exercise", req["exercise"]}};
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
        out.push_back(err.empty() ? nlohmann::json{{"file", f}, {"patient", p.patient}, {"device", p.device}, {"valid", true}}
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
      return {{"patient", p.patient}, {"device", p.device}, {"size", p.size}, {"handedness", p.handedness},
              {"rom_deg", rom}, {"file", p.source}};
    }
    if (cmd == "recordings") {
      allowFields(req, {"patient"});
      const std::string patient = strField(req, "patient", "");
      nlohmann::json out = nlohmann::json::array();
      // A patient's records by their parsed name (never a prefix: demo-001's are not demo's), oldest first.
      const auto files = patient.empty() ? listDir(cfg_.records_dir, ".phrec") : therapy::patientRecords(cfg_.records_dir, patient);
      for (const auto& f : files) {
        struct stat st {};
        ::stat((cfg_.records_dir + "/" + f).c_str(), &st);
        const std::string html = f.substr(0, f.size() - 6) + ".html";
        out.push_back({{"file", f}, {"bytes", st.st_size},
                       {"report", ::access((cfg_.records_dir + "/" + html).c_str(), R_OK) == 0 ? html : ""}});
      }
      return out;
    }
    throw RequestError{"unknown command '" + cmd +
                       "' (commands: version, status, start, stop, exercise, reset, limits, profiles, profile, recordings)"};
  }

  void loadPatient(const std::string& patient, therapy::Profile& p) {
    if (!std::regex_match(patient, std::regex("[A-Za-z0-9_-]{1,64}"))) {
      throw RequestError{"field 'patient': expected a patient id (1-64 letters, digits, '-' or '_')"};
    }
    const std::string err = therapy::loadProfileFile(cfg_.profiles_dir + "/" + patient + ".yaml", p);
    if (!err.empty()) throw RequestError{"profile refused: " + err};
  }

  bool running() const { return session_ && !session_done_.load(); }

  nlohmann::json status() {
    std::lock_guard<std::mutex> lock(mutex_);
    nlohmann::json j{{"api_version", kApiVersion}, {"session_running", running()}};
    if (session_) j["session"] = session_->statusJson();
    if (!last_summary_.is_null()) j["last_session"] = last_summary_;
    return j;
  }

  nlohmann::json start(const nlohmann::json& req) {
    allowFields(req, {"patient", "exercise", "params", "device", "scenario", "seconds", "seed"});
    std::lock_guard<std::mutex> lock(mutex_);
    if (running()) throw RequestError{"a session is already running (stop it first)"};
    if (thread_.joinable()) thread_.join();
    therapy::TherapySessionConfig tcfg;
    const std::string patient = strField(req, "patient", "");
    if (!patient.empty()) {
      loadPatient(patient, tcfg.profile);
      tcfg.have_profile = true;
    }
    tcfg.exercise = strField(req, "exercise", "assessment");
    if (req.contains("params")) {
      if (!req["params"].is_object()) throw RequestError{"field 'params': expected an object"};
      tcfg.exercise_params = req["params"];
    }
    RunOptions opt = cfg_.defaults;
    opt.device = strField(req, "device", opt.device);
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
    if (const std::string err = validate(opt); !err.empty()) throw RequestError{err};
    // Validate the exercise before anything starts: a refused request changes nothing.
    {
      std::string err;
      const std::string dev_name = opt.device.substr(opt.device.find(':') + 1);
      auto device = therapy::makeTherapyDevice(tcfg.have_profile ? tcfg.profile.device : dev_name,
                                               tcfg.profile.kinematics, err);
      if (device) {
        if (tcfg.have_profile && opt.device.rfind("sim:", 0) == 0 && dev_name != tcfg.profile.device) {
          throw RequestError{"profile is for a " + tcfg.profile.device + ", the device is " + opt.device};
        }
        auto pattern = std::make_shared<therapy::Pattern>(device->channelCount());
        if (!therapy::makeExercise(tcfg.exercise, tcfg.exercise_params, *device, tcfg.profile, pattern, err)) {
          throw RequestError{err};
        }
      } else if (opt.device.rfind("sim:", 0) == 0) {
        throw RequestError{err};
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
    const std::string record = session->config().record_path;
    tcfg.report_path = session->config().report_path;
    session_ = std::move(session);
    session_done_ = false;
    therapy::TherapySession* s = session_.get();
    thread_ = std::thread([this, s, opt]() mutable {
      opt.hooks = s;
      nlohmann::json summary;
      const int rc = runSession(opt, summary);
      s->finish(summary, rc);
      session_done_ = true;
    });
    return {{"record", record}, {"report", tcfg.report_path}, {"exercise", tcfg.exercise},
            {"previous_record", tcfg.previous_record}};
  }

  nlohmann::json stopLocked() {
    if (!session_) return nullptr;
    session_->requestStop();
    if (thread_.joinable()) thread_.join();
    last_summary_ = session_->endSummary();
    return last_summary_;
  }

  ServerConfig cfg_;
  std::mutex mutex_;
  std::unique_ptr<therapy::TherapySession> session_;
  std::atomic<bool> session_done_{true};
  std::thread thread_;
  nlohmann::json last_summary_;
};

struct Client {
  int fd = -1;
  std::string in;
};

}  // namespace

std::string defaultSocketPath() {
  if (const char* x = std::getenv("XDG_RUNTIME_DIR"); x != nullptr && *x != 0) return std::string(x) + "/phalanxd.sock";
  return "/tmp/phalanxd-" + std::to_string(::getuid()) + ".sock";
}

int serve(const ServerConfig& config) {
  struct sigaction sa {};
  sa.sa_handler = onApiStop;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  signal(SIGPIPE, SIG_IGN);

  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (config.socket_path.empty() || config.socket_path.size() >= sizeof addr.sun_path) {
    std::fprintf(stderr, "phalanxd: error: --api: socket path empty or longer than %zu bytes\n", sizeof addr.sun_path - 1);
    return 2;
  }
  std::memcpy(addr.sun_path, config.socket_path.c_str(), config.socket_path.size() + 1);
  const int lfd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (lfd < 0) {
    std::fprintf(stderr, "phalanxd: error: socket: %s\n", std::strerror(errno));
    return 3;
  }
  // A socket file left by a crashed daemon is replaced; one a live daemon answers on is not.
  struct stat st {};
  if (::lstat(config.socket_path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      std::fprintf(stderr, "phalanxd: error: %s exists and is not a socket\n", config.socket_path.c_str());
      return 3;
    }
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool live = ::connect(probe, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0;
    ::close(probe);
    if (live) {
      std::fprintf(stderr, "phalanxd: error: another phalanxd already serves %s\n", config.socket_path.c_str());
      return 3;
    }
    ::unlink(config.socket_path.c_str());
  }
  const mode_t old_umask = ::umask(0777 & ~config.socket_mode);
  const int brc = ::bind(lfd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  ::umask(old_umask);
  if (brc != 0 || ::listen(lfd, kMaxClients) != 0) {
    std::fprintf(stderr, "phalanxd: error: cannot serve %s: %s\n", config.socket_path.c_str(), std::strerror(errno));
    ::close(lfd);
    return 3;
  }
  ::chmod(config.socket_path.c_str(), config.socket_mode);
  std::fprintf(stderr, "phalanxd: control API on %s\n", config.socket_path.c_str());
  std::printf("API %s\n", config.socket_path.c_str());
  std::fflush(stdout);

  Daemon daemon(config);
  // One request at a time, whichever way it came (UNIX socket or the dashboard): the same validated handler.
  std::mutex request_mutex;
  auto handle = [&daemon, &request_mutex](const std::string& line) {
    std::lock_guard<std::mutex> lock(request_mutex);
    return daemon.handle(line);
  };
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
    ::unlink(url_file.c_str());
    const int ufd = ::open(url_file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0600);
    if (ufd >= 0) {
      const std::string text = dashboard->url() + "\n";
      (void)!::write(ufd, text.data(), text.size());
      ::fchmod(ufd, config.socket_mode);
      ::close(ufd);
    }
    std::fprintf(stderr, "phalanxd: dashboard on http://%s:%u/ (URL with its access token in %s)\n",
                 config.dashboard.address.c_str(), dashboard->port(), url_file.c_str());
    std::printf("DASHBOARD %s\n", dashboard->url().c_str());
    std::fflush(stdout);
  }
  std::vector<Client> clients;
  while (g_api_stop == 0) {
    std::vector<pollfd> fds;
    fds.push_back({lfd, POLLIN, 0});
    for (const auto& c : clients) fds.push_back({c.fd, POLLIN, 0});
    ::poll(fds.data(), fds.size(), 100);
    daemon.housekeeping();
    if (fds[0].revents & POLLIN) {
      for (;;) {
        const int cfd = ::accept4(lfd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
        if (cfd < 0) break;
        if (clients.size() >= static_cast<std::size_t>(kMaxClients)) {
          const char* msg = "{\"ok\":false,\"error\":\"too many clients\"}\n";
          (void)!::send(cfd, msg, std::strlen(msg), MSG_NOSIGNAL);
          ::close(cfd);
          continue;
        }
        clients.push_back({cfd, {}});
      }
    }
    for (std::size_t i = 1; i < fds.size(); ++i) {
      if ((fds[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      Client& c = clients[i - 1];
      char buf[4096];
      const ssize_t n = ::recv(c.fd, buf, sizeof buf, 0);
      if (n <= 0) {
        ::close(c.fd);
        c.fd = -1;
        continue;
      }
      c.in.append(buf, static_cast<std::size_t>(n));
      for (std::size_t nl; c.fd >= 0 && (nl = c.in.find('\n')) != std::string::npos;) {
        const std::string line = c.in.substr(0, nl);
        c.in.erase(0, nl + 1);
        const std::string out = handle(line).dump() + "\n";
        // Replies are small; a client that does not read its answer is dropped rather than blocking the daemon.
        if (::send(c.fd, out.data(), out.size(), MSG_NOSIGNAL | MSG_DONTWAIT) != static_cast<ssize_t>(out.size())) {
          ::close(c.fd);
          c.fd = -1;
        }
      }
      if (c.fd >= 0 && c.in.size() > kMaxRequestBytes) {
        const char* msg = "{\"ok\":false,\"error\":\"request longer than 65536 bytes\"}\n";
        (void)!::send(c.fd, msg, std::strlen(msg), MSG_NOSIGNAL | MSG_DONTWAIT);
        ::close(c.fd);
        c.fd = -1;
      }
    }
    clients.erase(std::remove_if(clients.begin(), clients.end(), [](const Client& c) { return c.fd < 0; }),
                  clients.end());
  }
  std::fprintf(stderr, "phalanxd: stopping\n");
  if (dashboard) {
    dashboard->stop();
    ::unlink(url_file.c_str());
  }
  daemon.stopSession();
  for (const auto& c : clients) ::close(c.fd);
  ::close(lfd);
  ::unlink(config.socket_path.c_str());
  return 0;
}

}  // namespace phalanx::host::api
