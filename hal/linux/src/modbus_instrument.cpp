#include "phalanx/linux/modbus_instrument.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pty.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace phalanx::linux_hal {
namespace {

bool parseUnsigned(const std::string& s, unsigned long& out) {
  if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos || s.size() > 9) return false;
  out = std::strtoul(s.c_str(), nullptr, 10);
  return true;
}

bool parseNumber(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(s.c_str(), &end);
  return errno == 0 && end == s.c_str() + s.size() && std::isfinite(out);
}

}  // namespace

std::string validateRegisterMap(const InstrumentConfig& c, const std::string& p) {
  if (c.unit_id > 247) return p + ".unit_id: must be in [0, 247]";
  if (c.table != "input" && c.table != "holding") return p + ".table: '" + c.table + "' is not input or holding";
  if (c.type != "int16" && c.type != "uint16" && c.type != "int32" && c.type != "uint32" && c.type != "float32") {
    return p + ".type: '" + c.type + "' is not int16, uint16, int32, uint32 or float32";
  }
  if (c.word_order != "big" && c.word_order != "little") return p + ".word_order: must be big or little";
  if (c.address + c.registers() > 65536u) return p + ".address: the value runs past register 65535";
  if (!std::isfinite(c.scale) || c.scale == 0.0) return p + ".scale: must be finite and non-zero";
  if (!std::isfinite(c.offset)) return p + ".offset: must be finite";
  return {};
}

std::string validateInstrumentConfig(const InstrumentConfig& c, const std::string& p) {
  if (c.transport != "tcp" && c.transport != "rtu") return p + ".transport: '" + c.transport + "' is not tcp or rtu";
  if (c.transport == "tcp" && (c.port < 1 || c.port > 65535)) return p + ".port: must be in [1, 65535]";
  if (c.transport == "rtu" && c.serial_device.empty()) return p + ".serial_device: required for rtu";
  if (c.parity != 'N' && c.parity != 'E' && c.parity != 'O') return p + ".parity: must be N, E or O";
  if (c.data_bits != 7 && c.data_bits != 8) return p + ".data_bits: must be 7 or 8";
  if (c.stop_bits != 1 && c.stop_bits != 2) return p + ".stop_bits: must be 1 or 2";
  if (std::string map = validateRegisterMap(c, p); !map.empty()) return map;
  if (!std::isfinite(c.poll_hz) || c.poll_hz < 1.0 || c.poll_hz > 2000.0) return p + ".poll_hz: must be in [1, 2000]";
  if (c.timeout_ms < 1 || c.timeout_ms > 5000) return p + ".timeout_ms: must be in [1, 5000]";
  if (c.stale_ms < 1 || c.stale_ms > 10000) return p + ".stale_ms: must be in [1, 10000]";
  return {};
}

std::string parseRegisterMap(const std::string& list, const std::string& p, InstrumentConfig& out) {
  InstrumentConfig c = out;  // out changes only if the whole list is valid
  size_t begin = 0;
  while (begin <= list.size()) {
    const size_t end = std::min(list.find(',', begin), list.size());
    const std::string item = list.substr(begin, end - begin);
    begin = end + 1;
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0) return p + ": '" + item + "' is not key=value";
    const std::string key = item.substr(0, eq), value = item.substr(eq + 1);
    const std::string k = p + "." + key;
    if (key == "unit_id" || key == "address") {
      unsigned long n = 0;
      if (!parseUnsigned(value, n) || n > 65535ul) return k + ": expected an integer in [0, 65535], got '" + value + "'";
      (key == "unit_id" ? c.unit_id : c.address) = static_cast<unsigned>(n);
    } else if (key == "scale" || key == "offset") {
      double x = 0.0;
      if (!parseNumber(value, x)) return k + ": expected a number, got '" + value + "'";
      (key == "scale" ? c.scale : c.offset) = x;
    } else if (key == "table") {
      c.table = value;
    } else if (key == "type") {
      c.type = value;
    } else if (key == "word_order") {
      c.word_order = value;
    } else {
      return k + ": unknown key (allowed: unit_id, table, address, type, word_order, scale, offset)";
    }
  }
  std::string problem = validateRegisterMap(c, p);
  if (problem.empty()) out = c;
  return problem;
}

