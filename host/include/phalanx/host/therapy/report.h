#pragma once
/// End-of-session report for the therapist: one self-contained HTML file (inline SVG plots, no scripts, no
/// external assets) computed from the session record: active range of motion per joint against the previous
/// session, force/torque traces, tracking error, transparency (Pearson r, 000 Table 4), faults.
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/record_reader.h"

namespace phalanx::host::therapy {

/// The report's numbers (also embedded in the HTML as JSON). previous may be null.
nlohmann::json sessionMetrics(const record::SessionRecord& rec);

/// Reads record_path (and previous_path if not empty), writes html_path. "" or an error.
std::string writeReport(const std::string& record_path, const std::string& previous_path, const std::string& html_path,
                        const std::function<void(const std::string&)>& progress = nullptr);

}  // namespace phalanx::host::therapy
