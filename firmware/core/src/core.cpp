#include "phalanx/fw/core.h"

#include <cmath>

namespace phalanx::fw {

using protocol::Command;
using protocol::Event;
using protocol::EventCode;
using protocol::Mode;
using protocol::MsgId;
using protocol::RejectReason;

namespace {
constexpr uint16_t kMaxTimeoutMs = 1000;
constexpr uint16_t kMaxGainPermille = 2000;
constexpr uint8_t kNoChannel = 0xFF;
/// Newer in a wrapping 16-bit sequence: 1..32767 ahead. 0 (a duplicate) and 32768..65535 ahead (behind) are not.
constexpr bool seqNewer(uint16_t seq, uint16_t than) {
  const uint16_t ahead = static_cast<uint16_t>(seq - than);
  return ahead != 0 && ahead < 0x8000u;
}
/// Messages only a device sends: received by a device they are rejected (wrong direction).
bool deviceSends(MsgId id) {
  return id == MsgId::kHelloAck || id == MsgId::kTelemetry || id == MsgId::kEvent || id == MsgId::kParamValue ||
         id == MsgId::kUpdateStatus;
}
Event makeEvent(EventCode code, uint64_t now_us, float value) {
  Event ev;
  ev.time_us = static_cast<uint32_t>(now_us);
  ev.code = code;
  ev.channel = kNoChannel;
  ev.value = value;
  return ev;
}
}  // namespace

FirmwareCore::FirmwareCore(hal::Board& board, DeviceApp& app, const CoreConfig& config)
    : board_(board), app_(app), config_(config), dt_s_(1.0f / static_cast<float>(config.tick_rate_hz)) {
  board_.pwm->disableAll();
  if (board_.gpio != nullptr) board_.gpio->setDriveEnable(false);
  app_.init(board_);
  if (config_.settings != nullptr) config_.settings->load(app_);
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

void FirmwareCore::answer(const Event& event) {
  if (observer_ != nullptr) observer_->onEvent(event);
  send(event);
}

uint32_t FirmwareCore::rxErrors() const {
  const uint32_t transport = board_.packets != nullptr ? board_.packets->rxStats().total() : 0u;
  return decoder_.stats().total_rejected() + transport + counters_.commands_rejected + counters_.frames_invalid +
         counters_.frames_wrong_direction;
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
  emit(makeEvent(EventCode::kFaultLatched, now_us, static_cast<float>(faults_)));
}

void FirmwareCore::reject(RejectReason reason, uint8_t channel, float value, uint64_t now_us) {
  ++counters_.commands_rejected;
  // One Event per tick at most: a flood of bad or replayed commands must not crowd telemetry off the link.
  if (rejection_answered_) return;
  rejection_answered_ = true;
  Event ev = makeEvent(EventCode::kCommandRejected, now_us, value);
  ev.channel = channel;
  ev.detail = static_cast<uint8_t>(reason);
  answer(ev);
}

bool FirmwareCore::acceptSequence(uint16_t seq) {
  if (have_seq_ && !seqNewer(seq, newest_seq_)) return false;
  if (have_seq_) counters_.cmd_lost += static_cast<uint16_t>(seq - newest_seq_ - 1u);
  have_seq_ = true;
  newest_seq_ = seq;
  return true;
}

bool FirmwareCore::findFieldError(const Command& cmd, RejectReason& reason, uint8_t& channel, float& value) const {
  const protocol::DeviceLayout& layout = app_.layout();
  channel = kNoChannel;
  if (cmd.flags != 0) {
    reason = RejectReason::kBadFlags;
    value = cmd.flags;
    return true;
  }
  if (cmd.reserved != 0) {
    reason = RejectReason::kReservedNotZero;
    value = cmd.reserved;
    return true;
  }
  if (cmd.channel_count != layout.setpoint_count) {
    reason = RejectReason::kBadChannelCount;
    value = cmd.channel_count;
    return true;
  }
  if (cmd.timeout_ms == 0 || cmd.timeout_ms > kMaxTimeoutMs) {
    reason = RejectReason::kBadTimeout;
    value = cmd.timeout_ms;
    return true;
  }
  // Every channel: used ones within the device's limit, unused ones 0; every gain scale at most 2000 ‰.
  for (uint8_t i = 0; i < protocol::kMaxSetpoints; ++i) {
    const float limit = i < layout.setpoint_count ? layout.setpoint_limit : 0.0f;
    channel = i;
    if (!std::isfinite(cmd.setpoint[i])) {
      reason = RejectReason::kNonFinite;
      value = 0.0f;
      return true;
    }
    if (std::fabs(cmd.setpoint[i]) > limit) {
      reason = RejectReason::kOutOfRange;
      value = cmd.setpoint[i];
      return true;
    }
    if (cmd.gain_scale_permille[i] > kMaxGainPermille) {
      reason = RejectReason::kOutOfRange;
      value = cmd.gain_scale_permille[i];
      return true;
    }
  }
  return false;
}

void FirmwareCore::apply(const Command& cmd, uint64_t now_us) {
  ++counters_.commands_applied;
  applied_seq_ = cmd.seq;
  command_ = cmd;
  deadline_us_ = now_us + static_cast<uint64_t>(cmd.timeout_ms) * 1000u;
  have_command_ = true;
}

void FirmwareCore::handleCommandFrame(const protocol::Frame& frame, uint64_t now_us) {
  if (!session_open_) return reject(RejectReason::kNoSession, kNoChannel, 0.0f, now_us);
  // The sequence is judged first, on the raw seq: a command that is received counts as received (not lost)
  // even when its fields are then rejected, and a stale one is never judged further.
  const uint16_t seq = static_cast<uint16_t>(frame.payload[0] | (frame.payload[1] << 8));
  if (!acceptSequence(seq)) {
    ++counters_.cmd_stale;
    return reject(RejectReason::kStaleSequence, kNoChannel, static_cast<float>(seq), now_us);
  }
  Command cmd;
  if (!protocol::decodePayload(frame.payload, frame.len, cmd)) {
    return reject(RejectReason::kBadMode, kNoChannel, frame.payload[4], now_us);
  }
  RejectReason reason = RejectReason::kNoSession;
  uint8_t channel = kNoChannel;
  float value = 0.0f;
  if (findFieldError(cmd, reason, channel, value)) return reject(reason, channel, value, now_us);
  if (updating()) return reject(RejectReason::kUpdateInProgress, kNoChannel, 0.0f, now_us);
  if (saving()) return reject(RejectReason::kSaveInProgress, kNoChannel, 0.0f, now_us);
  apply(cmd, now_us);
}

void FirmwareCore::handleHello(const protocol::Frame& frame, uint64_t now_us) {
  protocol::Hello hello;
  if (!protocol::decodePayload(frame.payload, frame.len, hello) || hello.reserved != 0) {
    ++counters_.frames_invalid;
    return;
  }
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
  const bool ok = ack.status == protocol::HandshakeStatus::kOk;
  // The Hello of the session already open, repeated by a host that had not yet seen the answer (docs/protocol.md
  // "Session"): answered again, the session goes on.
  if (ok && session_open_ && hello.session_id == session_id_) {
    send(ack);
    return;
  }
  // A new session never inherits the previous one's command: outputs stay safe until its first command, whose
  // sequence number starts the session's sequence.
  if (ok) {
    if (outputs_active_) enterSafe();
    have_command_ = false;
    have_seq_ = false;
    session_open_ = true;
    session_id_ = hello.session_id;
  }
  send(ack);
  if (ok) emit(makeEvent(EventCode::kSessionOpened, now_us, static_cast<float>(faults_)));
}

uint16_t FirmwareCore::presentConditions() const {
  const bool estop = board_.gpio != nullptr && board_.gpio->estopPressed();
  return static_cast<uint16_t>(sensor_conditions_ | (estop ? protocol::fault::kEstop : 0u));
}

void FirmwareCore::handleClearFaults(const protocol::Frame& frame, uint64_t now_us) {
  protocol::ClearFaults clear;
  if (!protocol::decodePayload(frame.payload, frame.len, clear) || !session_open_ || clear.session_id != session_id_) {
    ++counters_.frames_invalid;
    return;
  }
  const uint16_t present = presentConditions();
  if (present != 0) {
    emit(makeEvent(EventCode::kClearRefused, now_us, static_cast<float>(present)));
    return;
  }
  if (faults_ == 0) return;  // nothing latched: nothing changes, the command in effect goes on
  const uint16_t cleared = faults_;
  faults_ = 0;
  have_command_ = false;  // resume only on a fresh command
  emit(makeEvent(EventCode::kFaultsCleared, now_us, static_cast<float>(cleared)));
}

bool FirmwareCore::coreParam(uint16_t id, float& value) const {
  switch (id) {
    case protocol::core_param::kTickRate: value = static_cast<float>(config_.tick_rate_hz); return true;
    case protocol::core_param::kBuildIdLow: value = static_cast<float>(config_.firmware_build_id & 0xFFFFu); return true;
    case protocol::core_param::kBuildIdHigh: value = static_cast<float>(config_.firmware_build_id >> 16); return true;
    case protocol::core_param::kDeviceVariant: value = static_cast<float>(config_.device_variant); return true;
    case protocol::core_param::kUpdateTrial:
      if (config_.update == nullptr) return false;
      value = config_.update->onTrial() ? 1.0f : 0.0f;
      return true;
    default: return settingsParam(id, value);
  }
}

bool FirmwareCore::settingsParam(uint16_t id, float& value) const {
  const SettingsStore* s = config_.settings;
  if (s == nullptr) return false;
  const SettingsReport& r = s->lastLoad();
  switch (id) {
    case protocol::core_param::kSettingsSave: value = static_cast<float>(s->newestSequence()); return true;
    case protocol::core_param::kSettingsLoad: value = static_cast<float>(r.result); return true;
    case protocol::core_param::kSettingsLayout: value = static_cast<float>(s->layoutVersion(app_)); return true;
    case protocol::core_param::kSettingsRefused: value = static_cast<float>(r.refused + r.dropped); return true;
    default: return false;
  }
}

bool FirmwareCore::saveSettings(float value, protocol::ParamValue& answer) {
  // Never while the outputs are driven (settings never move a motor), and one flash writer at a time.
  if (outputs_active_ || saving() || updating()) {
    answer.status = protocol::ParamStatus::kBusy;
    return true;
  }
  if (value != 1.0f) {
    answer.status = protocol::ParamStatus::kOutOfRange;
    return true;
  }
  SettingsSave r = config_.settings->beginSave(app_);
  // Its first step at once: on a flash that completes at once (firmware-sim's file, the tests' RAM) the save
  // ends here and is answered in line, before the next frame of this tick is handled.
  if (r == SettingsSave::kInProgress) r = config_.settings->stepSave();
  if (r != SettingsSave::kInProgress) {
    answer = saveAnswer(r);
    return true;
  }
  // Until the save ends commands are refused (kSaveInProgress): the one in effect ends here, as for an update.
  have_command_ = false;
  return false;
}

protocol::ParamValue FirmwareCore::saveAnswer(SettingsSave result) const {
  protocol::ParamValue a;
  a.param_id = protocol::core_param::kSettingsSave;
  const bool ok = result == SettingsSave::kSaved || result == SettingsSave::kUnchanged;
  a.status = ok                               ? protocol::ParamStatus::kOk
             : result == SettingsSave::kBusy ? protocol::ParamStatus::kBusy
                                              : protocol::ParamStatus::kFailed;
  a.value = ok ? static_cast<float>(config_.settings->newestSequence()) : 1.0f;
  return a;
}

void FirmwareCore::stepSettings() {
  if (!saving()) return;
  const SettingsSave r = config_.settings->stepSave();
  if (r != SettingsSave::kInProgress) send(saveAnswer(r));
}

void FirmwareCore::handleParamGet(const protocol::Frame& frame) {
  protocol::ParamGet get;
  if (!protocol::decodePayload(frame.payload, frame.len, get)) {
    ++counters_.frames_invalid;
    return;
  }
  protocol::ParamValue answer;
  answer.param_id = get.param_id;
  if (!coreParam(get.param_id, answer.value)) answer.status = app_.getParam(get.param_id, answer.value);
  send(answer);
}

void FirmwareCore::handleParamSet(const protocol::Frame& frame) {
  protocol::ParamSet set;
  if (!protocol::decodePayload(frame.payload, frame.len, set) || set.reserved != 0) {
    ++counters_.frames_invalid;
    return;
  }
  protocol::ParamValue answer;
  answer.param_id = set.param_id;
  answer.value = set.value;
  float core_value = 0.0f;
  if (set.param_id == protocol::core_param::kSettingsSave && config_.settings != nullptr) {
    if (!saveSettings(set.value, answer)) return;  // answered when the save ends
  } else if (set.param_id == protocol::core_param::kUpdateTrial && config_.update != nullptr) {
    // Confirm the running image: a boot record, written at once (a blocking flash write: outputs off, one flash
    // writer at a time, as for a save).
    if (set.value != 1.0f) {
      answer.status = protocol::ParamStatus::kOutOfRange;
    } else if (outputs_active_ || saving() || updating()) {
      answer.status = protocol::ParamStatus::kBusy;
    } else {
      answer.status = config_.update->confirm() ? protocol::ParamStatus::kOk : protocol::ParamStatus::kFailed;
      answer.value = config_.update->onTrial() ? 1.0f : 0.0f;
    }
  } else if (coreParam(set.param_id, core_value)) {
    answer.status = protocol::ParamStatus::kReadOnly;
  } else if (outputs_active_) {
    answer.status = protocol::ParamStatus::kBusy;
  } else if (!std::isfinite(set.value)) {
    answer.status = protocol::ParamStatus::kOutOfRange;
  } else {
    answer.status = app_.setParam(set.param_id, set.value);
  }
  send(answer);
}

void FirmwareCore::handleUpdate(const protocol::Frame& frame) {
  const auto id = static_cast<MsgId>(frame.id);
  protocol::UpdateBegin begin;
  protocol::UpdateData data;
  protocol::UpdateCommit commit;
  const bool ok = id == MsgId::kUpdateBegin  ? protocol::decodePayload(frame.payload, frame.len, begin)
                  : id == MsgId::kUpdateData ? protocol::decodePayload(frame.payload, frame.len, data)
                                             : protocol::decodePayload(frame.payload, frame.len, commit);
  if (!ok) {
    ++counters_.frames_invalid;
    return;
  }
  protocol::UpdateStatus answer;
  answer.answers = id;
  if (config_.update == nullptr) {
    answer.result = protocol::UpdateResult::kNoUpdater;
  } else if (id == MsgId::kUpdateBegin) {
    // Only with the outputs off; from then until the reboot no command drives them (kUpdateInProgress). Not
    // during a settings save: one flash writer at a time.
    if (outputs_active_ || saving()) {
      answer.result = protocol::UpdateResult::kBusy;
    } else {
      answer = config_.update->begin(begin, session_open_ ? session_id_ : 0u);
      if (updating()) have_command_ = false;
    }
  } else if (id == MsgId::kUpdateData) {
    answer = config_.update->data(data);
  } else {
    answer = config_.update->commit(commit);
  }
  send(answer);
}

void FirmwareCore::handleFrame(const protocol::Frame& frame, uint64_t now_us) {
  const auto id = static_cast<MsgId>(frame.id);
  if (deviceSends(id)) {
    ++counters_.frames_wrong_direction;
    return;
  }
  switch (id) {
    case MsgId::kHello: return handleHello(frame, now_us);
    case MsgId::kCommand:
      if (frame.len != Command::kWireSize) {
        ++counters_.frames_invalid;
        return;
      }
      return handleCommandFrame(frame, now_us);
    case MsgId::kClearFaults: return handleClearFaults(frame, now_us);
    case MsgId::kParamGet: return handleParamGet(frame);
    case MsgId::kParamSet: return handleParamSet(frame);
    case MsgId::kUpdateBegin:
    case MsgId::kUpdateData:
    case MsgId::kUpdateCommit: return handleUpdate(frame);
    default: ++counters_.frames_invalid; return;  // an ID no transport should have delivered
  }
}

void FirmwareCore::receive(uint64_t now_us) {
  if (board_.packets != nullptr) {
    uint8_t payload[protocol::kMaxPayload];
    for (size_t i = 0; i < config_.max_rx_messages_per_tick && !resetting(); ++i) {
      protocol::Frame frame;
      if (!board_.packets->receive(frame.id, payload, frame.len)) break;
      frame.payload = payload;
      handleFrame(frame, now_us);
    }
    return;
  }
  uint8_t buf[64];
  size_t budget = config_.max_rx_bytes_per_tick;
  while (budget > 0 && !resetting()) {
    const size_t n = board_.link->read(buf, budget < sizeof buf ? budget : sizeof buf);
    if (n == 0) break;
    budget -= n;
    const uint8_t* p = buf;
    while (p < buf + n && !resetting()) {  // each feed() consumes at least one byte
      if (decoder_.feed(p, buf + n)) handleFrame(decoder_.frame(), now_us);
    }
  }
}

bool FirmwareCore::drivesOutputs(Mode mode) const {
  if (mode == Mode::kSafe) return false;
  return mode != Mode::kLock || app_.layout().passive_lock;
}

void FirmwareCore::sendTelemetry(uint64_t now_us) {
  if (!session_open_) return;
  protocol::Telemetry t;
  t.time_us = static_cast<uint32_t>(now_us);
  t.seq = telemetry_seq_++;
  t.cmd_seq_echo = applied_seq_;
  t.mode = outputs_active_ ? command_.mode : Mode::kSafe;
  t.fault_bits = faults_;
  t.state_flags = static_cast<uint8_t>((faults_ != 0 ? protocol::state::kFaultLatched : 0) |
                                       (session_open_ ? protocol::state::kSessionOpen : 0) |
                                       (outputs_active_ ? protocol::state::kOutputsActive : 0));
  if (board_.gpio != nullptr && board_.gpio->estopPressed()) t.state_flags |= protocol::state::kEstopPressed;
  t.cmd_lost = static_cast<uint8_t>(counters_.cmd_lost);
  t.rx_errors = static_cast<uint8_t>(rxErrors());
  app_.fillSamples(t.sample);
  send(t);
}

void FirmwareCore::tick() {
  const uint64_t now_us = board_.clock->nowUs();
  ++counters_.ticks;
  rejection_answered_ = false;
  receive(now_us);
  // A save under way (an MCU's flash: over tens of ticks) takes one step per tick.
  stepSettings();

  // Supervisor: the firmware never depends on the host for safety.
  if (have_command_ && now_us > deadline_us_) latch(protocol::fault::kCommandTimeout, now_us);
  if (board_.gpio != nullptr && board_.gpio->estopPressed()) latch(protocol::fault::kEstop, now_us);
  sensor_conditions_ = app_.sense(dt_s_);
  if (sensor_conditions_ != 0) latch(sensor_conditions_, now_us);

  const bool run = faults_ == 0 && have_command_ && !updating() && !saving() && drivesOutputs(command_.mode);
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
