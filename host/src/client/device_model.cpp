// The client channel's device-model stage: telemetry → model-level state; model-level commands and the compliant
// fallback → raw setpoints, before the limits stage. Per cycle: fixed-size work on preallocated members only.
#include "phalanx/host/client/device_model.h"

#include <cmath>

#include "phalanx/host/sea/sea_finger_controller.h"
#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/sea_device.h"

namespace phalanx::host::client {

namespace pg = phalanx::glove;
namespace pp = phalanx::pen;
using client_wire::CommandKind;
using client_wire::FallbackKind;

namespace {

constexpr double kVelocityCutoffHz = 30.0;  // velocity estimates for damping: encoder steps filtered, 5 ms lag
constexpr size_t kForceSample0 = 15;        // kGlove5Layout: 15..19 pad forces
constexpr size_t kPenTorqueSample0 = 6;     // kPantographLayout: 6..11 measured motor torques

float f32(double v) { return static_cast<float>(v); }

void zeroSetpoints(protocol::Command& cmd) {
  for (auto& s : cmd.setpoint) s = 0.0f;
}

}  // namespace

std::array<pg::Model<double>, 5> ModelGeometry::defaultGlove() {
  std::array<pg::Model<double>, 5> m{};
  for (size_t f = 0; f < 5; ++f) m[f] = pg::defaultModel<double>(static_cast<pg::FingerId>(f));
  return m;
}

DeviceModelStage::DeviceModelStage(const protocol::DeviceLayout& layout, const ModelGeometry& geometry)
    : layout_(layout), geometry_(geometry) {
  if (layout_.type == protocol::DeviceType::kSeaFinger) sea_ = std::make_unique<therapy::SeaTherapyDevice>();
  if (layout_.type == protocol::DeviceType::kPantograph) {
    pen_model_ok_ = pp::makeModel(geometry_.pen, pen_model_) == pp::Status::kOk;
  }
}

DeviceModelStage::~DeviceModelStage() = default;

double DeviceModelStage::lowPass(double dt) const {
  return dt > 0.0 ? dt / (dt + 1.0 / (2.0 * M_PI * kVelocityCutoffHz)) : 0.0;
}

void DeviceModelStage::observe(const TelemetryFrame& tel) {
  const double dt = have_prev_ && tel.device_time_us > last_device_time_us_
                        ? static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6
                        : 0.0;
  if (have_prev_ && dt <= 0.0 && layout_.type != protocol::DeviceType::kSeaFinger) return;  // repeated frame
  switch (layout_.type) {
    case protocol::DeviceType::kGlove5: observeGlove(tel, dt); break;
    case protocol::DeviceType::kSeaFinger: observeSea(tel); break;
    case protocol::DeviceType::kPantograph: observePen(tel, dt); break;
    default: return;
  }
  last_device_time_us_ = tel.device_time_us;
  have_prev_ = true;
}

void DeviceModelStage::observeGlove(const TelemetryFrame& tel, double dt) {
  const double a = lowPass(dt);
  for (size_t f = 0; f < 5; ++f) {
    const pg::Vec3<double> alpha{tel.value[3 * f], tel.value[3 * f + 1], tel.value[3 * f + 2]};
    const bool ok = pg::isUsable(pg::computeFromAlpha(geometry_.glove[f], alpha, glove_data_[f]));
    const pg::Data<double>& d = glove_data_[f];
    glove_.valid[f] = ok ? 1 : 0;
    glove_.pad_force_N[f] = tel.value[kForceSample0 + f];
    for (size_t j = 0; j < 3; ++j) {
      glove_.joint_rad[f][j] = ok ? f32(d.theta_rad[j]) : 0.0f;
      glove_.fingertip[f][j] = ok ? f32(d.O_u_tip[j]) : 0.0f;
    }
    for (size_t k = 0; k < 2; ++k) {
      const double p = d.O_u_tip[k];
      double v = glove_.fingertip_velocity[f][k];
      if (!ok || !have_prev_) v = 0.0;
      else if (dt > 0.0) v += a * ((p - prev_[2 * f + k]) / dt - v);
      glove_.fingertip_velocity[f][k] = f32(v);
      prev_[2 * f + k] = ok ? p : 0.0;
    }
  }
}

void DeviceModelStage::observeSea(const TelemetryFrame& tel) {
  const double dt = have_prev_ && tel.device_time_us > last_device_time_us_
                        ? static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6
                        : 0.0;
  therapy::Observation o{};
  sea_->observe(tel, o);  // 001 eq 3–5 (joint angles) and eq 9 (τ̂_f = J_n^{-T} τ̂_j); keeps J_n for convert()
  const bool ok = o.channel_valid[0] && o.channel_valid[1];
  sea_state_.valid = ok ? 1 : 0;
  const double a = lowPass(dt);
  for (size_t j = 0; j < 3; ++j) {
    const double q = o.flexion_rad[j];
    sea_state_.flexion_rad[j] = f32(q);
    double v = sea_state_.flexion_rate_rad_s[j];
    if (!have_prev_) v = 0.0;
    else if (dt > 0.0) v += a * ((q - prev_[j]) / dt - v);
    sea_state_.flexion_rate_rad_s[j] = f32(v);
    if (dt > 0.0 || !have_prev_) prev_[j] = q;
  }
  for (size_t c = 0; c < 2; ++c) {
    sea_state_.finger_torque_Nm[c] = f32(o.effort[c]);
    sea_state_.exo_torque_Nm[c] = tel.value[host::sea::kSampleSeaTorque0 + c];
  }
}

void DeviceModelStage::observePen(const TelemetryFrame& tel, double dt) {
  pp::JointVec<double> q{};
  for (size_t i = 0; i < pp::kNumJoints; ++i) q[i] = pen_model_.q_home_rad[i] + static_cast<double>(tel.value[i]);
  const bool ok = pen_model_ok_ && pp::isUsable(pp::computeForward(pen_model_, q, pen_kin_));
  pen_.valid = ok ? 1 : 0;
  if (!ok) {
    pen_ = client_wire::PenModelState{};
    pen_wrench_ok_ = false;
    return;
  }
  const pp::Data<double>& k = pen_kin_;
  const double a = lowPass(dt);
  for (size_t i = 0; i < 3; ++i) {
    pen_.centre_m[i] = f32(k.B_p_centre[i]);
    pen_.axis[i] = f32(k.B_axis[i]);
    pen_.tip_m[i] = f32(k.pantograph[pp::kBottom].B_p_tip[i]);
    double v = pen_.velocity_m_s[i];
    if (!have_prev_) v = 0.0;
    else if (dt > 0.0) v += a * ((k.B_p_centre[i] - prev_[i]) / dt - v);
    pen_.velocity_m_s[i] = f32(v);
    prev_[i] = k.B_p_centre[i];
  }
  pen_.theta_x_rad = f32(k.pose.theta_x_rad);
  pen_.theta_z_rad = f32(k.pose.theta_z_rad);
  // Measured wrench: each pantograph's end force f = J⁻ᵀ τ from its measured motor torques, then the statics.
  std::array<host::pen::Vec3d, 2> f{};
  bool fok = true;
  for (size_t p = 0; p < pp::kNumPantographs; ++p) {
    const host::pen::Vec3d tau{tel.value[kPenTorqueSample0 + 3 * p], tel.value[kPenTorqueSample0 + 3 * p + 1],
                               tel.value[kPenTorqueSample0 + 3 * p + 2]};
    fok = host::pen::tipForceFromTorques(k.pantograph[p].J, tau, f[p]) && fok;
  }
  host::pen::PenWrench& w = pen_wrench_;
  w = host::pen::PenWrench{};
  if (fok) host::pen::endForcesToWrench(k, f[pp::kBottom], f[pp::kTop], w);
  pen_wrench_ok_ = fok;
  for (size_t i = 0; i < 3; ++i) {
    pen_.force_N[i] = f32(w.force_N[i]);
    pen_.torque_Nm[i] = f32(w.torque_Nm[i]);
  }
}

void DeviceModelStage::fill(client_wire::StatePayload& s) const {
  switch (layout_.type) {
    case protocol::DeviceType::kGlove5: s.glove = glove_; break;
    case protocol::DeviceType::kSeaFinger: s.sea = sea_state_; break;
    case protocol::DeviceType::kPantograph: s.pen = pen_; break;
    default: break;
  }
}

ConvertStatus DeviceModelStage::convert(CommandKind kind, const float* model, protocol::Command& cmd, float& scale) {
  zeroSetpoints(cmd);
  scale = 1.0f;
  if (kind == CommandKind::kGloveFingertipForce && layout_.type == protocol::DeviceType::kGlove5) {
    // The glove exerts one force component per finger, along the pad normal (docs/glove-model.md).
    ConvertStatus st = ConvertStatus::kExact;
    for (size_t f = 0; f < 5; ++f) {
      if (glove_.valid[f] == 0) {
        if (model[2 * f] != 0.0f || model[2 * f + 1] != 0.0f) st = ConvertStatus::kModelInvalid;
        continue;
      }
      const pg::Vec3<double> n = pg::padNormal<double>(glove_data_[f].O_u_tip[2]);
      cmd.setpoint[f] = f32(static_cast<double>(model[2 * f]) * n[0] + static_cast<double>(model[2 * f + 1]) * n[1]);
    }
    return st;
  }
  if (kind == CommandKind::kSeaFingerTorque && layout_.type == protocol::DeviceType::kSeaFinger) {
    if (sea_state_.valid == 0) return ConvertStatus::kModelInvalid;
    std::array<double, therapy::kMaxChannels> effort{};
    std::array<float, therapy::kMaxChannels> sp{};
    effort[0] = model[0];
    effort[1] = model[1];
    const double before = std::hypot(effort[0], effort[1]);
    sea_->commandFromEffort(effort, sp);  // τ_j,d = J_nᵀ τ_f,d (001 eq 6/11), scaled to |τ_j| ≤ 0.5 N·m
    cmd.setpoint[0] = sp[0];
    cmd.setpoint[1] = sp[1];
    const double after = std::hypot(effort[0], effort[1]);
    if (before > 0.0 && after < before * (1.0 - 1e-9)) {
      scale = f32(after / before);
      return ConvertStatus::kSaturated;
    }
    return ConvertStatus::kExact;
  }
  if (kind == CommandKind::kPenWrench && layout_.type == protocol::DeviceType::kPantograph) {
    if (pen_.valid == 0) return ConvertStatus::kModelInvalid;
    host::pen::PenWrench w{};
    for (size_t i = 0; i < 3; ++i) {
      w.force_N[i] = model[i];
      w.torque_Nm[i] = model[3 + i];
    }
    const host::pen::SplitStatus ss = splitter_.split(pen_kin_, w, split_);
    if (ss != host::pen::SplitStatus::kOk && ss != host::pen::SplitStatus::kInternalForceRedistributed &&
        ss != host::pen::SplitStatus::kScaled) {
      return ConvertStatus::kModelInvalid;
    }
    const float limit = layout_.setpoint_limit;
    for (size_t i = 0; i < pp::kNumJoints; ++i) {
      const float t = f32(split_.tau_Nm[i]);
      cmd.setpoint[i] = t > limit ? limit : (t < -limit ? -limit : t);  // float rounding of a torque at its limit
    }
    scale = f32(split_.scale);
    return ss == host::pen::SplitStatus::kScaled ? ConvertStatus::kSaturated : ConvertStatus::kExact;
  }
  return ConvertStatus::kWrongDevice;
}

ConvertStatus DeviceModelStage::renderSpring(const client_wire::FallbackSpring& spring, protocol::Command& cmd,
                                             float& scale) {
  float model[client_wire::kMaxModelValues] = {};
  const auto& e = spring.element;
  switch (layout_.type) {
    case protocol::DeviceType::kGlove5:
      for (size_t f = 0; f < 5; ++f) {  // F = k (p0 − p) − b v, on the fingertip in {O}
        for (size_t k = 0; k < 2; ++k) {
          model[2 * f + k] = e[f].stiffness * (e[f].target[k] - glove_.fingertip[f][k]) -
                             e[f].damping * glove_.fingertip_velocity[f][k];
        }
      }
      return convert(CommandKind::kGloveFingertipForce, model, cmd, scale);
    case protocol::DeviceType::kSeaFinger:
      for (size_t j = 0; j < 2; ++j) {  // τ_f = k (q − q0) + b q̇: + extends, so it pulls the joint back to q0
        model[j] = e[j].stiffness * (sea_state_.flexion_rad[j] - e[j].target[0]) +
                   e[j].damping * sea_state_.flexion_rate_rad_s[j];
      }
      return convert(CommandKind::kSeaFingerTorque, model, cmd, scale);
    case protocol::DeviceType::kPantograph:
      for (size_t i = 0; i < 3; ++i) {  // F = k (c0 − c) − b v at the pen centre, no moment
        model[i] = e[0].stiffness * (e[0].target[i] - pen_.centre_m[i]) - e[0].damping * pen_.velocity_m_s[i];
      }
      return convert(CommandKind::kPenWrench, model, cmd, scale);
    default: return ConvertStatus::kWrongDevice;
  }
}

bool DeviceModelStage::finite(const client_wire::CommandPayload& c) {
  if (static_cast<uint8_t>(c.kind) >= static_cast<uint8_t>(CommandKind::kCount)) return false;
  if (c.kind != CommandKind::kRaw) {
    for (float v : c.model) {
      if (!std::isfinite(v)) return false;
    }
  }
  if (c.fallback.kind == FallbackKind::kNone) return true;
  if (c.fallback.kind != FallbackKind::kSpring) return false;
  for (const auto& e : c.fallback.element) {
    for (float v : e.target) {
      if (!std::isfinite(v)) return false;
    }
    if (!std::isfinite(e.stiffness) || !std::isfinite(e.damping) || e.stiffness < 0.0f || e.damping < 0.0f) return false;
  }
  return true;
}

}  // namespace phalanx::host::client
