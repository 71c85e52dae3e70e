#pragma once
// Child processes for the multi-process tests: spawn with captured stdout/stderr, read lines, signal, reap.
#include <sys/types.h>

#include <string>
#include <vector>

namespace phalanx::test {

class Process {
 public:
  explicit Process(const std::vector<std::string>& argv);
  ~Process();
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  /// Next stdout line, waiting up to timeout_ms; empty string on timeout/EOF.
  std::string readStdoutLine(int timeout_ms);
  void signal(int sig);
  /// Wait for exit up to timeout_ms; returns the exit status (or -signal), or INT_MIN on timeout.
  int wait(int timeout_ms);
  /// Everything written to stdout / stderr so far (drains the pipes).
  const std::string& stdoutText();
  const std::string& stderrText();
  pid_t pid() const { return pid_; }

 private:
  void drain();
  pid_t pid_ = -1;
  int out_ = -1;
  int err_ = -1;
  std::string out_text_;
  std::string err_text_;
  size_t out_read_ = 0;
  bool exited_ = false;
  int status_ = 0;
};

std::string binPath(const std::string& name);

}  // namespace phalanx::test
