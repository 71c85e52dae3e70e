#include "phalanx/fw/core.h"

#include <cmath>

namespace phalanx::fw {

using protocol::Command;
using protocol::Event;
using protocol::EventCode;
using protocol::Mode;
using protocol::RejectReason;

namespace {
constexpr uint16_t kMaxTimeoutMs = 1000;
constexpr uint16_t kMaxGainPermille = 2000;
constexpr uint8_t kNoChannel = 0xFF;
constexpr uint16_t kParamTickRate = 0x0001;
constexpr uint16_t kParamBuildId = 0x0002;
}  // namespace

FirmwareCore::FirmwareCore(hal::Board& board, DeviceApp& app, const CoreConfig& config)
    : board_(board), app_(app), config_(config), dt_s_(1.0f / static_cast<float>(config.tick_rate_hz)) {
  board_.pwm->disableAll();
  if (board_.gpio != nullptr) board_.gpio->setDriveEnable(false);
  app_.init(board_);
}

template <class Msg>
void FirmwareCore::send(const Msg& msg) {
  if (board_.packets != nullptr) {
    uint8_t payload[Msg::kWireSize];
    protocol::encodePayload(msg, payload);
    if (!board_.packets->send(static_cast<uint8_t>(Msg::kId), payload, Msg::kWireSize)) ++counters_.tx_dropped;
    return;
  }
  uint8_t frame[protocol::kMaxEncodedFrame];
  const size_t n = protocol::encodeFrame(msg, frame);
  if (board_.link->writeSpace() < n) {
    ++counters_.tx_dropped;
    return;
  }
  board_.link->write(frame, n);
}

void FirmwareCore::emit(const Event& event) {
  if (observer_ != nullptr) observer_->onEvent(event);
  if (session_open_) send(event);
}

void FirmwareCore::enterSafe() {
  // Power stage off first, then let the app reset its controllers and put its outputs in their safe state.
  board_.pwm->disableAll();
  if (board_.gpio != nullptr) board_.gpio->setDriveEnable(false);
  app_.safe();
  if (outputs_active_) ++counters_.safe_entries;
  outputs_active_ = false;
}

void FirmwareCore::latch(uint16_t bits, uint64_t now_us) {
  const uint16_t fresh = static_cast<uint16_t>(bits & ~faults_);
  if (fresh == 0) return;
  faults_ = static_cast<uint16_t>(faults_ | fresh);
  enterSafe();
  have_command_ = false;
  Event ev;
  ev.time_us = static_cast<uint32_t>(now_us);
  ev.code = EventCode::kFaultLatched;
  ev.channel = kNoChannel;
  ev.value = static_cast<float>(faults_);
  emit(ev);
}

void FirmwareCore::reject(RejectReason reason, uint8_t channel, float value, uint64_t now_us) {
  ++counters_.commands_rejected;
  Event ev;
  ev.time_us = static_cast<uint32_t>(now_us);
  ev.code = EventCode::kCommandRejected;
  ev.channel = channel;
  ev.detail = static_cast<uint8_t>(reason);
  ev.value = value;
  emit(ev);
}

void FirmwareCore::handleCommand(const Command& cmd, uint64_t now_us) {
  const protocol::DeviceLayout& layout = app_.layout();
  if (!session_open_) return reject(RejectReason::kNoSession, kNoChannel, 0.0f, now_us);
  if (cmd.flags != 0) return reject(RejectReason::kBadFlags, kNoChannel, cmd.flags, now_us);
  if (cmd.channel_count != layout.setpoint_count) {
    return reject(RejectReason::kBadChannelCount, kNoChannel, cmd.channel_count, now_us);
  }
  if (cmd.timeout_ms == 0 || cmd.timeout_ms > kMaxTimeoutMs) {
    return reject(RejectReason::kBadTimeout, kNoChannel, cmd.timeout_ms, now_us);
  }
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) {
    if (!std::isfinite(cmd.setpoint[i])) return reject(RejectReason::kNonFinite, i, 0.0f, now_us);
    if (std::fabs(cmd.setpoint[i]) > layout.setpoint_limit) {
      return reject(RejectReason::kOutOfRange, i, cmd.setpoint[i], now_us);
    }
    if (cmd.gain_scale_permille[i] > kMaxGainPermille) {
      return reject(RejectReason::kOutOfRange, i, cmd.gain_scale_permille[i], now_us);
    }
  }
  if (have_seq_) {
    const uint16_t gap = static_cast<uint16_t>(cmd.seq - last_seq_ - 1u);
    if (gap != 0 && gap < 0x8000u) counters_.cmd_lost += gap;
  }
  have_seq_ = true;
  last_seq_ = cmd.seq;
  ++counters_.commands_applied;
  command_ = cmd;
  deadline_us_ = now_us + static_cast<uint64_t>(cmd.timeout_ms) * 1000u;
  have_command_ = true;
}

