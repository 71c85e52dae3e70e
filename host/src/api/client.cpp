#include "phalanx/host/api/client.h"

#include "phalanx/host/api/socket_access.h"

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

namespace phalanx::host::api {

std::string callRaw(const std::string& socket_path, const std::string& line, std::string& response_line,
                    int timeout_ms, long trusted_uid) {
  response_line.clear();
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  if (socket_path.size() >= sizeof addr.sun_path) return "socket path too long: " + socket_path;
  std::memcpy(addr.sun_path, socket_path.c_str(), socket_path.size() + 1);
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::string("socket: ") + std::strerror(errno);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const std::string err = "cannot connect to phalanxd at " + socket_path + ": " + std::strerror(errno) +
                            (errno == ENOENT || errno == ECONNREFUSED ? " (is phalanxd running with --api?)" : "");
    ::close(fd);
    return err;
  }
  // Before anything is sent: whoever answers on this path must be root or us (a squatter's "ok" is no answer).
  if (std::string err = refuseServer(fd, socket_path, trusted_uid); !err.empty()) {
    ::close(fd);
    return err;
  }
  std::string out = line;
  if (out.empty() || out.back() != '\n') out += '\n';
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::send(fd, out.data() + done, out.size() - done, MSG_NOSIGNAL);
    if (n <= 0) {
      ::close(fd);
      return std::string("send: ") + std::strerror(errno);
    }
    done += static_cast<std::size_t>(n);
  }
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  std::string in;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      ::close(fd);
      return "no answer from phalanxd within " + std::to_string(timeout_ms) + " ms";
    }
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
    char buf[4096];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    in.append(buf, static_cast<std::size_t>(n));
    if (in.find('\n') != std::string::npos) break;
  }
  ::close(fd);
  const auto nl = in.find('\n');
  if (nl == std::string::npos) return "phalanxd closed the connection without an answer";
  response_line = in.substr(0, nl);
  return {};
}

std::string call(const std::string& socket_path, const nlohmann::json& request, nlohmann::json& response,
                 int timeout_ms, long trusted_uid) {
  std::string line;
  if (std::string err = callRaw(socket_path, request.dump(), line, timeout_ms, trusted_uid); !err.empty()) return err;
  response = nlohmann::json::parse(line, nullptr, false);
  if (response.is_discarded()) return "phalanxd answered something that is not JSON: " + line;
  return {};
}

}  // namespace phalanx::host::api
