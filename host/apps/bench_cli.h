#pragma once
// `phalanx bench …` subcommands: the single lockstep benches (glove, SEA, pen) and `bench run PLAN`.
#include <CLI/CLI.hpp>
#include <memory>

namespace phalanx::host {

class BenchCommands {
 public:
  explicit BenchCommands(CLI::App& app);
  ~BenchCommands();
  bool parsed() const;
  /// Runs the parsed subcommand; returns the process exit code: 0 every target met (or none declared), 1 a target
  /// missed; `bench run`: its own codes (docs/bench-runner.md).
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace phalanx::host
