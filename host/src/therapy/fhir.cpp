#include "phalanx/host/therapy/fhir.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <regex>

#include "phalanx/host/record/output_file.h"
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

}  // namespace

nlohmann::json fhirBundle(const nlohmann::json& m, const std::string& record_name, std::string& error) {
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

std::string writeFhirBundle(const std::string& record_path, const std::string& out_path) {
  if (std::string err = record::refuseSameFile(record_path, out_path); !err.empty()) return err;
  record::SessionRecord rec;
  if (std::string err = record::readRecord(record_path, rec); !err.empty()) return err;
  const nlohmann::json m = sessionMetrics(rec);
  if (m.contains("error")) return record_path + ": " + m["error"].get<std::string>();
  std::string error;
  const nlohmann::json b = fhirBundle(m, record_path.substr(record_path.rfind('/') + 1), error);
  if (!error.empty()) return record_path + ": " + error;
  record::AtomicOutputFile out;
  if (std::string err = out.open(out_path); !err.empty()) return err;
  out.write(b.dump(2) + "\n");
  return out.commit();
}

}  // namespace phalanx::host::therapy
