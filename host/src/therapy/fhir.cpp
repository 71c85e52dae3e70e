#include "phalanx/host/therapy/fhir.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <regex>

#include "phalanx/host/record/output_file.h"
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/guidance.h"
#include "phalanx/host/therapy/report.h"

namespace phalanx::host::therapy {
namespace {

/// FNV-1a, 64 bit: deterministic entry ids (the same record gives the same Bundle, byte for byte).
uint64_t fnv1a(const std::string& s, uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

/// A version-4-shaped UUID derived from the text (RFC 4122 layout: version and variant bits set).
std::string uuidOf(const std::string& text) {
  const uint64_t a = fnv1a(text), b = fnv1a(text, a ^ 0x9e3779b97f4a7c15ull);
  char out[40];
  std::snprintf(out, sizeof out, "%08x-%04x-4%03x-%04x-%012llx", static_cast<unsigned>(a >> 32),
                static_cast<unsigned>((a >> 16) & 0xffff), static_cast<unsigned>(a & 0xfff),
                static_cast<unsigned>(0x8000 | ((b >> 48) & 0x3fff)),
                static_cast<unsigned long long>(b & 0xffffffffffffull));
  return out;
}

/// UCUM for the units the device reports.
std::string ucum(const std::string& unit) {
  if (unit == "N·m") return "N.m";
  return unit;
}

nlohmann::json quantity(double v, const std::string& unit, const std::string& code) {
  // FHIR decimals: finite only; 6 significant digits are far beyond the instruments' resolution.
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return {{"value", std::strtod(b, nullptr)}, {"unit", unit}, {"system", "http://unitsofmeasure.org"}, {"code", code}};
}

nlohmann::json localCode(const std::string& code, const std::string& display) {
  return {{"coding", {{{"system", kPhalanxCodeSystem}, {"code", code}, {"display", display}}}}, {"text", display}};
}

/// "index_mcp" → "index finger MCP joint", "thumb" → "thumb", SEA "mcp" → "MCP joint (index finger exoskeleton)".
std::string bodySiteText(const std::string& name, const std::string& device) {
  const auto us = name.find('_');
  std::string finger = us == std::string::npos ? "" : name.substr(0, us);
  std::string joint = us == std::string::npos ? name : name.substr(us + 1);
  if (finger.empty() && (joint == "thumb" || joint == "index" || joint == "middle" || joint == "ring" || joint == "little")) {
    return joint == "thumb" ? "thumb" : joint + " finger";
  }
  for (auto& c : joint) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (finger.empty()) return joint + " joint of the finger in the " + device + " exoskeleton (index finger)";
  return (finger == "thumb" ? std::string("thumb") : finger + " finger") + " " + joint + " joint";
}

/// The local code, display text, UCUM unit and body site of an instrumented-assessment figure
/// (assessmentFigures()); false for the figures exported otherwise (the active ROM).
struct FigureCode {
  std::string code, display, unit, site;
};
bool figureCode(const std::string& name, const nlohmann::json& in, const std::string& effort_unit, FigureCode& out) {
  const bool glove = effort_unit == "N";
  const std::string u = ucum(effort_unit);
  const auto dot1 = name.find('.'), dot2 = name.find('.', dot1 + 1);
  const std::string family = name.substr(0, dot1);
  const std::string part = name.substr(dot1 + 1, dot2 == std::string::npos ? std::string::npos : dot2 - dot1 - 1);
  const std::string last = dot2 == std::string::npos ? "" : name.substr(dot2 + 1);
  const std::string stretched = in.contains("tardieu") ? in["tardieu"].value("channel", std::string()) : "";
  if (family == "passive_rom") {
    out = last == "extension_deg"
              ? FigureCode{"passive-rom-extension", "Passive range of motion: flexion of the relaxed joint under the extending test effort", "deg", part}
              : FigureCode{"passive-rom-flexion", "Passive range of motion: flexion of the relaxed joint under the flexing test effort", "deg", part};
    return true;
  }
  if (family == "max_force") {
    out = {"max-voluntary-effort", glove ? "Maximal voluntary fingertip force (isometric, the device holding the pose)"
                                         : "Maximal voluntary finger joint torque (isometric, the device holding the pose)",
           u, part};
    return true;
  }
  if (family != "tardieu") return false;
  if (part == "catch_deg") out = {"tardieu-catch-angle", "Catch angle: joint flexion at the catch of the fastest stretch (instrumented Modified Tardieu, R1)", "deg", stretched};
  else if (part == "threshold_deg_s") out = {"stretch-reflex-threshold-velocity", "Stretch-reflex threshold velocity (instrumented Modified Tardieu)", "deg/s", stretched};
  else if (part == "gain_per_rad_s") out = {"stretch-reflex-gain", "Stretch-reflex gain: reflex effort per stretch velocity above the threshold", u + ".s/rad", stretched};
  else out = {"stretch-reflex-effort", "Mean stretch-reflex effort after the catch in one imposed stretch", u, stretched};
  return true;
}

/// The nominal velocity (deg/s) of a figure tardieu.reflex_at_<v>_deg_s, and that stretch's figures.
nlohmann::json stretchOf(const std::string& name, const nlohmann::json& in) {
  const std::string prefix = "tardieu.reflex_at_";
  if (name.rfind(prefix, 0) != 0 || !in.contains("tardieu")) return nullptr;
  const int v = std::atoi(name.c_str() + prefix.size());
  for (const auto& s : in["tardieu"].value("stretches", nlohmann::json::array())) {
    if (s.value("nominal_deg_s", -1) == v) return s;
  }
  return nullptr;
}

}  // namespace

nlohmann::json fhirBundle(const nlohmann::json& m, const std::string& record_name, std::string& error,
                          const nlohmann::json& repeatability) {
  const std::string patient = m.value("patient", std::string());
  if (patient.empty()) {
    error = "the record has no patient (a session without a profile): a FHIR Observation needs a subject";
    return {};
  }
  const std::string device = m.value("device", std::string());
  const std::string start = m.value("start_utc", std::string());
  const std::string unit = m.value("effort_unit", std::string());
  const bool glove = unit == "N";
  // effectivePeriod: start and end (start + duration) in the FHIR dateTime format.
  nlohmann::json period = nlohmann::json::object();
  if (!start.empty()) {
    period["start"] = start;
    std::tm tm{};
    if (::strptime(start.c_str(), "%Y-%m-%dT%H:%M:%SZ", &tm) != nullptr) {
      const std::time_t t0 = ::timegm(&tm) + static_cast<std::time_t>(std::ceil(m.value("duration_s", 0.0)));
      char b[32];
      std::tm e{};
      ::gmtime_r(&t0, &e);
      std::strftime(b, sizeof b, "%Y-%m-%dT%H:%M:%SZ", &e);
      period["end"] = b;
    }
  }
  nlohmann::json subject{{"type", "Patient"},
                         {"identifier", {{"system", kPhalanxPatientIdSystem}, {"value", patient}}},
                         {"display", patient}};
  // A FHIR id is [A-Za-z0-9.-]{1,64}: a profile id with '_' is referred to by its identifier only.
  if (std::regex_match(patient, std::regex("[A-Za-z0-9.-]{1,64}"))) subject["reference"] = "Patient/" + patient;
  const std::string method_text = "Instrumented measurement by the " + device +
                                  (glove ? " force-feedback glove" : " series-elastic finger exoskeleton") +
                                  " (Phalanx)";
  const double excluded_s = m.value("excluded_s", 0.0);
  const std::string exclusion_note =
      excluded_s > 0.0 ? "Excludes " + humanNumber(excluded_s, 1) +
                             " s during which the device was locked or faulted (not exercise)."
                       : "";
  nlohmann::json entries = nlohmann::json::array();
  auto add = [&](const std::string& key, nlohmann::json code, const std::string& site, nlohmann::json value,
                 nlohmann::json components, const std::string& category) {
    nlohmann::json o{{"resourceType", "Observation"},
                     {"status", m.value("complete", true) ? "final" : "preliminary"},
                     {"category", {{{"coding", {{{"system", "http://terminology.hl7.org/CodeSystem/observation-category"},
                                                 {"code", category}}}}}}},
                     {"code", std::move(code)},
                     {"subject", subject},
                     {"device", {{"display", device}}},
                     {"method", {{"text", method_text}}}};
    if (!period.empty()) o["effectivePeriod"] = period;
    if (!site.empty()) o["bodySite"] = {{"text", site}};
    if (!value.is_null()) o["valueQuantity"] = std::move(value);
    if (!components.empty()) o["component"] = std::move(components);
    if (!exclusion_note.empty()) o["note"] = {{{"text", exclusion_note}}};
    if (!m.value("complete", true)) {
      o["note"].push_back({{"text", "The record has no end marker (the daemon stopped without closing it)."}});
    }
    entries.push_back({{"fullUrl", "urn:uuid:" + uuidOf(record_name + "|" + key)}, {"resource", std::move(o)}});
  };
  const std::string rom_source = m.value("rom_source", std::string());
  const nlohmann::json rom = m.value("rom_deg", nlohmann::json::object());
  for (const std::string& j : anatomicalKeys(rom)) {
    const double lo = rom[j][0].get<double>(), hi = rom[j][1].get<double>();
    nlohmann::json comps = nlohmann::json::array();
    comps.push_back({{"code", localCode("flexion-min", "Least flexion reached")}, {"valueQuantity", quantity(lo, "deg", "deg")}});
    comps.push_back({{"code", localCode("flexion-max", "Greatest flexion reached")}, {"valueQuantity", quantity(hi, "deg", "deg")}});
    add("rom|" + j, localCode("active-rom", "Active range of motion of a finger joint (flexion arc)"),
        bodySiteText(j, device), quantity(hi - lo, "deg", "deg"), comps, "exam");
    if (!rom_source.empty()) entries.back()["resource"]["method"]["text"] = method_text + "; measured during " + rom_source;
  }
  const nlohmann::json tr = m.value("transparency", nlohmann::json::object());
  for (const std::string& c : anatomicalKeys(tr)) {
    add("interaction|" + c,
        localCode("interaction-effort-rms", glove ? "Fingertip interaction force during free motion (RMS)"
                                                  : "Finger joint interaction torque during free motion (RMS)"),
        bodySiteText(c, device), quantity(tr[c]["interaction_rms"].get<double>(), unit, ucum(unit)),
        nlohmann::json::array({{{"code", localCode("interaction-effort-peak", "Peak interaction effort")},
                                {"valueQuantity", quantity(tr[c]["interaction_peak"].get<double>(), unit, ucum(unit))}}}),
        "exam");
  }
  const nlohmann::json tk = m.value("tracking", nlohmann::json::object());
  for (const std::string& c : anatomicalKeys(tk)) {
    nlohmann::json comps = nlohmann::json::array();
    if (tk[c]["pearson_r"].is_number()) {
      comps.push_back({{"code", localCode("tracking-pearson-r", "Pearson r between target and measured flexion")},
                       {"valueQuantity", quantity(tk[c]["pearson_r"].get<double>(), "1", "1")}});
    }
    comps.push_back({{"code", localCode("tracking-duration", "Time spent tracking a target")},
                     {"valueQuantity", quantity(tk[c]["seconds"].get<double>(), "s", "s")}});
    add("tracking|" + c, localCode("tracking-rms-error", "Finger flexion tracking error against the exercise target (RMS)"),
        bodySiteText(c, device), quantity(tk[c]["rms_error_deg"].get<double>(), "deg", "deg"), comps, "therapy");
  }
  // The instrumented assessments (assessment_analysis.h), one Observation per figure, with the figure's ICC(2,1)
  // and MDC95 as components when a repeatability study gives them.
  const nlohmann::json in = m.value("instrumented", nlohmann::json::object());
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& rep = repeatability.is_object() && repeatability.contains("figures") ? repeatability["figures"] : none;
  for (const auto& [name, v] : assessmentFigures(m)) {
    FigureCode fc;
    if (!figureCode(name, in, unit, fc)) continue;
    nlohmann::json comps = nlohmann::json::array();
    if (const nlohmann::json st = stretchOf(name, in); st.is_object()) {
      comps.push_back({{"code", localCode("stretch-velocity-nominal", "Imposed stretch velocity")},
                       {"valueQuantity", quantity(st["nominal_deg_s"].get<double>(), "deg/s", "deg/s")}});
      if (st["velocity_deg_s"].is_number()) {
        comps.push_back({{"code", localCode("stretch-velocity-measured", "Measured stretch velocity")},
                         {"valueQuantity", quantity(st["velocity_deg_s"].get<double>(), "deg/s", "deg/s")}});
      }
    }
    if (rep.contains(name)) {
      comps.push_back({{"code", localCode("icc-2-1", "Test-retest ICC(2,1) of this measurement")},
                       {"valueQuantity", quantity(rep[name]["icc"].get<double>(), "1", "1")}});
      comps.push_back({{"code", localCode("mdc95", "Minimal detectable change (95 %) of this measurement")},
                       {"valueQuantity", quantity(rep[name]["mdc95"].get<double>(), fc.unit, fc.unit)}});
    }
    add("figure|" + name, localCode(fc.code, fc.display), fc.site.empty() ? "" : bodySiteText(fc.site, device),
        quantity(v, fc.unit, fc.unit), comps, "exam");
    nlohmann::json& o = entries.back()["resource"];
    o["method"]["text"] = method_text + "; figure " + name;
    if (rep.contains(name)) {
      o["note"].push_back({{"text", "ICC(2,1) and MDC95 are the measurement's test-retest repeatability from " +
                                        repeatability.value("source", std::string("a repeatability study")) +
                                        ", not properties of this patient."}});
    }
  }
  const nlohmann::json ef = m.value("effort", nlohmann::json::object());
  for (const std::string& c : anatomicalKeys(ef)) {
    add("peak|" + c,
        localCode("peak-effort", glove ? "Peak fingertip force measured in the session"
                                       : "Peak finger joint torque measured in the session"),
        bodySiteText(c, device), quantity(ef[c]["peak_measured"].get<double>(), unit, ucum(unit)), nullptr, "exam");
  }
  nlohmann::json comps = nlohmann::json::array();
  comps.push_back({{"code", localCode("excluded-time", "Time the device was locked or faulted (excluded from the metrics)")},
                   {"valueQuantity", quantity(excluded_s, "s", "s")}});
  comps.push_back({{"code", localCode("faults-seen", "Device faults latched during the session")},
                   {"valueString", m.value("faults_seen", std::string("none"))}});
  add("session", localCode("session-duration", "Duration of the instrumented therapy session"), "",
      quantity(m.value("duration_s", 0.0), "s", "s"), comps, "therapy");
  nlohmann::json bundle{{"resourceType", "Bundle"},
                        {"identifier", {{"system", kPhalanxRecordSystem}, {"value", record_name}}},
                        {"type", "collection"},
                        {"entry", entries}};
  if (!start.empty()) bundle["timestamp"] = start;
  return bundle;
}

std::string writeFhirBundle(const std::string& record_path, const std::string& out_path,
                            const std::string& repeatability_path) {
  if (std::string err = record::refuseSameFile(record_path, out_path); !err.empty()) return err;
  nlohmann::json rep;
  if (!repeatability_path.empty()) {
    if (std::string err = record::refuseSameFile(repeatability_path, out_path); !err.empty()) return err;
    if (std::string err = loadRepeatability(repeatability_path, rep); !err.empty()) return err;
  }
  record::SessionRecord rec;
  if (std::string err = record::readRecord(record_path, rec); !err.empty()) return err;
  const nlohmann::json m = sessionMetrics(rec);
  if (m.contains("error")) return record_path + ": " + m["error"].get<std::string>();
  std::string error;
  const nlohmann::json b = fhirBundle(m, record_path.substr(record_path.rfind('/') + 1), error, rep);
  if (!error.empty()) return record_path + ": " + error;
  record::AtomicOutputFile out;
  if (std::string err = out.open(out_path); !err.empty()) return err;
  out.write(b.dump(2) + "\n");
  return out.commit();
}

}  // namespace phalanx::host::therapy
