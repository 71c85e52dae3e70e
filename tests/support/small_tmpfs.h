#pragma once
// A real small filesystem for the "records disk full / read-only" tests: a tmpfs of a given size mounted on a new
// directory inside a private mount namespace of the test process (unshare(CLONE_NEWNS)), so nothing outside the
// test sees it; child processes (phalanxd, phalanx) inherit it. Needs root (CAP_SYS_ADMIN); otherwise
// skipReason() says why and the test skips.
#include <sched.h>
#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>

namespace phalanx::test {

class SmallTmpfs {
 public:
  explicit SmallTmpfs(std::size_t bytes, bool read_only = false) {
    if (::geteuid() != 0) {
      skip_ = "needs root to mount a small tmpfs (in a private mount namespace)";
      return;
    }
    if (const std::string err = privateMountNamespace(); !err.empty()) {
      skip_ = err;
      return;
    }
    char tmpl[] = "/tmp/phalanx-tmpfs-XXXXXX";
    if (::mkdtemp(tmpl) == nullptr) {
      skip_ = std::string("mkdtemp: ") + std::strerror(errno);
      return;
    }
    dir_ = tmpl;
    const std::string opts = "size=" + std::to_string(bytes) + ",mode=0755";
    if (::mount("tmpfs", dir_.c_str(), "tmpfs", read_only ? MS_RDONLY : 0, opts.c_str()) != 0) {
      skip_ = std::string("mount -t tmpfs: ") + std::strerror(errno);
      ::rmdir(dir_.c_str());
      dir_.clear();
      return;
    }
    mounted_ = true;
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
    if (!dir_.empty()) ::rmdir(dir_.c_str());
  }
  SmallTmpfs(const SmallTmpfs&) = delete;
  SmallTmpfs& operator=(const SmallTmpfs&) = delete;

  const std::string& dir() const { return dir_; }
  /// "" when mounted.
  const std::string& skipReason() const { return skip_; }

 private:
  /// Once per process: a mount namespace of its own, with no propagation back to the host's.
  static std::string privateMountNamespace() {
    static std::string result = [] {
      if (::unshare(CLONE_NEWNS) != 0) return std::string("unshare(CLONE_NEWNS): ") + std::strerror(errno);
      if (::mount("none", "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) {
        return std::string("mount --make-rprivate /: ") + std::strerror(errno);
      }
      return std::string();
    }();
    return result;
  }

  std::string dir_;
  std::string skip_;
  bool mounted_ = false;
};

}  // namespace phalanx::test
