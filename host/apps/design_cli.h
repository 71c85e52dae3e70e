#pragma once
// `phalanx design …` subcommands: glove workspace/optimisation (000 §3–4.1) and pen GII/culling (004 §IV–VI).
#include <CLI/CLI.hpp>
#include <memory>

namespace phalanx::host {

class DesignCommands {
 public:
  explicit DesignCommands(CLI::App& app);
  ~DesignCommands();
  bool parsed() const;
  /// Runs the parsed subcommand; returns the process exit code.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phalanx::host
