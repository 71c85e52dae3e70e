#include "phalanx/host/daemon.h"

#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <vector>

#include "phalanx/host/client/client_port.h"
#include "phalanx/host/command_limits.h"
#include "phalanx/host/config.h"
#include "phalanx/host/controller.h"
#include "phalanx/host/dds/dds_bridge.h"
#include "phalanx/host/cycle_clock.h"
#include "phalanx/host/device_link.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/modbus/server.h"
#include "phalanx/host/program_name.h"
#include "phalanx/host/record/csv_recorder.h"
#include "phalanx/host/record/replay.h"
#include "phalanx/host/safety_io.h"
#include "phalanx/host/link_recovery.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/gpio.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/linux/usb_link.h"

namespace phalanx::host {

namespace {

volatile std::sig_atomic_t g_stop = 0;
void onStopSignal(int) { g_stop = 1; }
volatile std::sig_atomic_t g_reset = 0;
void onResetSignal(int) { g_reset = 1; }

/// One e-stop stop, measured: the kernel's edge timestamp, when the daemon read it, and when the daemon first saw
/// the device report its safe state (mode safe, outputs off) - in time and in device ticks (telemetry sequence).
struct StopRecord {
  StopCause cause = StopCause::kNone;
  uint64_t edge_ns = 0;   ///< kernel timestamp of the press edge (0: a lost line, no edge)
  uint64_t seen_ns = 0;   ///< the daemon read the e-stop (the edge reached the daemon)
  uint64_t sent_ns = 0;   ///< the safe command was written to the link (same cycle)
  uint16_t seq_at_seen = 0;
  bool device_was_active = false;
  bool safe_confirmed = false;
  uint64_t safe_rx_ns = 0;
  uint16_t ticks_to_safe = 0;
  uint16_t device_ticks_to_safe = 0;  ///< from the device having the safe command to its safe report
};

/// The bench GPIO lines of one session, opened before the handshake and released after the device is left safe.
struct GpioLines {
  linux_hal::GpioEstopInput estop;
  linux_hal::GpioOutput enable;
  linux_hal::GpioSyncPulse sync;
  bool have_estop = false, have_enable = false, have_sync = false;
  bool estop_open = false;
  std::string estop_error;
};

nlohmann::json histogramJson(const Histogram& h) {
  return {{"count", h.count()},          {"mean_us", h.mean()},         {"p50_us", h.percentile(0.5)},
          {"p99_us", h.percentile(0.99)}, {"p999_us", h.percentile(0.999)}, {"max_us", h.max()}};
}

void logEvent(void* hooks, const protocol::Event& e) {
  if (hooks != nullptr) static_cast<SessionHooks*>(hooks)->onDeviceEvent(e);
  switch (e.code) {
    case protocol::EventCode::kFaultLatched:
      std::fprintf(stderr, "%s: device fault latched: %s\n", programName(),
                   faultList(static_cast<uint16_t>(e.value)).c_str());
      break;
    case protocol::EventCode::kCommandRejected:
      std::fprintf(stderr, "%s: device rejected a command (reason %u, channel %u, value %g)\n", programName(), e.detail,
                   e.channel, static_cast<double>(e.value));
      break;
    case protocol::EventCode::kClearRefused:
      std::fprintf(stderr, "%s: device refused to clear faults: %s still present\n", programName(),
                   faultList(static_cast<uint16_t>(e.value)).c_str());
      break;
    default:
      break;
  }
}

}  // namespace

void installStopSignals() {
  struct sigaction sa {};
  sa.sa_handler = onStopSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  struct sigaction sr {};
  sr.sa_handler = onResetSignal;
  sigemptyset(&sr.sa_mask);
  sigaction(SIGUSR1, &sr, nullptr);
  signal(SIGPIPE, SIG_IGN);
}

std::string parseCanDevice(const std::string& spec, linux_hal::CanLink::Options& out) {
  if (spec.rfind("can:", 0) != 0) return "not a CAN device";
  std::string rest = spec.substr(4);
  out = linux_hal::CanLink::Options{};
  out.role = protocol::can::Role::kHost;
  if (const auto at = rest.find('@'); at != std::string::npos) {
    const std::string mode = rest.substr(at + 1);
    if (mode == "fd") {
      out.flavor = protocol::can::Flavor::kFd;
    } else if (mode == "fd-compact") {
      out.flavor = protocol::can::Flavor::kFdCompact;
    } else if (mode == "classic") {
      out.flavor = protocol::can::Flavor::kClassic;
    } else {
      return "device: '" + spec + "': CAN mode '" + mode + "' is not fd, fd-compact or classic";
    }
    rest = rest.substr(0, at);
  }
  if (const auto colon = rest.find(':'); colon != std::string::npos) {
    const std::string node = rest.substr(colon + 1);
    char* end = nullptr;
    const long n = std::strtol(node.c_str(), &end, 10);
    if (node.empty() || *end != 0 || n < protocol::can::kMinNode || n > protocol::can::kMaxNode) {
      return "device: '" + spec + "': CAN node id '" + node + "' is not in 1..63";
    }
    out.node = static_cast<uint8_t>(n);
    rest = rest.substr(0, colon);
  }
  if (rest.empty() || rest.size() >= 16) return "device: '" + spec + "': bad CAN interface name";
  out.ifname = rest;
  return {};
}

std::string validateGpio(const GpioOptions& g) {
  linux_hal::GpioLineSpec e, n, y;
  double hz = 0.0;
  if (!g.estop.empty()) {
    if (std::string err = linux_hal::parseGpioLine(g.estop, e); !err.empty()) return "gpio.estop: " + err;
  }
  if (!g.enable.empty()) {
    if (std::string err = linux_hal::parseGpioLine(g.enable, n); !err.empty()) return "gpio.enable: " + err;
  }
  if (!g.sync.empty()) {
    if (std::string err = linux_hal::parseGpioSync(g.sync, y, hz); !err.empty()) return "gpio.sync: " + err;
  }
  const auto same = [](const linux_hal::GpioLineSpec& a, const linux_hal::GpioLineSpec& b) {
    return a.chip == b.chip && a.offset == b.offset;
  };
  if (!g.estop.empty() && !g.enable.empty() && same(e, n)) return "gpio: the e-stop and enable lines are the same line";
  if (!g.estop.empty() && !g.sync.empty() && same(e, y)) return "gpio: the e-stop and sync lines are the same line";
  if (!g.enable.empty() && !g.sync.empty() && same(n, y)) return "gpio: the enable and sync lines are the same line";
  if (!std::isfinite(g.estop_release_ms) || g.estop_release_ms < 1.0 || g.estop_release_ms > 1000.0) {
    return "gpio.estop_release_ms: must be in [1, 1000]";
  }
  return {};
}

std::string validate(const RunOptions& opt) {
  if (opt.device.rfind("sim:", 0) != 0 && opt.device.rfind("serial:", 0) != 0 && opt.device.rfind("can:", 0) != 0 &&
      opt.device.rfind("usb:", 0) != 0) {
    return "device: '" + opt.device + "' is not a device (use sim:glove5, sim:sea_finger, sim:sea_rig, sim:pantograph, serial:/dev/ttyACM0[@baud], can:can0[:node][@fd|@fd-compact|@classic] or usb:VID:PID[:serial])";
  }
  if (opt.device.rfind("usb:", 0) == 0) {
    linux_hal::UsbLink::Options o;
    if (std::string err = linux_hal::parseUsbDevice(opt.device, o); !err.empty()) return err;
  }
  if (opt.device.rfind("serial:", 0) == 0) {
    if (opt.device.size() == 7 || opt.device[7] == '@') return "device: 'serial:' needs a path (serial:/dev/ttyACM0)";
    if (const auto at = opt.device.find('@'); at != std::string::npos) {
      char* end = nullptr;
      const unsigned long b = std::strtoul(opt.device.c_str() + at + 1, &end, 10);
      if (at + 1 == opt.device.size() || *end != 0 || b == 0 || b > 4000000) {
        return "device: bad baud rate in '" + opt.device + "' (a number of bit/s, e.g. @921600)";
      }
    }
  }
  if (opt.device.rfind("can:", 0) == 0) {
    linux_hal::CanLink::Options o;
    if (std::string err = parseCanDevice(opt.device, o); !err.empty()) return err;
  }
  if (opt.device.rfind("sim:", 0) == 0) {
    const std::string d = opt.device.substr(4);
    if (d != "glove5" && d != "sea_finger" && d != "sea_rig" && d != "pantograph") {
      return "device: unknown simulated device '" + d + "' (glove5, sea_finger, sea_rig, pantograph)";
    }
  }
  if (!std::isfinite(opt.seconds) || opt.seconds < 0 || opt.seconds > 86400) return "seconds: must be in [0, 86400]";
  if (opt.rate_hz < 100 || opt.rate_hz > 4000) return "rate_hz: must be in [100, 4000]";
  if (std::string err = checkSessionLength(opt.seconds, opt.rate_hz); !err.empty()) return "seconds: " + err;
  if (opt.command_timeout_ms < 2 || opt.command_timeout_ms > 1000) return "command_timeout_ms: must be in [2, 1000]";
  if (opt.command_timeout_ms * opt.rate_hz < 2000) {
    return "command_timeout_ms: must cover at least two host periods (" + std::to_string(2000 / opt.rate_hz + 1) + " ms at " +
           std::to_string(opt.rate_hz) + " Hz)";
  }
  if (opt.telemetry_timeout_ms < 10 || opt.telemetry_timeout_ms > 10000) {
    return "telemetry_timeout_ms: must be in [10, 10000]";
  }
  if (opt.rt_priority < 1 || opt.rt_priority > 99) return "realtime.priority: must be in [1, 99]";
  if (CycleMode m; !parseCycleMode(opt.cycle, m)) return "cycle: '" + opt.cycle + "' is not one of telemetry, timer";
  if (opt.scenario != "still" && opt.scenario != "close-open" && opt.scenario != "grasp" && opt.scenario != "random" &&
      opt.scenario != "spastic" && opt.scenario != "press") {
    return "scenario: '" + opt.scenario + "' is not one of still, close-open, grasp, random, spastic, press";
  }
  if (opt.scenario == "press" && opt.device.rfind("sim:", 0) == 0 && opt.device != "sim:pantograph") {
    return "scenario: 'press' is the pen's (sim:pantograph), not " + opt.device + "'s";
  }
  if (opt.scenario == "spastic" && opt.device.rfind("sim:", 0) == 0 && opt.device != "sim:sea_finger") {
    return "scenario: 'spastic' (a finger with a stretch reflex) is for sim:sea_finger only, not " + opt.device;
  }
  if (opt.scene != "none" && opt.scene != "rigid-ball" && opt.scene != "soft-ball" && opt.scene != "wall") {
    return "scene: '" + opt.scene + "' is not one of none, rigid-ball, soft-ball, wall";
  }
  if (opt.mode != "render" && opt.mode != "transparent") return "mode: '" + opt.mode + "' is not one of render, transparent";
  if (!opt.sim_truth.empty() && opt.device.rfind("sim:", 0) != 0) {
    return "--sim-truth: the plant's truth exists for sim: devices only, not '" + opt.device + "'";
  }
  if (!opt.sim_settings.empty() && opt.device.rfind("sim:", 0) != 0) {
    return "--sim-settings: for sim: devices only, not '" + opt.device + "'";
  }
  if (opt.sim_settings.empty() && opt.sim_settings_layout != 0) return "--sim-settings-layout needs --sim-settings";
  if (!opt.sim_args.empty() && opt.device.rfind("sim:", 0) != 0) {
    return "sim_args: firmware-sim arguments are for sim: devices only, not '" + opt.device + "'";
  }
  // Geometry files are read and validated here, so a bad file is refused before any device is opened.
  for (const auto& [finger, path] : opt.glove_geometry) {
    if (finger != "thumb" && finger != "index" && finger != "middle" && finger != "ring" && finger != "little") {
      return "glove.geometry: '" + finger + "' is not a finger (thumb, index, middle, ring, little)";
    }
    phalanx::glove::Model<double> m;
    if (std::string err = design::loadGloveGeometryYaml(path, m); !err.empty()) {
      return "glove.geometry." + finger + ": " + err;
    }
  }
  if (!opt.pen_geometry.empty()) {
    phalanx::pen::Geometry<double> g;
    if (std::string err = design::loadPenGeometryYaml(opt.pen_geometry, g); !err.empty()) return "pen.geometry: " + err;
  }
  if (!std::isfinite(opt.pen_wall_stiffness_N_per_cm) || opt.pen_wall_stiffness_N_per_cm < 0 ||
      opt.pen_wall_stiffness_N_per_cm > 1000) {
    return "pen.wall_stiffness_N_per_cm: must be in [0, 1000]";
  }
  if (!std::isfinite(opt.pen_floor_mm) || opt.pen_floor_mm < -120 || opt.pen_floor_mm > -40) {
    return "pen.floor_mm: must be in [-120, -40]";
  }
  if (std::string err = validateGpio(opt.gpio); !err.empty()) return err;
  if (std::string err = dds::validateDdsOptions(opt.dds, opt.rate_hz); !err.empty()) return err;
  return modbus::validateServerOptions(opt.modbus);
}

namespace {

/// One session, in the stages a reader follows top to bottom: open bench lines → open device → handshake →
/// configure → run cycles → shut down. A stage that fails returns the process exit code (README "Exit codes").
/// The cycle is the design's data flow: telemetry → device model → command source → limits → send.
class SessionRunner {
 public:
  SessionRunner(const RunOptions& opt, nlohmann::json& summary) : opt_(opt), summary_(summary) {}

