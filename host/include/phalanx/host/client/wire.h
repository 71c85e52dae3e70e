#pragma once
/// The client channel's wire format: what phalanxd and libphalanx exchange (docs/sdk.md §"Channel").
///
/// Control socket (UNIX stream, one message each way per step, fixed-size little-endian structs):
///   client → daemon  ConnectRequest
///   daemon → client  ConnectReply, with the shared-memory file descriptor attached (SCM_RIGHTS) when accepted
///   client → daemon  Release (optional, a clean hand-back of control) - then either side closes.
/// Shared memory (one memfd of sizeof(SharedChannel), mapped by both): the daemon's loop writes `state` each
/// cycle under a seqlock and reads `command` once per cycle under the client's seqlock; neither side ever waits
/// for the other (a reader that sees an odd or changed sequence retries - the client - or keeps its previous
/// copy - the daemon), so no lock exists that a client could hold.
///
/// This header is the one definition, used by host/src/client/ and sdk/ alike.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace phalanx::client_wire {

constexpr uint32_t kMagic = 0x50484c58u;  // "PHLX"
/// Bumped on any change to the structs below; the daemon refuses another (ConnectStatus::kVersionMismatch).
constexpr uint16_t kVersion = 1;
constexpr size_t kMaxSamples = 25;
constexpr size_t kMaxSetpoints = 8;

/// What the device does when the daemon forces a client's control off (timeout, invalid command, ...).
enum class Fallback : uint8_t { kSafe = 0, kTransparent = 1 };

enum class ConnectStatus : uint8_t {
  kOk = 0,
  kVersionMismatch = 1,
  kBusy = 2,          ///< another client is connected
  kBadRequest = 3,    ///< a field is out of range (reply.message says which)
  kNotPermitted = 4,  ///< peer credentials refused (never sent: the connection is closed), kept for the C API
};

/// Why the daemon took force off a client (state.force_off_cause; also recorded in the session summary).
enum class ForceOffCause : uint8_t {
  kNone = 0,
  kClientTimeout = 1,   ///< no new command within the client's deadline
  kInvalidCommand = 2,  ///< a non-finite value or an undefined mode (refused before the limits stage)
  kLimit = 3,           ///< the limits stage refused the command (it sent the safe command)
  kDeviceFault = 4,     ///< the device latched a fault (it is safe by itself)
  kEstop = 5,           ///< the daemon is stopped (e-stop line)
  kLinkLoss = 6,        ///< the device link was lost; the session ended
  kDaemonStop = 7,      ///< the session ended (SIGINT/SIGTERM, --seconds, API stop)
};

/// The cause's name in summaries, logs and docs/sdk.md.
inline const char* forceOffCauseName(ForceOffCause c) {
  switch (c) {
    case ForceOffCause::kNone: return "none";
    case ForceOffCause::kClientTimeout: return "client-timeout";
    case ForceOffCause::kInvalidCommand: return "invalid-command";
    case ForceOffCause::kLimit: return "limit";
    case ForceOffCause::kDeviceFault: return "device-fault";
    case ForceOffCause::kEstop: return "e-stop";
    case ForceOffCause::kLinkLoss: return "link-loss";
    case ForceOffCause::kDaemonStop: return "daemon-stop";
  }
  return "unknown";
}

/// Who commands the device this cycle, from the client's point of view (state.control).
enum class Control : uint8_t {
  kNotYet = 0,      ///< connected, no command yet (the built-in controller commands)
  kClient = 1,      ///< this client's command was used this cycle
  kOtherSource = 2, ///< Modbus holds control: this client's commands are refused (counted)
  kForcedOff = 3,   ///< force is off (force_off_cause); the fallback state is sent until this client leaves
  kStopped = 4,     ///< the daemon is stopped (e-stop): the safe command is sent
};

struct ConnectRequest {
  uint32_t magic = kMagic;
  uint16_t version = kVersion;
  uint16_t deadline_ms = 20;  ///< a command older than this forces off (≥ 2 daemon periods, ≤ 1000)
  Fallback fallback = Fallback::kSafe;
  uint8_t reserved[7] = {};
};
static_assert(sizeof(ConnectRequest) == 16, "ConnectRequest layout");

