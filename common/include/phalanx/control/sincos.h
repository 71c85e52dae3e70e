#pragma once
/// Sine and cosine of one angle in single precision, for the firmware's 1 kHz path (the glove's feed-forward
/// moment arms, firmware/apps/glove5). On the Cortex-M4 the C library's sinf and cosf each reduce the argument
/// again and cost 60–100 instructions; this computes both from one reduction and two short polynomials, the
/// same on the MCU and in firmware-sim. Accuracy: within 2.5e-7 of the exact values over ±4π (measured 8.3e-8)
/// (tests/unit/sincos_test.cpp); not for the host's models, which keep std::sin/std::cos in double.
#include <cstdint>
#include <limits>

namespace phalanx::control {

struct SinCos {
  float s = 0.0f, c = 1.0f;
};

/// sin x and cos x. |x| > 1e4 or NaN: both NaN (no angle of a device's joint is that large).
inline SinCos sinCos(float x) {
  if (!(x <= 1.0e4f && x >= -1.0e4f)) {
    return {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::quiet_NaN()};
  }
  // x = k·π/2 + r, |r| ≤ π/4 (a little more at the rounding edge), with π/2 split in three parts whose first two
  // have short mantissas, so that k·part is exact for |k| < 2^13 and the subtractions lose nothing.
  constexpr float kTwoOverPi = 0.636619772f;
  constexpr float kPiO2A = 1.5703125f;               // 201/128
  constexpr float kPiO2B = 4.8351287841796875e-4f;   // 0x1.fb0p-12, 11 bits
  constexpr float kPiO2C = 3.13916473e-7f;           // π/2 − A − B
  const float kf = x * kTwoOverPi;
  const int32_t k = static_cast<int32_t>(kf + (kf >= 0.0f ? 0.5f : -0.5f));
  const float fk = static_cast<float>(k);
  const float r = ((x - fk * kPiO2A) - fk * kPiO2B) - fk * kPiO2C;
  // Taylor polynomials on |r| ≤ π/4: truncation below 2e-9 (sine, to r^9) and 2e-10 (cosine, to r^10).
  const float z = r * r;
  const float sr = r + r * z * (-1.0f / 6 + z * (1.0f / 120 + z * (-1.0f / 5040 + z * (1.0f / 362880))));
  const float cr = 1.0f + z * (-0.5f + z * (1.0f / 24 + z * (-1.0f / 720 + z * (1.0f / 40320 + z * (-1.0f / 3628800)))));
  switch (k & 3) {
    case 0: return {sr, cr};
    case 1: return {cr, -sr};
    case 2: return {-sr, -cr};
    default: return {-cr, sr};
  }
}

}  // namespace phalanx::control
