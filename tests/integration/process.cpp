#include "process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <climits>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace phalanx::test {

std::string binPath(const std::string& name) { return std::string(PHALANX_BIN_DIR) + "/" + name; }

Process::Process(const std::vector<std::string>& argv) {
  int out[2];
  int err[2];
  if (pipe2(out, O_CLOEXEC) != 0 || pipe2(err, O_CLOEXEC) != 0) throw std::runtime_error("pipe");
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, out[1], 1);
  posix_spawn_file_actions_adddup2(&fa, err[1], 2);
  std::vector<char*> args;
  std::vector<std::string> copy = argv;
  for (auto& a : copy) args.push_back(a.data());
  args.push_back(nullptr);
  if (posix_spawn(&pid_, args[0], &fa, nullptr, args.data(), environ) != 0) throw std::runtime_error("spawn " + argv[0]);
  posix_spawn_file_actions_destroy(&fa);
  close(out[1]);
  close(err[1]);
  out_ = out[0];
  err_ = err[0];
  fcntl(out_, F_SETFL, O_NONBLOCK);
  fcntl(err_, F_SETFL, O_NONBLOCK);
}

Process::~Process() {
  if (!exited_ && pid_ > 0) {
    kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
  }
  if (out_ >= 0) close(out_);
  if (err_ >= 0) close(err_);
}

void Process::drain() {
  char buf[4096];
  for (int fd : {out_, err_}) {
    for (;;) {
      const ssize_t n = read(fd, buf, sizeof buf);
      if (n <= 0) break;
      (fd == out_ ? out_text_ : err_text_).append(buf, static_cast<size_t>(n));
    }
  }
}

std::string Process::readStdoutLine(int timeout_ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    drain();
    const size_t nl = out_text_.find('\n', out_read_);
    if (nl != std::string::npos) {
      std::string line = out_text_.substr(out_read_, nl - out_read_);
      out_read_ = nl + 1;
      return line;
    }
    if (std::chrono::steady_clock::now() > end) return {};
    pollfd p{out_, POLLIN, 0};
    poll(&p, 1, 10);
  }
}

void Process::signal(int sig) {
  if (!exited_) kill(pid_, sig);
}

int Process::wait(int timeout_ms) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (!exited_) {
    drain();
    const pid_t r = waitpid(pid_, &status_, WNOHANG);
    if (r == pid_) {
      exited_ = true;
      break;
    }
    if (std::chrono::steady_clock::now() > end) return INT_MIN;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  drain();
  return WIFEXITED(status_) ? WEXITSTATUS(status_) : -WTERMSIG(status_);
}

const std::string& Process::stdoutText() {
  drain();
  return out_text_;
}
const std::string& Process::stderrText() {
  drain();
  return err_text_;
}

}  // namespace phalanx::test
