#pragma once
/// End-of-session report for the therapist: one self-contained HTML file (inline SVG plots, no scripts, no
/// external assets) computed from the session record: active range of motion per joint against the previous
/// session, force/torque traces, tracking error, transparency (Pearson r, 000 Table 4), faults.
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/record_reader.h"

namespace phalanx::host::therapy {

/// A device-free recording of the same motion (001 §7.2: motion capture without the exoskeleton; in simulation
/// the simulated user's own trajectory), for the transparency Pearson r of 001 Table 2 / 000 Table 4.
/// CSV: a header `t_s,<joint>_deg,...` (joint names of the device, any subset), one row per sample, times in
/// the session's clock, '#' comment lines allowed.
struct TransparencyReference {
  std::vector<double> t_s;
  std::vector<std::pair<std::string, std::vector<double>>> joints_deg;
};
/// "" or "<path>:<line>: <problem>".
std::string loadTransparencyReference(const std::string& path, TransparencyReference& out);

/// The report's numbers (also embedded in the HTML as JSON). With a reference, "transparency_r" gives per joint
/// the Pearson r between the joint flexion recorded during assessment and the reference at the same times.
nlohmann::json sessionMetrics(const record::SessionRecord& rec, const TransparencyReference* reference = nullptr);

/// Reads record_path (and previous_path / reference_path / repeatability_path if not empty), writes html_path.
/// The repeatability file (assessment_analysis.h loadRepeatability) puts each assessment figure's ICC(2,1) and
/// MDC95 beside it. "" or an error.
std::string writeReport(const std::string& record_path, const std::string& previous_path, const std::string& html_path,
                        const std::function<void(const std::string&)>& progress = nullptr,
                        const std::string& reference_path = "", const std::string& repeatability_path = "");

/// Repeatability from session records (`phalanx record repeatability`): the records are grouped by the patient in
/// their headers (every patient needs the same number ≥ 2 of sessions, and ≥ 2 patients — ICC(2,1) needs
/// between-patient spread); each record's assessment figures (sessionMetrics) give ICC(2,1), SEM and MDC95 per
/// figure (assessment_analysis.h repeatabilityOf), written to out_path as the report's repeatability file.
/// "" or an error naming the record or the problem.
std::string writeRepeatability(const std::vector<std::string>& records, const std::string& out_path,
                               nlohmann::json& result);

}  // namespace phalanx::host::therapy
