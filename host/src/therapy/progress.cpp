#include "phalanx/host/therapy/progress.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "phalanx/host/design/svg.h"
#include "phalanx/host/record/output_file.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/guidance.h"
#include "phalanx/host/therapy/records_dir.h"
#include "phalanx/host/therapy/report.h"

extern char** environ;

namespace phalanx::host::therapy {
namespace {

// Printed layout (A4, 12 mm margins): rows per table page and plots per page, chosen so that each page's content
// fits one sheet; `pages` in the JSON is the plan, and the test checks the PDF has exactly that many.
constexpr std::size_t kSessionRowsFirstPage = 14, kRowsPerPage = 26, kChangeRowsPerPage = 20, kPlotsPerPage = 6;
constexpr const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd"};
constexpr const char* kExcludedColour = "#e67e00";

const auto& esc = design::markupEscape;

/// Three significant digits, never float noise or "-0" (humanNumber).
std::string sig(double v) {
  if (!std::isfinite(v) || v == 0.0) return humanNumber(v, 0);
  const int digits = std::clamp(2 - static_cast<int>(std::floor(std::log10(std::fabs(v)))), 0, 6);
  return humanNumber(v, digits);
}

/// "index_mcp" → "index MCP", "mcp" → "MCP", "thumb" → "thumb".
std::string siteName(const std::string& name) {
  static const std::vector<std::string> kJoints = {"cmc", "mcp", "pip", "dip", "ip"};
  const auto us = name.rfind('_');
  std::string joint = us == std::string::npos ? name : name.substr(us + 1);
  if (std::find(kJoints.begin(), kJoints.end(), joint) == kJoints.end()) return name;
  for (char& c : joint) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return us == std::string::npos ? joint : name.substr(0, us) + " " + joint;
}

struct FigureInfo {
  std::string section, group, title, series;
};

/// Where a figure goes: its section, the plot it shares with its pair (passive and active ROM: both ends of a
/// joint's range in one plot), the plot's title and the series' label.
FigureInfo infoOf(const std::string& name, const std::string& unit) {
  const auto dot1 = name.find('.'), dot2 = name.find('.', dot1 + 1);
  const std::string family = name.substr(0, dot1);
  const std::string part = dot2 == std::string::npos ? name.substr(dot1 + 1) : name.substr(dot1 + 1, dot2 - dot1 - 1);
  const std::string last = dot2 == std::string::npos ? "" : name.substr(dot2 + 1);
  const std::string effort = unit == "N" ? "force" : "torque";
  if (family == "tardieu") {
    const std::string s = "Spasticity: instrumented Modified Tardieu test";
    if (part == "catch_deg") return {s, name, "Catch angle (flexion at the catch, R1)", ""};
    if (part == "threshold_deg_s") return {s, name, "Stretch-reflex threshold velocity", ""};
    if (part == "gain_per_rad_s") return {s, name, "Stretch-reflex gain", ""};
    std::string v = part.substr(std::string("reflex_at_").size());
    v = v.substr(0, v.find('_'));
    return {s, name, "Reflex " + effort + " at the " + v + "°/s stretch", ""};
  }
  if (family == "passive_rom") {
    return {"Passive range of motion", "passive_rom." + part, "Passive ROM, " + siteName(part),
            last == "extension_deg" ? "under the extending effort" : "under the flexing effort"};
  }
  if (family == "max_force") return {"Maximal voluntary force", name, "Maximal voluntary " + effort + ", " + siteName(part), ""};
  if (family == "rom") {
    return {"Active range of motion", "rom." + part, "Active ROM, " + siteName(part),
            last == "min_deg" ? "least flexion" : "greatest flexion"};
  }
  if (family == "tracking") return {"Tracking (assistance, playback)", name, "Tracking error (RMS), " + siteName(part), ""};
  return {"Transparency (free motion)", name, "Interaction " + effort + " in free motion (RMS), " + siteName(part), ""};
}

bool isDirectory(const std::string& dir, std::string& error) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    error = "records directory " + dir + ": " + std::strerror(errno);
    return false;
  }
  if (!S_ISDIR(st.st_mode)) {
    error = "records directory " + dir + ": not a directory";
    return false;
  }
  DIR* d = ::opendir(dir.c_str());
  if (d == nullptr) {
    error = "records directory " + dir + ": cannot list it: " + std::strerror(errno);
    return false;
  }
  ::closedir(d);
  return true;
}

