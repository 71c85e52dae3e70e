#include "phalanx/host/modbus/server.h"
#include "phalanx/host/program_name.h"

#include <arpa/inet.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pthread.h>
#include <sched.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "phalanx/linux/realtime.h"

namespace phalanx::host::modbus {
namespace {

modbus_t* ctxOf(void* p) { return static_cast<modbus_t*>(p); }
modbus_mapping_t* mapOf(void* p) { return static_cast<modbus_mapping_t*>(p); }

uint16_t be16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }

}  // namespace

Server::Server(const ServerOptions& options, const WriteLimits& limits) : opt_(options), limits_(limits) {
  encodeHolding(holding_cmd_, holding_);
}

Server::~Server() { stop(); }

std::string Server::prepare() {
  if (ctx_ != nullptr) return {};
  const char* ip = opt_.address == "0.0.0.0" || opt_.address == "*" ? nullptr : opt_.address.c_str();
  modbus_t* ctx = modbus_new_tcp(ip, static_cast<int>(opt_.port));
  if (ctx == nullptr) return "modbus: cannot create a TCP context: " + std::string(modbus_strerror(errno));
  ctx_ = ctx;
  // A frame that has started must finish within byte_timeout_ms, or the connection is dropped.
  modbus_set_byte_timeout(ctx, 0, opt_.byte_timeout_ms * 1000u);
  modbus_set_response_timeout(ctx, 0, opt_.byte_timeout_ms * 1000u);
  mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, 0, hold::kCount, 0, in::kCount);
  if (mapping_ == nullptr) return "modbus: cannot allocate the register map";
  return {};
}

std::string Server::start() {
  if (std::string err = prepare(); !err.empty()) return err;
  modbus_t* ctx = ctxOf(ctx_);
  listen_fd_ = modbus_tcp_listen(ctx, static_cast<int>(std::min(opt_.max_clients, 64u)));
  if (listen_fd_ < 0) {
    return "modbus: cannot listen on " + opt_.address + ":" + std::to_string(opt_.port) + ": " + modbus_strerror(errno);
  }
  sockaddr_in sa{};
  socklen_t len = sizeof sa;
  if (getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &len) == 0) port_ = ntohs(sa.sin_port);
  running_ = true;
  thread_ = std::thread([this] { serve(); });
  return {};
}

void Server::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
  if (mapping_ != nullptr) modbus_mapping_free(mapOf(mapping_));
  mapping_ = nullptr;
  if (ctx_ != nullptr) modbus_free(ctxOf(ctx_));
  ctx_ = nullptr;
}

void Server::serve() {
  // Threads inherit the creator's policy: phalanxd starts us after switching to SCHED_FIFO, and a network server
  // must never compete with the loop at real-time priority.
  sched_param normal{};
  normal.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  std::vector<int> clients;
  std::vector<uint8_t> query(MODBUS_TCP_MAX_ADU_LENGTH);
  modbus_t* ctx = ctxOf(ctx_);
  while (running_) {
    fd_set rd;
    FD_ZERO(&rd);
    FD_SET(listen_fd_, &rd);
    int maxfd = listen_fd_;
    for (int fd : clients) {
      FD_SET(fd, &rd);
      maxfd = std::max(maxfd, fd);
    }
    timeval tv{0, 50000};  // wake to notice stop()
    const int n = ::select(maxfd + 1, &rd, nullptr, nullptr, &tv);
    if (n < 0) {
      if (errno == EINTR) continue;
      std::fprintf(stderr, "%s: modbus: select: %s; server stopped\n", programName(), std::strerror(errno));
      break;
    }
    if (n == 0) continue;
    if (FD_ISSET(listen_fd_, &rd)) {
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd >= 0) {
        // FD_SETSIZE bounds select(); max_clients (≤ 256, validated) keeps us far below it.
        if (clients.size() >= opt_.max_clients || fd >= FD_SETSIZE) {
          ::close(fd);
          stats_.refused_connections++;
        } else {
          timeval snd{0, 100000};  // a client that does not read its answers cannot stall the thread for long
          setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &snd, sizeof snd);
          const int one = 1;
          setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
          clients.push_back(fd);
          stats_.connections++;
        }
      }
    }
    for (size_t i = 0; i < clients.size();) {
      const int fd = clients[i];
      if (!FD_ISSET(fd, &rd)) {
        ++i;
        continue;
      }
      if (serveRequest(fd, query.data()) >= 0) {
        ++i;
      } else {
        // Closed by the peer, or a frame that is malformed or did not complete within the byte timeout: the
        // stream cannot be resynchronised, so the connection is dropped.
        if (errno != ECONNRESET) stats_.dropped++;
        ::close(fd);
        clients.erase(clients.begin() + static_cast<long>(i));
      }
    }
  }
  for (int fd : clients) ::close(fd);
  modbus_set_socket(ctx, -1);
}

