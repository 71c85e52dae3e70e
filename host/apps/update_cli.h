#pragma once
// phalanx update IMAGE --device DEV: firmware update over the device's own link (docs/firmware-update.md).
#include <CLI/CLI.hpp>
#include <string>

#include "phalanx/host/firmware_update.h"

namespace phalanx::host {

struct UpdateCommand {
  CLI::App* app = nullptr;
  update::Request req;
  std::string board = "stm32g474", sim_flash, sim_provision;

  explicit UpdateCommand(CLI::App& parent);
  /// Validates the options (exit 2 naming the option), then runs update::run.
  int run();
};

}  // namespace phalanx::host