  int run() {
    if (const std::string problem = validate(opt_); !problem.empty()) return fail(problem, 2);
    summary_["device"] = opt_.device;
    if (int rc = openBenchLines(); rc != 0) return rc;
    if (int rc = openDevice(); rc != 0) return rc;
    if (int rc = handshake(); rc != 0) return rc;
    if (int rc = configure(); rc != 0) return rc;
    runCycles();
    return shutDown();
  }

 private:
  int fail(const std::string& msg, int code) {
    summary_["error"] = msg;
    std::fprintf(stderr, "%s: error: %s\n", programName(), msg.c_str());
    return code;
  }
  double waitBoundS() const { return opt_.handshake_timeout_s; }
  /// Poll the link until done() or the handshake bound passes; done()'s last answer.
  template <class Done>
  bool pollUntil(Done done) {
    const uint64_t t0 = linux_hal::monotonicNs();
    while (!done()) {
      if (static_cast<double>(linux_hal::monotonicNs() - t0) > waitBoundS() * 1e9) return done();
      usleep(500);
      session_->poll(linux_hal::monotonicNs());
    }
    return true;
  }

  // ---- stage 1: bench GPIO first: the enable line is held inactive from here on, before any device is opened.
  int openBenchLines() {
    const GpioOptions& g = opt_.gpio;
    if (!g.enable.empty()) {
      linux_hal::GpioLineSpec spec;
      linux_hal::parseGpioLine(g.enable, spec);  // validated
      if (std::string err = io_.enable.open(spec, "phalanxd-enable"); !err.empty()) return fail("gpio.enable: " + err, 3);
      io_.have_enable = true;
    }
    if (!g.sync.empty()) {
      linux_hal::GpioLineSpec spec;
      double hz = 0.0;
      linux_hal::parseGpioSync(g.sync, spec, hz);
      if (std::string err = io_.sync.open(spec, hz, "phalanxd-sync"); !err.empty()) return fail("gpio.sync: " + err, 3);
      io_.have_sync = true;
    }
    if (!g.estop.empty()) {
      // An e-stop that cannot be opened does not end the daemon: it counts as pressed (the daemon runs stopped,
      // devices safe, and retries the line) - docs/gpio.md.
      linux_hal::GpioLineSpec spec;
      linux_hal::parseGpioLine(g.estop, spec);
      io_.have_estop = true;
      io_.estop_error = io_.estop.open(spec, "phalanxd-estop");
      io_.estop_open = io_.estop_error.empty();
      if (!io_.estop_open) std::fprintf(stderr, "%s: e-stop: %s - counts as pressed\n", programName(), io_.estop_error.c_str());
    }
    return 0;
  }