int Server::serveRequest(int fd, uint8_t* query) {
  modbus_t* ctx = ctxOf(ctx_);
  modbus_set_socket(ctx, fd);
  const int rc = modbus_receive(ctx, query);
  if (rc > 0) {
    stats_.requests++;
    handle(fd, query, rc);
  }
  return rc;  // 0: not addressed to us (RTU only), nothing to answer
}

std::string Server::serveConnection(int fd) {
  if (running_) return "modbus: the server is listening";
  if (std::string err = prepare(); !err.empty()) return err;
  std::vector<uint8_t> query(MODBUS_TCP_MAX_ADU_LENGTH);
  while (serveRequest(fd, query.data()) >= 0) {
  }
  modbus_set_socket(ctxOf(ctx_), -1);
  return {};
}

void Server::handle(int fd, const uint8_t* q, int length) {
  modbus_t* ctx = ctxOf(ctx_);
  modbus_mapping_t* map = mapOf(mapping_);
  const int off = modbus_get_header_length(ctx);
  const uint8_t fc = q[off];
  auto exception = [&](unsigned code) {
    stats_.exceptions++;
    if (modbus_reply_exception(ctx, q, code) < 0) stats_.dropped++;
  };
  auto reply = [&] {
    if (modbus_reply(ctx, q, length, map) < 0) stats_.dropped++;
  };
  (void)fd;
  switch (fc) {
    case MODBUS_FC_READ_INPUT_REGISTERS: {
      LoopSnapshot s;
      snapshot_.read(s);
      encodeInputs(s, opt_.writes_enabled, limits_.setpoint_limit, static_cast<uint16_t>(opt_.command_timeout_ms),
                   map->tab_input_registers);
      const uint16_t addr = be16(q + off + 1), count = be16(q + off + 3);
      if (count >= 1 && count <= MODBUS_MAX_READ_REGISTERS && static_cast<uint32_t>(addr) + count > in::kCount) {
        exception(MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS);
        return;
      }
      reply();
      return;
    }
    case MODBUS_FC_READ_HOLDING_REGISTERS:
      std::memcpy(map->tab_registers, holding_, sizeof holding_);
      reply();
      return;
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
      if (!opt_.writes_enabled) {
        exception(MODBUS_EXCEPTION_ILLEGAL_FUNCTION);  // read-only server
        return;
      }
      uint16_t addr = 0, count = 0;
      uint16_t values[MODBUS_MAX_WRITE_REGISTERS];
      if (fc == MODBUS_FC_WRITE_SINGLE_REGISTER) {
        if (length < off + 5) {
          exception(MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
          return;
        }
        addr = be16(q + off + 1);
        count = 1;
        values[0] = be16(q + off + 3);
      } else {
        if (length < off + 6) {
          exception(MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
          return;
        }
        addr = be16(q + off + 1);
        count = be16(q + off + 3);
        const uint8_t bytes = q[off + 5];
        if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || bytes != 2 * count || length < off + 6 + bytes) {
          exception(MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
          return;
        }
        for (uint16_t i = 0; i < count; ++i) values[i] = be16(q + off + 6 + 2 * i);
      }
      std::string why;
      RemoteCommand next = holding_cmd_;
      const WriteStatus st = applyWrite(holding_, addr, count, values, limits_, next, why);
      if (st != WriteStatus::kOk) {
        exception(static_cast<unsigned>(st));
        return;
      }
      next.written_ns = linux_hal::monotonicNs();
      next.generation = holding_cmd_.generation + 1;
      holding_cmd_ = next;
      command_.publish(holding_cmd_);
      stats_.writes_accepted++;
      std::memcpy(map->tab_registers, holding_, sizeof holding_);
      reply();
      return;
    }
    case MODBUS_FC_WRITE_AND_READ_REGISTERS:
    case MODBUS_FC_WRITE_SINGLE_COIL:
    case MODBUS_FC_WRITE_MULTIPLE_COILS:
    case MODBUS_FC_MASK_WRITE_REGISTER:
      exception(MODBUS_EXCEPTION_ILLEGAL_FUNCTION);  // not part of this map
      return;
    default:
      // Coil/discrete reads hit an empty table (illegal address), unknown codes get illegal function: both
      // answered by libmodbus itself.
      reply();
      return;
  }
}

nlohmann::json Server::statsJson() const {
  return {{"port", port_},
          {"connections", stats_.connections.load()},
          {"refused_connections", stats_.refused_connections.load()},
          {"requests", stats_.requests.load()},
          {"exceptions", stats_.exceptions.load()},
          {"writes_accepted", stats_.writes_accepted.load()},
          {"dropped_connections", stats_.dropped.load()}};
}

LoopPort::LoopPort(Server& server, const ServerOptions& options, uint16_t device_type, uint16_t sample_count,
                   uint16_t setpoint_count)
    : server_(server), timeout_ns_(static_cast<uint64_t>(options.command_timeout_ms) * 1000000ull) {
  snap_.device_type = device_type;
  snap_.sample_count = sample_count;
  snap_.setpoint_count = setpoint_count;
}

bool LoopPort::overrideCommand(protocol::Command& cmd, uint64_t now_ns) {
  commanding_ = selectCommand(cmd, now_ns);
  return commanding_;
}

bool LoopPort::selectCommand(protocol::Command& cmd, uint64_t now_ns) {
  RemoteCommand latest;
  if (server_.latestCommand(latest)) {
    remote_ = latest;
    have_remote_ = true;
  }
  timed_out_ = false;
  if (!have_remote_ || remote_.source != ControlSource::kModbus) {
    snap_.source = ControlSource::kController;
    return false;
  }
  if (locked_out_) {
    ++refused_cycles_;
    snap_.source = ControlSource::kController;  // not Modbus: another source holds the device
    return false;
  }
  snap_.source = ControlSource::kModbus;
  ++remote_cycles_;
  if (timeout_ns_ > 0 && now_ns > remote_.written_ns + timeout_ns_) {
    // The lab controller went quiet while holding control: the safe state, not its last setpoints.
    if (!snap_.remote_timed_out) ++remote_timeouts_;
    timed_out_ = true;
    cmd.mode = protocol::Mode::kSafe;
    for (auto& s : cmd.setpoint) s = 0.0f;
    for (auto& g : cmd.gain_scale_permille) g = 1000;
    return true;
  }
  cmd.mode = remote_.mode;
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) {
    cmd.setpoint[i] = remote_.setpoint[i];
    cmd.gain_scale_permille[i] = 1000;
  }
  return true;
}

