// The client channel's loop side: O(1) per cycle, no allocation, no lock, one non-blocking futex wake.
#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <cmath>

#include "phalanx/host/client/client_port.h"
#include "phalanx/host/client/device_model.h"
#include "phalanx/host/modbus/server.h"
#include "phalanx/linux/realtime.h"

namespace phalanx::host::client {

using client_wire::Control;
using client_wire::ForceOffCause;

static_assert(client_wire::kMaxSamples == protocol::kMaxSamples, "wire and protocol sample counts");
static_assert(client_wire::kMaxSetpoints == protocol::kMaxSetpoints, "wire and protocol setpoint counts");

namespace {

constexpr uint16_t kNominalGainPermille = 1000;

}  // namespace

ClientPort::ClientPort(Server& server, const protocol::DeviceLayout& layout, uint32_t rate_hz, modbus::LoopPort* modbus,
                       const ModelGeometry& geometry)
    : server_(server), layout_(layout), modbus_(modbus), period_ns_(1000000000ull / rate_hz),
      model_(std::make_unique<DeviceModelStage>(layout, geometry)) {}

ClientPort::~ClientPort() = default;

void ClientPort::observeOnce(const TelemetryFrame& tel) {
  if (observed_this_cycle_) return;
  observed_this_cycle_ = true;
  model_->observe(tel);  // the device-model stage: the state a client reads, the pose a model command needs
}

bool ClientPort::overrideCommand(const TelemetryFrame& tel, protocol::Command& cmd, uint64_t now_ns) {
  const bool handled = overrideCommandAt(tel, cmd, now_ns);
  previous_cycle_ns_ = now_ns;
  return handled;
}

bool ClientPort::overrideCommandAt(const TelemetryFrame& tel, protocol::Command& cmd, uint64_t now_ns) {
  offered_this_cycle_ = true;
  commanded_this_cycle_ = false;
  invalid_this_cycle_ = false;
  rendered_ = client_wire::Rendered::kNothing;
  model_scale_ = 1.0f;
  followAttachment();
  if (phase_ != Phase::kIdle) observeOnce(tel);
  if (phase_ == Phase::kIdle) return false;
  if (phase_ == Phase::kForcedOff) {
    fallbackCommand(cmd);
    return true;
  }
  const bool fresh = readFreshCommand(now_ns);
  if (phase_ == Phase::kConnected) {
    if (!fresh) return false;  // no command yet: the built-in controller's stands
    phase_ = Phase::kHolding;
    holdControl(true);
  }
  if (now_ns - last_fresh_ns_ > deadline_ns_) {
    forceOff(ForceOffCause::kClientTimeout, now_ns);
    fallbackCommand(cmd);
    return true;
  }
  if (!commandIsValid()) {
    // Refused, counted, and this cycle renders the fallback; the client's next valid command is used again.
    ++refused_invalid_;
    ++state_.refused_invalid;
    invalid_this_cycle_ = true;
    fallbackCommand(cmd);
    return true;
  }
  if (!fresh) countMissed(now_ns);
  if (!fresh && command_.fallback.kind == client_wire::FallbackKind::kSpring) {
    springFallback(cmd);  // a missed cycle: the client's spring-damper at this cycle's state, not a stale force
  } else {
    clientCommand(cmd);
    rendered_ = fresh ? client_wire::Rendered::kCommand : client_wire::Rendered::kRepeat;
  }
  commanded_this_cycle_ = true;
  ++cycles_commanded_;
  return true;
}

void ClientPort::countMissed(uint64_t now_ns) {
  ++cycles_without_fresh_;
  const uint64_t window = now_ns > woken_ns_ ? now_ns - woken_ns_ : 0;  // the client's time to answer the last state
  const uint64_t gap = now_ns - previous_cycle_ns_;
  if (2 * window < period_ns_ || 2 * gap > 3 * period_ns_) ++missed_off_schedule_;
}

void ClientPort::followAttachment() {
  Attachment& a = server_.attachment();
  const uint32_t g = a.generation.load(std::memory_order_acquire);
  if (g != 0 && g != generation_) attach(g);
  if (phase_ == Phase::kIdle) return;
  if (a.released.load(std::memory_order_acquire) == generation_) {
    detach();  // a clean hand-back: the built-in controller commands again
  } else if (a.gone.load(std::memory_order_acquire) == generation_) {
    if (phase_ == Phase::kConnected) detach();               // never commanded: nothing to take off
    if (phase_ == Phase::kForcedOff) holdControl(false);     // latched fallback, but Modbus may take over
  }
}

void ClientPort::attach(uint32_t generation) {
  Attachment& a = server_.attachment();
  generation_ = generation;
  deadline_ns_ = static_cast<uint64_t>(a.deadline_ms.load(std::memory_order_relaxed)) * 1000000ull;
  fallback_ = static_cast<client_wire::Fallback>(a.fallback.load(std::memory_order_relaxed));
  source_ = static_cast<CommandSource>(a.source.load(std::memory_order_relaxed));
  phase_ = Phase::kConnected;
  control_ = Control::kNotYet;
  cause_ = ForceOffCause::kNone;
  last_command_seq_ = 0;
  state_ = client_wire::StatePayload{};
  state_.generation = generation;
  rate_window_commands_ = 0;
  rate_window_start_ns_ = 0;
  holdControl(false);
  ++clients_seen_;
}

void ClientPort::detach() {
  phase_ = Phase::kIdle;
  holdControl(false);
}

void ClientPort::holdControl(bool hold) {
  if (modbus_ != nullptr) modbus_->lockOut(hold);
  server_.attachment().holding.store(hold ? generation_ : 0, std::memory_order_release);
}

bool ClientPort::readFreshCommand(uint64_t now_ns) {
  client_wire::CommandBlock& block = server_.channel().command;
  client_wire::CommandPayload p;
  if (!client_wire::seqlockTryRead(block.seq, block.payload, p)) return false;  // mid-write: next cycle
  if (p.generation != generation_ || p.command_seq == last_command_seq_) return false;
  command_ = p;
  last_command_seq_ = p.command_seq;
  last_fresh_ns_ = now_ns;
  ++rate_window_commands_;
  return true;
}

bool ClientPort::commandIsValid() const {
  if (command_.mode >= protocol::kModeCount) return false;
  if (!DeviceModelStage::finite(command_)) return false;
  const auto k = command_.kind;
  const auto t = layout_.type;
  if (k == client_wire::CommandKind::kGloveFingertipForce && t != protocol::DeviceType::kGlove5) return false;
  if (k == client_wire::CommandKind::kSeaFingerTorque && t != protocol::DeviceType::kSeaFinger) return false;
  if (k == client_wire::CommandKind::kPenWrench && t != protocol::DeviceType::kPantograph) return false;
  if (command_.kind != client_wire::CommandKind::kRaw) return true;
  for (uint8_t i = 0; i < layout_.setpoint_count; ++i) {
    if (!std::isfinite(command_.setpoint[i])) return false;
  }
  return true;
}

void ClientPort::clientCommand(protocol::Command& cmd) {
  cmd.mode = static_cast<protocol::Mode>(command_.mode);
  for (auto& g : cmd.gain_scale_permille) g = kNominalGainPermille;
  if (command_.kind == client_wire::CommandKind::kRaw) {
    for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) {
      cmd.setpoint[i] = i < layout_.setpoint_count ? command_.setpoint[i] : 0.0f;
    }
  } else {
    float scale = 1.0f;
    const ConvertStatus st = model_->convert(command_.kind, command_.model, cmd, scale);
    noteConversion(st, scale);
  }
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) intended_[i] = cmd.setpoint[i];
}

