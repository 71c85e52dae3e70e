#include "phalanx/host/device_link.h"

#include "phalanx/host/program_name.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include "phalanx/host/daemon.h"
#include "phalanx/linux/can_link.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/usb_link.h"

extern char** environ;

namespace phalanx::host {
namespace {

std::string selfDir() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return ".";
  buf[n] = 0;
  std::string p(buf);
  const auto slash = p.rfind('/');
  return slash == std::string::npos ? "." : p.substr(0, slash);
}

/// The byte link's descriptor, readable when bytes arrive (none while it is closed: unplugged).
size_t fdToWaitOn(const linux_hal::FdLink& link, pollfd* fds, size_t max) {
  if (!link.isOpen() || max == 0) return 0;
  fds[0] = {link.fd(), POLLIN, 0};
  return 1;
}

/// Tick rate of every board image (firmware/boards/qemu/board_main.cpp, firmware/boards/stm32g474/main.cpp).
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
    // The simulated firmware ticks at the boards' rate (1 kHz, firmware/boards/*/main: kTickHz), or faster with a faster
    // host loop, never at a slower host's rate: the glove's force loop is designed for >= 1 kHz (000 §4.3; issue
    // #3) and at a 100 Hz tick it limit-cycled into current-limit in 5 of 6 sessions with a still hand.
    const std::string hz = std::to_string(std::max(opt.rate_hz, kSimDeviceTickHz));
    std::vector<std::string> args = {exe, "--device", device_name, "--tick-hz", hz, "--seed", seed,
                                     "--scenario", opt.scenario, "--exit-with-parent"};
    if (!opt.sim_truth.empty()) args.insert(args.end(), {"--truth", opt.sim_truth});
    // A real-time session's simulated board runs under SCHED_FIFO too, below the session thread (as the VM lane runs
    // it): it stands in for a board with a CPU of its own, which the host machine's load must not starve (the bench
    // runner's measurement without it, beside stress-ng --cpu 1: 4 800 overruns in 16 s; docs/bench-runner.md).
    if (opt.realtime) args.insert(args.end(), {"--fifo", std::to_string(std::max(1, opt.rt_priority - 10))});
    args.insert(args.end(), opt.sim_args.begin(), opt.sim_args.end());
    const bool instrument = std::find(opt.sim_args.begin(), opt.sim_args.end(), "--instrument") != opt.sim_args.end();
    if (!opt.sim_settings.empty()) {
      args.insert(args.end(), {"--settings", opt.sim_settings, "--settings-layout", std::to_string(opt.sim_settings_layout)});
    }
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
    // Read its first line, and with --instrument the second (bounded wait). The pipe stays open until then: a
    // line written to a closed pipe would kill it.
    std::string line;
    pollfd pfd{out[0], POLLIN, 0};
    const size_t lines = instrument ? 2 : 1;
    while (static_cast<size_t>(std::count(line.begin(), line.end(), '\n')) < lines) {
      if (::poll(&pfd, 1, 5000) <= 0) break;
      char c[256];
      const ssize_t n = ::read(out[0], c, sizeof c);
      if (n <= 0) break;
      line.append(c, static_cast<size_t>(n));
    }
    ::close(out[0]);
    if (line.rfind("PTY ", 0) != 0) return "the simulated firmware did not report its link (got '" + line + "')";
    const size_t eol = line.find('\n');
    pty_path = line.substr(4, eol - 4);
    if (instrument) {
      const std::string second = eol == std::string::npos ? std::string() : line.substr(eol + 1);
      if (second.rfind("instrument: modbus ", 0) != 0) return "the simulated firmware did not report its instrument (got '" + second + "')";
      instrument_line_ = second.substr(0, second.find('\n'));
    }
    return {};
  }
  /// "" while the child runs; how it ended once it has (reaped here).
  std::string exited() {
    if (pid_ <= 0) return {};
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) != pid_) return {};
    pid_ = -1;
    if (WIFSIGNALED(status)) return "the simulated firmware was killed by signal " + std::to_string(WTERMSIG(status));
    return "the simulated firmware exited with code " + std::to_string(WEXITSTATUS(status));
  }
  /// firmware-sim's "instrument: modbus ..." line ("" without --instrument).
  const std::string& instrumentLine() const { return instrument_line_; }
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
  std::string instrument_line_;
};

