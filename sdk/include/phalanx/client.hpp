#pragma once
/// libphalanx C++ API (docs/sdk.md): connect to phalanxd's client channel, read each cycle's state, command the
/// device - polling (DHD style) or a servo callback run at the device rate (OpenHaptics style). Every command is
/// checked by the daemon (NaN/Inf refused, device then patient limits); a client that misses its deadline is
/// forced off and told why (State::force_off_cause).
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

#include "phalanx/phalanx.h"

namespace phalanx {

constexpr int kVersionMajor = PHALANX_VERSION_MAJOR;
constexpr int kVersionMinor = PHALANX_VERSION_MINOR;

enum class Fallback : int { kSafe = PHALANX_FALLBACK_SAFE, kTransparent = PHALANX_FALLBACK_TRANSPARENT };
enum class Mode : int { kSafe = PHALANX_MODE_SAFE, kTransparent = PHALANX_MODE_TRANSPARENT, kSetpoint = PHALANX_MODE_SETPOINT };

/// Thrown at connect (the only place the C++ API throws), with the daemon's reason.
class Error : public std::runtime_error {
 public:
  Error(int code, const std::string& what) : std::runtime_error(what), code_(code) {}
  int code() const { return code_; }  ///< PHALANX_E*

 private:
  int code_;
};

using DeviceInfo = phalanx_device_info;
using State = phalanx_state;

enum class CommandKind : int {
  kRaw = PHALANX_COMMAND_RAW,
  kGloveFingertipForce = PHALANX_COMMAND_GLOVE_FINGERTIP_FORCE,
  kSeaFingerTorque = PHALANX_COMMAND_SEA_FINGER_TORQUE,
  kPenWrench = PHALANX_COMMAND_PEN_WRENCH,
};
using Spring = phalanx_spring;
using FallbackSpring = phalanx_fallback_spring;

/// One command: raw per-channel setpoints in the device's SI units (glove: pad force N), or a model-level
/// command (kind, model[]), with the compliant fallback the daemon renders in cycles this client misses.
struct Command {
  Mode mode = Mode::kSetpoint;
  std::array<float, PHALANX_MAX_SETPOINTS> setpoint{};
  CommandKind kind = CommandKind::kRaw;
  std::array<float, PHALANX_MAX_MODEL_VALUES> model{};
  FallbackSpring fallback{};

  /// sea_finger: finger joint torques MCP, PIP (N·m, + extends), converted through J_n by the daemon.
  void fingerTorques(double mcp_Nm, double pip_Nm);
  /// pantograph: wrench at the pen centre in the base frame.
  void penWrench(const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm = {});
  /// glove5: force (x, y) on each fingertip in its base frame, N; the glove exerts its pad-normal part.
  void fingertipForces(const std::array<std::array<double, 2>, PHALANX_GLOVE_FINGERS>& force_N);
};

struct ConnectOptions {
  std::string socket_path;
  unsigned deadline_ms = 20;             ///< a command older than this forces the device to `fallback`
  Fallback fallback = Fallback::kSafe;
};

/// Fingertip pose (x_m, y_m, phi_rad) of a glove finger (0 thumb … 4 little) in its base frame {O}, from the
/// state's mechanism angles α and the default glove geometry (docs/glove-model.md, eq 3–5).
std::array<double, 3> gloveFingertip(const State& s, int finger);
/// The glove's measured pad force of a finger, N (telemetry sample 15 + finger).
inline double glovePadForce(const State& s, int finger) { return s.sample[15 + finger]; }

class Client {
 public:
  /// Connect and negotiate; throws Error naming what was refused.
  explicit Client(const ConnectOptions& options);
  ~Client();  ///< releases control cleanly
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const DeviceInfo& device() const;
  /// Polling: the newest complete state; false before the daemon published one.
  bool getState(State& out);
  /// The next state newer than the last one read, waiting up to timeout_ms; false on timeout.
  bool waitState(State& out, int timeout_ms);
  /// Command the device (raw setpoints; count must equal device().setpoint_count). false: bad count.
  bool setCommand(const Command& cmd);
  /// glove5: fingertip pad forces in N, thumb..little (positive resists flexion).
  bool setFingertipForces(const std::array<double, PHALANX_GLOVE_FINGERS>& force_N);
  /// Any command (raw or model-level, with its fallback).
  bool set(const Command& cmd);
  /// sea_finger / pantograph shorthands (fallback: none = the daemon repeats this command when a cycle is missed).
  bool setFingerTorques(double mcp_Nm, double pip_Nm, const FallbackSpring* fallback = nullptr);
  bool setPenWrench(const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm,
                    const FallbackSpring* fallback = nullptr);
  /// The rate at which the daemon received this client's commands, over the last second (Hz).
  double achievedRateHz();
  /// Servo loop: cb runs once per daemon cycle with the newest state and fills the command; return false to
  /// stop. Returns PHALANX_OK when cb stopped, PHALANX_EFORCED_OFF when the daemon forced this client off
  /// (last.force_off_cause says why).
  int runServo(const std::function<bool(const State&, Command&)>& cb, State* last = nullptr);
  /// Hand control back cleanly; the daemon's built-in controller resumes. Called by the destructor.
  void release();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phalanx
