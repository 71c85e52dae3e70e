#include "phalanx/host/daemon.h"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include "phalanx/host/controller.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/modbus/server.h"
#include "phalanx/host/record/csv_recorder.h"
#include "phalanx/host/safety_io.h"
#include "phalanx/host/link_recovery.h"
#include "phalanx/host/session.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/gpio.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/linux/usb_link.h"

extern char** environ;

namespace phalanx::host {

std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error);

namespace {

volatile std::sig_atomic_t g_stop = 0;
void onStopSignal(int) { g_stop = 1; }
volatile std::sig_atomic_t g_reset = 0;
void onResetSignal(int) { g_reset = 1; }

std::string selfDir() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return ".";
  buf[n] = 0;
  std::string p(buf);
  const auto slash = p.rfind('/');
  return slash == std::string::npos ? "." : p.substr(0, slash);
}

/// Tick rate of every board image (hal/mcu/qemu/board_main.cpp, hal/mcu/stm32g474/main.cpp).
constexpr unsigned kSimDeviceTickHz = 1000;

/// The simulated firmware as a child process; it prints "PTY <path>" once its link is up.
class SimChild {
 public:
  ~SimChild() { stop(); }
  std::string start(const RunOptions& opt, const std::string& device_name, std::string& pty_path) {
    const std::string exe = opt.firmware_sim.empty() ? selfDir() + "/firmware-sim" : opt.firmware_sim;
    if (access(exe.c_str(), X_OK) != 0) return "cannot run the simulated firmware '" + exe + "': " + std::strerror(errno);
    int out[2];
    if (pipe2(out, O_CLOEXEC) != 0) return std::string("pipe: ") + std::strerror(errno);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, out[1], STDOUT_FILENO);
    const std::string seed = std::to_string(opt.seed);
    // The simulated firmware ticks at the boards' rate (1 kHz, hal/mcu/*/main: kTickHz), or faster with a faster
    // host loop, never at a slower host's rate: the glove's force loop is designed for >= 1 kHz (000 §4.3; issue
    // #3) and at a 100 Hz tick it limit-cycled into current-limit in 5 of 6 sessions with a still hand.
    const std::string hz = std::to_string(std::max(opt.rate_hz, kSimDeviceTickHz));
    std::vector<std::string> args = {exe, "--device", device_name, "--tick-hz", hz, "--seed", seed,
                                     "--scenario", opt.scenario, "--exit-with-parent"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, exe.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(out[1]);
    if (rc != 0) {
      ::close(out[0]);
      pid_ = -1;
      return "cannot start " + exe + ": " + std::strerror(rc);
    }
    // Read its first line (bounded wait).
    std::string line;
    pollfd pfd{out[0], POLLIN, 0};
    while (line.find('\n') == std::string::npos) {
      if (::poll(&pfd, 1, 5000) <= 0) break;
      char c[256];
      const ssize_t n = ::read(out[0], c, sizeof c);
      if (n <= 0) break;
      line.append(c, static_cast<size_t>(n));
    }
    ::close(out[0]);
    if (line.rfind("PTY ", 0) != 0) return "the simulated firmware did not report its link (got '" + line + "')";
    pty_path = line.substr(4, line.find('\n') - 4);
    return {};
  }
  void stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    int status = 0;
    for (int i = 0; i < 200 && waitpid(pid_, &status, WNOHANG) == 0; ++i) usleep(5000);
    if (waitpid(pid_, &status, WNOHANG) == 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
    }
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

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
      std::fprintf(stderr, "phalanxd: device fault latched: %s\n",
                   faultList(static_cast<uint16_t>(e.value)).c_str());
      break;
    case protocol::EventCode::kCommandRejected:
      std::fprintf(stderr, "phalanxd: device rejected a command (reason %u, channel %u, value %g)\n", e.detail,
                   e.channel, static_cast<double>(e.value));
      break;
    case protocol::EventCode::kClearRefused:
      std::fprintf(stderr, "phalanxd: device refused to clear faults: %s still present\n",
                   faultList(static_cast<uint16_t>(e.value)).c_str());
      break;
    default:
      break;
  }
}

