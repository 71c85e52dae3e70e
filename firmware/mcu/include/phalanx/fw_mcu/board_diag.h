#pragma once
/// Board diagnostics through the protocol's parameters without touching the firmware core: the board wraps the
/// device app in DiagApp, which answers parameter IDs 0x0080–0x00FF from the board and forwards everything else
/// (the core itself owns 0x0001–0x007F, device apps 0x0100 and up). Read with ParamGet like any parameter.
#include <cstdint>

#include "phalanx/fw/app.h"

namespace phalanx::fw_mcu {

/// Board diagnostic parameter IDs (read-only unless noted). Tick durations are in the board's measurement unit:
/// instructions on the QEMU board under -icount, CPU cycles on silicon (kTickUnitNs says which).
namespace diag_param {
constexpr uint16_t kFirst = 0x0080;
constexpr uint16_t kLast = 0x00FF;
constexpr uint16_t kTickCount = 0x0080;       ///< ticks measured since boot or the last reset
constexpr uint16_t kTickWorst = 0x0081;       ///< longest core.tick() (sense + control + telemetry)
constexpr uint16_t kTickMedian = 0x0082;
constexpr uint16_t kTickP99 = 0x0083;
constexpr uint16_t kTickWorstTimer = 0x0084;  ///< longest tick in raw timer counts (SysTick)
constexpr uint16_t kTickUnitNs = 0x0085;      ///< ns per measurement unit (QEMU -icount: 2^shift, else one SysTick count; 170 MHz: 5.88)
constexpr uint16_t kOverruns = 0x0086;        ///< ticks that ended after the next period had started
constexpr uint16_t kPlantMs = 0x0087;         ///< simulated time the plant has reached, ms (QEMU board only)
constexpr uint16_t kRxOverflows = 0x0088;     ///< bytes lost because the receive ring was full
constexpr uint16_t kLinkKind = 0x0089;        ///< 0 UART, 1 semihosting console (QEMU board)
constexpr uint16_t kResetStats = 0x008F;      ///< write any value: restart the statistics
}  // namespace diag_param

/// What the board exposes; implemented by each board's main.
class DiagSource {
 public:
  virtual ~DiagSource() = default;
  /// True and value set if id is one of the board's parameters.
  virtual bool diagGet(uint16_t id, float& value) const = 0;
  /// True if id is settable and was set.
  virtual bool diagSet(uint16_t id, float value) = 0;
};

/// The device app as the core sees it on an MCU board: the real app plus the board's diagnostic parameters.
class DiagApp final : public fw::DeviceApp {
 public:
  DiagApp(fw::DeviceApp& app, DiagSource& diag) : app_(app), diag_(diag) {}
  static constexpr bool isDiagParam(uint16_t id) { return id >= diag_param::kFirst && id <= diag_param::kLast; }

  const protocol::DeviceLayout& layout() const override { return app_.layout(); }
  void init(hal::Board& board) override { app_.init(board); }
  uint16_t sense(float dt_s) override { return app_.sense(dt_s); }
  uint16_t control(const protocol::Command& cmd, float dt_s) override { return app_.control(cmd, dt_s); }
  void safe() override { app_.safe(); }
  void fillSamples(int16_t* samples) const override { app_.fillSamples(samples); }
  protocol::ParamStatus getParam(uint16_t id, float& value) const override {
    if (!isDiagParam(id)) return app_.getParam(id, value);
    return diag_.diagGet(id, value) ? protocol::ParamStatus::kOk : protocol::ParamStatus::kUnknownParam;
  }
  protocol::ParamStatus setParam(uint16_t id, float value) override {
    if (!isDiagParam(id)) return app_.setParam(id, value);
    float unused = 0.0f;
    if (diag_.diagSet(id, value)) return protocol::ParamStatus::kOk;
    return diag_.diagGet(id, unused) ? protocol::ParamStatus::kReadOnly : protocol::ParamStatus::kUnknownParam;
  }
  /// The app's persisted settings (the board diagnostics are never kept): without this the settings store would
  /// see no layout behind the wrapper and keep nothing.
  fw::SettingsHistory settingsHistory() const override { return app_.settingsHistory(); }

 private:
  fw::DeviceApp& app_;
  DiagSource& diag_;
};

}  // namespace phalanx::fw_mcu