/// One session's entry of the progress JSON, from its record.
std::string sessionEntry(const std::string& path, const std::string& file, const std::string& patient,
                         nlohmann::json& entry) {
  record::SessionRecord rec;
  if (std::string err = record::readRecord(path, rec); !err.empty()) return "cannot read the record " + path + ": " + err;
  const nlohmann::json m = sessionMetrics(rec);
  if (m.contains("error")) return path + ": " + m["error"].get<std::string>();
  if (m.value("patient", std::string()) != patient) {
    return path + ": the record's header names patient '" + m.value("patient", std::string()) + "', its name '" +
           patient + "': not included (a renamed file?)";
  }
  nlohmann::json figures = nlohmann::json::object(), order = nlohmann::json::array();
  for (const auto& [name, v] : progressFigures(m)) figures[name] = v, order.push_back(name);
  std::vector<std::string> exercises;
  for (const auto& e : m["exercises"]) {
    const std::string x = e["exercise"].get<std::string>();
    if (std::find(exercises.begin(), exercises.end(), x) == exercises.end()) exercises.push_back(x);
  }
  entry = {{"file", file},
           {"device", m["device"]},
           {"effort_unit", m["effort_unit"]},
           {"start_utc", m["start_utc"]},
           {"duration_s", m["duration_s"]},
           {"complete", m["complete"]},
           {"exercises", exercises},
           {"excluded_s", m["excluded_s"]},
           {"excluded_cycles", m["excluded_cycles"]},
           {"excluded_periods", m["excluded_periods"]},
           {"faults_seen", m["faults_seen"]},
           {"figures", figures},
           {"figure_order", order}};  // the JSON object sorts its keys; the sections' order is kept here
  return "";
}

std::size_t pagesFor(std::size_t rows, std::size_t per_page) { return rows == 0 ? 0 : (rows + per_page - 1) / per_page; }

/// The plots of the figures, in order: each is (section, title, [figure indices]).
struct Plot {
  std::string section, title;
  std::vector<std::size_t> figures;
};
std::vector<Plot> plotsOf(const nlohmann::json& figures) {
  std::vector<Plot> plots;
  std::string last_group;
  for (std::size_t i = 0; i < figures.size(); ++i) {
    const nlohmann::json& f = figures[i];
    const std::string group = f["group"].get<std::string>();
    if (plots.empty() || group != last_group) plots.push_back({f["section"].get<std::string>(), f["title"].get<std::string>(), {}});
    plots.back().figures.push_back(i);
    last_group = group;
  }
  return plots;
}

/// Plot pages: every section starts a page; kPlotsPerPage plots a page.
std::vector<std::vector<std::size_t>> plotPages(const std::vector<Plot>& plots) {
  std::vector<std::vector<std::size_t>> pages;
  for (std::size_t i = 0; i < plots.size(); ++i) {
    if (pages.empty() || pages.back().size() == kPlotsPerPage || plots[i].section != plots[pages.back().back()].section) {
      pages.emplace_back();
    }
    pages.back().push_back(i);
  }
  return pages;
}

std::size_t periodRows(const nlohmann::json& sessions) {
  std::size_t n = 0;
  for (const auto& s : sessions) n += s["excluded_periods"].size();
  return n;
}

/// First and last finite value of a figure, and the sessions they come from.
bool firstLast(const nlohmann::json& values, double& first, double& last) {
  int seen = 0;
  for (const auto& v : values) {
    if (!v.is_number()) continue;
    if (seen++ == 0) first = v.get<double>();
    last = v.get<double>();
  }
  return seen >= 1;
}

