#pragma once
/// The protocol's CAN mapping (docs/protocol.md, "CAN and CAN-FD"): 11-bit identifiers carrying a function code
/// and the node id, CAN-FD frames carrying one whole message each (with an end-to-end CRC on every host → device
/// frame), a compact CAN-FD mapping (int16 setpoints and a rotating window of samples in one short frame per
/// direction per tick: the 1 kHz bus-load budget), and classic CAN compact encodings with a documented split for
/// what does not fit 8 bytes.
/// Freestanding (no heap, no exceptions): the SocketCAN transport (hal/linux) and MCU FDCAN ports share it.
#include <cstddef>
#include <cstdint>

#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::protocol::can {

/// Node ids 1..63 (6 bits of the identifier); 0 is reserved.
constexpr uint8_t kMinNode = 1;
constexpr uint8_t kMaxNode = 63;

/// kFd: one whole protocol message per CAN-FD frame. kFdCompact: CAN-FD frames, Command and Telemetry in the
/// compact encodings of docs/protocol.md ("CAN-FD compact"), every other message whole as in kFd.
enum class Flavor : uint8_t { kClassic = 0, kFd = 1, kFdCompact = 2 };
constexpr bool isFd(Flavor f) { return f != Flavor::kClassic; }
/// Which end of the link an endpoint is: it accepts only frames of the other direction.
enum class Role : uint8_t { kHost = 0, kDevice = 1 };

/// Function codes: identifier = function << 6 | node. Lower identifiers win arbitration, so the function code
/// is the priority: commands first, then telemetry, then the rare messages. Explicit and never renumbered.
enum class Function : uint8_t {
  kCommand = 0x01,           ///< host → device. FD: whole Command. Classic: part 0
  kCommandPart1Even = 0x02,  ///< host → device, classic: part 1 of a command with an even seq
  kCommandPart1Odd = 0x03,   ///< host → device, classic: part 1 of a command with an odd seq
  kTelemetry = 0x04,         ///< device → host. FD: whole Telemetry. Classic: status frame (sent last)
  kTelemetryGroup0 = 0x05,   ///< device → host, classic: samples 4g..4g+3 of group g = function − 0x05 (0..6)
  kEvent = 0x0C,             ///< device → host
  kClearFaults = 0x0D,       ///< host → device
  kHello = 0x0E,             ///< host → device
  kHelloAck = 0x0F,          ///< device → host. FD: whole HelloAck. Classic: part 0
  kHelloAckPart1 = 0x10,     ///< device → host, classic: part 1
  kParamGet = 0x11,          ///< host → device
  kParamSet = 0x12,          ///< host → device
  kParamValue = 0x13,        ///< device → host
  kUpdateBegin = 0x14,       ///< host → device, CAN-FD only (firmware update: docs/firmware-update.md)
  kUpdateData = 0x15,        ///< host → device, CAN-FD only
  kUpdateCommit = 0x16,      ///< host → device, CAN-FD only
  kUpdateStatus = 0x17,      ///< device → host, CAN-FD only
};
constexpr uint8_t kTelemetryGroups = (kMaxSamples + 3) / 4;  // 7 groups of 4 samples

constexpr uint32_t canId(Function f, uint8_t node) { return (static_cast<uint32_t>(f) << 6) | (node & 0x3Fu); }
constexpr uint8_t nodeOf(uint32_t id) { return static_cast<uint8_t>(id & 0x3Fu); }
constexpr uint8_t functionOf(uint32_t id) { return static_cast<uint8_t>((id >> 6) & 0x1Fu); }

/// One frame as the mapping sees it (the SocketCAN layer copies to and from struct can(fd)_frame).
struct CanFrame {
  uint32_t id = 0;        ///< 11-bit identifier (29-bit when extended)
  uint8_t len = 0;        ///< data bytes: 0..8 classic, 0..8/12/16/20/24/32/48/64 CAN-FD
  bool fd = false;        ///< a CAN-FD frame
  bool extended = false;  ///< 29-bit identifier (never used by the protocol: rejected)
  bool remote = false;    ///< remote request (never used: rejected)
  uint8_t data[64] = {};
};