  // ---- stage 2: the device link, whatever its transport.
  int openDevice() {
    std::string err;
    link_ = openDeviceLink(opt_, err);
    if (!link_) return fail(err, 3);
    summary_["link"] = link_->info();
    session_ = std::make_unique<HostSession>(link_->makeSession());
    session_->setEventCallback(logEvent, opt_.hooks);
    return 0;
  }

  // ---- stage 3: Hello / HelloAck, then the first telemetry.
  int handshake() {
    // Hello again every 500 ms while unanswered, with the same session id: a device still starting (a board
    // booting, a USB gadget not yet serviced) may have missed the first; the firmware answers a repeat of the open
    // session's Hello without restarting it.
    const auto id = static_cast<uint32_t>(rd_());
    uint64_t next_hello_ns = 0;
    if (!pollUntil([&] {
          if (session_->handshake() != HandshakeResult::kPending) return true;
          if (const uint64_t now = linux_hal::monotonicNs(); now >= next_hello_ns) {
            session_->sendHello(id, link_->expectedDevice());
            link_->push();
            next_hello_ns = now + 500000000ull;
          }
          return false;
        })) {
      return fail("device did not answer the handshake within " + std::to_string(waitBoundS()) + " s on " +
                      link_->where() + " (wrong port, or not Phalanx firmware?)",
                  4);
    }
    if (session_->handshake() != HandshakeResult::kOk) return fail(session_->handshakeError(), 4);
    layout_ = session_->layout();
    summary_["device_type"] = layout_->name;
    summary_["firmware_build_id"] = session_->deviceInfo().firmware_build_id;
    summary_["firmware_tick_hz"] = session_->deviceInfo().tick_rate_hz;
    summary_["protocol_version"] = protocol::kProtocolVersion;
    return 0;
  }

  // ---- stage 4: controller, limits, recording, real time, device faults and parameters, outside surfaces.
  int configure() {
    if (int rc = chooseController(); rc != 0) return rc;
    limits_ = std::make_unique<CommandLimits>(*layout_);
    if (opt_.hooks != nullptr) limits_->setPatientStage(opt_.hooks->patientLimits());
    if (!opt_.record_csv.empty()) {
      if (std::string err = recorder_.open(opt_.record_csv, *layout_, recordingContext()); !err.empty()) return fail(err, 3);
    }
    setUpRealtime();
    // The first telemetry, bounded like the handshake: a device that answered late on a slow or loaded link
    // also streams late.
    if (!pollUntil([&] { return session_->hasTelemetry(); })) {
      return fail("device answered the handshake but sends no telemetry", 4);
    }
    if (int rc = clearPriorFaults(); rc != 0) return rc;
    if (int rc = checkVariant(); rc != 0) return rc;
    if (int rc = checkRequiredParams(); rc != 0) return rc;
    if (int rc = setStartupParams(); rc != 0) return rc;
    readBackStartupParams();
    if (int rc = startModbus(); rc != 0) return rc;
    if (int rc = startClientChannel(); rc != 0) return rc;
    if (int rc = startDds(); rc != 0) return rc;
    if (opt_.hooks != nullptr) {
      if (std::string err = opt_.hooks->onStart(*layout_, summary_); !err.empty()) return fail(err, 3);
    }
    return 0;
  }

  /// What --record FILE holds besides the cycles: the replay configuration, the pen's geometry.
  record::RecordingContext recordingContext() const {
    record::RecordingContext c;
    c.sync_column = io_.have_sync;
    const bool patient = opt_.hooks != nullptr && opt_.hooks->patientLimits() != nullptr;
    c.replay = record::replayConfig(opt_, controller_->name(), patient);
    c.pen_model = record::penModelOf(*controller_);
    return c;
  }

  int chooseController() {
    std::string err;
    if (opt_.hooks != nullptr) controller_ = opt_.hooks->makeController(*layout_, err);
    if (!controller_ && !err.empty()) return fail(err, 2);
    if (!controller_) controller_ = makeController(*layout_, opt_, err);
    if (!controller_) return fail(err, 2);
    summary_["controller"] = controller_->name();
    if (!link_->carriesGainScales() && controller_->usesGainScale()) {
      return fail(std::string("controller '") + controller_->name() +
                      "' sends per-finger gain scales in contact, which classic CAN does not carry (docs/protocol.md): "
                      "use @fd or @fd-compact, or --mode transparent",
                  2);
    }
    return 0;
  }

