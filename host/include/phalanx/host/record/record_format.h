#pragma once
/// Session record format (`.phrec`), version 1: crash-safe, append-only, one file per session.
///
///   file   := "PHXREC1\n" record*
///   record := sync:u32 (0x43455250, "PREC") | length:u16 | type:u8 | reserved:u8 (0) | payload[length] |
///             crc32:u32 (zlib CRC-32 of length..payload)
///
/// All integers little-endian, floats IEEE-754. A reader checks sync, length and CRC of every record; a record
/// that fails (a torn tail after `kill -9` or power loss, or a damaged block) is skipped by scanning for the
/// next sync word, so one bad record never hides the rest of the file. docs/records.md is the prose spec.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "phalanx/protocol/messages.h"

namespace phalanx::host::record {

inline constexpr char kFileMagic[8] = {'P', 'H', 'X', 'R', 'E', 'C', '1', '\n'};
inline constexpr uint32_t kSync = 0x43455250u;  // "PREC" little-endian
inline constexpr std::size_t kRecordOverhead = 4 + 2 + 1 + 1 + 4;
inline constexpr std::size_t kMaxPayload = 65535;
/// Per-channel values a therapy exercise publishes beside the command (target, assistance gain, …); named in
/// the header's "aux" list.
inline constexpr std::size_t kMaxAux = 32;

enum class RecordType : uint8_t {
  kHeader = 1,  ///< JSON: device, layout, rate, patient, exercise, aux names, wall-clock start
  kCycle = 2,   ///< binary CycleRecord: one per host cycle
  kEvent = 3,   ///< JSON: {"t_s", "kind", ...} — device faults, mode/exercise changes, API requests, limits
  kFooter = 4,  ///< JSON: end-of-session summary (absent when the daemon died)
  /// A block of cycles (format version 2): u16 count, u16 cycle payload length L (every cycle in a block has the
  /// same), then zlib (deflate) of the count cycle payloads transposed byte-wise (byte 0 of every cycle, then byte
  /// 1, …): slowly changing values then sit in long runs. One per writer flush (20 ms): a kill still loses ≤ 20 ms.
  kCycleBlock = 5,
};

/// One host cycle: the telemetry it used and the command it sent.
struct CycleRecord {
  uint64_t host_ns = 0;          ///< CLOCK_MONOTONIC at the cycle's wake-up
  double t_s = 0.0;              ///< since the session's first cycle
  uint64_t device_time_us = 0;
  uint16_t tel_seq = 0;
  uint16_t cmd_seq_echo = 0;
  uint16_t cmd_seq = 0;
  uint16_t fault_bits = 0;
  uint8_t tel_mode = 0;
  uint8_t cmd_mode = 0;
  uint8_t state_flags = 0;
  uint8_t sample_count = 0;
  uint8_t setpoint_count = 0;
  uint8_t aux_count = 0;
  std::array<float, protocol::kMaxSamples> sample{};
  std::array<float, protocol::kMaxSetpoints> setpoint{};
  std::array<float, kMaxAux> aux{};
};

/// Appends one framed record (sync … crc) to out.
void appendRecord(std::vector<uint8_t>& out, RecordType type, const uint8_t* payload, std::size_t length);
/// Binary payload of a cycle record; returns its length (≤ kMaxCyclePayload).
std::size_t encodeCycle(const CycleRecord& c, uint8_t* out);
inline constexpr std::size_t kMaxCyclePayload =
    8 + 8 + 8 + 2 * 4 + 6 + 4 * (protocol::kMaxSamples + protocol::kMaxSetpoints + kMaxAux);
/// false when the payload is not a valid cycle record (lengths inconsistent).
bool decodeCycle(const uint8_t* payload, std::size_t length, CycleRecord& c);
/// Uncompressed bytes a cycle block may hold (its compressed payload stays below kMaxPayload).
inline constexpr std::size_t kMaxBlockBytes = 48 * 1024;
/// Cycle-block payload of `count` encoded cycles of `length` bytes each, back to back in `cycles`; empty when it
/// cannot be compressed (the caller writes plain cycle records then).
std::vector<uint8_t> encodeCycleBlock(const uint8_t* cycles, uint16_t count, uint16_t length);
/// The cycles of a block payload, appended to out; false when the block is damaged (nothing appended).
bool decodeCycleBlock(const uint8_t* payload, std::size_t length, std::vector<CycleRecord>& out);

}  // namespace phalanx::host::record
