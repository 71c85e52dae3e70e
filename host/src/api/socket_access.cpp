#include "phalanx/host/api/socket_access.h"

#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace phalanx::host::api {
namespace {

std::string parentDirectory(const std::string& path) {
  const auto slash = path.rfind('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

bool peerCredentials(int fd, ucred& out) {
  socklen_t len = sizeof out;
  return ::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &out, &len) == 0 && len == sizeof out;
}

/// Supplementary groups of the peer (SO_PEERGROUPS, Linux 4.13).
bool peerInGroup(int fd, gid_t group) {
  std::vector<gid_t> groups(64);
  for (int attempt = 0; attempt < 2; ++attempt) {
    socklen_t len = static_cast<socklen_t>(groups.size() * sizeof(gid_t));
    if (::getsockopt(fd, SOL_SOCKET, SO_PEERGROUPS, groups.data(), &len) == 0) {
      for (std::size_t i = 0; i < len / sizeof(gid_t); ++i) {
        if (groups[i] == group) return true;
      }
      return false;
    }
    if (errno != ERANGE) return false;
    groups.resize(len / sizeof(gid_t) + 1);
  }
  return false;
}

}  // namespace

std::string defaultSocketPath() {
  if (const char* x = std::getenv("XDG_RUNTIME_DIR"); x != nullptr && *x != 0) return std::string(x) + "/phalanxd.sock";
  if (::geteuid() == 0) return "/run/phalanx/phalanxd.sock";
  return "/tmp/phalanxd-" + std::to_string(::geteuid()) + "/phalanxd.sock";
}

std::string prepareSocketDirectory(const std::string& socket_path, long group) {
  const std::string dir = parentDirectory(socket_path);
  struct stat st {};
  if (::lstat(dir.c_str(), &st) != 0 && errno == ENOENT && socket_path == defaultSocketPath()) {
    if (::mkdir(dir.c_str(), group >= 0 ? 0750 : 0700) != 0 && errno != EEXIST) {
      return "cannot create the socket directory " + dir + ": " + std::strerror(errno);
    }
    if (group >= 0 && ::chown(dir.c_str(), static_cast<uid_t>(-1), static_cast<gid_t>(group)) != 0) {
      return "cannot give the socket directory " + dir + " to group " + std::to_string(group) + ": " +
             std::strerror(errno);
    }
  }
  if (::lstat(dir.c_str(), &st) != 0) return "socket directory " + dir + ": " + std::strerror(errno);
  if (S_ISLNK(st.st_mode)) return "socket directory " + dir + " is a symbolic link (refused: use the real directory)";
  if (!S_ISDIR(st.st_mode)) return "socket directory " + dir + " is not a directory";
  if (st.st_uid != ::geteuid() && st.st_uid != 0) {
    return "socket directory " + dir + " belongs to uid " + std::to_string(st.st_uid) +
           ", not to this daemon's user or root (someone else could replace the socket)";
  }
  if ((st.st_mode & (S_IWGRP | S_IWOTH)) != 0) {
    return "socket directory " + dir + " is writable by other users (anyone could create the socket first); use a "
           "private directory such as $XDG_RUNTIME_DIR or /run/phalanx";
  }
  return {};
}

std::string refusePeer(int fd, long group) {
  ucred cr{};
  if (!peerCredentials(fd, cr)) return std::string("cannot read the client's credentials: ") + std::strerror(errno);
  if (cr.uid == 0 || cr.uid == ::geteuid()) return {};
  const gid_t g = group >= 0 ? static_cast<gid_t>(group) : ::getegid();
  if (cr.gid == g || peerInGroup(fd, g)) return {};
  return "uid " + std::to_string(cr.uid) + " may not use this API (allowed: uid " + std::to_string(::geteuid()) +
         ", root, and members of group " + std::to_string(g) + ")";
}

std::string refuseServer(int fd, const std::string& socket_path, long trusted_uid) {
  ucred cr{};
  if (!peerCredentials(fd, cr)) return "cannot read the credentials of the server at " + socket_path;
  if (cr.uid == 0 || cr.uid == ::getuid() || (trusted_uid >= 0 && cr.uid == static_cast<uid_t>(trusted_uid))) return {};
  return "refusing the server at " + socket_path + ": it runs as uid " + std::to_string(cr.uid) +
         ", neither root nor you (not phalanxd, or another user's; --daemon-uid trusts a daemon account)";
}

}  // namespace phalanx::host::api
