// firmware-sim: the firmware core and a device app running on the simulated board in real time, with the
// device's physical plant inside, talking to the host over a pseudo-terminal exactly as a USB CDC board would.
// With --can IF it talks over SocketCAN instead (classic CAN or CAN-FD, docs/protocol.md "CAN and CAN-FD").
// With --ffs DIR it is a USB device through FunctionFS (vendor interface, bulk endpoints; docs/usb.md), with
// --tty PATH it talks over an existing serial device (the USB gadget's CDC-ACM port /dev/ttyGS0), reopened after a
// hang-up (USB unplug).
// Prints "PTY <path>" (or "CAN <if> node <n> <fd|fd-compact|classic>", "USB <dir>", "TTY <path>") on stdout once the link
// is up; logs events and safe-state entries on stderr.
// With --instrument tcp:PORT | rtu one quantity of the plant's truth is also served as a Modbus amplifier (a reference
// instrument the host does not simulate; docs/modbus.md "firmware-sim's instrument"), announced by an
// "instrument: modbus ..." line on stdout after the link's.
#include <signal.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "phalanx/fw/core.h"
#include "phalanx/fw_sim/sim_device.h"
#include "phalanx/linux/can_link.h"
#include "phalanx/linux/fd_link.h"
#include "phalanx/linux/ffs_link.h"
#include "phalanx/linux/modbus_instrument.h"
#include "phalanx/linux/realtime.h"
#include "phalanx/sim/board.h"
#include "phalanx/sim/sim_flash.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;

/// Tick timing of this process (docs/vm-lane.md "Why the VM missed 1 kHz"): how late each tick woke after its
/// deadline, and how long its own work took. 10 µs buckets up to 10 ms; later values land in the last bucket.
class TickTimes {
 public:
  void add(uint64_t late_ns, uint64_t busy_ns) {
    ++late_[bucket(late_ns)];
    ++busy_[bucket(busy_ns)];
    ++count_;
    if (late_ns > max_late_ns_) max_late_ns_ = late_ns;
    if (busy_ns > max_busy_ns_) max_busy_ns_ = busy_ns;
  }
  void print() const {
    std::fprintf(stderr,
                 "firmware-sim: tick timing (us) wake_late p50=%u p99=%u max=%llu; work p50=%u p99=%u max=%llu\n",
                 percentile(late_, 0.5), percentile(late_, 0.99), static_cast<unsigned long long>(max_late_ns_ / 1000),
                 percentile(busy_, 0.5), percentile(busy_, 0.99), static_cast<unsigned long long>(max_busy_ns_ / 1000));
  }

 private:
  static constexpr unsigned kBuckets = 1001;  // 10 µs each: 0 .. 10 ms, the last one open-ended
  static unsigned bucket(uint64_t ns) {
    const uint64_t b = ns / 10000;
    return b < kBuckets - 1 ? static_cast<unsigned>(b) : kBuckets - 1;
  }
  unsigned percentile(const uint32_t (&h)[kBuckets], double p) const {
    if (count_ == 0) return 0;
    const auto want = static_cast<uint64_t>(p * static_cast<double>(count_));
    uint64_t seen = 0;
    for (unsigned i = 0; i < kBuckets; ++i) {
      seen += h[i];
      if (seen > want) return (i + 1) * 10;  // upper edge of the bucket
    }
    return kBuckets * 10;
  }
  uint32_t late_[kBuckets] = {};
  uint32_t busy_[kBuckets] = {};
  uint64_t count_ = 0;
  uint64_t max_late_ns_ = 0;
  uint64_t max_busy_ns_ = 0;
};
void onSignal(int) { g_stop = 1; }

/// --truth FILE: the plant's ground truth after every plant step, one CSV row per tick, keyed by the device clock
/// that the tick's telemetry carries (device_time_us), so a test joins it with the daemon's --record CSV.
class TruthLog {
 public:
  ~TruthLog() {
    if (f_ != nullptr) std::fclose(f_);
  }
  std::string open(const std::string& path, const phalanx::fw_sim::SimDevice& dev) {
    f_ = std::fopen(path.c_str(), "w");
    if (f_ == nullptr) return "--truth " + path + ": " + std::strerror(errno);
    std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
    std::fputs("device_time_us", f_);
    const std::vector<std::string> columns = dev.truthColumns();
    for (const std::string& c : columns) std::fprintf(f_, ",truth_%s", c.c_str());
    std::fputc('\n', f_);
    return {};
  }
  bool isOpen() const { return f_ != nullptr; }
  /// values: this tick's dev.truthValues(), in truthColumns() order.
  void write(uint64_t device_time_us, const std::vector<double>& values) {
    if (f_ == nullptr) return;
    std::fprintf(f_, "%llu", static_cast<unsigned long long>(device_time_us));
    for (double v : values) std::fprintf(f_, ",%.9g", v);
    std::fputc('\n', f_);
  }
  /// false when a write failed (disk full): reported at exit, the truth file is then incomplete.
  bool close() {
    if (f_ == nullptr) return true;
    const bool ok = std::ferror(f_) == 0 && std::fclose(f_) == 0;
    f_ = nullptr;
    return ok;
  }

