#include "phalanx/host/modbus/instrument.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pty.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <set>
#include <vector>

#include "phalanx/linux/realtime.h"

namespace phalanx::host::modbus {
namespace {

struct Bad {
  std::string what;
};

template <class T>
T get(const YAML::Node& n, const std::string& key, const char* type) {
  if (!n.IsScalar()) throw Bad{key + ": expected a " + type};
  try {
    return n.as<T>();
  } catch (const YAML::Exception&) {
    throw Bad{key + ": expected a " + type + ", got '" + n.Scalar() + "'"};
  }
}

void sleepUntil(uint64_t t_ns) {
  timespec ts{static_cast<time_t>(t_ns / 1000000000ull), static_cast<long>(t_ns % 1000000000ull)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void setError(InstrumentReading& r, const std::string& what) {
  std::snprintf(r.last_error, sizeof r.last_error, "%s", what.c_str());
}

}  // namespace

std::string loadInstrumentConfig(const YAML::Node& node, const std::string& prefix, InstrumentConfig& out) {
  InstrumentConfig c = out;  // out changes only if the whole mapping is valid
  try {
    if (!node.IsMap()) throw Bad{prefix + ": expected a mapping"};
    const std::set<std::string> allowed = {"transport", "host",    "port",       "serial_device", "baud",
                                           "parity",    "data_bits", "stop_bits", "unit_id",       "table",
                                           "address",   "type",    "word_order", "scale",         "offset",
                                           "unit",      "poll_hz", "timeout_ms", "stale_ms"};
    for (const auto& kv : node) {
      const std::string key = kv.first.as<std::string>();
      if (allowed.count(key) == 0) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        throw Bad{prefix + "." + key + ": unknown key (allowed: " + list + ")"};
      }
    }
    auto k = [&](const char* key) { return prefix + "." + key; };
    if (node["transport"]) c.transport = get<std::string>(node["transport"], k("transport"), "string");
    if (node["host"]) c.host = get<std::string>(node["host"], k("host"), "string");
    if (node["port"]) c.port = get<unsigned>(node["port"], k("port"), "port number");
    if (node["serial_device"]) c.serial_device = get<std::string>(node["serial_device"], k("serial_device"), "path");
    if (node["baud"]) c.baud = get<unsigned>(node["baud"], k("baud"), "positive integer");
    if (node["parity"]) {
      const std::string p = get<std::string>(node["parity"], k("parity"), "N, E or O");
      if (p.size() != 1) throw Bad{k("parity") + ": expected N, E or O"};
      c.parity = p[0];
    }
    if (node["data_bits"]) c.data_bits = get<unsigned>(node["data_bits"], k("data_bits"), "7 or 8");
    if (node["stop_bits"]) c.stop_bits = get<unsigned>(node["stop_bits"], k("stop_bits"), "1 or 2");
    if (node["unit_id"]) c.unit_id = get<unsigned>(node["unit_id"], k("unit_id"), "integer");
    if (node["table"]) c.table = get<std::string>(node["table"], k("table"), "string");
    if (node["address"]) c.address = get<unsigned>(node["address"], k("address"), "register address");
    if (node["type"]) c.type = get<std::string>(node["type"], k("type"), "string");
    if (node["word_order"]) c.word_order = get<std::string>(node["word_order"], k("word_order"), "string");
    if (node["scale"]) c.scale = get<double>(node["scale"], k("scale"), "number");
    if (node["offset"]) c.offset = get<double>(node["offset"], k("offset"), "number");
    if (node["unit"]) c.unit = get<std::string>(node["unit"], k("unit"), "string");
    if (node["poll_hz"]) c.poll_hz = get<double>(node["poll_hz"], k("poll_hz"), "number");
    if (node["timeout_ms"]) c.timeout_ms = get<unsigned>(node["timeout_ms"], k("timeout_ms"), "positive integer");
    if (node["stale_ms"]) c.stale_ms = get<unsigned>(node["stale_ms"], k("stale_ms"), "positive integer");
  } catch (const Bad& b) {
    return b.what;
  }
  std::string problem = validateInstrumentConfig(c, prefix);
  if (problem.empty()) out = c;
  return problem;
}

std::string validateInstrumentConfig(const InstrumentConfig& c, const std::string& p) {
  if (c.transport != "tcp" && c.transport != "rtu") return p + ".transport: '" + c.transport + "' is not tcp or rtu";
  if (c.transport == "tcp" && (c.port < 1 || c.port > 65535)) return p + ".port: must be in [1, 65535]";
  if (c.transport == "rtu" && c.serial_device.empty()) return p + ".serial_device: required for rtu";
  if (c.parity != 'N' && c.parity != 'E' && c.parity != 'O') return p + ".parity: must be N, E or O";
  if (c.data_bits != 7 && c.data_bits != 8) return p + ".data_bits: must be 7 or 8";
  if (c.stop_bits != 1 && c.stop_bits != 2) return p + ".stop_bits: must be 1 or 2";
  if (c.unit_id > 247) return p + ".unit_id: must be in [0, 247]";
  if (c.table != "input" && c.table != "holding") return p + ".table: '" + c.table + "' is not input or holding";
  if (c.type != "int16" && c.type != "uint16" && c.type != "int32" && c.type != "uint32" && c.type != "float32") {
    return p + ".type: '" + c.type + "' is not int16, uint16, int32, uint32 or float32";
  }
  if (c.word_order != "big" && c.word_order != "little") return p + ".word_order: must be big or little";
  if (c.address + c.registers() > 65536u) return p + ".address: the value runs past register 65535";
  if (!std::isfinite(c.scale) || c.scale == 0.0) return p + ".scale: must be finite and non-zero";
  if (!std::isfinite(c.offset)) return p + ".offset: must be finite";
  if (!std::isfinite(c.poll_hz) || c.poll_hz < 1.0 || c.poll_hz > 2000.0) return p + ".poll_hz: must be in [1, 2000]";
  if (c.timeout_ms < 1 || c.timeout_ms > 5000) return p + ".timeout_ms: must be in [1, 5000]";
  if (c.stale_ms < 1 || c.stale_ms > 10000) return p + ".stale_ms: must be in [1, 10000]";
  return {};
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

// ---------------------------------------------------------------- client

InstrumentClient::InstrumentClient(const InstrumentConfig& config) : cfg_(config) {}
InstrumentClient::~InstrumentClient() { stop(); }

std::string InstrumentClient::start() {
  if (std::string err = validateInstrumentConfig(cfg_, "instrument"); !err.empty()) return err;
  running_ = true;
  thread_ = std::thread([this] { poll(); });
  return {};
}

void InstrumentClient::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

InstrumentReading InstrumentClient::latest(uint64_t now_ns) {
  buf_.read(last_);
  InstrumentReading r = last_;
  r.age_ns = r.valid && now_ns > r.sample_ns ? now_ns - r.sample_ns : 0;
  r.stale = !r.valid || r.age_ns > static_cast<uint64_t>(cfg_.stale_ms) * 1000000ull;
  return r;
}

nlohmann::json InstrumentClient::statsJson(uint64_t now_ns) {
  const InstrumentReading r = latest(now_ns);
  return {{"transport", cfg_.transport},
          {"polls_ok", r.polls_ok},
          {"errors", r.errors},
          {"timeouts", r.timeouts},
          {"connected", r.connected},
          {"last_error", std::string(r.last_error)}};
}

void InstrumentClient::poll() {
  InstrumentReading state;  // thread-owned; published after every attempt
  modbus_t* ctx = nullptr;
  const auto period_ns = static_cast<uint64_t>(1e9 / cfg_.poll_hz);
  uint64_t next_ns = linux_hal::monotonicNs();
  uint16_t regs[2] = {};
  auto disconnect = [&] {
    if (ctx != nullptr) {
      modbus_close(ctx);
      modbus_free(ctx);
    }
    ctx = nullptr;
    state.connected = false;
  };
  while (running_) {
    if (ctx == nullptr) {
      ctx = cfg_.transport == "tcp"
                ? modbus_new_tcp(cfg_.host.c_str(), static_cast<int>(cfg_.port))
                : modbus_new_rtu(cfg_.serial_device.c_str(), static_cast<int>(cfg_.baud), cfg_.parity,
                                 static_cast<int>(cfg_.data_bits), static_cast<int>(cfg_.stop_bits));
      if (ctx != nullptr) {
        modbus_set_slave(ctx, static_cast<int>(cfg_.unit_id));
        modbus_set_response_timeout(ctx, cfg_.timeout_ms / 1000u, (cfg_.timeout_ms % 1000u) * 1000u);
        modbus_set_byte_timeout(ctx, cfg_.timeout_ms / 1000u, (cfg_.timeout_ms % 1000u) * 1000u);
        modbus_set_error_recovery(ctx, static_cast<modbus_error_recovery_mode>(MODBUS_ERROR_RECOVERY_PROTOCOL));
      }
      if (ctx == nullptr || modbus_connect(ctx) != 0) {
        state.errors++;
        setError(state, std::string("connect: ") + modbus_strerror(errno));
        disconnect();
        buf_.publish(state);
        // Retry at most every 100 ms (never faster than the poll rate), waking early to notice stop().
        const uint64_t retry_ns = linux_hal::monotonicNs() + std::max<uint64_t>(period_ns, 100000000ull);
        while (running_ && linux_hal::monotonicNs() < retry_ns) sleepUntil(std::min<uint64_t>(retry_ns, linux_hal::monotonicNs() + 10000000ull));
        next_ns = linux_hal::monotonicNs();
        continue;
      }
      if (cfg_.transport == "tcp") {
        const int one = 1;
        setsockopt(modbus_get_socket(ctx), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      }
      state.connected = true;
    }
    const int nreg = static_cast<int>(cfg_.registers());
    const int rc = cfg_.table == "input" ? modbus_read_input_registers(ctx, static_cast<int>(cfg_.address), nreg, regs)
                                         : modbus_read_registers(ctx, static_cast<int>(cfg_.address), nreg, regs);
    const uint64_t now = linux_hal::monotonicNs();
    if (rc == nreg) {
      state.value = decodeInstrument(cfg_, regs);
      state.sample_ns = now;
      state.valid = true;
      state.polls_ok++;
    } else {
      const int err = errno;
      state.errors++;
      if (err == ETIMEDOUT) state.timeouts++;
      setError(state, std::string("read: ") + modbus_strerror(err));
      // A Modbus exception leaves the stream in step; anything else (timeout, reset) may not: reconnect.
      const bool exception_reply = err > MODBUS_ENOBASE && err <= MODBUS_ENOBASE + MODBUS_EXCEPTION_GATEWAY_TARGET;
      if (!exception_reply) disconnect();
    }
    buf_.publish(state);
    next_ns += period_ns;
    if (next_ns < now) next_ns = now;  // after a timeout: restart the schedule, no burst of catch-up requests
    sleepUntil(next_ns);
  }
  disconnect();
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
  if (mapping_ == nullptr || listen_fd_ < 0) return std::string("instrument server: cannot listen: ") + modbus_strerror(errno);
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
  ::close(slave);  // the client opens it by name
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

}  // namespace phalanx::host::modbus
