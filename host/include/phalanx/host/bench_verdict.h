#pragma once
/// The verdict of a single bench (`phalanx bench glove-*|sea-*|pen-*`): each target the bench's JSON declares
/// ("target") judged against its result, the figures a person reads first, and the short human summary the CLI
/// prints by default (`--json` prints the whole result instead). docs/bench-runner.md §"Single benches".
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace phalanx::host {

struct BenchFigure {
  std::string name;   ///< human name ("peak contact force, worst finger")
  double value = 0;
  std::string unit;   ///< "N", "%", "" ...
};

struct BenchCheck {
  std::string what;   ///< human name of the figure judged
  double value = 0;   ///< for a yes/no check: 1 yes, 0 no
  double limit = 0;
  bool is_min = false;  ///< limit is a minimum (else a maximum)
  bool is_flag = false; ///< a yes/no condition (value must be 1)
  bool pass = false;
  std::string unit;
  std::string note;   ///< what the value means beyond its number ("-3 dB not reached within the sweep")
};

struct BenchVerdict {
  std::string bench;
  std::vector<BenchFigure> figures;
  std::vector<BenchCheck> checks;
  std::vector<std::string> notes;  ///< e.g. why a target was not judged
  bool pass() const;               ///< every check passed (true when there is none)
};

/// bench: the subcommand's name (glove-free-motion … pen-wall); result: its JSON. A missing or non-finite figure
/// fails its check, naming it.
BenchVerdict judgeBench(const std::string& bench, const nlohmann::json& result);

/// A few lines: "glove-grasp: PASS", the figures, each check with ✓/✗, the notes.
std::string benchSummaryText(const BenchVerdict& v);

}  // namespace phalanx::host
