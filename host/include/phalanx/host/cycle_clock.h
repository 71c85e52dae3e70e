#pragma once
/// When a host cycle starts (docs/session-runner.md, "The cycle's clock"): as soon as a telemetry frame arrives,
/// locked to the device's clock (`telemetry`, the default), with the period timer as the fallback when frames
/// stop; or on the period timer alone (`timer`, the loop before issue #20, kept for comparison).
#include <cstdint>
#include <string>

#include "phalanx/host/device_link.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/realtime.h"

namespace phalanx::host {

enum class CycleMode : uint8_t { kTelemetry = 0, kTimer = 1 };

/// "telemetry" | "timer"; false for anything else (out untouched).
bool parseCycleMode(const std::string& name, CycleMode& out);
const char* cycleModeName(CycleMode mode);

/// How one cycle started.
struct CycleStart {
  uint64_t wake_ns = 0;        ///< CLOCK_MONOTONIC at the start
  int new_telemetry = 0;       ///< telemetry frames found by the session's poll (its return value)
  uint32_t missed = 0;         ///< whole host periods that passed without a cycle (overruns)
  double jitter_us = 0.0;      ///< timer: lateness against the absolute period grid; telemetry: |interval − period|
  bool by_telemetry = false;   ///< a frame's arrival started it (else the timer: the fallback, or timer mode)
};

/// Waits for the next cycle and polls the session (so `new_telemetry` is the poll's answer in both modes).
///
/// telemetry mode: a cycle starts on the first telemetry frame that arrives once the window for it is open
/// (period − half a device tick after the previous cycle started: one cycle per host period when the device
/// ticks faster), waiting on the link's descriptors (DeviceLink::waitFds) with ppoll; if no frame came by 1.5
/// periods after a frame-started cycle (one period after a timer-started one) the timer starts it instead, so
/// commands keep flowing, the telemetry timeout is checked and --seconds keeps its meaning while frames stop.
class CycleClock {
 public:
  /// period_ns: the host period; device_period_ns: the device's tick period (0: unknown, taken as the host's).
  CycleClock(CycleMode mode, uint64_t period_ns, uint64_t device_period_ns, DeviceLink& link, HostSession& session);
  CycleStart next();
  CycleMode mode() const { return mode_; }
  uint64_t startedByTelemetry() const { return by_telemetry_; }
  uint64_t startedByTimer() const { return by_timer_; }
  /// Wakes from the link's descriptors that brought no telemetry (events, partial frames, USB completions).
  uint64_t wakesWithoutTelemetry() const { return idle_wakes_; }

 private:
  CycleStart onTimer();
  CycleStart onTelemetry();
  CycleStart started(uint64_t now_ns, uint64_t nominal_ns, int fresh, bool by_telemetry);
  /// Sleep in ppoll on the link's descriptors until input (1), `until_ns` or a signal (0); -1: nothing to wait on
  /// or a descriptor reported an error or hang-up (the caller then sleeps on the clock: the cycle's checks see it).
  int waitForInput(uint64_t until_ns);

  CycleMode mode_;
  uint64_t period_ns_;
  uint64_t window_ns_;  ///< the window opens this long before the nominal period ends
  DeviceLink& link_;
  HostSession& session_;
  linux_hal::PeriodicTimer timer_;
  uint64_t expected_wake_ns_ = 0;  ///< timer mode: the absolute grid
  uint64_t last_ns_ = 0;           ///< telemetry mode: when the previous cycle started (its deadline if by timer)
  bool last_by_telemetry_ = false;
  bool input_unusable_ = false;    ///< this cycle: a descriptor reported an error; sleep on the clock
  uint64_t by_telemetry_ = 0, by_timer_ = 0, idle_wakes_ = 0;
};

}  // namespace phalanx::host
