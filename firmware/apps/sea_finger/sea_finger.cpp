#include "phalanx/apps/sea_finger.h"

#include <cmath>

#include "phalanx/sea/board.h"

namespace phalanx::apps {
namespace {

constexpr uint16_t kZeroTicks = 64;
constexpr float kTwoPi = 6.2831853f;

float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }
/// One-pole low-pass coefficient for cutoff f_c at step dt.
float lowPassAlpha(float cutoff_hz, float dt_s) { return dt_s / (dt_s + 1.0f / (kTwoPi * cutoff_hz)); }

}  // namespace

SeaFingerApp::SeaFingerApp(const SeaFingerCalibration& calibration, const SeaFingerConfig& config)
    : cal_(calibration), cfg_(config) {
  if (cfg_.joint_ma_samples < 1) cfg_.joint_ma_samples = 1;
  if (cfg_.joint_ma_samples > kSeaMaxMovingAverage) cfg_.joint_ma_samples = kSeaMaxMovingAverage;
  if (cfg_.paper_rate_divider < 1) cfg_.paper_rate_divider = 1;
}

const protocol::DeviceLayout& SeaFingerApp::layout() const { return protocol::kSeaFingerLayout; }

void SeaFingerApp::init(hal::Board& board) {
  board_ = &board;
  zero_ticks_left_ = kZeroTicks;
}

float SeaFingerApp::playWidth(int sea, float tau_abs) const {
  return cfg_.backlash_compensation * (cal_.backlash_base_m[sea] + cal_.backlash_per_Nm_m[sea] * tau_abs);
}

/// An SEA joint's sensor whose raw count froze while the finger moved (frozen_sensor.h): its torque estimate
/// would take a moving joint for a still one, and the SEA would resist the finger unseen. "The finger moved" is
/// read on the chain's redundant and DIP sensors, which move whenever the finger flexes; not on the other SEA's
/// sensor: on the §7.1 rig the two SEA joints are clamped and loaded independently (one still, noise-free in
/// simulation, while the other is driven), and the redundant and DIP sensors sit on an unmoving fixture.
uint16_t SeaFingerApp::frozenJointSensors(const int32_t (&raw)[kSeaJointSensors]) {
  uint16_t faults = 0;
  for (int i = 0; i < kSeaCount; ++i) {
    const int s = cal_.joint_sensor_of_sea[i];
    const bool unchanged = primed_ && raw[s] == joint_raw_[s];
    int32_t related_motion = 0;
    for (int o = kSeaChainSensorsFirst; unchanged && o <= kSeaChainSensorsLast; ++o) {
      const int32_t d = raw[o] - joint_raw_[o];
      related_motion += d < 0 ? -d : d;
    }
    if (joint_frozen_[i].update(unchanged, related_motion, cfg_.joint_stuck)) faults |= protocol::fault::kSensorStuck;
  }
  for (int s = 0; s < kSeaJointSensors; ++s) joint_raw_[s] = raw[s];
  return faults;
}

