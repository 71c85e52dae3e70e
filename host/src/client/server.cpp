// The client channel's socket side (its own thread, never the loop's): directory and socket, the shared memory,
// peer credentials, negotiation, release and disconnect. docs/sdk.md §"Channel".
#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <pthread.h>
#include <pwd.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <new>
#include <vector>

#include "phalanx/host/client/client_port.h"
#include "phalanx/host/program_name.h"

namespace phalanx::host::client {
namespace {

std::string sysError(const std::string& what) { return what + ": " + std::strerror(errno); }

std::string parentOf(const std::string& path) {
  const auto slash = path.find_last_of('/');
  return slash == 0 ? "/" : path.substr(0, slash);
}

bool uidInGroup(uid_t uid, gid_t gid) {
  passwd pw{};
  passwd* found = nullptr;
  std::vector<char> buf(16384);
  if (getpwuid_r(uid, &pw, buf.data(), buf.size(), &found) != 0 || found == nullptr) return false;
  int n = 64;
  std::vector<gid_t> groups(static_cast<size_t>(n));
  if (getgrouplist(pw.pw_name, pw.pw_gid, groups.data(), &n) < 0) {
    groups.resize(static_cast<size_t>(n));
    if (getgrouplist(pw.pw_name, pw.pw_gid, groups.data(), &n) < 0) return false;
  }
  return std::find(groups.begin(), groups.begin() + n, gid) != groups.begin() + n;
}

/// Send the whole buffer, with fd attached when fd >= 0.
bool sendWithFd(int sock, const void* data, size_t size, int fd) {
  iovec iov{const_cast<void*>(data), size};
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(int))] = {};
  if (fd >= 0) {
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    cmsghdr* c = CMSG_FIRSTHDR(&msg);
    c->cmsg_level = SOL_SOCKET;
    c->cmsg_type = SCM_RIGHTS;
    c->cmsg_len = CMSG_LEN(sizeof(int));
    std::memcpy(CMSG_DATA(c), &fd, sizeof(int));
  }
  return ::sendmsg(sock, &msg, MSG_NOSIGNAL) == static_cast<ssize_t>(size);
}

void setTimeouts(int fd, long usec) {
  timeval tv{0, usec};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

void copyText(char* dst, size_t n, const std::string& s) {
  std::memset(dst, 0, n);
  std::memcpy(dst, s.data(), std::min(n - 1, s.size()));
}

}  // namespace

Server::Server(const ClientOptions& options, const DeviceIdentity& identity) : opt_(options), id_(identity) {}

Server::~Server() { stop(); }

std::string Server::start() {
  if (opt_.socket_path.empty()) return createSharedMemory();  // in-process sources only (DDS commands)
  if (!opt_.group.empty()) {
    const group* g = getgrnam(opt_.group.c_str());
    if (g == nullptr) return "client.group: no group named '" + opt_.group + "'";
    group_gid_ = g->gr_gid;
    have_group_ = true;
  }
  if (std::string err = prepareDirectory(); !err.empty()) return err;
  if (std::string err = createSharedMemory(); !err.empty()) return err;
  listen_fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0) return sysError("client socket");
  sockaddr_un sa{};
  sa.sun_family = AF_UNIX;
  std::memcpy(sa.sun_path, opt_.socket_path.c_str(), opt_.socket_path.size());  // length validated
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
    return sysError("client socket " + opt_.socket_path + ": bind");
  }
  // The directory already keeps others out; the socket's own mode says the same.
  if (::chmod(opt_.socket_path.c_str(), have_group_ ? 0660 : 0600) != 0) return sysError("client socket: chmod");
  if (have_group_ && ::chown(opt_.socket_path.c_str(), static_cast<uid_t>(-1), group_gid_) != 0) {
    return sysError("client socket: chown to group " + opt_.group);
  }
  if (::listen(listen_fd_, 4) != 0) return sysError("client socket: listen");
  running_ = true;
  thread_ = std::thread([this] { serve(); });
  return {};
}

