#pragma once
/// A session's results as HL7 FHIR R4 resources (docs/fhir.md): one `Bundle` (type collection) of `Observation`s
/// — active range of motion per joint, the instrumented assessments' figures (passive ROM, maximal voluntary
/// force, the Modified Tardieu catch angle and stretch reflex), interaction effort per channel during assessment,
/// tracking error during assistance/playback, peak effort, the session's duration, faults and excluded (locked)
/// time — each with the
/// patient as `subject` (a `Patient` reference by the profile's id). Codes: LOINC where a code exists for the
/// quantity (none does yet for these instrumented finger measurements: docs/fhir.md says why), else the local
/// code system kPhalanxCodeSystem documented in docs/fhir.md.
#include <string>

#include <nlohmann/json.hpp>

#include "phalanx/host/record/record_reader.h"

namespace phalanx::host::therapy {

inline constexpr const char* kPhalanxCodeSystem = "urn:phalanx:fhir:codesystem:session-metrics:1";
inline constexpr const char* kPhalanxPatientIdSystem = "urn:phalanx:patient-id";
inline constexpr const char* kPhalanxRecordSystem = "urn:phalanx:session-record";

/// The Bundle of a session's metrics (sessionMetrics()). `record_name`: the record's file name (the Bundle's
/// identifier). `repeatability` (loadRepeatability's JSON, or null) adds each instrumented figure's ICC(2,1) and
/// MDC95 as components of its Observation. Empty JSON with `error` set when the session has no patient (no
/// subject to report on).
nlohmann::json fhirBundle(const nlohmann::json& metrics, const std::string& record_name, std::string& error,
                          const nlohmann::json& repeatability = nullptr);

/// Reads record_path (and the repeatability file, if given), writes the Bundle (JSON) to out_path atomically.
/// "" or an error.
std::string writeFhirBundle(const std::string& record_path, const std::string& out_path,
                            const std::string& repeatability_path = "");

}  // namespace phalanx::host::therapy
