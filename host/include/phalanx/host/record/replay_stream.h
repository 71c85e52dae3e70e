#pragma once
/// `phalanx record replay FILE --dashboard ADDRESS:PORT [--speed X] [--hold]` (docs/records.md, "Replay";
/// docs/dashboard.md, "Replay mode"): the replay of a `--record FILE.mcap` recording (replay.h) shown on the live
/// dashboard, paced at X times the recorded speed. The dashboard's request handler answers `status` from the
/// recording (the snapshot format the page reads, one frame per 1/50 s of session time), `profiles` with none,
/// and refuses every control request: there is no device, so nothing can reach a motor.
#include <array>
#include <atomic>
#include <chrono>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/api/dashboard_options.h"
#include "phalanx/host/record/replay.h"
#include "phalanx/host/session.h"

namespace phalanx::host::therapy {
class TherapyDevice;
}

namespace phalanx::host::record {

/// Replay speeds accepted (× the recorded session's speed).
inline constexpr double kReplaySpeedMin = 0.1, kReplaySpeedMax = 100.0;

/// One status frame, compact (a long recording holds 180 000 per hour): the recorded cycle it shows and what a
/// session record adds. ReplayFrames::session() turns it into the status snapshot when it is shown.
struct ReplayFrame {
  double t_s = 0.0;
  uint64_t cycle = 0;         ///< 0-based index of the recorded cycle
  TelemetryFrame tel;         ///< as recorded
  protocol::Command command;  ///< as replayed (a .phrec: as sent)
  float exercise_id = std::numeric_limits<float>::quiet_NaN();  ///< .phrec: the exercise running
  std::array<float, protocol::kMaxSetpoints> target_rad{};      ///< .phrec: each channel's target (NaN: none)
};

/// A replayed recording as status frames: the first replayed cycle of each 1/50 s of session time
/// (floor(t_s · 50) advances; the dashboard's sample rate). A frame shows what the recording's telemetry gives
/// through the device's therapy adapter (joint flexion, channel q, measured effort: glove5, sea_finger) or its raw
/// angles (pantograph), and the replayed command as commanded effort.
struct ReplayFrames {
  std::string file;  ///< the file's name (no directory), as the page shows it
  ReplayResult result;
  std::vector<ReplayFrame> frames;
  const protocol::DeviceLayout* layout = nullptr;
  std::shared_ptr<therapy::TherapyDevice> device;  ///< null: no therapy adapter (the raw channels)
  nlohmann::json patient;                          ///< .phrec: the header's patient (null: none)
  bool session_record = false;                     ///< a .phrec (recorded values, targets; nothing replayed)
  /// The session object of a status answer (as TherapySession::statusJson) for frame i. Not thread-safe (the
  /// adapter's observe()): one thread, frames in order.
  nlohmann::json session(std::size_t i) const;
};

/// True for a therapy session record (.phrec, by its first bytes): streamed with its recorded values.
bool isSessionRecord(const std::string& path);

/// replayRecording(path, options) and its frames; for a session record (.phrec) its recorded values as frames
/// (nothing replayed or compared: a therapy session's exercise and limit changes are not tied to their cycles). "" or why the file cannot be replayed (naming the file).
std::string replayFrames(const std::string& path, const ReplayOptions& options, ReplayFrames& out);

/// The request handler of a replay's dashboard (thread-safe): status from the frame shown now, no profiles,
/// every other request refused.
class ReplayStatus {
 public:
  ReplayStatus(const ReplayFrames& frames, double speed);
  /// One JSON request line → the answer (Dashboard::RequestHandler).
  nlohmann::json handle(const std::string& line) const;
  /// Show frame i (the pacing thread, frames in order); finished: the replay reached the end of the file.
  void show(std::size_t i, bool finished);
  /// The status answer shown now ({"ok": true, "result": {...}}).
  nlohmann::json statusAnswer() const;

 private:
  const ReplayFrames& frames_;
  double speed_;
  mutable std::mutex mutex_;  // guards the three below
  nlohmann::json session_;
  bool finished_ = false;
  bool started_ = false;
};

struct ReplayStreamOptions {
  ReplayOptions replay;
  api::DashboardOptions dashboard;
  double speed = 1.0;
  bool hold = false;  ///< at the end: keep serving the last frame until stop
};

/// Streams a replay to a dashboard: prints "DASHBOARD <url>" on stdout, shows each frame at its time / speed,
/// and at the end (or when `stop` becomes true) prints the summary JSON on stdout. Without hold it waits, after
/// the last frame, until a page has fetched every sample (while one keeps fetching, ≤ 30 s), so a page watching
/// sees the end. Returns the exit code: 0 (identical or stopped), 1 a replayed command differs, 2 the
/// file cannot be replayed, 3 the dashboard cannot listen.
int streamReplay(const std::string& path, const ReplayStreamOptions& options, const std::atomic<bool>& stop);

}  // namespace phalanx::host::record
