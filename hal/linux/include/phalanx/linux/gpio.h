#pragma once
/// GPIO lines of a bench through libgpiod (Debian 12: libgpiod 1.6, the v1 API): the emergency-stop input, the
/// drive-enable output and the motion-capture sync pulse output. Nothing here blocks the real-time loop: the e-stop
/// is read with non-blocking reads of its edge-event descriptor, the enable line is one ioctl per write, and the
/// sync pulse runs on its own thread. docs/gpio.md describes the wiring, the options and the measured figures.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

struct gpiod_chip;
struct gpiod_line;

namespace phalanx::linux_hal {

/// One line: a chip (gpiochipN, /dev/gpiochipN, its label or its number, as libgpiod's gpiod_chip_open_lookup
/// takes it) and a line offset on it.
struct GpioLineSpec {
  std::string chip;
  unsigned offset = 0;
  bool active_low = false;  ///< logical "active" (pressed / enabled) is the physical low level
};

/// Parse "CHIP:LINE[:active-low]" (e.g. "gpiochip0:5", "/dev/gpiochip1:0:active-low"). Returns an empty string
/// or what is wrong with it.
std::string parseGpioLine(const std::string& text, GpioLineSpec& out);
/// Parse "CHIP:LINE@HZ" for the sync pulse output, HZ in [kSyncMinHz, kSyncMaxHz].
std::string parseGpioSync(const std::string& text, GpioLineSpec& out, double& rate_hz);
constexpr double kSyncMinHz = 0.1;
/// 1 kHz: a half-period of 0.5 ms is the shortest the pulse thread keeps on a PREEMPT_DYNAMIC desktop kernel
/// within its lateness budget (docs/gpio.md).
constexpr double kSyncMaxHz = 1000.0;

/// What one non-blocking poll of the e-stop input found.
struct EstopSample {
  bool ok = false;              ///< false: the line is lost (not open, read error, chip gone) - counts as pressed
  bool active = false;          ///< logical level now (pressed)
  bool press_seen = false;      ///< an edge to active since the previous poll (even if released again since)
  uint64_t press_edge_ns = 0;   ///< kernel timestamp (CLOCK_MONOTONIC) of the first such edge, 0 if none
  uint64_t release_edge_ns = 0; ///< kernel timestamp of the last edge to inactive since the previous poll, 0 if none
  int error = 0;                ///< errno of the failure when !ok
};

/// The seam between the daemon's e-stop logic and the kernel: libgpiod below, a mock in unit tests.
class EstopSource {
 public:
  virtual ~EstopSource() = default;
  /// Non-blocking: drain the pending edge events and read the level.
  virtual EstopSample poll() = 0;
  /// Try to open the line again after it was lost (not real-time: opens the chip). Returns true when open.
  virtual bool reopen() = 0;
};

/// The seam for a digital output (drive enable).
class DigitalOutput {
 public:
  virtual ~DigitalOutput() = default;
  /// Set the logical level; false on failure (line lost).
  virtual bool write(bool active) = 0;
};

/// E-stop input requested for both edges (edge events carry kernel timestamps, CLOCK_MONOTONIC).
class GpioEstopInput : public EstopSource {
 public:
  GpioEstopInput() = default;
  GpioEstopInput(const GpioEstopInput&) = delete;
  GpioEstopInput& operator=(const GpioEstopInput&) = delete;
  ~GpioEstopInput() override;
  /// Request the line. Returns an empty string or what went wrong (the caller counts that as pressed).
  std::string open(const GpioLineSpec& spec, const char* consumer);
  void close();
  bool isOpen() const { return line_ != nullptr; }
  EstopSample poll() override;
  bool reopen() override;
  const std::string& lastError() const { return last_error_; }

 private:
  GpioLineSpec spec_;
  std::string consumer_;
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  int fd_ = -1;
  std::string last_error_;
};

/// Output line (drive enable), requested inactive.
class GpioOutput : public DigitalOutput {
 public:
  GpioOutput() = default;
  GpioOutput(const GpioOutput&) = delete;
  GpioOutput& operator=(const GpioOutput&) = delete;
  ~GpioOutput() override;
  std::string open(const GpioLineSpec& spec, const char* consumer);
  void close();
  bool isOpen() const { return line_ != nullptr; }
  bool write(bool active) override;
  int lastErrno() const { return last_errno_; }

 private:
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  int last_errno_ = 0;
};

struct SyncPulseStats {
  uint64_t pulses = 0;          ///< rising edges emitted
  uint64_t missed = 0;          ///< periods skipped because the thread woke more than a whole period late
  uint64_t write_errors = 0;
  double max_late_us = 0.0;     ///< worst lateness of an edge write after its scheduled time
  double mean_late_us = 0.0;
  uint64_t first_rise_ns = 0;   ///< CLOCK_MONOTONIC of the first rising edge's write
};

/// Square wave at rate_hz (50 % duty) on an output line, from its own thread: rising edges on the absolute grid
/// first_rise_ns + k / rate_hz (clock_nanosleep TIMER_ABSTIME, no drift). The loop reads pulses() (one atomic
/// load) to tag each recorded cycle with the number of rising edges so far: the mocap frame index.
class GpioSyncPulse {
 public:
  GpioSyncPulse() = default;
  GpioSyncPulse(const GpioSyncPulse&) = delete;
  GpioSyncPulse& operator=(const GpioSyncPulse&) = delete;
  ~GpioSyncPulse();
  /// Request the line (low). Returns an empty string or what went wrong.
  std::string open(const GpioLineSpec& spec, double rate_hz, const char* consumer);
  /// Start the thread; SCHED_FIFO at rt_priority when > 0 (else the creating thread's policy is inherited).
  std::string start(int rt_priority);
  /// Stop the thread, leave the line low, release it.
  void stop();
  uint64_t pulses() const { return pulses_.load(std::memory_order_relaxed); }
  /// Valid after stop() (or racy snapshot while running).
  SyncPulseStats stats() const;
  double rateHz() const { return rate_hz_; }

 private:
  void run();
  GpioOutput out_;
  double rate_hz_ = 0.0;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> pulses_{0};
  uint64_t missed_ = 0;
  uint64_t write_errors_ = 0;
  double max_late_ns_ = 0.0;
  double sum_late_ns_ = 0.0;
  uint64_t edges_ = 0;
  uint64_t first_rise_ns_ = 0;
};

}  // namespace phalanx::linux_hal