void ClientPort::springFallback(protocol::Command& cmd) {
  cmd.mode = protocol::Mode::kSetpoint;
  for (auto& g : cmd.gain_scale_permille) g = kNominalGainPermille;
  float scale = 1.0f;
  const ConvertStatus st = model_->renderSpring(command_.fallback, cmd, scale);
  noteConversion(st, scale);
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) intended_[i] = cmd.setpoint[i];
  rendered_ = client_wire::Rendered::kFallbackSpring;
  ++fallback_cycles_;
  ++state_.fallback_cycles;
}

void ClientPort::noteConversion(ConvertStatus st, float scale) {
  model_scale_ = scale;
  if (st == ConvertStatus::kSaturated) {
    ++model_saturated_;
    ++state_.model_saturated;
  }
}

void ClientPort::fallbackCommand(protocol::Command& cmd) const {
  cmd.mode = fallback_ == client_wire::Fallback::kTransparent ? protocol::Mode::kTransparent : protocol::Mode::kSafe;
  for (auto& s : cmd.setpoint) s = 0.0f;
  for (auto& g : cmd.gain_scale_permille) g = kNominalGainPermille;
}

void ClientPort::forceOff(ForceOffCause cause, uint64_t now_ns) {
  if (phase_ == Phase::kForcedOff) return;
  phase_ = Phase::kForcedOff;
  cause_ = cause;
  ++force_offs_;
  ++state_.force_offs;
  if (record_count_ < kMaxForceOffRecords) records_[record_count_++] = {cause, generation_, source_, now_ns, last_fresh_ns_};
}

