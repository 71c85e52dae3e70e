#pragma once
/// Reference instruments over Modbus: a client for a load-cell / torque-transducer amplifier (Modbus TCP or RTU
/// over a serial line) polled from its own thread, and — for simulation — an amplifier server backed by a value
/// the simulation sets (the plant's true joint torque; the register map and the server are
/// phalanx/linux/modbus_instrument.h). The consumer (bench or loop) only ever reads the latest sample through
/// a wait-free TripleBuffer, with its age, so a slow or dead instrument cannot block it and stale data is detected
/// rather than used.
#include <atomic>
#include <cstdint>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "phalanx/host/modbus/triple_buffer.h"
#include "phalanx/linux/modbus_instrument.h"

namespace YAML {
class Node;
}

namespace phalanx::host::modbus {

// The register map and the simulated amplifier live in phalanx_modbus_instrument (firmware-sim serves one too).
using phalanx::linux_hal::decodeInstrument;
using phalanx::linux_hal::encodeInstrument;
using phalanx::linux_hal::InstrumentConfig;
using phalanx::linux_hal::SimInstrumentServer;
using phalanx::linux_hal::validateInstrumentConfig;
using phalanx::linux_hal::validateRegisterMap;

/// Read `instrument:` YAML into c; "" or "<key>: <problem>" (prefix names the mapping).
std::string loadInstrumentConfig(const YAML::Node& node, const std::string& prefix, InstrumentConfig& c);

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

/// A reading's counters and last error as JSON (what statsJson reports, for a reading kept from earlier).
nlohmann::json readingStatsJson(const InstrumentConfig& cfg, const InstrumentReading& r);

}  // namespace phalanx::host::modbus
