#pragma once
/// Patient profiles: validated, versioned YAML files (docs/therapy.md has the schema) and the limits they
/// impose, enforced by the daemon on top of the device's own limits.
#include <array>
#include <cstddef>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/therapy/device.h"

namespace phalanx::host::therapy {

/// Limits enforced every cycle on the exercise's output (never loosened beyond the device's own limits).
struct PatientLimits {
  std::size_t channel_count = 0;
  std::size_t joint_count = 0;
  std::array<double, kMaxChannels> effort_max{};  ///< |effort| per channel (N or N·m)
  std::array<double, kMaxJoints> flexion_min_rad{};
  std::array<double, kMaxJoints> flexion_max_rad{};
  std::array<std::size_t, kMaxJoints> joint_channel{};

  /// The device's own limits, nothing patient-specific.
  static PatientLimits deviceDefaults(const TherapyDevice& device);
  /// Real time: clamp effort[c] in place. |effort| ≤ effort_max; a channel whose joint is beyond its range
  /// is never pushed further out (flexion beyond max: no flexing effort; below min: no extending effort).
  /// Non-finite effort becomes 0. Returns a bit per channel that was limited.
  uint32_t apply(const Observation& obs, std::array<double, kMaxChannels>& effort) const;
};

/// A named exercise with its parameters, chosen by the therapist instead of typing parameters (`presets:`).
struct Preset {
  std::string name;
  std::string exercise;
  nlohmann::json params = nlohmann::json::object();
};

/// A session plan kept in the profile (`plans:`), started by name. Validated at load with the plan parser
/// (parsePlan, against the device and this profile's presets and ranges) and parsed again at `start` (so
/// self-training's `allowed` is checked there, as for an inline plan).
struct NamedPlan {
  std::string name;
  nlohmann::json plan;        ///< {"steps": [...]}: the profile's YAML as the API's inline plan
  std::size_t step_count = 0;
  double total_s = 0.0;       ///< all steps' durations
};

/// What the patient may do alone (`self_training:`); a self-training start is refused without it.
struct SelfTraining {
  bool allowed = false;               ///< the profile has a self_training section
  std::set<std::string> steps;        ///< preset or exercise names the patient may run alone
  double max_session_s = 0.0;         ///< the session ends after this long
  double effort_scale = 1.0;          ///< (0, 1]: the profile's effort_max scaled by it while self-training
};

struct Profile {
  int version = 1;
  std::string patient;      ///< id: letters, digits, '-', '_' (1–64), not "anonymous"; no names on disk
  std::string device;       ///< glove5 (sea_finger once its adapter exists)
  std::string size;         ///< S | M | L (glove shell / exoskeleton link setting)
  std::string handedness;   ///< left | right
  KinematicParams kinematics;
  /// Measured active range of motion per joint (rad, flexion positive) from the last assessment.
  std::vector<std::pair<std::string, std::pair<double, double>>> rom_rad;
  PatientLimits limits;     ///< resolved against the device
  std::vector<Preset> presets;
  std::vector<NamedPlan> plans;
  SelfTraining self_training;
  std::string source;       ///< file it came from
};

/// Parse and validate; nothing in `out` changes unless the whole profile is valid. Returns "" or
/// "<source>: <key>: <problem>".
std::string loadProfileText(const std::string& yaml_text, const std::string& source, Profile& out);
/// Reads `path` with readProfileFile, then loadProfileText.
/// From a file: a regular file of at most 1 MiB, named after its patient (`<patient>.yaml`, any extension): a
/// `patient` field that differs from the file name is refused naming both.
std::string loadProfileFile(const std::string& path, Profile& out);

/// The largest profile file read (a real one is < 4 KiB).
constexpr std::size_t kMaxProfileBytes = 1024 * 1024;
/// Reads a profile file without ever waiting: opened O_NONBLOCK|O_NOFOLLOW, refused unless a regular file of at
/// most kMaxProfileBytes. Returns "" or "<path>: <why>".
std::string readProfileFile(const std::string& path, std::string& text);

}  // namespace phalanx::host::therapy
