#pragma once
/// phalanxd's Modbus register map (docs/modbus.md is the user's copy of this table; keep them in step).
/// Addresses are 0-based PDU addresses. 32-bit values take two registers, high word first ("ABCD": big-endian
/// words, as the Modbus byte order suggests; mbpoll needs -B). Floats are IEEE-754 single precision in SI units.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include "phalanx/protocol/messages.h"

namespace phalanx::host::modbus {

constexpr uint16_t kMapVersion = 1;

/// Input registers (function code 04), read-only.
namespace in {
constexpr uint16_t kMapVersion = 0;       ///< u16, = modbus::kMapVersion
constexpr uint16_t kDeviceType = 1;       ///< u16, protocol::DeviceType (1 glove5, 2 sea_finger, 3 pantograph)
constexpr uint16_t kLoopState = 2;        ///< u16, LoopState
constexpr uint16_t kDeviceMode = 3;       ///< u16, protocol::Mode in effect on the device (telemetry)
constexpr uint16_t kFaultBits = 4;        ///< u16, latched fault bits (protocol fault::*)
constexpr uint16_t kStateFlags = 5;       ///< u16, device state flags (protocol state::*)
constexpr uint16_t kControlSource = 6;    ///< u16, ControlSource in effect this cycle
constexpr uint16_t kRemoteTimedOut = 7;   ///< u16, 1 while a Modbus command is older than its timeout (safe sent)
constexpr uint16_t kCycles = 8;           ///< u32, loop cycles since start
constexpr uint16_t kOverruns = 10;        ///< u32, whole loop periods missed since start
constexpr uint16_t kUptimeMs = 12;        ///< u32, loop time since start, ms
constexpr uint16_t kTelemetryLost = 14;   ///< u32, telemetry frames lost on the link
constexpr uint16_t kTelemetrySeq = 16;    ///< u16, sequence number of the latest telemetry frame
constexpr uint16_t kSampleCount = 17;     ///< u16, telemetry samples of this device (layout)
constexpr uint16_t kSetpointCount = 18;   ///< u16, setpoint channels of this device (layout)
constexpr uint16_t kWritesEnabled = 19;   ///< u16, 1 when the configuration enables Modbus writes
constexpr uint16_t kJitterUs = 20;        ///< f32, |wake − deadline| of the latest cycle, µs
constexpr uint16_t kJitterMaxUs = 22;     ///< f32, max jitter over the last kWindowCycles cycles, µs
constexpr uint16_t kCycleTimeUs = 24;     ///< f32, wake → command sent of the latest cycle, µs
constexpr uint16_t kSetpointLimit = 26;   ///< f32, |setpoint| accepted from Modbus (SI units of the setpoints)
constexpr uint16_t kRemoteTimeoutMs = 28; ///< u16, Modbus command timeout (0: none)
constexpr uint16_t kSamples = 32;         ///< f32 × protocol::kMaxSamples: telemetry samples in SI units (layout)
constexpr uint16_t kSetpointsSent = 96;   ///< f32 × protocol::kMaxSetpoints: setpoints of the command sent
constexpr uint16_t kCount = kSetpointsSent + 2 * protocol::kMaxSetpoints;
static_assert(kSamples + 2 * protocol::kMaxSamples <= kSetpointsSent, "sample block overlaps the setpoint block");
}  // namespace in

/// Holding registers (function codes 03 read; 06 and 16 write when writes are enabled).
namespace hold {
constexpr uint16_t kControlSource = 0;    ///< u16, ControlSource requested
constexpr uint16_t kMode = 1;             ///< u16, protocol::Mode used while the source is kModbus
constexpr uint16_t kSetpoints = 2;        ///< f32 × protocol::kMaxSetpoints, used while the source is kModbus
constexpr uint16_t kCount = kSetpoints + 2 * protocol::kMaxSetpoints;
}  // namespace hold

constexpr uint32_t kWindowCycles = 1000;  ///< jitter-max window (1 s at 1 kHz)

enum class LoopState : uint16_t { kStarting = 0, kRunning = 1, kStopping = 2 };
enum class ControlSource : uint16_t { kController = 0, kModbus = 1 };

/// What the loop hands to the server each cycle (copied by value through a TripleBuffer).
struct LoopSnapshot {
  uint16_t device_type = 0;
  LoopState loop_state = LoopState::kStarting;
  uint16_t device_mode = 0;
  uint16_t fault_bits = 0;
  uint16_t state_flags = 0;
  ControlSource source = ControlSource::kController;
  bool remote_timed_out = false;
  uint32_t cycles = 0;
  uint32_t overruns = 0;
  uint32_t uptime_ms = 0;
  uint32_t telemetry_lost = 0;
  uint16_t telemetry_seq = 0;
  uint16_t sample_count = 0;
  uint16_t setpoint_count = 0;
  float jitter_us = 0.0f;
  float jitter_max_us = 0.0f;
  float cycle_time_us = 0.0f;
  std::array<float, protocol::kMaxSamples> samples{};
  std::array<float, protocol::kMaxSetpoints> setpoints_sent{};
};

/// The holding-register block as the loop sees it (published by the server after each accepted write).
struct RemoteCommand {
  ControlSource source = ControlSource::kController;
  protocol::Mode mode = protocol::Mode::kSafe;
  std::array<float, protocol::kMaxSetpoints> setpoint{};
  uint64_t written_ns = 0;  ///< monotonic time of the accepted write
  uint32_t generation = 0;  ///< accepted writes so far
};

/// Limits a write must respect (the active limits of the session).
struct WriteLimits {
  uint16_t setpoint_count = 0;  ///< channels beyond it must stay 0
  float setpoint_limit = 0.0f;  ///< |setpoint| ≤ this (min of the device layout limit and the configuration)
};

void putU32(uint16_t* regs, uint16_t addr, uint32_t v);
void putF32(uint16_t* regs, uint16_t addr, float v);
uint32_t getU32(const uint16_t* regs, uint16_t addr);
float getF32(const uint16_t* regs, uint16_t addr);

/// Fill the kCount input registers from a snapshot.
void encodeInputs(const LoopSnapshot& s, bool writes_enabled, float setpoint_limit, uint16_t remote_timeout_ms,
                  uint16_t* regs);
/// Holding registers ↔ RemoteCommand.
void encodeHolding(const RemoteCommand& c, uint16_t* regs);

/// Outcome of a write request, as a Modbus exception code (0: accepted).
enum class WriteStatus : uint8_t { kOk = 0, kIllegalFunction = 1, kIllegalAddress = 2, kIllegalValue = 3 };

/// Apply a write of `count` registers at `addr` to the holding image `regs` (kCount registers) and validate the
/// result against the limits. On kOk, regs and out hold the new block; otherwise regs is unchanged and `why`
/// names the problem. A write that covers only half of a float is an illegal address.
WriteStatus applyWrite(uint16_t* regs, uint16_t addr, uint16_t count, const uint16_t* values, const WriteLimits& limits,
                       RemoteCommand& out, std::string& why);

}  // namespace phalanx::host::modbus