/// serial:PATH[@baud] — a board's USB CDC-ACM port or a UART adapter. Survives an unplug (reconnects).
class SerialDeviceLink : public DeviceLink {
 public:
  std::string open(const std::string& path, unsigned baud) {
    path_ = path;
    baud_ = baud;
    return link_.open(path, baud);
  }
  HostSession makeSession() override { return HostSession(link_); }
  bool push() override {
    // A write error (CDC-ACM unplugged: the tty may fail writes before it reads as hung up) is a lost link,
    // handled by reconnecting like a hang-up, not the end of the session.
    if (link_.isOpen() && !link_.flush()) {
      write_error_ = link_.error();
      link_.close();
    }
    return true;
  }
  std::string linkError() const override { return link_.error(); }
  bool reconnects() const override { return true; }
  std::string where() const override { return path_; }
  nlohmann::json info() const override { return path_; }
  bool lost() override { return link_.hungUp() || !link_.isOpen(); }
  void drop() override { link_.close(); }  // an open descriptor would keep the ttyACM minor busy
  std::string reopen() override {
    std::string err = link_.open(path_, baud_);
    if (err.empty()) write_error_.clear();
    return err;
  }
  void flush() override { link_.flush(); }
  size_t waitFds(pollfd* fds, size_t max) override { return fdToWaitOn(link_, fds, max); }
  std::string describe() override {
    if (link_.hungUp()) return "serial port hung up";
    if (link_.isOpen()) return path_;
    return write_error_.empty() ? "serial port closed" : write_error_;
  }

 protected:
  linux_hal::SerialLink link_;
  std::string path_;
  unsigned baud_ = 0;
  std::string write_error_;
};

/// sim:NAME — firmware-sim spawned as a child, over a pseudo-terminal exactly as a board's CDC port. Does not
/// reconnect: the child exiting (or its pty hanging up) is the device lost.
class SimDeviceLink : public DeviceLink {
 public:
  std::string open(const RunOptions& opt, const std::string& name) {
    name_ = name;
    // sim:sea_rig is the sea_finger firmware on the §7.1 test-rig plant: it answers as a sea_finger and reports its
    // variant in core parameter 0x0004 (checked by the runner, expectedVariant()).
    expected_ = name == "glove5"                            ? protocol::DeviceType::kGlove5
                : name == "sea_finger" || name == "sea_rig" ? protocol::DeviceType::kSeaFinger
                                                            : protocol::DeviceType::kPantograph;
    if (std::string err = child_.start(opt, name, path_); !err.empty()) return err;
    return link_.open(path_, 0);
  }
  HostSession makeSession() override { return HostSession(link_); }
  protocol::DeviceType expectedDevice() const override { return expected_; }
  int expectedVariant() const override {
    if (name_ == "sea_rig") return protocol::variant::kSeaTestRig;
    return name_ == "sea_finger" ? protocol::variant::kStandard : -1;
  }
  bool push() override { return link_.flush(); }
  std::string linkError() const override { return link_.error(); }
  std::string deviceGone() override {
    if (std::string why = child_.exited(); !why.empty()) return why;
    if (link_.hungUp()) return "the simulated firmware's pseudo-terminal hung up";
    return {};
  }
  std::string where() const override { return path_; }
  /// The pty's path; with firmware-sim's instrument (RunOptions::sim_args) {"pty", "instrument": its line}.
  nlohmann::json info() const override {
    if (child_.instrumentLine().empty()) return path_;
    return {{"pty", path_}, {"instrument", child_.instrumentLine()}};
  }
  void close() override { child_.stop(); }
  size_t waitFds(pollfd* fds, size_t max) override { return fdToWaitOn(link_, fds, max); }

 private:
  SimChild child_;
  linux_hal::SerialLink link_;
  std::string name_, path_;
  protocol::DeviceType expected_ = protocol::DeviceType::kAny;
};

/// can:IF[:node][@fd|@fd-compact|@classic] — SocketCAN.
class CanDeviceLink : public DeviceLink {
 public:
  std::string open(const linux_hal::CanLink::Options& o) {
    opt_ = o;
    if (std::string err = can_.open(o); !err.empty()) return err;
    state_ = can_.state();
    return {};
  }
  HostSession makeSession() override { return HostSession(static_cast<hal::PacketLink&>(can_)); }
  bool push() override { return can_.flush(); }
  std::string linkError() const override { return can_.error(); }
  bool carriesGainScales() const override { return opt_.flavor != protocol::can::Flavor::kClassic; }
  bool inOutage() const override {
    return can_.state() == linux_hal::CanBusState::kBusOff || can_.state() == linux_hal::CanBusState::kDown;
  }
  void afterCycle(double t_s) override {
    if (can_.state() == state_) return;
    std::fprintf(stderr, "%s: CAN bus %s -> %s at t=%.3f s\n", programName(), linux_hal::canBusStateName(state_),
                 linux_hal::canBusStateName(can_.state()), t_s);
    state_ = can_.state();
  }
  size_t waitFds(pollfd* fds, size_t max) override {
    if (can_.fd() < 0 || max == 0) return 0;
    fds[0] = {can_.fd(), POLLIN, 0};
    return 1;
  }
  std::string where() const override { return opt_.ifname; }
  nlohmann::json info() const override {
    return {{"interface", opt_.ifname},
            {"node", opt_.node},
            {"flavor", opt_.flavor == protocol::can::Flavor::kFd          ? "fd"
                       : opt_.flavor == protocol::can::Flavor::kFdCompact ? "fd-compact"
                                                                          : "classic"}};
  }
  void summarize(nlohmann::json& summary) const override {
    const auto& c = can_.stats();
    const auto& m = can_.mapperStats();
    summary["can"] = {{"state", linux_hal::canBusStateName(can_.state())},
                      {"tx_frames", c.tx_frames},
                      {"tx_would_block", c.tx_would_block},
                      {"tx_superseded", c.tx_superseded},
                      {"tx_dropped_queue_full", c.tx_dropped_full},
                      {"tx_dropped_bus_off", c.tx_dropped_bus_off},
                      {"tx_not_representable", c.tx_not_representable},
                      {"tx_refusal", can_.lastRefusal() != nullptr ? can_.lastRefusal() : ""},
                      {"tx_link_down", c.tx_link_down},
                      {"rx_frames", c.rx_frames},
                      {"rx_kernel_dropped", c.rx_kernel_dropped},
                      {"error_frames", c.error_frames},
                      {"bus_off_events", c.bus_off_events},
                      {"restarts", c.restarts},
                      {"rx_rejected", {{"bad_id", m.bad_id}, {"bad_length", m.bad_length}, {"crc", m.crc},
                                        {"sequence", m.sequence}}}};
  }

