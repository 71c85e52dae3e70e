#pragma once
/// Reference instruments over Modbus: a client for a load-cell / torque-transducer amplifier (Modbus TCP or RTU
/// over a serial line) polled from its own thread, and — for simulation — an amplifier server backed by a value
/// the simulation sets (the plant's true joint torque). The consumer (bench or loop) only ever reads the latest
/// sample through a wait-free TripleBuffer, with its age, so a slow or dead instrument cannot block it and stale
/// data is detected rather than used.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "phalanx/host/modbus/triple_buffer.h"

namespace YAML {
class Node;
}

namespace phalanx::host::modbus {

/// Where the value lives on the amplifier and how raw registers become SI units: value = raw · scale + offset.
struct InstrumentConfig {
  std::string transport = "tcp";        ///< tcp | rtu
  std::string host = "127.0.0.1";       ///< tcp
  unsigned port = 502;                  ///< tcp
  std::string serial_device;            ///< rtu: /dev/ttyUSB0 …
  unsigned baud = 115200;               ///< rtu
  char parity = 'N';                    ///< rtu: N | E | O
  unsigned data_bits = 8;               ///< rtu
  unsigned stop_bits = 1;               ///< rtu
  unsigned unit_id = 1;                 ///< Modbus slave/unit id
  std::string table = "input";          ///< input (FC 04) | holding (FC 03)
  unsigned address = 0;                 ///< first register (0-based PDU address)
  std::string type = "int32";           ///< int16 | uint16 | int32 | uint32 | float32
  std::string word_order = "big";       ///< 32-bit values: big (high word first, "ABCD") | little ("CDAB")
  double scale = 1.0;                   ///< SI units per count (float32: usually 1)
  double offset = 0.0;                  ///< SI units added after scaling (tare)
  std::string unit = "N*m";             ///< for reports only
  double poll_hz = 500.0;               ///< request rate
  unsigned timeout_ms = 50;             ///< response timeout of one request
  unsigned stale_ms = 20;               ///< a sample older than this is stale

  unsigned registers() const { return type == "int16" || type == "uint16" ? 1u : 2u; }
};

/// Read `instrument:` YAML into c; "" or "<key>: <problem>" (prefix names the mapping).
std::string loadInstrumentConfig(const YAML::Node& node, const std::string& prefix, InstrumentConfig& c);
std::string validateInstrumentConfig(const InstrumentConfig& c, const std::string& prefix);

/// Raw registers → SI value per the map (decode), and SI value → registers (what a simulated amplifier sends).
double decodeInstrument(const InstrumentConfig& c, const uint16_t* regs);
void encodeInstrument(const InstrumentConfig& c, double value, uint16_t* regs);

struct InstrumentReading {
  bool valid = false;       ///< at least one sample was read
  bool stale = true;        ///< no sample, or the latest is older than stale_ms
  double value = 0.0;       ///< SI
  uint64_t sample_ns = 0;   ///< monotonic time the response arrived
  uint64_t age_ns = 0;
  uint64_t polls_ok = 0, errors = 0, timeouts = 0;
  bool connected = false;
  char last_error[96] = {};
};

class InstrumentClient {
 public:
  explicit InstrumentClient(const InstrumentConfig& config);
  ~InstrumentClient();
  InstrumentClient(const InstrumentClient&) = delete;
  InstrumentClient& operator=(const InstrumentClient&) = delete;

  /// Start the polling thread (connection problems are reported through readings, not here). "" or the problem
  /// with the configuration.
  std::string start();
  void stop();
  /// The latest sample and its age at now_ns. Wait-free; call from any one consumer thread.
  InstrumentReading latest(uint64_t now_ns);
  nlohmann::json statsJson(uint64_t now_ns);

 private:
  void poll();
  InstrumentConfig cfg_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  TripleBuffer<InstrumentReading> buf_;
  InstrumentReading last_{};
};

/// A simulated amplifier: a Modbus TCP (or RTU over a pseudo-terminal) server exposing set() as the configured
/// register(s). Its own thread; set() is wait-free.
class SimInstrumentServer {
 public:
  explicit SimInstrumentServer(const InstrumentConfig& map);
  ~SimInstrumentServer();
  SimInstrumentServer(const SimInstrumentServer&) = delete;
  SimInstrumentServer& operator=(const SimInstrumentServer&) = delete;

  /// Serve Modbus TCP on 127.0.0.1:port (0: a free port, see port()). "" or the problem.
  std::string startTcp(unsigned port = 0);
  /// Serve Modbus RTU on a new pseudo-terminal; slave_path is the device a client opens. "" or the problem.
  std::string startRtu(std::string& slave_path);
  void stop();
  unsigned port() const { return port_; }
  void set(double value_si) { value_.store(value_si, std::memory_order_relaxed); }
  /// false: receive requests but never answer (a hung amplifier), for timeout handling.
  void setResponsive(bool responsive) { responsive_.store(responsive); }
  uint64_t requests() const { return requests_.load(); }

 private:
  void serveTcp();
  void serveRtu();
  InstrumentConfig map_;
  void* ctx_ = nullptr;
  void* mapping_ = nullptr;
  int listen_fd_ = -1;
  int pty_master_ = -1;
  unsigned port_ = 0;
  std::atomic<bool> running_{false};
  std::atomic<bool> responsive_{true};
  std::atomic<double> value_{0.0};
  std::atomic<uint64_t> requests_{0};
  std::thread thread_;
};

}  // namespace phalanx::host::modbus