/// Host-side last line of defence: nothing non-finite or beyond the device's limit leaves the host.
bool commandIsSafe(const protocol::Command& cmd, const protocol::DeviceLayout& layout) {
  if (static_cast<uint8_t>(cmd.mode) >= protocol::kModeCount) return false;
  for (uint8_t i = 0; i < layout.setpoint_count; ++i) {
    if (!std::isfinite(cmd.setpoint[i]) || std::fabs(cmd.setpoint[i]) > layout.setpoint_limit) return false;
  }
  return true;
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
  if (opt.device.rfind("serial:", 0) == 0 && opt.device.size() == 7) return "device: 'serial:' needs a path (serial:/dev/ttyACM0)";
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
  if (opt.command_timeout_ms < 2 || opt.command_timeout_ms > 1000) return "command_timeout_ms: must be in [2, 1000]";
  if (opt.command_timeout_ms * opt.rate_hz < 2000) {
    return "command_timeout_ms: must cover at least two host periods (" + std::to_string(2000 / opt.rate_hz + 1) + " ms at " +
           std::to_string(opt.rate_hz) + " Hz)";
  }
  if (opt.rt_priority < 1 || opt.rt_priority > 99) return "realtime.priority: must be in [1, 99]";
  if (opt.scenario != "still" && opt.scenario != "close-open" && opt.scenario != "grasp" && opt.scenario != "random") {
    return "scenario: '" + opt.scenario + "' is not one of still, close-open, grasp, random";
  }
  if (opt.scene != "none" && opt.scene != "rigid-ball" && opt.scene != "soft-ball" && opt.scene != "wall") {
    return "scene: '" + opt.scene + "' is not one of none, rigid-ball, soft-ball, wall";
  }
  if (opt.mode != "render" && opt.mode != "transparent") return "mode: '" + opt.mode + "' is not one of render, transparent";
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
  if (std::string err = validateGpio(opt.gpio); !err.empty()) return err;
  return modbus::validateServerOptions(opt.modbus);
}

