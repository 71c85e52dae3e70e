#pragma once
/// Faults firmware-sim injects into the simulated board's inputs on a schedule (`--inject KIND@T[+D]`, issue #21's
/// soak; docs/soak.md): what a real board would see from a failed sensor or a pressed e-stop. The firmware is not
/// told: it has to detect each one itself (sensor plausibility, the e-stop input) and latch its safe state.
///
///   sensor-range@T     from T on, the device's first joint sensor reads an implausible value: the glove's index MCP
///                      Hall sensor and the SEA's MCP joint sensor read 0 counts (an open sensor, below their
///                      plausible minimum), the pen's first encoder jumps by 4 × the largest plausible step per tick
///   sensor-stuck@T     from T on, that sensor holds the value it had at T (a frozen ADC or encoder)
///   estop@T+D          the e-stop input is pressed from T for D seconds, then released
/// T and D are seconds of the board's clock since start-up.
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "phalanx/sim/plant.h"

namespace phalanx::fw_sim {

/// The raw input a sensor fault acts on.
struct InjectableSensor {
  bool encoder = false;        ///< an encoder (else an ADC channel)
  uint8_t channel = 0;
  int32_t open_counts = 0;     ///< ADC: the reading of an open sensor (implausible)
  int32_t jump_counts = 0;     ///< encoder: an implausible jump
};

struct Injection {
  enum class Kind { kSensorRange, kSensorStuck, kEstop } kind = Kind::kEstop;
  uint64_t start_us = 0;
  uint64_t end_us = UINT64_MAX;  ///< estop: release; sensor faults last
};

/// Parses one `--inject` argument; "" or why it is not one (naming the argument).
std::string parseInjection(const std::string& text, Injection& out);

class FaultInjector {
 public:
  FaultInjector(std::vector<Injection> schedule, InjectableSensor sensor)
      : schedule_(std::move(schedule)), held_(schedule_.size(), 0), logged_(schedule_.size(), 0), sensor_(sensor) {}
  /// After the plant wrote the sensor inputs of the tick at now_us: overwrite them as the schedule says, and log
  /// each injection's start and end to `log` ("firmware-sim: INJECT estop started t_us=…", "… ended …").
  void apply(uint64_t now_us, sim::SimIo& io, std::FILE* log);

 private:
  int32_t& input(sim::SimIo& io) const;
  std::vector<Injection> schedule_;
  std::vector<int32_t> held_;      ///< stuck: the value at the start
  std::vector<uint8_t> logged_;    ///< 0 not started, 1 started, 2 ended
  InjectableSensor sensor_;
};

}  // namespace phalanx::fw_sim
