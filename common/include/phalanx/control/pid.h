#pragma once
/// PID with derivative on measurement, derivative low-pass and conditional-integration anti-windup.
/// Config + State + step(), single precision, freestanding.
#include <cmath>

namespace phalanx::control {

struct PidConfig {
  float kp = 0.0f;
  float ki = 0.0f;            ///< 1/s units of kp
  float kd = 0.0f;            ///< s units of kp
  float d_cutoff_hz = 100.0f; ///< first-order low-pass on the derivative term
  float out_min = -1.0f;
  float out_max = 1.0f;
  float i_limit = 1.0f;       ///< |integral contribution| bound
};

struct PidState {
  float integral = 0.0f;       ///< integral contribution (already multiplied by ki)
  float d_filtered = 0.0f;     ///< filtered derivative of the measurement
  float last_measured = 0.0f;
  float last_error = 0.0f;
  float output = 0.0f;
  bool primed = false;         ///< false until the first step (no derivative kick)
  bool saturated = false;
};

/// std::fmin / std::fmax (a NaN operand yields the other one), written out: on the MCU the C library's fminf
/// and fmaxf classify both operands in two calls, about 40 instructions each, five of them per glove finger.
inline float minNum(float a, float b) {
  if (a != a) return b;
  if (b != b) return a;
  return a < b ? a : b;
}
inline float maxNum(float a, float b) {
  if (a != a) return b;
  if (b != b) return a;
  return a > b ? a : b;
}

/// One step: output = kp·e + ∫ki·e − kd·d(measured)/dt + feed_forward, clamped to [out_min, out_max].
/// The integrator only integrates when that does not push further into saturation (anti-windup).
/// gain_scale multiplies kp, ki and kd (the protocol's per-channel gain scale).
inline float pidStep(const PidConfig& c, PidState& s, float measured, float desired, float dt_s,
                     float feed_forward = 0.0f, float gain_scale = 1.0f) {
  const float e = desired - measured;
  if (!s.primed) {
    s.last_measured = measured;
    s.d_filtered = 0.0f;
    s.primed = true;
  }
  const float d_raw = (measured - s.last_measured) / dt_s;
  const float alpha = dt_s / (dt_s + 1.0f / (6.2831853f * c.d_cutoff_hz));
  s.d_filtered += alpha * (d_raw - s.d_filtered);
  s.last_measured = measured;
  s.last_error = e;

  const float kp = c.kp * gain_scale;
  const float kd = c.kd * gain_scale;
  const float unsat = kp * e + s.integral - kd * s.d_filtered + feed_forward;
  const float i_step = c.ki * gain_scale * e * dt_s;
  const bool pushing_high = unsat >= c.out_max && i_step > 0.0f;
  const bool pushing_low = unsat <= c.out_min && i_step < 0.0f;
  if (!pushing_high && !pushing_low) {
    s.integral = maxNum(-c.i_limit, minNum(c.i_limit, s.integral + i_step));
  }
  const float out = kp * e + s.integral - kd * s.d_filtered + feed_forward;
  s.saturated = out > c.out_max || out < c.out_min;
  s.output = maxNum(c.out_min, minNum(c.out_max, out));
  return s.output;
}

inline void pidReset(PidState& s) { s = PidState{}; }

/// First-order low-pass y += a (x − y), a = dt / (dt + 1/(2π f_c)).
struct LowPass {
  float y = 0.0f;
  bool primed = false;
  float step(float x, float cutoff_hz, float dt_s) {
    if (!primed) {
      y = x;
      primed = true;
      return y;
    }
    const float a = dt_s / (dt_s + 1.0f / (6.2831853f * cutoff_hz));
    y += a * (x - y);
    return y;
  }
};


}  // namespace phalanx::control
