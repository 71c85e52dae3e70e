#pragma once
/// Host-side controllers: turn the newest telemetry into the next full-state command, every cycle.
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/session.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host {

class Controller {
 public:
  virtual ~Controller() = default;
  virtual const char* name() const = 0;
  /// Fill cmd.mode and cmd.setpoint[0..n) from the newest telemetry. t_s: time since the session started.
  /// Must not allocate (it runs in the 1 kHz loop).
  virtual void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) = 0;
  /// Extra per-device numbers for the end-of-session summary.
  virtual void summarize(nlohmann::json& /*out*/) const {}
  /// The live terminal view's device lines (called at ~10 Hz, may allocate): one or more lines separated by '\n',
  /// each at most 78 columns, so the view fits an 80-column terminal (daemon.cpp adds its own status line).
  virtual std::string liveLine(const TelemetryFrame& tel) const;
  /// The legend printed once above the live view: what every column and symbol of liveLine means (≤ 78 columns
  /// a line).
  virtual std::string liveLegend() const;
  /// Device parameters to set once after the handshake, before the first command (e.g. the glove's strain-gauge
  /// tare with the hand relaxed), and how long the device needs after them.
  virtual std::vector<std::pair<uint16_t, float>> startupParams() const { return {}; }
  virtual double startupSettleS() const { return 0.0; }
  /// Device parameters whose value must equal `value` before the session may start (read with ParamGet after
  /// the handshake); a mismatch or a device that does not know the parameter refuses the session with `what`
  /// in the error. Used for the geometry fingerprint when the model comes from a geometry file
  /// (docs/design-tools.md §"Geometry files").
  struct RequiredParam {
    uint16_t id = 0;
    float value = 0.0f;
    std::string what;
  };
  virtual std::vector<RequiredParam> requiredParams() const { return {}; }
  /// Parameters read back once start-up has settled, and what their values mean: a warning for the operator, or
  /// "" when the value is as expected (e.g. the glove's tare refused for a pressed pad).
  virtual std::vector<uint16_t> startupReadback() const { return {}; }
  /// True when commands may carry a gain scale other than 1000 ‰ (the glove's contact gain), which the classic
  /// CAN mapping cannot carry (docs/protocol.md): the daemon then refuses a classic CAN link at start.
  virtual bool usesGainScale() const { return false; }
  virtual std::string startupWarning(uint16_t /*id*/, float /*value*/) const { return {}; }
};

/// Zero force/torque on every channel: the device follows the user.
class TransparentController : public Controller {
 public:
  const char* name() const override { return "transparent"; }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override;
};

}  // namespace phalanx::host
