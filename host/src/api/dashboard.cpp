#include "phalanx/host/api/dashboard.h"

#include <arpa/inet.h>
#include <poll.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <unistd.h>

#include <httplib.h>

#include <chrono>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <set>
#include "phalanx/host/therapy/guidance.h"

namespace phalanx::host::api {

// dashboard_assets.cpp, generated at configure time from host/web/ (the page and its canvas plotter are
// compiled into the binary: no CDN, no files to install).
const char* dashboardHtml();
const char* dashboardJs();

namespace {

/// Connections served at once. A page keeps one keep-alive connection polling; a clinic has one or two screens
/// open. Every served connection has its own worker, so a slow client never queues another one's STOP.
constexpr int kMaxConnections = 16;
/// Workers: one per served connection, plus spares that answer connections over the limit with a 503 at once.
constexpr int kWorkers = kMaxConnections + 4;
/// The largest valid API request is < 1 KiB; the socket API's limit.
constexpr std::size_t kMaxBodyBytes = 64 * 1024;
/// A request (line, headers and body) must arrive whole within this time, and be at most this many bytes on
/// the wire (chunk framing included): a client sending a byte now and then holds its connection 10 s at most.
constexpr auto kRequestDeadline = std::chrono::seconds(10);
constexpr std::size_t kMaxRequestWireBytes = 1024 * 1024;
constexpr int kReadTimeoutMs = 5000;
constexpr int kWriteTimeoutMs = 5000;
constexpr int kKeepAliveTimeoutMs = 2000;
constexpr std::size_t kKeepAliveMaxCount = 200;

std::string bodyTooLong() {
  return "{\"ok\":false,\"error\":\"request body longer than " + std::to_string(kMaxBodyBytes) + " bytes\"}";
}

bool waitFor(int fd, short events, int timeout_ms) {
  pollfd p{fd, events, 0};
  for (;;) {
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0 && errno == EINTR) continue;
    return r > 0 && (p.revents & (events | POLLHUP | POLLERR)) != 0;
  }
}

void addressOf(int fd, bool peer, std::string& ip, int& port) {
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  const int rc = peer ? ::getpeername(fd, reinterpret_cast<sockaddr*>(&ss), &len)
                      : ::getsockname(fd, reinterpret_cast<sockaddr*>(&ss), &len);
  char buf[INET6_ADDRSTRLEN] = "";
  port = 0;
  if (rc == 0 && ss.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&ss);
    ::inet_ntop(AF_INET, &a->sin_addr, buf, sizeof buf);
    port = ntohs(a->sin_port);
  } else if (rc == 0 && ss.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&ss);
    ::inet_ntop(AF_INET6, &a->sin6_addr, buf, sizeof buf);
    port = ntohs(a->sin6_port);
  }
  ip = buf;
}

/// One request's view of its connection: reads end at the request's deadline or byte budget (each read also
/// waits at most kReadTimeoutMs), writes wait at most kWriteTimeoutMs.
class RequestStream final : public httplib::Stream {
 public:
  explicit RequestStream(int fd) : fd_(fd), deadline_(std::chrono::steady_clock::now() + kRequestDeadline) {}

