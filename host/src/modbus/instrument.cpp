#include "phalanx/host/modbus/instrument.h"

#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <time.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <set>

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

nlohmann::json InstrumentClient::statsJson(uint64_t now_ns) { return readingStatsJson(cfg_, latest(now_ns)); }

nlohmann::json readingStatsJson(const InstrumentConfig& cfg, const InstrumentReading& r) {
  return {{"transport", cfg.transport},
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

}  // namespace phalanx::host::modbus
