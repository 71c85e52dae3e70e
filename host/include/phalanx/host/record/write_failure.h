#pragma once
/// What the session recorders (the CSV recorder and the `.phrec` writer) share about a failing records disk
/// (full, read-only, I/O error): the first write/flush/fsync error is latched, logged on stderr at once and kept
/// for the summary; nothing is written after it (the rest of the session is counted as lost, never silently
/// missing). docs/records.md, "When the records disk fails".
#include <sys/types.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>

namespace phalanx::host::record {

/// Exit code of a session whose recording failed while the device session itself went well (0 ok, 2 bad
/// arguments, 3 cannot open, 4 handshake, 5 faulted at start, 6 link lost; README "Exit codes").
inline constexpr int kExitRecordFailed = 7;

/// First failure of a recorder: set once by its writer thread, read by any thread (failed() is one atomic load,
/// fit for the real-time loop).
class WriteFailure {
 public:
  /// Latches `what` if nothing failed yet and logs "<program>: error: <what>" on stderr; later calls do nothing.
  void set(const std::string& what);
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  /// "" while nothing failed.
  std::string error() const;

 private:
  std::atomic<bool> failed_{false};
  mutable std::mutex mutex_;
  std::string error_;
};

/// write(2)s all n bytes (retrying short writes and EINTR). Returns the bytes that reached the file; on an error
/// (or a write of 0 bytes) also sets err_no (ENOSPC when the kernel wrote nothing without saying why).
std::size_t writeFully(int fd, const void* data, std::size_t n, int& err_no);

/// fdatasync(2), ignoring the errors that only say the file cannot be synchronised (a pipe, a character device).
/// 0 or errno.
int syncData(int fd);

}  // namespace phalanx::host::record
