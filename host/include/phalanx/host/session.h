#pragma once
/// The host's protocol endpoint for one device: handshake, command sending, telemetry decoding and the
/// link statistics (lost frames, CRC errors, round-trip latency from the echoed command sequence).
#include <array>
#include <functional>
#include <cstdint>
#include <string>

#include "phalanx/hal/hal.h"
#include "phalanx/host/stats.h"
#include "phalanx/protocol/codec.h"
#include "phalanx/protocol/devices.h"

namespace phalanx::host {

/// One decoded telemetry frame in SI units.
struct TelemetryFrame {
  uint64_t device_time_us = 0;  ///< unwrapped device clock
  uint64_t host_rx_ns = 0;
  uint16_t seq = 0;
  uint16_t cmd_seq_echo = 0;
  protocol::Mode mode = protocol::Mode::kSafe;
  uint8_t state_flags = 0;
  uint16_t fault_bits = 0;
  uint8_t sample_count = 0;
  std::array<float, protocol::kMaxSamples> value{};
};

struct LinkStats {
  uint64_t telemetry_received = 0;
  uint64_t telemetry_lost = 0;       ///< gaps in the telemetry sequence (not counting frames that came late)
  uint64_t telemetry_late = 0;       ///< frames older than the newest received (reordered): dropped, not lost
  uint64_t commands_sent = 0;
  uint64_t commands_unsent = 0;      ///< link buffer full
  uint64_t device_cmd_lost = 0;      ///< commands the device reported missing from the sequence (unwrapped)
  uint64_t device_rx_errors = 0;     ///< frames the device rejected (unwrapped)
  protocol::DecodeStats host_rx;     ///< frames the host rejected
  uint64_t events = 0;
};

enum class HandshakeResult { kPending, kOk, kVersionMismatch, kDeviceMismatch, kTimeout };

class HostSession {
 public:
  explicit HostSession(hal::ByteLink& link);
  /// The same session over a message-per-packet transport (CAN-FD, classic CAN).
  explicit HostSession(hal::PacketLink& packets);

  void sendHello(uint32_t session_id, protocol::DeviceType expected);
  /// A whole handshake, for the command-line tools (not the session runner): a Hello with a random session id
  /// every 500 ms (a backed-up link may lose one; push() sends it) until the device answers or `timeout_s` passes,
  /// or gone() names why the device cannot answer. "" once it succeeded (deviceInfo() is the HelloAck), else why
  /// not; `what` names the link in the message.
  std::string handshakeWithin(double timeout_s, protocol::DeviceType expected, const std::string& what,
                              const std::function<void()>& push, const std::function<std::string()>& gone = {});
  /// Assigns the next sequence number, records the send time for the round-trip measurement, sends.
  bool sendCommand(protocol::Command& cmd, uint64_t now_ns);
  void sendClearFaults();
  /// The byte stream was interrupted and reopened: a frame cut by the interruption is dropped, not counted.
  void resyncStream() { decoder_.resync(); }
  bool sendParamGet(uint16_t id);
  bool sendParamSet(uint16_t id, float value);
  /// Firmware update requests (docs/firmware-update.md); each is answered by an UpdateStatus (popUpdateStatus).
  bool sendUpdate(const protocol::UpdateBegin& m);
  bool sendUpdate(const protocol::UpdateData& m);
  bool sendUpdate(const protocol::UpdateCommit& m);

  /// Read everything available now. Returns how many telemetry frames arrived; latest() is the newest.
  int poll(uint64_t now_ns);

