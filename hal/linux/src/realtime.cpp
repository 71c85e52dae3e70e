#include "phalanx/linux/realtime.h"

#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <cerrno>
#include <cstring>

namespace phalanx::linux_hal {

RealtimeStatus setupRealtime(int priority) {
  RealtimeStatus st;
  st.memory_locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
  if (!st.memory_locked) st.warning += std::string("mlockall failed (") + std::strerror(errno) + "); ";
  sched_param sp{};
  sp.sched_priority = priority;
  st.fifo_scheduling = sched_setscheduler(0, SCHED_FIFO, &sp) == 0;
  if (!st.fifo_scheduling) {
    st.warning += std::string("SCHED_FIFO unavailable (") + std::strerror(errno) +
                  "): running best effort under the default scheduler, expect more jitter";
  }
  return st;
}

uint64_t monotonicNs() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

PeriodicTimer::PeriodicTimer(uint64_t period_ns) : period_ns_(period_ns), next_ns_(monotonicNs() + period_ns) {}

uint32_t PeriodicTimer::wait() {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(next_ns_ / 1000000000ull);
  ts.tv_nsec = static_cast<long>(next_ns_ % 1000000000ull);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
  last_deadline_ns_ = next_ns_;
  next_ns_ += period_ns_;
  const uint64_t now = monotonicNs();
  uint32_t missed = 0;
  if (now > next_ns_) {
    missed = static_cast<uint32_t>((now - next_ns_) / period_ns_) + 1;
    next_ns_ += static_cast<uint64_t>(missed) * period_ns_;
  }
  return missed;
}

}  // namespace phalanx::linux_hal
