#pragma once
/// Progress of a long command-line run on stderr, with an estimate of the time left:
///   pen-wall --sweep: 32 % (12/37 runs), 14.2 s elapsed, ~30 s left
/// On a terminal the line is rewritten in place; in a log (not a terminal) each report is its own line. At most one
/// report every interval_s and the first once interval_s have passed, so a run shorter than that prints nothing.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <utility>

namespace phalanx::host {

class ProgressLine {
 public:
  /// interval_s <= 0: silent.
  explicit ProgressLine(std::string what, double interval_s = 5.0, std::FILE* out = stderr)
      : what_(std::move(what)), interval_s_(interval_s), out_(out), tty_(isatty(fileno(out)) != 0),
        t0_(std::chrono::steady_clock::now()) {}
  ~ProgressLine() { finish(); }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  double elapsedS() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  }

  /// fraction: share of the work done, 0..1 (negative: unknown, no estimate); detail: what was done, "12/37 runs".
  void update(double fraction, const std::string& detail = "") {
    if (interval_s_ <= 0.0) return;
    const double t = elapsedS();
    if (t - last_s_ < interval_s_) return;
    last_s_ = t;
    const std::string line = format(what_, t, fraction, detail);
    std::fprintf(out_, tty_ ? "\r\033[K%s" : "%s\n", line.c_str());
    std::fflush(out_);
    pending_newline_ = tty_;
  }

  /// Ends an in-place line (call before printing anything else on stderr).
  void finish() {
    if (!pending_newline_) return;
    std::fputc('\n', out_);
    pending_newline_ = false;
  }

  /// The report line (without a newline). The time left is elapsed · (1 − f) / f: the rate so far continued.
  static std::string format(const std::string& what, double elapsed_s, double fraction, const std::string& detail) {
    char b[64];
    std::string s = what + ": ";
    if (fraction >= 0.0) {
      std::snprintf(b, sizeof b, "%.0f %%", 100.0 * std::min(fraction, 1.0));
      s += b;
      if (!detail.empty()) s += " (" + detail + ")";
      s += ", ";
    } else if (!detail.empty()) {
      s += detail + ", ";
    }
    std::snprintf(b, sizeof b, "%.1f s elapsed", elapsed_s);
    s += b;
    if (fraction > 0.0 && fraction < 1.0) s += ", ~" + duration(elapsed_s * (1.0 - fraction) / fraction) + " left";
    return s;
  }

  /// "42 s", "3 min 10 s", "1 h 05 min".
  static std::string duration(double s) {
    char b[64];
    if (s < 90.0) std::snprintf(b, sizeof b, "%.0f s", s);
    else if (s < 3600.0) std::snprintf(b, sizeof b, "%d min %02d s", static_cast<int>(s / 60.0), static_cast<int>(s) % 60);
    else std::snprintf(b, sizeof b, "%d h %02d min", static_cast<int>(s / 3600.0), static_cast<int>(s / 60.0) % 60);
    return b;
  }

 private:
  std::string what_;
  double interval_s_;
  std::FILE* out_;
  bool tty_;
  std::chrono::steady_clock::time_point t0_;
  double last_s_ = 0.0;
  bool pending_newline_ = false;
};

}  // namespace phalanx::host