/// The change from the first to the last session in words, against the MDC95.
std::string verdict(const nlohmann::json& f, double change, std::string& css) {
  css = "same";
  if (!f.contains("mdc95")) return "MDC unknown";
  const double mdc = f["mdc95"].get<double>();
  if (std::fabs(change) <= mdc) return "within MDC95";
  const int dir = f["direction"].get<int>();
  const bool up = change > 0;
  if (dir == 0) return up ? "▲ higher" : "▼ lower";
  const bool better = (dir > 0) == up;
  css = better ? "better" : "worse";
  return std::string(up ? "▲ " : "▼ ") + (better ? "better" : "worse");
}

std::string sessionTick(const nlohmann::json& s) {
  const std::string start = s.value("start_utc", std::string());
  const std::string date = start.size() >= 10 ? start.substr(5, 5) : "";
  return "#" + std::to_string(s["n"].get<int>()) + (s["excluded_cycles"].get<std::size_t>() > 0 ? "†" : "") + "\n" + date;
}

std::string plotSvg(const nlohmann::json& p, const Plot& plot) {
  const nlohmann::json& sessions = p["sessions"];
  const nlohmann::json& figures = p["figures"];
  const std::string unit = figures[plot.figures[0]]["unit"].get<std::string>();
  design::SvgPlot svg("", "session", unit, 360, 250);
  std::vector<std::pair<double, std::string>> ticks;
  const std::size_t n = sessions.size();
  const std::size_t every = std::max<std::size_t>(1, (n + 9) / 10);  // at most ~10 labels
  for (std::size_t i = 0; i < n; ++i) {
    if (i % every == 0 || i + 1 == n) ticks.emplace_back(static_cast<double>(i + 1), sessionTick(sessions[i]));
    if (sessions[i]["excluded_cycles"].get<std::size_t>() > 0) svg.addVLine(static_cast<double>(i + 1), kExcludedColour, "†");
  }
  svg.setXTicks(ticks);
  for (std::size_t k = 0; k < plot.figures.size(); ++k) {
    const nlohmann::json& f = figures[plot.figures[k]];
    const char* colour = kColours[k % 4];
    std::vector<std::array<double, 2>> pts;
    for (std::size_t i = 0; i < f["values"].size(); ++i) {
      if (f["values"][i].is_number()) pts.push_back({static_cast<double>(i + 1), f["values"][i].get<double>()});
    }
    if (f.contains("mdc95") && !pts.empty()) {
      const double mdc = f["mdc95"].get<double>();
      svg.addBand(pts[0][1] - mdc, pts[0][1] + mdc, colour, 0.15);
    }
    svg.addLine(pts, colour, plot.figures.size() > 1 ? f["series"].get<std::string>() : "", true);
  }
  return svg.render();
}

std::string pageHeader(const nlohmann::json& p, const std::string& heading) {
  return "<div class='head'>Progress report · patient " + esc(p["patient"].get<std::string>()) + " · " +
         esc(p["device"].get<std::string>()) + "</div><h2>" + esc(heading) + "</h2>";
}

