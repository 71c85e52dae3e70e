#pragma once
/// The host daemon's session runner, shared by `phalanxd` and `phalanx run`: open the device (spawning the
/// simulated firmware for sim:* devices), handshake, run the 1 kHz loop, record, and summarise.
#include <cstdint>
#include <memory>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/linux/can_link.h"
#include "phalanx/protocol/devices.h"
#include "phalanx/protocol/messages.h"
#include "phalanx/host/client/client_options.h"
#include "phalanx/host/dds/dds_options.h"
#include "phalanx/host/modbus/server_options.h"
#include "phalanx/host/api/dashboard_options.h"

namespace phalanx::host {

class Controller;
class PatientLimitStage;
struct TelemetryFrame;

/// Optional observer of a session, for the therapy layer (session records, the control API, patient limits):
/// phalanx::host::therapy implements it. Every call comes from the session's thread.
class SessionHooks {
 public:
  virtual ~SessionHooks() = default;
  /// After the handshake: the controller to run instead of the default one (nullptr + error: abort the
  /// session; nullptr + "": keep the default).
  virtual std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, std::string& error) = 0;
  /// Just before the first cycle; a non-empty return aborts the session with that error.
  virtual std::string onStart(const protocol::DeviceLayout& layout, const nlohmann::json& info) {
    (void)layout;
    (void)info;
    return {};
  }
  /// Every cycle, after the command was sent (real time: must not block or allocate).
  virtual void onCycle(uint64_t wake_ns, double t_s, const TelemetryFrame& tel, const protocol::Command& cmd) = 0;
  /// Each device event (fault latched, command rejected, …), from the session thread.
  virtual void onDeviceEvent(const protocol::Event& event) { (void)event; }
  /// The active patient's limits, applied by the session's limits stage after the device's to every command,
  /// whatever its source (nullptr: no patient). Called once, before the first cycle.
  virtual PatientLimitStage* patientLimits() { return nullptr; }
  /// Polled every cycle: true ends the session cleanly (safe command sent, summary written).
  virtual bool stopRequested() { return false; }
  /// Polled every cycle: true sends one ClearFaults to the device (the therapist's e-stop reset).
  virtual bool takeClearFaultsRequest() { return false; }
  /// After the device was left safe, with the end-of-session summary.
  virtual void onEnd(const nlohmann::json& summary) { (void)summary; }
};

/// Bench GPIO lines (docs/gpio.md). Empty: not used.
struct GpioOptions {
  std::string estop;   ///< e-stop input "CHIP:LINE[:active-low]": a press stops the daemon until an explicit reset
  std::string enable;  ///< drive-enable output "CHIP:LINE[:active-low]": active while running, dropped on a stop
  std::string sync;    ///< motion-capture sync pulse output "CHIP:LINE@HZ" (square wave, rising edge = frame)
  double estop_release_ms = 20.0;  ///< the e-stop must stay released this long before a reset is accepted
};

