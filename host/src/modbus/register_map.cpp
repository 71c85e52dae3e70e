#include "phalanx/host/modbus/register_map.h"

#include <cmath>
#include <cstring>

namespace phalanx::host::modbus {

void putU32(uint16_t* regs, uint16_t addr, uint32_t v) {
  regs[addr] = static_cast<uint16_t>(v >> 16);
  regs[addr + 1] = static_cast<uint16_t>(v & 0xFFFFu);
}

void putF32(uint16_t* regs, uint16_t addr, float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  putU32(regs, addr, bits);
}

uint32_t getU32(const uint16_t* regs, uint16_t addr) {
  return (static_cast<uint32_t>(regs[addr]) << 16) | regs[addr + 1];
}

float getF32(const uint16_t* regs, uint16_t addr) {
  const uint32_t bits = getU32(regs, addr);
  float v = 0.0f;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

void encodeInputs(const LoopSnapshot& s, bool writes_enabled, float setpoint_limit, uint16_t remote_timeout_ms,
                  uint16_t* r) {
  std::memset(r, 0, sizeof(uint16_t) * in::kCount);
  r[in::kMapVersion] = kMapVersion;
  r[in::kDeviceType] = s.device_type;
  r[in::kLoopState] = static_cast<uint16_t>(s.loop_state);
  r[in::kDeviceMode] = s.device_mode;
  r[in::kFaultBits] = s.fault_bits;
  r[in::kStateFlags] = s.state_flags;
  r[in::kControlSource] = static_cast<uint16_t>(s.source);
  r[in::kRemoteTimedOut] = s.remote_timed_out ? 1 : 0;
  putU32(r, in::kCycles, s.cycles);
  putU32(r, in::kOverruns, s.overruns);
  putU32(r, in::kUptimeMs, s.uptime_ms);
  putU32(r, in::kTelemetryLost, s.telemetry_lost);
  r[in::kTelemetrySeq] = s.telemetry_seq;
  r[in::kSampleCount] = s.sample_count;
  r[in::kSetpointCount] = s.setpoint_count;
  r[in::kWritesEnabled] = writes_enabled ? 1 : 0;
  putF32(r, in::kJitterUs, s.jitter_us);
  putF32(r, in::kJitterMaxUs, s.jitter_max_us);
  putF32(r, in::kCycleTimeUs, s.cycle_time_us);
  putF32(r, in::kSetpointLimit, setpoint_limit);
  r[in::kRemoteTimeoutMs] = remote_timeout_ms;
  for (size_t i = 0; i < protocol::kMaxSamples; ++i) {
    putF32(r, static_cast<uint16_t>(in::kSamples + 2 * i), i < s.sample_count ? s.samples[i] : 0.0f);
  }
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) {
    putF32(r, static_cast<uint16_t>(in::kSetpointsSent + 2 * i), i < s.setpoint_count ? s.setpoints_sent[i] : 0.0f);
  }
}

void encodeHolding(const RemoteCommand& c, uint16_t* r) {
  r[hold::kControlSource] = static_cast<uint16_t>(c.source);
  r[hold::kMode] = static_cast<uint16_t>(c.mode);
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) putF32(r, static_cast<uint16_t>(hold::kSetpoints + 2 * i), c.setpoint[i]);
}

WriteStatus applyWrite(uint16_t* regs, uint16_t addr, uint16_t count, const uint16_t* values, const WriteLimits& limits,
                       RemoteCommand& out, std::string& why) {
  if (count == 0 || static_cast<uint32_t>(addr) + count > hold::kCount) {
    why = "register range " + std::to_string(addr) + "+" + std::to_string(count) + " is outside the holding map (0.." +
          std::to_string(hold::kCount - 1) + ")";
    return WriteStatus::kIllegalAddress;
  }
  // A float is written whole: both halves in the same request.
  const uint32_t end = static_cast<uint32_t>(addr) + count;
  const auto splits = [](uint32_t a) { return a > hold::kSetpoints && (a - hold::kSetpoints) % 2 == 1; };
  if (splits(addr) || splits(end)) {
    why = "write splits a 32-bit setpoint (write both registers of a float in one request)";
    return WriteStatus::kIllegalAddress;
  }
  uint16_t next[hold::kCount];
  std::memcpy(next, regs, sizeof next);
  for (uint16_t i = 0; i < count; ++i) next[addr + i] = values[i];

  RemoteCommand c;
  if (next[hold::kControlSource] > static_cast<uint16_t>(ControlSource::kModbus)) {
    why = "control source " + std::to_string(next[hold::kControlSource]) + " is not 0 (controller) or 1 (modbus)";
    return WriteStatus::kIllegalValue;
  }
  c.source = static_cast<ControlSource>(next[hold::kControlSource]);
  if (next[hold::kMode] >= protocol::kModeCount) {
    why = "mode " + std::to_string(next[hold::kMode]) + " is not a mode (0.." + std::to_string(protocol::kModeCount - 1) + ")";
    return WriteStatus::kIllegalValue;
  }
  c.mode = static_cast<protocol::Mode>(next[hold::kMode]);
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) {
    const float v = getF32(next, static_cast<uint16_t>(hold::kSetpoints + 2 * i));
    if (!std::isfinite(v)) {
      why = "setpoint " + std::to_string(i) + " is not finite";
      return WriteStatus::kIllegalValue;
    }
    if (i >= limits.setpoint_count && v != 0.0f) {
      why = "setpoint " + std::to_string(i) + " does not exist on this device (" + std::to_string(limits.setpoint_count) +
            " channels)";
      return WriteStatus::kIllegalValue;
    }
    if (std::fabs(v) > limits.setpoint_limit) {
      why = "setpoint " + std::to_string(i) + " = " + std::to_string(v) + " is beyond the active limit ±" +
            std::to_string(limits.setpoint_limit);
      return WriteStatus::kIllegalValue;
    }
    c.setpoint[i] = v;
  }
  std::memcpy(regs, next, sizeof next);
  out.source = c.source;
  out.mode = c.mode;
  out.setpoint = c.setpoint;
  return WriteStatus::kOk;
}

}  // namespace phalanx::host::modbus