std::string summaryPages(const nlohmann::json& p) {
  const nlohmann::json& sessions = p["sessions"];
  std::ostringstream h;
  h << "<section class='page'><h1>Progress over time</h1><table class='kv'><tr><th>patient</th><td>"
    << esc(p["patient"].get<std::string>()) << "</td></tr><tr><th>device</th><td>" << esc(p["device"].get<std::string>())
    << "</td></tr><tr><th>sessions</th><td>" << sessions.size() << ", " << esc(sessions.front()["start_utc"].get<std::string>())
    << " to " << esc(sessions.back()["start_utc"].get<std::string>()) << " (UTC)</td></tr><tr><th>records</th><td>"
    << esc(p["records_dir"].get<std::string>()) << "</td></tr></table>";
  h << "<p class='note'>Every figure is the session report's own (phalanx record report): the time the device was "
       "locked or faulted — from a latched fault until the device moved again — is left out of every exercise and "
       "assessment figure; sessions with such time are marked <b class='excl'>†</b> (a dashed orange line in the "
       "plots) and listed below. Peak efforts are not trended.</p>";
  if (p["mdc_source"].is_string()) {
    h << "<p class='note'><b>MDC band</b>: the shaded band around a figure's first value is ± its minimal detectable "
         "change (MDC95 = 1.96·√2·SEM, SEM = SD·√(1 − ICC(2,1))) from the repeatability study "
      << esc(p["mdc_source"].get<std::string>())
      << ". A later value outside the band is a change beyond the measurement's own test–retest variation.</p>";
  } else {
    h << "<p class='note warn'><b>No MDC band</b>: no repeatability file was given (phalanx record progress "
         "--repeatability FILE, made by phalanx record repeatability), so whether a change exceeds the measurement's "
         "own variation is unknown.</p>";
  }
  const auto table_head = [](std::ostringstream& o) {
    o << "<table><tr><th>#</th><th>start (UTC)</th><th>record</th><th>duration (s)</th><th>exercises</th>"
         "<th>locked/faulted, excluded</th><th>faults</th></tr>";
  };
  h << "<h2>Sessions</h2>";
  table_head(h);
  for (std::size_t i = 0; i < sessions.size(); ++i) {
    if (i == kSessionRowsFirstPage || (i > kSessionRowsFirstPage && (i - kSessionRowsFirstPage) % kRowsPerPage == 0)) {
      h << "</table></section><section class='page'>" << pageHeader(p, "Sessions (continued)");
      table_head(h);
    }
    const nlohmann::json& s = sessions[i];
    std::string ex;
    for (const auto& e : s["exercises"]) ex += (ex.empty() ? "" : ", ") + e.get<std::string>();
    const std::size_t cycles = s["excluded_cycles"].get<std::size_t>();
    h << "<tr><td>" << s["n"].get<int>() << (cycles > 0 ? "<b class='excl'>†</b>" : "") << "</td><td>"
      << esc(s["start_utc"].get<std::string>()) << "</td><td class='text'>" << esc(s["file"].get<std::string>())
      << (s["complete"].get<bool>() ? "" : " <span class='warn'>(no end marker)</span>") << "</td><td>"
      << humanNumber(s["duration_s"].get<double>(), 1) << "</td><td class='text'>" << esc(ex) << "</td><td>"
      << (cycles > 0 ? humanNumber(s["excluded_s"].get<double>(), 2) + " s (" + std::to_string(cycles) + " cycles)" : "none")
      << "</td><td class='text'>" << esc(s["faults_seen"].get<std::string>()) << "</td></tr>";
  }
  h << "</table></section>";
  // The locked or faulted periods, every one.
  std::size_t row = 0;
  for (const auto& s : sessions) {
    for (const auto& e : s["excluded_periods"]) {
      if (row % kRowsPerPage == 0) {
        if (row > 0) h << "</table></section>";
        h << "<section class='page'>" << pageHeader(p, row == 0 ? "Locked or faulted periods (excluded from every figure)"
                                                                  : "Locked or faulted periods (continued)")
          << "<table><tr><th>session</th><th>from (s)</th><th>to (s)</th><th>length (s)</th><th>faults</th></tr>";
      }
      ++row;
      h << "<tr><td>#" << s["n"].get<int>() << "</td><td>" << humanNumber(e["start_s"].get<double>(), 2) << "</td><td>"
        << humanNumber(e["end_s"].get<double>(), 2) << "</td><td>"
        << humanNumber(e["end_s"].get<double>() - e["start_s"].get<double>(), 2) << "</td><td class='text'>"
        << esc(e["faults"].get<std::string>()) << "</td></tr>";
    }
  }
  if (row > 0) h << "</table></section>";
  return h.str();
}

