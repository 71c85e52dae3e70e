#include "phalanx/linux/gpio.h"

#include <fcntl.h>
#include <gpiod.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>

#include "phalanx/linux/realtime.h"

namespace phalanx::linux_hal {
namespace {

bool parseUnsigned(const std::string& s, unsigned long max, unsigned long& out) {
  if (s.empty() || s.size() > 9) return false;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
  }
  out = std::strtoul(s.c_str(), nullptr, 10);
  return out <= max;
}

std::string openLine(const GpioLineSpec& spec, gpiod_chip*& chip, gpiod_line*& line) {
  chip = gpiod_chip_open_lookup(spec.chip.c_str());
  if (chip == nullptr) return "cannot open GPIO chip '" + spec.chip + "': " + std::strerror(errno);
  if (spec.offset >= gpiod_chip_num_lines(chip)) {
    const std::string n = std::to_string(gpiod_chip_num_lines(chip));
    gpiod_chip_close(chip);
    chip = nullptr;
    return "GPIO chip '" + spec.chip + "' has " + n + " lines, no line " + std::to_string(spec.offset);
  }
  line = gpiod_chip_get_line(chip, spec.offset);
  if (line == nullptr) {
    const std::string err = std::strerror(errno);
    gpiod_chip_close(chip);
    chip = nullptr;
    return "cannot get line " + std::to_string(spec.offset) + " of '" + spec.chip + "': " + err;
  }
  return {};
}

uint64_t tsNs(const timespec& ts) {
  return static_cast<uint64_t>(ts.tv_sec) * 1000000000ull + static_cast<uint64_t>(ts.tv_nsec);
}

timespec nsTs(uint64_t ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1000000000ull);
  ts.tv_nsec = static_cast<long>(ns % 1000000000ull);
  return ts;
}

}  // namespace

std::string parseGpioLine(const std::string& text, GpioLineSpec& out) {
  GpioLineSpec spec;
  std::string rest = text;
  const std::string suffix = ":active-low";
  if (rest.size() > suffix.size() && rest.compare(rest.size() - suffix.size(), suffix.size(), suffix) == 0) {
    spec.active_low = true;
    rest.resize(rest.size() - suffix.size());
  }
  const auto colon = rest.rfind(':');
  if (colon == std::string::npos || colon == 0) {
    return "'" + text + "' is not CHIP:LINE[:active-low] (e.g. gpiochip0:5)";
  }
  unsigned long offset = 0;
  if (!parseUnsigned(rest.substr(colon + 1), 1023, offset)) {
    return "'" + text + "': line '" + rest.substr(colon + 1) + "' is not a line number (0..1023)";
  }
  spec.chip = rest.substr(0, colon);
  spec.offset = static_cast<unsigned>(offset);
  out = spec;
  return {};
}

std::string parseGpioSync(const std::string& text, GpioLineSpec& out, double& rate_hz) {
  const auto at = text.rfind('@');
  if (at == std::string::npos) return "'" + text + "' is not CHIP:LINE@HZ (e.g. gpiochip0:2@480)";
  const std::string hz = text.substr(at + 1);
  char* end = nullptr;
  const double r = std::strtod(hz.c_str(), &end);
  if (hz.empty() || end == nullptr || *end != 0 || !std::isfinite(r) || r < kSyncMinHz || r > kSyncMaxHz) {
    char range[64];
    std::snprintf(range, sizeof range, "%g..%g", kSyncMinHz, kSyncMaxHz);
    return "'" + text + "': rate '" + hz + "' is not a number of Hz in " + range;
  }
  GpioLineSpec spec;
  if (std::string err = parseGpioLine(text.substr(0, at), spec); !err.empty()) return err;
  out = spec;
  rate_hz = r;
  return {};
}

// ---------------------------------------------------------------- e-stop input

GpioEstopInput::~GpioEstopInput() { close(); }

std::string GpioEstopInput::open(const GpioLineSpec& spec, const char* consumer) {
  close();
  spec_ = spec;
  consumer_ = consumer;
  if (std::string err = openLine(spec, chip_, line_); !err.empty()) return last_error_ = err;
  const int flags = spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_both_edges_events_flags(line_, consumer, flags) != 0) {
    const std::string err = "cannot request e-stop line " + spec.chip + ":" + std::to_string(spec.offset) +
                            " for edge events: " + std::strerror(errno);
    close();
    return last_error_ = err;
  }
  fd_ = gpiod_line_event_get_fd(line_);
  // Non-blocking reads: poll() drains what is pending and never waits.
  const int fl = fd_ >= 0 ? fcntl(fd_, F_GETFL) : -1;
  if (fl < 0 || fcntl(fd_, F_SETFL, fl | O_NONBLOCK) != 0) {
    const std::string err = std::string("e-stop line: cannot make its event descriptor non-blocking: ") + std::strerror(errno);
    close();
    return last_error_ = err;
  }
  last_error_.clear();
  return {};
}

void GpioEstopInput::close() {
  if (line_ != nullptr) gpiod_line_release(line_);
  if (chip_ != nullptr) gpiod_chip_close(chip_);
  line_ = nullptr;
  chip_ = nullptr;
  fd_ = -1;
}

bool GpioEstopInput::reopen() {
  if (spec_.chip.empty()) return false;
  return open(spec_, consumer_.c_str()).empty();
}

