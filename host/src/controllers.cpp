#include <cstdio>

#include "phalanx/host/controller.h"
#include "phalanx/host/daemon.h"
#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/glove/glove_controller.h"
#include "phalanx/host/pen/pen_controller.h"
#include "phalanx/host/sea/sea_calibrate.h"
#include "phalanx/host/sea/sea_finger_controller.h"

namespace phalanx::host {

std::string Controller::liveLine(const TelemetryFrame&) const { return {}; }
std::string Controller::liveLegend() const { return {}; }

void TransparentController::update(const TelemetryFrame&, double, double, protocol::Command& cmd) {
  cmd.mode = protocol::Mode::kTransparent;
  for (auto& s : cmd.setpoint) s = 0.0f;
}

std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error) {
  // A geometry file for another device type is an error, never ignored.
  if (!opt.pen_geometry.empty() && layout.type != protocol::DeviceType::kPantograph) {
    error = "pen.geometry: given, but the device is a " + std::string(layout.name) + ", not a pantograph";
    return nullptr;
  }
  if (!opt.glove_geometry.empty() && layout.type != protocol::DeviceType::kGlove5) {
    error = "glove.geometry: given, but the device is a " + std::string(layout.name) + ", not a glove5";
    return nullptr;
  }
  if (layout.type == protocol::DeviceType::kGlove5) {
    glove::GloveControllerConfig cfg;
    cfg.transparent = opt.mode == "transparent";
    static const char* const kFingerNames[] = {"thumb", "index", "middle", "ring", "little"};  // FingerId order
    for (const auto& [finger, path] : opt.glove_geometry) {
      std::size_t f = 0;
      while (f < 5 && finger != kFingerNames[f]) ++f;
      if (f == 5) {
        error = "glove.geometry: '" + finger + "' is not a finger (thumb, index, middle, ring, little)";
        return nullptr;
      }
      if (std::string err = design::loadGloveGeometryYaml(path, cfg.hand.fingers[f]); !err.empty()) {
        error = "glove.geometry." + finger + ": " + err;
        return nullptr;
      }
      cfg.geometry_file[f] = path;
    }
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
    if (!opt.pen_geometry.empty()) {
      if (std::string err = design::loadPenGeometryYaml(opt.pen_geometry, cfg.geometry); !err.empty()) {
        error = "pen.geometry: " + err;
        return nullptr;
      }
      cfg.geometry_file = opt.pen_geometry;
    }
    if (opt.scene == "none") {
      cfg.scene.box = false;
      cfg.scene.button = false;
    } else if (opt.scene == "wall") {
      cfg.scene.button = false;
    } else if (opt.scene != "rigid-ball" && opt.scene != "soft-ball") {
      error = "unknown pen scene '" + opt.scene + "'";
      return nullptr;
    }
    if (opt.pen_wall_stiffness_N_per_cm > 0.0) {
      cfg.scene.horizontal.stiffness_N_per_m = opt.pen_wall_stiffness_N_per_cm * 100.0;
      cfg.scene.vertical.stiffness_N_per_m = opt.pen_wall_stiffness_N_per_cm * 100.0;
    }
    cfg.scene.box_min[1] = opt.pen_floor_mm * 1e-3;
    return std::make_unique<pen::PenController>(cfg);
  }
  if (layout.type == protocol::DeviceType::kSeaFinger) {
    // mode transparent: zero finger (= zero exoskeleton) torque, §7.7; otherwise the finger-torque profile
    // (eq 18 sine on the finger MCP/PIP torques) through eq 9–11.
    sea::SeaFingerControllerConfig cfg;
    cfg.mode = opt.mode == "transparent" ? sea::SeaFingerMode::kTransparent : sea::SeaFingerMode::kFingerTorque;
    if (!opt.sea_subject.empty()) {
      error = sea::loadSubjectYaml(opt.sea_subject, cfg.model.subject, cfg.model.fixed);
      if (!error.empty()) return nullptr;
    }
    return std::make_unique<sea::SeaFingerController>(cfg);
  }
  (void)error;
  return std::make_unique<TransparentController>();
}

}  // namespace phalanx::host