 private:
  std::FILE* f_ = nullptr;
};

/// --instrument: one truth quantity served as a Modbus amplifier, set every tick from the values --truth writes
/// (plus Gaussian noise of --instrument-noise N*m, N, ... seeded from --seed) and quantised by the register map.
class TruthInstrument {
 public:
  void addOptions(CLI::App& cli) {
    cli.add_option("--instrument", o_.where,
                   "serve one truth quantity as a Modbus amplifier: tcp:PORT (127.0.0.1; 0: a free port) or rtu (a new "
                   "pseudo-terminal); prints \"instrument: modbus ...\" (docs/modbus.md)");
    cli.add_option("--instrument-signal", o_.signal,
                   "the truth column served (default: glove5 pad_force_index_N, sea_rig load_cell_mcp_Nm, sea_finger "
                   "sea_torque_mcp_Nm, pantograph hand_force_x_N)");
    cli.add_option("--instrument-noise", o_.noise_sd,
                   "Gaussian noise on the served value: its standard deviation in the signal's SI unit (seeded from --seed)");
    cli.add_option("--instrument-delay-ms", o_.delay_ms,
                   "serve each tick's value this much later (a slow amplifier or filter; whole ticks; the bench runner's "
                   "alignment test)")
        ->check(CLI::Range(0.0, 1000.0));
    cli.add_option("--instrument-map", o_.map,
                   "register map, key=value,... of unit_id, table (input|holding), address, type "
                   "(int16|uint16|int32|uint32|float32), word_order (big|little), scale, offset (default int32, scale 1e-5)");
  }
  /// Check the options against the device; "" or the problem (a bad argument: exit 2).
  std::string configure(const phalanx::fw_sim::SimDevice& dev, const std::string& device, uint32_t seed, unsigned tick_hz) {
    const Options& o = o_;
    if (o.where.empty()) {
      if (!o.signal.empty() || o.noise_sd != 0.0 || !o.map.empty() || o.delay_ms != 0.0) {
        return "--instrument-signal, --instrument-noise, --instrument-delay-ms and --instrument-map need --instrument";
      }
      return {};
    }
    if (o.where == "rtu") {
      map_.transport = "rtu";
    } else if (o.where.rfind("tcp:", 0) == 0) {
      const std::string port = o.where.substr(4);
      if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
          std::stoul(port) > 65535ul) {
        return "--instrument '" + o.where + "': the port must be an integer in [0, 65535] (0: a free port)";
      }
      map_.transport = "tcp";
      port_ = static_cast<unsigned>(std::stoul(port));
    } else {
      return "--instrument '" + o.where + "': unknown transport (tcp:PORT on 127.0.0.1, or rtu on a new pseudo-terminal)";
    }
    if (!std::isfinite(o.noise_sd) || o.noise_sd < 0.0) return "--instrument-noise: must be a finite standard deviation >= 0";
    const std::vector<std::string> columns = dev.truthColumns();
    signal_ = o.signal.empty() ? dev.instrumentSignal() : o.signal.rfind("truth_", 0) == 0 ? o.signal.substr(6) : o.signal;
    index_ = columns.size();
    for (size_t i = 0; i < columns.size(); ++i) {
      if (columns[i] == signal_) index_ = i;
    }
    if (index_ == columns.size()) {
      std::string list;
      for (const std::string& c : columns) list += (list.empty() ? "" : ", ") + c;
      return "--instrument-signal '" + o.signal + "': " + device + "'s truth has no such quantity (" + list + ")";
    }
    // The simulated amplifier of docs/modbus.md: int32 counts of 1e-5 SI units (10 µN·m on a torque cell).
    map_.type = "int32";
    map_.scale = 1e-5;
    map_.unit = unitOf(signal_);
    if (!o.map.empty()) {
      if (const std::string err = phalanx::linux_hal::parseRegisterMap(o.map, "--instrument-map", map_); !err.empty()) {
        return err;
      }
    }
    noise_sd_ = o.noise_sd;
    delay_ms_ = o.delay_ms;
    delay_line_.assign(static_cast<size_t>(std::lround(o.delay_ms * tick_hz / 1000.0)) + 1, 0.0);
    std::seed_seq seq{seed, 0x696e7374u};  // "inst": a stream of its own, apart from the plant's sensor noise
    rng_.seed(seq);
    enabled_ = true;
    server_ = std::make_unique<phalanx::linux_hal::SimInstrumentServer>(map_);
    return {};
  }
  bool enabled() const { return enabled_; }
  /// Start serving; "" or the problem (exit 3, like a link that cannot be opened). line: where a client finds it.
  std::string start(std::string& line) {
    std::string where;
    if (map_.transport == "tcp") {
      if (std::string err = server_->startTcp(port_); !err.empty()) return err;
      where = "tcp 127.0.0.1:" + std::to_string(server_->port());
    } else {
      std::string path;
      if (std::string err = server_->startRtu(path); !err.empty()) return err;
      where = "rtu " + path;
    }
    char noise[32];
    std::snprintf(noise, sizeof noise, "%.9g", noise_sd_);
    line = "instrument: modbus " + where + " " + phalanx::linux_hal::describeRegisterMap(map_) + " signal " + signal_ +
           " noise " + noise;
    if (delay_ms_ > 0.0) {
      char delay[32];
      std::snprintf(delay, sizeof delay, " delay_ms %.9g", delay_ms_);
      line += delay;
    }
    return {};
  }
  /// truth: this tick's truthValues().
  void update(const std::vector<double>& truth) {
    if (!server_) return;
    double v = truth[index_];
    if (noise_sd_ > 0.0) v += noise_sd_ * gauss_(rng_);
    // The delay line: the value served is the one of delay_line_.size() - 1 ticks ago (the first tick's until then).
    delay_line_[delay_at_] = v;
    delay_at_ = (delay_at_ + 1) % delay_line_.size();
    if (delay_filled_ < delay_line_.size()) ++delay_filled_;
    server_->set(delay_filled_ < delay_line_.size() ? delay_line_[0] : delay_line_[delay_at_]);
  }
  void stop() {
    if (server_) server_->stop();
  }
  uint64_t requests() const { return server_ ? server_->requests() : 0; }

 private:
  /// The SI unit a truth column's name ends in (truthColumns' convention), as the register map's label.
  static std::string unitOf(const std::string& column) {
    auto ends = [&](const char* suffix) {
      const size_t n = std::strlen(suffix);
      return column.size() > n && column.compare(column.size() - n, n, suffix) == 0;
    };
    if (ends("_Nm")) return "N*m";
    if (ends("_N")) return "N";
    if (ends("_rad")) return "rad";
    if (ends("_m")) return "m";
    return "";
  }
  struct Options {
    std::string where;   ///< tcp:PORT | rtu ("": no instrument)
    std::string signal;  ///< a truth column ("": the device's instrumentSignal())
    double noise_sd = 0.0;
    double delay_ms = 0.0;
    std::string map;     ///< --instrument-map key=value,...
  };

  Options o_;
  bool enabled_ = false;
  phalanx::linux_hal::InstrumentConfig map_{};
  unsigned port_ = 0;
  std::string signal_;
  size_t index_ = 0;
  double delay_ms_ = 0.0;
  std::vector<double> delay_line_;  ///< the last ticks' values, a ring (one slot: no delay)
  size_t delay_at_ = 0, delay_filled_ = 0;
  double noise_sd_ = 0.0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
  std::unique_ptr<phalanx::linux_hal::SimInstrumentServer> server_;
};

