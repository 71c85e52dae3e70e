#include "phalanx/host/record/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <vector>

#include "phalanx/host/record/write_failure.h"

namespace phalanx::host::record {

FileId fileId(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  return {st.st_dev, st.st_ino, true};
}

std::string refuseSameFile(const std::string& input, const std::string& output) {
  if (fileId(input) == fileId(output)) {
    return "refusing to write " + output + ": it is the input " + input + " (the same file)";
  }
  return {};
}

AtomicOutputFile::~AtomicOutputFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!temp_.empty()) ::unlink(temp_.c_str());
}

std::string AtomicOutputFile::open(const std::string& path, mode_t mode) {
  path_ = path;
  const auto slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  if (name.empty()) return "cannot write " + path + ": not a file name";
  std::string tmpl = dir + "/." + name + ".XXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  fd_ = ::mkostemp(buf.data(), O_CLOEXEC);
  if (fd_ < 0) return "cannot write " + path + ": cannot create a file in " + dir + ": " + std::strerror(errno);
  temp_ = buf.data();
  ::fchmod(fd_, mode);
  buffer_.reserve(1 << 20);
  return {};
}

bool AtomicOutputFile::flushBuffer() {
  if (err_no_ != 0 || fd_ < 0) return false;
  int e = 0;
  writeFully(fd_, buffer_.data(), buffer_.size(), e);
  buffer_.clear();
  err_no_ = e;
  return e == 0;
}

bool AtomicOutputFile::write(const void* data, std::size_t n) {
  if (err_no_ != 0 || fd_ < 0) return false;
  buffer_.append(static_cast<const char*>(data), n);
  return buffer_.size() < (1u << 20) || flushBuffer();
}

std::string AtomicOutputFile::commit() {
  if (fd_ < 0) return "cannot write " + path_ + ": not open";
  flushBuffer();
  if (err_no_ == 0 && ::fsync(fd_) != 0 && errno != EINVAL) err_no_ = errno;
  if (::close(fd_) != 0 && err_no_ == 0) err_no_ = errno;
  fd_ = -1;
  if (err_no_ == 0 && ::rename(temp_.c_str(), path_.c_str()) != 0) err_no_ = errno;
  if (err_no_ != 0) return "writing " + path_ + " failed: " + std::strerror(err_no_) + " (an existing file is left as it was)";
  temp_.clear();
  return {};
}

}  // namespace phalanx::host::record
