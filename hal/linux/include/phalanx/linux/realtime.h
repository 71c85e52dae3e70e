#pragma once
/// Real-time thread set-up and a periodic timer on CLOCK_MONOTONIC.
#include <cstdint>
#include <string>

namespace phalanx::linux_hal {

struct RealtimeStatus {
  bool memory_locked = false;
  bool fifo_scheduling = false;
  std::string warning;  ///< why best effort was used instead (empty when both succeeded)
};

/// Lock memory and switch the calling thread to SCHED_FIFO at priority; never fails hard.
RealtimeStatus setupRealtime(int priority);

uint64_t monotonicNs();

/// Absolute-deadline periodic timer (clock_nanosleep TIMER_ABSTIME): no drift, missed periods are counted.
class PeriodicTimer {
 public:
  explicit PeriodicTimer(uint64_t period_ns);
  /// Sleep until the next period; returns how many whole periods were missed (0 normally).
  uint32_t wait();
  uint64_t period_ns() const { return period_ns_; }
  /// The deadline the last wait() slept until (CLOCK_MONOTONIC ns): wake lateness = monotonicNs() after wait()
  /// minus this.
  uint64_t lastDeadlineNs() const { return last_deadline_ns_; }

 private:
  uint64_t period_ns_;
  uint64_t next_ns_;
  uint64_t last_deadline_ns_ = 0;
};

}  // namespace phalanx::linux_hal