  bool is_readable() const override { return pos_ < len_ || waitFor(fd_, POLLIN, readWaitMs()); }
  bool is_writable() const override { return waitFor(fd_, POLLOUT, kWriteTimeoutMs); }
  ssize_t read(char* ptr, size_t size) override {
    if (pos_ == len_ && !fill()) return -1;
    const size_t n = std::min(size, len_ - pos_);
    std::memcpy(ptr, buf_ + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    return ::send(fd_, ptr, size, MSG_NOSIGNAL);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { addressOf(fd_, true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { addressOf(fd_, false, ip, port); }
  socket_t socket() const override { return fd_; }

  /// The request ran into its deadline or byte budget, or its handler asked for the connection to close.
  bool mustClose() const { return exhausted_ || close_; }
  void closeAfterResponse() { close_ = true; }

 private:
  int readWaitMs() const {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - std::chrono::steady_clock::now());
    return static_cast<int>(std::max<long>(0, std::min<long>(left.count(), kReadTimeoutMs)));
  }
  bool fill() {
    if (received_ >= kMaxRequestWireBytes || std::chrono::steady_clock::now() >= deadline_ ||
        !waitFor(fd_, POLLIN, readWaitMs())) {
      exhausted_ = true;
      return false;
    }
    const size_t want = std::min(sizeof buf_, kMaxRequestWireBytes - received_);
    const ssize_t n = ::recv(fd_, buf_, want, 0);
    if (n <= 0) {
      exhausted_ = true;
      return false;
    }
    received_ += static_cast<size_t>(n);
    pos_ = 0;
    len_ = static_cast<size_t>(n);
    return true;
  }

  int fd_;
  std::chrono::steady_clock::time_point deadline_;
  char buf_[4096];
  size_t pos_ = 0, len_ = 0, received_ = 0;
  bool exhausted_ = false, close_ = false;
};

/// The stream of the request this worker thread is serving (for handlers that must close the connection).
thread_local RequestStream* t_stream = nullptr;

/// cpp-httplib's server with its connection loop replaced: at most kMaxConnections served (more get a 503 at
/// once, never a place in a queue), each request bounded by RequestStream, idle keep-alive ended after
/// kKeepAliveTimeoutMs. cpp-httplib 0.11's own loop bounds only each single read, so a client sending a
/// header byte every few seconds held a worker for ever.
class BoundedServer final : public httplib::Server {
 public:
  std::atomic<int> connections{0};
  /// One connection's requests from memory (Dashboard::serveInMemory): the same request processing as a socket.
  std::string serveMemory(const std::string& bytes);

  /// Ends every open connection now: no new request is read, and a read or write waiting on a connection's
  /// socket returns at once. httplib::Server::stop() only closes the listener (and is_running() stays true until
  /// every worker has finished), so a page polling on a keep-alive connection kept its worker, and stop(), busy
  /// for up to kKeepAliveMaxCount requests (20 s at the page's 100 ms).
  void closeConnections() {
    closing_ = true;
    std::lock_guard<std::mutex> lock(open_mutex_);
    for (int fd : open_) ::shutdown(fd, SHUT_RDWR);
  }

 private:
  bool process_and_close_socket(socket_t sock) override {
    const int served = ++connections;
    bool ok = false;
    if (served > kMaxConnections) {
      refuseBusy(sock);
    } else if (track(sock)) {
      ok = serveRequests(sock);
      untrack(sock);
    }
    --connections;
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
    return ok;
  }

  /// Registers an open connection for closeConnections(); false once closing (the connection is not served).
  /// The set only holds descriptors not yet closed, so a shutdown() never reaches a reused descriptor.
  bool track(int sock) {
    std::lock_guard<std::mutex> lock(open_mutex_);
    if (closing_) return false;
    open_.insert(sock);
    return true;
  }
  void untrack(int sock) {
    std::lock_guard<std::mutex> lock(open_mutex_);
    open_.erase(sock);
  }

  bool serveRequests(int sock) {
    bool ok = false;
    for (size_t left = kKeepAliveMaxCount; left > 0 && !closing_ && waitForRequest(sock); --left) {
      RequestStream strm(sock);
      t_stream = &strm;
      bool closed = false;
      ok = process_request(strm, left == 1, closed, nullptr);
      t_stream = nullptr;
      if (!ok || closed || strm.mustClose()) break;
    }
    return ok;
  }

  bool waitForRequest(int sock) const {
    for (int waited = 0; waited < kKeepAliveTimeoutMs && is_running() && !closing_; waited += 100) {
      if (waitFor(sock, POLLIN, 100)) return true;
    }
    return false;
  }

  static void refuseBusy(int sock) {
    const std::string body = "{\"ok\":false,\"error\":\"dashboard busy: " + std::to_string(kMaxConnections) +
                             " connections are open\"}";
    const std::string resp = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nContent-Length: " +
                             std::to_string(body.size()) + "\r\nConnection: close\r\nCache-Control: no-store\r\n\r\n" + body;
    (void)!::send(sock, resp.data(), resp.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  }

  std::atomic<bool> closing_{false};
  std::mutex open_mutex_;  // guards open_
  std::set<int> open_;
};

/// A connection whose bytes are all in memory: reads end with them, writes are collected.
class MemoryStream final : public httplib::Stream {
 public:
  explicit MemoryStream(const std::string& in) : in_(in) {}
  bool is_readable() const override { return pos_ < in_.size(); }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    if (pos_ >= in_.size()) return -1;
    const size_t n = std::min(size, in_.size() - pos_);
    std::memcpy(ptr, in_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    out_.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { ip = "127.0.0.1", port = 1; }
  void get_local_ip_and_port(std::string& ip, int& port) const override { ip = "127.0.0.1", port = 0; }
  socket_t socket() const override { return -1; }
  bool exhausted() const { return pos_ >= in_.size(); }
  const std::string& output() const { return out_; }

 private:
  const std::string& in_;
  size_t pos_ = 0;
  std::string out_;
};

std::string BoundedServer::serveMemory(const std::string& bytes) {
  MemoryStream strm(bytes);
  for (size_t left = kKeepAliveMaxCount; left > 0 && !strm.exhausted(); --left) {
    bool closed = false;
    if (!process_request(strm, left == 1, closed, nullptr) || closed) break;
  }
  return strm.output();
}

std::string hostPort(const std::string& address, uint16_t port) {
  const bool v6 = address.find(':') != std::string::npos;
  return (v6 ? "[" + address + "]" : address) + ":" + std::to_string(port);
}

bool tokensEqual(const std::string& a, const std::string& b) {
  // Constant time over the expected length: the comparison does not tell how many characters matched.
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

nlohmann::json num(const nlohmann::json& v) { return v.is_number() ? v : nlohmann::json(nullptr); }

}  // namespace

bool isLoopbackAddress(const std::string& address) {
  in_addr a4{};
  if (::inet_pton(AF_INET, address.c_str(), &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
  in6_addr a6{};
  if (::inet_pton(AF_INET6, address.c_str(), &a6) == 1) return IN6_IS_ADDR_LOOPBACK(&a6);
  return false;
}

std::string parseDashboardSpec(const std::string& spec, DashboardOptions& out) {
  std::string address, port;
  if (!spec.empty() && spec[0] == '[') {
    const auto close = spec.find(']');
    if (close == std::string::npos || close + 1 >= spec.size() || spec[close + 1] != ':') {
      return "--dashboard: '" + spec + "' is not [IPV6]:PORT";
    }
    address = spec.substr(1, close - 1);
    port = spec.substr(close + 2);
  } else {
    const auto colon = spec.rfind(':');
    if (colon == std::string::npos || spec.find(':') != colon) return "--dashboard: '" + spec + "' is not ADDRESS:PORT";
    address = spec.substr(0, colon);
    port = spec.substr(colon + 1);
  }
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
      std::stoul(port) > 65535) {
    return "--dashboard: port '" + port + "' is not 0..65535";
  }
  DashboardOptions o = out;
  o.enabled = true;
  o.address = address;
  o.port = static_cast<uint16_t>(std::stoul(port));
  if (std::string err = validateDashboardOptions(o); !err.empty()) return err;
  out = o;
  return {};
}

std::string validateDashboardOptions(const DashboardOptions& opt) {
  in_addr a4{};
  in6_addr a6{};
  if (::inet_pton(AF_INET, opt.address.c_str(), &a4) != 1 && ::inet_pton(AF_INET6, opt.address.c_str(), &a6) != 1) {
    return "dashboard address '" + opt.address + "' is not an IPv4 or IPv6 address literal";
  }
  if (!isLoopbackAddress(opt.address) && !opt.allow_remote) {
    return "dashboard address " + opt.address +
           " is not a loopback address: the dashboard serves patient data and session controls over plain HTTP; "
           "set dashboard.allow_remote: true in the configuration file to serve it on a network";
  }
  return {};
}

struct Dashboard::Http {
  BoundedServer server;
};

Dashboard::Dashboard(const DashboardOptions& options, RequestHandler handler, Sampling sampling)
    : options_(options), handler_(std::move(handler)), sampling_(sampling), http_(std::make_unique<Http>()) {}

Dashboard::~Dashboard() { stop(); }

std::string Dashboard::url() const { return "http://" + hostPort(options_.address, port_) + "/#token=" + token_; }

std::string Dashboard::start() {
  if (std::string err = validateDashboardOptions(options_); !err.empty()) return err;
  unsigned char raw[16];
  if (::getrandom(raw, sizeof raw, 0) != static_cast<ssize_t>(sizeof raw)) return "dashboard: no random token";
  char hex[3];
  token_.clear();
  for (unsigned char b : raw) {
    std::snprintf(hex, sizeof hex, "%02x", b);
    token_ += hex;
  }
  routes();
  httplib::Server& s = http_->server;
  int port = -1;
  if (options_.port == 0) {
    port = s.bind_to_any_port(options_.address);
  } else if (s.bind_to_port(options_.address, options_.port)) {
    port = options_.port;
  }
  if (port <= 0) return "dashboard: cannot listen on " + hostPort(options_.address, options_.port);
  port_ = static_cast<uint16_t>(port);
  running_ = true;
  listen_thread_ = std::thread([this] { http_->server.listen_after_bind(); });
  // Serving before start() returns, so that stop() (which only stops a running server) can never miss it.
  for (int i = 0; i < 1000 && !http_->server.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  if (sampling_ == Sampling::kPolled) sample_thread_ = std::thread([this] { sampleLoop(); });
  return {};
}

std::string Dashboard::serveInMemory(const std::string& request_bytes, const std::string& token) {
  if (running_) return {};
  token_ = token;
  routes();
  return http_->server.serveMemory(request_bytes);
}

void Dashboard::routes() {
  if (routes_set_) return;
  routes_set_ = true;
  httplib::Server& s = http_->server;
  s.new_task_queue = [] { return new httplib::ThreadPool(kWorkers); };
  // cpp-httplib sets SO_REUSEPORT by default, which would let a second process bind the same port and take
  // connections; a listener here is exclusive (SO_REUSEADDR only, for restarts).
  s.set_socket_options([](int sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  // Bodies with a Content-Length above the limit are refused before they are read (413); chunked bodies are
  // counted as they arrive (/api/request below); timeouts and connection limits are BoundedServer's.
  s.set_payload_max_length(kMaxBodyBytes);

  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Content-Type-Options", "nosniff");
    res.set_header("X-Frame-Options", "DENY");
    res.set_header("Referrer-Policy", "no-referrer");
    res.set_header("Content-Security-Policy",
                   "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; "
                   "connect-src 'self'; frame-ancestors 'none'");
    // DNS rebinding: the Host header must name this listener.
    const std::string host = req.get_header_value("Host");
    std::set<std::string> allowed{hostPort(options_.address, port_)};
    if (isLoopbackAddress(options_.address)) {
      allowed.insert("localhost:" + std::to_string(port_));
      allowed.insert(hostPort("127.0.0.1", port_));
      allowed.insert(hostPort("::1", port_));
    }
    if (allowed.count(host) == 0) {
      res.status = 421;
      res.set_content("{\"ok\":false,\"error\":\"Host header does not name this dashboard\"}", "application/json");
      return httplib::Server::HandlerResponse::Handled;
    }
    const std::string origin = req.get_header_value("Origin");
    if (!origin.empty() && origin != "http://" + host) {
      res.status = 403;
      res.set_content("{\"ok\":false,\"error\":\"cross-origin request refused\"}", "application/json");
      return httplib::Server::HandlerResponse::Handled;
    }
    if (req.path.rfind("/api/", 0) == 0 && !tokensEqual(req.get_header_value("X-Phalanx-Token"), token_)) {
      res.status = 401;
      res.set_content("{\"ok\":false,\"error\":\"missing or wrong X-Phalanx-Token (open the URL phalanxd printed)\"}",
                      "application/json");
      return httplib::Server::HandlerResponse::Handled;
    }
    return httplib::Server::HandlerResponse::Unhandled;
  });
  s.Get("/", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(dashboardHtml(), "text/html; charset=utf-8");
  });
  s.Get("/dashboard.js", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(dashboardJs(), "text/javascript; charset=utf-8");
  });
  s.Get("/api/samples", [this](const httplib::Request& req, httplib::Response& res) {
    uint64_t after = 0;
    if (req.has_param("after")) {
      const std::string a = req.get_param_value("after");
      if (a.empty() || a.size() > 19 || a.find_first_not_of("0123456789") != std::string::npos) {
        res.status = 400;
        res.set_content("{\"ok\":false,\"error\":\"after: expected a non-negative integer\"}", "application/json");
        return;
      }
      after = std::stoull(a);
    }
    res.set_content(samplesAfter(after).dump(), "application/json");
    std::lock_guard<std::mutex> lock(mutex_);
    last_fetch_ = std::chrono::steady_clock::now();
  });
  s.Post("/api/request", [this](const httplib::Request&, httplib::Response& res, const httplib::ContentReader& reader) {
    std::string body;
    bool too_long = false;
    const bool read = reader([&](const char* data, size_t len) {
      if (body.size() + len > kMaxBodyBytes) {
        too_long = true;
        return false;
      }
      body.append(data, len);
      return true;
    });
    if (too_long || res.status == 413) {
      res.status = 413;
      res.set_content(bodyTooLong(), "application/json");
      if (t_stream != nullptr) t_stream->closeAfterResponse();  // the rest of the body is never read
      return;
    }
    if (!read) {
      res.status = 400;
      res.set_content("{\"ok\":false,\"error\":\"request body incomplete\"}", "application/json");
      if (t_stream != nullptr) t_stream->closeAfterResponse();
      return;
    }
    // The same validated handler as the UNIX socket: one JSON request, one answer.
    res.set_content(handler_(body).dump(), "application/json");
  });
  s.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.status == 413) {
      res.set_content(bodyTooLong(), "application/json");
    } else if (res.body.empty()) {
      res.set_content("{\"ok\":false,\"error\":\"HTTP " + std::to_string(res.status) + "\"}", "application/json");
    }
  });
}

void Dashboard::stop() {
  if (!running_.exchange(false)) return;
  http_->server.stop();                // the listener: no new connection
  http_->server.closeConnections();    // the open ones (a page's keep-alive connection), so the workers end now
  if (listen_thread_.joinable()) listen_thread_.join();
  if (sample_thread_.joinable()) sample_thread_.join();
}

void Dashboard::sampleLoop() {
  const auto period = std::chrono::microseconds(static_cast<long>(1e6 / kSampleRateHz));
  auto next = std::chrono::steady_clock::now();
  while (running_) {
    takeSample();
    next += period;
    const auto now = std::chrono::steady_clock::now();
    if (next < now) next = now;  // after a long status call (a "stop" writing its report): no burst
    std::this_thread::sleep_until(next);
  }
}

void Dashboard::takeSample() { publish(handler_("{\"cmd\":\"status\"}")); }

uint64_t Dashboard::lastSeq() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return seq_;
}

std::chrono::steady_clock::time_point Dashboard::lastFetch() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_fetch_;
}

