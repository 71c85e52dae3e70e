#pragma once
/// The therapy controller run by the session loop: telemetry → observation (device adapter) → active exercise
/// → patient limits → command. Exercise and limit changes arrive from the API thread through lock-free
/// mailboxes; the loop never blocks on them and never frees memory (retired exercises are freed by the API
/// thread in collectRetired()).
#include <array>
#include <atomic>
#include <memory>
#include <mutex>

#include "phalanx/host/controller.h"
#include "phalanx/host/record/record_writer.h"
#include "phalanx/host/therapy/device.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/profile.h"

namespace phalanx::host::therapy {

/// What the API's status request and the dashboard see; published by the loop at ~50 Hz.
struct StatusSnapshot {
  bool valid = false;
  double t_s = 0.0;
  uint64_t cycles = 0;
  uint8_t device_mode = 0;
  uint16_t fault_bits = 0;
  uint8_t state_flags = 0;
  ExerciseId exercise = ExerciseId::kIdle;
  bool paused = false;  ///< the device was held paused (zero effort)
  std::size_t channels = 0;
  std::size_t joints = 0;
  std::array<double, kMaxChannels> q_rad{};
  std::array<double, kMaxChannels> target_q_rad{};
  std::array<double, kMaxChannels> effort_measured{};
  std::array<double, kMaxChannels> effort_command{};
  std::array<double, kMaxChannels> assist_gain{};
  std::array<double, kMaxChannels> effort_max{};
  std::array<double, kMaxJoints> flexion_rad{};
  std::array<double, kMaxJoints> rom_min_rad{};  ///< active ROM seen during assessment so far
  std::array<double, kMaxJoints> rom_max_rad{};
  uint64_t limited_cycles = 0;
};

class TherapyController : public Controller {
 public:
  /// Aux values recorded per cycle: per channel q, target, assist gain, commanded effort; then the exercise id
  /// and the limited-channel bits. Names from auxNames().
  TherapyController(std::unique_ptr<TherapyDevice> device, const PatientLimits& limits,
                    std::unique_ptr<Exercise> initial, record::RecordWriter* writer);
  ~TherapyController() override;

  const char* name() const override { return "therapy"; }
  void update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) override;
  std::vector<std::pair<uint16_t, float>> startupParams() const override { return device_->startupParams(); }
  double startupSettleS() const override { return device_->startupSettleS(); }
  std::vector<uint16_t> startupReadback() const override { return device_->startupReadback(); }
  std::string startupWarning(uint16_t id, float value) const override { return device_->startupWarning(id, value); }
  void summarize(nlohmann::json& out) const override;

  // --- API thread ---
  /// Queue an exercise to start at the next cycle (replaces one still queued).
  void offerExercise(std::unique_ptr<Exercise> exercise);
  /// Free exercises the loop retired. Call periodically from a non-real-time thread.
  void collectRetired();
  /// Queue new limits (already validated against the profile by the caller).
  void offerLimits(const PatientLimits& limits);
  PatientLimits limits() const;
  StatusSnapshot status() const;
  /// Pause: from the next cycle the device is held transparent with zero effort (through the limits stage like
  /// any command) and the exercise's clock stops; resume continues it where it was.
  void setPaused(bool paused) { paused_.store(paused, std::memory_order_relaxed); }
  bool paused() const { return paused_.load(std::memory_order_relaxed); }
  const TherapyDevice& device() const { return *device_; }

  // --- loop thread ---
  std::vector<std::string> auxNames() const;
  std::size_t auxCount() const { return 4 * device_->channelCount() + 2; }
  /// Aux values of the last update(), in auxNames() order.
  void fillAux(std::array<float, record::kMaxAux>& aux) const;
  /// The last update()'s observation (channel coordinates for the session plan's repetition count).
  const Observation& observation() const { return obs_; }
  /// Whether the last update() held the device paused.
  bool heldPaused() const { return held_paused_; }
  /// The session plan's next exercise (ownership passes; no allocation): queued like offerExercise's, started at
  /// the next cycle. False (nothing taken) while another exercise is still queued.
  bool offerExerciseFromLoop(Exercise* exercise);

 private:
  // loop stages of update()
  void estimateRates(double dt_s);
  void takeMailboxes(double t_ex);
  void writeLimitAndFaultEvents(const TelemetryFrame& tel, double t_s, uint32_t limited);
  void commandFromOutput(protocol::Command& cmd);
  void trackRom(double dt_s);
  void publishStatus(const TelemetryFrame& tel, double t_s);

  std::unique_ptr<TherapyDevice> device_;
  PatientLimits limits_;
  std::unique_ptr<Exercise> active_;
  record::RecordWriter* writer_;
  std::atomic<Exercise*> pending_{nullptr};
  std::atomic<Exercise*> retired_{nullptr};
  mutable std::mutex limits_mutex_;
  PatientLimits pending_limits_;
  std::atomic<bool> limits_pending_{false};
  mutable std::mutex status_mutex_;
  StatusSnapshot status_;
  // loop state
  Observation obs_{};
  std::array<double, kMaxChannels> last_q_{};
  bool primed_ = false;
  ExerciseOutput out_{};
  uint32_t limited_bits_ = 0;
  uint16_t last_faults_ = 0;
  uint64_t cycles_ = 0;
  uint64_t limited_cycles_ = 0;
  std::array<double, kMaxJoints> rom_min_{};
  std::array<double, kMaxJoints> rom_max_{};
  std::array<bool, kMaxJoints> rom_seen_{};
  std::array<double, kMaxJoints> flex_lp_{};
  std::array<bool, kMaxJoints> flex_lp_valid_{};
  std::atomic<bool> paused_{false};
  bool held_paused_ = false;
  double paused_s_ = 0.0;  // session time spent paused: the exercise's clock is t_s − paused_s_
  double next_status_s_ = 0.0;
  double max_abs_command_ = 0.0;
};

}  // namespace phalanx::host::therapy
