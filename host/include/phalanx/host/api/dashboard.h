#pragma once
/// The live dashboard: a web page served by phalanxd (API mode) with live plots of joint angles, efforts
/// (forces/torques) and setpoints, the mode, faults, e-stop state and start/stop controls. docs/dashboard.md.
///
/// - HTTP by cpp-httplib (Debian libcpp-httplib-dev): own listener thread + a bounded worker pool, never the
///   session's thread. Its data come from the API's status request, sampled at 50 Hz by a sampler thread into a
///   bounded ring (the loop itself only publishes its 50 Hz status snapshot with a try-lock, as for the API);
///   or, for a replay (record/replay_stream.h), handed each snapshot by publish().
/// - Controls are API requests: POST /api/request carries one JSON request to the SAME handler as the UNIX
///   socket (validated there; a refused one changes nothing). There is no other path into the daemon.
/// - Access: a random token (128 bit) in the URL fragment, sent back as the X-Phalanx-Token header on every /api
///   request; the Host header must name the listening address (DNS rebinding); no CORS, so other web pages
///   cannot read or post. The URL is printed on stdout and written next to the API socket, mode 0660 (who may
///   use the API may use the dashboard).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "phalanx/host/api/dashboard_options.h"

namespace phalanx::host::api {

class Dashboard {
 public:
  /// The daemon's request handler: one JSON request line → the answer object (thread-safe).
  using RequestHandler = std::function<nlohmann::json(const std::string& line)>;
  /// 50 Hz: the rate the session loop publishes its status snapshot (therapy_controller.cpp).
  static constexpr double kSampleRateHz = 50.0;
  /// 60 s of samples at 50 Hz kept for clients (a page polling every 100 ms needs 5).
  static constexpr std::size_t kRingSamples = 3000;
  /// Samples per /api/samples answer.
  static constexpr std::size_t kMaxSamplesPerAnswer = 500;

  /// Where the samples come from. kPolled: the sampler thread asks the handler for status at kSampleRateHz
  /// (phalanxd). kPublished: the owner hands each status answer to publish() (`phalanx record replay
  /// --dashboard`: every recorded sample reaches the ring, at any replay speed and however loaded the machine).
  enum class Sampling { kPolled, kPublished };

  Dashboard(const DashboardOptions& options, RequestHandler handler, Sampling sampling = Sampling::kPolled);
  ~Dashboard();
  Dashboard(const Dashboard&) = delete;
  Dashboard& operator=(const Dashboard&) = delete;

  /// Bind and start serving (own threads). "" or the error.
  std::string start();
  void stop();
  uint16_t port() const { return port_; }
  const std::string& token() const { return token_; }
  /// http://ADDRESS:PORT/#token=…
  std::string url() const;

  /// Serve one connection's bytes from memory, without a socket (fuzzing, tests): the same routes and checks as
  /// the listener (Host, Origin, token, body limits). Only before start(): `token` is the access token the
  /// routes check, and the port is 0. Returns the response bytes.
  std::string serveInMemory(const std::string& request_bytes, const std::string& token);

  /// The /api/samples answer for samples after `after` (exposed for tests).
  nlohmann::json samplesAfter(uint64_t after) const;

  /// One status answer ({"ok": true, "result": {...}}, as the handler's "status") → the status the page shows
  /// and, when its session time is newer than the last sample's, one sample (seq lastSeq() + 1). kPublished.
  void publish(const nlohmann::json& status_answer);
  /// The newest sample's seq (0: none yet).
  uint64_t lastSeq() const;
  /// The highest seq up to which an /api/samples answer has handed out every sample (a client has seen them).
  uint64_t deliveredSeq() const { return delivered_seq_.load(); }
  /// When an /api/samples request was last answered (steady clock; epoch: never).
  std::chrono::steady_clock::time_point lastFetch() const;

 private:
  void routes();
  void sampleLoop();
  void takeSample();

  DashboardOptions options_;
  RequestHandler handler_;
  Sampling sampling_;
  mutable std::atomic<uint64_t> delivered_seq_{0};  // written by samplesAfter()
  std::string token_;
  uint16_t port_ = 0;
  struct Http;
  std::unique_ptr<Http> http_;
  std::thread listen_thread_;
  std::thread sample_thread_;
  std::atomic<bool> running_{false};
  bool routes_set_ = false;
  mutable std::mutex mutex_;  // guards everything below
  std::deque<nlohmann::json> ring_;
  uint64_t seq_ = 0;
  double last_t_s_ = -1.0;
  std::string last_session_;
  nlohmann::json status_;  // the latest status without per-channel/joint values
  nlohmann::json meta_;    // channel/joint names, effort unit of the running session
  std::chrono::steady_clock::time_point last_fetch_{};
};

}  // namespace phalanx::host::api
