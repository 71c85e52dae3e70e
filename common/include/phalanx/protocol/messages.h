#pragma once
/// The Phalanx wire protocol: the one definition of every message, used by firmware, host and tools.
/// Freestanding C++17 (no heap, no exceptions). Fields are fixed-width and little-endian on the wire; each
/// message's wire size is a constant checked at compile time, and every message fits one CAN-FD frame (64 bytes).
/// docs/protocol.md is the prose specification of the same layouts.
#include <cstddef>
#include <cstdint>

namespace phalanx::protocol {

/// Bumped on any incompatible change of a layout, ID or meaning. Checked in the handshake.
constexpr uint16_t kProtocolVersion = 1;
/// Largest payload of any message (one CAN-FD frame).
constexpr size_t kMaxPayload = 64;
/// Most setpoint channels in a command, and most sample channels in a telemetry frame.
constexpr size_t kMaxSetpoints = 8;
constexpr size_t kMaxSamples = 25;

/// Message IDs are explicit and never renumbered: a new message takes a new number.
enum class MsgId : uint8_t {
  kHello = 0x01,        ///< host → device: start a session
  kHelloAck = 0x02,     ///< device → host: identity and handshake status
  kCommand = 0x10,      ///< host → device: full-state command (mode, setpoints, gain scales, own timeout)
  kTelemetry = 0x20,    ///< device → host: one per control tick
  kEvent = 0x30,        ///< device → host: fault latched / cleared, request refused
  kClearFaults = 0x31,  ///< host → device: explicit clear of latched faults
  kParamGet = 0x40,     ///< host → device
  kParamSet = 0x41,     ///< host → device
  kParamValue = 0x42,   ///< device → host: answer to get/set
  kUpdateBegin = 0x50,  ///< host → device: start (or resume) a firmware update (docs/firmware-update.md)
  kUpdateData = 0x51,   ///< host → device: one chunk of the image
  kUpdateCommit = 0x52, ///< host → device: verify the received image and boot it
  kUpdateStatus = 0x53, ///< device → host: answer to each of the three
};

enum class DeviceType : uint8_t {
  kAny = 0,  ///< only in Hello: accept whatever device answers
  kGlove5 = 1,
  kSeaFinger = 2,
  kPantograph = 3,
};

/// Control mode carried by every command. What a setpoint means depends on the device (docs/protocol.md).
enum class Mode : uint8_t {
  kSafe = 0,         ///< outputs off; the device's passive state
  kTransparent = 1,  ///< zero interaction force/torque: the device follows the user
  kSetpoint = 2,     ///< track the per-channel setpoints (glove: fingertip force N; SEA: joint torque N·m; pen: motor torque N·m)
  kLock = 3,         ///< motors off, mechanism held passively (glove worm drive); same as safe on back-drivable devices
};
constexpr uint8_t kModeCount = 4;

enum class HandshakeStatus : uint8_t {
  kOk = 0,
  kVersionMismatch = 1,
  kDeviceMismatch = 2,
};

/// Fault bits (telemetry.fault_bits, Event.code for kFaultLatched). Sticky until ClearFaults.
namespace fault {
constexpr uint16_t kCommandTimeout = 1u << 0;  ///< no valid command within the last command's timeout
constexpr uint16_t kInvalidCommand = 1u << 1;  ///< command with NaN/Inf, out-of-range mode or setpoint
constexpr uint16_t kEstop = 1u << 2;           ///< e-stop input pressed
constexpr uint16_t kSensorRange = 1u << 3;     ///< ADC value outside its plausible range
constexpr uint16_t kSensorStuck = 1u << 4;     ///< sensor did not change while the mechanism moved
constexpr uint16_t kForceLimit = 1u << 5;      ///< measured force/torque beyond the hard limit
constexpr uint16_t kJointLimit = 1u << 6;      ///< joint outside its allowed range
constexpr uint16_t kCurrentLimit = 1u << 7;    ///< motor current beyond its limit
constexpr uint16_t kSensorSaturated = 1u << 8; ///< force sensor at full scale
constexpr uint16_t kMotorAngle = 1u << 9;      ///< motor angle outside its watchdog window (SEA ±60°)
constexpr uint16_t kTickOverrun = 1u << 10;    ///< control tick missed its deadline
constexpr uint16_t kInternal = 1u << 15;
}  // namespace fault

/// Telemetry state flags.
namespace state {
constexpr uint8_t kFaultLatched = 1u << 0;
constexpr uint8_t kEstopPressed = 1u << 1;
constexpr uint8_t kSessionOpen = 1u << 2;  ///< a Hello was accepted
constexpr uint8_t kOutputsActive = 1u << 3;  ///< motors are being driven this tick
}  // namespace state

struct Hello {
  static constexpr MsgId kId = MsgId::kHello;
  static constexpr size_t kWireSize = 8;
  uint16_t protocol_version = kProtocolVersion;
  DeviceType expected_device = DeviceType::kAny;
  uint8_t reserved = 0;
  uint32_t session_id = 0;
};

struct HelloAck {
  static constexpr MsgId kId = MsgId::kHelloAck;
  static constexpr size_t kWireSize = 16;
  uint16_t protocol_version = kProtocolVersion;
  DeviceType device_type = DeviceType::kAny;
  HandshakeStatus status = HandshakeStatus::kOk;
  uint32_t session_id = 0;
  uint32_t firmware_build_id = 0;
  uint16_t tick_rate_hz = 0;
  uint8_t setpoint_count = 0;
  uint8_t sample_count = 0;
};

/// Stateless full-state command: a lost one is harmless, the next carries everything again.
struct Command {
  static constexpr MsgId kId = MsgId::kCommand;
  static constexpr size_t kWireSize = 56;
  uint16_t seq = 0;            ///< echoed in telemetry; wraps
  uint16_t timeout_ms = 0;     ///< the device enters its safe state if no valid command follows within this (1..1000)
  Mode mode = Mode::kSafe;
  uint8_t flags = 0;           ///< reserved, must be 0
  uint8_t channel_count = 0;   ///< must equal the device's setpoint count
  uint8_t reserved = 0;
  float setpoint[kMaxSetpoints] = {};               ///< SI units of the device's setpoint kind
  uint16_t gain_scale_permille[kMaxSetpoints] = {};  ///< controller gain scale per channel, 0..2000 (1000 = nominal)
};

/// One per control tick. Samples are int16 fixed-point; the scale of each channel is given by its kind.
struct Telemetry {
  static constexpr MsgId kId = MsgId::kTelemetry;
  static constexpr size_t kWireSize = 64;
  uint32_t time_us = 0;       ///< device clock, wraps every 71.6 min; the host unwraps
  uint16_t seq = 0;           ///< telemetry sequence; gaps = lost telemetry
  uint16_t cmd_seq_echo = 0;  ///< seq of the last valid command applied
  Mode mode = Mode::kSafe;    ///< mode in effect this tick (kSafe whenever faulted)
  uint8_t state_flags = 0;    ///< state::*
  uint16_t fault_bits = 0;    ///< fault::* (latched)
  uint8_t cmd_lost = 0;       ///< running count mod 256 of commands missing from the sequence (a jump of n+1: n)
  uint8_t rx_errors = 0;      ///< running count mod 256 of rejected frames (framing, CRC, ID, length, fields, stale)
  int16_t sample[kMaxSamples] = {};
};

enum class EventCode : uint16_t {
  kFaultLatched = 1,    ///< value = all latched fault bits
  kFaultsCleared = 2,   ///< value = the bits cleared (never sent when nothing was latched)
  kClearRefused = 3,    ///< a fault condition is still present (e-stop held, sensor still implausible); value = its bits
  kCommandRejected = 4, ///< detail = RejectReason, channel and value say what was wrong
  kSessionOpened = 5,   ///< value = latched fault bits
};

/// Why a Command was rejected (Event kCommandRejected, detail). Explicit and never renumbered.
enum class RejectReason : uint8_t {
  kNoSession = 1,
  kBadMode = 2,
  kBadChannelCount = 3,
  kNonFinite = 4,        ///< channel = the setpoint (used or unused)
  kOutOfRange = 5,       ///< channel = the setpoint or gain; value = it. Unused channels: setpoint ≠ 0 or gain > 2000
  kBadTimeout = 6,
  kBadFlags = 7,
  kReservedNotZero = 8,  ///< the reserved byte; value = it
  kStaleSequence = 9,    ///< seq not newer than the newest received this session; value = that seq
  kUpdateInProgress = 10,  ///< a firmware update is being received: outputs stay off until it ends (a reboot)
  kSaveInProgress = 11,    ///< a settings save (core_param::kSettingsSave) is being written: outputs stay off until it ends
};

/// Core parameters (ParamGet/ParamSet IDs 0x0001..0x007F, answered by the firmware core, read-only except
/// kSettingsSave). MCU boards
/// answer 0x0080..0x00FF (board diagnostics, phalanx/fw_mcu/board_diag.h); device parameters start at 0x0100.
namespace core_param {
constexpr uint16_t kTickRate = 0x0001;       ///< firmware control tick rate, Hz
constexpr uint16_t kBuildIdLow = 0x0002;     ///< firmware_build_id bits 0..15 (exact in an f32)
constexpr uint16_t kBuildIdHigh = 0x0003;    ///< firmware_build_id bits 16..31
constexpr uint16_t kDeviceVariant = 0x0004;  ///< protocol::variant::* (what the firmware is mounted on)
/// Persistent settings (docs/params.md); unknown (kUnknownParam) on firmware without a settings store.
/// Set 1: save the device parameters the app persists to flash (kBusy while outputs are active or a save or an
/// update is under way, kFailed when the write failed; the previous record is kept). The answer comes when the
/// save has ended, which on an MCU board is some ticks later (docs/params.md). Read: sequence number of the newest
/// record stored (0: none).
constexpr uint16_t kSettingsSave = 0x0010;
constexpr uint16_t kSettingsLoad = 0x0011;     ///< what the load at start found: fw::SettingsLoad (settings_store.h)
constexpr uint16_t kSettingsLayout = 0x0012;   ///< the settings layout version this firmware writes
constexpr uint16_t kSettingsRefused = 0x0013;  ///< stored values not applied at start (refused by the app or dropped)
/// Trial boot (docs/firmware-update.md "Trial boot"); unknown (kUnknownParam) on firmware without an updater. Read:
/// 1 while the running image is on trial (booted once after an update, not yet confirmed: the next reset goes back
/// to the previous image), else 0. Set 1: confirm it (kFailed when the boot record could not be written).
constexpr uint16_t kUpdateTrial = 0x0014;
}  // namespace core_param

struct Event {
  static constexpr MsgId kId = MsgId::kEvent;
  static constexpr size_t kWireSize = 12;
  uint32_t time_us = 0;
  EventCode code = EventCode::kFaultLatched;
  uint8_t channel = 0;   ///< channel concerned, 0xFF = none
  uint8_t detail = 0;    ///< RejectReason for kCommandRejected
  float value = 0.0f;
};

struct ClearFaults {
  static constexpr MsgId kId = MsgId::kClearFaults;
  static constexpr size_t kWireSize = 4;
  uint32_t session_id = 0;
};

struct ParamGet {
  static constexpr MsgId kId = MsgId::kParamGet;
  static constexpr size_t kWireSize = 2;
  uint16_t param_id = 0;
};

struct ParamSet {
  static constexpr MsgId kId = MsgId::kParamSet;
  static constexpr size_t kWireSize = 8;
  uint16_t param_id = 0;
  uint16_t reserved = 0;
  float value = 0.0f;
};

enum class ParamStatus : uint8_t {
  kOk = 0,
  kUnknownParam = 1,
  kOutOfRange = 2,
  kReadOnly = 3,
  kBusy = 4,  ///< not settable while outputs are active
  kFailed = 5,  ///< the device could not do it (core_param::kSettingsSave: the flash write failed)
};

struct ParamValue {
  static constexpr MsgId kId = MsgId::kParamValue;
  static constexpr size_t kWireSize = 8;
  uint16_t param_id = 0;
  ParamStatus status = ParamStatus::kOk;
  uint8_t reserved = 0;
  float value = 0.0f;
};

/// Firmware update over the device's own link (docs/firmware-update.md). The image goes into the slot the device
/// did not boot from; the slot it runs from is never written, so a power or link loss at any point leaves it
/// bootable. Chunks are sequential: UpdateStatus.next_offset is always the first byte the device still needs.
struct UpdateBegin {
  static constexpr MsgId kId = MsgId::kUpdateBegin;
  static constexpr size_t kWireSize = 20;
  uint32_t image_size = 0;   ///< bytes of the image (its image-info block's image_size)
  uint32_t image_crc32 = 0;  ///< its image-info CRC-32
  uint32_t build_id = 0;     ///< its build id (the HelloAck's firmware_build_id after the update)
  uint8_t device_type = 0;   ///< protocol::DeviceType of the image
  uint8_t board = 0;         ///< image::BoardId it was linked for
  uint16_t reserved = 0;
  uint32_t session_id = 0;   ///< 0 or the open session's id (any other value is refused: another host's session)
};

/// Largest chunk of image in one UpdateData (a whole number of flash program units).
constexpr size_t kUpdateChunkBytes = 48;

struct UpdateData {
  static constexpr MsgId kId = MsgId::kUpdateData;
  static constexpr size_t kWireSize = 8 + kUpdateChunkBytes;
  uint32_t offset = 0;   ///< of data[0] in the image; a multiple of 8
  uint8_t length = 0;    ///< 1..kUpdateChunkBytes; a multiple of 8 except in the image's last chunk
  uint8_t reserved[3] = {};
  uint8_t data[kUpdateChunkBytes] = {};  ///< bytes past length must be 0
};

struct UpdateCommit {
  static constexpr MsgId kId = MsgId::kUpdateCommit;
  static constexpr size_t kWireSize = 8;
  uint32_t image_crc32 = 0;  ///< must be UpdateBegin's
  uint32_t build_id = 0;     ///< must be UpdateBegin's
};

/// What an update request came to. Explicit values, never renumbered.
enum class UpdateResult : uint8_t {
  kOk = 0,            ///< begun / chunk taken (or already had) / —
  kCommitted = 1,     ///< the image verified and is marked to boot: the device restarts into it now
  kBusy = 2,          ///< outputs are active: stop the motion first (nothing was changed)
  kBadImage = 3,      ///< UpdateBegin's fields do not suit this board (detail: UpdateImageField)
  kNotStarted = 4,    ///< data or commit without a begun update (or after a failure: begin again)
  kOutOfOrder = 5,    ///< chunk offset beyond next_offset: resend from next_offset
  kBadChunk = 6,      ///< length or offset breaks the rules, or runs past image_size
  kFlashError = 7,    ///< erase/program/read-back failed: begin again (the running image is untouched)
  kVerifyFailed = 8,  ///< at commit: the received image's CRC or image-info block is wrong: begin again
  kNoUpdater = 9,     ///< this board cannot be updated over its link
  kUnconfirmed = 10,  ///< the running image is on trial: confirm it (core_param::kUpdateTrial) or reset first
};
constexpr uint8_t kUpdateResultCount = 11;

/// UpdateStatus.detail for kBadImage: which of UpdateBegin's fields.
enum class UpdateImageField : uint8_t {
  kNone = 0, kDeviceType = 1, kBoard = 2, kSize = 3, kBuildId = 4, kReserved = 5, kSession = 6,
};

struct UpdateStatus {
  static constexpr MsgId kId = MsgId::kUpdateStatus;
  static constexpr size_t kWireSize = 12;
  MsgId answers = MsgId::kUpdateBegin;   ///< the request this answers
  UpdateResult result = UpdateResult::kOk;
  uint8_t detail = 0;                     ///< kBadImage: UpdateImageField
  uint8_t slot = 0;                       ///< the slot being written (0 or 1)
  uint32_t next_offset = 0;               ///< first image byte the device does not have yet
  uint32_t value = 0;                     ///< begin: the running build id; commit: the build id it will boot
};

// The in-memory structs are laid out without padding, so sizeof equals the wire size; the codec still
// serialises field by field (explicit little-endian), this only guards against silent layout drift.
static_assert(sizeof(Hello) == Hello::kWireSize);
static_assert(sizeof(HelloAck) == HelloAck::kWireSize);
static_assert(sizeof(Command) == Command::kWireSize);
static_assert(sizeof(Telemetry) == Telemetry::kWireSize);
static_assert(sizeof(Event) == Event::kWireSize);
static_assert(sizeof(ClearFaults) == ClearFaults::kWireSize);
static_assert(sizeof(ParamGet) == ParamGet::kWireSize);
static_assert(sizeof(ParamSet) == ParamSet::kWireSize);
static_assert(sizeof(ParamValue) == ParamValue::kWireSize);
static_assert(sizeof(UpdateBegin) == UpdateBegin::kWireSize);
static_assert(sizeof(UpdateData) == UpdateData::kWireSize);
static_assert(sizeof(UpdateCommit) == UpdateCommit::kWireSize);
static_assert(sizeof(UpdateStatus) == UpdateStatus::kWireSize);
static_assert(UpdateData::kWireSize <= kMaxPayload && kUpdateChunkBytes % 8 == 0);
static_assert(Telemetry::kWireSize <= kMaxPayload && Command::kWireSize <= kMaxPayload);

/// Wire size of a message ID's payload, or 0 for an unknown ID.
constexpr size_t wireSize(uint8_t id) {
  switch (static_cast<MsgId>(id)) {
    case MsgId::kHello: return Hello::kWireSize;
    case MsgId::kHelloAck: return HelloAck::kWireSize;
    case MsgId::kCommand: return Command::kWireSize;
    case MsgId::kTelemetry: return Telemetry::kWireSize;
    case MsgId::kEvent: return Event::kWireSize;
    case MsgId::kClearFaults: return ClearFaults::kWireSize;
    case MsgId::kParamGet: return ParamGet::kWireSize;
    case MsgId::kParamSet: return ParamSet::kWireSize;
    case MsgId::kParamValue: return ParamValue::kWireSize;
    case MsgId::kUpdateBegin: return UpdateBegin::kWireSize;
    case MsgId::kUpdateData: return UpdateData::kWireSize;
    case MsgId::kUpdateCommit: return UpdateCommit::kWireSize;
    case MsgId::kUpdateStatus: return UpdateStatus::kWireSize;
  }
  return 0;
}

}  // namespace phalanx::protocol