class LogObserver : public phalanx::fw::CoreObserver {
 public:
  void onEvent(const phalanx::protocol::Event& e) override {
    std::fprintf(stderr, "firmware-sim: EVENT t_us=%u code=%u channel=%u detail=%u value=%g\n", e.time_us,
                 static_cast<unsigned>(e.code), e.channel, e.detail, static_cast<double>(e.value));
  }
};

/// At exit: the USB or CAN link's own counters (nullptr: that link was not used).
void printLinkStats(const phalanx::linux_hal::FfsLink* ffs, const phalanx::linux_hal::CanLink* can) {
  using namespace phalanx;
  if (ffs != nullptr) {
    const auto& f = ffs->stats();
    const auto& r = ffs->rxStats();
    std::fprintf(stderr,
                 "firmware-sim: usb tx_submitted=%llu tx_completed=%llu tx_dropped_full=%llu tx_dropped_offline=%llu "
                 "tx_dropped_host_idle=%llu tx_cancelled=%llu tx_failed=%llu rx_transfers=%llu rx_overflow=%llu enables=%llu disables=%llu rx_bad_id=%u "
                 "rx_bad_length=%u rx_crc=%u\n",
                 static_cast<unsigned long long>(f.tx_submitted), static_cast<unsigned long long>(f.tx_completed),
                 static_cast<unsigned long long>(f.tx_dropped_full), static_cast<unsigned long long>(f.tx_dropped_offline),
                 static_cast<unsigned long long>(f.tx_dropped_host_idle), static_cast<unsigned long long>(f.tx_cancelled),
                 static_cast<unsigned long long>(f.tx_failed), static_cast<unsigned long long>(f.rx_transfers),
                 static_cast<unsigned long long>(f.rx_overflow), static_cast<unsigned long long>(f.enables),
                 static_cast<unsigned long long>(f.disables), r.bad_id, r.bad_length, r.crc);
  }
  if (can != nullptr) {
    const auto& c = can->stats();
    const auto& m = can->mapperStats();
    std::fprintf(stderr,
                 "firmware-sim: can state=%s tx_frames=%llu tx_would_block=%llu tx_superseded=%llu tx_dropped_full=%llu "
                 "tx_dropped_bus_off=%llu rx_frames=%llu rx_kernel_dropped=%llu error_frames=%llu bus_off=%llu "
                 "restarts=%llu rx_bad_id=%u rx_bad_length=%u rx_crc=%u rx_sequence=%u\n",
                 linux_hal::canBusStateName(can->state()), static_cast<unsigned long long>(c.tx_frames),
                 static_cast<unsigned long long>(c.tx_would_block), static_cast<unsigned long long>(c.tx_superseded),
                 static_cast<unsigned long long>(c.tx_dropped_full),
                 static_cast<unsigned long long>(c.tx_dropped_bus_off), static_cast<unsigned long long>(c.rx_frames),
                 static_cast<unsigned long long>(c.rx_kernel_dropped), static_cast<unsigned long long>(c.error_frames),
                 static_cast<unsigned long long>(c.bus_off_events), static_cast<unsigned long long>(c.restarts),
                 m.bad_id, m.bad_length, m.crc, m.sequence);
  }
}