  void setUpRealtime() {
    linux_hal::RealtimeStatus rt;
    if (opt_.realtime) {
      rt = linux_hal::setupRealtime(opt_.rt_priority);
      if (!rt.warning.empty()) std::fprintf(stderr, "%s: warning: %s\n", programName(), rt.warning.c_str());
    }
    summary_["realtime"] = {{"memory_locked", rt.memory_locked}, {"sched_fifo", rt.fifo_scheduling}};
  }

  /// Faults left latched by a previous session are cleared if asked to (logged), else refuse to start.
  int clearPriorFaults() {
    if (session_->latest().fault_bits == 0) return 0;
    const std::string prior = faultList(session_->latest().fault_bits);
    summary_["faults_at_start"] = prior;
    if (!opt_.clear_faults) return fail("device has latched faults (" + prior + ") and clear_faults is off", 5);
    std::fprintf(stderr, "%s: clearing faults latched before this session: %s\n", programName(), prior.c_str());
    session_->sendClearFaults();
    link_->push();
    return 0;
  }

  /// ParamGet and wait (bounded like the handshake) for its answer; true when it came.
  bool getParam(uint16_t id) {
    session_->sendParamGet(id);
    link_->push();
    return pollUntil([&] { return session_->lastParamValid() && session_->lastParam().param_id == id; });
  }

  /// The rig and the finger are one device type; the variant parameter says which one answered.
  int checkVariant() {
    const int want = link_->expectedVariant();
    if (want < 0) return 0;
    if (!getParam(protocol::core_param::kDeviceVariant) || session_->lastParam().status != protocol::ParamStatus::kOk ||
        session_->lastParam().value != static_cast<float>(want)) {
      return fail("device variant: " + opt_.device + " answered as another " + layout_->name + " variant: refused", 2);
    }
    summary_["device_variant"] = want == protocol::variant::kSeaTestRig ? "sea_rig" : "standard";
    return 0;
  }

  /// A model from a geometry file must match the geometry the firmware was built with (fingerprint parameter):
  /// the host never silently runs one geometry against firmware made for another (docs/design-tools.md).
  int checkRequiredParams() {
    for (const Controller::RequiredParam& rp : controller_->requiredParams()) {
      if (!getParam(rp.id)) return fail(rp.what + ": the device did not answer the geometry fingerprint query: refused", 2);
      if (session_->lastParam().status != protocol::ParamStatus::kOk) {
        return fail(rp.what + ": the firmware does not report its geometry fingerprint: refused", 2);
      }
      if (session_->lastParam().value != rp.value) {
        char fw[32];
        std::snprintf(fw, sizeof fw, "%.0f", static_cast<double>(session_->lastParam().value));
        return fail(rp.what + " differs from the firmware's compile-time geometry (fingerprint " + fw +
                        "): build the firmware with this geometry, or run without the file; refused",
                    2);
      }
    }
    return 0;
  }

  int setStartupParams() {
    for (const auto& [id, value] : controller_->startupParams()) {
      session_->sendParamSet(id, value);
      link_->push();
      // Same bound as the handshake: a slow link (emulated, loaded) answers late but does answer.
      char what[128];
      if (!pollUntil([&] { return session_->lastParamValid(); })) {
        std::snprintf(what, sizeof what, "device did not answer start-up parameter 0x%04x within %.1f s", id, waitBoundS());
        return fail(what, 4);
      }
      if (session_->lastParam().status != protocol::ParamStatus::kOk) {
        std::snprintf(what, sizeof what, "device refused start-up parameter 0x%04x (status %d)", id,
                      static_cast<int>(session_->lastParam().status));
        return fail(what, 4);
      }
    }
    usleep(static_cast<useconds_t>(controller_->startupSettleS() * 1e6));
    session_->poll(linux_hal::monotonicNs());
    return 0;
  }

  void readBackStartupParams() {
    summary_["startup_warnings"] = nlohmann::json::array();
    for (const uint16_t id : controller_->startupReadback()) {
      if (!getParam(id) || session_->lastParam().status != protocol::ParamStatus::kOk) continue;
      const std::string warning = controller_->startupWarning(id, session_->lastParam().value);
      if (warning.empty()) continue;
      std::fprintf(stderr, "%s: WARNING: %s\n", programName(), warning.c_str());
      summary_["startup_warnings"].push_back(warning);
    }
  }

  /// Optional Modbus TCP server (docs/modbus.md): its own thread; the loop only publishes and polls, wait-free.
  int startModbus() {
    if (!opt_.modbus.enabled) return 0;
    modbus::WriteLimits limits{layout_->setpoint_count, layout_->setpoint_limit};
    if (opt_.modbus.setpoint_limit > 0.0) {
      limits.setpoint_limit = std::min(limits.setpoint_limit, static_cast<float>(opt_.modbus.setpoint_limit));
    }
    mb_server_ = std::make_unique<modbus::Server>(opt_.modbus, limits);
    if (std::string err = mb_server_->start(); !err.empty()) return fail(err, 3);
    std::fprintf(stderr, "%s: modbus: serving on %s:%u (%s)\n", programName(), opt_.modbus.address.c_str(), mb_server_->port(),
                 opt_.modbus.writes_enabled ? "writes enabled" : "read-only");
    mb_port_ = std::make_unique<modbus::LoopPort>(*mb_server_, opt_.modbus, static_cast<uint16_t>(layout_->type),
                                                  layout_->sample_count, layout_->setpoint_count);
    return 0;
  }

  /// The client channel's device models use the session's geometry files (validated before the device opened).
  client::ModelGeometry clientModelGeometry() const {
    client::ModelGeometry g;
    static const char* const kFingers[5] = {"thumb", "index", "middle", "ring", "little"};
    for (size_t f = 0; f < 5; ++f) {
      const auto it = opt_.glove_geometry.find(kFingers[f]);
      if (it != opt_.glove_geometry.end()) design::loadGloveGeometryYaml(it->second, g.glove[f]);
    }
    if (!opt_.pen_geometry.empty()) design::loadPenGeometryYaml(opt_.pen_geometry, g.pen);
    return g;
  }

