#include <cstdio>

#include "phalanx/host/controller.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/pen/pen_controller.h"

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
  if (layout.type == protocol::DeviceType::kPantograph) {
    // Pen scenes through the shared --scene option: none = gravity compensation only, wall = the stiff pencil
    // box, rigid-ball/soft-ball (the default) = the box with the click button (docs/pen-plant.md).
    pen::PenControllerConfig cfg;
    cfg.transparent = opt.mode == "transparent";
    if (opt.scene == "none") {
      cfg.scene.box = false;
      cfg.scene.button = false;
    } else if (opt.scene == "wall") {
      cfg.scene.button = false;
    } else if (opt.scene != "rigid-ball" && opt.scene != "soft-ball") {
      error = "unknown pen scene '" + opt.scene + "'";
      return nullptr;
    }
    return std::make_unique<pen::PenController>(cfg);
  }
  (void)error;
  return std::make_unique<TransparentController>();
}

}  // namespace phalanx::host
