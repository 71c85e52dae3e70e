#include <cstdio>

#include "phalanx/host/controller.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/sea/sea_finger_controller.h"

namespace phalanx::host {

std::string Controller::liveLine(const TelemetryFrame&) const { return {}; }

void TransparentController::update(const TelemetryFrame&, double, double, protocol::Command& cmd) {
  cmd.mode = protocol::Mode::kTransparent;
  for (auto& s : cmd.setpoint) s = 0.0f;
}

std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error) {
  if (layout.type == protocol::DeviceType::kGlove5) {
    glove::GloveControllerConfig cfg;
    cfg.transparent = opt.mode == "transparent";
    if (opt.scene == "none") cfg.scene = glove::DemoScene::kNone;
    else if (opt.scene == "rigid-ball") cfg.scene = glove::DemoScene::kRigidBall;
    else if (opt.scene == "soft-ball") cfg.scene = glove::DemoScene::kSoftBall;
    else if (opt.scene == "wall") cfg.scene = glove::DemoScene::kWall;
    else {
      error = "unknown glove scene '" + opt.scene + "'";
      return nullptr;
    }
    return std::make_unique<glove::GloveController>(cfg);
  }
  if (layout.type == protocol::DeviceType::kSeaFinger) {
    // mode transparent: zero finger (= zero exoskeleton) torque, §7.7; otherwise the finger-torque profile
    // (eq 18 sine on the finger MCP/PIP torques) through eq 9–11.
    sea::SeaFingerControllerConfig cfg;
    cfg.mode = opt.mode == "transparent" ? sea::SeaFingerMode::kTransparent : sea::SeaFingerMode::kFingerTorque;
    return std::make_unique<sea::SeaFingerController>(cfg);
  }
  (void)error;
  return std::make_unique<TransparentController>();
}

}  // namespace phalanx::host
