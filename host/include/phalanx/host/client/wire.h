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
constexpr uint16_t kVersion = 2;  // 2: model-level state and commands, the compliant fallback
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

/// Model-level state, computed by the daemon each cycle from the telemetry through its own device models
/// (host/src/client/device_model.cpp). Only the block of the connected device type is filled; `valid` is 0 when
/// the model could not be evaluated this cycle (its fields are then 0).
struct GloveModelState {
  float joint_rad[5][3] = {};   ///< finger angles θ1..θ3 per finger, thumb..little (flexion negative, 000 eq 3–8)
  float fingertip[5][3] = {};   ///< fingertip pose (x_m, y_m, phi_rad) in the finger's base frame {O}
  float fingertip_velocity[5][2] = {};  ///< d(x, y)/dt, m/s (device clock, low-pass 30 Hz)
  float pad_force_N[5] = {};    ///< measured pad force, + pushes towards extension (along padNormal(phi))
  uint8_t valid[5] = {};
  uint8_t reserved[3] = {};
};
struct SeaModelState {
  float flexion_rad[3] = {};          ///< MCP, PIP, DIP flexion (+ flexes), 001 eq 3–5
  float flexion_rate_rad_s[3] = {};   ///< low-pass 30 Hz
  float finger_torque_Nm[2] = {};     ///< MCP, PIP finger joint torque τ̂_f = J_n^{-T} τ̂_j (001 eq 9), + extends
  float exo_torque_Nm[2] = {};        ///< measured SEA (exoskeleton joint) torques τ̂_j
  uint8_t valid = 0;
  uint8_t reserved[3] = {};
};
struct PenModelState {
  float centre_m[3] = {};         ///< pen centre in the base frame {B} (seeds/004)
  float axis[3] = {};             ///< unit pen axis, tip → eraser
  float tip_m[3] = {};            ///< bottom end (tip)
  float theta_x_rad = 0.0f, theta_z_rad = 0.0f;  ///< the two controlled rotations (Table X)
  float velocity_m_s[3] = {};     ///< centre velocity (device clock, low-pass 30 Hz)
  float force_N[3] = {};          ///< measured wrench at the centre, from the measured motor torques (f = J⁻ᵀτ)
  float torque_Nm[3] = {};
  uint8_t valid = 0;
  uint8_t reserved[3] = {};
};

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
  // version 2
  uint32_t model_saturated = 0;        ///< cycles a model-level command was scaled by the device model's saturation
  uint32_t fallback_cycles = 0;        ///< cycles the client's compliant fallback was rendered (no fresh command)
  uint8_t rendered = 0;                ///< Rendered: what this cycle sent for this client
  uint8_t reserved2[3] = {};
  float model_scale = 1.0f;            ///< fraction of the model-level command delivered this cycle (1: exact)
  GloveModelState glove{};
  SeaModelState sea{};
  PenModelState pen{};
};

/// What the daemon rendered for the client this cycle (state.rendered).
enum class Rendered : uint8_t { kNothing = 0, kCommand = 1, kFallbackSpring = 2, kRepeat = 3 };

struct StateBlock {
  std::atomic<uint32_t> seq{0};  ///< seqlock: odd while being written; also the futex word clients wait on
  uint32_t pad = 0;
  StatePayload payload;
};

/// What CommandPayload carries. Model-level commands are converted by the daemon's device model into the raw
/// setpoints BEFORE the limits stage (device, then patient), like every other command.
enum class CommandKind : uint8_t {
  kRaw = 0,                 ///< setpoint[] as sent (the bench's per-channel access)
  kGloveFingertipForce = 1, ///< model[2f], model[2f+1]: force (x, y) on fingertip f in {O}, N; the glove exerts
                            ///< its pad-normal component F·padNormal(phi) as that finger's pad force
  kSeaFingerTorque = 2,     ///< model[0..1]: finger joint torque MCP, PIP (N·m, + extends); τ_j = J_nᵀ τ_f
                            ///< (001 eq 6/11), scaled down together when |τ_j| > 0.5 N·m
  kPenWrench = 3,           ///< model[0..2] force (N), model[3..5] moment (N·m) at the pen centre in {B};
                            ///< the redundant-actuator force split (seeds/004 Fig. 18) with its saturation
  kCount = 4,
};
constexpr size_t kMaxModelValues = 10;

/// A spring-damper the daemon renders while the client sends no fresh command (until the client's deadline;
/// then force-off). kind kNone repeats the last command, as version 1 did.
enum class FallbackKind : uint8_t { kNone = 0, kSpring = 1 };
struct SpringElement {
  float target[3] = {};   ///< glove: fingertip (x, y) in {O}, m; SEA: joint flexion [0] rad; pen: centre, m
  float stiffness = 0.0f; ///< glove, pen: N/m; SEA: N·m/rad (≥ 0)
  float damping = 0.0f;   ///< glove, pen: N·s/m; SEA: N·m·s/rad (≥ 0)
};
struct FallbackSpring {
  FallbackKind kind = FallbackKind::kNone;
  uint8_t reserved[3] = {};
  SpringElement element[5] = {};  ///< glove: per finger (stiffness 0: that finger gets 0 N); SEA: [0] MCP,
                                  ///< [1] PIP; pen: [0] (force only, no moment)
};

/// Written by the client; read by the daemon once per cycle (a torn or in-progress write is skipped).
struct CommandPayload {
  uint32_t generation = 0;       ///< ConnectReply.generation
  uint32_t command_seq = 0;      ///< incremented by the client per command; a new value is a fresh command
  uint16_t for_telemetry_seq = 0;///< the state's telemetry_seq this command was computed from
  uint8_t mode = 2;              ///< protocol::Mode: 1 transparent, 2 setpoint (0 safe releases force itself)
  CommandKind kind = CommandKind::kRaw;
  float setpoint[kMaxSetpoints] = {};  ///< kRaw: per-channel setpoints, SI (glove: pad force N)
  float model[kMaxModelValues] = {};   ///< model-level command, layout by `kind` (see CommandKind)
  FallbackSpring fallback{};           ///< rendered by the daemon in cycles without a fresh command
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