uint16_t SeaFingerApp::sense(float dt_s) {
  uint16_t faults = 0;
  const hal::AdcInputs& adc = *board_->adc;
  namespace board = sea::board;

  // Joint sensors: plausibility on the raw counts, then the moving average of the last n samples (§7.5).
  const uint8_t n = cfg_.joint_ma_samples;
  if (ma_pos_ >= n) ma_pos_ = 0;
  int32_t raw[kSeaJointSensors];
  for (int s = 0; s < kSeaJointSensors; ++s) {
    raw[s] = adc.read(static_cast<uint8_t>(board::kAdcFirstJoint + s));
    if (raw[s] < cal_.joint_valid_min || raw[s] > cal_.joint_valid_max) faults |= protocol::fault::kSensorRange;
    ma_sum_[s] += raw[s] - ma_buf_[s][ma_pos_];
    ma_buf_[s][ma_pos_] = raw[s];
  }
  faults |= frozenJointSensors(raw);
  ma_pos_ = static_cast<uint8_t>((ma_pos_ + 1) % n);
  if (ma_fill_ < n) ++ma_fill_;
  for (int s = 0; s < kSeaJointSensors; ++s) {
    const float counts = static_cast<float>(ma_sum_[s]) / static_cast<float>(ma_fill_);
    joint_rad_[s] = cal_.joint_centre_rad[s] + (counts - cal_.joint_zero_counts) / cal_.joint_counts_per_rad;
  }

  const float a_joint = lowPassAlpha(cfg_.joint_velocity_filter_hz, dt_s);
  const float a_motor = lowPassAlpha(cfg_.motor_velocity_filter_hz, dt_s);
  int32_t enc[kSeaCount];
  for (int i = 0; i < kSeaCount; ++i) {
    SeaChannelState& c = ch_[i];
    enc[i] = board_->encoders->read(static_cast<uint8_t>(i));
    const float joint = joint_rad_[cal_.joint_sensor_of_sea[i]] - joint_zero_rad_[i];
    const float motor = static_cast<float>(enc[i] - encoder_zero_[i]) * cal_.motor_rad_per_count;
    if (primed_) {
      c.joint_rate_rad_s += a_joint * ((joint - last_joint_[i]) / dt_s - c.joint_rate_rad_s);
      c.motor_rate_rad_s += a_motor * ((motor - last_motor_[i]) / dt_s - c.motor_rate_rad_s);
    }
    last_joint_[i] = joint;
    last_motor_[i] = motor;
    c.joint_rad = joint;
    c.motor_rad = motor;
    const int32_t i_raw = adc.read(static_cast<uint8_t>(board::kAdcFirstCurrent + i));
    c.current_A = (static_cast<float>(i_raw) - cal_.current_zero_counts) / cal_.current_counts_per_A;
    const int32_t lc_raw = adc.read(static_cast<uint8_t>(board::kAdcFirstLoadCell + i));
    c.load_cell_Nm = (static_cast<float>(lc_raw) - load_cell_zero_counts_[i]) / cal_.load_cell_counts_per_Nm;

    // eq 7: τ̂_j = 2k r_j (r_m θ_m − r_j (θ_j − θ_j0)).
    const float k = cal_.spring_N_per_m[i];
    const float rj = cal_.joint_pulley_radius_m;
    const float x_m = cal_.motor_pulley_radius_m * motor;
    c.tau_eq7_Nm = 2.0f * k * rj * (x_m - rj * joint);
    // The same law on the spring-side cable travel: the motor-side travel passes the cable's play first
    // (width b̂ = b_0 + b_1 |τ̂|, §8.1.1 "load-dependent effective backlash").
    const float half = 0.5f * playWidth(i, std::fabs(c.tau_play_Nm));
    c.cable_spring_m = clampf(c.cable_spring_m, x_m - half, x_m + half);
    c.tau_play_Nm = 2.0f * k * rj * (c.cable_spring_m - rj * joint);
    c.tau_hat_Nm = cfg_.controller == SeaControllerKind::kOurs ? c.tau_play_Nm : c.tau_eq7_Nm;

    // Motor-angle watchdog (§6.2), once the encoders have a zero.
    if (zero_ticks_left_ == 0 && std::fabs(motor) > cfg_.motor_angle_limit_rad) faults |= protocol::fault::kMotorAngle;
  }
  primed_ = true;

  // Zeroing: θ_j0 and the load-cell zero are averaged over kZeroTicks with the springs relaxed (outputs off);
  // the encoders are zeroed at the end. The play model starts centred.
  if (zero_ticks_left_ > 0) {
    for (int i = 0; i < kSeaCount; ++i) {
      zero_joint_sum_[i] += joint_rad_[cal_.joint_sensor_of_sea[i]];
      zero_lc_sum_[i] += static_cast<float>(adc.read(static_cast<uint8_t>(board::kAdcFirstLoadCell + i)));
    }
    if (--zero_ticks_left_ == 0) {
      for (int i = 0; i < kSeaCount; ++i) {
        joint_zero_rad_[i] = zero_joint_sum_[i] / static_cast<float>(kZeroTicks);
        load_cell_zero_counts_[i] = zero_lc_sum_[i] / static_cast<float>(kZeroTicks);
        encoder_zero_[i] = enc[i];
        zero_joint_sum_[i] = 0.0f;
        zero_lc_sum_[i] = 0.0f;
        ch_[i] = SeaChannelState{};
      }
      primed_ = false;
      resetControllers();
    }
  }
  return faults;
}

void SeaFingerApp::resetControllers() {
  for (auto& c : ch_) {
    c.integral_rad = 0.0f;
    c.pos_integral_Nm = 0.0f;
    c.tau_desired_rate_Nm_s = 0.0f;
    c.tau_hat_rate_Nm_s = 0.0f;
    c.u_ff_rate_rad_s = 0.0f;
    c.play_side = 0.0f;
    c.play_side_target = 0.0f;
    c.duty = 0.0f;
    c.command_limited = false;
  }
  ctl_primed_ = false;
  paper_phase_ = 0;
  for (auto& t : overtorque_ticks_) t = 0;
  for (auto& t : overcurrent_ticks_) t = 0;
}