std::string changePages(const nlohmann::json& p) {
  const nlohmann::json& figures = p["figures"];
  std::ostringstream h;
  for (std::size_t i = 0; i < figures.size(); ++i) {
    if (i % kChangeRowsPerPage == 0) {
      if (i > 0) h << "</table></section>";
      h << "<section class='page'>" << pageHeader(p, i == 0 ? "Change from the first to the last session" : "Change (continued)")
        << "<p class='note'>Beyond the MDC95 (a change larger than the measurement's own test–retest variation): "
           "▲ higher / ▼ lower, and better or worse where the figure has a direction; otherwise \"within "
           "MDC95\" (no detectable change).</p><table><tr><th style='width:45%'>figure</th><th>unit</th><th>first</th>"
           "<th>last</th><th>change</th><th>MDC95</th><th>ICC(2,1)</th><th>verdict</th></tr>";
    }
    const nlohmann::json& f = figures[i];
    double first = 0.0, last = 0.0;
    firstLast(f["values"], first, last);
    std::string css;
    const std::string word = verdict(f, last - first, css);
    const std::string label = f["title"].get<std::string>() +
                              (f["series"].get<std::string>().empty() ? "" : ", " + f["series"].get<std::string>());
    h << "<tr><td class='text'>" << esc(label) << "<br><span class='name'>" << esc(f["name"].get<std::string>())
      << "</span></td><td>" << esc(f["unit"].get<std::string>()) << "</td><td>" << sig(first) << "</td><td>" << sig(last)
      << "</td><td>" << (last - first >= 0 ? "+" : "−") << sig(std::fabs(last - first)) << "</td><td>"
      << (f.contains("mdc95") ? sig(f["mdc95"].get<double>()) : "–") << "</td><td>"
      << (f.contains("icc") ? humanNumber(f["icc"].get<double>(), 3) : "–") << "</td><td class='text " << css << "'>"
      << esc(word) << "</td></tr>";
  }
  if (!figures.empty()) h << "</table></section>";
  return h.str();
}

std::string plotPagesHtml(const nlohmann::json& p) {
  const std::vector<Plot> plots = plotsOf(p["figures"]);
  std::ostringstream h;
  std::string last_section;
  for (const auto& page : plotPages(plots)) {
    const std::string& section = plots[page.front()].section;
    h << "<section class='page'>" << pageHeader(p, section + (section == last_section ? " (continued)" : ""))
      << "<div class='plots'>";
    last_section = section;
    for (const std::size_t i : page) {
      const Plot& plot = plots[i];
      const nlohmann::json& f0 = p["figures"][plot.figures[0]];
      h << "<figure><figcaption><b>" << esc(plot.title) << "</b> (" << esc(f0["unit"].get<std::string>()) << ")";
      for (const std::size_t k : plot.figures) {
        const nlohmann::json& f = p["figures"][k];
        h << "<br><span class='name'>" << esc(f["name"].get<std::string>())
          << (f.contains("mdc95") ? ", MDC95 " + sig(f["mdc95"].get<double>()) : ", MDC unknown") << "</span>";
      }
      h << "</figcaption>" << plotSvg(p, plot) << "</figure>";
    }
    h << "</div><p class='note legend'>Points: each session's value (the session report's figure). Shaded band: the "
         "first value ± MDC95. <b class='excl'>†</b> dashed line: a session with locked or faulted time, left out of "
         "its figures.</p></section>";
  }
  return h.str();
}

}  // namespace

std::vector<std::pair<std::string, double>> progressFigures(const nlohmann::json& m) {
  std::vector<std::pair<std::string, double>> out = assessmentFigures(m);
  const nlohmann::json tracking = m.value("tracking", nlohmann::json::object());
  for (const std::string& c : anatomicalKeys(tracking)) {
    const nlohmann::json& v = tracking[c]["rms_error_deg"];
    if (v.is_number() && std::isfinite(v.get<double>())) out.emplace_back("tracking." + c + ".rms_error_deg", v.get<double>());
  }
  const nlohmann::json transparency = m.value("transparency", nlohmann::json::object());
  for (const std::string& c : anatomicalKeys(transparency)) {
    const nlohmann::json& v = transparency[c]["interaction_rms"];
    if (v.is_number() && std::isfinite(v.get<double>())) out.emplace_back("transparency." + c + ".interaction_rms", v.get<double>());
  }
  return out;
}

int figureDirection(const std::string& name) {
  auto starts = [&](const char* p) { return name.rfind(p, 0) == 0; };
  auto ends = [&](const char* s) {
    const std::size_t n = std::strlen(s);
    return name.size() >= n && name.compare(name.size() - n, n, s) == 0;
  };
  // Tardieu: the stretch runs from flexion towards extension, so a catch at less flexion comes later in it.
  if (starts("tardieu.catch") || starts("tardieu.gain") || starts("tardieu.reflex")) return -1;
  if (starts("tardieu.threshold")) return +1;
  // Ranges: the wider the better (less flexion at the extended end, more at the flexed end).
  if (starts("passive_rom.") || starts("rom.")) return ends("extension_deg") || ends("min_deg") ? -1 : +1;
  if (starts("max_force.")) return +1;
  if (starts("tracking.")) return -1;
  return 0;  // transparency: a property of the device, not of the patient
}