  /// Optional local client channel (docs/sdk.md): its socket thread; the loop only copies through shared memory.
  /// DDS commands (docs/dds.md §"Commands") come in through it too: with them on and no socket, the channel has
  /// no socket, only the command path.
  int startClientChannel() {
    const bool dds_commands = opt_.dds.enabled && opt_.dds.commands;
    if (opt_.client.socket_path.empty() && !dds_commands) return 0;
    if (std::string err = client::validateClientOptions(opt_.client); !err.empty()) return fail(err, 2);
    const client::DeviceIdentity id{layout_, opt_.rate_hz, session_->deviceInfo().firmware_build_id};
    client_server_ = std::make_unique<client::Server>(opt_.client, id);
    if (std::string err = client_server_->start(); !err.empty()) return fail(err, 3);
    if (!opt_.client.socket_path.empty()) {
      std::fprintf(stderr, "%s: client: serving on %s\n", programName(), opt_.client.socket_path.c_str());
    }
    client_port_ = std::make_unique<client::ClientPort>(*client_server_, *layout_, opt_.rate_hz, mb_port_.get(),
                                                        clientModelGeometry());
    return 0;
  }

  /// Optional DDS bridge (docs/dds.md): its own thread; the loop only copies into a preallocated ring.
  int startDds() {
    if (!opt_.dds.enabled) return 0;
    dds::BridgeDevice dev;
    dev.layout = layout_;
    dev.rate_hz = opt_.rate_hz;
    dev.firmware_build_id = session_->deviceInfo().firmware_build_id;
    dev.device_spec = opt_.device;
    dev.geometry = clientModelGeometry();
    dev.commands = opt_.dds.commands ? client_server_.get() : nullptr;
    dds_port_ = std::make_unique<dds::LoopPort>(opt_.dds, opt_.rate_hz);
    std::string err;
    dds_bridge_ = dds::startBridge(opt_.dds, dev, *dds_port_, err);
    if (!dds_bridge_) return fail(err, 3);
    std::fprintf(stderr, "%s: dds: publishing rt/%s/* on domain %u%s\n", programName(),
                 dds::topicNamespace(opt_.dds, *layout_).c_str(), opt_.dds.domain_id,
                 opt_.dds.commands ? "; commands on rt/<ns>/command" : "");
    return 0;
  }

  // ---- stage 5: the cycles.
  void runCycles() {
    period_ns_ = 1000000000ull / opt_.rate_hz;
    max_cycles_ = static_cast<uint64_t>(std::llround(opt_.seconds * opt_.rate_hz));
    telemetry_timeout_ns_ = static_cast<uint64_t>(opt_.telemetry_timeout_ms) * 1000000ull;
    cmd_.channel_count = layout_->setpoint_count;
    cmd_.timeout_ms = static_cast<uint16_t>(opt_.command_timeout_ms);
    makeSafe(cmd_);
    startSafetyIo();
    if (link_->reconnects()) std::fprintf(stderr, "%s: control loop started on %s\n", programName(), link_->where().c_str());
    CycleMode mode = CycleMode::kTelemetry;
    parseCycleMode(opt_.cycle, mode);  // validated
    const unsigned device_hz = session_->deviceInfo().tick_rate_hz;
    clock_ = std::make_unique<CycleClock>(mode, period_ns_, device_hz > 0 ? 1000000000ull / device_hz : 0, *link_,
                                          *session_);
    start_ns_ = linux_hal::monotonicNs();
    next_live_ns_ = start_ns_;
    last_new_telemetry_ns_ = start_ns_;
    // Hot-unplug (usb:, serial:): report, send nothing, reconnect, new handshake, start-up parameters, faults
    // cleared, then new commands (host/include/phalanx/host/link_recovery.h).
    LinkRecoveryOptions rec_opt;
    rec_opt.handshake_timeout_ns = static_cast<uint64_t>(opt_.handshake_timeout_s * 1e9);
    rec_opt.clear_faults = opt_.clear_faults;
    recovery_ = std::make_unique<LinkRecovery>(
        *link_, *session_, layout_->type, controller_->startupParams(), rec_opt,
        [this]() { return static_cast<uint32_t>(rd_()); },
        [](const std::string& m) { std::fprintf(stderr, "%s: %s\n", programName(), m.c_str()); }, start_ns_);
    while (g_stop == 0 && (max_cycles_ == 0 || cycles_ < max_cycles_) &&
           (opt_.hooks == nullptr || !opt_.hooks->stopRequested())) {
      if (!cycle()) break;
    }
  }

  /// One cycle: telemetry → device model → command source → limits → send. false ends the session.
  bool cycle() {
    const uint64_t wake_ns = waitForCycle();
    const int new_telemetry = cycle_start_.new_telemetry;
    if (link_->reconnects()) {
      const LinkRecovery::Step st = recovery_->step(wake_ns);
      if (st == LinkRecovery::Step::kFailed) return linkLost(recovery_->error());
      if (st == LinkRecovery::Step::kOffline) {
        last_new_telemetry_ns_ = wake_ns;  // the recovery owns the outage's timing
        return true;
      }
    }
    if (std::string why = deviceSilent(new_telemetry, wake_ns); !why.empty()) return linkLost(why);
    const TelemetryFrame& tel = session_->latest();
    faults_seen_ |= tel.fault_bits;
    const double t_s = static_cast<double>(wake_ns - start_ns_) * 1e-9;
    readSafetyInputs(tel, t_s);
    commandFromSources(tel, t_s, wake_ns);
    limits_->apply(tel, cmd_);
    if (!sendCommand(t_s)) return false;
    if (new_telemetry > 0) reaction_us_.add(static_cast<double>(session_->lastSendNs() - tel.host_rx_ns) / 1000.0);
    recorder_.row(t_s, tel, cmd_, io_.have_sync ? io_.sync.pulses() : 0, last_source_);
    if (opt_.hooks != nullptr) opt_.hooks->onCycle(wake_ns, t_s, tel, cmd_);
    publish(tel, wake_ns, t_s);
    return !recorder_.failed();  // a recording asked for and failing ends the session (exit 7), never silently
  }

  /// The cycle's clock (docs/session-runner.md): a telemetry frame's arrival, or the period timer; it polls.
  uint64_t waitForCycle() {
    cycle_start_ = clock_->next();
    last_jitter_us_ = cycle_start_.jitter_us;
    jitter_us_.add(last_jitter_us_);
    overruns_ += cycle_start_.missed;
    ++cycles_;
    return cycle_start_.wake_ns;
  }

  /// Why the device is lost although the link is open ("" while it answers): the simulated firmware exited, or
  /// no new telemetry for telemetry_timeout_ms. Cycles without new telemetry are counted (stale cycles).
  std::string deviceSilent(int new_telemetry, uint64_t wake_ns) {
    if (std::string gone = link_->deviceGone(); !gone.empty()) return gone;
    if (new_telemetry > 0) {
      last_new_telemetry_ns_ = wake_ns;
      return {};
    }
    ++cycles_without_telemetry_;
    // A CAN bus off or down is the bus's own outage (the device goes safe by its command timeout, traffic resumes
    // after the restart): the telemetry timeout counts from its end.
    if (link_->inOutage()) last_new_telemetry_ns_ = wake_ns;
    if (wake_ns - last_new_telemetry_ns_ <= telemetry_timeout_ns_) return {};
    char why[96];
    std::snprintf(why, sizeof why, "no telemetry from the device for %.1f ms (telemetry_timeout_ms %u)",
                  static_cast<double>(wake_ns - last_new_telemetry_ns_) / 1e6, opt_.telemetry_timeout_ms);
    return why;
  }

