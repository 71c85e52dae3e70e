#include "phalanx/host/cycle_clock.h"

#include <poll.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>

namespace phalanx::host {
namespace {

/// Descriptors one link may hand over (libusb: its event and timer descriptors and the device's node).
constexpr size_t kMaxWaitFds = 8;
/// Wakes without telemetry tolerated in one cycle before it sleeps on the clock alone: a descriptor that keeps
/// reporting input the session does not consume must not spin a SCHED_FIFO loop (64: far above the 1-3 wakes per
/// cycle measured on a USB link, whose OUT completions wake it too).
constexpr uint32_t kMaxIdleWakesPerCycle = 64;

void sleepUntil(uint64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1000000000ull);
  ts.tv_nsec = static_cast<long>(t_ns % 1000000000ull);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace

bool parseCycleMode(const std::string& name, CycleMode& out) {
  if (name == "telemetry") {
    out = CycleMode::kTelemetry;
  } else if (name == "timer") {
    out = CycleMode::kTimer;
  } else {
    return false;
  }
  return true;
}

const char* cycleModeName(CycleMode mode) { return mode == CycleMode::kTimer ? "timer" : "telemetry"; }

CycleClock::CycleClock(CycleMode mode, uint64_t period_ns, uint64_t device_period_ns, DeviceLink& link,
                       HostSession& session)
    : mode_(mode),
      period_ns_(period_ns),
      window_ns_(std::min(period_ns, device_period_ns == 0 ? period_ns : device_period_ns) / 2),
      link_(link),
      session_(session),
      timer_(period_ns) {
  const uint64_t now = linux_hal::monotonicNs();
  expected_wake_ns_ = now + period_ns_;
  last_ns_ = now;
}

CycleStart CycleClock::next() { return mode_ == CycleMode::kTimer ? onTimer() : onTelemetry(); }

/// The period timer alone: the loop as it was before the lock (the jitter against the absolute grid).
CycleStart CycleClock::onTimer() {
  CycleStart s;
  s.missed = timer_.wait();
  s.wake_ns = linux_hal::monotonicNs();
  s.jitter_us = std::fabs(static_cast<double>(s.wake_ns) - static_cast<double>(expected_wake_ns_)) / 1000.0;
  expected_wake_ns_ += (1 + s.missed) * period_ns_;
  s.new_telemetry = session_.poll(s.wake_ns);
  ++by_timer_;
  return s;
}

/// Locked to the device: start on a frame's arrival once the window is open, else at the fallback deadline.
CycleStart CycleClock::onTelemetry() {
  const uint64_t open_ns = last_by_telemetry_ ? last_ns_ + period_ns_ - window_ns_ : last_ns_;
  const uint64_t fallback_ns = last_ns_ + (last_by_telemetry_ ? period_ns_ + period_ns_ / 2 : period_ns_);
  input_unusable_ = false;
  int fresh = 0;
  uint32_t wakes = 0;
  bool woke = false;
  for (;;) {
    const uint64_t now = linux_hal::monotonicNs();
    const int got = session_.poll(now);
    fresh += got;
    if (woke && got == 0) ++idle_wakes_;
    woke = false;
    if (fresh > 0 && now >= open_ns) return started(now, last_ns_ + period_ns_, fresh, true);
    if (now >= fallback_ns) return started(now, fallback_ns, fresh, false);
    // A frame that came before the window opened (a burst) starts the cycle when it opens.
    if (fresh > 0 || input_unusable_ || wakes >= kMaxIdleWakesPerCycle) {
      sleepUntil(fresh > 0 ? open_ns : fallback_ns);
      continue;
    }
    const int w = waitForInput(fallback_ns);
    if (w < 0) input_unusable_ = true;
    woke = w > 0;
    wakes += w > 0 ? 1 : 0;
  }
}

CycleStart CycleClock::started(uint64_t now_ns, uint64_t nominal_ns, int fresh, bool by_telemetry) {
  CycleStart s;
  s.wake_ns = now_ns;
  s.new_telemetry = fresh;
  s.by_telemetry = by_telemetry;
  const uint64_t interval = now_ns - last_ns_;
  s.jitter_us = std::fabs(static_cast<double>(now_ns) - static_cast<double>(nominal_ns)) / 1000.0;
  if (by_telemetry) s.jitter_us = std::fabs(static_cast<double>(interval) - static_cast<double>(period_ns_)) / 1000.0;
  // Whole periods with no cycle in them (the 1.5-period fallback itself is not one).
  if (interval >= 2 * period_ns_) s.missed = static_cast<uint32_t>(interval / period_ns_ - 1);
  // A timer-started cycle keeps the fallback on a drift-free grid (its deadline, not its wake-up); periods the
  // loop slept through are skipped, not caught up in a burst (as the timer mode's PeriodicTimer does).
  uint64_t grid_ns = nominal_ns;
  if (!by_telemetry && now_ns > nominal_ns + period_ns_) {
    grid_ns += (now_ns - nominal_ns) / period_ns_ * period_ns_;
    s.missed = static_cast<uint32_t>((now_ns - nominal_ns) / period_ns_);
  }
  last_ns_ = by_telemetry ? now_ns : grid_ns;
  last_by_telemetry_ = by_telemetry;
  ++(by_telemetry ? by_telemetry_ : by_timer_);
  return s;
}

int CycleClock::waitForInput(uint64_t until_ns) {
  pollfd fds[kMaxWaitFds];
  const size_t n = link_.waitFds(fds, kMaxWaitFds);
  if (n == 0) return -1;
  const uint64_t now = linux_hal::monotonicNs();
  const uint64_t left = until_ns > now ? until_ns - now : 0;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(left / 1000000000ull);
  ts.tv_nsec = static_cast<long>(left % 1000000000ull);
  const int r = ::ppoll(fds, static_cast<nfds_t>(n), &ts, nullptr);
  if (r <= 0) return 0;  // the deadline, or a signal (EINTR): the loop above decides
  for (size_t i = 0; i < n; ++i) {
    if ((fds[i].revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) return -1;
  }
  return 1;
}

}  // namespace phalanx::host