uint16_t SeaFingerApp::control(const protocol::Command& cmd, float dt_s) {
  uint16_t faults = 0;
  hal::PwmOutputs& pwm = *board_->pwm;
  // kLock never gets here: on the back-drivable SEA it is the core's safe state (DeviceLayout::passive_lock).
  if (zero_ticks_left_ > 0) {
    // Not zeroed yet: bridges on at zero duty until the zero is known.
    for (int i = 0; i < kSeaCount; ++i) {
      ch_[i].duty = 0.0f;
      pwm.setDuty(static_cast<uint8_t>(i), 0.0f);
    }
    resetControllers();
    return 0;
  }
  const bool ours = cfg_.controller == SeaControllerKind::kOurs;
  const bool run_outer = ours || paper_phase_ == 0;
  const float dt_outer = ours ? dt_s : dt_s * static_cast<float>(cfg_.paper_rate_divider);
  const float a_d = lowPassAlpha(cfg_.torque_derivative_filter_hz, dt_s);
  const float rj = cal_.joint_pulley_radius_m;
  const float rm = cal_.motor_pulley_radius_m;

  for (int i = 0; i < kSeaCount; ++i) {
    SeaChannelState& c = ch_[i];
    const float k = cal_.spring_N_per_m[i];
    const float tau_d = cmd.mode == protocol::Mode::kSetpoint
                            ? clampf(cmd.setpoint[i], -cfg_.max_torque_Nm[i], cfg_.max_torque_Nm[i])
                            : 0.0f;  // transparent: zero torque, the exoskeleton follows the finger
    c.tau_desired_Nm = tau_d;
    if (ctl_primed_) {
      c.tau_desired_rate_Nm_s += a_d * ((tau_d - last_tau_d_[i]) / dt_s - c.tau_desired_rate_Nm_s);
      c.tau_hat_rate_Nm_s += a_d * ((c.tau_hat_Nm - last_tau_hat_[i]) / dt_s - c.tau_hat_rate_Nm_s);
    }
    last_tau_d_[i] = tau_d;
    last_tau_hat_[i] = c.tau_hat_Nm;

    // eq 8 feed-forward: the motor angle at which the ideal SEA (eq 2) delivers y_d at the current joint angle.
    const float joint_ff = ours ? c.joint_rad + cfg_.joint_lead_s * c.joint_rate_rad_s : c.joint_rad;
    // Spring-side cable position at which the ideal SEA (eq 2) delivers y_d at the current joint angle.
    const float x_d = tau_d / (2.0f * k * rj) + rj * joint_ff;
    float u_ff = x_d / rm;
    if (ours) {
      // Inverse of the cable play: to move the spring side towards x_d the motor must hold the play's far edge,
      // b̂/2 beyond x_d in that direction; the play model (sense()) says which edge.
      const float gap = x_d - c.cable_spring_m;
      if (gap > cfg_.backlash_deadband_m) c.play_side_target = 1.0f;
      if (gap < -cfg_.backlash_deadband_m) c.play_side_target = -1.0f;
      const float max_step = 2.0f * dt_s / cfg_.backlash_switch_s;
      c.play_side += clampf(c.play_side_target - c.play_side, -max_step, max_step);
      u_ff += c.play_side * 0.5f * playWidth(i, std::fabs(tau_d)) / rm;
    }
    if (ctl_primed_) c.u_ff_rate_rad_s += a_d * ((u_ff - last_u_ff_[i]) / dt_s - c.u_ff_rate_rad_s);
    last_u_ff_[i] = u_ff;
    c.u_ff_rad = u_ff;

    if (run_outer) {
      // eq 8: u = feed-forward + K_p e + K_d ė + K_i ∫e, e = y_d − ŷ.
      const SeaTorqueGains& g = ours ? cfg_.ours[i] : cfg_.paper[i];
      const float gain = static_cast<float>(cmd.gain_scale_permille[i]) * 1e-3f;
      const float e = tau_d - c.tau_hat_Nm;
      const float e_dot = c.tau_desired_rate_Nm_s - c.tau_hat_rate_Nm_s;
      const float u_unsat_pre = u_ff + gain * (g.kp_rad_per_Nm * e + g.kd_rad_s_per_Nm * e_dot) + c.integral_rad;
      const float i_step = gain * g.ki_rad_per_Nm_s * e * dt_outer;
      // Anti-windup: no integration further into the motor-command clamp.
      const bool push_high = u_unsat_pre >= cfg_.motor_command_limit_rad && i_step > 0.0f;
      const bool push_low = u_unsat_pre <= -cfg_.motor_command_limit_rad && i_step < 0.0f;
      if (!push_high && !push_low) c.integral_rad = clampf(c.integral_rad + i_step, -g.i_limit_rad, g.i_limit_rad);
      const float u = u_ff + gain * (g.kp_rad_per_Nm * e + g.kd_rad_s_per_Nm * e_dot) + c.integral_rad;
      c.command_limited = std::fabs(u) > cfg_.motor_command_limit_rad;
      c.u_rad = clampf(u, -cfg_.motor_command_limit_rad, cfg_.motor_command_limit_rad);
    }

    // Motor position loop → duty.
    const float pos_err = c.u_rad - c.motor_rad;
    const float nkt = cal_.gear_ratio * cal_.torque_constant_Nm_per_A;
    float duty;
    if (ours) {
      const float wc = kTwoPi * cfg_.pos_bandwidth_hz;
      const float v_ref = c.command_limited ? 0.0f : c.u_ff_rate_rad_s;
      const float friction = rm * cal_.sheath_friction * 2.0f * cal_.pretension_N + cal_.coulomb_Nm;
      const float tau_cmd = cal_.inertia_kg_m2 * (wc * wc * pos_err + 2.0f * cfg_.pos_damping * wc * (v_ref - c.motor_rate_rad_s)) +
                            rm * c.tau_hat_Nm / rj +  // spring load on the motor pulley, r_m (T_2 − T_1)
                            friction * std::tanh(v_ref / 0.05f);
      // Armature voltage for that torque plus the back-EMF at the measured speed.
      duty = (cal_.resistance_Ohm * tau_cmd / nkt + nkt * c.motor_rate_rad_s) / cal_.supply_V;
    } else {
      c.pos_integral_Nm = clampf(c.pos_integral_Nm + cfg_.paper_pos_ki_Nm_per_rad_s * pos_err * dt_s, -1.0f, 1.0f);
      const float tau_cmd = cfg_.paper_pos_kp_Nm_per_rad * pos_err + c.pos_integral_Nm -
                            cfg_.paper_pos_kd_Nm_s_per_rad * c.motor_rate_rad_s;
      duty = cal_.resistance_Ohm * tau_cmd / nkt / cal_.supply_V;
    }
    c.duty = clampf(duty, -cfg_.max_duty, cfg_.max_duty);
    pwm.setDuty(static_cast<uint8_t>(i), c.duty);

    overtorque_ticks_[i] = std::fabs(c.tau_hat_Nm) > cfg_.torque_fault_Nm[i] ? static_cast<uint16_t>(overtorque_ticks_[i] + 1)
                                                                            : static_cast<uint16_t>(0);
    if (overtorque_ticks_[i] >= cfg_.torque_fault_ticks) faults |= protocol::fault::kForceLimit;
    overcurrent_ticks_[i] = std::fabs(c.current_A) > cfg_.current_limit_A ? static_cast<uint16_t>(overcurrent_ticks_[i] + 1)
                                                                         : static_cast<uint16_t>(0);
    if (overcurrent_ticks_[i] >= cfg_.current_limit_ticks) faults |= protocol::fault::kCurrentLimit;
  }
  ctl_primed_ = true;
  paper_phase_ = static_cast<uint8_t>((paper_phase_ + 1) % cfg_.paper_rate_divider);
  return faults;
}