  bool linkLost(const std::string& why) {
    summary_["link_error"] = why;
    return false;
  }

  void startSafetyIo() {
    SafetyIoConfig cfg;
    cfg.release_debounce_ns = static_cast<uint64_t>(opt_.gpio.estop_release_ms * 1e6);
    safety_ = std::make_unique<SafetyIo>(io_.have_estop ? &io_.estop : nullptr, io_.have_enable ? &io_.enable : nullptr, cfg);
    have_safety_io_ = io_.have_estop || io_.have_enable;
    stops_.reserve(kMaxStopRecords);
    if (have_safety_io_) {
      safety_->start(io_.estop_open, linux_hal::monotonicNs());
      last_pressed_ = safety_->estopPressed();
      if (safety_->stopped()) {
        std::fprintf(stderr, "%s: e-stop: starting STOPPED (%s): devices held safe until a reset (SIGUSR1 or the API's reset)\n", programName(),
                     stopCauseName(safety_->cause()));
      } else if (io_.have_enable) {
        std::fprintf(stderr, "%s: enable: drives enabled\n", programName());
      }
    }
    if (io_.have_sync) {
      if (std::string w = io_.sync.start(opt_.realtime ? std::max(1, opt_.rt_priority - 1) : 0); !w.empty()) {
        std::fprintf(stderr, "%s: warning: %s\n", programName(), w.c_str());
      }
      std::fprintf(stderr, "%s: sync: pulses at %g Hz on %s\n", programName(), io_.sync.rateHz(), opt_.gpio.sync.c_str());
    }
  }

  /// A reset request (SIGUSR1 or the API's reset) and the e-stop line, read right after the telemetry poll so the
  /// newest telemetry is the device's state when the edge reached the daemon; a stop drops the enable line inside
  /// update(), before the safe command goes out.
  void readSafetyInputs(const TelemetryFrame& tel, double t_s) {
    bool reset_request = g_reset != 0;
    if (reset_request) g_reset = 0;
    if (opt_.hooks != nullptr && opt_.hooks->takeClearFaultsRequest()) reset_request = true;
    // One ClearFaults to the device (its own latched faults; it refuses while its own e-stop is pressed).
    if (reset_request) session_->sendClearFaults();
    if (have_safety_io_) readEstop(tel, t_s, reset_request);
    if (awaiting_safe_ && session_->safeSeen()) confirmSafe();
  }

  void readEstop(const TelemetryFrame& tel, double t_s, bool reset_request) {
    const uint64_t now_ns = linux_hal::monotonicNs();
    if (reset_request && safety_->stopped()) {
      if (const char* why = safety_->requestReset(now_ns); why != nullptr) {
        std::fprintf(stderr, "%s: e-stop: reset refused at t=%.3f s: %s\n", programName(), t_s, why);
      } else {
        std::fprintf(stderr, "%s: e-stop: reset accepted at t=%.3f s: drives enabled, control resumes\n", programName(), t_s);
      }
    }
    if (safety_->update(now_ns)) {
      StopRecord r;
      r.cause = safety_->cause();
      r.edge_ns = safety_->stopEdgeNs();
      r.seen_ns = linux_hal::monotonicNs();
      r.seq_at_seen = tel.seq;
      r.device_was_active = (tel.state_flags & protocol::state::kOutputsActive) != 0;
      awaiting_safe_ = stops_.size() < kMaxStopRecords;
      if (awaiting_safe_) {
        stops_.push_back(r);
        session_->watchForSafe(tel.seq);
      }
      log_stop_ = true;  // after the safe command is out: stderr may be a slow file or pipe
    }
    if (safety_->estopPressed() != last_pressed_) {
      last_pressed_ = safety_->estopPressed();
      if (!last_pressed_) std::fprintf(stderr, "%s: e-stop: released at t=%.3f s (%s)\n", programName(), t_s,
                                       safety_->stopped() ? "still stopped: a reset is needed" : "running");
    }
  }

  void confirmSafe() {
    StopRecord& r = stops_.back();
    r.safe_confirmed = true;
    r.safe_rx_ns = session_->safeRxNs();
    r.ticks_to_safe = static_cast<uint16_t>(session_->safeSeq() - r.seq_at_seen);
    r.device_ticks_to_safe = session_->deviceTicksToSafe();
    awaiting_safe_ = false;
    std::fprintf(stderr, "%s: e-stop: device safe %u tick(s) after the edge reached the daemon "
                 "(edge->daemon %.0f us, daemon->safe telemetry %.0f us)\n", programName(), r.ticks_to_safe,
                 r.edge_ns != 0 ? static_cast<double>(r.seen_ns - r.edge_ns) / 1000.0 : -1.0,
                 static_cast<double>(r.safe_rx_ns - r.seen_ns) / 1000.0);
  }

  /// Exactly one source commands the device each cycle: a stop (e-stop) commands the safe state and nothing runs;
  /// else a Modbus client that took control; else the session's controller (built-in or therapy exercise). The
  /// controller runs whenever the daemon is not stopped, so its state follows the hand while Modbus commands.
  void commandFromSources(const TelemetryFrame& tel, double t_s, uint64_t wake_ns) {
    if (have_safety_io_ && safety_->stopped()) {
      makeSafe(cmd_);  // no controller update while stopped: no integrator wind-up
      countSource(kSourceStop);
      return;
    }
    controller_->update(tel, t_s, 1.0 / opt_.rate_hz, cmd_);
    if (mb_port_ && mb_port_->overrideCommand(cmd_, wake_ns)) {
      countSource(kSourceModbus);
      return;
    }
    if (client_port_ && client_port_->overrideCommand(tel, cmd_, wake_ns)) {
      countSource(kSourceClient);
      return;
    }
    countSource(kSourceController);
  }

  void countSource(uint8_t source) {
    ++source_cycles_[source];
    last_source_ = source;  // recorded with the cycle (record::CommandExtras::source: the same numbering)
  }

  /// Send, push the link, time-stamp an e-stop's safe command. false on a hard link error.
  bool sendCommand(double t_s) {
    if (!session_->sendCommand(cmd_, linux_hal::monotonicNs()) && link_->reconnects() && link_->lost()) {
      // The link went away inside this very send (USB: the submit found the device unplugged): part of the
      // outage that the next cycle's recovery step reports, not a full link.
      ++commands_unsent_link_lost_;
    }
    link_->afterCycle(t_s);
    const bool pushed = link_->push();
    if (awaiting_safe_ && stops_.back().sent_ns == 0) {
      stops_.back().sent_ns = linux_hal::monotonicNs();
      session_->markSafeCommand(cmd_.seq);
    }
    if (log_stop_) {
      log_stop_ = false;
      std::fprintf(stderr, "%s: E-STOP (%s) at t=%.3f s: enable dropped, devices commanded safe; stopped until reset\n", programName(),
                   stopCauseName(safety_->cause()), t_s);
    }
    if (!pushed) return linkLost(link_->linkError());
    return true;
  }