/// The smallest CAN-FD data length that holds n bytes (CAN-FD lengths above 8 are 12,16,20,24,32,48,64).
constexpr uint8_t fdLength(size_t n) {
  return n <= 8 ? static_cast<uint8_t>(n)
         : n <= 12 ? 12
         : n <= 16 ? 16
         : n <= 20 ? 20
         : n <= 24 ? 24
         : n <= 32 ? 32
         : n <= 48 ? 48
                   : 64;
}

/// CAN-FD compact (docs/protocol.md, "CAN-FD compact"). Command: seq u16 | timeout_ms (bits 0-9) + mode (bits
/// 10-11) u16 | setpoint i16[n] | gain code u8[n] | CRC-16. Telemetry: seq u16 | cmd_seq_echo u16 | fault_bits u16
/// | mode + state_flags u8 | cmd_lost u8 | rx_errors u8 | first u8 | sample i16[K] (samples first..first+K-1 mod S).
constexpr uint16_t kCompactMaxTimeoutMs = 1023;   ///< 10-bit field; the device itself requires 1..1000
constexpr uint16_t kCompactGainStepPermille = 8;  ///< gain code LSB: 1000 ‰ = 125, 2000 ‰ = 250 (both exact)
constexpr uint8_t kCompactMaxGainCode = 250;      ///< 2000 ‰, the device's limit; codes above are rejected
constexpr size_t kCompactCommandHeader = 4;
constexpr size_t kCompactTelemetryHeader = 10;
/// Samples per compact telemetry frame: the 32-byte frame the 20 % budget allows (10 + 2·11 = 32 bytes).
constexpr uint8_t kCompactWindow = 11;
constexpr size_t compactCommandBytes(uint8_t setpoints) { return kCompactCommandHeader + 3u * setpoints + 2u; }
constexpr uint8_t compactWindow(uint8_t samples) { return samples < kCompactWindow ? samples : kCompactWindow; }
constexpr size_t compactTelemetryBytes(uint8_t samples) { return kCompactTelemetryHeader + 2u * compactWindow(samples); }

/// Most frames one message maps to (classic telemetry: two sample groups + status).
constexpr size_t kMaxFramesPerMessage = 3;

/// Classic CAN per-device parameters: the fixed-point kind of a setpoint (the same scale as telemetry samples of
/// that kind) and how many 4-sample telemetry groups are sent per tick (the budget in docs/protocol.md).
struct ClassicProfile {
  SampleKind setpoint_kind;
  uint8_t groups_per_tick;
};
constexpr ClassicProfile classicProfile(DeviceType type) {
  switch (type) {
    case DeviceType::kGlove5: return {SampleKind::kForce, 1};      // 7 groups: each sample every 7 ticks
    case DeviceType::kSeaFinger: return {SampleKind::kTorque, 2};  // 3 groups: each every 1.5 ticks
    case DeviceType::kPantograph: return {SampleKind::kTorque, 1}; // 3 groups: each every 3 ticks
    case DeviceType::kAny: break;
  }
  return {SampleKind::kForce, 0};
}
/// Classic command limits: timeout_ms is one byte, gain scales are not carried (always 1000 ‰).
constexpr uint16_t kClassicMaxTimeoutMs = 255;
constexpr int16_t kClassicNotFinite = -32768;  ///< setpoint code for NaN/Inf (decodes to NaN: the device rejects it)

/// Counters of received frames. A rejected frame is never partly applied.
struct RxStats {
  uint32_t frames_ok = 0;      ///< frames accepted (classic: parts included)
  uint32_t messages_ok = 0;    ///< whole messages delivered
  uint32_t bad_id = 0;         ///< unknown function, other node, wrong direction, extended or remote frame
  uint32_t bad_length = 0;     ///< length, padding, FD/classic format, reserved bits or an undefined field code
  uint32_t crc = 0;            ///< end-to-end CRC failed (CAN-FD host → device frames)
  uint32_t sequence = 0;       ///< classic: a part out of order, or a message left incomplete
  uint32_t total_rejected() const { return bad_id + bad_length + crc + sequence; }
};

enum class EncodeStatus : uint8_t {
  kOk = 0,
  kUnknownMessage = 1,    ///< not a protocol message ID, or the payload length differs from its wire size
  kWrongDirection = 2,    ///< this endpoint does not send that message
  kNotRepresentable = 3,  ///< a field the compact encoding cannot carry: Mapper::refusal() names it
  kNoDevice = 4,          ///< classic command/telemetry before the device type is known
};

