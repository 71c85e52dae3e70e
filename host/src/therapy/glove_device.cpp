#include "phalanx/host/therapy/glove_device.h"

#include <cmath>

#include "phalanx/host/glove/glove_controller.h"

namespace phalanx::host::therapy {
namespace {

constexpr const char* kFingers[5] = {"thumb", "index", "middle", "ring", "little"};
constexpr const char* kFingerJoints[3] = {"mcp", "pip", "dip"};
constexpr const char* kThumbJoints[3] = {"cmc", "mcp", "ip"};  // the glove's planar thumb (glove-model.md)
constexpr std::size_t kForceSample0 = 15;                       // kGlove5Layout
constexpr std::size_t kDutySample0 = 20;

}  // namespace

std::unique_ptr<GloveTherapyDevice> GloveTherapyDevice::make(const KinematicParams& params, std::string& error) {
  auto d = std::make_unique<GloveTherapyDevice>();
  for (std::size_t f = 0; f < 5; ++f) {
    d->models_[f] = phalanx::glove::defaultModel<double>(static_cast<phalanx::glove::FingerId>(f));
  }
  for (const auto& [finger, lengths] : params.segment_lengths_mm) {
    const int f = d->channelIndex(finger);
    if (f < 0) {
      error = "kinematics." + finger + ": not a glove finger (thumb, index, middle, ring, little)";
      return nullptr;
    }
    for (std::size_t i = 0; i < 3; ++i) {
      // 5–120 mm: outside any adult or child phalanx (Buchholz et al. 1992 hand-length ratios).
      if (!std::isfinite(lengths[i]) || lengths[i] < 5.0 || lengths[i] > 120.0) {
        error = "kinematics." + finger + ".p" + std::to_string(i + 1) + "_mm: must be in [5, 120] mm";
        return nullptr;
      }
    }
    auto& m = d->models_[static_cast<std::size_t>(f)];
    m.finger.p1_m = lengths[0] * 1e-3;
    m.finger.p2_m = lengths[1] * 1e-3;
    m.finger.p3_m = lengths[2] * 1e-3;
  }
  return d;
}

std::string GloveTherapyDevice::channelName(std::size_t c) const { return c < 5 ? kFingers[c] : "?"; }

double GloveTherapyDevice::effortLimit(std::size_t) const {
  return static_cast<double>(protocol::kGlove5Layout.setpoint_limit);
}

std::string GloveTherapyDevice::jointName(std::size_t j) const {
  if (j >= 15) return "?";
  const std::size_t f = j / 3;
  return std::string(kFingers[f]) + "_" + (f == 0 ? kThumbJoints[j % 3] : kFingerJoints[j % 3]);
}

std::pair<double, double> GloveTherapyDevice::jointBounds(std::size_t j) const {
  // Flexion = −θ; θ ranges are 000 Table 2 (MCP [−90, 30]°, PIP [−120, 0]°, DIP [−80, 0]°).
  const auto& fg = models_[j / 3].finger;
  return {-fg.theta_max_rad[j % 3], -fg.theta_min_rad[j % 3]};
}

std::vector<std::string> GloveTherapyDevice::sampleNames() const {
  std::vector<std::string> v;
  for (std::size_t f = 0; f < 5; ++f) {
    for (int a = 1; a <= 3; ++a) v.push_back("alpha" + std::to_string(a) + "_" + kFingers[f] + "_rad");
  }
  for (std::size_t f = 0; f < 5; ++f) v.push_back(std::string("force_") + kFingers[f] + "_N");
  for (std::size_t f = 0; f < 5; ++f) v.push_back(std::string("duty_") + kFingers[f]);
  return v;
}

void GloveTherapyDevice::observe(const TelemetryFrame& tel, Observation& out) {
  for (std::size_t f = 0; f < 5; ++f) {
    const phalanx::glove::Vec3<double> alpha{static_cast<double>(tel.value[3 * f]),
                                              static_cast<double>(tel.value[3 * f + 1]),
                                              static_cast<double>(tel.value[3 * f + 2])};
    const auto status = phalanx::glove::computeFromAlpha(models_[f], alpha, data_[f]);
    const bool ok = phalanx::glove::isUsable(status);
    // kReachClamped (α a little beyond the finger's reach: sensor error at full extension/flexion) gives a
    // usable but clamped θ: fine for control, not a measurement of the joint (range of motion, range limits).
    const bool exact = status == phalanx::glove::Status::kOk;
    double q = 0.0;
    for (std::size_t j = 0; j < 3; ++j) {
      const double flex = ok ? -data_[f].theta_rad[j] : 0.0;  // θ is flexion-negative (kinematics.h)
      out.flexion_rad[3 * f + j] = flex;
      out.joint_valid[3 * f + j] = exact;
      q += flex;
    }
    out.q_rad[f] = q;
    const double force = static_cast<double>(tel.value[kForceSample0 + f]);
    out.effort[f] = force;  // pad force, + = glove pushes towards extension (kGlove5Layout)
    out.channel_valid[f] = ok && std::isfinite(force);
  }
  (void)kDutySample0;
}

std::string GloveTherapyDevice::startupWarning(uint16_t id, float value) const {
  return glove::tareWarning(id, value);
}

std::unique_ptr<Controller> GloveTherapyDevice::makeGraspController(const std::string& scene, std::string& error) const {
  glove::GloveControllerConfig cfg;
  if (scene == "rigid-ball") cfg.scene = glove::DemoScene::kRigidBall;
  else if (scene == "soft-ball") cfg.scene = glove::DemoScene::kSoftBall;
  else if (scene == "wall") cfg.scene = glove::DemoScene::kWall;
  else {
    error = "scene: '" + scene + "' is not one of rigid-ball, soft-ball, wall";
    return nullptr;
  }
  return std::make_unique<glove::GloveController>(cfg);
}

}  // namespace phalanx::host::therapy