void ClientPort::publish(const TelemetryFrame& tel, const protocol::Command& sent, uint64_t now_ns, uint64_t cycle) {
  // A client that connects while Modbus (or the stop) commands is attached here: it reads states and is refused.
  if (!offered_this_cycle_) followAttachment();
  if (!offered_this_cycle_ && phase_ != Phase::kIdle) {
    // The cycle's command came from an earlier source: Modbus (this client is refused) or the stop.
    const bool modbus = modbus_ != nullptr && modbus_->commanding();
    if (modbus && phase_ == Phase::kConnected) {
      ++refused_other_source_;
      ++state_.refused_other_source;
    }
    if (!modbus) {
      if (phase_ == Phase::kHolding) forceOff(ForceOffCause::kEstop, now_ns);
      control_ = Control::kStopped;
    } else {
      control_ = Control::kOtherSource;
    }
  } else if (phase_ != Phase::kIdle) {
    if (phase_ == Phase::kHolding && tel.fault_bits != 0) forceOff(ForceOffCause::kDeviceFault, now_ns);
    noteSentCommand(sent, now_ns);
    control_ = phase_ == Phase::kForcedOff ? Control::kForcedOff
               : commanded_this_cycle_     ? Control::kClient
                                           : Control::kNotYet;
  }
  offered_this_cycle_ = false;
  updateRate(now_ns);
  if (phase_ != Phase::kIdle) observeOnce(tel);
  observed_this_cycle_ = false;
  if (generation_ == 0) return;
  model_->fill(state_);
  state_.rendered = static_cast<uint8_t>(commanded_this_cycle_ ? rendered_ : client_wire::Rendered::kNothing);
  state_.model_scale = model_scale_;
  state_.cycle = cycle;
  state_.daemon_time_ns = now_ns;
  state_.telemetry_rx_ns = tel.host_rx_ns;
  state_.device_time_us = tel.device_time_us;
  state_.telemetry_seq = tel.seq;
  state_.device_mode = static_cast<uint8_t>(tel.mode);
  state_.state_flags = tel.state_flags;
  state_.fault_bits = tel.fault_bits;
  state_.control = phase_ == Phase::kIdle ? Control::kNotYet : control_;
  state_.force_off_cause = invalid_this_cycle_ ? ForceOffCause::kInvalidCommand : cause_;
  state_.command_seq_used = commanded_this_cycle_ ? command_.command_seq : 0;
  for (size_t i = 0; i < protocol::kMaxSamples; ++i) state_.sample[i] = tel.value[i];
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) state_.setpoint_sent[i] = sent.setpoint[i];
  writeState();
}

