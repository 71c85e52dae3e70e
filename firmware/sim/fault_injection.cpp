#include "phalanx/fw_sim/fault_injection.h"

#include <cmath>
#include <cstdlib>

namespace phalanx::fw_sim {
namespace {

/// Seconds in [0, 86400] from text, all of it a number; false otherwise.
bool parseSeconds(const std::string& text, uint64_t& us) {
  if (text.empty()) return false;
  char* end = nullptr;
  const double s = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || !std::isfinite(s) || s < 0.0 || s > 86400.0) return false;
  us = static_cast<uint64_t>(std::llround(s * 1e6));
  return true;
}

const char* kindName(Injection::Kind k) {
  switch (k) {
    case Injection::Kind::kSensorRange: return "sensor-range";
    case Injection::Kind::kSensorStuck: return "sensor-stuck";
    case Injection::Kind::kEstop: return "estop";
  }
  return "?";
}

}  // namespace

std::string parseInjection(const std::string& text, Injection& out) {
  const std::string where = "--inject '" + text + "': ";
  const size_t at = text.find('@');
  if (at == std::string::npos) return where + "expected KIND@T[+D] (e.g. sensor-range@2.5, estop@1+0.5)";
  const std::string kind = text.substr(0, at);
  std::string when = text.substr(at + 1), length;
  if (const size_t plus = when.find('+'); plus != std::string::npos) {
    length = when.substr(plus + 1);
    when.resize(plus);
  }
  if (kind == "sensor-range") out.kind = Injection::Kind::kSensorRange;
  else if (kind == "sensor-stuck") out.kind = Injection::Kind::kSensorStuck;
  else if (kind == "estop") out.kind = Injection::Kind::kEstop;
  else return where + "unknown kind '" + kind + "' (sensor-range, sensor-stuck, estop)";
  if (!parseSeconds(when, out.start_us)) return where + "the time '" + when + "' is not seconds in [0, 86400]";
  if (out.kind == Injection::Kind::kEstop) {
    uint64_t d = 0;
    if (!parseSeconds(length, d) || d == 0) return where + "an e-stop press needs its length: estop@T+D, D > 0 seconds";
    out.end_us = out.start_us + d;
  } else if (!length.empty()) {
    return where + "a sensor fault lasts to the end: no +D";
  }
  return {};
}

int32_t& FaultInjector::input(sim::SimIo& io) const {
  return sensor_.encoder ? io.encoder[sensor_.channel] : io.adc[sensor_.channel];
}

void FaultInjector::apply(uint64_t now_us, sim::SimIo& io, std::FILE* log) {
  for (size_t i = 0; i < schedule_.size(); ++i) {
    const Injection& j = schedule_[i];
    if (now_us < j.start_us) continue;
    const bool active = now_us < j.end_us;
    const uint8_t phase = active ? 1 : 2;
    if (logged_[i] != phase) {
      if (logged_[i] == 0) held_[i] = input(io);
      if (!active && j.kind == Injection::Kind::kEstop) io.estop_pressed = false;  // released
      logged_[i] = phase;
      std::fprintf(log, "firmware-sim: INJECT %s %s t_us=%llu\n", kindName(j.kind),
                   active ? "started" : "ended", static_cast<unsigned long long>(now_us));
    }
    if (!active) continue;
    switch (j.kind) {
      case Injection::Kind::kEstop: io.estop_pressed = true; break;
      case Injection::Kind::kSensorStuck: input(io) = held_[i]; break;
      case Injection::Kind::kSensorRange:
        if (sensor_.encoder) {
          held_[i] += sensor_.jump_counts;  // a new jump every tick: the encoder's reading is garbage
          input(io) = held_[i];
        } else {
          input(io) = sensor_.open_counts;
        }
        break;
    }
  }
}

}  // namespace phalanx::fw_sim