struct RunOptions {
  std::string device = "sim:glove5";  ///< sim:<glove5|sea_finger|pantograph>, serial:<path>[@baud], can:<if>[:node][@fd|@fd-compact|@classic] or usb:VID:PID[:serial]
  double seconds = 0.0;               ///< 0: until SIGINT/SIGTERM
  unsigned rate_hz = 1000;
  unsigned command_timeout_ms = 20;   ///< each command's own timeout: the device goes safe if the next is late
  /// No new telemetry for this long ends the session as a lost link (exit 6), on every kind of link.
  unsigned telemetry_timeout_ms = 500;
  bool realtime = true;               ///< try SCHED_FIFO + mlockall
  int rt_priority = 80;
  /// What starts a host cycle: "telemetry" (a frame's arrival, the timer as fallback: locked to the device) or
  /// "timer" (the period timer alone). docs/session-runner.md "The cycle's clock".
  std::string cycle = "telemetry";
  std::string record_csv;             ///< one row per cycle; empty: no recording
  std::string scenario = "grasp";     ///< simulated hand (sim:glove5): still|close-open|grasp|random
  std::string scene = "rigid-ball";   ///< glove virtual scene: none|rigid-ball|soft-ball|wall
  std::string mode = "render";        ///< glove: render|transparent; sea_finger: transparent, else finger torque
  std::string sea_subject;            ///< sea_finger: subject YAML from `phalanx sea-calibrate` (empty: Table 4 P̂)
  /// glove5: per-finger geometry files written by `phalanx design glove-optimize|glove-workspace --yaml`
  /// (finger name thumb|index|middle|ring|little → path); fingers not listed keep glove::defaultModel.
  std::map<std::string, std::string> glove_geometry;
  /// pantograph: pen geometry file written by `phalanx design pen-gii --yaml` (empty: pen::defaultGeometry).
  std::string pen_geometry;
  /// pantograph: stiffness of every wall of the box and its floor, N/cm (0: the scene's §VI gains); damping and
  /// braking keep the scene's. The stiffness sweep of tools/lock-bench.py sets it.
  double pen_wall_stiffness_N_per_cm = 0.0;
  /// pantograph: the box floor's height y in {B}, mm (the scene's -90 by default; -68 puts it 2 mm into the tip
  /// of a pen held at home, a steady contact for the stiffness sweep).
  double pen_floor_mm = -90.0;
  uint32_t seed = 1;
  bool live_view = false;             ///< per-finger terminal view at 10 Hz on stderr
  bool clear_faults = true;           ///< clear faults latched before this session (logged)
  std::string firmware_sim;           ///< path of firmware-sim (default: next to this executable)
  std::string sim_truth;              ///< sim: devices: firmware-sim writes the plant's ground truth here (--truth)
  /// sim: devices: more firmware-sim arguments (the bench runner's `--instrument ...`, docs/bench-runner.md). With
  /// `--instrument` the link also reads firmware-sim's "instrument: modbus ..." line: summary["link"]["instrument"].
  std::vector<std::string> sim_args;
  std::string sim_settings;           ///< sim: devices: firmware-sim's settings flash file (--settings; docs/params.md)
  unsigned sim_settings_layout = 0;   ///< sim: devices: the settings layout firmware-sim plays (--settings-layout; 0 newest)
  double handshake_timeout_s = 2.0;
  SessionHooks* hooks = nullptr;      ///< therapy layer (not owned); nullptr: none
  modbus::ServerOptions modbus;       ///< optional Modbus TCP server (docs/modbus.md); off by default
  client::ClientOptions client;       ///< local client channel for libphalanx (docs/sdk.md); off by default
  GpioOptions gpio;                   ///< e-stop, drive enable, sync pulse (docs/gpio.md); none by default
  api::DashboardOptions dashboard;    ///< live web dashboard (docs/dashboard.md; API mode only); off by default
  dds::DdsOptions dds;                ///< ROS 2-compatible topics over Cyclone DDS (docs/dds.md); off by default
};

/// Validate the GPIO options (line specs, distinct lines, ranges); empty string or the problem, naming the option.
std::string validateGpio(const GpioOptions& g);

/// Parse a CAN device spec "can:<interface>[:<node 1..63>][@fd|@fd-compact|@classic]" (defaults: node 1, fd).
/// Returns an empty string or what is wrong with it.
std::string parseCanDevice(const std::string& spec, linux_hal::CanLink::Options& out);

/// Validate options; returns an empty string or the first problem, naming the option.
std::string validate(const RunOptions& opt);

/// The built-in controller the options ask for (the session's, when no SessionHooks supplies one; also the
/// replay's, record/replay.h). null and error set when the options do not fit the device.
std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error);

/// Run one session. Returns the process exit code (0 ok); summary is filled in either case, with
/// summary["error"] set on failure.
int runSession(const RunOptions& opt, nlohmann::json& summary);

/// Install SIGINT/SIGTERM handlers that ask runSession to stop cleanly, and SIGUSR1: an explicit e-stop reset
/// (the same as the control API's `reset`).
void installStopSignals();

}  // namespace phalanx::host