struct ConnectReply {
  uint32_t magic = kMagic;
  uint16_t version = kVersion;
  ConnectStatus status = ConnectStatus::kOk;
  uint8_t device_type = 0;  ///< protocol::DeviceType (1 glove5, 2 sea_finger, 3 pantograph)
  char device_name[16] = {};
  uint32_t generation = 0;  ///< this connection's number: every command block must carry it
  uint32_t rate_hz = 0;     ///< the daemon's loop rate
  uint16_t deadline_ms = 0; ///< the deadline the daemon enforces (the request's)
  uint8_t setpoint_count = 0;
  uint8_t sample_count = 0;
  float setpoint_limit = 0.0f;  ///< |setpoint| device limit (SI); the patient's limit may be lower
  uint8_t sample_kind[kMaxSamples] = {};  ///< protocol::SampleKind per sample
  uint8_t reserved[3] = {};
  uint32_t firmware_build_id = 0;
  char message[96] = {};  ///< why, when status != kOk
};
static_assert(sizeof(ConnectReply) == 168, "ConnectReply layout");

struct Release {
  uint32_t magic = kMagic;
  uint32_t generation = 0;
};
static_assert(sizeof(Release) == 8, "Release layout");

/// Written by the daemon's loop once per cycle, after the command was sent (StateBlock::payload).
struct StatePayload {
  uint32_t generation = 0;       ///< the connection this block is meant for
  uint64_t cycle = 0;            ///< daemon cycle number
  uint64_t daemon_time_ns = 0;   ///< CLOCK_MONOTONIC of this cycle's wake-up
  uint64_t telemetry_rx_ns = 0;  ///< CLOCK_MONOTONIC when this telemetry arrived
  uint64_t device_time_us = 0;
  uint16_t telemetry_seq = 0;
  uint8_t device_mode = 0;       ///< protocol::Mode the device reports
  uint8_t state_flags = 0;
  uint16_t fault_bits = 0;
  Control control = Control::kNotYet;
  ForceOffCause force_off_cause = ForceOffCause::kNone;
  uint32_t commands_used = 0;          ///< this client's commands the daemon sent
  uint32_t command_seq_used = 0;       ///< command.command_seq of the command sent this cycle (0: none)
  uint32_t refused_invalid = 0;        ///< non-finite / undefined-mode commands refused
  uint32_t refused_other_source = 0;   ///< cycles refused because Modbus held control
  uint32_t limited = 0;                ///< cycles the limits stage changed this client's setpoints
  uint32_t force_offs = 0;
  float achieved_rate_hz = 0.0f;       ///< fresh commands per second over the last second
  float sample[kMaxSamples] = {};      ///< telemetry samples (SI)
  float setpoint_sent[kMaxSetpoints] = {};  ///< what the daemon sent (after limits)
};

struct StateBlock {
  std::atomic<uint32_t> seq{0};  ///< seqlock: odd while being written; also the futex word clients wait on
  uint32_t pad = 0;
  StatePayload payload;
};

/// Written by the client; read by the daemon once per cycle (a torn or in-progress write is skipped).
struct CommandPayload {
  uint32_t generation = 0;       ///< ConnectReply.generation
  uint32_t command_seq = 0;      ///< incremented by the client per command; a new value is a fresh command
  uint16_t for_telemetry_seq = 0;///< the state's telemetry_seq this command was computed from
  uint8_t mode = 2;              ///< protocol::Mode: 1 transparent, 2 setpoint (0 safe releases force itself)
  uint8_t reserved = 0;
  float setpoint[kMaxSetpoints] = {};  ///< raw per-channel setpoints, SI (glove: pad force N)
};

struct CommandBlock {
  std::atomic<uint32_t> seq{0};  ///< seqlock: odd while the client writes
  uint32_t pad = 0;
  CommandPayload payload;
};

struct SharedChannel {
  StateBlock state;
  alignas(64) CommandBlock command;
};
static_assert(std::atomic<uint32_t>::is_always_lock_free, "the seqlock word must be lock-free across processes");
static_assert(std::is_trivially_copyable_v<StatePayload> && std::is_trivially_copyable_v<CommandPayload>,
              "payloads are copied with memcpy");

/// Seqlock writer (one writer per block): the sequence is odd while the payload changes.
template <class P>
inline void seqlockWrite(std::atomic<uint32_t>& seq, P& dst, const P& src) {
  const uint32_t s = seq.load(std::memory_order_relaxed) | 1u;  // odd even if the other side scribbled on it
  seq.store(s, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  std::memcpy(&dst, &src, sizeof(P));
  seq.store(s + 1u, std::memory_order_release);
}

/// Seqlock reader, one attempt: false when the writer was mid-write (the caller keeps its previous copy, or
/// retries - never both sides waiting on each other).
template <class P>
inline bool seqlockTryRead(const std::atomic<uint32_t>& seq, const P& src, P& out) {
  const uint32_t s1 = seq.load(std::memory_order_acquire);
  if ((s1 & 1u) != 0) return false;
  std::memcpy(&out, &src, sizeof(P));
  std::atomic_thread_fence(std::memory_order_acquire);
  return seq.load(std::memory_order_relaxed) == s1;
}

}  // namespace phalanx::client_wire
