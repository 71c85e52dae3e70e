#pragma once
// A minimal HTTP/1.1 client on loopback for the dashboard tests (they need exact control of Host and headers):
// one request per connection (http()), or several on one keep-alive connection (KeepAlive), as a browser does.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

namespace phalanx::test {

struct HttpAnswer {
  int status = 0;
  std::string body;
};

inline int connectLoopback(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in sa{};
  sa.sin_family = AF_INET;
  sa.sin_port = htons(static_cast<uint16_t>(port));
  sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

inline std::string requestText(const std::string& method, const std::string& path, const std::string& host,
                               const std::string& connection, const std::string& extra_headers,
                               const std::string& body) {
  std::string req = method + " " + path + " HTTP/1.1\r\nHost: " + host + "\r\nConnection: " + connection + "\r\n" +
                    extra_headers;
  if (!body.empty() || method == "POST") {
    req += "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) + "\r\n";
  }
  return req + "\r\n" + body;
}

inline HttpAnswer parseAnswer(const std::string& resp) {
  HttpAnswer a;
  if (resp.rfind("HTTP/1.1 ", 0) == 0) a.status = std::atoi(resp.c_str() + 9);
  const auto b = resp.find("\r\n\r\n");
  if (b != std::string::npos) a.body = resp.substr(b + 4);
  return a;
}

/// One request on its own connection (Connection: close); status 0 when there was no answer.
inline HttpAnswer http(int port, const std::string& method, const std::string& path, const std::string& host,
                       const std::string& extra_headers = "", const std::string& body = "") {
  const int fd = connectLoopback(port);
  if (fd < 0) return {};
  const std::string req = requestText(method, path, host, "close", extra_headers, body);
  (void)!::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
  std::string resp;
  char buf[8192];
  pollfd p{fd, POLLIN, 0};
  while (::poll(&p, 1, 5000) > 0) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    resp.append(buf, static_cast<size_t>(n));
  }
  ::close(fd);
  return parseAnswer(resp);
}

/// A keep-alive connection: requests one after another, each answer read by its Content-Length.
class KeepAlive {
 public:
  explicit KeepAlive(int port) : fd_(connectLoopback(port)) {}
  ~KeepAlive() {
    if (fd_ >= 0) ::close(fd_);
  }
  KeepAlive(const KeepAlive&) = delete;
  KeepAlive& operator=(const KeepAlive&) = delete;
  bool connected() const { return fd_ >= 0; }
  /// Sends raw bytes (e.g. half a request).
  bool send(const std::string& bytes) {
    return fd_ >= 0 && ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size());
  }
  /// status 0: the server closed the connection (or sent nothing within timeout_ms).
  HttpAnswer request(const std::string& method, const std::string& path, const std::string& host,
                     const std::string& extra_headers = "", const std::string& body = "", int timeout_ms = 5000) {
    if (!send(requestText(method, path, host, "keep-alive", extra_headers, body))) return {};
    std::string resp;
    char buf[16384];
    pollfd p{fd_, POLLIN, 0};
    for (;;) {
      const auto head_end = resp.find("\r\n\r\n");
      if (head_end != std::string::npos) {
        const auto cl = resp.find("Content-Length: ");
        const std::size_t len = cl != std::string::npos && cl < head_end ? std::strtoul(resp.c_str() + cl + 16, nullptr, 10) : 0;
        if (resp.size() >= head_end + 4 + len) return parseAnswer(resp.substr(0, head_end + 4 + len));
      }
      if (::poll(&p, 1, timeout_ms) <= 0) return {};
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) return {};
      resp.append(buf, static_cast<size_t>(n));
    }
  }
  /// Waits up to timeout_ms for the server to close the connection; true if it did.
  bool closedByServer(int timeout_ms) {
    char c;
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, timeout_ms) > 0 && ::recv(fd_, &c, 1, 0) <= 0;
  }

 private:
  int fd_;
};

}  // namespace phalanx::test