  HandshakeResult handshake() const { return handshake_; }
  const protocol::HelloAck& deviceInfo() const { return ack_; }
  const protocol::DeviceLayout* layout() const { return layout_; }
  /// Human-readable reason for a failed handshake.
  std::string handshakeError() const;
  const TelemetryFrame& latest() const { return latest_; }
  bool hasTelemetry() const { return stats_.telemetry_received > 0; }
  const LinkStats& stats() const { return stats_; }
  const Histogram& roundTripUs() const { return rtt_us_; }
  /// Sensor to actuation, in device time: from the device tick whose telemetry was the newest when a command was
  /// sent (the sample it was computed from) to the tick whose telemetry first echoes it (the tick that applied
  /// it). One device period is the least a firmware that reads commands once per tick allows (docs/session-runner.md).
  const Histogram& sensorToActuationUs() const { return s2a_us_; }
  /// When the last command was handed to the link (sendCommand's now_ns).
  uint64_t lastSendNs() const { return last_send_ns_; }
  /// Last event received (fault latched, command rejected, …).
  const protocol::Event& lastEvent() const { return last_event_; }
  /// Called for each event (for logging); optional.
  void setEventCallback(void (*fn)(void*, const protocol::Event&), void* ctx) {
    event_fn_ = fn;
    event_ctx_ = ctx;
  }
  /// Watch for the first telemetry after the one numbered after_seq that reports the safe state (mode safe,
  /// outputs off) - every frame is examined, not only the newest of a poll (the e-stop measurement, docs/gpio.md).
  void watchForSafe(uint16_t after_seq) {
    safe_watch_ = true;
    safe_seen_ = false;
    safe_after_seq_ = after_seq;
    safe_cmd_marked_ = false;
    safe_cmd_arrived_ = false;
  }
  /// The sequence number of the first safe command sent for the watched stop: the first telemetry that echoes it
  /// (or a later one) is the tick the device had it, so deviceTicksToSafe() counts the firmware's own reaction
  /// in its ticks, free of how long the host or an emulator took to send it.
  void markSafeCommand(uint16_t cmd_seq) {
    safe_cmd_seq_ = cmd_seq;
    safe_cmd_marked_ = true;
  }
  /// Device ticks from the telemetry that first echoed the safe command to the one that reported safe (0 when
  /// the device was safe in the tick it had the command, or went safe before it).
  uint16_t deviceTicksToSafe() const { return safe_cmd_arrived_ ? static_cast<uint16_t>(safe_seq_ - safe_cmd_arrival_seq_) : 0; }
  bool safeSeen() const { return safe_seen_; }
  uint16_t safeSeq() const { return safe_seq_; }
  uint64_t safeRxNs() const { return safe_rx_ns_; }  ///< the poll time of the frame that reported it
  bool lastParamValid() const { return param_valid_; }
  const protocol::ParamValue& lastParam() const { return last_param_; }
  /// The oldest UpdateStatus not taken yet; false when none. Up to kUpdateStatusQueue are kept; beyond that the
  /// oldest is dropped and counted (updateStatusDropped).
  bool popUpdateStatus(protocol::UpdateStatus& out);
  uint32_t updateStatusDropped() const { return update_dropped_; }
  static constexpr size_t kUpdateStatusQueue = 64;

 private:
  void handleFrame(const protocol::Frame& frame, uint64_t now_ns);
  template <class Msg>
  bool sendMsg(const Msg& m);

  hal::ByteLink* link_ = nullptr;
  hal::PacketLink* packets_ = nullptr;
  protocol::StreamDecoder decoder_;
  HandshakeResult handshake_ = HandshakeResult::kPending;
  uint32_t session_id_ = 0;
  protocol::HelloAck ack_{};
  const protocol::DeviceLayout* layout_ = nullptr;
  TelemetryFrame latest_;
  LinkStats stats_;
  Histogram rtt_us_;
  uint16_t next_seq_ = 1;
  static constexpr size_t kSendLog = 1024;  // power of two; outstanding commands tracked for RTT
  std::array<uint64_t, kSendLog> sent_ns_{};
  std::array<uint16_t, kSendLog> sent_seq_{};
  std::array<uint64_t, kSendLog> sent_from_us_{};  ///< newest telemetry's device time when each was sent
  Histogram s2a_us_;
  uint64_t last_send_ns_ = 0;
  bool have_tel_seq_ = false;
  uint16_t last_tel_seq_ = 0;
  uint32_t last_time_us_ = 0;
  uint64_t time_wraps_ = 0;
  uint8_t last_dev_cmd_lost_ = 0;
  uint8_t last_dev_rx_errors_ = 0;
  uint16_t last_echo_ = 0;
  bool have_echo_ = false;
  protocol::Event last_event_{};
  void (*event_fn_)(void*, const protocol::Event&) = nullptr;
  void* event_ctx_ = nullptr;
  protocol::ParamValue last_param_{};
  bool param_valid_ = false;
  std::array<protocol::UpdateStatus, kUpdateStatusQueue> update_queue_{};
  size_t update_head_ = 0, update_count_ = 0;
  uint32_t update_dropped_ = 0;
  bool safe_watch_ = false;
  bool safe_seen_ = false;
  uint16_t safe_after_seq_ = 0;
  uint16_t safe_seq_ = 0;
  uint64_t safe_rx_ns_ = 0;
  uint16_t safe_cmd_seq_ = 0;
  bool safe_cmd_marked_ = false;
  bool safe_cmd_arrived_ = false;
  uint16_t safe_cmd_arrival_seq_ = 0;
};

const char* faultName(uint16_t single_bit);
/// "command-timeout|estop" style list of the set bits, "none" when 0.
std::string faultList(uint16_t bits);
const char* modeName(protocol::Mode mode);

}  // namespace phalanx::host
