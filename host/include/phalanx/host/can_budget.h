#pragma once
/// CAN bus-load budget (docs/protocol.md, "Bus load"): computed from the frames the real mapping produces for
/// each device at its tick rate, and measured from a candump log of a running session.
#include <string>

#include <nlohmann/json.hpp>

namespace phalanx::host {

/// Bus load of every device at rate_hz (one command + one telemetry per tick) on classic CAN at nominal_bps and
/// on CAN-FD at nominal_bps with data phases at 1× and 5× that rate: frames and bytes per tick, load in percent
/// with worst-case and without bit stuffing.
nlohmann::json canBudget(double rate_hz, double nominal_bps);

/// Bus load measured from a `candump -L` log: bus time of every logged frame (worst-case stuffing and none)
/// over the log's duration. Returns {"error": ...} when the log cannot be read.
nlohmann::json canLoadFromLog(const std::string& path, double nominal_bps, double data_bps);

}  // namespace phalanx::host