void FirmwareCore::handleFrame(const protocol::Frame& frame, uint64_t now_us) {
  using protocol::MsgId;
  switch (static_cast<MsgId>(frame.id)) {
    case MsgId::kHello: {
      protocol::Hello hello;
      if (!protocol::decodePayload(frame.payload, frame.len, hello)) return;
      protocol::HelloAck ack;
      ack.device_type = app_.layout().type;
      ack.session_id = hello.session_id;
      ack.firmware_build_id = config_.firmware_build_id;
      ack.tick_rate_hz = config_.tick_rate_hz;
      ack.setpoint_count = app_.layout().setpoint_count;
      ack.sample_count = app_.layout().sample_count;
      if (hello.protocol_version != protocol::kProtocolVersion) {
        ack.status = protocol::HandshakeStatus::kVersionMismatch;
      } else if (hello.expected_device != protocol::DeviceType::kAny && hello.expected_device != ack.device_type) {
        ack.status = protocol::HandshakeStatus::kDeviceMismatch;
      }
      // A new session never inherits the previous one's command: outputs stay safe until its first command.
      if (ack.status == protocol::HandshakeStatus::kOk) {
        if (outputs_active_) enterSafe();
        have_command_ = false;
        have_seq_ = false;
        session_open_ = true;
        session_id_ = hello.session_id;
      }
      send(ack);
      if (ack.status == protocol::HandshakeStatus::kOk) {
        Event ev;
        ev.time_us = static_cast<uint32_t>(now_us);
        ev.code = EventCode::kSessionOpened;
        ev.channel = kNoChannel;
        ev.value = static_cast<float>(faults_);
        emit(ev);
      }
      return;
    }
    case MsgId::kCommand: {
      Command cmd;
      if (!protocol::decodePayload(frame.payload, frame.len, cmd)) {
        return reject(RejectReason::kBadMode, kNoChannel, frame.payload[4], now_us);
      }
      return handleCommand(cmd, now_us);
    }
    case MsgId::kClearFaults: {
      protocol::ClearFaults clear;
      if (!protocol::decodePayload(frame.payload, frame.len, clear) || !session_open_ ||
          clear.session_id != session_id_) {
        return;
      }
      Event ev;
      ev.time_us = static_cast<uint32_t>(now_us);
      ev.channel = kNoChannel;
      const bool estop = board_.gpio != nullptr && board_.gpio->estopPressed();
      if (estop) {
        ev.code = EventCode::kClearRefused;
        ev.value = static_cast<float>(protocol::fault::kEstop);
      } else {
        faults_ = 0;
        have_command_ = false;  // resume only on a fresh command
        ev.code = EventCode::kFaultsCleared;
      }
      emit(ev);
      return;
    }
    case MsgId::kParamGet:
    case MsgId::kParamSet: {
      protocol::ParamValue answer;
      if (static_cast<MsgId>(frame.id) == MsgId::kParamGet) {
        protocol::ParamGet get;
        if (!protocol::decodePayload(frame.payload, frame.len, get)) return;
        answer.param_id = get.param_id;
        if (get.param_id == kParamTickRate) {
          answer.value = static_cast<float>(config_.tick_rate_hz);
        } else if (get.param_id == kParamBuildId) {
          answer.value = static_cast<float>(config_.firmware_build_id);
        } else {
          answer.status = app_.getParam(get.param_id, answer.value);
        }
      } else {
        protocol::ParamSet set;
        if (!protocol::decodePayload(frame.payload, frame.len, set)) return;
        answer.param_id = set.param_id;
        answer.value = set.value;
        if (set.param_id == kParamTickRate || set.param_id == kParamBuildId) {
          answer.status = protocol::ParamStatus::kReadOnly;
        } else if (outputs_active_) {
          answer.status = protocol::ParamStatus::kBusy;
        } else if (!std::isfinite(set.value)) {
          answer.status = protocol::ParamStatus::kOutOfRange;
        } else {
          answer.status = app_.setParam(set.param_id, set.value);
        }
      }
      send(answer);
      return;
    }
    default:
      return;  // device → host messages are ignored if echoed back
  }
}