/// The simulated board's code flash (--flash): the STM32G474's geometry (256 pages of 2 KiB), image slot 0 in
/// pages 0-119, the boot record's two copies in pages 120-121, slot 1 in pages 128-247 (bank 2). firmware-sim
/// cannot execute the ARM code a slot holds: "booting" a slot is taking its image's identity (the build id the
/// HelloAck reports) after the same checks the boot stage makes (docs/firmware-update.md).
class CodeFlash {
 public:
  static constexpr size_t kPages = 256, kPageSize = 2048;
  bool enabled() const { return enabled_; }

  /// Open the file; when no slot holds a valid image and `provision` is given, write it into slot 0 first.
  std::string open(const std::string& path, const std::string& provision, uint8_t device_type) {
    enabled_ = true;
    layout_.slot_first_page[0] = 0;
    layout_.slot_first_page[1] = 128;
    layout_.slot_pages = 120;
    layout_.record_first_page = 120;
    layout_.board = static_cast<uint8_t>(phalanx::image::BoardId::kStm32g474);
    layout_.device_type = device_type;
    if (std::string err = flash_.open(path); !err.empty()) return "--flash " + err;
    boot_ = phalanx::fw::bootStage(flash_, layout_);
    if (!boot_.valid && !provision.empty()) {
      if (std::string err = provisionSlot0(provision); !err.empty()) return "--flash-provision " + provision + ": " + err;
      boot_ = phalanx::fw::bootStage(flash_, layout_);
    }
    if (!boot_.valid) {
      return "--flash " + path + ": neither slot holds a valid " + std::string(phalanx::protocol::layoutFor(
                 static_cast<phalanx::protocol::DeviceType>(device_type))->name) +
             " image for the stm32g474 board (give --flash-provision IMAGE)";
    }
    updater_.emplace(flash_, layout_, boot_);
    return {};
  }
  /// The board resets (after a committed update): the boot stage chooses again, the updater starts afresh.
  void reboot() {
    boot_ = phalanx::fw::bootStage(flash_, layout_);
    updater_.emplace(flash_, layout_, boot_);
  }
  void report(const char* when) const {
    std::fprintf(stderr, "firmware-sim: %s: slot %u build %08x (boot record seq %u)%s%s%s\n", when, boot_.slot,
                 static_cast<unsigned>(boot_.build_id), static_cast<unsigned>(boot_.record_sequence),
                 boot_.fell_back ? ", fell back: the record's slot did not verify" : "",
                 boot_.trial ? ", on trial: not yet confirmed" : "",
                 boot_.trial_failed ? ", back from a trial that was not confirmed" : "");
  }
  phalanx::fw::FirmwareUpdate* updater() { return updater_ ? &*updater_ : nullptr; }
  const phalanx::fw::BootChoice& boot() const { return boot_; }
  phalanx::sim::FileFlash& flash() { return flash_; }

 private:
  std::string provisionSlot0(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr) return std::strerror(errno);
    std::vector<uint8_t> bytes(layout_.slot_pages * kPageSize + 1);
    const size_t n = std::fread(bytes.data(), 1, bytes.size(), f);
    std::fclose(f);
    if (n == 0 || n > layout_.slot_pages * kPageSize) return std::to_string(n) + " bytes: empty or larger than a slot";
    bytes.resize((n + 7) / 8 * 8, 0xFF);
    for (size_t at = 0; at < bytes.size(); at += kPageSize) {
      const size_t take = bytes.size() - at < kPageSize ? bytes.size() - at : kPageSize;
      if (!flash_.erase(at / kPageSize) || !flash_.program(at / kPageSize, 0, &bytes[at], take)) return "flash write failed";
    }
    phalanx::image::ImageInfo info;
    if (!phalanx::fw::verifySlot(flash_, layout_, 0, &info)) {
      return "not a valid image for this board and device (image-info block, board stm32g474, device type, CRC)";
    }
    phalanx::fw::BootRecord rec;
    rec.slot = 0;
    rec.image_size = info.image_size;
    rec.image_crc32 = info.image_crc32;
    rec.build_id = info.build_id;
    return phalanx::fw::writeBootRecord(flash_, layout_, rec) ? "" : "boot record write failed";
  }

  bool enabled_ = false;
  phalanx::sim::FileFlash flash_{kPages, kPageSize};
  phalanx::fw::UpdateLayout layout_;
  phalanx::fw::BootChoice boot_;
  std::optional<phalanx::fw::FirmwareUpdate> updater_;
};

