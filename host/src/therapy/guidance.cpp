#include "phalanx/host/therapy/guidance.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "phalanx/host/session.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::therapy {
namespace {

namespace pf = protocol::fault;

// Every fault latches the device into its safe state first (firmware: outputs off, the glove's worm gears hold
// its fingers where they are, the SEA motors unpowered); the session goes on recording; "reset faults" sends one
// ClearFaults, which the device refuses while the cause persists.
constexpr const char* kSafeOff =
    "Yes: the device switched itself to its safe state at once: motors off, no force or torque is applied (the "
    "glove's worm gears hold its fingers where they are).";

const std::vector<FaultGuidance> kTable = {
    {pf::kCommandTimeout, "command-timeout",
     "The device stopped receiving commands from the computer in time (the computer was too busy, or the cable or "
     "link was interrupted).",
     kSafeOff,
     "Check the cable and that the computer is not overloaded, then press reset faults to continue. If it happens "
     "again, stop the session and report it."},
    {pf::kInvalidCommand, "invalid-command", "The device refused a command it received as invalid (a software fault).",
     kSafeOff, "Press reset faults to continue. If it happens again, stop the session and report it."},
    {pf::kEstop, "estop", "The emergency stop was pressed.", kSafeOff,
     "Check on the patient. When it is safe, release the emergency-stop button and press reset faults."},
    {pf::kSensorRange, "sensor-range",
     "A sensor reading is outside its plausible range (a loose connector or a damaged sensor).", kSafeOff,
     "Do not continue. Stop the session, take the device off the hand gently and have its cable and sensors "
     "checked."},
    {pf::kSensorStuck, "sensor-stuck", "A sensor stopped changing while the mechanism moved (a failed sensor).",
     kSafeOff,
     "Do not continue. Stop the session, take the device off the hand gently and have the sensor checked."},
    {pf::kForceLimit, "force-limit",
     "The measured force or torque exceeded the device's hard limit (a strong push, a spasm, or a sensor fault).",
     kSafeOff,
     "Ask the patient about pain or discomfort and check the finger. Reset faults to continue; if it happens "
     "again, lower the effort limit or stop."},
    {pf::kJointLimit, "joint-limit", "A joint moved outside the range the device allows.", kSafeOff,
     "Check the finger's position and comfort and bring it gently back into range, then press reset faults."},
    {pf::kCurrentLimit, "current-limit",
     "A motor drew more current than allowed (the mechanism was blocked or overloaded).", kSafeOff,
     "Check that nothing is jammed and the patient is comfortable, then press reset faults. If it happens again, "
     "stop the session."},
    {pf::kSensorSaturated, "sensor-saturated", "A force sensor reached the end of its measuring range.", kSafeOff,
     "Check that the patient is not pressing hard against the device, then press reset faults."},
    {pf::kMotorAngle, "motor-angle",
     "A motor turned beyond its watchdog window (on the SEA exoskeleton: the spring or cable may have slipped).",
     kSafeOff, "Stop the session and have the device's cable and spring checked before it is used again."},
    {pf::kTickOverrun, "tick-overrun", "The device's own control cycle missed its deadline.", kSafeOff,
     "Press reset faults to continue. If it happens again, stop the session and report it."},
    {pf::kInternal, "internal", "The device reported an internal error.", kSafeOff,
     "Stop the session, take the device off the hand and report the fault."},
};

int fingerRank(const std::string& n) {
  static const char* kFingers[] = {"thumb", "index", "middle", "ring", "little"};
  for (int i = 0; i < 5; ++i) {
    if (n.rfind(kFingers[i], 0) == 0) return i;
  }
  return -1;
}

int jointRank(const std::string& n) {
  const auto us = n.rfind('_');
  const std::string j = us == std::string::npos ? n : n.substr(us + 1);
  static const char* kJoints[] = {"cmc", "mcp", "pip", "ip", "dip"};
  static const int kRank[] = {0, 1, 2, 3, 3};
  for (int i = 0; i < 5; ++i) {
    if (j == kJoints[i]) return kRank[i];
  }
  return -1;
}

}  // namespace

const std::vector<FaultGuidance>& faultGuidanceTable() { return kTable; }

std::vector<FaultGuidance> faultGuidance(uint16_t bits) {
  std::vector<FaultGuidance> out;
  for (int i = 0; i < 16; ++i) {
    const auto bit = static_cast<uint16_t>(1u << i);
    if ((bits & bit) == 0) continue;
    const auto it = std::find_if(kTable.begin(), kTable.end(), [&](const FaultGuidance& g) { return g.bit == bit; });
    if (it != kTable.end()) {
      out.push_back(*it);
    } else {
      out.push_back({bit, faultName(bit), "The device reported a fault this version does not know.", kSafeOff,
                     "Stop the session and report the fault."});
    }
  }
  return out;
}

nlohmann::json faultGuidanceJson(uint16_t bits) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& g : faultGuidance(bits)) {
    out.push_back({{"fault", g.fault}, {"what", g.what}, {"safe", g.safe}, {"action", g.action}});
  }
  return out;
}

std::string faultGuidanceText(uint16_t bits) {
  std::string out;
  for (const auto& g : faultGuidance(bits)) {
    out += std::string("FAULT ") + g.fault + "\n  what happened: " + g.what + "\n  patient safe:  " + g.safe +
           "\n  what to do:    " + g.action + "\n";
  }
  return out;
}

int anatomicalRank(const std::string& name) {
  const int f = fingerRank(name), j = jointRank(name);
  if (f < 0 && j < 0) return 1000;
  // A finger's own channel ("index") sorts with its joints; device joints without a finger (SEA "mcp") by joint.
  return (f < 0 ? 0 : f) * 10 + (j < 0 ? 0 : j + 1);
}

std::vector<std::string> anatomicalOrder(std::vector<std::string> names) {
  std::stable_sort(names.begin(), names.end(), [](const std::string& a, const std::string& b) {
    const int ra = anatomicalRank(a), rb = anatomicalRank(b);
    return ra != rb ? ra < rb : a < b;
  });
  return names;
}

std::vector<std::string> anatomicalKeys(const nlohmann::json& object) {
  std::vector<std::string> keys;
  if (!object.is_object()) return keys;
  for (const auto& [k, v] : object.items()) keys.push_back(k);
  return anatomicalOrder(std::move(keys));
}

std::string humanNumber(double v, int digits) {
  if (!std::isfinite(v)) return std::isnan(v) ? "–" : (v > 0 ? "inf" : "-inf");
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  std::string s = b;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

}  // namespace phalanx::host::therapy