  void publish(const TelemetryFrame& tel, uint64_t wake_ns, double t_s) {
    const uint64_t done_ns = linux_hal::monotonicNs();
    const double cycle_us = static_cast<double>(done_ns - wake_ns) / 1000.0;
    cycle_us_.add(cycle_us);
    if (mb_port_) {
      mb_port_->publish(tel, cmd_, cycles_, overruns_, last_jitter_us_, cycle_us, wake_ns - start_ns_,
                        session_->stats().telemetry_lost, modbus::LoopState::kRunning);
    }
    if (client_port_) client_port_->publish(tel, cmd_, wake_ns, cycles_);
    if (dds_port_) dds_port_->offer(tel, wake_ns, cycles_, overruns_, last_jitter_us_, cycle_us);
    if (opt_.live_view && wake_ns >= next_live_ns_) {
      next_live_ns_ = wake_ns + 100000000ull;
      drawLiveView(tel, t_s);
    }
  }

  /// The live terminal view: a legend once, then a block redrawn in place (cursor moved up over the previous
  /// block), every line cut to 79 columns so an 80-column terminal never wraps it.
  void drawLiveView(const TelemetryFrame& tel, double t_s) {
    char head[48];
    std::snprintf(head, sizeof head, "  t %.1f s   device ", t_s);
    std::string block = head + std::string(modeName(tel.mode)) + "   faults " + faultList(tel.fault_bits);
    if (tel.fault_bits != 0) block += "  (phalanx status explains)";
    block += "\n" + controller_->liveLine(tel);
    std::string out;
    if (live_lines_ == 0) {
      const std::string legend = controller_->liveLegend();
      out += (legend.empty() ? "Live view, every 0.1 s" : legend) +
             "\n  device = the mode the device reports (safe/transparent/setpoint/lock)\n";
    } else {
      out += "\033[" + std::to_string(live_lines_) + "A";
    }
    int lines = 0;
    std::size_t pos = 0;
    while (pos <= block.size()) {
      const std::size_t nl = block.find('\n', pos);
      std::string line = block.substr(pos, nl == std::string::npos ? std::string::npos : nl - pos);
      if (line.size() > 79) line.resize(79);  // ASCII only: bytes are columns
      out += "\r\033[K" + line + "\n";
      ++lines;
      if (nl == std::string::npos) break;
      pos = nl + 1;
    }
    live_lines_ = lines;
    std::fputs(out.c_str(), stderr);
    std::fflush(stderr);
  }

  // ---- stage 6: leave the device safe (drives disabled, then explicit safe commands; the device would also
  // time out), stop the outside surfaces, summarise.
  int shutDown() {
    if (have_safety_io_) safety_->shutdown();
    if (io_.have_sync) io_.sync.stop();
    makeSafe(cmd_);
    // At least three safe commands, then more until the device reports its safe state (at most 250 ms): a
    // firmware that lags its host (a loaded machine: the soak saw 150 ticks behind) must have applied one before
    // final_mode is read, or the summary would report the mode of a frame sent before it. A lost link is not
    // waited for.
    const uint64_t confirm_until_ns = linux_hal::monotonicNs() + 250000000ull;
    for (int i = 0;; ++i) {
      session_->sendCommand(cmd_, linux_hal::monotonicNs());
      link_->push();
      usleep(2000);
      session_->poll(linux_hal::monotonicNs());
      if (i < 2) continue;
      if (summary_.contains("link_error") || session_->latest().mode == protocol::Mode::kSafe ||
          linux_hal::monotonicNs() > confirm_until_ns)
        break;
    }
    recorder_.close();
    link_->close();
    if (mb_server_) {
      mb_server_->stop();
      summary_["modbus"] = mb_server_->statsJson();
      summary_["modbus"]["cycles_under_modbus_control"] = mb_port_->remoteCycles();
      summary_["modbus"]["command_timeouts"] = mb_port_->remoteTimeouts();
    }
    if (dds_bridge_) dds_bridge_->stop();  // first: its command reader writes into the client channel
    if (client_server_) {
      client_port_->finish(summary_.contains("link_error") ? client_wire::ForceOffCause::kLinkLoss
                                                            : client_wire::ForceOffCause::kDaemonStop);
      client_server_->stop();
      summary_["client"] = client_port_->summaryJson(start_ns_);
    }
    if (dds_bridge_) summary_["dds"] = dds_bridge_->summaryJson();
    summarize();
    if (opt_.hooks != nullptr) opt_.hooks->onEnd(summary_);
    if (summary_.contains("link_error")) {
      std::fprintf(stderr, "%s: session ended by a link error: %s\n", programName(),
                   summary_["link_error"].get<std::string>().c_str());
      return 6;
    }
    if (recorder_.failed()) return record::kExitRecordFailed;  // checked after close(): it can latch fsync/close
    return 0;
  }

