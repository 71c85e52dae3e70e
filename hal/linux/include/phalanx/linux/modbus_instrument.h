#pragma once
/// A Modbus reference instrument (a load-cell / torque-transducer amplifier): where its value lives and how raw
/// registers become SI units (InstrumentConfig), and a simulated amplifier serving a value through that map
/// (SimInstrumentServer). Shared by the host (the instrument client and the bench runner,
/// phalanx/host/modbus/instrument.h) and firmware-sim (--instrument: the plant's truth served by a process the host
/// does not run; docs/modbus.md). Needs libmodbus and threads only.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

namespace phalanx::linux_hal {

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

/// The register map alone (unit_id, table, address, type, word_order, scale, offset): "" or "<prefix>.<key>: <problem>".
std::string validateRegisterMap(const InstrumentConfig& c, const std::string& prefix);
/// The whole client configuration (transport, serial line, polling, and the register map).
std::string validateInstrumentConfig(const InstrumentConfig& c, const std::string& prefix);

/// "key=value,key=value" over the register map's keys (unit_id, table, address, type, word_order, scale, offset)
/// into c, validated; c changes only when the whole list is valid. "" or the problem, named "<prefix>.<key>".
std::string parseRegisterMap(const std::string& list, const std::string& prefix, InstrumentConfig& c);
/// The map in one line, e.g. "unit 1 input register 0 int32 word_order big scale 1e-05 offset 0 N*m".
std::string describeRegisterMap(const InstrumentConfig& c);

/// Raw registers → SI value per the map (decode), and SI value → registers (what a simulated amplifier sends:
/// rounded to the nearest count, saturated at the type's range).
double decodeInstrument(const InstrumentConfig& c, const uint16_t* regs);
void encodeInstrument(const InstrumentConfig& c, double value, uint16_t* regs);

/// A simulated amplifier: a Modbus TCP (or RTU over a pseudo-terminal) server exposing set() as the configured
/// register(s), in both the input and the holding table. Its own thread; set() is wait-free.
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
  int pty_slave_keepalive_ = -1;  ///< rtu: held open so the master never reads as hung up between clients
  unsigned port_ = 0;
  std::atomic<bool> running_{false};
  std::atomic<bool> responsive_{true};
  std::atomic<double> value_{0.0};
  std::atomic<uint64_t> requests_{0};
  std::thread thread_;
};

}  // namespace phalanx::linux_hal