std::string Server::prepareDirectory() {
  const std::string dir = parentOf(opt_.socket_path);
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    if (errno != ENOENT) return sysError("client.socket: directory " + dir);
    if (::mkdir(dir.c_str(), have_group_ ? 0750 : 0700) != 0) return sysError("client.socket: cannot create " + dir);
    if (have_group_ && ::chown(dir.c_str(), static_cast<uid_t>(-1), group_gid_) != 0) {
      return sysError("client.socket: chown " + dir + " to group " + opt_.group);
    }
    if (::stat(dir.c_str(), &st) != 0) return sysError("client.socket: directory " + dir);
  }
  if (!S_ISDIR(st.st_mode)) return "client.socket: " + dir + " is not a directory";
  if ((st.st_mode & S_IWOTH) != 0 && (st.st_mode & S_ISVTX) == 0) {
    return "client.socket: " + dir + " is writable by every user (use a private runtime directory, e.g. $XDG_RUNTIME_DIR/phalanx)";
  }
  struct stat sock {};
  if (::lstat(opt_.socket_path.c_str(), &sock) == 0) {
    if (!S_ISSOCK(sock.st_mode)) return "client.socket: " + opt_.socket_path + " exists and is not a socket";
    // A socket left by a daemon that died: nobody answers on it, so it is replaced. One that answers is in use.
    const int probe = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::memcpy(sa.sun_path, opt_.socket_path.c_str(), opt_.socket_path.size());
    const bool in_use = ::connect(probe, reinterpret_cast<sockaddr*>(&sa), sizeof sa) == 0;
    ::close(probe);
    if (in_use) return "client.socket: " + opt_.socket_path + " is served by another phalanxd";
    ::unlink(opt_.socket_path.c_str());
  }
  return {};
}

std::string Server::createSharedMemory() {
  memfd_ = ::memfd_create("phalanx-client", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  if (memfd_ < 0) return sysError("client channel: memfd_create");
  if (::ftruncate(memfd_, sizeof(client_wire::SharedChannel)) != 0) return sysError("client channel: ftruncate");
  // A client holding the fd must not shrink it under the daemon's mapping (SIGBUS in the loop) or grow it.
  if (::fcntl(memfd_, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) != 0) {
    return sysError("client channel: seal");
  }
  void* p = ::mmap(nullptr, sizeof(client_wire::SharedChannel), PROT_READ | PROT_WRITE, MAP_SHARED, memfd_, 0);
  if (p == MAP_FAILED) return sysError("client channel: mmap");
  channel_ = new (p) client_wire::SharedChannel();
  // Touched now, before the loop: no page fault in the first cycles (mlockall locks it when real time is on).
  std::memset(static_cast<void*>(&channel_->state.payload), 0, sizeof channel_->state.payload);
  return {};
}

void Server::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (client_fd_ >= 0) ::close(client_fd_);
  client_fd_ = -1;
  if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    ::unlink(opt_.socket_path.c_str());
  }
  listen_fd_ = -1;
  if (channel_ != nullptr) ::munmap(channel_, sizeof(client_wire::SharedChannel));
  channel_ = nullptr;
  if (memfd_ >= 0) ::close(memfd_);
  memfd_ = -1;
}

void Server::serve() {
  // Threads inherit the loop's SCHED_FIFO; a socket server must never compete with it.
  sched_param normal{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  while (running_) {
    pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {client_fd_, POLLIN, 0}};
    const int n = ::poll(fds, client_fd_ >= 0 ? 2 : 1, 50);  // wake to notice stop()
    if (n < 0 && errno != EINTR) {
      std::fprintf(stderr, "%s: client channel: poll: %s; no more clients are served\n", programName(), std::strerror(errno));
      return;
    }
    if (n <= 0) continue;
    if ((fds[0].revents & POLLIN) != 0) accept();
    if (client_fd_ >= 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) != 0) watchClient();
  }
}

