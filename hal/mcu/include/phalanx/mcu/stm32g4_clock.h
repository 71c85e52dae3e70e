#pragma once
/// STM32G4 clock-tree arithmetic (RM0440 rev 8, §7 RCC and §3.3.3 flash read access latency), pure functions
/// that compile on the host so the register values the board writes are unit-tested.
///   SYSCLK = f_src / M × N / R with M ∈ 1..16, N ∈ 8..127, R ∈ {2, 4, 6, 8},
///   f_src / M ∈ [2.66, 16] MHz (PLL input), f_src / M × N ∈ [96, 344] MHz (VCO), SYSCLK ≤ 170 MHz.
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

constexpr uint32_t kMaxSysclkHz = 170000000u;
constexpr uint32_t kBoostThresholdHz = 150000000u;  ///< above this, range 1 boost mode (PWR_CR5.R1MODE = 0)
constexpr uint32_t kPllInMinHz = 2660000u;
constexpr uint32_t kPllInMaxHz = 16000000u;
constexpr uint32_t kVcoMinHz = 96000000u;
constexpr uint32_t kVcoMaxHz = 344000000u;

struct PllConfig {
  bool ok = false;
  uint32_t m = 0, n = 0, r = 0;
  uint32_t vco_hz = 0;
  uint32_t sysclk_hz = 0;
};

/// First exact PLL setting for target_hz from a source of src_hz, preferring the smallest M (highest PLL input
/// frequency, lowest jitter) and then the smallest R (lowest VCO). ok = false when no exact setting exists.
constexpr PllConfig pllFor(uint32_t src_hz, uint32_t target_hz) {
  PllConfig best{};
  if (target_hz == 0 || target_hz > kMaxSysclkHz) return best;
  for (uint32_t m = 1; m <= 16; ++m) {
    if (src_hz % m != 0) continue;
    const uint32_t in = src_hz / m;
    if (in < kPllInMinHz || in > kPllInMaxHz) continue;
    for (uint32_t r = 2; r <= 8; r += 2) {
      const uint64_t vco = static_cast<uint64_t>(target_hz) * r;
      if (vco < kVcoMinHz || vco > kVcoMaxHz || vco % in != 0) continue;
      const uint64_t n = vco / in;
      if (n < 8 || n > 127) continue;
      best.ok = true;
      best.m = m;
      best.n = static_cast<uint32_t>(n);
      best.r = r;
      best.vco_hz = static_cast<uint32_t>(vco);
      best.sysclk_hz = target_hz;
      return best;
    }
  }
  return best;
}

/// RCC_PLLCFGR value: PLLSRC = HSE (0b11), PLLM = M−1 [7:4], PLLN [14:8], PLLREN [24], PLLR = R/2−1 [26:25].
constexpr uint32_t pllcfgrHse(const PllConfig& p) {
  return 0x3u | ((p.m - 1u) << 4) | (p.n << 8) | (1u << 24) | (((p.r / 2u) - 1u) << 25);
}

/// Flash wait states (FLASH_ACR.LATENCY) for an HCLK in voltage range 1 (RM0440 Table 9): boost mode allows
/// 34 MHz per wait state up to 170 MHz, normal mode 30 MHz per wait state up to 150 MHz. Returns −1 if the
/// frequency is not allowed in that mode.
constexpr int flashWaitStates(uint32_t hclk_hz, bool boost) {
  const uint32_t step = boost ? 34000000u : 30000000u;
  const uint32_t max = boost ? kMaxSysclkHz : kBoostThresholdHz;
  if (hclk_hz == 0 || hclk_hz > max) return -1;
  return static_cast<int>((hclk_hz - 1u) / step);
}

constexpr bool needsBoost(uint32_t hclk_hz) { return hclk_hz > kBoostThresholdHz; }

/// SysTick reload for a tick rate (24-bit counter, counts reload+1 core clocks per period); 0 if impossible.
constexpr uint32_t systickReload(uint32_t core_hz, uint32_t rate_hz) {
  if (rate_hz == 0 || core_hz % rate_hz != 0) return 0;
  const uint32_t ticks = core_hz / rate_hz;
  return (ticks >= 2 && ticks <= 0x1000000u) ? ticks - 1u : 0;
}

}  // namespace phalanx::mcu::stm32g4