/// Every command-line option of firmware-sim.
struct SimOptions {
  std::string device = "glove5";
  unsigned tick_hz = 1000;
  unsigned substeps = 10;
  phalanx::fw_sim::SimDeviceOptions dev;
  bool exit_with_parent = false;
  double seconds = 0.0;
  std::string can_if;
  unsigned can_node = 1;
  std::string can_mode = "fd";
  std::string ffs_dir, tty_path, truth_path;
  int fifo = 0;
  std::string settings_path;
  unsigned settings_layout = 0;
  std::vector<std::string> inject_args;
  std::string flash_path, flash_provision;
  long long power_cut_after = -1;
};

void addOptions(CLI::App& cli, SimOptions& o, TruthInstrument& instrument) {
  cli.add_option("--device", o.device, "glove5 | sea_finger | sea_rig | pantograph");
  cli.add_option("--tick-hz", o.tick_hz, "firmware tick rate")->check(CLI::Range(100u, 10000u));
  cli.add_option("--substeps", o.substeps, "plant integration steps per tick")->check(CLI::Range(1u, 100u));
  cli.add_option("--seed", o.dev.seed, "plant noise seed");
  cli.add_option("--scenario", o.dev.scenario, "simulated user: still|close-open|grasp|random|spastic (sea_finger: a stretch reflex)|press (pantograph: push along +x)")
      ->check(CLI::IsMember({"still", "close-open", "grasp", "random", "spastic", "press"}));
  cli.add_option("--seconds", o.seconds, "stop after this long (0: until SIGTERM)")->check(CLI::Range(0.0, 86400.0));
  cli.add_option("--can", o.can_if, "talk over this SocketCAN interface instead of a pseudo-terminal");
  cli.add_option("--node", o.can_node, "CAN node id")->check(CLI::Range(1u, 63u));
  cli.add_option("--can-mode", o.can_mode, "fd (one message per CAN-FD frame) | fd-compact (short CAN-FD command and telemetry "
                 "frames, docs/protocol.md) | classic (compact 8-byte frames)")
      ->check(CLI::IsMember({"fd", "fd-compact", "classic"}));
  cli.add_option("--ffs", o.ffs_dir, "be a USB device: a mounted FunctionFS instance (e.g. /dev/ffs-phalanx)");
  cli.add_option("--tty", o.tty_path, "talk over this serial device (e.g. the gadget's /dev/ttyGS0)");
  cli.add_option("--truth", o.truth_path, "write the plant's ground truth after every tick to this CSV (docs/sdk.md \"Plant truth\")");
  instrument.addOptions(cli);
  cli.add_flag("--exit-with-parent", o.exit_with_parent, "terminate when the parent process dies");
  cli.add_option("--fifo", o.fifo,
                 "run under SCHED_FIFO at this priority with memory locked (0: off): a simulated board has a CPU of its "
                 "own, which the host machine's load must not starve (the bench runner asks for 70)")
      ->check(CLI::Range(0, 99));
  cli.add_option("--settings", o.settings_path,
                 "the board's settings flash, kept in this file (created when absent): a restart is a power cycle "
                 "(docs/params.md)");
  cli.add_option("--settings-layout", o.settings_layout,
                 "be the firmware that writes this settings layout version (0: the newest; tests play an older "
                 "firmware before an update with it)")
      ->check(CLI::Range(0u, 255u));
  cli.add_option("--inject", o.inject_args,
                 "fail an input on the board's clock (repeatable): sensor-range@T, sensor-stuck@T, estop@T+D (seconds; "
                 "docs/soak.md)");
  cli.add_option("--flash", o.flash_path,
                 "the board's code flash (two image slots and a boot record, the STM32G474's geometry), kept in this file: "
                 "firmware update over the link; the HelloAck's build id is the booted slot's (docs/firmware-update.md)");
  cli.add_option("--flash-provision", o.flash_provision,
                 "when no slot of --flash holds a valid image, write this one into slot 0 first (as the factory would)");
  cli.add_option("--flash-power-cut-after", o.power_cut_after,
                 "lose power after this many more bytes are programmed into --flash: the process ends at once with status 75")
      ->check(CLI::Range(0ll, 1ll << 30));
}