bool Server::peerAllowed(int fd) {
  ucred cred{};
  socklen_t len = sizeof cred;
  if (getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) return false;
  if (cred.uid == geteuid() || cred.uid == 0) return true;
  return have_group_ && (cred.gid == group_gid_ || uidInGroup(cred.uid, group_gid_));
}

void Server::accept() {
  const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
  if (fd < 0) return;
  if (!peerAllowed(fd)) {
    ++counters_.refused_credentials;
    ::close(fd);  // nothing is said to a peer that may not connect
    return;
  }
  negotiate(fd);
}

client_wire::ConnectStatus checkConnectRequest(const client_wire::ConnectRequest& req, long got, uint32_t rate_hz,
                                               bool busy, std::string& why) {
  const uint32_t min_deadline_ms = 2000 / rate_hz + ((2000 % rate_hz) != 0 ? 1 : 0);
  if (got != static_cast<long>(sizeof req) || req.magic != client_wire::kMagic) {
    why = "not a Phalanx client request";
    return client_wire::ConnectStatus::kBadRequest;
  }
  if (req.version != client_wire::kVersion) {
    why = "client channel version " + std::to_string(req.version) + ", this phalanxd speaks " +
          std::to_string(client_wire::kVersion);
    return client_wire::ConnectStatus::kVersionMismatch;
  }
  if (busy) {
    // A client that vanished still holds the device until its deadline forces it off.
    why = "another client holds this device";
    return client_wire::ConnectStatus::kBusy;
  }
  if (req.deadline_ms < min_deadline_ms || req.deadline_ms > 1000) {
    why = "deadline_ms " + std::to_string(req.deadline_ms) + " is not in [" + std::to_string(min_deadline_ms) +
          ", 1000] (at least two daemon periods)";
    return client_wire::ConnectStatus::kBadRequest;
  }
  if (static_cast<uint8_t>(req.fallback) > 1) {
    why = "fallback must be safe (0) or transparent (1)";
    return client_wire::ConnectStatus::kBadRequest;
  }
  return client_wire::ConnectStatus::kOk;
}

void Server::negotiate(int fd) {
  setTimeouts(fd, 500000);  // a peer that connects and says nothing holds this thread at most 0.5 s
  client_wire::ConnectRequest req;
  client_wire::ConnectReply reply;
  const ssize_t got = ::recv(fd, &req, sizeof req, MSG_WAITALL);
  std::string why;
  std::lock_guard<std::mutex> lock(attach_mutex_);  // against an in-process source attaching meanwhile
  const bool busy = client_fd_ >= 0 || in_process_generation_ != 0 || attach_.holding.load(std::memory_order_acquire) != 0;
  reply.status = checkConnectRequest(req, static_cast<long>(got), id_.rate_hz, busy, why);
  const protocol::DeviceLayout& l = *id_.layout;
  reply.device_type = static_cast<uint8_t>(l.type);
  copyText(reply.device_name, sizeof reply.device_name, l.name);
  reply.rate_hz = id_.rate_hz;
  reply.setpoint_count = l.setpoint_count;
  reply.sample_count = l.sample_count;
  reply.setpoint_limit = l.setpoint_limit;
  for (size_t i = 0; i < l.sample_count; ++i) reply.sample_kind[i] = static_cast<uint8_t>(l.sample_kind[i]);
  reply.firmware_build_id = id_.firmware_build_id;
  if (reply.status != client_wire::ConnectStatus::kOk) {
    copyText(reply.message, sizeof reply.message, why);
    ++(reply.status == client_wire::ConnectStatus::kBusy ? counters_.refused_busy : counters_.refused_request);
    sendWithFd(fd, &reply, sizeof reply, -1);
    ::close(fd);
    return;
  }
  const uint32_t generation = next_generation_++;
  reply.generation = generation;
  reply.deadline_ms = req.deadline_ms;
  attach_.deadline_ms.store(req.deadline_ms, std::memory_order_relaxed);
  attach_.fallback.store(static_cast<uint8_t>(req.fallback), std::memory_order_relaxed);
  attach_.source.store(static_cast<uint8_t>(CommandSource::kSocket), std::memory_order_relaxed);
  attach_.generation.store(generation, std::memory_order_release);  // the loop picks it up at its next cycle
  if (!sendWithFd(fd, &reply, sizeof reply, memfd_)) {
    attach_.gone.store(generation, std::memory_order_release);
    ::close(fd);
    return;
  }
  ++counters_.connections;
  setTimeouts(fd, 0);
  client_fd_ = fd;
  client_generation_ = generation;
  socket_client_.store(true, std::memory_order_release);
}

