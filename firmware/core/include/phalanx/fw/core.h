#pragma once
/// The device-independent firmware core: protocol endpoint, command watchdog, fault latch and the tick.
/// One instance per board, statically allocated; tick() is called once per control period by the scheduler
/// (a hardware timer on the MCU, the simulated clock in firmware-sim and the lockstep rig).
#include <cstdint>

#include "phalanx/fw/app.h"
#include "phalanx/fw/firmware_update.h"
#include "phalanx/fw/settings_store.h"
#include "phalanx/hal/hal.h"
#include "phalanx/protocol/codec.h"

namespace phalanx::fw {

struct CoreConfig {
  uint16_t tick_rate_hz = 1000;
  uint32_t firmware_build_id = 0;
  /// Bytes read from the link per tick at most (bounds the tick's work; 4 full frames).
  uint16_t max_rx_bytes_per_tick = 4 * static_cast<uint16_t>(protocol::kMaxEncodedFrame);
  /// Messages taken from a packet link (CAN) per tick at most. Generous so that a backlog (host faster than the
  /// device for a while) drains in one tick and the newest command applies, not one queued long ago.
  uint16_t max_rx_messages_per_tick = 32;
  /// protocol::variant::* reported by core parameter core_param::kDeviceVariant (the sea_finger on its test rig).
  uint8_t device_variant = protocol::variant::kStandard;
  /// Persistent settings (docs/params.md): loaded into the app at construction, saved on core_param::kSettingsSave
  /// one step per tick (SettingsStore::stepSave), commands refused (kSaveInProgress) until the save ends.
  /// nullptr: the board keeps none (the settings core parameters then answer kUnknownParam).
  SettingsStore* settings = nullptr;
  /// Firmware update over the link (docs/firmware-update.md). nullptr: the board answers every update request
  /// with UpdateResult::kNoUpdater. The board polls update->rebootRequested() after each tick and resets.
  FirmwareUpdate* update = nullptr;
};

/// Observer for what the core does (logging in firmware-sim, assertions in tests). Optional.
class CoreObserver {
 public:
  virtual ~CoreObserver() = default;
  virtual void onEvent(const protocol::Event& event) = 0;
};

/// Counters kept by the core (the low bytes of cmd_lost and rxErrors() go into every telemetry frame).
struct CoreCounters {
  uint32_t ticks = 0;
  uint32_t commands_applied = 0;
  uint32_t commands_rejected = 0;       ///< every Command not applied, stale ones included (the first of a tick: an Event)
  uint32_t cmd_lost = 0;                ///< commands missing from the sequence: a jump from n to n+k adds k−1
  uint32_t cmd_stale = 0;               ///< commands not newer than the newest received (replays, reordering)
  uint32_t frames_invalid = 0;          ///< host → device frames whose fields break the message's rules
  uint32_t frames_wrong_direction = 0;  ///< device → host messages received (Telemetry, HelloAck, Event, ParamValue)
  uint32_t tx_dropped = 0;              ///< frames not sent because the link was full
  uint32_t safe_entries = 0;
};

class FirmwareCore {
 public:
  FirmwareCore(hal::Board& board, DeviceApp& app, const CoreConfig& config);
  void setObserver(CoreObserver* observer) { observer_ = observer; }

  /// One control period: receive, supervise, sense, control (or hold safe), send telemetry.
  void tick();

  uint16_t faultBits() const { return faults_; }
  bool outputsActive() const { return outputs_active_; }
  bool sessionOpen() const { return session_open_; }
  uint32_t sessionId() const { return session_id_; }
  /// Absolute time (µs) after which the current command expires; 0 when there is none.
  uint64_t commandDeadlineUs() const { return have_command_ ? deadline_us_ : 0; }
  const CoreCounters& counters() const { return counters_; }
  /// Frames rejected so far, of every kind (transport, framing, fields, stale, wrong direction, commands); the
  /// low byte is telemetry's rx_errors.
  uint32_t rxErrors() const;
  const protocol::DecodeStats& rxStats() const { return decoder_.stats(); }
  float tickPeriodS() const { return dt_s_; }