 private:
  linux_hal::CanLink can_;
  linux_hal::CanLink::Options opt_;
  linux_hal::CanBusState state_ = linux_hal::CanBusState::kActive;
};

/// usb:VID:PID[:serial] — vendor USB bulk through libusb. Survives an unplug (reconnects).
class UsbDeviceLink : public DeviceLink {
 public:
  std::string open(const std::string& spec) {
    spec_ = spec;
    linux_hal::UsbLink::Options o;
    linux_hal::parseUsbDevice(spec, o);  // validated before
    if (std::string err = usb_.open(o); !err.empty()) return err;
    std::fprintf(stderr, "%s: USB device %s at %s\n", programName(), spec.substr(4).c_str(), usb_.where().c_str());
    return {};
  }
  HostSession makeSession() override { return HostSession(static_cast<hal::PacketLink&>(usb_)); }
  /// Handles libusb's completions; never a hard error: an unplug is a link outage (lost()).
  bool push() override {
    usb_.service();
    return true;
  }
  std::string linkError() const override { return usb_.error(); }
  bool reconnects() const override { return true; }
  std::string where() const override { return spec_; }
  nlohmann::json info() const override { return {{"usb", spec_.substr(4)}, {"where", usb_.where()}}; }
  bool lost() override { return !usb_.connected(); }
  std::string reopen() override { return usb_.reconnect(); }
  void flush() override { usb_.service(); }
  /// libusb's own descriptors (its event and timer descriptors and the device's usbfs node): readiness on any
  /// of them means completions to handle, which the session's poll does (UsbLink::receive → service).
  size_t waitFds(pollfd* fds, size_t max) override { return usb_.pollFds(fds, max); }
  std::string describe() override { return usb_.connected() ? usb_.where() : usb_.error(); }
  void summarize(nlohmann::json& summary) const override {
    const auto& u = usb_.stats();
    const auto& r = usb_.rxStats();
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

 private:
  linux_hal::UsbLink usb_;
  std::string spec_;
};

template <class L, class... A>
std::unique_ptr<DeviceLink> openAs(std::string& error, A&&... args) {
  auto link = std::make_unique<L>();
  error = link->open(std::forward<A>(args)...);
  if (!error.empty()) return nullptr;
  return link;
}

}  // namespace

std::unique_ptr<DeviceLink> openDeviceLink(const RunOptions& opt, std::string& error) {
  const std::string& spec = opt.device;
  const std::string rest = spec.substr(spec.find(':') + 1);
  if (spec.rfind("sim:", 0) == 0) return openAs<SimDeviceLink>(error, opt, rest);
  if (spec.rfind("usb:", 0) == 0) return openAs<UsbDeviceLink>(error, spec);
  if (spec.rfind("can:", 0) == 0) {
    linux_hal::CanLink::Options o;
    parseCanDevice(spec, o);  // validated before
    return openAs<CanDeviceLink>(error, o);
  }
  // serial:PATH[@baud]
  std::string path = rest;
  unsigned baud = 0;
  if (const auto at = path.find('@'); at != std::string::npos) {
    char* end = nullptr;
    const unsigned long b = std::strtoul(path.c_str() + at + 1, &end, 10);
    if (at + 1 == path.size() || *end != 0 || b == 0 || b > 4000000) {
      error = "device: bad baud rate in '" + spec + "'";
      return nullptr;
    }
    baud = static_cast<unsigned>(b);
    path = path.substr(0, at);
  }
  return openAs<SerialDeviceLink>(error, path, baud);
}

std::string handshakeDevice(DeviceLink& link, HostSession& session, double timeout_s) {
  return session.handshakeWithin(timeout_s, link.expectedDevice(), link.where(), [&] { link.push(); },
                                 [&] { return link.deviceGone(); });
}

}  // namespace phalanx::host
