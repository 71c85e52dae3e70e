#pragma once
/// Therapy exercises, written once against TherapyDevice's channel space (docs/therapy.md):
///  - assessment: transparent (zero effort); the session records active range of motion and transparency
///    (000 §4.3 free-motion test, 001 §7.2–7.3).
///  - resistance: virtual spring + damper on each channel, effort = k·(q − q0)⁺ + b·q̇ (000 eq 1 applied to the
///    channel coordinate).
///  - assistance: towards a close/open target trajectory with assist-as-needed scaling (001 §9, Cai et al.
///    2006): no effort inside a tunnel of half-width w around the target, a spring outside it scaled by a gain g
///    that grows with the error and decays with a forgetting time constant.
///  - record-pattern / playback: record the patient's own grip/release pattern (transparent), then play it back
///    as the assistance target (000 §5).
///  - grasp: the device's virtual-object rendering (glove: GloveController, 000 eq 1).
///  - tardieu / passive-rom / max-force: the instrumented assessments (docs/therapy.md "Instrumented
///    assessments"); their figures are computed from the record (assessment_analysis.h).
/// Every exercise's update() runs in the 1 kHz loop: no allocation, no blocking.
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/protocol/messages.h"

namespace phalanx::host::therapy {

enum class ExerciseId : uint8_t {
  kIdle = 0,  ///< device held safe (before the first exercise, after "stop exercise")
  kAssessment = 1,
  kResistance = 2,
  kAssistance = 3,
  kRecordPattern = 4,
  kPlayback = 5,
  kGrasp = 6,
  kTardieu = 7,     ///< instrumented Modified Tardieu: imposed stretches of one channel at several velocities
  kPassiveRom = 8,  ///< passive ROM: a constant test effort extends, then flexes every channel
  kMaxForce = 9,    ///< maximal voluntary force: the device holds the pose, the patient pushes as hard as they can
};
const char* exerciseName(ExerciseId id);
/// Whether `name` is one of the exercises above (exerciseName of one of their ids).
bool isExerciseName(const std::string& name);

inline constexpr double kNoTarget = std::numeric_limits<double>::quiet_NaN();

struct ExerciseOutput {
  protocol::Mode mode = protocol::Mode::kSafe;
  std::array<double, kMaxChannels> effort{};       ///< + resists flexion
  std::array<uint16_t, kMaxChannels> gain_permille{};
  std::array<double, kMaxChannels> target_q_rad{};  ///< NaN: no target
  std::array<double, kMaxChannels> assist_gain{};   ///< NaN: not an assistance exercise
  void clear() {
    mode = protocol::Mode::kSafe;
    effort.fill(0.0);
    gain_permille.fill(1000);
    target_q_rad.fill(kNoTarget);
    assist_gain.fill(kNoTarget);
  }
};

class Exercise {
 public:
  virtual ~Exercise() = default;
  virtual ExerciseId id() const = 0;
  /// Called once in the loop when the exercise becomes active (t_s: session time). No allocation.
  virtual void start(const Observation& obs, double t_s) {
    (void)obs;
    (void)t_s;
  }
  virtual void update(const TelemetryFrame& tel, const Observation& obs, double t_s, double dt_s,
                      ExerciseOutput& out) = 0;
  /// Its parameters, as accepted (for records, status and reports).
  virtual nlohmann::json params() const = 0;
};

/// The grip/release pattern shared by record-pattern (writer, loop thread) and playback (reader, built on the
/// API thread): append-only, fixed capacity, length published with release semantics.
class Pattern {
 public:
  static constexpr double kRateHz = 100.0;       ///< 100 Hz: 10× the bandwidth of voluntary finger motion
  static constexpr std::size_t kMaxSamples = 6000;  ///< 60 s
  explicit Pattern(std::size_t channels) : channels_(channels), q_(kMaxSamples * channels) {}
  void reset() { length_.store(0, std::memory_order_release); }
  bool append(const std::array<double, kMaxChannels>& q);
  std::size_t length() const { return length_.load(std::memory_order_acquire); }
  std::size_t channels() const { return channels_; }
  double at(std::size_t i, std::size_t c) const { return q_[i * channels_ + c]; }

 private:
  std::size_t channels_;
  std::vector<double> q_;
  std::atomic<std::size_t> length_{0};
};

/// Builds an exercise from its name and JSON parameters (API thread). Unknown names, unknown parameters and
/// out-of-range values are refused with a message naming them; nothing is built then.
std::unique_ptr<Exercise> makeExercise(const std::string& name, const nlohmann::json& params,
                                       const TherapyDevice& device, const Profile& profile,
                                       const std::shared_ptr<Pattern>& pattern, std::string& error);

/// The imposed-stretch schedule of the tardieu exercise (exposed for its analysis and tests): for each
/// velocity, approach `from` at kApproach_rad_s, hold, stretch to `to` at the velocity, hold.
struct TardieuPlan {
  static constexpr std::size_t kMaxStretches = 4;
  static constexpr double kApproach_rad_s = 0.5;  ///< ≈ 29°/s: slow, below any stretch-reflex threshold
  std::size_t channel = 0;
  std::size_t count = 0;                           ///< stretches used
  std::array<double, kMaxStretches> velocity_rad_s{};
  double from_rad = 0.0, to_rad = 0.0, hold_s = 1.0;
  /// Target coordinate and rate at time t after the exercise started from q0. No allocation.
  void targetAt(double t_s, double q0_rad, double& q_rad, double& q_dot_rad_s) const;
  double durationS(double q0_rad) const;
};

/// The assist-as-needed law of one channel (001 §9 / Cai et al. 2006), exposed for tests.
struct AssistLaw {
  double stiffness = 0.0;       ///< K: effort per rad of error outside the tunnel
  double deadband_rad = 0.0;    ///< w: tunnel half-width, no assistance inside
  double forgetting_s = 10.0;   ///< τ: the gain decays as ġ = −g/τ when the patient tracks well
  double learning_per_rad_s = 0.5;  ///< β: ġ += β·(|e| − w)⁺
  double gain_min = 0.0;
  double gain = 1.0;            ///< g ∈ [gain_min, 1]
  /// One step: e = target − q (rad, + = needs more flexion). Returns the effort (+ resists flexion).
  double step(double target_rad, double q_rad, double dt_s);
};

}  // namespace phalanx::host::therapy