EstopSample GpioEstopInput::poll() {
  EstopSample s;
  if (line_ == nullptr) {
    s.error = ENODEV;
    return s;
  }
  // Drain the edge events (bounded: 16 per read, at most 4 reads - more than 64 edges in one period is a bouncing
  // contact; what is left is read next cycle and the level read below is authoritative anyway).
  gpiod_line_event ev[16];
  for (int round = 0; round < 4; ++round) {
    const int n = gpiod_line_event_read_fd_multiple(fd_, ev, 16);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      s.error = errno;
      return s;  // ENODEV when the chip went away: lost, counts as pressed
    }
    for (int i = 0; i < n; ++i) {
      const uint64_t t = tsNs(ev[i].ts);
      if (ev[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE) {
        if (!s.press_seen) s.press_edge_ns = t;
        s.press_seen = true;
      } else {
        s.release_edge_ns = t;
      }
    }
    if (n < 16) break;
  }
  const int v = gpiod_line_get_value(line_);
  if (v < 0) {
    s.error = errno;
    return s;
  }
  s.ok = true;
  s.active = v != 0;
  return s;
}

// ---------------------------------------------------------------- outputs

GpioOutput::~GpioOutput() { close(); }

std::string GpioOutput::open(const GpioLineSpec& spec, const char* consumer) {
  close();
  if (std::string err = openLine(spec, chip_, line_); !err.empty()) return err;
  const int flags = spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags(line_, consumer, flags, 0) != 0) {
    const std::string err = "cannot request output line " + spec.chip + ":" + std::to_string(spec.offset) + ": " +
                            std::strerror(errno);
    close();
    return err;
  }
  return {};
}

void GpioOutput::close() {
  if (line_ != nullptr) gpiod_line_release(line_);
  if (chip_ != nullptr) gpiod_chip_close(chip_);
  line_ = nullptr;
  chip_ = nullptr;
}

bool GpioOutput::write(bool active) {
  if (line_ == nullptr) {
    last_errno_ = ENODEV;
    return false;
  }
  if (gpiod_line_set_value(line_, active ? 1 : 0) != 0) {
    last_errno_ = errno;
    return false;
  }
  return true;
}

// ---------------------------------------------------------------- sync pulse

GpioSyncPulse::~GpioSyncPulse() { stop(); }

std::string GpioSyncPulse::open(const GpioLineSpec& spec, double rate_hz, const char* consumer) {
  if (!(rate_hz >= kSyncMinHz && rate_hz <= kSyncMaxHz)) return "sync pulse rate out of range";
  rate_hz_ = rate_hz;
  return out_.open(spec, consumer);
}

std::string GpioSyncPulse::start(int rt_priority) {
  if (!out_.isOpen()) return "sync pulse line is not open";
  if (thread_.joinable()) return {};
  stop_.store(false);
  thread_ = std::thread([this] { run(); });
  if (rt_priority > 0) {
    sched_param sp{};
    sp.sched_priority = rt_priority;
    if (pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &sp) != 0) {
      return "sync pulse thread runs without SCHED_FIFO (no permission)";  // a warning: the pulses still run
    }
  }
  return {};
}

void GpioSyncPulse::stop() {
  if (thread_.joinable()) {
    stop_.store(true);
    thread_.join();
  }
  if (out_.isOpen()) {
    out_.write(false);
    out_.close();
  }
}

SyncPulseStats GpioSyncPulse::stats() const {
  SyncPulseStats s;
  s.pulses = pulses_.load();
  s.missed = missed_;
  s.write_errors = write_errors_;
  s.max_late_us = max_late_ns_ / 1000.0;
  s.mean_late_us = edges_ > 0 ? sum_late_ns_ / static_cast<double>(edges_) / 1000.0 : 0.0;
  s.first_rise_ns = first_rise_ns_;
  return s;
}

void GpioSyncPulse::run() {
  // Edge k (even: rising, odd: falling) is due at t0 + k * half_period, computed from k (no accumulated error).
  const double half_ns = 0.5e9 / rate_hz_;
  const uint64_t t0 = monotonicNs() + 2000000ull;  // 2 ms: the first edge on the grid, not mid-set-up
  uint64_t k = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    const uint64_t due = t0 + static_cast<uint64_t>(std::llround(static_cast<double>(k) * half_ns));
    const timespec ts = nsTs(due);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
    const bool rising = (k % 2) == 0;
    if (!out_.write(rising)) {
      ++write_errors_;
      if (write_errors_ >= 3) break;  // the line is gone: stop pulsing (reported in the summary)
    }
    const uint64_t now = monotonicNs();
    const double late = static_cast<double>(now - due);
    if (late > max_late_ns_) max_late_ns_ = late;
    sum_late_ns_ += late;
    ++edges_;
    if (rising) {
      if (first_rise_ns_ == 0) first_rise_ns_ = now;
      pulses_.fetch_add(1, std::memory_order_relaxed);
    }
    ++k;
    // Woke more than a whole period late (a loaded machine): skip the missed periods rather than bursting them out;
    // keep the phase (k stays even at a rising edge) so the grid is unchanged.
    const uint64_t next_due = t0 + static_cast<uint64_t>(std::llround(static_cast<double>(k) * half_ns));
    if (now > next_due + static_cast<uint64_t>(2.0 * half_ns)) {
      const auto behind = static_cast<uint64_t>(static_cast<double>(now - next_due) / (2.0 * half_ns));
      k += 2 * behind;
      missed_ += behind;
    }
  }
}

}  // namespace phalanx::linux_hal