void LoopPort::publish(const TelemetryFrame& tel, const protocol::Command& cmd, uint64_t cycles, uint64_t overruns,
                       double jitter_us, double cycle_us, uint64_t uptime_ns, uint64_t telemetry_lost, LoopState state) {
  snap_.loop_state = state;
  snap_.remote_timed_out = timed_out_;
  snap_.device_mode = static_cast<uint16_t>(tel.mode);
  snap_.fault_bits = tel.fault_bits;
  snap_.state_flags = tel.state_flags;
  snap_.cycles = static_cast<uint32_t>(cycles);
  snap_.overruns = static_cast<uint32_t>(overruns);
  snap_.uptime_ms = static_cast<uint32_t>(uptime_ns / 1000000ull);
  snap_.telemetry_lost = static_cast<uint32_t>(telemetry_lost);
  snap_.telemetry_seq = tel.seq;
  snap_.jitter_us = static_cast<float>(jitter_us);
  window_max_ = std::max(window_max_, snap_.jitter_us);
  if (++window_n_ >= kWindowCycles) {
    prev_window_max_ = window_max_;
    window_max_ = 0.0f;
    window_n_ = 0;
  }
  snap_.jitter_max_us = std::max(window_max_, prev_window_max_);
  snap_.cycle_time_us = static_cast<float>(cycle_us);
  for (size_t i = 0; i < protocol::kMaxSamples; ++i) snap_.samples[i] = tel.value[i];
  for (size_t i = 0; i < protocol::kMaxSetpoints; ++i) snap_.setpoints_sent[i] = cmd.setpoint[i];
  server_.publish(snap_);
}

}  // namespace phalanx::host::modbus
