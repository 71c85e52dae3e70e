#include "phalanx/host/safety_io.h"

namespace phalanx::host {

const char* stopCauseName(StopCause c) {
  switch (c) {
    case StopCause::kNone: return "none";
    case StopCause::kEstopPressed: return "estop-pressed";
    case StopCause::kEstopLineLost: return "estop-line-lost";
    case StopCause::kEnableLineFailed: return "enable-line-failed";
    case StopCause::kPressedAtStart: return "estop-pressed-at-start";
  }
  return "?";
}

SafetyIo::SafetyIo(linux_hal::EstopSource* estop, linux_hal::DigitalOutput* enable, const SafetyIoConfig& cfg)
    : estop_(estop), enable_(enable), cfg_(cfg) {}

void SafetyIo::stop(StopCause cause, uint64_t edge_ns) {
  if (stopped_) return;  // the first cause stays the reported one
  stopped_ = true;
  stop_began_ = true;
  cause_ = cause;
  stop_edge_ns_ = edge_ns;
  ++counters_.stops;
}

void SafetyIo::markLost() {
  line_ok_ = false;
  pressed_ = true;
  released_known_ = false;
  ++counters_.line_lost;
}

void SafetyIo::writeEnable(uint64_t now_ns, bool force) {
  if (enable_ == nullptr) {
    enable_level_ = !stopped_;
    return;
  }
  const bool want = !stopped_;
  if (!force && want == enable_level_ && enable_ok_ && now_ns - last_enable_write_ns_ < cfg_.enable_refresh_ns) return;
  last_enable_write_ns_ = now_ns;
  if (enable_->write(want)) {
    enable_ok_ = true;
    enable_level_ = want;
    return;
  }
  ++counters_.enable_failures;
  enable_ok_ = false;
  enable_level_ = false;  // unknown; never reported as enabled
  stop(StopCause::kEnableLineFailed, 0);
}

void SafetyIo::start(bool estop_open, uint64_t now_ns) {
  started_ = true;
  stopped_ = false;
  cause_ = StopCause::kNone;
  if (estop_ != nullptr) {
    line_ok_ = estop_open;
    last_reopen_ns_ = now_ns;
    if (!estop_open) {
      markLost();
      stop(StopCause::kEstopLineLost, 0);
    } else {
      const linux_hal::EstopSample s = estop_->poll();
      if (!s.ok) {
        markLost();
        stop(StopCause::kEstopLineLost, 0);
      } else if (s.active || s.press_seen) {
        ++counters_.presses;
        pressed_ = true;
        stop(StopCause::kPressedAtStart, s.press_edge_ns);
      } else {
        pressed_ = false;
        released_known_ = true;
        released_since_ns_ = now_ns;
      }
    }
  }
  writeEnable(now_ns, true);
  stop_began_ = false;  // a stop at start is reported by stopped(), not as a new edge
}

bool SafetyIo::update(uint64_t now_ns) {
  stop_began_ = false;
  if (estop_ != nullptr) {
    // A lost line is re-opened only while stopped (it always is: a lost line stops), at a bounded rate.
    if (!line_ok_ && now_ns - last_reopen_ns_ >= cfg_.reopen_interval_ns) {
      last_reopen_ns_ = now_ns;
      ++counters_.reopen_attempts;
      if (estop_->reopen()) {
        line_ok_ = true;
        ++counters_.reopened;
      }
    }
    if (line_ok_) {
      const linux_hal::EstopSample s = estop_->poll();
      if (!s.ok) {
        markLost();
        stop(StopCause::kEstopLineLost, 0);
      } else {
        if (s.press_seen || s.active) {
          if (s.press_seen || !pressed_) ++counters_.presses;  // each press edge, or a level first seen pressed
          pressed_ = true;
          released_known_ = false;
          stop(StopCause::kEstopPressed, s.press_edge_ns);
        }
        if (!s.active) {
          if (pressed_ || !released_known_) {
            // Released: since the last release edge when the kernel saw one, else since now.
            released_since_ns_ = s.release_edge_ns != 0 ? s.release_edge_ns : now_ns;
            released_known_ = true;
          }
          pressed_ = false;
        }
      }
    } else {
      pressed_ = true;
    }
  }
  writeEnable(now_ns, stop_began_);
  return stop_began_;
}

const char* SafetyIo::requestReset(uint64_t now_ns) {
  if (!stopped_) return nullptr;
  const char* why = nullptr;
  if (estop_ != nullptr && !line_ok_) {
    why = "the e-stop line is lost (counts as pressed)";
  } else if (estop_ != nullptr && pressed_) {
    why = "the e-stop is still pressed";
  } else if (estop_ != nullptr && (!released_known_ || now_ns < released_since_ns_ ||
                                   now_ns - released_since_ns_ < cfg_.release_debounce_ns)) {
    why = "the e-stop was released less than the release debounce time ago";
  } else if (enable_ != nullptr && !enable_ok_) {
    why = "the enable line cannot be written";
  }
  if (why != nullptr) {
    ++counters_.resets_refused;
    return why;
  }
  stopped_ = false;
  cause_ = StopCause::kNone;
  stop_edge_ns_ = 0;
  ++counters_.resets;
  return nullptr;  // the next update() raises the enable line (and stops again if that write fails)
}

void SafetyIo::shutdown() {
  if (enable_ != nullptr) enable_->write(false);
  enable_level_ = false;
}

}  // namespace phalanx::host
