#include "phalanx/host/command_limits.h"

#include <cmath>

namespace phalanx::host {
namespace {
constexpr uint16_t kMaxGainPermille = 2000;  // docs/protocol.md: a gain scale above 2000 ‰ is rejected
constexpr uint16_t kNominalGainPermille = 1000;
}  // namespace

void makeSafe(protocol::Command& cmd) {
  cmd.mode = protocol::Mode::kSafe;
  for (auto& s : cmd.setpoint) s = 0.0f;
  for (auto& g : cmd.gain_scale_permille) g = kNominalGainPermille;
}

bool CommandLimits::deviceLimits(protocol::Command& cmd) {
  bool limited = false;
  const float lim = layout_.setpoint_limit;
  for (uint8_t i = 0; i < protocol::kMaxSetpoints; ++i) {
    if (i >= layout_.setpoint_count) {  // unused channels carry nothing (docs/protocol.md)
      cmd.setpoint[i] = 0.0f;
      cmd.gain_scale_permille[i] = kNominalGainPermille;
      continue;
    }
    if (std::fabs(cmd.setpoint[i]) > lim) {
      cmd.setpoint[i] = std::copysign(lim, cmd.setpoint[i]);
      limited = true;
    }
    if (cmd.gain_scale_permille[i] > kMaxGainPermille) {
      cmd.gain_scale_permille[i] = kMaxGainPermille;
      limited = true;
    }
  }
  return limited;
}

CommandLimits::Verdict CommandLimits::apply(const TelemetryFrame& tel, protocol::Command& cmd) {
  cmd.channel_count = layout_.setpoint_count;
  bool finite = true;
  for (uint8_t i = 0; i < layout_.setpoint_count; ++i) finite = finite && std::isfinite(cmd.setpoint[i]);
  if (static_cast<uint8_t>(cmd.mode) >= protocol::kModeCount || !finite) {
    ++counters_.refused;
    makeSafe(cmd);
    return Verdict::kRefused;
  }
  bool limited = deviceLimits(cmd);
  if (limited) ++counters_.device_limited;
  if (patient_ != nullptr && patient_->limit(tel, cmd) != 0) {
    ++counters_.patient_limited;
    limited = true;
  }
  return limited ? Verdict::kLimited : Verdict::kPassed;
}

}  // namespace phalanx::host
