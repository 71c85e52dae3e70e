#include "phalanx/apps/glove5.h"

#include "phalanx/geometry_fingerprint.h"

#include "phalanx/control/sincos.h"
#include "phalanx/glove/tendon.h"

#include <cmath>

namespace phalanx::apps {
namespace {

constexpr uint16_t kTareTicks = 64;

float interpolate(const HallTable& t, float counts) {
  if (t.points < 2) return 0.0f;
  if (counts <= t.counts[0]) return t.angle_rad[0];
  for (int i = 1; i < t.points; ++i) {
    if (counts <= t.counts[i]) {
      const float u = (counts - t.counts[i - 1]) / (t.counts[i] - t.counts[i - 1]);
      return t.angle_rad[i - 1] + u * (t.angle_rad[i] - t.angle_rad[i - 1]);
    }
  }
  return t.angle_rad[t.points - 1];
}

/// The chained sines and cosines of α1, α1+α2, α1+α2+α3 with one reduction each (control::sinCos): the C
/// library's sinf and cosf cost most of the glove's control step on the MCU.
glove::ThetaTrig<float> alphaTrig(const float (&alpha)[kGloveJoints]) {
  glove::ThetaTrig<float> tr;
  const float a12 = alpha[0] + alpha[1];
  tr.t123 = a12 + alpha[2];
  const control::SinCos t1 = control::sinCos(alpha[0]), t12 = control::sinCos(a12), t123 = control::sinCos(tr.t123);
  tr.s1 = t1.s;
  tr.c1 = t1.c;
  tr.s12 = t12.s;
  tr.c12 = t12.c;
  tr.s123 = t123.s;
  tr.c123 = t123.c;
  return tr;
}

float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

}  // namespace

Glove5App::Glove5App(const Glove5Calibration& calibration, const Glove5Config& config)
    : cal_(calibration), cfg_(config) {}

const protocol::DeviceLayout& Glove5App::layout() const { return protocol::kGlove5Layout; }

void Glove5App::init(hal::Board& board) { board_ = &board; }

uint16_t Glove5App::sense(float dt_s) {
  uint16_t faults = 0;
  const hal::AdcInputs& adc = *board_->adc;
  int32_t raw[kGloveHallChannels];
  for (int ch = 0; ch < kGloveHallChannels; ++ch) raw[ch] = adc.read(static_cast<uint8_t>(ch));

  for (int f = 0; f < kGloveFingers; ++f) {
    GloveFingerState& s = finger_[f];
    for (int j = 0; j < kGloveJoints; ++j) {
      const int ch = f * kGloveJoints + j;
      if (raw[ch] < cal_.hall_valid_min || raw[ch] > cal_.hall_valid_max) faults |= protocol::fault::kSensorRange;
      const float alpha = interpolate(cal_.hall[ch], static_cast<float>(raw[ch]));
      const float rate = primed_ ? (alpha - last_alpha_[ch]) / dt_s : 0.0f;
      last_alpha_[ch] = alpha;
      s.alpha_rad[j] = alpha;
      s.alpha_rate_rad_per_s[j] = rate_lp_[ch].step(rate, cfg_.velocity_filter_hz, dt_s);

      // Stuck sensor: its raw value froze while the finger's other two sensors kept moving.
      const bool unchanged = primed_ && raw[ch] == last_raw_[ch];
      int32_t related_motion = 0;
      for (int k = 0; unchanged && k < kGloveJoints; ++k) {
        const int other = f * kGloveJoints + k;
        const int32_t d = raw[other] - last_raw_[other];
        if (other != ch) related_motion += d < 0 ? -d : d;
      }
      if (hall_frozen_[ch].update(unchanged, related_motion, cfg_.hall_stuck)) {
        faults |= protocol::fault::kSensorStuck;
      }
    }

    const auto strain_raw = adc.read(static_cast<uint8_t>(kGloveHallChannels + f));
    if (strain_raw <= cal_.strain_saturation_min || strain_raw >= cal_.strain_saturation_max) {
      faults |= protocol::fault::kSensorSaturated;
    }
    const float counts = static_cast<float>(strain_raw);
    if (tare_ticks_left_ > 0) tare_sum_[f] += counts;
    const float force = (counts - cal_.strain_zero_counts[f]) / cal_.strain_counts_per_N[f];
    s.force_N = force_lp_[f].step(force, cfg_.force_filter_hz, dt_s);

    const auto current_raw = adc.read(static_cast<uint8_t>(kGloveHallChannels + kGloveFingers + f));
    s.current_A = (static_cast<float>(current_raw) - cal_.current_zero_counts) / cal_.current_counts_per_A;
  }
  for (int ch = 0; ch < kGloveHallChannels; ++ch) last_raw_[ch] = raw[ch];
  primed_ = true;

  if (tare_ticks_left_ > 0 && --tare_ticks_left_ == 0) {
    tare_refused_mask_ = 0;
    for (int f = 0; f < kGloveFingers; ++f) {
      const float zero = tare_sum_[f] / static_cast<float>(kTareTicks);
      tare_sum_[f] = 0.0f;
      if (std::fabs(zero - cal_.strain_zero_counts[f]) > kTareMaxShift_N * cal_.strain_counts_per_N[f]) {
        tare_refused_mask_ = static_cast<uint8_t>(tare_refused_mask_ | (1u << f));  // loaded pad: keep the zero
      } else {
        cal_.strain_zero_counts[f] = zero;
      }
    }
  }
  return faults;
}

uint16_t Glove5App::control(const protocol::Command& cmd, float dt_s) {
  uint16_t faults = 0;
  hal::PwmOutputs& pwm = *board_->pwm;
  for (int f = 0; f < kGloveFingers; ++f) {
    GloveFingerState& s = finger_[f];
    for (int j = 0; j < kGloveJoints; ++j) {
      if (s.alpha_rad[j] < cfg_.joint_min_rad[f][j] || s.alpha_rad[j] > cfg_.joint_max_rad[f][j]) {
        faults |= protocol::fault::kJointLimit;
      }
    }
    overcurrent_ticks_[f] = std::fabs(s.current_A) > cfg_.current_limit_A
                                ? static_cast<uint16_t>(overcurrent_ticks_[f] + 1)
                                : static_cast<uint16_t>(0);
    if (overcurrent_ticks_[f] >= cfg_.current_limit_ticks) faults |= protocol::fault::kCurrentLimit;

    // Lock, or an active mode entered while the pad is pressed (Glove5Config::engage_max_force_N): motor off,
    // the self-locking worm holds the mechanism (000 §2.2).
    if (cmd.mode == protocol::Mode::kLock) {
      s.engaged = false;
    } else if (!s.engaged) {
      s.engaged = std::fabs(s.force_N) <= cfg_.engage_max_force_N;
    }
    if (!s.engaged) {
      control::pidReset(s.pid);
      s.duty = 0.0f;
      pwm.setDuty(static_cast<uint8_t>(f), 0.0f);
      continue;
    }
    const float desired_N = cmd.mode == protocol::Mode::kSetpoint
                                ? clampf(cmd.setpoint[f], -cfg_.active_force_limit_N, cfg_.active_force_limit_N)
                                : 0.0f;  // transparent: zero force, the glove follows the finger
    const glove::Vec3<float> r = glove::tendonMomentArms(cal_.mech[f], alphaTrig(s.alpha_rad), cal_.pad_transmission);
    float v_ff = 0.0f;
    for (int j = 0; j < kGloveJoints; ++j) v_ff += r[static_cast<size_t>(j)] * s.alpha_rate_rad_per_s[j];
    v_ff *= cfg_.ff_scale;
    const float commanded_gain = static_cast<float>(cmd.gain_scale_permille[f]) * 1e-3f;
    s.gain_scale = commanded_gain < s.gain_scale ? commanded_gain
                                                 : control::minNum(commanded_gain, s.gain_scale + cfg_.gain_scale_rise_per_s * dt_s);
    const float gain = s.gain_scale;
    const float sign = cal_.force_per_duty_sign;
    const float v_fb = sign * control::pidStep(cfg_.force_pid, s.pid, sign * s.force_N, sign * desired_N, dt_s, 0.0f, gain);
    s.tendon_velocity_m_per_s = v_ff + v_fb;
    const float motor_rad_per_s = s.tendon_velocity_m_per_s * cal_.motor_rad_per_tendon_m;
    const float duty = motor_rad_per_s * cal_.duty_per_motor_rad_per_s + cfg_.ir_compensation * cal_.duty_per_A * s.current_A;
    s.duty = clampf(duty, -cfg_.max_duty, cfg_.max_duty);
    pwm.setDuty(static_cast<uint8_t>(f), s.duty);
  }
  return faults;
}

void Glove5App::safe() {
  for (auto& s : finger_) {
    control::pidReset(s.pid);
    s.duty = 0.0f;
    s.gain_scale = 1.0f;
    s.engaged = false;
  }
  for (auto& n : overcurrent_ticks_) n = 0;
}

void Glove5App::fillSamples(int16_t* samples) const {
  using protocol::encodeSample;
  using protocol::SampleKind;
  for (int f = 0; f < kGloveFingers; ++f) {
    for (int j = 0; j < kGloveJoints; ++j) {
      samples[f * kGloveJoints + j] = encodeSample(finger_[f].alpha_rad[j], SampleKind::kAngle);
    }
    samples[kGloveHallChannels + f] = encodeSample(finger_[f].force_N, SampleKind::kForce);
    samples[kGloveHallChannels + kGloveFingers + f] = encodeSample(finger_[f].duty, SampleKind::kDuty);
  }
}

protocol::ParamStatus Glove5App::getParam(uint16_t id, float& value) const {
  if (id >= glove5_param::kGeometryFingerprintBase && id < glove5_param::kGeometryFingerprintBase + kGloveFingers) {
    value = static_cast<float>(geometryFingerprint(cal_.mech[id - glove5_param::kGeometryFingerprintBase]));
    return protocol::ParamStatus::kOk;
  }
  switch (id) {
    case glove5_param::kForceKp: value = cfg_.force_pid.kp; return protocol::ParamStatus::kOk;
    case glove5_param::kForceKi: value = cfg_.force_pid.ki; return protocol::ParamStatus::kOk;
    case glove5_param::kForceKd: value = cfg_.force_pid.kd; return protocol::ParamStatus::kOk;
    case glove5_param::kFeedForwardScale: value = cfg_.ff_scale; return protocol::ParamStatus::kOk;
    case glove5_param::kTare:
      value = tare_ticks_left_ > 0 ? static_cast<float>(tare_ticks_left_) : -static_cast<float>(tare_refused_mask_);
      return protocol::ParamStatus::kOk;
    default: return protocol::ParamStatus::kUnknownParam;
  }
}

protocol::ParamStatus Glove5App::setParam(uint16_t id, float value) {
  if (id >= glove5_param::kGeometryFingerprintBase && id < glove5_param::kGeometryFingerprintBase + kGloveFingers) {
    return protocol::ParamStatus::kReadOnly;
  }
  auto bounded = [&](float& field, float lo, float hi) {
    if (value < lo || value > hi) return protocol::ParamStatus::kOutOfRange;
    field = value;
    return protocol::ParamStatus::kOk;
  };
  switch (id) {
    case glove5_param::kForceKp: return bounded(cfg_.force_pid.kp, 0.0f, 10.0f);
    case glove5_param::kForceKi: return bounded(cfg_.force_pid.ki, 0.0f, 1000.0f);
    case glove5_param::kForceKd: return bounded(cfg_.force_pid.kd, 0.0f, 1.0f);
    case glove5_param::kFeedForwardScale: return bounded(cfg_.ff_scale, 0.0f, 2.0f);
    case glove5_param::kTare:
      if (value != 1.0f) return protocol::ParamStatus::kOutOfRange;
      tare_ticks_left_ = kTareTicks;
      for (auto& s : tare_sum_) s = 0.0f;
      return protocol::ParamStatus::kOk;
    default: return protocol::ParamStatus::kUnknownParam;
  }
}

static_assert(sizeof glove5_param::kPersisted / sizeof(uint16_t) == 4);

fw::SettingsHistory Glove5App::settingsHistory() const { return fw::settingsHistoryOf(glove5_param::kSettingsLayouts); }

}  // namespace phalanx::apps
