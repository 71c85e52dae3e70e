#pragma once
/// Session plans (docs/therapy.md "Session plan"): an ordered list of steps, each an exercise (or a preset of the
/// patient's profile) for a duration in session time with an optional repetition target, run one after the other
/// by the session. parsePlan() validates a plan on the API thread; PlanRunner is its loop-side bookkeeping (O(1),
/// no allocation per cycle); RepetitionCounter counts flex-extend cycles of one channel coordinate.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/profile.h"

namespace phalanx::host::therapy {

/// One repetition = the channel coordinate q going from at most `extend_rad` to at least `flex_rad` and back to at
/// most `extend_rad` (counted on the return). Starting flexed, the first return only arms it. Hysteresis
/// = flex − extend, so noise smaller than that never counts one. Real time: no allocation.
struct RepetitionCounter {
  double extend_rad = 0.0;
  double flex_rad = 0.0;
  bool armed = false;   ///< q has been at or below extend
  bool flexed = false;  ///< since armed, q has reached flex
  uint32_t count = 0;
  void reset() { armed = flexed = false; count = 0; }
  /// Feeds one sample; returns true when it completed a repetition. A non-finite q is ignored.
  bool update(double q_rad);
};

inline constexpr std::size_t kMaxPlanSteps = 32;          ///< a therapy session is a handful of exercises
inline constexpr double kMaxPlanStepS = 3600.0;           ///< one step of at most an hour
inline constexpr double kMaxPlanTotalS = 4.0 * 3600.0;    ///< a whole plan of at most four hours
inline constexpr uint32_t kMaxPlanRepetitions = 1000;
/// Repetition thresholds at these fractions of the patient's range of the channel coordinate.
inline constexpr double kRepExtendFraction = 0.25;
inline constexpr double kRepFlexFraction = 0.75;

struct PlanStep {
  std::string preset;        ///< "" or the profile preset it came from
  std::string exercise;
  nlohmann::json params = nlohmann::json::object();
  double duration_s = 0.0;
  uint32_t repetitions = 0;  ///< target; 0 = none (counted, the step runs its duration)
  std::size_t channel = 0;   ///< the channel whose coordinate is counted
  double extend_rad = 0.0, flex_rad = 0.0;
};

struct SessionPlan {
  std::string name;          ///< "" (inline) or the profile plan it came from
  std::vector<PlanStep> steps;
  bool empty() const { return steps.empty(); }
  double totalS() const;
  /// The normalised plan (for the record header, status and the report): steps with their resolved fields.
  nlohmann::json toJson(const TherapyDevice& device) const;
};

/// The presets of a profile (`presets:`) as the API lists them: {name: {exercise, params}}.
nlohmann::json presetsJson(const Profile& profile);
/// The plans of a profile (`plans:`) as the API lists them: {name: {steps (count), duration_s (all steps)}}.
nlohmann::json plansJson(const Profile& profile);
/// The profile's plan of that name, or nullptr.
const NamedPlan* findPlan(const Profile& profile, const std::string& name);
/// "a, b" (the names of the profile's plans) or "none".
std::string planList(const Profile& profile);

/// Validates `j` ({"steps": [...]}) against the device and the profile (its presets, ranges); when `allowed` is
/// non-null, every step's preset or exercise must be in it (self-training). Every field is checked; errors name
/// it after `where` ("plan", or "plans.<name>" for a profile's plan): "plan.steps[1].duration_s: must be in
/// (0, 3600] s". Each step's exercise is built once to check its parameters. `out` changes only when the whole
/// plan is valid. Returns "" or the error.
std::string parsePlan(const nlohmann::json& j, const TherapyDevice& device, const Profile& profile,
                      const std::set<std::string>* allowed, SessionPlan& out, const std::string& where = "plan");

/// The loop's view of a running plan. Built before the session starts with every step's exercise prebuilt (step 0's
/// is the session's first exercise), so advancing hands over a ready object and allocates nothing. cycle() is
/// called once per loop cycle; status is published through atomics for the API thread.
class PlanRunner {
 public:
  enum class Ended : uint8_t { kNo = 0, kDuration = 1, kRepetitions = 2 };
  PlanRunner(SessionPlan plan, std::vector<std::unique_ptr<Exercise>> later_steps);
  const SessionPlan& plan() const { return plan_; }

  /// Loop: counts dt_s of a cycle that `counts` (not paused, not faulted or locked) on the current step's clock,
  /// feeds the channel coordinate to its repetition counter, and ends the step at its duration or its repetition
  /// target, whichever comes first. Returns kNo or why the step (index endedStep()) ended.
  Ended cycle(const Observation& obs, double dt_s, bool counts);
  /// Loop, after cycle() ended a step that was not the last: the next step's exercise (ownership passes on).
  Exercise* takeNextExercise();
  std::size_t endedStep() const { return ended_step_; }

  // Any thread.
  std::size_t step() const { return step_.load(std::memory_order_relaxed); }
  bool finished() const { return finished_.load(std::memory_order_relaxed); }
  double elapsedS() const { return static_cast<double>(elapsed_us_.load(std::memory_order_relaxed)) * 1e-6; }
  uint32_t repetitions() const { return reps_.load(std::memory_order_relaxed); }
  /// Outcome of step i once it ended: reason, repetitions, counted seconds (valid for i < step() or finished()).
  struct StepResult {
    std::atomic<uint8_t> ended{0};
    std::atomic<uint32_t> repetitions{0};
    std::atomic<int64_t> elapsed_us{0};
  };
  const StepResult& result(std::size_t i) const { return results_[i]; }

 private:
  void beginStep(std::size_t i);
  SessionPlan plan_;
  std::vector<std::unique_ptr<Exercise>> later_;  // later_[i] = step i's exercise (i ≥ 1); [0] empty
  std::array<StepResult, kMaxPlanSteps> results_{};
  RepetitionCounter counter_;
  double elapsed_s_ = 0.0;
  std::size_t ended_step_ = 0;
  std::atomic<std::size_t> step_{0};
  std::atomic<bool> finished_{false};
  std::atomic<int64_t> elapsed_us_{0};
  std::atomic<uint32_t> reps_{0};
};

/// The patient's range of each channel coordinate (rad): the profile's rom_deg within its allowed range, joint by
/// joint, summed per channel (the assistance exercise's range). `profile.limits` must be resolved for the device.
void patientChannelRange(const TherapyDevice& device, const Profile& profile, std::array<double, kMaxChannels>& lo,
                         std::array<double, kMaxChannels>& hi);

}  // namespace phalanx::host::therapy