  void summarize() {
    const LinkStats& s = session_->stats();
    const LimitCounters& lim = limits_->counters();
    summary_["seconds"] = static_cast<double>(linux_hal::monotonicNs() - start_ns_) * 1e-9;
    summary_["rate_hz"] = opt_.rate_hz;
    summary_["cycles"] = cycles_;
    summary_["overruns"] = overruns_;
    summary_["period_jitter"] = histogramJson(jitter_us_);
    summary_["cycle_time"] = histogramJson(cycle_us_);
    summary_["round_trip"] = histogramJson(session_->roundTripUs());
    summary_["sensor_to_actuation"] = histogramJson(session_->sensorToActuationUs());
    summary_["cycle"] = {{"mode", cycleModeName(clock_->mode())},
                         {"started_by_telemetry", clock_->startedByTelemetry()},
                         {"started_by_timer", clock_->startedByTimer()},
                         {"wakes_without_telemetry", clock_->wakesWithoutTelemetry()},
                         {"read_to_command", histogramJson(reaction_us_)}};
    summary_["telemetry"] = {{"received", s.telemetry_received},
                             {"lost", s.telemetry_lost},
                             {"late", s.telemetry_late},
                             {"cycles_without_new_telemetry", cycles_without_telemetry_}};
    summary_["commands"] = {{"sent", s.commands_sent},
                            {"unsent_link_full", s.commands_unsent - commands_unsent_link_lost_},
                            {"unsent_link_lost", commands_unsent_link_lost_},
                            {"refused_by_host_limits", lim.refused},
                            {"limited_by_device_limits", lim.device_limited},
                            {"limited_by_patient_limits", lim.patient_limited},
                            {"lost_seen_by_device", s.device_cmd_lost},
                            {"rejected_by_device", s.device_rx_errors}};
    summary_["command_sources"] = {{"controller", source_cycles_[kSourceController]},
                                   {"modbus", source_cycles_[kSourceModbus]},
                                   {"client", source_cycles_[kSourceClient]},
                                   {"stop", source_cycles_[kSourceStop]}};
    summary_["host_rx_errors"] = {{"crc", s.host_rx.crc_errors},
                                  {"framing", s.host_rx.framing_errors},
                                  {"unknown_id", s.host_rx.unknown_id},
                                  {"bad_length", s.host_rx.bad_length}};
    // Faults latched while the link was down are read (and cleared) by the reconnect, outside the control cycles.
    if (link_->reconnects()) faults_seen_ |= recovery_->stats().faults_after_reconnect;
    summary_["faults_seen"] = faultList(faults_seen_);
    if (link_->reconnects()) {
      const LinkRecoveryStats& r = recovery_->stats();
      summary_["outages"] = {{"count", r.outages},  {"reconnects", r.reconnects}, {"cycles_offline", r.cycles_offline},
                             {"max_s", r.max_s},    {"total_s", r.total_s},
                             {"connected_at_end", recovery_->phase() == LinkRecovery::Phase::kUp}};
    }
    link_->summarize(summary_);
    summary_["final_mode"] = modeName(session_->latest().mode);
    summarizeGpio();
    if (!opt_.record_csv.empty()) {
      summary_["recording"] = {{"path", opt_.record_csv}, {"rows", recorder_.rowsWritten()},
                               {"dropped_rows", recorder_.rowsLost()}};
      if (recorder_.failed()) summary_["recording"]["error"] = recorder_.error();
    }
    nlohmann::json extra = nlohmann::json::object();
    controller_->summarize(extra);
    if (!extra.empty()) summary_[layout_->name] = extra;
  }

  void summarizeGpio() {
    if (!have_safety_io_ && !io_.have_sync) return;
    nlohmann::json g = nlohmann::json::object();
    if (have_safety_io_) {
      const SafetyIoCounters& c = safety_->counters();
      nlohmann::json list = nlohmann::json::array();
      for (const StopRecord& r : stops_) {
        nlohmann::json j = {{"cause", stopCauseName(r.cause)}, {"device_was_active", r.device_was_active},
                            {"safe_confirmed", r.safe_confirmed}};
        if (r.edge_ns != 0) j["edge_to_daemon_us"] = static_cast<double>(r.seen_ns - r.edge_ns) / 1000.0;
        if (r.sent_ns != 0) j["daemon_reaction_us"] = static_cast<double>(r.sent_ns - r.seen_ns) / 1000.0;
        if (r.safe_confirmed) {
          j["daemon_to_safe_telemetry_us"] = static_cast<double>(r.safe_rx_ns - r.seen_ns) / 1000.0;
          j["ticks_to_safe"] = r.ticks_to_safe;
          j["device_ticks_to_safe"] = r.device_ticks_to_safe;
        }
        list.push_back(j);
      }
      g["estop"] = {{"line", opt_.gpio.estop}, {"state", safety_->stopped() ? "stopped" : "running"},
                    {"cause", stopCauseName(safety_->cause())}, {"line_ok", safety_->estopLineOk()},
                    {"open_error", io_.estop_error}, {"stops", c.stops}, {"presses", c.presses},
                    {"line_lost", c.line_lost}, {"resets", c.resets}, {"resets_refused", c.resets_refused},
                    {"reopen_attempts", c.reopen_attempts}, {"reopened", c.reopened},
                    {"enable_failures", c.enable_failures}, {"release_debounce_ms", opt_.gpio.estop_release_ms},
                    {"stop_records", list}};
      if (io_.have_enable) g["enable"] = {{"line", opt_.gpio.enable}, {"write_failures", c.enable_failures}};
    }
    if (io_.have_sync) {
      const linux_hal::SyncPulseStats y = io_.sync.stats();
      g["sync"] = {{"line", opt_.gpio.sync}, {"rate_hz", io_.sync.rateHz()}, {"pulses", y.pulses},
                   {"missed_periods", y.missed}, {"write_errors", y.write_errors},
                   {"edge_late_mean_us", y.mean_late_us}, {"edge_late_max_us", y.max_late_us},
                   {"first_rise_ns", y.first_rise_ns}};
    }
    summary_["gpio"] = g;
  }

  static constexpr size_t kMaxStopRecords = 256;  // fixed: no allocation in the loop; later stops are counted only
  enum Source : uint8_t { kSourceController = 0, kSourceModbus, kSourceClient, kSourceStop, kSourceCount };
  uint8_t last_source_ = kSourceController;

  const RunOptions& opt_;
  nlohmann::json& summary_;
  std::random_device rd_;
  GpioLines io_;
  std::unique_ptr<DeviceLink> link_;
  std::unique_ptr<HostSession> session_;
  const protocol::DeviceLayout* layout_ = nullptr;
  std::unique_ptr<Controller> controller_;
  std::unique_ptr<CommandLimits> limits_;
  record::CsvRecorder recorder_;
  std::unique_ptr<modbus::Server> mb_server_;
  std::unique_ptr<modbus::LoopPort> mb_port_;
  std::unique_ptr<client::Server> client_server_;
  std::unique_ptr<client::ClientPort> client_port_;
  std::unique_ptr<dds::LoopPort> dds_port_;
  std::unique_ptr<dds::Bridge> dds_bridge_;
  std::unique_ptr<SafetyIo> safety_;
  std::unique_ptr<LinkRecovery> recovery_;
  std::unique_ptr<CycleClock> clock_;
  CycleStart cycle_start_;
  Histogram reaction_us_{5000};  ///< the poll that read a frame → the command computed from it sent
  bool have_safety_io_ = false;
  std::vector<StopRecord> stops_;
  bool awaiting_safe_ = false, log_stop_ = false, last_pressed_ = false;
  protocol::Command cmd_;
  uint64_t period_ns_ = 0, max_cycles_ = 0, telemetry_timeout_ns_ = 0;
  uint64_t start_ns_ = 0, next_live_ns_ = 0, last_new_telemetry_ns_ = 0;
  int live_lines_ = 0;  ///< lines of the live view's last block (drawLiveView)
  Histogram jitter_us_{5000};
  Histogram cycle_us_{5000};
  double last_jitter_us_ = 0.0;
  uint64_t cycles_ = 0, overruns_ = 0, cycles_without_telemetry_ = 0, commands_unsent_link_lost_ = 0;
  std::array<uint64_t, kSourceCount> source_cycles_{};
  uint16_t faults_seen_ = 0;
};

}  // namespace

int runSession(const RunOptions& opt, nlohmann::json& summary) {
  SessionRunner runner(opt, summary);
  return runner.run();
}

}  // namespace phalanx::host