/// One endpoint's mapping state: encoder (message → frames) and decoder (frames → message, with the classic
/// reassembly state). The device side knows its device at start; the host side learns it from the HelloAck.
class Mapper {
 public:
  Mapper(Flavor flavor, Role role, uint8_t node) : flavor_(flavor), role_(role), node_(node) {}
  /// The device this link talks to/for, and its tick rate (classic telemetry time is derived from it).
  void setDevice(DeviceType type, uint16_t tick_rate_hz);
  const DeviceLayout* layout() const { return layout_; }

  /// Map one message (payload of exactly its wire size) to frames in out[kMaxFramesPerMessage], in sending
  /// order. Returns the number of frames; 0 with status set when the message cannot be sent on this link.
  size_t encode(uint8_t msg_id, const uint8_t* payload, size_t len, CanFrame* out, EncodeStatus& status);

  /// Feed one received frame. Returns true when it completes a message: then msg_id, payload (≥ 64 bytes) and
  /// len hold it, checked against the wire size. Rejected frames are counted in stats().
  bool decode(const CanFrame& frame, uint8_t& msg_id, uint8_t* payload, size_t& len);
  const RxStats& stats() const { return stats_; }
  /// Why the last encode() returned kNotRepresentable (a static string naming the field), nullptr if none was.
  const char* refusal() const { return refusal_; }
  Flavor flavor() const { return flavor_; }
  uint8_t node() const { return node_; }

 private:
  bool decodeFd(const CanFrame& f, uint8_t fn, uint8_t& msg_id, uint8_t* payload, size_t& len);
  bool decodeClassic(const CanFrame& f, uint8_t fn, uint8_t& msg_id, uint8_t* payload, size_t& len);
  size_t encodeClassic(uint8_t msg_id, const uint8_t* payload, size_t len, CanFrame* out, EncodeStatus& status);
  bool encodeCompact(uint8_t msg_id, const uint8_t* payload, CanFrame& f, EncodeStatus& status);
  bool decodeCompactCommand(const CanFrame& f, uint8_t* payload);
  bool decodeCompactTelemetry(const CanFrame& f, uint8_t* payload);
  void resetTelemetryClock();
  uint32_t derivedTimeUs() const;

  Flavor flavor_;
  Role role_;
  uint8_t node_;
  const DeviceLayout* layout_ = nullptr;
  ClassicProfile profile_{SampleKind::kForce, 0};
  uint32_t period_us_ = 1000;
  RxStats stats_;
  const char* refusal_ = nullptr;
  // Classic encoder: next telemetry group to send. Compact encoder: first sample of the next window.
  uint8_t next_group_ = 0;
  uint8_t next_first_ = 0;
  // Classic decoder: command part 0 awaiting part 1, HelloAck part 0 awaiting part 1, held telemetry samples
  // (also the compact decoder's held samples and derived telemetry clock).
  bool cmd_pending_ = false;
  uint8_t cmd_part0_[8] = {};
  bool ack_pending_ = false;
  uint8_t ack_part0_[8] = {};
  int16_t held_[kMaxSamples] = {};
  bool have_tel_seq_ = false;
  uint16_t last_tel_seq_ = 0;
  uint64_t tel_ticks_ = 0;
  uint8_t cmd_lost_nibble_ = 0, rx_err_nibble_ = 0;
  uint8_t cmd_lost_ = 0, rx_errors_ = 0;
};

/// Bus time of one frame (docs/protocol.md, "Bus load"): 11-bit identifier, worst-case dynamic bit stuffing
/// when worst_case_stuffing (else none), CAN-FD with bit-rate switch when data_bps ≠ nominal_bps.
double frameTimeS(const CanFrame& frame, double nominal_bps, double data_bps, bool worst_case_stuffing);
/// Bits on the wire of a classic 11-bit frame with n data bytes (Davis et al. 2007: 47 + 8n + stuff bits).
constexpr uint32_t classicFrameBits(uint32_t n, bool worst_case_stuffing) {
  return 47u + 8u * n + (worst_case_stuffing ? (34u + 8u * n - 1u) / 4u : 0u);
}

}  // namespace phalanx::protocol::can
