#pragma once
/// phalanxd's YAML configuration: loaded, validated (unknown keys, wrong types and out-of-range values are
/// errors naming the key), and applied onto RunOptions.
#include <string>

#include "phalanx/host/daemon.h"

namespace phalanx::host {

/// Parse YAML text into opt (keys absent keep opt's values). Returns "" or "<source>: <key>: <problem>".
std::string loadConfigText(const std::string& yaml_text, const std::string& source, RunOptions& opt);
std::string loadConfigFile(const std::string& path, RunOptions& opt);

}  // namespace phalanx::host
