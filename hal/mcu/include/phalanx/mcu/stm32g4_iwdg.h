#pragma once
/// Independent watchdog timing (RM0440 §42 IWDG): clocked by the 32 kHz LSI through a prescaler 4·2^PR
/// (PR 0..6 → /4 … /256) into a 12-bit down-counter reloaded with RLR: timeout = 4·2^PR·(RLR + 1) / f_LSI.
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

constexpr uint32_t kLsiHz = 32000u;

struct IwdgConfig {
  bool ok = false;
  uint8_t pr = 0;
  uint16_t rlr = 0;
  uint32_t timeout_us = 0;  ///< nominal (the LSI spreads about ±5 % over temperature)
};

/// Smallest prescaler whose 12-bit reload reaches the timeout (finest resolution); rounds the reload down so the
/// watchdog never fires later than asked at nominal LSI.
constexpr IwdgConfig iwdgFor(uint32_t timeout_us, uint32_t lsi_hz = kLsiHz) {
  IwdgConfig c{};
  for (uint8_t pr = 0; pr <= 6; ++pr) {
    const uint64_t div = 4ull << pr;
    const uint64_t counts = static_cast<uint64_t>(timeout_us) * lsi_hz / (div * 1000000ull);
    if (counts == 0) return c;  // shorter than one tick at the finest prescaler
    if (counts > 4096u) continue;
    c.ok = true;
    c.pr = pr;
    c.rlr = static_cast<uint16_t>(counts - 1u);
    c.timeout_us = static_cast<uint32_t>(counts * div * 1000000ull / lsi_hz);
    return c;
  }
  return c;
}

}  // namespace phalanx::mcu::stm32g4