std::string describeRegisterMap(const InstrumentConfig& c) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "unit %u %s register %u %s word_order %s scale %.9g offset %.9g %s", c.unit_id,
                c.table.c_str(), c.address, c.type.c_str(), c.word_order.c_str(), c.scale, c.offset, c.unit.c_str());
  return buf;
}

double decodeInstrument(const InstrumentConfig& c, const uint16_t* r) {
  double raw = 0.0;
  if (c.type == "int16") {
    raw = static_cast<int16_t>(r[0]);
  } else if (c.type == "uint16") {
    raw = r[0];
  } else {
    const uint32_t bits = c.word_order == "big" ? (static_cast<uint32_t>(r[0]) << 16) | r[1]
                                                : (static_cast<uint32_t>(r[1]) << 16) | r[0];
    if (c.type == "int32") {
      raw = static_cast<int32_t>(bits);
    } else if (c.type == "uint32") {
      raw = bits;
    } else {
      float f = 0.0f;
      std::memcpy(&f, &bits, sizeof f);
      raw = f;
    }
  }
  return raw * c.scale + c.offset;
}

void encodeInstrument(const InstrumentConfig& c, double value, uint16_t* r) {
  const double raw = (value - c.offset) / c.scale;
  auto sat = [](double x, double lo, double hi) { return std::min(hi, std::max(lo, std::round(x))); };
  if (c.type == "int16") {
    r[0] = static_cast<uint16_t>(static_cast<int16_t>(sat(raw, -32768.0, 32767.0)));
    return;
  }
  if (c.type == "uint16") {
    r[0] = static_cast<uint16_t>(sat(raw, 0.0, 65535.0));
    return;
  }
  uint32_t bits = 0;
  if (c.type == "int32") {
    bits = static_cast<uint32_t>(static_cast<int32_t>(sat(raw, -2147483648.0, 2147483647.0)));
  } else if (c.type == "uint32") {
    bits = static_cast<uint32_t>(sat(raw, 0.0, 4294967295.0));
  } else {
    const auto f = static_cast<float>(raw);
    std::memcpy(&bits, &f, sizeof bits);
  }
  const auto hi = static_cast<uint16_t>(bits >> 16), lo = static_cast<uint16_t>(bits & 0xFFFFu);
  if (c.word_order == "big") {
    r[0] = hi;
    r[1] = lo;
  } else {
    r[0] = lo;
    r[1] = hi;
  }
}

// ---------------------------------------------------------------- simulated amplifier

SimInstrumentServer::SimInstrumentServer(const InstrumentConfig& map) : map_(map) {}
SimInstrumentServer::~SimInstrumentServer() { stop(); }

std::string SimInstrumentServer::startTcp(unsigned port) {
  modbus_t* ctx = modbus_new_tcp("127.0.0.1", static_cast<int>(port));
  if (ctx == nullptr) return std::string("instrument server: ") + modbus_strerror(errno);
  ctx_ = ctx;
  modbus_set_byte_timeout(ctx, 0, 50000);
  mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, map_.address, map_.registers(), map_.address, map_.registers());
  listen_fd_ = modbus_tcp_listen(ctx, 4);
  if (mapping_ == nullptr || listen_fd_ < 0) {
    return "instrument server: cannot listen on 127.0.0.1:" + std::to_string(port) + ": " + modbus_strerror(errno);
  }
  sockaddr_in sa{};
  socklen_t len = sizeof sa;
  if (getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&sa), &len) == 0) port_ = ntohs(sa.sin_port);
  running_ = true;
  thread_ = std::thread([this] { serveTcp(); });
  return {};
}

