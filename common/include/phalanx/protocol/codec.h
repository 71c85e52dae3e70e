#pragma once
/// Message ⇄ payload bytes (explicit little-endian, field by field) and the byte-stream framing:
/// frame = COBS(msg_id | payload | CRC-16/CCITT-FALSE(msg_id | payload), little-endian) followed by 0x00.
/// Freestanding: no heap, no exceptions.
#include <cstddef>
#include <cstdint>

#include "phalanx/protocol/messages.h"

namespace phalanx::protocol {

/// Largest encoded frame on a byte stream: COBS overhead 1 byte per 254 + delimiter.
constexpr size_t kMaxFrameBody = 1 + kMaxPayload + 2;
constexpr size_t kMaxEncodedFrame = kMaxFrameBody + 1 + (kMaxFrameBody / 254) + 1;

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor); check value "123456789" → 0x29B1.
uint16_t crc16(const uint8_t* data, size_t len, uint16_t crc = 0xFFFF);

/// COBS encode len bytes (no delimiter appended). Returns the encoded length; dst needs len + len/254 + 1 bytes.
size_t cobsEncode(const uint8_t* src, size_t len, uint8_t* dst);
/// COBS decode (input without the delimiter). Returns decoded length, or 0 on malformed input / overflow.
size_t cobsDecode(const uint8_t* src, size_t len, uint8_t* dst, size_t dst_cap);

// Payload serialisation. encode*: writes exactly T::kWireSize bytes. decode*: false if len != T::kWireSize or a
// field holds a value outside its enum (the message is then rejected, never half-applied).
void encodePayload(const Hello& m, uint8_t* out);
void encodePayload(const HelloAck& m, uint8_t* out);
void encodePayload(const Command& m, uint8_t* out);
void encodePayload(const Telemetry& m, uint8_t* out);
void encodePayload(const Event& m, uint8_t* out);
void encodePayload(const ClearFaults& m, uint8_t* out);
void encodePayload(const ParamGet& m, uint8_t* out);
void encodePayload(const ParamSet& m, uint8_t* out);
void encodePayload(const ParamValue& m, uint8_t* out);
void encodePayload(const UpdateBegin& m, uint8_t* out);
void encodePayload(const UpdateData& m, uint8_t* out);
void encodePayload(const UpdateCommit& m, uint8_t* out);
void encodePayload(const UpdateStatus& m, uint8_t* out);
bool decodePayload(const uint8_t* in, size_t len, Hello& m);
bool decodePayload(const uint8_t* in, size_t len, HelloAck& m);
bool decodePayload(const uint8_t* in, size_t len, Command& m);
bool decodePayload(const uint8_t* in, size_t len, Telemetry& m);
bool decodePayload(const uint8_t* in, size_t len, Event& m);
bool decodePayload(const uint8_t* in, size_t len, ClearFaults& m);
bool decodePayload(const uint8_t* in, size_t len, ParamGet& m);
bool decodePayload(const uint8_t* in, size_t len, ParamSet& m);
bool decodePayload(const uint8_t* in, size_t len, ParamValue& m);
bool decodePayload(const uint8_t* in, size_t len, UpdateBegin& m);
bool decodePayload(const uint8_t* in, size_t len, UpdateData& m);
bool decodePayload(const uint8_t* in, size_t len, UpdateCommit& m);
bool decodePayload(const uint8_t* in, size_t len, UpdateStatus& m);

/// Frame one message for a byte stream into out (capacity ≥ kMaxEncodedFrame). Returns bytes written incl. 0x00.
/// Single pass: the payload is serialised straight into its place in out, then one pass over id | payload computes
/// the CRC and turns the zero bytes into COBS codes in place (the bytes are those of cobsEncode over the body).
template <class Msg>
size_t encodeFrame(const Msg& m, uint8_t* out);
size_t encodeFrameRaw(uint8_t id, const uint8_t* payload, size_t len, uint8_t* out);
/// The framing step of encodeFrame: out[1] holds the ID and out[2 .. 2 + len) the payload (len ≤ kMaxPayload);
/// writes the CRC, the COBS codes and the delimiter around them. Returns the frame's length (len + 5).
size_t finishFrame(uint8_t* out, size_t len);

/// A decoded frame: message ID and its payload (valid until the next push() or feed()).
struct Frame {
  uint8_t id = 0;
  const uint8_t* payload = nullptr;
  size_t len = 0;
};

/// Counters of rejected input; never reset by the decoder itself.
struct DecodeStats {
  uint32_t frames_ok = 0;
  uint32_t crc_errors = 0;
  uint32_t framing_errors = 0;   ///< malformed COBS, too short, or longer than the largest frame
  uint32_t unknown_id = 0;
  uint32_t bad_length = 0;       ///< known ID, payload length differs from its wire size
  uint32_t total_rejected() const { return crc_errors + framing_errors + unknown_id + bad_length; }
};

/// Incremental byte-stream decoder: feed bytes as they arrive; a complete valid frame is reported once.
/// Bounded memory (one frame buffer, decoded in place); an oversized frame is discarded up to the next delimiter.
class StreamDecoder {
 public:
  /// Consumes bytes from [data, end) up to and including the delimiter of the next valid frame and returns true
  /// (frame() is then valid until the next push() or feed(); data points past that delimiter), or consumes them
  /// all and returns false. Call it until data == end. Same result as push() of every byte, a run at a time:
  /// the delimiter is found with memchr and the bytes before it copied with memcpy.
  bool feed(const uint8_t*& data, const uint8_t* end);
  /// One byte; returns true when it completes a valid frame (frame() is then valid until the next push()/feed()).
  bool push(uint8_t byte);
  const Frame& frame() const { return frame_; }
  const DecodeStats& stats() const { return stats_; }
  /// The stream was interrupted (a serial port reopened after a hang-up): drop what was collected. The first frame
  /// after it is judged like any other but, if rejected, not counted: it may be the tail of a frame the
  /// interruption cut. A whole first frame (a reopened port starts at a frame boundary, as a new pseudo-terminal
  /// or a re-enumerated CDC-ACM port does) is taken: it is often the device's answer to the new handshake.
  void resync() {
    raw_len_ = 0;
    overflow_ = false;
    after_resync_ = true;
  }

 private:
  bool judge();  // at a delimiter: the collected frame, quietly when it is the first after resync()
  bool judgeCollected(size_t n, bool overflow);  // COBS-decode raw_ in place and check the body
  bool after_resync_ = false;
  uint8_t raw_[kMaxEncodedFrame] = {};
  size_t raw_len_ = 0;
  bool overflow_ = false;
  Frame frame_;
  DecodeStats stats_;
};

/// Decode a frame body (already COBS-decoded: id | payload | crc) with the same checks as the stream decoder.
/// Used by packet transports (CAN-FD, USB bulk) that carry one frame per packet.
enum class BodyStatus : uint8_t { kOk = 0, kTooShort = 1, kCrc = 2, kUnknownId = 3, kBadLength = 4 };
BodyStatus checkBody(const uint8_t* body, size_t len, Frame& out);

template <class Msg>
size_t encodeFrame(const Msg& m, uint8_t* out) {
  static_assert(Msg::kWireSize <= kMaxPayload, "every payload fits one frame");
  out[1] = static_cast<uint8_t>(Msg::kId);
  encodePayload(m, out + 2);
  return finishFrame(out, Msg::kWireSize);
}

}  // namespace phalanx::protocol