 private:
  void receive(uint64_t now_us);
  void handleFrame(const protocol::Frame& frame, uint64_t now_us);
  void handleHello(const protocol::Frame& frame, uint64_t now_us);
  void handleCommandFrame(const protocol::Frame& frame, uint64_t now_us);
  /// Sequence rule (docs/protocol.md "Command sequence"): true when seq is newer than the newest received in this
  /// session (then it becomes the newest and the commands skipped are counted lost).
  bool acceptSequence(uint16_t seq);
  /// True when a field of cmd breaks the Command rules; reason, channel and value then name the first one.
  bool findFieldError(const protocol::Command& cmd, protocol::RejectReason& reason, uint8_t& channel,
                      float& value) const;
  void apply(const protocol::Command& cmd, uint64_t now_us);
  void handleClearFaults(const protocol::Frame& frame, uint64_t now_us);
  void handleParamGet(const protocol::Frame& frame);
  void handleParamSet(const protocol::Frame& frame);
  /// UpdateBegin / UpdateData / UpdateCommit: one UpdateStatus each (an undecodable one is counted invalid).
  void handleUpdate(const protocol::Frame& frame);
  bool updating() const { return config_.update != nullptr && config_.update->inProgress(); }
  /// A committed update: the board resets after this tick, so nothing received after the commit is handled (the
  /// host's next Hello is for the new image).
  bool resetting() const { return config_.update != nullptr && config_.update->rebootRequested(); }
  bool coreParam(uint16_t id, float& value) const;
  bool settingsParam(uint16_t id, float& value) const;
  /// A ParamSet of core_param::kSettingsSave: true with `answer` filled when it is answered now; false when the
  /// save has begun and runs on over the next ticks (stepSettings answers when it ends).
  bool saveSettings(float value, protocol::ParamValue& answer);
  /// Once per tick: one step of the save under way, and its answer when it ends.
  void stepSettings();
  bool saving() const { return config_.settings != nullptr && config_.settings->saving(); }
  protocol::ParamValue saveAnswer(SettingsSave result) const;
  /// Fault conditions present now: the e-stop input, and the sensor faults the last sense() reported.
  uint16_t presentConditions() const;
  /// Whether mode drives the outputs on this device (kLock only where the mechanism locks passively).
  bool drivesOutputs(protocol::Mode mode) const;
  void reject(protocol::RejectReason reason, uint8_t channel, float value, uint64_t now_us);
  void latch(uint16_t bits, uint64_t now_us);
  void enterSafe();
  void sendTelemetry(uint64_t now_us);
  /// Events about the device's state: sent only inside a session (the observer always sees them).
  void emit(const protocol::Event& event);
  /// Answers to a frame the host sent (command rejected): sent with or without a session.
  void answer(const protocol::Event& event);
  template <class Msg>
  void send(const Msg& msg);

  hal::Board& board_;
  DeviceApp& app_;
  CoreConfig config_;
  float dt_s_;
  CoreObserver* observer_ = nullptr;
  protocol::StreamDecoder decoder_;

  bool session_open_ = false;
  uint32_t session_id_ = 0;
  bool have_command_ = false;
  protocol::Command command_{};
  uint64_t deadline_us_ = 0;
  bool have_seq_ = false;
  uint16_t newest_seq_ = 0;   ///< newest command seq received in this session (applied or rejected)
  uint16_t applied_seq_ = 0;  ///< seq of the last command applied: telemetry's cmd_seq_echo
  bool rejection_answered_ = false;  ///< a command-rejected Event went out this tick (at most one per tick)
  uint16_t sensor_conditions_ = 0;   ///< fault bits the last sense() reported
  uint16_t faults_ = 0;
  bool outputs_active_ = false;
  uint16_t telemetry_seq_ = 0;
  CoreCounters counters_;
};

}  // namespace phalanx::fw
