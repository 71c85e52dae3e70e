#pragma once
/// Advanced-control timer (TIM1/TIM8) and encoder arithmetic for the STM32G4 (RM0440 §28 TIM1/TIM8/TIM20),
/// pure functions tested on the host.
///
/// Center-aligned PWM (CR1.CMS = 01): the counter runs 0 → ARR → 0, so one PWM period is 2·ARR timer ticks:
///   f_pwm = f_tim / ((PSC + 1) · 2 · ARR).
/// PWM mode 1 drives the output active while CNT < CCR on both slopes, so duty = CCR / ARR and the pulse is
/// centred on the counter underflow, where the ADC is triggered (TRGO on update) between switching edges.
#include <cstdint>

namespace phalanx::mcu::stm32g4 {

struct PwmTiming {
  bool ok = false;
  uint16_t psc = 0;   ///< prescaler register (divides by psc + 1)
  uint16_t arr = 0;   ///< auto-reload: CCR resolution is arr steps
  uint32_t actual_hz = 0;
};

/// Timer setting for a center-aligned PWM frequency, smallest prescaler first (best duty resolution).
constexpr PwmTiming centerAlignedPwm(uint32_t tim_hz, uint32_t pwm_hz) {
  PwmTiming t{};
  if (pwm_hz == 0 || tim_hz == 0) return t;
  for (uint32_t psc = 0; psc <= 0xFFFFu; ++psc) {
    const uint64_t denom = static_cast<uint64_t>(psc + 1u) * 2u * pwm_hz;
    const uint64_t arr = (static_cast<uint64_t>(tim_hz) + denom / 2u) / denom;  // rounded
    if (arr < 2u) return t;
    if (arr > 0xFFFFu) continue;
    t.ok = true;
    t.psc = static_cast<uint16_t>(psc);
    t.arr = static_cast<uint16_t>(arr);
    t.actual_hz = static_cast<uint32_t>(tim_hz / (static_cast<uint64_t>(psc + 1u) * 2u * arr));
    return t;
  }
  return t;
}

/// Compare value for |duty| (NaN → 0), clamped to [0, max_duty]·ARR, rounded to nearest.
constexpr uint16_t dutyToCcr(float duty, uint16_t arr, float max_duty = 1.0f) {
  float d = duty < 0.0f ? -duty : duty;
  if (!(d == d)) d = 0.0f;
  if (d > max_duty) d = max_duty;
  if (d > 1.0f) d = 1.0f;
  const float c = d * static_cast<float>(arr) + 0.5f;
  return static_cast<uint16_t>(c >= static_cast<float>(arr) ? arr : static_cast<uint16_t>(c));
}

/// Dead-time generator field BDTR.DTG[7:0] for at least dead_ticks timer-kernel ticks (t_DTS = 1/f_tim, CKD = 0),
/// RM0440 §28.6.20: 0xxxxxxx → DTG·t; 10xxxxxx → (64+DTG[5:0])·2t; 110xxxxx → (32+DTG[4:0])·8t;
/// 111xxxxx → (32+DTG[4:0])·16t. Rounds up (never less dead time than asked); saturates at 1008 ticks.
struct DeadTime {
  uint8_t dtg = 0;
  uint32_t ticks = 0;  ///< dead time actually programmed
};
constexpr DeadTime deadTimeDtg(uint32_t dead_ticks) {
  if (dead_ticks <= 127u) return {static_cast<uint8_t>(dead_ticks), dead_ticks};
  if (dead_ticks <= 254u) {
    const uint32_t k = (dead_ticks + 1u) / 2u - 64u;
    return {static_cast<uint8_t>(0x80u | k), (64u + k) * 2u};
  }
  if (dead_ticks <= 504u) {
    const uint32_t k = (dead_ticks + 7u) / 8u - 32u;
    return {static_cast<uint8_t>(0xC0u | k), (32u + k) * 8u};
  }
  uint32_t k = (dead_ticks + 15u) / 16u;
  k = k < 32u ? 0u : k - 32u;
  if (k > 31u) k = 31u;
  return {static_cast<uint8_t>(0xE0u | k), (32u + k) * 16u};
}

/// Timer ticks for a time in nanoseconds at f_tim, rounded up.
constexpr uint32_t nsToTicks(uint32_t ns, uint32_t tim_hz) {
  return static_cast<uint32_t>((static_cast<uint64_t>(ns) * tim_hz + 999999999u) / 1000000000u);
}

/// Extends a 16-bit encoder-mode counter (TIM3/TIM4) to a running 32-bit count. Correct as long as the shaft
/// moves less than 32767 counts between two update() calls (at 1 kHz: 32.7 M counts/s).
class EncoderExtender {
 public:
  int32_t update(uint16_t raw) {
    if (!primed_) {
      last_ = raw;
      primed_ = true;
      return count_;
    }
    const auto delta = static_cast<int16_t>(static_cast<uint16_t>(raw - last_));
    last_ = raw;
    count_ = static_cast<int32_t>(static_cast<uint32_t>(count_) + static_cast<uint32_t>(static_cast<int32_t>(delta)));
    return count_;
  }
  int32_t count() const { return count_; }

 private:
  uint16_t last_ = 0;
  int32_t count_ = 0;
  bool primed_ = false;
};

}  // namespace phalanx::mcu::stm32g4
