#include "phalanx/apps/pantograph.h"

#include <cmath>

#include "phalanx/geometry_fingerprint.h"

namespace phalanx::apps {
namespace {

namespace board = pen::board;

float clampf(float v, float lo, float hi) { return v < lo ? lo : (v > hi ? hi : v); }

constexpr float kRadPerCount = 6.28318530718f / board::kEncoderCountsPerRev;

}  // namespace

PantographConfig pantographDefaultConfig() { return PantographConfig{}; }

PantographApp::PantographApp(const PantographConfig& config) : cfg_(config) {}

const protocol::DeviceLayout& PantographApp::layout() const { return protocol::kPantographLayout; }

void PantographApp::init(hal::Board& board) { board_ = &board; }

uint16_t PantographApp::sense(float dt_s) {
  uint16_t faults = 0;
  for (int i = 0; i < kPenJoints; ++i) {
    PenJointState& s = joint_[i];
    const int32_t counts = board_->encoders->read(static_cast<uint8_t>(i));
    const int32_t jump = counts - s.counts;
    if (primed_ && (jump > cfg_.max_counts_per_tick || jump < -cfg_.max_counts_per_tick)) {
      faults |= protocol::fault::kSensorRange;
    }
    const float angle = static_cast<float>(counts) * kRadPerCount;
    const float rate = primed_ ? (angle - s.angle_rad) / dt_s : 0.0f;
    s.counts = counts;
    s.angle_rad = angle;
    s.rate_rad_per_s = rate_lp_[i].step(rate, cfg_.velocity_filter_hz, dt_s);
    const int32_t raw = board_->adc->read(static_cast<uint8_t>(i));
    if (raw <= 0 || raw >= board::kAdcMaxCounts) faults |= protocol::fault::kSensorSaturated;
    s.current_A = static_cast<float>(raw - board::kAdcMidCounts) * board::kAmpsPerCount;
  }
  primed_ = true;
  return faults | watchRigidPen();
}

/// kSensorStuck after ends_inconsistent_ticks ticks in a row whose encoders place the pen's two ends more than the
/// tolerance away from one pen length, or cannot close a five-bar (PantographConfig::ends_inconsistent_ticks). A
/// singular five-bar (outside the soft stops) gives no verdict and ends the run.
uint16_t PantographApp::watchRigidPen() {
  pen::JointVec<float> q{};
  for (size_t i = 0; i < q.size(); ++i) q[i] = model_.q_home_rad[i] + joint_[i].angle_rad;
  const pen::Status s = pen::computeEnds(model_, q, kin_);
  const bool broken = s == pen::Status::kEndsInconsistent || s == pen::Status::kUnreachable;
  inconsistent_ticks_ = broken ? static_cast<uint16_t>(inconsistent_ticks_ < 0xFFFF ? inconsistent_ticks_ + 1 : 0xFFFF) : 0;
  return inconsistent_ticks_ >= cfg_.ends_inconsistent_ticks ? protocol::fault::kSensorStuck : 0;
}

uint16_t PantographApp::control(const protocol::Command& cmd, float /*dt_s*/) {
  uint16_t faults = 0;
  hal::PwmOutputs& pwm = *board_->pwm;
  for (int i = 0; i < kPenJoints; ++i) {
    PenJointState& s = joint_[i];
    if (s.angle_rad < cfg_.joint_min_rad[i] || s.angle_rad > cfg_.joint_max_rad[i]) faults |= protocol::fault::kJointLimit;
    if (std::fabs(s.current_A) > cfg_.overcurrent_A) faults |= protocol::fault::kCurrentLimit;
    // The amplifier should deliver what the last tick commanded; a persistent disagreement is a drive fault.
    const float expected_A = s.torque_cmd_Nm / board::kTorqueConstant_Nm_per_A;
    mismatch_ticks_[i] = std::fabs(s.current_A - expected_A) > cfg_.current_mismatch_A
                             ? static_cast<uint16_t>(mismatch_ticks_[i] + 1)
                             : static_cast<uint16_t>(0);
    if (mismatch_ticks_[i] >= cfg_.current_mismatch_ticks) faults |= protocol::fault::kCurrentLimit;

    float tau = 0.0f;  // kTransparent: no torque (kLock is the core's safe state: the direct-drive pen is back-drivable)
    if (cmd.mode == protocol::Mode::kSetpoint) {
      const float gain = static_cast<float>(cmd.gain_scale_permille[i]) * 1e-3f;
      tau = clampf(cmd.setpoint[i] * gain, -cfg_.torque_limit_Nm[i], cfg_.torque_limit_Nm[i]);
    }
    s.torque_cmd_Nm = tau;
    s.duty = clampf(board::dutyFromTorque(tau), -1.0f, 1.0f);
    pwm.setDuty(static_cast<uint8_t>(i), s.duty);
  }
  return faults;
}

void PantographApp::safe() {
  for (int i = 0; i < kPenJoints; ++i) {
    joint_[i].torque_cmd_Nm = 0.0f;
    joint_[i].duty = 0.0f;
    mismatch_ticks_[i] = 0;
  }
}

void PantographApp::fillSamples(int16_t* samples) const {
  using protocol::encodeSample;
  using protocol::SampleKind;
  for (int i = 0; i < kPenJoints; ++i) {
    samples[i] = encodeSample(joint_[i].angle_rad, SampleKind::kAngle);
    samples[kPenJoints + i] = encodeSample(joint_[i].current_A * board::kTorqueConstant_Nm_per_A, SampleKind::kTorque);
  }
}

protocol::ParamStatus PantographApp::getParam(uint16_t id, float& value) const {
  if (id == pantograph_param::kGeometryFingerprint) {
    value = static_cast<float>(geometryFingerprint(pen::defaultGeometry<float>()));
    return protocol::ParamStatus::kOk;
  }
  if (id >= pantograph_param::kTorqueLimitBase && id < pantograph_param::kTorqueLimitBase + kPenJoints) {
    value = cfg_.torque_limit_Nm[id - pantograph_param::kTorqueLimitBase];
    return protocol::ParamStatus::kOk;
  }
  return protocol::ParamStatus::kUnknownParam;
}

protocol::ParamStatus PantographApp::setParam(uint16_t id, float value) {
  if (id == pantograph_param::kGeometryFingerprint) return protocol::ParamStatus::kReadOnly;
  if (id >= pantograph_param::kTorqueLimitBase && id < pantograph_param::kTorqueLimitBase + kPenJoints) {
    if (!(value > 0.0f && value <= board::kPeakTorque_Nm)) return protocol::ParamStatus::kOutOfRange;
    cfg_.torque_limit_Nm[id - pantograph_param::kTorqueLimitBase] = value;
    return protocol::ParamStatus::kOk;
  }
  return protocol::ParamStatus::kUnknownParam;
}

static_assert(kPenJoints == 6, "one persisted torque limit per joint");

fw::SettingsHistory PantographApp::settingsHistory() const { return fw::settingsHistoryOf(pantograph_param::kSettingsLayouts); }

}  // namespace phalanx::apps