void SeaFingerApp::safe() {
  resetControllers();
  for (auto& c : ch_) {
    c.u_rad = c.motor_rad;
    c.tau_desired_Nm = 0.0f;
  }
}

void SeaFingerApp::fillSamples(int16_t* samples) const {
  using protocol::encodeSample;
  using protocol::SampleKind;
  for (int s = 0; s < kSeaJointSensors; ++s) samples[s] = encodeSample(joint_rad_[s], SampleKind::kAngle);
  for (int i = 0; i < kSeaCount; ++i) {
    samples[5 + i] = encodeSample(ch_[i].motor_rad, SampleKind::kAngle);
    samples[7 + i] = encodeSample(ch_[i].tau_hat_Nm, SampleKind::kTorque);
    samples[9 + i] = encodeSample(ch_[i].duty, SampleKind::kDuty);
    samples[11 + i] = encodeSample(ch_[i].load_cell_Nm, SampleKind::kTorque);
  }
}

protocol::ParamStatus SeaFingerApp::getParam(uint16_t id, float& value) const {
  const bool ours = cfg_.controller == SeaControllerKind::kOurs;
  if (id >= sea_param::kKp && id < sea_param::kKp + kSeaCount) {
    value = (ours ? cfg_.ours : cfg_.paper)[id - sea_param::kKp].kp_rad_per_Nm;
    return protocol::ParamStatus::kOk;
  }
  if (id >= sea_param::kKi && id < sea_param::kKi + kSeaCount) {
    value = (ours ? cfg_.ours : cfg_.paper)[id - sea_param::kKi].ki_rad_per_Nm_s;
    return protocol::ParamStatus::kOk;
  }
  if (id >= sea_param::kKd && id < sea_param::kKd + kSeaCount) {
    value = (ours ? cfg_.ours : cfg_.paper)[id - sea_param::kKd].kd_rad_s_per_Nm;
    return protocol::ParamStatus::kOk;
  }
  switch (id) {
    case sea_param::kController: value = static_cast<float>(cfg_.controller); return protocol::ParamStatus::kOk;
    case sea_param::kBacklashCompensation: value = cfg_.backlash_compensation; return protocol::ParamStatus::kOk;
    case sea_param::kJointMovingAverage: value = static_cast<float>(cfg_.joint_ma_samples); return protocol::ParamStatus::kOk;
    case sea_param::kZero: value = static_cast<float>(zero_ticks_left_); return protocol::ParamStatus::kOk;
    default: return protocol::ParamStatus::kUnknownParam;
  }
}