void FirmwareCore::receive(uint64_t now_us) {
  if (board_.packets != nullptr) {
    uint8_t payload[protocol::kMaxPayload];
    for (size_t i = 0; i < config_.max_rx_messages_per_tick; ++i) {
      protocol::Frame frame;
      if (!board_.packets->receive(frame.id, payload, frame.len)) break;
      frame.payload = payload;
      handleFrame(frame, now_us);
    }
    return;
  }
  uint8_t buf[64];
  size_t budget = config_.max_rx_bytes_per_tick;
  while (budget > 0) {
    const size_t n = board_.link->read(buf, budget < sizeof buf ? budget : sizeof buf);
    if (n == 0) break;
    budget -= n;
    for (size_t i = 0; i < n; ++i) {
      if (decoder_.push(buf[i])) handleFrame(decoder_.frame(), now_us);
    }
  }
}

void FirmwareCore::sendTelemetry(uint64_t now_us) {
  if (!session_open_) return;
  protocol::Telemetry t;
  t.time_us = static_cast<uint32_t>(now_us);
  t.seq = telemetry_seq_++;
  t.cmd_seq_echo = last_seq_;
  t.mode = outputs_active_ ? command_.mode : Mode::kSafe;
  t.fault_bits = faults_;
  t.state_flags = static_cast<uint8_t>((faults_ != 0 ? protocol::state::kFaultLatched : 0) |
                                       (session_open_ ? protocol::state::kSessionOpen : 0) |
                                       (outputs_active_ ? protocol::state::kOutputsActive : 0));
  if (board_.gpio != nullptr && board_.gpio->estopPressed()) t.state_flags |= protocol::state::kEstopPressed;
  t.cmd_lost = static_cast<uint8_t>(counters_.cmd_lost);
  const uint32_t transport_rejected = board_.packets != nullptr ? board_.packets->rxStats().total() : 0u;
  t.rx_errors = static_cast<uint8_t>(decoder_.stats().total_rejected() + transport_rejected + counters_.commands_rejected);
  app_.fillSamples(t.sample);
  send(t);
}

void FirmwareCore::tick() {
  const uint64_t now_us = board_.clock->nowUs();
  ++counters_.ticks;
  receive(now_us);

  // Supervisor: the firmware never depends on the host for safety.
  if (have_command_ && now_us > deadline_us_) latch(protocol::fault::kCommandTimeout, now_us);
  if (board_.gpio != nullptr && board_.gpio->estopPressed()) latch(protocol::fault::kEstop, now_us);
  const uint16_t sensor_faults = app_.sense(dt_s_);
  if (sensor_faults != 0) latch(sensor_faults, now_us);

  const bool run = faults_ == 0 && have_command_ && command_.mode != Mode::kSafe;
  if (run) {
    if (!outputs_active_ && board_.gpio != nullptr) board_.gpio->setDriveEnable(true);
    outputs_active_ = true;
    const uint16_t control_faults = app_.control(command_, dt_s_);
    if (control_faults != 0) latch(control_faults, now_us);
  } else if (outputs_active_) {
    enterSafe();
  }
  sendTelemetry(now_us);
}

}  // namespace phalanx::fw
