#pragma once
/// The device-independent firmware core: protocol endpoint, command watchdog, fault latch and the tick.
/// One instance per board, statically allocated; tick() is called once per control period by the scheduler
/// (a hardware timer on the MCU, the simulated clock in firmware-sim and the lockstep rig).
#include <cstdint>

#include "phalanx/fw/app.h"
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
};

/// Observer for what the core does (logging in firmware-sim, assertions in tests). Optional.
class CoreObserver {
 public:
  virtual ~CoreObserver() = default;
  virtual void onEvent(const protocol::Event& event) = 0;
};

/// Counters kept by the core (the low bytes of cmd_lost and rx_errors go into every telemetry frame).
struct CoreCounters {
  uint32_t ticks = 0;
  uint32_t commands_applied = 0;
  uint32_t commands_rejected = 0;
  uint32_t cmd_lost = 0;       ///< gaps in the command sequence
  uint32_t tx_dropped = 0;     ///< frames not sent because the link was full
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
  /// Absolute time (µs) after which the current command expires; 0 when there is none.
  uint64_t commandDeadlineUs() const { return have_command_ ? deadline_us_ : 0; }
  const CoreCounters& counters() const { return counters_; }
  const protocol::DecodeStats& rxStats() const { return decoder_.stats(); }
  float tickPeriodS() const { return dt_s_; }

 private:
  void receive(uint64_t now_us);
  void handleFrame(const protocol::Frame& frame, uint64_t now_us);
  void handleCommand(const protocol::Command& cmd, uint64_t now_us);
  void reject(protocol::RejectReason reason, uint8_t channel, float value, uint64_t now_us);
  void latch(uint16_t bits, uint64_t now_us);
  void enterSafe();
  void sendTelemetry(uint64_t now_us);
  void emit(const protocol::Event& event);
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
  uint16_t last_seq_ = 0;
  uint16_t faults_ = 0;
  bool outputs_active_ = false;
  uint16_t telemetry_seq_ = 0;
  CoreCounters counters_;
};

}  // namespace phalanx::fw