void ClientPort::noteSentCommand(const protocol::Command& sent, uint64_t now_ns) {
  if (!commanded_this_cycle_) return;
  ++state_.commands_used;
  if (sent.mode == protocol::Mode::kSafe && command_.mode != static_cast<uint8_t>(protocol::Mode::kSafe)) {
    forceOff(ForceOffCause::kLimit, now_ns);  // the limits stage replaced the command by the safe command
    return;
  }
  for (uint8_t i = 0; i < layout_.setpoint_count; ++i) {
    if (sent.setpoint[i] != intended_[i]) {
      ++limited_;
      ++state_.limited;
      return;
    }
  }
}

void ClientPort::updateRate(uint64_t now_ns) {
  if (rate_window_start_ns_ == 0) rate_window_start_ns_ = now_ns;
  const uint64_t span_ns = now_ns - rate_window_start_ns_;
  if (span_ns < 1000000000ull) return;
  state_.achieved_rate_hz = static_cast<float>(static_cast<double>(rate_window_commands_) * 1e9 /
                                               static_cast<double>(span_ns));
  rate_window_commands_ = 0;
  rate_window_start_ns_ = now_ns;
}

void ClientPort::writeState() {
  client_wire::StateBlock& block = server_.channel().state;
  client_wire::seqlockWrite(block.seq, block.payload, state_);
  // Non-blocking: wakes a client waiting for this cycle (libphalanx's servo thread), returns at once otherwise.
  syscall(SYS_futex, reinterpret_cast<uint32_t*>(&block.seq), FUTEX_WAKE, INT_MAX, nullptr, nullptr, 0);
  woken_ns_ = linux_hal::monotonicNs();
}

void ClientPort::finish(ForceOffCause cause) {
  if (phase_ == Phase::kHolding || phase_ == Phase::kConnected) {
    if (phase_ == Phase::kHolding) forceOff(cause, last_fresh_ns_);
    phase_ = Phase::kForcedOff;
    cause_ = cause;
  }
  holdControl(false);
  if (generation_ == 0) return;
  state_.control = Control::kForcedOff;
  state_.force_off_cause = cause;
  writeState();
}

nlohmann::json ClientPort::summaryJson(uint64_t start_ns) const {
  const ServerCounters& c = server_.counters();
  const auto at_s = [start_ns](uint64_t ns) { return ns >= start_ns ? static_cast<double>(ns - start_ns) * 1e-9 : 0.0; };
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < record_count_; ++i) {
    const ForceOffRecord& r = records_[i];
    list.push_back({{"cause", client_wire::forceOffCauseName(r.cause)}, {"client", r.generation},
                    {"source", commandSourceName(r.source)}, {"at_s", at_s(r.at_ns)},
                    {"last_command_at_s", at_s(r.last_command_ns)}});
  }
  return {{"socket", server_.path()},
          {"connections", c.connections.load()},
          {"refused_credentials", c.refused_credentials.load()},
          {"refused_busy", c.refused_busy.load()},
          {"refused_request", c.refused_request.load()},
          {"releases", c.releases.load()},
          {"disconnects_without_release", c.disconnects_without_release.load()},
          {"dds_attachments", c.in_process_attachments.load()},
          {"cycles_commanded", cycles_commanded_},
          {"refused_invalid", refused_invalid_},
          {"refused_other_source", refused_other_source_},
          {"modbus_refused_while_client_held", modbus_ != nullptr ? modbus_->refusedCycles() : 0},
          {"limited", limited_},
          {"model_saturated", model_saturated_},
          {"fallback_cycles", fallback_cycles_},
          {"cycles_without_fresh_command", cycles_without_fresh_},
          {"missed_on_schedule", cycles_without_fresh_ - missed_off_schedule_},
          {"missed_off_schedule", missed_off_schedule_},
          {"force_offs", force_offs_},
          {"force_off_records", list}};
}

}  // namespace phalanx::host::client