std::string progressOf(const std::string& records_dir, const std::string& patient, const nlohmann::json& repeatability,
                       const std::string& repeatability_source, nlohmann::json& out,
                       const std::function<void(const std::string&)>& progress) {
  if (!std::regex_match(patient, std::regex("[A-Za-z0-9_-]{1,64}"))) {
    return "patient '" + patient + "': not a patient id (1-64 characters of A-Z a-z 0-9 _ -)";
  }
  std::string error;
  if (!isDirectory(records_dir, error)) return error;
  const std::vector<std::string> files = patientRecords(records_dir, patient);
  if (files.empty()) {
    const std::vector<std::string> others = recordPatients(records_dir);
    std::string list;
    for (const std::string& o : others) list += (list.empty() ? "" : ", ") + o;
    return "no session records of patient '" + patient + "' in " + records_dir +
           (others.empty() ? std::string(" (it holds no session records: <patient>-<UTC start>.phrec)")
                           : " (records there are of: " + list + ")");
  }
  nlohmann::json sessions = nlohmann::json::array();
  for (std::size_t i = 0; i < files.size(); ++i) {
    if (progress) progress("reading " + std::to_string(i + 1) + "/" + std::to_string(files.size()) + " " + files[i]);
    nlohmann::json s;
    if (std::string err = sessionEntry(records_dir + "/" + files[i], files[i], patient, s); !err.empty()) return err;
    if (!sessions.empty() && s["device"] != sessions[0]["device"]) {
      return records_dir + "/" + files[i] + ": a " + s["device"].get<std::string>() + " session, the earlier ones are " +
             sessions[0]["device"].get<std::string>() + ": a progress report covers one device";
    }
    s["n"] = static_cast<int>(i + 1);
    sessions.push_back(std::move(s));
  }
  const std::string unit = sessions[0]["effort_unit"].get<std::string>();
  // Every figure any session has, in the order of the sessions' own lists (sections, then anatomical order).
  std::vector<std::string> names;
  for (const auto& s : sessions) {
    for (const auto& n : s["figure_order"]) {
      if (std::find(names.begin(), names.end(), n.get<std::string>()) == names.end()) names.push_back(n.get<std::string>());
    }
  }
  // Sessions with different exercises: keep each family together, in the sessions' order of families.
  static const std::vector<std::string> kFamilies = {"tardieu", "passive_rom", "max_force", "rom", "tracking", "transparency"};
  auto family = [](const std::string& n) {
    return std::find(kFamilies.begin(), kFamilies.end(), n.substr(0, n.find('.'))) - kFamilies.begin();
  };
  std::stable_sort(names.begin(), names.end(), [&](const std::string& a, const std::string& b) { return family(a) < family(b); });
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& rep = repeatability.is_object() && repeatability.contains("figures") ? repeatability["figures"] : none;
  nlohmann::json figures = nlohmann::json::array();
  for (const std::string& name : names) {
    const FigureInfo info = infoOf(name, unit);
    nlohmann::json values = nlohmann::json::array();
    for (const auto& s : sessions) values.push_back(s["figures"].contains(name) ? s["figures"][name] : nlohmann::json());
    nlohmann::json f{{"name", name},       {"section", info.section},
                     {"group", info.group}, {"title", info.title},
                     {"series", info.series}, {"unit", figureUnit(name, unit)},
                     {"direction", figureDirection(name)}, {"values", values}};
    if (rep.contains(name)) {
      f["mdc95"] = rep[name]["mdc95"];
      f["icc"] = rep[name]["icc"];
    }
    figures.push_back(std::move(f));
  }
  for (auto& s : sessions) s.erase("figure_order");
  out = {{"version", 1},
         {"patient", patient},
         {"device", sessions[0]["device"]},
         {"effort_unit", unit},
         {"records_dir", records_dir},
         {"sessions", sessions},
         {"figures", figures},
         {"mdc_source", repeatability.is_object()
                            ? nlohmann::json(repeatability.value("source", std::string("a repeatability study")) + ", " +
                                             repeatability_source)
                            : nlohmann::json()}};
  const std::size_t n = sessions.size();
  const std::size_t session_pages = 1 + (n > kSessionRowsFirstPage ? pagesFor(n - kSessionRowsFirstPage, kRowsPerPage) : 0);
  out["pages"] = session_pages + pagesFor(periodRows(sessions), kRowsPerPage) + pagesFor(figures.size(), kChangeRowsPerPage) +
                 plotPages(plotsOf(figures)).size();
  return "";
}

