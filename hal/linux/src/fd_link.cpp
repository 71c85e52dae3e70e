#include "phalanx/linux/fd_link.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

namespace phalanx::linux_hal {
namespace {

std::string errnoText(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

bool makeRaw(int fd, speed_t speed, std::string& err) {
  termios t{};
  if (tcgetattr(fd, &t) != 0) {
    err = errnoText("tcgetattr");
    return false;
  }
  cfmakeraw(&t);
  t.c_cflag |= CLOCAL | CREAD;
  // VMIN 1 (not 0): with VMIN = VTIME = 0 a tty read() with no data returns 0 even on a non-blocking descriptor,
  // indistinguishable from the 0 of a hung-up tty (USB CDC-ACM unplugged); with VMIN 1 "no data" is EAGAIN and 0
  // means hang-up. The descriptor is O_NONBLOCK, so VMIN never makes a read wait.
  t.c_cc[VMIN] = 1;
  t.c_cc[VTIME] = 0;
  if (speed != 0 && (cfsetispeed(&t, speed) != 0 || cfsetospeed(&t, speed) != 0)) {
    err = errnoText("cfsetspeed");
    return false;
  }
  if (tcsetattr(fd, TCSANOW, &t) != 0) {
    err = errnoText("tcsetattr");
    return false;
  }
  return true;
}

speed_t baudConstant(unsigned baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return 0;
  }
}

}  // namespace

FdLink::~FdLink() { close(); }

void FdLink::adopt(int fd) {
  close();
  fd_ = fd;
  tx_len_ = 0;
  empty_polls_ = 0;
  probe_when_idle_ = true;
  hung_up_ = false;
  error_.clear();
}

void FdLink::close() {
  // Discard unsent output first: closing a tty waits for it to drain (the USB gadget's ttyGS0 up to 15 s when no
  // host reads), and stale frames are worth nothing to the next session anyway.
  if (fd_ >= 0 && isatty(fd_)) tcflush(fd_, TCIOFLUSH);
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

size_t FdLink::read(uint8_t* dst, size_t max_len) {
  if (fd_ < 0) return 0;
  // A tty read() that finds no input waits for the tty layer's flip-buffer work to finish (n_tty_read →
  // tty_buffer_flush_work), even on an O_NONBLOCK descriptor, and that work runs in a kworker at normal priority:
  // on a busy machine it blocked the SCHED_FIFO loop for up to 0.6 s (docs/modbus.md, "Measured"). FIONREAD
  // reads the line discipline's count without waiting, so read() is called only when it has bytes (with VMIN 1 a
  // read that copied bytes returns without that wait). Bytes still in the flip buffer arrive a cycle later.
  // A hung-up tty fails FIONREAD (EIO: the kernel's vhangup replaced its file operations, for a USB CDC-ACM
  // unplug and for a pty slave whose master closed) and read() then reports the hang-up. A pty master or a pipe
  // whose other side closed answers 0 forever, so there (probe_when_idle_) one real read() probes after
  // kProbeAfterEmpty empty polls; never on a serial tty (SerialLink), where that probe is the very read that
  // waits for the starved kworker when the device has been quiet (measured: one 88 ms stall in a 30 s run).
  constexpr uint32_t kProbeAfterEmpty = 100;  // 0.1 s at 1 kHz
  int avail = 0;
  if (::ioctl(fd_, FIONREAD, &avail) == 0) {
    if (avail <= 0 && (!probe_when_idle_ || ++empty_polls_ < kProbeAfterEmpty)) return 0;
    if (avail > 0 && static_cast<size_t>(avail) < max_len) max_len = static_cast<size_t>(avail);
  }
  empty_polls_ = 0;
  const ssize_t n = ::read(fd_, dst, max_len);
  if (n > 0) return static_cast<size_t>(n);
  if (n == 0) {
    hung_up_ = true;
  } else if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
    // EIO on a pty master means no slave is open right now: a hang-up, not corruption.
    hung_up_ = true;
    if (errno != EIO) error_ = errnoText("read");
  }
  return 0;
}

size_t FdLink::write(const uint8_t* src, size_t len) {
  if (fd_ < 0 || len > writeSpace()) return 0;
  std::memcpy(tx_.data() + tx_len_, src, len);
  tx_len_ += len;
  flush();
  return len;
}

bool FdLink::flush() {
  while (fd_ >= 0 && tx_len_ > 0) {
    const ssize_t n = ::write(fd_, tx_.data(), tx_len_);
    if (n > 0) {
      std::memmove(tx_.data(), tx_.data() + n, tx_len_ - static_cast<size_t>(n));
      tx_len_ -= static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return true;
    if (n < 0 && errno == EIO) {
      tx_len_ = 0;  // nobody is listening on the other end: drop, as a UART with no cable would
      return true;
    }
    error_ = errnoText("write");
    return false;
  }
  return true;
}

std::string SerialLink::open(const std::string& path, unsigned baud) {
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0 && errno == EBUSY) return "device busy: " + path + " is in use by another process (opened exclusively)";
  if (fd < 0) return errnoText(("cannot open serial device " + path).c_str());
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISCHR(st.st_mode) || !isatty(fd)) {
    ::close(fd);
    return path + " is not a serial device (not a tty)";
  }
  // One process per device: a second daemon opening it would answer the device's telemetry with its own Hello
  // and take the stream over. flock is advisory, held by this open file description until it is closed, and
  // honoured by every Phalanx process (TIOCEXCL below keeps out non-root openers that do not lock; root
  // ignores TIOCEXCL, hence the lock).
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    ::close(fd);
    if (e == EWOULDBLOCK) return "device busy: " + path + " is in use by another process";
    errno = e;
    return errnoText(("cannot lock serial device " + path).c_str());
  }
  speed_t speed = 0;
  if (baud != 0) {
    speed = baudConstant(baud);
    if (speed == 0) {
      ::close(fd);
      return "unsupported baud rate " + std::to_string(baud);
    }
  }
  std::string err;
  if (!makeRaw(fd, speed, err)) {
    ::close(fd);
    return path + ": " + err;
  }
  // Exclusive: a second opener (ModemManager probing a new ttyACM with AT commands, a stray terminal) would
  // steal bytes from the stream and inject its own.
  ioctl(fd, TIOCEXCL);
  tcflush(fd, TCIOFLUSH);
  adopt(fd);
  probe_when_idle_ = false;
  return {};
}

std::string PtyMaster::open() {
  const int fd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return errnoText("posix_openpt");
  if (grantpt(fd) != 0 || unlockpt(fd) != 0) {
    const std::string e = errnoText("grantpt/unlockpt");
    ::close(fd);
    return e;
  }
  char name[128];
  if (ptsname_r(fd, name, sizeof name) != 0) {
    const std::string e = errnoText("ptsname_r");
    ::close(fd);
    return e;
  }
  slave_path_ = name;
  slave_keepalive_ = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  std::string err;
  if (slave_keepalive_ < 0 || !makeRaw(slave_keepalive_, 0, err)) {
    if (err.empty()) err = errnoText("open pty slave");
    ::close(fd);
    return err;
  }
  adopt(fd);
  return {};
}

}  // namespace phalanx::linux_hal
