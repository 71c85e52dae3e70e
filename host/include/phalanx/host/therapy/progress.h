#pragma once
/// A patient's progress over time (issue #25 item 5, docs/therapy.md "Progress over time"): every assessment and
/// exercise figure of every session record of one patient in a records directory, as a trend across the sessions
/// with the figure's minimal detectable change (MDC95 from a repeatability file) as a band around the first
/// session's value, the sessions with locked or faulted time marked. Each session's figures are the single-session
/// report's (sessionMetrics(), which leaves the locked/faulted cycles out of every exercise metric), so the two
/// never disagree. Written as one self-contained printable HTML file (A4 pages, inline SVG, no scripts, no
/// external resources), and printed to PDF by headless Chromium.
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace phalanx::host::therapy {

/// The figures a progress report trends, of one session's metrics (sessionMetrics()): assessmentFigures() (the
/// instrumented assessments and the active ROM), then the exercise figures `tracking.<channel>.rms_error_deg`
/// and `transparency.<channel>.interaction_rms`, channels in anatomical order.
std::vector<std::pair<std::string, double>> progressFigures(const nlohmann::json& metrics);

/// +1: a higher value is the better one, −1: a lower one, 0: not rated (docs/therapy.md "Progress over time").
int figureDirection(const std::string& figure);

/// The progress of `patient` from the records in records_dir (records_dir.h names, oldest first), with the MDC95
/// and ICC of each figure from `repeatability` (loadRepeatability's JSON; null: none) whose origin is
/// `repeatability_source` (its path, for the report). JSON: {version, patient, device, effort_unit, records_dir,
/// sessions: [{n, file, start_utc, duration_s, complete, exercises, excluded_s, excluded_cycles,
/// excluded_periods, faults_seen, figures: {name: value}}], figures: [{name, section, title, unit, direction,
/// values: [value or null per session], mdc95?, icc?}], mdc_source, pages}; `pages` is the page count the
/// printed layout plans. "" or an error naming what was wrong (no such directory, no records of the patient —
/// listing the patients that have some, a record that cannot be read, a record of another patient or device).
std::string progressOf(const std::string& records_dir, const std::string& patient, const nlohmann::json& repeatability,
                       const std::string& repeatability_source, nlohmann::json& out,
                       const std::function<void(const std::string&)>& progress = nullptr);

/// The printable HTML of progressOf()'s JSON (embedded in it as <script type='application/json' id='progress'>).
std::string progressHtml(const nlohmann::json& progress);

struct ProgressRequest {
  std::string records_dir, patient;
  std::string repeatability_path;  ///< optional: MDC95 and ICC per figure (phalanx record repeatability)
  std::string html_path;           ///< the HTML report (required)
  std::string pdf_path;            ///< optional: the HTML printed to PDF (printHtmlToPdf)
};
/// progressOf + progressHtml, written atomically to html_path, then printed to pdf_path if given. "" or an error.
std::string writeProgressReport(const ProgressRequest& request, nlohmann::json& out,
                                const std::function<void(const std::string&)>& progress = nullptr);

/// Prints an HTML file to PDF with headless Chromium (`--print-to-pdf`, no header or footer, a temporary profile
/// directory; `--no-sandbox` only when running as root, which Chromium's sandbox refuses). The browser is
/// $PHALANX_CHROMIUM, else /usr/bin/chromium or /usr/bin/chromium-browser. Bounded to 120 s; the PDF is written
/// beside pdf_path and renamed over it only when complete and starting with %PDF. "" or an error.
std::string printHtmlToPdf(const std::string& html_path, const std::string& pdf_path);

}  // namespace phalanx::host::therapy
