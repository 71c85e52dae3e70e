#pragma once
/// What a therapist reads: fault guidance in plain words (one table, used by the CLI, the dashboard and the
/// report), and the anatomical order of fingers and joints (thumb → little; CMC/MCP → PIP → DIP/IP).
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace phalanx::host::therapy {

/// One latched fault, explained: what happened, whether the patient is safe, what to do.
struct FaultGuidance {
  uint16_t bit;
  const char* fault;   ///< the wire name (faultName(bit))
  const char* what;    ///< what happened
  const char* safe;    ///< whether the patient is safe, and why
  const char* action;  ///< what to do
};

/// The whole table, in bit order (one row per fault bit the firmware can latch).
const std::vector<FaultGuidance>& faultGuidanceTable();
/// The rows of every bit set in `bits` (bit order); an unknown bit gets a generic row.
std::vector<FaultGuidance> faultGuidance(uint16_t bits);
/// The same as JSON: [{fault, what, safe, action}, ...] (empty array for 0).
nlohmann::json faultGuidanceJson(uint16_t bits);
/// Plain-text block for a terminal (each fault: its name, then three indented lines), "" for 0.
std::string faultGuidanceText(uint16_t bits);

/// Sort rank of a finger/joint/channel name: thumb, index, middle, ring, little, then CMC, MCP, PIP, DIP/IP.
/// Names the table does not know rank last (in alphabetical order among themselves).
int anatomicalRank(const std::string& name);
/// The keys of a JSON object in anatomical order (nlohmann::json keeps its keys alphabetical).
std::vector<std::string> anatomicalKeys(const nlohmann::json& object);
/// A copy of `names` in anatomical order.
std::vector<std::string> anatomicalOrder(std::vector<std::string> names);

/// A number for people: at most `digits` decimals, trailing zeros dropped, never "-0" (-29.999999999999996 with
/// digits 2 → "-30", -0.0 → "0", 2.50 → "2.5").
std::string humanNumber(double v, int digits = 2);

}  // namespace phalanx::host::therapy