void Dashboard::publish(const nlohmann::json& resp) {
  if (!resp.is_object() || !resp.value("ok", false) || !resp.contains("result")) return;
  const nlohmann::json& r = resp["result"];
  nlohmann::json st{{"session_running", r.value("session_running", false)}};
  nlohmann::json sample;
  std::string session;
  nlohmann::json meta;
  if (r.contains("session")) {
    const nlohmann::json& s = r["session"];
    for (const char* k : {"phase", "patient", "record", "device", "exercise", "t_s", "cycles", "device_mode", "faults",
                          "estop", "limited_cycles", "effort_unit", "fault_guidance", "paused", "plan",
                          "self_training", "replay"}) {
      if (s.contains(k)) st[k] = s[k];
    }
    session = s.value("record", std::string()) + "|" + s.value("device", std::string());
    if (s.contains("channels") && s.contains("joints") && s["t_s"].is_number()) {
      meta = {{"session", session}, {"effort_unit", s.value("effort_unit", std::string())},
              {"channels", nlohmann::json::array()}, {"joints", nlohmann::json::array()},
              {"joint_channels", nlohmann::json::array()}};
      sample = {{"t", s["t_s"]}, {"j", nlohmann::json::array()}, {"q", nlohmann::json::array()},
                {"tg", nlohmann::json::array()}, {"em", nlohmann::json::array()}, {"ec", nlohmann::json::array()},
                {"lim", nlohmann::json::array()}};
      // Fingers and joints in anatomical order (thumb → little, MCP → PIP → DIP), not the JSON's alphabetical one.
      for (const std::string& name : therapy::anatomicalKeys(s["joints"])) {
        const nlohmann::json& v = s["joints"][name];
        meta["joints"].push_back(name);
        meta["joint_channels"].push_back(v.value("channel", std::string()));
        sample["j"].push_back(num(v.value("flexion_deg", nlohmann::json())));
      }
      for (const std::string& name : therapy::anatomicalKeys(s["channels"])) {
        const nlohmann::json& v = s["channels"][name];
        meta["channels"].push_back(name);
        sample["q"].push_back(num(v.value("q_deg", nlohmann::json())));
        sample["tg"].push_back(num(v.value("target_deg", nlohmann::json())));
        sample["em"].push_back(num(v.value("effort_measured", nlohmann::json())));
        sample["ec"].push_back(num(v.value("effort_command", nlohmann::json())));
        sample["lim"].push_back(num(v.value("effort_max", nlohmann::json())));
      }
    }
  }
  if (r.contains("last_session") && r["last_session"].is_object()) {
    const auto& l = r["last_session"];
    st["last_session"] = {{"exit_code", num(l.value("exit_code", nlohmann::json()))},
                          {"error", l.value("error", std::string())},
                          {"report", l.contains("report") ? l["report"] : nlohmann::json(nullptr)}};
  }
  std::lock_guard<std::mutex> lock(mutex_);
  status_ = st;
  if (sample.is_null()) return;
  const double t = sample["t"].get<double>();
  if (session != last_session_) {  // a new session: its plots start empty
    ring_.clear();
    last_session_ = session;
    last_t_s_ = -1.0;
  }
  meta_ = meta;
  if (t == last_t_s_) return;  // the loop has not published a newer snapshot
  last_t_s_ = t;
  sample["seq"] = ++seq_;
  ring_.push_back(std::move(sample));
  while (ring_.size() > kRingSamples) ring_.pop_front();
}

nlohmann::json Dashboard::samplesAfter(uint64_t after) const {
  std::lock_guard<std::mutex> lock(mutex_);
  nlohmann::json out{{"ok", true}, {"status", status_}, {"meta", meta_}, {"samples", nlohmann::json::array()},
                     {"rate_hz", kSampleRateHz}};
  std::size_t n = 0;
  uint64_t upto = after;  // every sample up to this seq is in the answer (or was before it)
  for (const auto& s : ring_) {
    const uint64_t seq = s["seq"].get<uint64_t>();
    if (seq <= after) continue;
    if (n >= kMaxSamplesPerAnswer) break;
    out["samples"].push_back(s);
    ++n;
    upto = seq;
  }
  if (n < kMaxSamplesPerAnswer) upto = seq_;
  out["last_seq"] = seq_;
  // Only from a client that had every sample up to `after` (the ring still held the one after it).
  const bool contiguous = ring_.empty() || ring_.front()["seq"].get<uint64_t>() <= after + 1;
  if (contiguous && upto > delivered_seq_.load()) delivered_seq_.store(upto);
  return out;
}

}  // namespace phalanx::host::api