int runSession(const RunOptions& opt, nlohmann::json& summary) {
  auto fail = [&](const std::string& msg, int code) {
    summary["error"] = msg;
    std::fprintf(stderr, "phalanxd: error: %s\n", msg.c_str());
    return code;
  };
  if (const std::string problem = validate(opt); !problem.empty()) return fail(problem, 2);
  summary["device"] = opt.device;

  // Bench GPIO first: the enable line is held inactive from here on, before any device is opened.
  GpioLines io;
  if (!opt.gpio.enable.empty()) {
    linux_hal::GpioLineSpec spec;
    linux_hal::parseGpioLine(opt.gpio.enable, spec);  // validated above
    if (std::string err = io.enable.open(spec, "phalanxd-enable"); !err.empty()) return fail("gpio.enable: " + err, 3);
    io.have_enable = true;
  }
  if (!opt.gpio.sync.empty()) {
    linux_hal::GpioLineSpec spec;
    double hz = 0.0;
    linux_hal::parseGpioSync(opt.gpio.sync, spec, hz);
    if (std::string err = io.sync.open(spec, hz, "phalanxd-sync"); !err.empty()) return fail("gpio.sync: " + err, 3);
    io.have_sync = true;
  }
  if (!opt.gpio.estop.empty()) {
    // An e-stop that cannot be opened is not an error that ends the daemon: it counts as pressed (the daemon
    // runs stopped, devices safe, and retries the line) - docs/gpio.md.
    linux_hal::GpioLineSpec spec;
    linux_hal::parseGpioLine(opt.gpio.estop, spec);
    io.have_estop = true;
    io.estop_error = io.estop.open(spec, "phalanxd-estop");
    io.estop_open = io.estop_error.empty();
    if (!io.estop_open) std::fprintf(stderr, "phalanxd: e-stop: %s - counts as pressed\n", io.estop_error.c_str());
  }

  SimChild sim;
  const bool is_can = opt.device.rfind("can:", 0) == 0;
  const bool is_usb = opt.device.rfind("usb:", 0) == 0;
  const bool is_serial = opt.device.rfind("serial:", 0) == 0;
  const bool can_reconnect = is_usb || is_serial;  // hot-unplug handled in the loop
  std::string path = opt.device.substr(opt.device.find(':') + 1);
  unsigned baud = 0;
  protocol::DeviceType expected = protocol::DeviceType::kAny;
  if (opt.device.rfind("sim:", 0) == 0) {
    const std::string name = path;
    // sim:sea_rig is the sea_finger firmware on the §7.1 test-rig plant: it answers as a sea_finger.
    expected = name == "glove5"                            ? protocol::DeviceType::kGlove5
               : name == "sea_finger" || name == "sea_rig" ? protocol::DeviceType::kSeaFinger
                                                           : protocol::DeviceType::kPantograph;
    if (std::string err = sim.start(opt, name, path); !err.empty()) return fail(err, 3);
  } else if (const auto at = path.find('@'); at != std::string::npos && !is_can && !is_usb) {
    try {
      baud = static_cast<unsigned>(std::stoul(path.substr(at + 1)));
    } catch (...) {
      return fail("device: bad baud rate in '" + opt.device + "'", 2);
    }
    path = path.substr(0, at);
  }
  linux_hal::SerialLink link;
  linux_hal::CanLink can;
  linux_hal::UsbLink usb;
  bool can_classic = false;  // classic CAN carries no gain scales (checked against the controller below)
  if (is_usb) {
    linux_hal::UsbLink::Options o;
    linux_hal::parseUsbDevice(opt.device, o);  // validated above
    if (std::string err = usb.open(o); !err.empty()) return fail(err, 3);
    path = opt.device;
    summary["link"] = {{"usb", opt.device.substr(4)}, {"where", usb.where()}};
    std::fprintf(stderr, "phalanxd: USB device %s at %s\n", opt.device.substr(4).c_str(), usb.where().c_str());
  } else if (is_can) {
    linux_hal::CanLink::Options o;
    parseCanDevice(opt.device, o);  // validated above
    can_classic = o.flavor == protocol::can::Flavor::kClassic;
    if (std::string err = can.open(o); !err.empty()) return fail(err, 3);
    path = o.ifname;
    summary["link"] = {{"interface", o.ifname},
                       {"node", o.node},
                       {"flavor", o.flavor == protocol::can::Flavor::kFd          ? "fd"
                                  : o.flavor == protocol::can::Flavor::kFdCompact ? "fd-compact"
                                                                                  : "classic"}};
  } else {
    if (std::string err = link.open(path, baud); !err.empty()) return fail(err, 3);
    summary["link"] = path;
  }
  std::string serial_write_error;
  // One flush for either transport; false on a hard link error.
  // USB: handle libusb's completions (never a hard error: an unplug is a link outage, handled below).
  auto flushLink = [&]() {
    if (is_usb) {
      usb.service();
      return true;
    }
    if (is_serial && link.isOpen() && !link.flush()) {
      // A write error on a serial device (CDC-ACM unplugged: the tty may fail writes before it reads as hung up)
      // is a lost link, handled by reconnecting like a hang-up, not the end of the session.
      serial_write_error = link.error();
      link.close();
      return true;
    }
    return is_can ? can.flush() : is_serial ? true : link.flush();
  };
  auto linkError = [&]() { return is_can ? can.error() : is_usb ? usb.error() : link.error(); };
  linux_hal::CanBusState can_state = can.state();

  HostSession session = is_can   ? HostSession(static_cast<hal::PacketLink&>(can))
                        : is_usb ? HostSession(static_cast<hal::PacketLink&>(usb))
                                 : HostSession(link);
  session.setEventCallback(logEvent, opt.hooks);
  std::random_device rd;
  uint32_t session_id = rd();
  session.sendHello(session_id, expected);
  flushLink();
  const uint64_t hs_start = linux_hal::monotonicNs();
  while (session.handshake() == HandshakeResult::kPending) {
    if (static_cast<double>(linux_hal::monotonicNs() - hs_start) > opt.handshake_timeout_s * 1e9) {
      return fail("device did not answer the handshake within " + std::to_string(opt.handshake_timeout_s) +
                      " s on " + path + " (wrong port, or not Phalanx firmware?)",
                  4);
    }
    usleep(1000);
    session.poll(linux_hal::monotonicNs());
  }
  if (session.handshake() != HandshakeResult::kOk) return fail(session.handshakeError(), 4);
  const protocol::DeviceLayout& layout = *session.layout();
  summary["device_type"] = layout.name;
  summary["firmware_build_id"] = session.deviceInfo().firmware_build_id;
  summary["firmware_tick_hz"] = session.deviceInfo().tick_rate_hz;
  summary["protocol_version"] = protocol::kProtocolVersion;

  std::string ctl_error;
  std::unique_ptr<Controller> controller;
  if (opt.hooks != nullptr) controller = opt.hooks->makeController(layout, ctl_error);
  if (!controller && !ctl_error.empty()) return fail(ctl_error, 2);
  if (!controller) controller = makeController(layout, opt, ctl_error);
  if (!controller) return fail(ctl_error, 2);
  summary["controller"] = controller->name();
  if (can_classic && controller->usesGainScale()) {
    return fail(std::string("controller '") + controller->name() +
                    "' sends per-finger gain scales in contact, which classic CAN does not carry (docs/protocol.md): "
                    "use @fd or @fd-compact, or --mode transparent",
                2);
  }

  record::CsvRecorder recorder;
  if (!opt.record_csv.empty()) {
    if (std::string err = recorder.open(opt.record_csv, layout, io.have_sync); !err.empty()) return fail(err, 3);
  }

  linux_hal::RealtimeStatus rt;
  if (opt.realtime) {
    rt = linux_hal::setupRealtime(opt.rt_priority);
    if (!rt.warning.empty()) std::fprintf(stderr, "phalanxd: warning: %s\n", rt.warning.c_str());
  } else {
    rt.warning = "real-time scheduling disabled by configuration";
  }
  summary["realtime"] = {{"memory_locked", rt.memory_locked}, {"sched_fifo", rt.fifo_scheduling}};

  // Wait for the first telemetry (bounded like the handshake: a device that answered late on a slow or loaded
  // link also streams late); clear faults left latched by a previous session if asked to.
  const uint64_t first_wait = linux_hal::monotonicNs();
  while (!session.hasTelemetry() &&
         static_cast<double>(linux_hal::monotonicNs() - first_wait) < opt.handshake_timeout_s * 1e9) {
    usleep(500);
    session.poll(linux_hal::monotonicNs());
  }
  if (!session.hasTelemetry()) return fail("device answered the handshake but sends no telemetry", 4);
  if (session.latest().fault_bits != 0) {
    const std::string prior = faultList(session.latest().fault_bits);
    summary["faults_at_start"] = prior;
    if (!opt.clear_faults) return fail("device has latched faults (" + prior + ") and clear_faults is off", 5);
    std::fprintf(stderr, "phalanxd: clearing faults latched before this session: %s\n", prior.c_str());
    session.sendClearFaults();
    flushLink();
  }

  // A model from a geometry file must match the geometry the firmware was built with (fingerprint parameter):
  // the host never silently runs one geometry against firmware made for another (docs/design-tools.md).
  // ParamGet and wait (bounded like the handshake) for its answer; true when it came.
  const auto getParam = [&](uint16_t id) {
    session.sendParamGet(id);
    flushLink();
    const uint64_t t0 = linux_hal::monotonicNs();
    while (!(session.lastParamValid() && session.lastParam().param_id == id) &&
           static_cast<double>(linux_hal::monotonicNs() - t0) < opt.handshake_timeout_s * 1e9) {
      usleep(500);
      session.poll(linux_hal::monotonicNs());
    }
    return session.lastParamValid() && session.lastParam().param_id == id;
  };
  for (const Controller::RequiredParam& rp : controller->requiredParams()) {
    if (!getParam(rp.id)) {
      return fail(rp.what + ": the device did not answer the geometry fingerprint query: refused", 2);
    }
    if (session.lastParam().status != protocol::ParamStatus::kOk) {
      return fail(rp.what + ": the firmware does not report its geometry fingerprint: refused", 2);
    }
    if (session.lastParam().value != rp.value) {
      char fw[32];
      std::snprintf(fw, sizeof fw, "%.0f", static_cast<double>(session.lastParam().value));
      return fail(rp.what + " differs from the firmware's compile-time geometry (fingerprint " + fw +
                      "): build the firmware with this geometry, or run without the file; refused",
                  2);
    }
  }
  for (const auto& [id, value] : controller->startupParams()) {
    session.sendParamSet(id, value);
    flushLink();
    const uint64_t t0 = linux_hal::monotonicNs();
    // Same bound as the handshake: a slow link (emulated, loaded) answers late but does answer.
    while (!session.lastParamValid() &&
           static_cast<double>(linux_hal::monotonicNs() - t0) < opt.handshake_timeout_s * 1e9) {
      usleep(500);
      session.poll(linux_hal::monotonicNs());
    }
    if (!session.lastParamValid()) {
      char what[128];
      std::snprintf(what, sizeof what, "device did not answer start-up parameter 0x%04x within %.1f s", id,
                    opt.handshake_timeout_s);
      return fail(what, 4);
    }
    if (session.lastParam().status != protocol::ParamStatus::kOk) {
      char what[96];
      std::snprintf(what, sizeof what, "device refused start-up parameter 0x%04x (status %d)", id,
                    static_cast<int>(session.lastParam().status));
      return fail(what, 4);
    }
  }
  usleep(static_cast<useconds_t>(controller->startupSettleS() * 1e6));
  session.poll(linux_hal::monotonicNs());
  summary["startup_warnings"] = nlohmann::json::array();
  for (const uint16_t id : controller->startupReadback()) {
    if (!getParam(id) || session.lastParam().status != protocol::ParamStatus::kOk) continue;
    const std::string warning = controller->startupWarning(id, session.lastParam().value);
    if (warning.empty()) continue;
    std::fprintf(stderr, "phalanxd: WARNING: %s\n", warning.c_str());
    summary["startup_warnings"].push_back(warning);
  }

  // Optional Modbus TCP server (docs/modbus.md): its own thread; the loop only publishes and polls, wait-free.
  std::unique_ptr<modbus::Server> mb_server;
  std::unique_ptr<modbus::LoopPort> mb_port;
  if (opt.modbus.enabled) {
    modbus::WriteLimits limits{layout.setpoint_count, layout.setpoint_limit};
    if (opt.modbus.setpoint_limit > 0.0) {
      limits.setpoint_limit = std::min(limits.setpoint_limit, static_cast<float>(opt.modbus.setpoint_limit));
    }
    mb_server = std::make_unique<modbus::Server>(opt.modbus, limits);
    if (std::string err = mb_server->start(); !err.empty()) return fail(err, 3);
    std::fprintf(stderr, "phalanxd: modbus: serving on %s:%u (%s)\n", opt.modbus.address.c_str(), mb_server->port(),
                 opt.modbus.writes_enabled ? "writes enabled" : "read-only");
    mb_port = std::make_unique<modbus::LoopPort>(*mb_server, opt.modbus, static_cast<uint16_t>(layout.type),
                                                 layout.sample_count, layout.setpoint_count);
  }

  const uint64_t period_ns = 1000000000ull / opt.rate_hz;
  const double dt_s = 1.0 / opt.rate_hz;
  Histogram jitter_us(5000);
  Histogram cycle_us(5000);
  uint64_t overruns = 0;
  uint64_t cycles = 0;
  uint64_t cycles_without_telemetry = 0;
  uint64_t host_refused = 0;
  uint64_t commands_unsent_link_lost = 0;  // sends that found the link lost (hot-unplug), within commands_unsent
  uint16_t faults_seen = 0;
  const auto max_cycles = static_cast<uint64_t>(std::llround(opt.seconds * opt.rate_hz));
  linux_hal::PeriodicTimer timer(period_ns);
  const uint64_t start_ns = linux_hal::monotonicNs();
  uint64_t expected_wake_ns = start_ns + period_ns;
  uint64_t next_live_ns = start_ns;
  protocol::Command cmd;
  cmd.channel_count = layout.setpoint_count;
  cmd.timeout_ms = static_cast<uint16_t>(opt.command_timeout_ms);
  for (auto& g : cmd.gain_scale_permille) g = 1000;

  if (opt.hooks != nullptr) {
    if (std::string err = opt.hooks->onStart(layout, summary); !err.empty()) return fail(err, 3);
  }
  SafetyIoConfig safety_cfg;
  safety_cfg.release_debounce_ns = static_cast<uint64_t>(opt.gpio.estop_release_ms * 1e6);
  SafetyIo safety(io.have_estop ? &io.estop : nullptr, io.have_enable ? &io.enable : nullptr, safety_cfg);
  const bool have_safety_io = io.have_estop || io.have_enable;
  constexpr size_t kMaxStopRecords = 256;  // fixed: no allocation in the loop; later stops are counted only
  std::vector<StopRecord> stops;
  stops.reserve(kMaxStopRecords);
  bool awaiting_safe = false;
  bool log_stop = false;
  bool last_pressed = false;
  if (have_safety_io) {
    safety.start(io.estop_open, linux_hal::monotonicNs());
    last_pressed = safety.estopPressed();
    if (safety.stopped()) {
      std::fprintf(stderr, "phalanxd: e-stop: starting STOPPED (%s): devices held safe until a reset (SIGUSR1 or the API's reset)\n",
                   stopCauseName(safety.cause()));
    } else if (io.have_enable) {
      std::fprintf(stderr, "phalanxd: enable: drives enabled\n");
    }
  }
  if (io.have_sync) {
    if (std::string w = io.sync.start(opt.realtime ? std::max(1, opt.rt_priority - 1) : 0); !w.empty()) {
      std::fprintf(stderr, "phalanxd: warning: %s\n", w.c_str());
    }
    std::fprintf(stderr, "phalanxd: sync: pulses at %g Hz on %s\n", io.sync.rateHz(), opt.gpio.sync.c_str());
  }
  if (can_reconnect) std::fprintf(stderr, "phalanxd: control loop started on %s\n", path.c_str());
  // Hot-unplug (usb:, serial:): report, send nothing, reconnect, new handshake, start-up parameters, faults
  // cleared, then new commands (host/include/phalanx/host/link_recovery.h).
  struct DaemonLink final : RecoveryLink {
    bool is_usb;
    linux_hal::UsbLink& usb;
    linux_hal::SerialLink& serial;
    const std::string& path;
    unsigned baud;
    std::string& write_error;
    DaemonLink(bool u, linux_hal::UsbLink& ul, linux_hal::SerialLink& sl, const std::string& p, unsigned b,
               std::string& we)
        : is_usb(u), usb(ul), serial(sl), path(p), baud(b), write_error(we) {}
    bool lost() override { return is_usb ? !usb.connected() : (serial.hungUp() || !serial.isOpen()); }
    void drop() override {
      if (!is_usb) serial.close();  // an open descriptor would keep the ttyACM minor busy
    }
    std::string reopen() override {
      if (is_usb) return usb.reconnect();
      std::string err = serial.open(path, baud);
      if (err.empty()) write_error.clear();
      return err;
    }
    void flush() override {
      if (is_usb) {
        usb.service();
      } else {
        serial.flush();
      }
    }
    std::string describe() override {
      if (!is_usb) {
        if (serial.hungUp()) return "serial port hung up";
        if (serial.isOpen()) return path;
        return write_error.empty() ? "serial port closed" : write_error;
      }
      return usb.connected() ? usb.where() : usb.error();
    }
  } daemon_link(is_usb, usb, link, path, baud, serial_write_error);
  LinkRecoveryOptions rec_opt;
  rec_opt.handshake_timeout_ns = static_cast<uint64_t>(opt.handshake_timeout_s * 1e9);
  rec_opt.clear_faults = opt.clear_faults;
  LinkRecovery recovery(
      daemon_link, session, layout.type, controller->startupParams(), rec_opt, [&rd]() { return static_cast<uint32_t>(rd()); },
      [](const std::string& m) { std::fprintf(stderr, "phalanxd: %s\n", m.c_str()); }, start_ns);
  while (g_stop == 0 && (max_cycles == 0 || cycles < max_cycles) &&
         (opt.hooks == nullptr || !opt.hooks->stopRequested())) {
    const uint32_t missed = timer.wait();
    const uint64_t wake_ns = linux_hal::monotonicNs();
    const double jitter = std::fabs(static_cast<double>(wake_ns) - static_cast<double>(expected_wake_ns)) / 1000.0;
    jitter_us.add(jitter);
    overruns += missed;
    expected_wake_ns += (1 + missed) * period_ns;
    ++cycles;

    const int new_telemetry = session.poll(wake_ns);
    if (can_reconnect) {
      const LinkRecovery::Step st = recovery.step(wake_ns);
      if (st == LinkRecovery::Step::kFailed) {
        summary["link_error"] = recovery.error();
        break;
      }
      if (st == LinkRecovery::Step::kOffline) continue;
    }
    if (new_telemetry == 0) ++cycles_without_telemetry;
    const TelemetryFrame& tel = session.latest();
    faults_seen |= tel.fault_bits;
    const double t_s = static_cast<double>(wake_ns - start_ns) * 1e-9;
    // An explicit reset (SIGUSR1 or the API's reset): clears the daemon's stop if the e-stop allows it, and sends
    // one ClearFaults to the device (its own latched faults; it refuses while its own e-stop is pressed).
    bool reset_request = g_reset != 0;
    if (reset_request) g_reset = 0;
    if (opt.hooks != nullptr && opt.hooks->takeClearFaultsRequest()) reset_request = true;
    if (reset_request) session.sendClearFaults();
    if (have_safety_io) {
      const uint64_t now_ns = linux_hal::monotonicNs();
      if (reset_request && safety.stopped()) {
        if (const char* why = safety.requestReset(now_ns); why != nullptr) {
          std::fprintf(stderr, "phalanxd: e-stop: reset refused at t=%.3f s: %s\n", t_s, why);
        } else {
          std::fprintf(stderr, "phalanxd: e-stop: reset accepted at t=%.3f s: drives enabled, control resumes\n", t_s);
        }
      }
      // Read the e-stop right after the telemetry poll, so the newest telemetry is the device's state when the
      // edge reached the daemon; a stop drops the enable line inside update(), before the safe command goes out.
      if (safety.update(now_ns)) {
        const uint64_t seen_ns = linux_hal::monotonicNs();
        StopRecord r;
        r.cause = safety.cause();
        r.edge_ns = safety.stopEdgeNs();
        r.seen_ns = seen_ns;
        r.seq_at_seen = tel.seq;
        r.device_was_active = (tel.state_flags & protocol::state::kOutputsActive) != 0;
        awaiting_safe = stops.size() < kMaxStopRecords;
        if (awaiting_safe) {
          stops.push_back(r);
          session.watchForSafe(tel.seq);
        }
        log_stop = true;  // after the safe command is out: stderr may be a slow file or pipe
      }
      if (safety.estopPressed() != last_pressed) {
        last_pressed = safety.estopPressed();
        if (!last_pressed) std::fprintf(stderr, "phalanxd: e-stop: released at t=%.3f s (%s)\n", t_s,
                                        safety.stopped() ? "still stopped: a reset is needed" : "running");
      }
    }
    if (awaiting_safe && session.safeSeen()) {
      StopRecord& r = stops.back();
      r.safe_confirmed = true;
      r.safe_rx_ns = session.safeRxNs();
      r.ticks_to_safe = static_cast<uint16_t>(session.safeSeq() - r.seq_at_seen);
      awaiting_safe = false;
      std::fprintf(stderr, "phalanxd: e-stop: device safe %u tick(s) after the edge reached the daemon "
                   "(edge->daemon %.0f us, daemon->safe telemetry %.0f us)\n", r.ticks_to_safe,
                   r.edge_ns != 0 ? static_cast<double>(r.seen_ns - r.edge_ns) / 1000.0 : -1.0,
                   static_cast<double>(r.safe_rx_ns - r.seen_ns) / 1000.0);
    }
    if (safety.stopped()) {
      // Stopped: every cycle commands the safe state; the controller does not run (no integrator wind-up).
      cmd.mode = protocol::Mode::kSafe;
      for (auto& sp : cmd.setpoint) sp = 0.0f;
    } else {
      controller->update(tel, t_s, dt_s, cmd);
    }
    cmd.channel_count = layout.setpoint_count;
    if (mb_port && !safety.stopped()) mb_port->overrideCommand(cmd, wake_ns);
    if (!commandIsSafe(cmd, layout)) {
      ++host_refused;
      cmd.mode = protocol::Mode::kSafe;
      for (auto& s : cmd.setpoint) s = 0.0f;
    }
    if (!session.sendCommand(cmd, linux_hal::monotonicNs()) && can_reconnect && daemon_link.lost()) {
      // The link went away inside this very send (USB: the submit found the device unplugged): part of the
      // outage that the next cycle's recovery step reports, not a full link.
      ++commands_unsent_link_lost;
    }
    if (is_can && can.state() != can_state) {
      std::fprintf(stderr, "phalanxd: CAN bus %s -> %s at t=%.3f s\n", linux_hal::canBusStateName(can_state),
                   linux_hal::canBusStateName(can.state()), t_s);
      can_state = can.state();
    }
    const bool flushed = flushLink();
    if (awaiting_safe && stops.back().sent_ns == 0) stops.back().sent_ns = linux_hal::monotonicNs();
    if (log_stop) {
      log_stop = false;
      std::fprintf(stderr, "phalanxd: E-STOP (%s) at t=%.3f s: enable dropped, devices commanded safe; stopped until reset\n",
                   stopCauseName(safety.cause()), t_s);
    }
    if (!flushed) {
      summary["link_error"] = linkError();
      break;
    }
    recorder.row(t_s, tel, cmd, io.have_sync ? io.sync.pulses() : 0);
    if (opt.hooks != nullptr) opt.hooks->onCycle(wake_ns, t_s, tel, cmd);
    const uint64_t done_ns = linux_hal::monotonicNs();
    cycle_us.add(static_cast<double>(done_ns - wake_ns) / 1000.0);
    if (mb_port) {
      mb_port->publish(tel, cmd, cycles, overruns, jitter, static_cast<double>(done_ns - wake_ns) / 1000.0, wake_ns - start_ns,
                       session.stats().telemetry_lost, modbus::LoopState::kRunning);
    }

    if (opt.live_view && wake_ns >= next_live_ns) {
      next_live_ns = wake_ns + 100000000ull;
      std::fprintf(stderr, "\r\033[K%7.2fs %-11s faults=%s %s", t_s, modeName(tel.mode),
                   faultList(tel.fault_bits).c_str(), controller->liveLine(tel).c_str());
      std::fflush(stderr);
    }
  }
  if (opt.live_view) std::fputc('\n', stderr);

  // Leave the device safe: drives disabled, then an explicit safe command (the device would also time out).
  if (have_safety_io) safety.shutdown();
  if (io.have_sync) io.sync.stop();
  cmd.mode = protocol::Mode::kSafe;
  for (auto& s : cmd.setpoint) s = 0.0f;
  for (int i = 0; i < 3; ++i) {
    session.sendCommand(cmd, linux_hal::monotonicNs());
    flushLink();
    usleep(2000);
  }
  session.poll(linux_hal::monotonicNs());
  recorder.close();
  sim.stop();
  if (mb_server) {
    mb_server->stop();
    summary["modbus"] = mb_server->statsJson();
    summary["modbus"]["cycles_under_modbus_control"] = mb_port->remoteCycles();
    summary["modbus"]["command_timeouts"] = mb_port->remoteTimeouts();
  }

  const LinkStats& s = session.stats();
  summary["seconds"] = static_cast<double>(linux_hal::monotonicNs() - start_ns) * 1e-9;
  summary["rate_hz"] = opt.rate_hz;
  summary["cycles"] = cycles;
  summary["overruns"] = overruns;
  summary["period_jitter"] = histogramJson(jitter_us);
  summary["cycle_time"] = histogramJson(cycle_us);
  summary["round_trip"] = histogramJson(session.roundTripUs());
  summary["telemetry"] = {{"received", s.telemetry_received},
                          {"lost", s.telemetry_lost},
                          {"cycles_without_new_telemetry", cycles_without_telemetry}};
  summary["commands"] = {{"sent", s.commands_sent},
                         {"unsent_link_full", s.commands_unsent - commands_unsent_link_lost},
                         {"unsent_link_lost", commands_unsent_link_lost},
                         {"refused_by_host_limits", host_refused},
                         {"lost_seen_by_device", s.device_cmd_lost},
                         {"rejected_by_device", s.device_rx_errors}};
  summary["host_rx_errors"] = {{"crc", s.host_rx.crc_errors},
                               {"framing", s.host_rx.framing_errors},
                               {"unknown_id", s.host_rx.unknown_id},
                               {"bad_length", s.host_rx.bad_length}};
  // Faults latched while the link was down are read (and cleared) by the reconnect, outside the control cycles.
  if (can_reconnect) faults_seen |= recovery.stats().faults_after_reconnect;
  summary["faults_seen"] = faultList(faults_seen);
  if (can_reconnect) {
    const LinkRecoveryStats& r = recovery.stats();
    summary["outages"] = {{"count", r.outages},  {"reconnects", r.reconnects}, {"cycles_offline", r.cycles_offline},
                          {"max_s", r.max_s},    {"total_s", r.total_s},
                          {"connected_at_end", recovery.phase() == LinkRecovery::Phase::kUp}};
  }
  if (is_usb) {
    const auto& u = usb.stats();
    const auto& r = usb.rxStats();
    summary["usb"] = {{"tx_messages", u.tx_messages},
                      {"tx_completed", u.tx_completed},
                      {"tx_queued", u.tx_queued},
                      {"tx_superseded", u.tx_superseded},
                      {"tx_dropped_busy", u.tx_dropped_busy},
                      {"tx_discarded_unplug", u.tx_discarded_unplug},
                      {"tx_dropped_offline", u.tx_dropped_offline},
                      {"tx_failed", u.tx_failed},
                      {"rx_transfers", u.rx_transfers},
                      {"rx_overflow", u.rx_overflow},
                      {"rx_failed", u.rx_failed},
                      {"disconnects", u.disconnects},
                      {"connects", u.connects},
                      {"reconnect_attempts", u.reconnect_attempts},
                      {"rx_rejected", {{"bad_id", r.bad_id}, {"bad_length", r.bad_length}, {"crc", r.crc}}}};
  }
  if (is_can) {
    const auto& c = can.stats();
    const auto& m = can.mapperStats();
    summary["can"] = {{"state", linux_hal::canBusStateName(can.state())},
                      {"tx_frames", c.tx_frames},
                      {"tx_would_block", c.tx_would_block},
                      {"tx_superseded", c.tx_superseded},
                      {"tx_dropped_queue_full", c.tx_dropped_full},
                      {"tx_dropped_bus_off", c.tx_dropped_bus_off},
                      {"tx_not_representable", c.tx_not_representable},
                      {"tx_refusal", can.lastRefusal() != nullptr ? can.lastRefusal() : ""},
                      {"tx_link_down", c.tx_link_down},
                      {"rx_frames", c.rx_frames},
                      {"rx_kernel_dropped", c.rx_kernel_dropped},
                      {"error_frames", c.error_frames},
                      {"bus_off_events", c.bus_off_events},
                      {"restarts", c.restarts},
                      {"rx_rejected", {{"bad_id", m.bad_id}, {"bad_length", m.bad_length}, {"crc", m.crc},
                                        {"sequence", m.sequence}}}};
  }
  summary["final_mode"] = modeName(session.latest().mode);
  if (have_safety_io || io.have_sync) {
    nlohmann::json g = nlohmann::json::object();
    if (have_safety_io) {
      const SafetyIoCounters& c = safety.counters();
      nlohmann::json list = nlohmann::json::array();
      for (const StopRecord& r : stops) {
        nlohmann::json j = {{"cause", stopCauseName(r.cause)}, {"device_was_active", r.device_was_active},
                            {"safe_confirmed", r.safe_confirmed}};
        if (r.edge_ns != 0) j["edge_to_daemon_us"] = static_cast<double>(r.seen_ns - r.edge_ns) / 1000.0;
        if (r.sent_ns != 0) j["daemon_reaction_us"] = static_cast<double>(r.sent_ns - r.seen_ns) / 1000.0;
        if (r.safe_confirmed) {
          j["daemon_to_safe_telemetry_us"] = static_cast<double>(r.safe_rx_ns - r.seen_ns) / 1000.0;
          j["ticks_to_safe"] = r.ticks_to_safe;
        }
        list.push_back(j);
      }
      g["estop"] = {{"line", opt.gpio.estop}, {"state", safety.stopped() ? "stopped" : "running"},
                    {"cause", stopCauseName(safety.cause())}, {"line_ok", safety.estopLineOk()},
                    {"open_error", io.estop_error}, {"stops", c.stops}, {"presses", c.presses},
                    {"line_lost", c.line_lost}, {"resets", c.resets}, {"resets_refused", c.resets_refused},
                    {"reopen_attempts", c.reopen_attempts}, {"reopened", c.reopened},
                    {"enable_failures", c.enable_failures}, {"release_debounce_ms", opt.gpio.estop_release_ms},
                    {"stop_records", list}};
      if (io.have_enable) g["enable"] = {{"line", opt.gpio.enable}, {"write_failures", c.enable_failures}};
    }
    if (io.have_sync) {
      const linux_hal::SyncPulseStats y = io.sync.stats();
      g["sync"] = {{"line", opt.gpio.sync}, {"rate_hz", io.sync.rateHz()}, {"pulses", y.pulses},
                   {"missed_periods", y.missed}, {"write_errors", y.write_errors},
                   {"edge_late_mean_us", y.mean_late_us}, {"edge_late_max_us", y.max_late_us},
                   {"first_rise_ns", y.first_rise_ns}};
    }
    summary["gpio"] = g;
  }
  if (!opt.record_csv.empty()) summary["recording"] = {{"path", opt.record_csv}, {"rows", recorder.rows()}, {"dropped_rows", recorder.dropped()}};
  nlohmann::json extra = nlohmann::json::object();
  controller->summarize(extra);
  if (!extra.empty()) summary[layout.name] = extra;
  if (opt.hooks != nullptr) opt.hooks->onEnd(summary);
  if (summary.contains("link_error")) {
    std::fprintf(stderr, "phalanxd: session ended by a link error: %s\n", summary["link_error"].get<std::string>().c_str());
    return 6;
  }
  return 0;
}

}  // namespace phalanx::host
