#include "phalanx/host/therapy/sea_device.h"

#include <cmath>

#include "phalanx/host/sea/sea_finger_controller.h"

namespace phalanx::host::therapy {
namespace {

constexpr const char* kJoints[3] = {"mcp", "pip", "dip"};
constexpr double kDeg = M_PI / 180.0;

}  // namespace

std::unique_ptr<SeaTherapyDevice> SeaTherapyDevice::make(const KinematicParams& params, std::string& error) {
  if (!params.segment_lengths_mm.empty()) {
    error = "kinematics." + params.segment_lengths_mm.front().first +
            ": sea_finger takes no profile segment lengths (its subject parameters are estimated by "
            "`phalanx sea-calibrate`, 001 eq 12)";
    return nullptr;
  }
  return std::make_unique<SeaTherapyDevice>();
}

std::string SeaTherapyDevice::channelName(std::size_t c) const { return c < 2 ? kJoints[c] : "?"; }

std::string SeaTherapyDevice::jointName(std::size_t j) const { return j < 3 ? kJoints[j] : "?"; }

std::pair<double, double> SeaTherapyDevice::jointBounds(std::size_t j) const {
  // Physiological flexion ranges of 000 Table 2 (the same finger model as the glove's): MCP [−30, 90]°,
  // PIP [0, 120]°, DIP [0, 80]°.
  switch (j) {
    case 0: return {-30.0 * kDeg, 90.0 * kDeg};
    case 1: return {0.0, 120.0 * kDeg};
    default: return {0.0, 80.0 * kDeg};
  }
}

std::vector<std::string> SeaTherapyDevice::sampleNames() const {
  // kSeaFingerLayout (common/include/phalanx/protocol/devices.h).
  return {"sensor0_exo_mcp_rad", "sensor1_exo_pip_rad", "sensor2_rad", "sensor3_rad", "sensor4_rad",
          "motor_mcp_rad",       "motor_pip_rad",       "sea_torque_mcp_Nm", "sea_torque_pip_Nm",
          "duty_mcp",            "duty_pip",            "load_cell_mcp_Nm",  "load_cell_pip_Nm"};
}

std::vector<std::string> SeaTherapyDevice::setpointNames() const {
  return {"setpoint_exo_torque_mcp_Nm", "setpoint_exo_torque_pip_Nm"};
}

void SeaTherapyDevice::observe(const TelemetryFrame& tel, Observation& out) {
  host::sea::Sensors sensors{};
  for (std::size_t i = 0; i < phalanx::sea::kNumSensors; ++i) {
    sensors[i] = static_cast<double>(tel.value[host::sea::kSampleSensor0 + i]);
  }
  // J̇_n (eq 20) on the device clock, as SeaFingerController: a repeated frame gives dt = 0.
  const double dt_dev = primed_ && tel.device_time_us > last_device_time_us_
                            ? static_cast<double>(tel.device_time_us - last_device_time_us_) * 1e-6
                            : 0.0;
  if (!primed_ || dt_dev > 0.0) last_device_time_us_ = tel.device_time_us;
  primed_ = true;
  const phalanx::sea::Status st = estimator_.update(sensors, dt_dev);
  const host::sea::Data& d = estimator_.data();
  const bool usable = phalanx::sea::isUsable(st);
  const double flex[3] = {-d.theta4_rad, -d.theta8_rad, -d.theta_dip_rad};  // θ is flexion-negative
  for (std::size_t j = 0; j < 3; ++j) {
    out.flexion_rad[j] = usable && std::isfinite(flex[j]) ? flex[j] : 0.0;
    // A chain that needed the least-squares fallback (eq 3–5 could not close: sensor or parameter error) is
    // usable for control but not a measurement of the joint (range limits, range of motion), as the glove's
    // reach-clamped joints.
    out.joint_valid[j] = usable && std::isfinite(flex[j]) && !d.least_squares[j];
  }
  out.q_rad[0] = out.flexion_rad[0];
  out.q_rad[1] = out.flexion_rad[1] + out.flexion_rad[2];
  const host::sea::Vec2 tau_j{static_cast<double>(tel.value[host::sea::kSampleSeaTorque0]),
                              static_cast<double>(tel.value[host::sea::kSampleSeaTorque0 + 1])};
  host::sea::Vec2 tau_f{};
  // eq 9: τ̂_f = J_n^{-T} τ̂_j (+ = extension). The 1e-6 determinant floor is FingerTorqueLimits'.
  const bool have_f = d.J_valid && phalanx::sea::fingerTorqueFromExoTorque(d.J_n, tau_j, 1e-6, tau_f) ==
                                       phalanx::sea::Status::kOk;
  for (std::size_t c = 0; c < 2; ++c) {
    out.effort[c] = have_f && std::isfinite(tau_f[c]) ? tau_f[c] : 0.0;
    out.channel_valid[c] = usable && have_f && std::isfinite(tau_f[c]);
  }
}

void SeaTherapyDevice::commandFromEffort(std::array<double, kMaxChannels>& effort,
                                         std::array<float, kMaxChannels>& setpoint) const {
  const host::sea::Data& d = estimator_.data();
  const bool finite = std::isfinite(effort[0]) && std::isfinite(effort[1]);
  if (!d.J_valid || !finite) {  // no Jacobian this cycle: zero torque, never a stale setpoint
    effort[0] = effort[1] = 0.0;
    setpoint[0] = setpoint[1] = 0.0f;
    return;
  }
  const host::sea::Vec2 tau_j = phalanx::sea::exoTorqueFromFingerTorque(d.J_n, host::sea::Vec2{effort[0], effort[1]});
  double scale = 1.0;
  for (std::size_t i = 0; i < 2; ++i) {
    const double a = std::fabs(tau_j[i]);
    if (!std::isfinite(a)) scale = 0.0;
    else if (a > kExoTorqueLimit_Nm) scale = std::fmin(scale, kExoTorqueLimit_Nm / a);
  }
  for (std::size_t i = 0; i < 2; ++i) {
    effort[i] *= scale;
    setpoint[i] = scale > 0.0 ? static_cast<float>(tau_j[i] * scale) : 0.0f;
  }
}

void SeaTherapyDevice::effortFromCommand(const std::array<float, kMaxChannels>& setpoint,
                                         std::array<double, kMaxChannels>& effort) const {
  const host::sea::Data& d = estimator_.data();
  const host::sea::Vec2 tau_j{static_cast<double>(setpoint[0]), static_cast<double>(setpoint[1])};
  host::sea::Vec2 tau_f{tau_j[0], tau_j[1]};
  if (!d.J_valid || phalanx::sea::fingerTorqueFromExoTorque(d.J_n, tau_j, host::sea::FingerTorqueLimits{}.min_abs_det_Jn, tau_f) != phalanx::sea::Status::kOk) {
    tau_f = tau_j;
  }
  effort[0] = tau_f[0];
  effort[1] = tau_f[1];
}

}  // namespace phalanx::host::therapy