/// The board's link to the host: a pseudo-terminal (the default), a serial device (--tty, reopened after a hang-up),
/// SocketCAN (--can) or a FunctionFS USB device (--ffs).
class HostLink {
 public:
  explicit HostLink(const SimOptions& o) : o_(o), can_(!o.can_if.empty()), ffs_(!o.ffs_dir.empty()), tty_(!o.tty_path.empty()) {}
  /// More than one of --can, --ffs, --tty.
  bool ambiguous() const { return static_cast<int>(can_) + static_cast<int>(ffs_) + static_cast<int>(tty_) > 1; }

  /// "" or why the link did not open.
  std::string open(phalanx::protocol::DeviceType type) {
    using namespace phalanx;
    if (ffs_) return ffs.open(o_.ffs_dir);
    if (tty_) return tty.open(o_.tty_path, 0);
    if (!can_) return pty.open();
    linux_hal::CanLink::Options c;
    c.ifname = o_.can_if;
    c.node = static_cast<uint8_t>(o_.can_node);
    c.flavor = o_.can_mode == "classic"      ? protocol::can::Flavor::kClassic
               : o_.can_mode == "fd-compact" ? protocol::can::Flavor::kFdCompact
                                             : protocol::can::Flavor::kFd;
    c.role = protocol::can::Role::kDevice;
    std::string err = can.open(c);
    if (err.empty()) can.setDevice(type, static_cast<uint16_t>(o_.tick_hz));
    return err;
  }

  /// The byte stream the board's UART stands for (unused when the protocol runs over packets()).
  phalanx::linux_hal::FdLink& stream() {
    return tty_ ? static_cast<phalanx::linux_hal::FdLink&>(tty) : static_cast<phalanx::linux_hal::FdLink&>(pty);
  }
  phalanx::hal::PacketLink* packets() {
    if (can_) return &can;
    if (ffs_) return &ffs;
    return nullptr;
  }

  /// The line the tools wait for on stdout once the link is up.
  void announce() const {
    if (can_) {
      std::printf("CAN %s node %u %s\n", o_.can_if.c_str(), o_.can_node, o_.can_mode.c_str());
    } else if (ffs_) {
      std::printf("USB %s\n", o_.ffs_dir.c_str());
    } else if (tty_) {
      std::printf("TTY %s\n", o_.tty_path.c_str());
    } else {
      std::printf("PTY %s\n", pty.slavePath().c_str());
    }
  }

  /// Before tick n: the USB function's state, and a hung-up tty reopened (every 50 ms until it is back).
  void service(uint64_t n, uint64_t now_us) {
    if (ffs_) {
      ffs.service();
      if (ffs.online() != ffs_online_) {
        ffs_online_ = ffs.online();
        std::fprintf(stderr, "firmware-sim: USB %s t_us=%llu\n", ffs_online_ ? "enabled (host configured us)" : "disabled (unplugged)",
                     static_cast<unsigned long long>(now_us));
      }
    }
    if (!tty_ || !tty.hungUp() || n < tty_reopen_at_) return;
    // USB unplug hangs the gadget's tty up: this descriptor is dead for good; reopen until the port is back.
    if (tty.isOpen()) {
      std::fprintf(stderr, "firmware-sim: TTY %s hung up t_us=%llu\n", o_.tty_path.c_str(), static_cast<unsigned long long>(now_us));
    }
    tty.close();
    if (tty.open(o_.tty_path, 0).empty()) {
      std::fprintf(stderr, "firmware-sim: TTY %s reopened t_us=%llu\n", o_.tty_path.c_str(), static_cast<unsigned long long>(now_us));
    } else {
      tty_reopen_at_ = n + o_.tick_hz / 20;
    }
  }

  /// After the tick: what it queued goes out (FunctionFS submits as it is written).
  void flush() {
    if (can_) {
      can.flush();
    } else if (tty_) {
      tty.flush();
    } else if (!ffs_) {
      pty.flush();
    }
  }

  void printStats() const { printLinkStats(ffs_ ? &ffs : nullptr, can_ ? &can : nullptr); }

 private:
  const SimOptions& o_;
  const bool can_, ffs_, tty_;
  phalanx::linux_hal::PtyMaster pty;
  phalanx::linux_hal::SerialLink tty;
  phalanx::linux_hal::CanLink can;
  phalanx::linux_hal::FfsLink ffs;
  bool ffs_online_ = false;
  uint64_t tty_reopen_at_ = 0;
};

/// The board's settings store on its flash (--settings; loaded by the firmware core when it starts), or nullptr;
/// error says why it could not be used.
std::unique_ptr<phalanx::fw::SettingsStore> openSettings(const SimOptions& o, phalanx::fw_sim::SimDevice& dev,
                                                         phalanx::sim::FileFlash& flash, std::string& error) {
  if (o.settings_path.empty()) return nullptr;
  if (const std::string err = flash.open(o.settings_path); !err.empty()) {
    error = "--settings " + err;
    return nullptr;
  }
  auto store = std::make_unique<phalanx::fw::SettingsStore>(flash, 0, static_cast<uint16_t>(o.settings_layout));
  if (store->layoutVersion(dev.app()) == 0) {
    error = "--settings-layout " + std::to_string(o.settings_layout) + ": " + o.device + " has no such settings layout";
    return nullptr;
  }
  return store;
}

