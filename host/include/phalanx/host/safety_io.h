#pragma once
/// The daemon's safety I/O logic: the e-stop input and the drive-enable output around the control loop.
/// A press (any edge to pressed, however short), a lost e-stop line (open failure, read error, chip gone) or a
/// failed write of the enable line stops the daemon: the enable line drops and the loop commands every device safe
/// until an explicit reset, which is refused while the e-stop is pressed, lost, or released for less than the
/// release debounce time. Pure logic over two small seams (linux_hal::EstopSource, linux_hal::DigitalOutput): the
/// daemon passes libgpiod lines, the unit tests mocks. Real time: no allocation, no blocking; the only non-real-time
/// action is re-opening a lost e-stop line, at most once per reopen interval and only while stopped.
#include <cstdint>

#include "phalanx/linux/gpio.h"

namespace phalanx::host {

enum class StopCause : uint8_t {
  kNone = 0,
  kEstopPressed = 1,      ///< edge to pressed, or pressed when polled
  kEstopLineLost = 2,     ///< e-stop line not open, read error, chip gone: counts as pressed
  kEnableLineFailed = 3,  ///< the enable line could not be written: the drives' state is unknown
  kPressedAtStart = 4,    ///< pressed when the session started
};
const char* stopCauseName(StopCause c);

struct SafetyIoConfig {
  /// The e-stop must read released, without an edge, for this long before a reset is accepted (contact bounce
  /// of push-button e-stops: docs/gpio.md).
  uint64_t release_debounce_ns = 20000000ull;
  /// The enable level is re-written at least this often, so that a lost enable line is found within it.
  uint64_t enable_refresh_ns = 10000000ull;
  /// While the e-stop line is lost, it is re-opened at most this often.
  uint64_t reopen_interval_ns = 1000000000ull;
};

struct SafetyIoCounters {
  uint64_t stops = 0;
  uint64_t presses = 0;          ///< press edges (and pressed levels not preceded by an edge), stopped or not
  uint64_t line_lost = 0;
  uint64_t enable_failures = 0;  ///< failed writes of the enable line
  uint64_t resets = 0;
  uint64_t resets_refused = 0;
  uint64_t reopen_attempts = 0;
  uint64_t reopened = 0;
};

class SafetyIo {
 public:
  /// Either pointer may be null (not configured). Neither is owned.
  SafetyIo(linux_hal::EstopSource* estop, linux_hal::DigitalOutput* enable, const SafetyIoConfig& cfg = {});

  /// Before the first cycle. estop_open says whether the e-stop line opened; when it did not, or the e-stop is
  /// pressed now, the daemon starts stopped (a reset is needed). Otherwise the enable line is raised.
  void start(bool estop_open, uint64_t now_ns);
  /// Once per cycle: read the e-stop, write the enable line. Returns true when a stop began in this call.
  bool update(uint64_t now_ns);
  /// Explicit reset: returns nullptr when accepted (or when not stopped), else the reason it was refused.
  /// Call it before update() in a cycle: update() then raises the enable line before any command is sent.
  const char* requestReset(uint64_t now_ns);
  /// End of session: enable low.
  void shutdown();

  bool stopped() const { return stopped_; }
  StopCause cause() const { return cause_; }
  bool estopPressed() const { return pressed_; }     ///< pressed or lost
  bool estopLineOk() const { return line_ok_; }
  bool enableActive() const { return enable_level_; }
  /// Kernel timestamp (CLOCK_MONOTONIC ns) of the press edge that caused the current stop, 0 when none (lost line).
  uint64_t stopEdgeNs() const { return stop_edge_ns_; }
  const SafetyIoCounters& counters() const { return counters_; }

 private:
  void stop(StopCause cause, uint64_t edge_ns);
  void writeEnable(uint64_t now_ns, bool force);
  void markLost();

  linux_hal::EstopSource* estop_;
  linux_hal::DigitalOutput* enable_;
  SafetyIoConfig cfg_;
  bool started_ = false;
  bool stopped_ = false;
  bool stop_began_ = false;
  StopCause cause_ = StopCause::kNone;
  bool line_ok_ = false;
  bool pressed_ = false;
  bool released_known_ = false;     ///< the e-stop is known to be released, since released_since_ns_
  uint64_t released_since_ns_ = 0;
  uint64_t stop_edge_ns_ = 0;
  uint64_t last_reopen_ns_ = 0;
  bool enable_level_ = false;
  bool enable_ok_ = true;
  uint64_t last_enable_write_ns_ = 0;
  SafetyIoCounters counters_;
};

}  // namespace phalanx::host