protocol::ParamStatus SeaFingerApp::setParam(uint16_t id, float value) {
  auto bounded = [&](float& field, float lo, float hi) {
    if (!(value >= lo && value <= hi)) return protocol::ParamStatus::kOutOfRange;
    field = value;
    return protocol::ParamStatus::kOk;
  };
  SeaTorqueGains* gains = cfg_.controller == SeaControllerKind::kOurs ? cfg_.ours : cfg_.paper;
  if (id >= sea_param::kKp && id < sea_param::kKp + kSeaCount) return bounded(gains[id - sea_param::kKp].kp_rad_per_Nm, 0.0f, 20.0f);
  if (id >= sea_param::kKi && id < sea_param::kKi + kSeaCount) return bounded(gains[id - sea_param::kKi].ki_rad_per_Nm_s, 0.0f, 2000.0f);
  if (id >= sea_param::kKd && id < sea_param::kKd + kSeaCount) return bounded(gains[id - sea_param::kKd].kd_rad_s_per_Nm, 0.0f, 1.0f);
  switch (id) {
    case sea_param::kController:
      if (value == 0.0f) cfg_.controller = SeaControllerKind::kOurs;
      else if (value == 1.0f) cfg_.controller = SeaControllerKind::kPaper;
      else return protocol::ParamStatus::kOutOfRange;
      resetControllers();
      return protocol::ParamStatus::kOk;
    case sea_param::kBacklashCompensation: return bounded(cfg_.backlash_compensation, 0.0f, 2.0f);
    case sea_param::kJointMovingAverage: {
      if (!(value >= 1.0f && value <= static_cast<float>(kSeaMaxMovingAverage)) || value != std::floor(value)) {
        return protocol::ParamStatus::kOutOfRange;
      }
      cfg_.joint_ma_samples = static_cast<uint8_t>(value);
      for (auto& row : ma_buf_) {
        for (auto& v : row) v = 0;
      }
      for (auto& s : ma_sum_) s = 0;
      ma_pos_ = 0;
      ma_fill_ = 0;
      return protocol::ParamStatus::kOk;
    }
    case sea_param::kZero:
      if (value != 1.0f) return protocol::ParamStatus::kOutOfRange;
      zero_ticks_left_ = kZeroTicks;
      for (int i = 0; i < kSeaCount; ++i) {
        zero_joint_sum_[i] = 0.0f;
        zero_lc_sum_[i] = 0.0f;
      }
      return protocol::ParamStatus::kOk;
    default: return protocol::ParamStatus::kUnknownParam;
  }
}

static_assert(sizeof sea_param::kPersisted / sizeof(uint16_t) == 9 && kSeaCount == 2);

fw::SettingsHistory SeaFingerApp::settingsHistory() const { return fw::settingsHistoryOf(sea_param::kSettingsLayouts); }

}  // namespace phalanx::apps