/// What the firmware core found in the settings flash when it started.
void reportSettings(const phalanx::fw::SettingsStore& store, phalanx::fw_sim::SimDevice& dev) {
  const phalanx::fw::SettingsReport& r = store.lastLoad();
  std::fprintf(stderr, "firmware-sim: settings layout v%u: %s (record v%u seq %u) applied=%u refused=%u dropped=%u\n",
               store.layoutVersion(dev.app()), phalanx::fw::settingsLoadName(r.result), r.record_version,
               static_cast<unsigned>(r.sequence), r.applied, r.refused, r.dropped);
}

/// The running board: plant, sensors, firmware core and link, one tick at a time.
struct RunningBoard {
  const SimOptions& o;
  phalanx::fw_sim::SimDevice& dev;
  phalanx::sim::SimBoard& board;
  HostLink& link;
  phalanx::fw_sim::FaultInjector& injector;
  TruthLog& truth;
  TruthInstrument& instrument;
  CodeFlash& code_flash;
  phalanx::fw::CoreConfig& cfg;
  std::optional<phalanx::fw::FirmwareCore>& core;
  LogObserver& observer;
  std::vector<double> truth_values;
  uint64_t period_us = 1000000u / o.tick_hz;
  bool was_active = false;

  /// Tick n (1 ms at 1 kHz): physics, injected faults, truth, the link's upkeep, the firmware, a reset after an
  /// update, the link's output and the safe-state report.
  void tick(uint64_t n) {
    dev.plant().advance(static_cast<double>(period_us) * 1e-6 / o.substeps, o.substeps, board.io());
    board.clock().advanceUs(period_us);
    const uint64_t now_us = board.clock().nowUs();
    injector.apply(now_us, board.io(), stderr);
    if (truth.isOpen() || instrument.enabled()) {
      // One truth per tick for both: the instrument serves what the truth file says, before this tick's telemetry.
      dev.truthValues(truth_values.data());
      truth.write(now_us, truth_values);
      instrument.update(truth_values);
    }
    const uint64_t deadline_us = core->commandDeadlineUs();
    link.service(n, now_us);
    core->tick();
    if (code_flash.enabled() && code_flash.flash().powerLost()) {
      std::fprintf(stderr, "firmware-sim: power lost (--flash-power-cut-after) t_us=%llu\n", static_cast<unsigned long long>(now_us));
      std::_Exit(75);  // as a board losing power: nothing more is written or flushed
    }
    if (cfg.update != nullptr && cfg.update->rebootRequested()) resetAfterUpdate();
    link.flush();
    // Observe the power stage itself (the simulated H-bridges), not the core's opinion of it.
    const bool active = board.io().pwm_enabled;
    if (was_active && !active) {
      std::fprintf(stderr, "firmware-sim: SAFE t_us=%llu deadline_us=%llu period_us=%llu faults=0x%04x\n",
                   static_cast<unsigned long long>(now_us), static_cast<unsigned long long>(deadline_us),
                   static_cast<unsigned long long>(period_us), core->faultBits());
    }
    was_active = active;
  }

  /// The board resets into the image the update committed (outputs off first).
  void resetAfterUpdate() {
    board.board().pwm->disableAll();
    code_flash.reboot();
    cfg.firmware_build_id = code_flash.boot().build_id;
    cfg.update = code_flash.updater();
    core.emplace(board.board(), dev.app(), cfg);
    core->setObserver(&observer);
    code_flash.report("reset after the update, boot");
  }

  void printSummary(uint64_t overruns) const {
    std::fprintf(stderr,
                 "firmware-sim: stopped ticks=%u overruns=%llu commands=%u rejected=%u cmd_lost=%u cmd_stale=%u rx_crc=%u "
                 "rx_framing=%u rx_invalid=%u rx_wrong_direction=%u tx_dropped=%u faults=0x%04x\n",
                 core->counters().ticks, static_cast<unsigned long long>(overruns), core->counters().commands_applied,
                 core->counters().commands_rejected, core->counters().cmd_lost, core->counters().cmd_stale,
                 core->rxStats().crc_errors, core->rxStats().framing_errors, core->counters().frames_invalid,
                 core->counters().frames_wrong_direction, core->counters().tx_dropped, core->faultBits());
  }
};

