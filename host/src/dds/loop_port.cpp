#include <cerrno>
#include <cmath>
#include <ctime>

#include "phalanx/host/dds/dds_bridge.h"

namespace phalanx::host::dds {

LoopPort::LoopPort(const DdsOptions& o, unsigned rate_hz) : ring_(o.queue_slots) {
  sem_init(&ready_, 0, 0);
  // Every n-th cycle: 1 kHz loop, 100 Hz state → every 10th cycle (a rate that does not divide rounds to the
  // nearest period; docs/dds.md).
  state_every_ = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(rate_hz / o.state_rate_hz)));
  diag_every_ = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(rate_hz / o.diagnostics_rate_hz)));
  if (!(o.joint_states || o.poses || o.wrenches)) state_every_ = 0;
  if (!o.diagnostics) diag_every_ = 0;
}

LoopPort::~LoopPort() { sem_destroy(&ready_); }

void LoopPort::offer(const TelemetryFrame& tel, uint64_t wake_ns, uint64_t cycle, uint64_t overruns,
                     double jitter_us, double cycle_us) {
  uint8_t what = 0;
  const bool fresh = tel.host_rx_ns != last_rx_ns_;
  if (state_every_ != 0 && cycle >= next_state_cycle_ && fresh) {
    what |= kState;
    next_state_cycle_ = cycle + state_every_;
  }
  if (diag_every_ != 0 && (cycle >= next_diag_cycle_ || tel.fault_bits != last_faults_)) {
    what |= kDiagnostics;
    next_diag_cycle_ = cycle + diag_every_;
  }
  if (what == 0) return;
  scratch_.tel = tel;
  scratch_.wake_ns = wake_ns;
  scratch_.cycle = cycle;
  scratch_.overruns = overruns;
  scratch_.jitter_us = static_cast<float>(jitter_us);
  scratch_.cycle_us = static_cast<float>(cycle_us);
  scratch_.what = what;
  offered_.fetch_add(1, std::memory_order_relaxed);
  if (!ring_.push(scratch_)) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;  // the fault change is retried next cycle (last_faults_ unchanged); state waits for its next turn
  }
  if ((what & kState) != 0) last_rx_ns_ = tel.host_rx_ns;
  last_faults_ = tel.fault_bits;
  sem_post(&ready_);  // never blocks; a futex wake only when the bridge waits
}

bool LoopPort::take(LoopSample& out, int timeout_ms) {
  if (ring_.pop(out)) {
    sem_trywait(&ready_);
    return true;
  }
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  ts.tv_nsec += static_cast<long>(timeout_ms % 1000) * 1000000L;
  ts.tv_sec += timeout_ms / 1000 + ts.tv_nsec / 1000000000L;
  ts.tv_nsec %= 1000000000L;
  while (sem_timedwait(&ready_, &ts) != 0) {
    if (errno != EINTR) return ring_.pop(out);
  }
  return ring_.pop(out);
}

}  // namespace phalanx::host::dds

namespace phalanx::host::dds {

std::string topicNamespace(const DdsOptions& o, const protocol::DeviceLayout& layout) {
  return o.ns.empty() ? std::string("phalanx/") + layout.name : o.ns;
}

}  // namespace phalanx::host::dds
