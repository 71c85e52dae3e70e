#pragma once
/// Byte links over Linux file descriptors: a termios serial port (USB CDC-ACM, UART adapters) and a
/// pseudo-terminal master (the simulated firmware's end of the link). Non-blocking; writes go through a
/// user-space buffer so a frame is never split by a short write.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "phalanx/hal/hal.h"

namespace phalanx::linux_hal {

class FdLink : public hal::ByteLink {
 public:
  FdLink() = default;
  FdLink(const FdLink&) = delete;
  FdLink& operator=(const FdLink&) = delete;
  ~FdLink() override;

  size_t read(uint8_t* dst, size_t max_len) override;
  size_t write(const uint8_t* src, size_t len) override;
  size_t writeSpace() const override { return tx_.size() - tx_len_; }
  /// Push buffered bytes to the fd; returns false on a hard error (peer gone).
  bool flush();
  int fd() const { return fd_; }
  bool isOpen() const { return fd_ >= 0; }
  /// Last hard I/O error (errno text) or empty.
  const std::string& error() const { return error_; }
  /// true once read() saw end-of-file / hang-up.
  bool hungUp() const { return hung_up_; }
  void close();

 protected:
  void adopt(int fd);
  std::string error_;
  bool probe_when_idle_ = true;  ///< see read(): false for a serial tty (SerialLink), whose hang-up FIONREAD reports

 private:
  int fd_ = -1;
  std::vector<uint8_t> tx_ = std::vector<uint8_t>(65536);
  size_t tx_len_ = 0;
  uint32_t empty_polls_ = 0;  ///< read() calls in a row that found no input (FIONREAD 0)
  bool hung_up_ = false;
};

/// A serial device in raw 8N1 mode. open() returns an empty string on success, else what went wrong.
class SerialLink : public FdLink {
 public:
  std::string open(const std::string& path, unsigned baud);
};

/// The master side of a new pseudo-terminal in raw mode; slavePath() is what the host daemon opens.
class PtyMaster : public FdLink {
 public:
  std::string open();
  const std::string& slavePath() const { return slave_path_; }

 private:
  std::string slave_path_;
  int slave_keepalive_ = -1;  // keeps the pty from reporting hang-up while no host is attached
};

}  // namespace phalanx::linux_hal