void Server::watchClient() {
  client_wire::Release rel;
  const ssize_t got = ::recv(client_fd_, &rel, sizeof rel, MSG_DONTWAIT);
  if (got < 0 && (errno == EAGAIN || errno == EINTR)) return;
  if (got == static_cast<ssize_t>(sizeof rel) && rel.magic == client_wire::kMagic && rel.generation == client_generation_) {
    attach_.released.store(client_generation_, std::memory_order_release);
    ++counters_.releases;
  } else {
    // Closed without a Release (crash, kill -9) or garbage: the loop keeps the client's claim until its deadline.
    attach_.gone.store(client_generation_, std::memory_order_release);
    ++counters_.disconnects_without_release;
  }
  ::close(client_fd_);
  std::lock_guard<std::mutex> lock(attach_mutex_);
  client_fd_ = -1;
  socket_client_.store(false, std::memory_order_release);
}

uint32_t Server::attachInProcess(uint32_t deadline_ms, client_wire::Fallback fallback, CommandSource source,
                                 std::string& why) {
  client_wire::ConnectRequest req;  // the request a socket client would send: the same checks
  req.deadline_ms = static_cast<uint16_t>(deadline_ms > 0xffff ? 0xffff : deadline_ms);
  req.fallback = fallback;
  std::lock_guard<std::mutex> lock(attach_mutex_);
  const bool busy = socket_client_.load(std::memory_order_acquire) || in_process_generation_ != 0 ||
                    attach_.holding.load(std::memory_order_acquire) != 0;
  if (checkConnectRequest(req, static_cast<long>(sizeof req), id_.rate_hz, busy, why) != client_wire::ConnectStatus::kOk) {
    ++(busy ? counters_.refused_busy : counters_.refused_request);
    return 0;
  }
  const uint32_t generation = next_generation_++;
  in_process_generation_ = generation;
  attach_.deadline_ms.store(deadline_ms, std::memory_order_relaxed);
  attach_.fallback.store(static_cast<uint8_t>(fallback), std::memory_order_relaxed);
  attach_.source.store(static_cast<uint8_t>(source), std::memory_order_relaxed);
  attach_.generation.store(generation, std::memory_order_release);
  ++counters_.in_process_attachments;
  return generation;
}

void Server::writeInProcess(const client_wire::CommandPayload& p) {
  client_wire::CommandBlock& block = channel_->command;
  client_wire::seqlockWrite(block.seq, block.payload, p);
}

void Server::releaseInProcess(uint32_t generation) {
  std::lock_guard<std::mutex> lock(attach_mutex_);
  if (generation == 0 || generation != in_process_generation_) return;
  attach_.released.store(generation, std::memory_order_release);
  ++counters_.releases;
  in_process_generation_ = 0;
}

void Server::goneInProcess(uint32_t generation) {
  std::lock_guard<std::mutex> lock(attach_mutex_);
  if (generation == 0 || generation != in_process_generation_) return;
  attach_.gone.store(generation, std::memory_order_release);  // the loop keeps its claim until its deadline
  ++counters_.disconnects_without_release;
  in_process_generation_ = 0;
}

}  // namespace phalanx::host::client
