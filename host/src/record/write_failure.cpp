#include "phalanx/host/record/write_failure.h"

#include <unistd.h>

#include <cerrno>
#include <cstdio>

namespace phalanx::host::record {

void WriteFailure::set(const std::string& what) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!error_.empty()) return;
    error_ = what;
  }
  failed_.store(true, std::memory_order_release);
  // program_invocation_short_name (glibc): phalanxd or phalanx, whichever runs the session.
  std::fprintf(stderr, "%s: error: %s\n", program_invocation_short_name, what.c_str());
  std::fflush(stderr);
}

std::string WriteFailure::error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

std::size_t writeFully(int fd, const void* data, std::size_t n, int& err_no) {
  const auto* p = static_cast<const uint8_t*>(data);
  std::size_t done = 0;
  err_no = 0;
  while (done < n) {
    const ssize_t w = ::write(fd, p + done, n - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) {
      err_no = w < 0 ? errno : ENOSPC;
      break;
    }
    done += static_cast<std::size_t>(w);
  }
  return done;
}

int syncData(int fd) {
  if (::fdatasync(fd) == 0) return 0;
  return (errno == EINVAL || errno == EROFS) ? 0 : errno;
}

}  // namespace phalanx::host::record
