#pragma once
/// phalanxd's YAML configuration: loaded, validated (unknown keys, wrong types and out-of-range values are
/// errors naming the key), and applied onto RunOptions.
#include <string>

#include "phalanx/host/daemon.h"

namespace phalanx::host {

/// Parse YAML text into opt (keys absent keep opt's values). Returns "" or "<source>: <key>: <problem>".
std::string loadConfigText(const std::string& yaml_text, const std::string& source, RunOptions& opt);
std::string loadConfigFile(const std::string& path, RunOptions& opt);

/// A session length the runner can honour: 0 (until stopped) or at least one host period. A positive length
/// shorter than that rounds to zero cycles, which the runner reads as "until stopped" (0.0004 s at 1 kHz ran
/// until killed). Returns "" or the problem, for the caller to prefix with where the value came from.
std::string checkSessionLength(double seconds_s, unsigned rate_hz);

}  // namespace phalanx::host
