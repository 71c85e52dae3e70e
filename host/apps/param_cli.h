#pragma once
// phalanx param list|get|set|save|load|diff: device parameters by name, persistent settings, YAML backup and
// restore (docs/params.md).
#include <CLI/CLI.hpp>
#include <string>

#include "phalanx/host/daemon.h"

namespace phalanx::host {

struct ParamCommands {
  CLI::App* app = nullptr;
  CLI::App *list = nullptr, *get = nullptr, *set = nullptr, *save = nullptr, *load = nullptr, *diff = nullptr;
  RunOptions opt;
  double timeout_s = 2.0;
  std::string key, value, file, yaml;
  bool save_after_set = false;

  explicit ParamCommands(CLI::App& parent);
  bool parsed() const { return app->parsed(); }
  int run();
};

}  // namespace phalanx::host
