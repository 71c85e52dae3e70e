#pragma once
// `phalanx flash IMAGE`: check a firmware image and write it into a board (host/include/phalanx/host/flash.h).
#include <CLI/CLI.hpp>
#include <string>

namespace phalanx::host {

struct FlashCommand {
  CLI::App* app = nullptr;
  std::string image, via = "gdb", target, board, device_type, build_id, device;
  double timeout_s = 10.0;
  bool dry_run = false;

  explicit FlashCommand(CLI::App& parent);
  /// Validates the options (exit 2 with the option named), then runs flash::run.
  int run() const;
};

}  // namespace phalanx::host