std::string progressHtml(const nlohmann::json& p) {
  std::ostringstream h;
  h << "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
       "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; style-src 'unsafe-inline'\">"
       "<title>Phalanx progress report: "
    << esc(p["patient"].get<std::string>())
    << "</title><style>"
       "@page{size:A4;margin:12mm}"
       "body{font-family:sans-serif;color:#222;margin:0;font-size:9.5pt}"
       ".page{width:186mm}.page+.page{break-before:page}"
       "h1{font-size:16pt;margin:0 0 3mm}h2{font-size:12pt;margin:2mm 0}"
       ".head{font-size:8pt;color:#666;border-bottom:1px solid #ccc;margin-bottom:2mm}"
       "table{border-collapse:collapse;margin:1mm 0;width:100%}td,th{border:1px solid #ccc;padding:1px 5px;"
       "text-align:right;font-size:8.5pt}th{background:#f4f4f4}td:first-child,th:first-child,td.text{text-align:left}"
       "table.kv{width:auto}.note{color:#444;font-size:8.5pt}.warn{color:#b00}.excl{color:#e67e00}"
       ".name{color:#777;font-size:7.5pt;font-family:monospace}.better{color:#176317}.worse{color:#b00}"
       ".same{color:#555}.plots{display:grid;grid-template-columns:1fr 1fr;gap:2mm 4mm}"
       "figure{margin:0;break-inside:avoid}figcaption{font-size:8.5pt;min-height:11mm}"
       "figure svg{width:100%;height:auto}"
       "</style></head><body>";
  h << summaryPages(p) << changePages(p) << plotPagesHtml(p);
  h << "<script type='application/json' id='progress'>" << esc(p.dump()) << "</script></body></html>\n";
  return h.str();
}

std::string writeProgressReport(const ProgressRequest& r, nlohmann::json& out,
                                const std::function<void(const std::string&)>& progress) {
  if (r.html_path.empty()) return "no output: give the HTML file (and a PDF file to print it to)";
  nlohmann::json rep;
  if (!r.repeatability_path.empty()) {
    if (std::string err = record::refuseSameFile(r.repeatability_path, r.html_path); !err.empty()) return err;
    if (std::string err = loadRepeatability(r.repeatability_path, rep); !err.empty()) return err;
  }
  if (!r.pdf_path.empty()) {
    if (std::string err = record::refuseSameFile(r.html_path, r.pdf_path); !err.empty()) return err;
  }
  if (std::string err = progressOf(r.records_dir, r.patient, rep, r.repeatability_path, out, progress); !err.empty()) {
    return err;
  }
  for (const auto& s : out["sessions"]) {
    const std::string rec = r.records_dir + "/" + s["file"].get<std::string>();
    for (const std::string* o : {&r.html_path, &r.pdf_path}) {
      if (o->empty()) continue;
      if (std::string err = record::refuseSameFile(rec, *o); !err.empty()) return err;
    }
  }
  if (progress) progress("writing " + r.html_path);
  record::AtomicOutputFile html;
  if (std::string err = html.open(r.html_path); !err.empty()) return err;
  html.write(progressHtml(out));
  if (std::string err = html.commit(); !err.empty()) return err;
  if (r.pdf_path.empty()) return "";
  if (progress) progress("printing " + r.pdf_path + " (headless Chromium)");
  return printHtmlToPdf(r.html_path, r.pdf_path);
}

