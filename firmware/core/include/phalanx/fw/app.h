#pragma once
/// The interface between the device-independent firmware core and one device's app (glove5, sea_finger, …).
/// The core owns the protocol, the watchdog and the fault latch; the app owns sensing and control.
#include <cstddef>
#include <cstdint>

#include "phalanx/hal/hal.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::fw {

/// An id renamed between two versions of an app's settings layout.
struct SettingsRename {
  uint16_t from_id;  ///< the id in the previous version
  uint16_t to_id;    ///< the id in this version
};

/// One version of the device parameters an app keeps in flash (firmware/core settings_store.h). A new firmware
/// that persists other ids, or renames one, adds a version; the store migrates records of older versions.
struct SettingsLayout {
  uint16_t version;                ///< 1, 2, ... (the index in the history + 1)
  const uint16_t* ids;             ///< persisted ids, in the order they are applied at load (a mode before its gains)
  uint8_t id_count;                ///< ≤ kMaxSettings (settings_store.h)
  const SettingsRename* renames;   ///< ids renamed from version − 1 to this one (ids absent there get the defaults)
  uint8_t rename_count;
};

/// Every settings layout an app's firmware has written, oldest first; the last one is the current one.
struct SettingsHistory {
  const SettingsLayout* layouts = nullptr;
  uint8_t count = 0;
};

template <size_t N>
constexpr SettingsHistory settingsHistoryOf(const SettingsLayout (&layouts)[N]) {
  return {layouts, static_cast<uint8_t>(N)};
}

class DeviceApp {
 public:
  virtual ~DeviceApp() = default;
  virtual const protocol::DeviceLayout& layout() const = 0;
  /// Called once before the first tick; may not allocate after this returns.
  virtual void init(hal::Board& board) = 0;
  /// Read and convert every sensor; returns the fault bits of implausible readings found this tick.
  virtual uint16_t sense(float dt_s) = 0;
  /// Run the control loops for a validated command and write the outputs; returns fault bits found
  /// (limits exceeded). Only called while no fault is latched and the mode is not kSafe.
  virtual uint16_t control(const protocol::Command& cmd, float dt_s) = 0;
  /// Outputs to their safe state and controller state reset. The core has already disabled the PWM.
  virtual void safe() = 0;
  /// Fill the telemetry samples (layout().sample_count of them) from the last sense().
  virtual void fillSamples(int16_t* samples) const = 0;
  /// Device parameters (IDs ≥ 0x100). Default: none.
  virtual protocol::ParamStatus getParam(uint16_t /*id*/, float& /*value*/) const {
    return protocol::ParamStatus::kUnknownParam;
  }
  virtual protocol::ParamStatus setParam(uint16_t /*id*/, float /*value*/) {
    return protocol::ParamStatus::kUnknownParam;
  }
  /// The device parameters kept across power cycles and updates (settable ones only, never actions such as a
  /// tare). Default: none.
  virtual SettingsHistory settingsHistory() const { return {}; }
};

}  // namespace phalanx::fw
