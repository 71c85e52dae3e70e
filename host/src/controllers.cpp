#include <cstdio>

#include "phalanx/host/controller.h"
#include "phalanx/host/daemon.h"

namespace phalanx::host {

std::string Controller::liveLine(const TelemetryFrame&) const { return {}; }

void TransparentController::update(const TelemetryFrame&, double, double, protocol::Command& cmd) {
  cmd.mode = protocol::Mode::kTransparent;
  for (auto& s : cmd.setpoint) s = 0.0f;
}

std::unique_ptr<Controller> makeController(const protocol::DeviceLayout& layout, const RunOptions& opt,
                                           std::string& error) {
  (void)layout;
  (void)opt;
  (void)error;
  return std::make_unique<TransparentController>();
}

}  // namespace phalanx::host