namespace {

std::string chromiumExecutable() {
  if (const char* e = std::getenv("PHALANX_CHROMIUM"); e != nullptr && *e != 0) return e;
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"}) {
    if (::access(p, X_OK) == 0) return p;
  }
  return "";
}

/// file:// URL of an absolute path, every byte outside the unreserved set percent-encoded.
std::string fileUrl(const std::string& abs) {
  static const char* kHex = "0123456789ABCDEF";
  std::string u = "file://";
  for (unsigned char c : abs) {
    if (std::isalnum(c) != 0 || c == '/' || c == '-' || c == '_' || c == '.' || c == '~') {
      u += static_cast<char>(c);
    } else {
      u += '%';
      u += kHex[c >> 4];
      u += kHex[c & 15];
    }
  }
  return u;
}

std::string tail(const std::string& path, std::size_t n) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string s = ss.str();
  return s.size() > n ? s.substr(s.size() - n) : s;
}

}  // namespace

std::string printHtmlToPdf(const std::string& html_path, const std::string& pdf_path) {
  const std::string exe = chromiumExecutable();
  if (exe.empty() || ::access(exe.c_str(), X_OK) != 0) {
    return "cannot print " + pdf_path + ": Chromium not found (" + (exe.empty() ? "/usr/bin/chromium" : exe) +
           "; install the Debian package chromium or set PHALANX_CHROMIUM); the HTML report " + html_path +
           " was written";
  }
  char abs[PATH_MAX];
  if (::realpath(html_path.c_str(), abs) == nullptr) return html_path + ": " + std::strerror(errno);
  // The PDF goes to a temporary file beside the output, renamed over it once complete (as every export).
  const auto slash = pdf_path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : pdf_path.substr(0, slash);
  const std::string base = slash == std::string::npos ? pdf_path : pdf_path.substr(slash + 1);
  std::string temp = dir + "/." + base + ".XXXXXX";
  const int fd = ::mkstemp(temp.data());
  if (fd < 0) return "cannot write " + pdf_path + ": " + std::strerror(errno);
  ::close(fd);
  char profile_tmpl[] = "/tmp/phalanx-print-XXXXXX";
  if (::mkdtemp(profile_tmpl) == nullptr) {
    ::unlink(temp.c_str());
    return std::string("cannot create a temporary Chromium profile: ") + std::strerror(errno);
  }
  const std::string profile = profile_tmpl, log = profile + "/chromium.log";
  std::vector<std::string> args = {exe, "--headless", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
                                   "--no-default-browser-check", "--disable-extensions", "--user-data-dir=" + profile,
                                   "--no-pdf-header-footer", "--print-to-pdf=" + temp};
  if (::geteuid() == 0) args.push_back("--no-sandbox");  // Chromium's sandbox refuses to run as root
  args.push_back(fileUrl(abs));
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setpgroup(&attr, 0);  // its own process group: a hung browser is ended with all its helpers
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  pid_t pid = -1;
  const int rc = ::posix_spawn(&pid, exe.c_str(), &fa, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  std::string error;
  if (rc != 0) {
    error = "cannot run " + exe + ": " + std::strerror(rc);
  } else {
    int status = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    pid_t done = 0;
    while ((done = ::waitpid(pid, &status, WNOHANG)) == 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (done == 0) {
      ::kill(-pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      error = exe + " did not finish printing within 120 s (stopped)";
    } else if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      error = exe + " failed printing " + html_path + " (status " + std::to_string(status) + "): " + tail(log, 400);
    }
  }
  if (error.empty()) {
    char magic[5] = {};
    std::ifstream(temp, std::ios::binary).read(magic, 5);
    if (std::string(magic, 5) != "%PDF-") error = exe + " wrote no PDF to " + pdf_path + ": " + tail(log, 400);
  }
  if (error.empty() && (::chmod(temp.c_str(), 0640) != 0 || ::rename(temp.c_str(), pdf_path.c_str()) != 0)) {
    error = "cannot write " + pdf_path + ": " + std::strerror(errno);
  }
  if (!error.empty()) ::unlink(temp.c_str());
  std::error_code ec;
  std::filesystem::remove_all(profile, ec);
  return error;
}

}  // namespace phalanx::host::therapy
