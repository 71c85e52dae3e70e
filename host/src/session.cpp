#include "phalanx/host/session.h"

#include <unistd.h>

#include <random>

#include "phalanx/linux/realtime.h"

namespace phalanx::host {

using namespace protocol;

HostSession::HostSession(hal::ByteLink& link) : link_(&link) {}
HostSession::HostSession(hal::PacketLink& packets) : packets_(&packets) {}

template <class Msg>
bool HostSession::sendMsg(const Msg& m) {
  if (packets_ != nullptr) {
    uint8_t payload[Msg::kWireSize];
    encodePayload(m, payload);
    return packets_->send(static_cast<uint8_t>(Msg::kId), payload, Msg::kWireSize);
  }
  uint8_t frame[kMaxEncodedFrame];
  const size_t n = encodeFrame(m, frame);
  if (link_->writeSpace() < n) return false;
  return link_->write(frame, n) == n;
}

void HostSession::sendHello(uint32_t session_id, DeviceType expected) {
  Hello h;
  h.expected_device = expected;
  h.session_id = session_id;
  session_id_ = session_id;
  handshake_ = HandshakeResult::kPending;
  // A new session (also after a reconnect) starts a new telemetry sequence baseline: a gap across the outage is
  // the outage, reported by the daemon, not frames lost inside a session.
  have_tel_seq_ = false;
  // On a byte stream the device may hold the start of a frame a previous host wrote and never finished (its
  // process died, or closing the port discarded the rest): without a delimiter first, the Hello would be read as
  // that frame's tail and fail its CRC. A lone 0x00 ends such a fragment and is idle fill to a device holding none.
  if (link_ != nullptr) {
    const uint8_t delimiter = 0;
    link_->write(&delimiter, 1);
  }
  sendMsg(h);
}

bool HostSession::sendCommand(Command& cmd, uint64_t now_ns) {
  cmd.seq = next_seq_++;
  const size_t slot = cmd.seq & (kSendLog - 1);
  sent_ns_[slot] = now_ns;
  sent_seq_[slot] = cmd.seq;
  sent_from_us_[slot] = latest_.device_time_us;
  last_send_ns_ = now_ns;
  if (!sendMsg(cmd)) {
    ++stats_.commands_unsent;
    return false;
  }
  ++stats_.commands_sent;
  return true;
}

void HostSession::sendClearFaults() {
  ClearFaults c;
  c.session_id = session_id_;
  sendMsg(c);
}

bool HostSession::sendParamGet(uint16_t id) {
  ParamGet g;
  g.param_id = id;
  param_valid_ = false;
  return sendMsg(g);
}

bool HostSession::sendParamSet(uint16_t id, float value) {
  ParamSet set;
  set.param_id = id;
  set.value = value;
  param_valid_ = false;
  return sendMsg(set);
}

std::string HostSession::handshakeWithin(double timeout_s, protocol::DeviceType expected, const std::string& what,
                                         const std::function<void()>& push, const std::function<std::string()>& gone) {
  std::random_device rd;
  const uint32_t session_id = rd();
  const auto timeout_ns = static_cast<uint64_t>(timeout_s * 1e9);
  const uint64_t t0 = linux_hal::monotonicNs();
  uint64_t last_hello = 0;
  while (handshake_ == HandshakeResult::kPending) {
    const uint64_t now = linux_hal::monotonicNs();
    if (now - t0 > timeout_ns) return "the device did not answer the handshake on " + what;
    if (last_hello == 0 || now - last_hello > 500000000ull) {
      sendHello(session_id, expected);
      push();
      last_hello = now;
    }
    if (gone) {
      if (std::string why = gone(); !why.empty()) return why;
    }
    usleep(1000);
    poll(linux_hal::monotonicNs());
  }
  return handshake_ == HandshakeResult::kOk ? "" : handshakeError();
}

bool HostSession::sendUpdate(const protocol::UpdateBegin& m) { return sendMsg(m); }
bool HostSession::sendUpdate(const protocol::UpdateData& m) { return sendMsg(m); }
bool HostSession::sendUpdate(const protocol::UpdateCommit& m) { return sendMsg(m); }

bool HostSession::popUpdateStatus(protocol::UpdateStatus& out) {
  if (update_count_ == 0) return false;
  out = update_queue_[update_head_];
  update_head_ = (update_head_ + 1) % kUpdateStatusQueue;
  --update_count_;
  return true;
}

int HostSession::poll(uint64_t now_ns) {
  int telemetry = 0;
  if (packets_ != nullptr) {
    uint8_t payload[kMaxPayload];
    Frame f;
    f.payload = payload;
    // Bounded per poll: a flooded bus cannot hold the control loop.
    for (int i = 0; i < 256 && packets_->receive(f.id, payload, f.len); ++i) {
      ++stats_.host_rx.frames_ok;
      if (f.id == static_cast<uint8_t>(MsgId::kTelemetry)) ++telemetry;
      handleFrame(f, now_ns);
    }
    const hal::PacketRxStats r = packets_->rxStats();
    stats_.host_rx.crc_errors = r.crc;
    stats_.host_rx.framing_errors = r.sequence;
    stats_.host_rx.unknown_id = r.bad_id;
    stats_.host_rx.bad_length = r.bad_length;
    return telemetry;
  }
  uint8_t buf[512];
  for (;;) {
    const size_t n = link_->read(buf, sizeof buf);
    if (n == 0) break;
    for (const uint8_t* p = buf; p < buf + n;) {  // each feed() consumes at least one byte
      if (!decoder_.feed(p, buf + n)) continue;
      const Frame& f = decoder_.frame();
      if (f.id == static_cast<uint8_t>(MsgId::kTelemetry)) ++telemetry;
      handleFrame(f, now_ns);
    }
  }
  stats_.host_rx = decoder_.stats();
  return telemetry;
}

void HostSession::handleFrame(const Frame& f, uint64_t now_ns) {
  switch (static_cast<MsgId>(f.id)) {
    case MsgId::kHelloAck: {
      HelloAck a;
      if (!decodePayload(f.payload, f.len, a) || a.session_id != session_id_) return;
      ack_ = a;
      if (a.status == HandshakeStatus::kVersionMismatch || a.protocol_version != kProtocolVersion) {
        handshake_ = HandshakeResult::kVersionMismatch;
      } else if (a.status == HandshakeStatus::kDeviceMismatch) {
        handshake_ = HandshakeResult::kDeviceMismatch;
      } else {
        layout_ = layoutFor(a.device_type);
        handshake_ = layout_ != nullptr && layout_->sample_count == a.sample_count &&
                             layout_->setpoint_count == a.setpoint_count
                         ? HandshakeResult::kOk
                         : HandshakeResult::kDeviceMismatch;
      }
      return;
    }
    case MsgId::kTelemetry: {
      Telemetry t;
      if (handshake_ != HandshakeResult::kOk || !decodePayload(f.payload, f.len, t)) return;
      if (have_tel_seq_) {
        const uint16_t gap = static_cast<uint16_t>(t.seq - last_tel_seq_ - 1u);
        if (gap >= 0x8000u) {
          // Not newer than the newest: a frame that arrived late (a device's transmit queue or a bus reordered it;
          // seen over CAN-FD in the VM lane). It is not the device's state now and its older clock is no wrap;
          // it was counted lost when the newer one jumped over it.
          ++stats_.telemetry_late;
          if (stats_.telemetry_lost > 0) --stats_.telemetry_lost;
          return;
        }
        stats_.telemetry_lost += gap;
        if (t.time_us < last_time_us_) ++time_wraps_;
        stats_.device_cmd_lost += static_cast<uint8_t>(t.cmd_lost - last_dev_cmd_lost_);
        stats_.device_rx_errors += static_cast<uint8_t>(t.rx_errors - last_dev_rx_errors_);
      }
      // Else: the first telemetry of a session only sets the baseline of the device's counters (what they held
      // before this session is not ours; what earlier sessions of this run accumulated stays counted).
      have_tel_seq_ = true;
      last_tel_seq_ = t.seq;
      last_time_us_ = t.time_us;
      last_dev_cmd_lost_ = t.cmd_lost;
      last_dev_rx_errors_ = t.rx_errors;
      ++stats_.telemetry_received;

      if (safe_watch_ && safe_cmd_marked_ && !safe_cmd_arrived_ &&
          static_cast<int16_t>(static_cast<uint16_t>(t.cmd_seq_echo - safe_cmd_seq_)) >= 0) {
        safe_cmd_arrived_ = true;
        safe_cmd_arrival_seq_ = t.seq;
      }
      if (safe_watch_ && t.seq != safe_after_seq_ && t.mode == Mode::kSafe &&
          (t.state_flags & protocol::state::kOutputsActive) == 0) {
        safe_watch_ = false;
        safe_seen_ = true;
        safe_seq_ = t.seq;
        safe_rx_ns_ = now_ns;
      }
      latest_.device_time_us = (time_wraps_ << 32) | t.time_us;
      latest_.host_rx_ns = now_ns;
      latest_.seq = t.seq;
      latest_.cmd_seq_echo = t.cmd_seq_echo;
      latest_.mode = t.mode;
      latest_.state_flags = t.state_flags;
      latest_.fault_bits = t.fault_bits;
      latest_.sample_count = layout_->sample_count;
      for (uint8_t i = 0; i < layout_->sample_count; ++i) {
        latest_.value[i] = decodeSample(t.sample[i], layout_->sample_kind[i]);
      }
      // Round trip: the first telemetry that echoes a command we sent closes that command's measurement.
      if (!have_echo_ || t.cmd_seq_echo != last_echo_) {
        const size_t slot = t.cmd_seq_echo & (kSendLog - 1);
        if (sent_seq_[slot] == t.cmd_seq_echo && sent_ns_[slot] != 0) {
          rtt_us_.add(static_cast<double>(now_ns - sent_ns_[slot]) / 1000.0);
          if (sent_from_us_[slot] != 0 && latest_.device_time_us >= sent_from_us_[slot]) {
            s2a_us_.add(static_cast<double>(latest_.device_time_us - sent_from_us_[slot]));
          }
          sent_ns_[slot] = 0;
        }
        last_echo_ = t.cmd_seq_echo;
        have_echo_ = true;
      }
      return;
    }
    case MsgId::kEvent: {
      Event e;
      if (!decodePayload(f.payload, f.len, e)) return;
      ++stats_.events;
      last_event_ = e;
      if (event_fn_ != nullptr) event_fn_(event_ctx_, e);
      return;
    }
    case MsgId::kParamValue: {
      if (decodePayload(f.payload, f.len, last_param_)) param_valid_ = true;
      return;
    }
    case MsgId::kUpdateStatus: {
      protocol::UpdateStatus st;
      if (!decodePayload(f.payload, f.len, st)) return;
      if (update_count_ == kUpdateStatusQueue) {  // full: the oldest goes
        update_head_ = (update_head_ + 1) % kUpdateStatusQueue;
        --update_count_;
        ++update_dropped_;
      }
      update_queue_[(update_head_ + update_count_) % kUpdateStatusQueue] = st;
      ++update_count_;
      return;
    }
    default:
      return;
  }
}

std::string HostSession::handshakeError() const {
  switch (handshake_) {
    case HandshakeResult::kOk: return {};
    case HandshakeResult::kPending: return "handshake still pending";
    case HandshakeResult::kTimeout: return "device did not answer the handshake (wrong port, or not Phalanx firmware?)";
    case HandshakeResult::kVersionMismatch:
      return "protocol version mismatch: host speaks v" + std::to_string(kProtocolVersion) + ", device speaks v" +
             std::to_string(ack_.protocol_version) + " (update the firmware or the host so both match)";
    case HandshakeResult::kDeviceMismatch: {
      const DeviceLayout* l = layoutFor(ack_.device_type);
      return std::string("device type mismatch: the connected device is '") + (l ? l->name : "unknown") +
             "' (" + std::to_string(ack_.setpoint_count) + " setpoints, " + std::to_string(ack_.sample_count) +
             " samples), not the one requested";
    }
  }
  return "unknown";
}

const char* faultName(uint16_t bit) {
  switch (bit) {
    case fault::kCommandTimeout: return "command-timeout";
    case fault::kInvalidCommand: return "invalid-command";
    case fault::kEstop: return "estop";
    case fault::kSensorRange: return "sensor-range";
    case fault::kSensorStuck: return "sensor-stuck";
    case fault::kForceLimit: return "force-limit";
    case fault::kJointLimit: return "joint-limit";
    case fault::kCurrentLimit: return "current-limit";
    case fault::kSensorSaturated: return "sensor-saturated";
    case fault::kMotorAngle: return "motor-angle";
    case fault::kTickOverrun: return "tick-overrun";
    case fault::kInternal: return "internal";
    default: return "unknown";
  }
}

std::string faultList(uint16_t bits) {
  if (bits == 0) return "none";
  std::string out;
  for (int i = 0; i < 16; ++i) {
    const auto bit = static_cast<uint16_t>(1u << i);
    if ((bits & bit) == 0) continue;
    if (!out.empty()) out += '|';
    out += faultName(bit);
  }
  return out;
}

const char* modeName(Mode mode) {
  switch (mode) {
    case Mode::kSafe: return "safe";
    case Mode::kTransparent: return "transparent";
    case Mode::kSetpoint: return "setpoint";
    case Mode::kLock: return "lock";
  }
  return "unknown";
}

}  // namespace phalanx::host