int fail(int code, const std::string& what) {
  std::fprintf(stderr, "firmware-sim: error: %s\n", what.c_str());
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace phalanx;
  CLI::App cli{"firmware-sim - Phalanx firmware on the simulated board, linked over a pseudo-terminal"};
  SimOptions o;
  TruthInstrument instrument;
  addOptions(cli, o, instrument);
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return cli.exit(e);
  }
  if (o.exit_with_parent) prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (o.fifo > 0) {  // before any thread starts: the instrument's server thread inherits it
    const linux_hal::RealtimeStatus rt = linux_hal::setupRealtime(o.fifo);
    if (!rt.warning.empty()) std::fprintf(stderr, "firmware-sim: warning: %s\n", rt.warning.c_str());
  }
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  std::string error;
  auto dev = fw_sim::makeSimDevice(o.device, o.dev, error);
  if (!dev) return fail(2, error);
  std::vector<fw_sim::Injection> schedule;
  for (const std::string& a : o.inject_args) {
    fw_sim::Injection j;
    if (const std::string err = fw_sim::parseInjection(a, j); !err.empty()) return fail(2, err);
    schedule.push_back(j);
  }
  fw_sim::FaultInjector injector(std::move(schedule), dev->injectableSensor());
  TruthLog truth;
  if (!o.truth_path.empty()) {
    if (const std::string err = truth.open(o.truth_path, *dev); !err.empty()) return fail(2, err);
  }
  if (const std::string err = instrument.configure(*dev, o.device, o.dev.seed, o.tick_hz); !err.empty()) return fail(2, err);
  HostLink link(o);
  if (link.ambiguous()) return fail(2, "--can, --ffs and --tty exclude each other");
  if (const std::string err = link.open(dev->app().layout().type); !err.empty()) return fail(3, err);
  sim::SimBoard board(dev->pwmCount(), dev->adcCount(), dev->encoderCount(), link.stream());
  board.board().packets = link.packets();
  // Two 512-byte pages (two slots of one record each), as the boards reserve for settings.
  sim::FileFlash settings_flash(2, 512);
  std::unique_ptr<fw::SettingsStore> settings = openSettings(o, *dev, settings_flash, error);
  if (!error.empty()) return fail(2, error);
  CodeFlash code_flash;
  if (!o.flash_path.empty()) {
    if (const std::string err = code_flash.open(o.flash_path, o.flash_provision, static_cast<uint8_t>(dev->app().layout().type));
        !err.empty()) {
      return fail(2, err);
    }
    if (o.power_cut_after >= 0) code_flash.flash().cutPowerAfter(static_cast<size_t>(o.power_cut_after));
  } else if (!o.flash_provision.empty() || o.power_cut_after >= 0) {
    return fail(2, "--flash-provision and --flash-power-cut-after need --flash");
  }
  fw::CoreConfig cfg;
  cfg.settings = settings.get();
  cfg.tick_rate_hz = static_cast<uint16_t>(o.tick_hz);
  cfg.firmware_build_id = code_flash.enabled() ? code_flash.boot().build_id : PHALANX_BUILD_ID;
  cfg.update = code_flash.updater();
  cfg.device_variant = dev->variant();  // sea_rig: the sea_finger firmware on the test rig
  std::optional<fw::FirmwareCore> core;  // re-made when the board resets after an update
  core.emplace(board.board(), dev->app(), cfg);
  LogObserver observer;
  core->setObserver(&observer);
  if (code_flash.enabled()) code_flash.report("boot");
  if (settings) reportSettings(*settings, *dev);

  RunningBoard sim{o, *dev, board, link, injector, truth, instrument, code_flash, cfg, core, observer,
            std::vector<double>(dev->truthColumns().size(), 0.0)};
  link.announce();
  if (instrument.enabled()) {
    // The first tick's truth is served from the start, never a value the plant did not have.
    dev->truthValues(sim.truth_values.data());
    instrument.update(sim.truth_values);
    std::string line;
    if (const std::string err = instrument.start(line); !err.empty()) return fail(3, "--instrument: " + err);
    std::printf("%s\n", line.c_str());
  }
  std::fflush(stdout);

  linux_hal::PeriodicTimer timer(sim.period_us * 1000u);
  uint64_t overruns = 0;
  const auto max_ticks = static_cast<uint64_t>(o.seconds * o.tick_hz);
  static TickTimes tick_times;  // static: 8 KB, off the stack
  for (uint64_t n = 0; g_stop == 0 && (max_ticks == 0 || n < max_ticks); ++n) {
    overruns += timer.wait();
    const uint64_t woke_ns = linux_hal::monotonicNs();
    sim.tick(n);
    tick_times.add(woke_ns - timer.lastDeadlineNs(), linux_hal::monotonicNs() - woke_ns);
  }
  board.board().pwm->disableAll();
  dev->app().safe();
  sim.printSummary(overruns);
  tick_times.print();
  if (instrument.enabled()) {
    std::fprintf(stderr, "firmware-sim: instrument requests=%llu\n", static_cast<unsigned long long>(instrument.requests()));
    instrument.stop();
  }
  link.printStats();
  if (!truth.close()) return fail(1, "--truth " + o.truth_path + ": a write failed; the file is incomplete");
  return 0;
}
