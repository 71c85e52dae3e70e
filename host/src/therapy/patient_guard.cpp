#include "phalanx/host/therapy/patient_guard.h"

#include <cmath>

namespace phalanx::host::therapy {

PatientGuard::PatientGuard(std::unique_ptr<TherapyDevice> device, const PatientLimits& limits)
    : device_(std::move(device)), limits_(limits) {}

void PatientGuard::offerLimits(const PatientLimits& limits) {
  std::lock_guard<std::mutex> lock(pending_mutex_);
  pending_ = limits;
  limits_pending_.store(true, std::memory_order_release);
}

std::array<double, kMaxChannels> PatientGuard::sentEffort() const {
  std::lock_guard<std::mutex> lock(sent_mutex_);
  return sent_;
}

uint32_t PatientGuard::limit(const TelemetryFrame& tel, protocol::Command& cmd) {
  if (limits_pending_.load(std::memory_order_acquire) && pending_mutex_.try_lock()) {
    limits_ = pending_;
    limits_pending_.store(false, std::memory_order_release);
    pending_mutex_.unlock();
  }
  device_->observe(tel, obs_);
  const std::size_t n = device_->channelCount();
  std::array<float, kMaxChannels> setpoint{};
  for (std::size_t c = 0; c < n; ++c) setpoint[c] = cmd.setpoint[c];
  std::array<double, kMaxChannels> effort{};
  device_->effortFromCommand(setpoint, effort);
  const std::array<double, kMaxChannels> asked = effort;
  limits_.apply(obs_, effort);
  // A command already within the limits is sent as it is: converting it back and forth only adds round-off.
  uint32_t changed = 0;
  for (std::size_t c = 0; c < n; ++c) {
    if (std::fabs(effort[c] - asked[c]) > 1e-6 * std::fmax(1.0, std::fabs(asked[c]))) changed |= 1u << c;
  }
  if (changed != 0) {
    device_->commandFromEffort(effort, setpoint);
    for (std::size_t c = 0; c < n; ++c) cmd.setpoint[c] = setpoint[c];
  }
  if (sent_mutex_.try_lock()) {
    sent_ = effort;
    sent_mutex_.unlock();
  }
  return changed;
}

}  // namespace phalanx::host::therapy