std::string SimInstrumentServer::startRtu(std::string& slave_path) {
  int master = -1, slave = -1;
  char name[128] = {};
  if (openpty(&master, &slave, name, nullptr, nullptr) != 0) return std::string("instrument server: openpty: ") + std::strerror(errno);
  termios t{};
  tcgetattr(slave, &t);
  cfmakeraw(&t);
  tcsetattr(slave, TCSANOW, &t);
  // The client opens the slave by name; this descriptor stays open meanwhile. With no slave open the master reads
  // as hung up (select() ready, read() EIO) and serveRtu() would spin: measured 2.5 s of system time in a 3 s
  // firmware-sim run with no client.
  pty_slave_keepalive_ = slave;
  pty_master_ = master;
  slave_path = name;
  modbus_t* ctx = modbus_new_rtu(name, static_cast<int>(map_.baud), map_.parity, static_cast<int>(map_.data_bits),
                                 static_cast<int>(map_.stop_bits));
  if (ctx == nullptr) return std::string("instrument server: ") + modbus_strerror(errno);
  ctx_ = ctx;
  modbus_set_slave(ctx, static_cast<int>(map_.unit_id));
  modbus_set_byte_timeout(ctx, 0, 50000);
  modbus_set_socket(ctx, master);  // never modbus_connect: the master side of the pty is our "serial port"
  mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, map_.address, map_.registers(), map_.address, map_.registers());
  if (mapping_ == nullptr) return "instrument server: cannot allocate the map";
  running_ = true;
  thread_ = std::thread([this] { serveRtu(); });
  return {};
}

void SimInstrumentServer::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
  if (pty_master_ >= 0) ::close(pty_master_);
  pty_master_ = -1;
  if (pty_slave_keepalive_ >= 0) ::close(pty_slave_keepalive_);
  pty_slave_keepalive_ = -1;
  if (mapping_ != nullptr) modbus_mapping_free(static_cast<modbus_mapping_t*>(mapping_));
  mapping_ = nullptr;
  if (ctx_ != nullptr) modbus_free(static_cast<modbus_t*>(ctx_));
  ctx_ = nullptr;
}

namespace {
void refresh(const InstrumentConfig& map, double value, modbus_mapping_t* m) {
  encodeInstrument(map, value, m->tab_input_registers);
  encodeInstrument(map, value, m->tab_registers);
}
}  // namespace

void SimInstrumentServer::serveTcp() {
  auto* ctx = static_cast<modbus_t*>(ctx_);
  auto* m = static_cast<modbus_mapping_t*>(mapping_);
  std::vector<int> clients;
  uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
  while (running_) {
    fd_set rd;
    FD_ZERO(&rd);
    FD_SET(listen_fd_, &rd);
    int maxfd = listen_fd_;
    for (int fd : clients) {
      FD_SET(fd, &rd);
      maxfd = std::max(maxfd, fd);
    }
    timeval tv{0, 20000};
    if (::select(maxfd + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
    if (FD_ISSET(listen_fd_, &rd)) {
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC);
      if (fd >= 0 && clients.size() < 8) {
        const int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        clients.push_back(fd);
      } else if (fd >= 0) {
        ::close(fd);
      }
    }
    for (size_t i = 0; i < clients.size();) {
      if (!FD_ISSET(clients[i], &rd)) {
        ++i;
        continue;
      }
      modbus_set_socket(ctx, clients[i]);
      const int rc = modbus_receive(ctx, q);
      if (rc < 0) {
        ::close(clients[i]);
        clients.erase(clients.begin() + static_cast<long>(i));
        continue;
      }
      requests_++;
      if (rc > 0 && responsive_) {
        refresh(map_, value_.load(std::memory_order_relaxed), m);
        modbus_reply(ctx, q, rc, m);
      }
      ++i;
    }
  }
  for (int fd : clients) ::close(fd);
}

void SimInstrumentServer::serveRtu() {
  auto* ctx = static_cast<modbus_t*>(ctx_);
  auto* m = static_cast<modbus_mapping_t*>(mapping_);
  uint8_t q[MODBUS_RTU_MAX_ADU_LENGTH];
  while (running_) {
    fd_set rd;
    FD_ZERO(&rd);
    FD_SET(pty_master_, &rd);
    timeval tv{0, 20000};
    if (::select(pty_master_ + 1, &rd, nullptr, nullptr, &tv) <= 0) continue;
    const int rc = modbus_receive(ctx, q);
    if (rc < 0) {
      modbus_flush(ctx);  // CRC error or a broken frame: resynchronise on the next request
      continue;
    }
    requests_++;
    if (rc > 0 && responsive_) {
      refresh(map_, value_.load(std::memory_order_relaxed), m);
      modbus_reply(ctx, q, rc, m);
    }
  }
}

}  // namespace phalanx::linux_hal
