#include "phalanx/host/therapy/therapy_controller.h"

#include <cmath>

namespace phalanx::host::therapy {
namespace {
/// Low-pass on the channel-coordinate differences that give q̇: 10 Hz passes voluntary finger motion (≤ 2 Hz
/// close/open in 001 §7.2) and removes most of the Hall-sensor noise differentiated at 1 kHz.
constexpr double kRateCutoffHz = 10.0;
/// Range of motion is the min/max of the joint angle low-passed at 5 Hz: the min/max of the raw 1 kHz signal picks
/// the tails of the sensor noise (measured in the sim: the extended PIP read 4.5° beyond the truth; ≤ 1.6° filtered).
constexpr double kRomCutoffHz = 5.0;
/// Status publication period: 50 Hz is smooth for a dashboard and costs nothing in the loop.
constexpr double kStatusPeriodS = 0.02;
}  // namespace

TherapyController::TherapyController(std::unique_ptr<TherapyDevice> device, const PatientLimits& limits,
                                     std::unique_ptr<Exercise> initial, record::RecordWriter* writer)
    : device_(std::move(device)), limits_(limits), active_(std::move(initial)), writer_(writer) {
  out_.clear();
  status_.channels = device_->channelCount();
  status_.joints = device_->jointCount();
}

TherapyController::~TherapyController() {
  delete pending_.exchange(nullptr);
  delete retired_.exchange(nullptr);
}

void TherapyController::offerExercise(std::unique_ptr<Exercise> exercise) {
  collectRetired();
  delete pending_.exchange(exercise.release());
}

void TherapyController::collectRetired() { delete retired_.exchange(nullptr); }

void TherapyController::offerLimits(const PatientLimits& limits) {
  std::lock_guard<std::mutex> lock(limits_mutex_);
  pending_limits_ = limits;
  limits_pending_.store(true, std::memory_order_release);
}

PatientLimits TherapyController::limits() const {
  std::lock_guard<std::mutex> lock(limits_mutex_);
  return limits_pending_.load() ? pending_limits_ : limits_;
}

StatusSnapshot TherapyController::status() const {
  std::lock_guard<std::mutex> lock(status_mutex_);
  return status_;
}

std::vector<std::string> TherapyController::auxNames() const {
  std::vector<std::string> v;
  const std::size_t n = device_->channelCount();
  for (std::size_t c = 0; c < n; ++c) v.push_back("q_" + device_->channelName(c) + "_rad");
  for (std::size_t c = 0; c < n; ++c) v.push_back("target_" + device_->channelName(c) + "_rad");
  for (std::size_t c = 0; c < n; ++c) v.push_back("assist_gain_" + device_->channelName(c));
  for (std::size_t c = 0; c < n; ++c) v.push_back("effort_cmd_" + device_->channelName(c));
  v.push_back("exercise_id");
  v.push_back("limited_bits");
  return v;
}

void TherapyController::fillAux(std::array<float, record::kMaxAux>& aux) const {
  const std::size_t n = device_->channelCount();
  for (std::size_t c = 0; c < n; ++c) {
    aux[c] = static_cast<float>(obs_.q_rad[c]);
    aux[n + c] = static_cast<float>(out_.target_q_rad[c]);
    aux[2 * n + c] = static_cast<float>(out_.assist_gain[c]);
    aux[3 * n + c] = static_cast<float>(out_.effort[c]);
  }
  aux[4 * n] = static_cast<float>(active_ ? static_cast<int>(active_->id()) : 0);
  aux[4 * n + 1] = static_cast<float>(limited_bits_);
}

bool TherapyController::offerExerciseFromLoop(Exercise* exercise) {
  Exercise* expected = nullptr;
  return pending_.compare_exchange_strong(expected, exercise, std::memory_order_acq_rel);
}

void TherapyController::update(const TelemetryFrame& tel, double t_s, double dt_s, protocol::Command& cmd) {
  ++cycles_;
  device_->observe(tel, obs_);
  estimateRates(dt_s);
  held_paused_ = paused_.load(std::memory_order_relaxed);
  if (held_paused_) paused_s_ += dt_s;
  const double t_ex = t_s - paused_s_;  // the exercise's clock stops while paused
  takeMailboxes(t_ex);
  out_.clear();
  if (held_paused_) {
    out_.mode = protocol::Mode::kTransparent;  // zero effort: the device follows the finger, holds nothing
  } else if (active_) {
    active_->update(tel, obs_, t_ex, dt_s, out_);
  }
  const uint32_t limited = limits_.apply(obs_, out_.effort);
  if (limited != 0) ++limited_cycles_;
  writeLimitAndFaultEvents(tel, t_s, limited);
  commandFromOutput(cmd);
  trackRom(dt_s);
  publishStatus(tel, t_s);
}

void TherapyController::estimateRates(double dt_s) {
  const double a = dt_s / (dt_s + 1.0 / (2.0 * M_PI * kRateCutoffHz));
  for (std::size_t c = 0; c < device_->channelCount(); ++c) {
    if (primed_ && dt_s > 0.0) {
      obs_.q_dot_rad_per_s[c] += a * ((obs_.q_rad[c] - last_q_[c]) / dt_s - obs_.q_dot_rad_per_s[c]);
    }
    last_q_[c] = obs_.q_rad[c];
  }
  primed_ = true;
}

void TherapyController::takeMailboxes(double t_ex) {
  if (limits_pending_.load(std::memory_order_acquire) && limits_mutex_.try_lock()) {
    limits_ = pending_limits_;
    limits_pending_.store(false, std::memory_order_release);
    limits_mutex_.unlock();
  }
  if (pending_.load(std::memory_order_acquire) == nullptr || retired_.load(std::memory_order_acquire) != nullptr) return;
  Exercise* next = pending_.exchange(nullptr);
  if (next == nullptr) return;
  retired_.store(active_.release(), std::memory_order_release);
  active_.reset(next);
  active_->start(obs_, t_ex);
  if (writer_ != nullptr) {
    record::LoopEvent e;
    e.t_s = t_ex + paused_s_;
    e.kind = record::LoopEvent::Kind::kExerciseStarted;
    e.code = static_cast<uint16_t>(active_->id());
    writer_->pushLoopEvent(e);
  }
}

void TherapyController::writeLimitAndFaultEvents(const TelemetryFrame& tel, double t_s, uint32_t limited) {
  if (writer_ != nullptr && (limited & ~limited_bits_) != 0) {
    record::LoopEvent e;
    e.t_s = t_s;
    e.kind = record::LoopEvent::Kind::kLimitActive;
    e.code = static_cast<uint16_t>(limited);
    writer_->pushLoopEvent(e);
  }
  limited_bits_ = limited;
  if (writer_ != nullptr && tel.fault_bits != last_faults_) {
    record::LoopEvent e;
    e.t_s = t_s;
    e.kind = record::LoopEvent::Kind::kFaultBits;
    e.code = tel.fault_bits;
    writer_->pushLoopEvent(e);
  }
  last_faults_ = tel.fault_bits;
}

void TherapyController::commandFromOutput(protocol::Command& cmd) {
  const std::size_t n = device_->channelCount();
  cmd.mode = out_.mode;
  std::array<float, kMaxChannels> setpoint{};
  if (out_.mode == protocol::Mode::kSetpoint) device_->commandFromEffort(out_.effort, setpoint);
  for (std::size_t c = 0; c < kMaxChannels; ++c) {
    const bool drive = c < n && out_.mode == protocol::Mode::kSetpoint;
    cmd.setpoint[c] = drive ? setpoint[c] : 0.0f;
    cmd.gain_scale_permille[c] = c < n ? out_.gain_permille[c] : 1000;
    if (!drive) out_.effort[c] = 0.0;
    max_abs_command_ = std::fmax(max_abs_command_, std::fabs(out_.effort[c]));
  }
}

void TherapyController::trackRom(double dt_s) {
  const double a_rom = dt_s / (dt_s + 1.0 / (2.0 * M_PI * kRomCutoffHz));
  const bool assessing = active_ && active_->id() == ExerciseId::kAssessment && !held_paused_;
  for (std::size_t j = 0; j < device_->jointCount(); ++j) {
    if (!obs_.joint_valid[j]) continue;
    flex_lp_[j] = flex_lp_valid_[j] ? flex_lp_[j] + a_rom * (obs_.flexion_rad[j] - flex_lp_[j]) : obs_.flexion_rad[j];
    flex_lp_valid_[j] = true;
    if (!assessing) continue;
    if (!rom_seen_[j]) {
      rom_min_[j] = rom_max_[j] = flex_lp_[j];
      rom_seen_[j] = true;
    } else {
      rom_min_[j] = std::fmin(rom_min_[j], flex_lp_[j]);
      rom_max_[j] = std::fmax(rom_max_[j], flex_lp_[j]);
    }
  }
}

void TherapyController::publishStatus(const TelemetryFrame& tel, double t_s) {
  if (t_s < next_status_s_ || !status_mutex_.try_lock()) return;
  next_status_s_ = t_s + kStatusPeriodS;
  status_.valid = true;
  status_.t_s = t_s;
  status_.cycles = cycles_;
  status_.device_mode = static_cast<uint8_t>(tel.mode);
  status_.fault_bits = tel.fault_bits;
  status_.state_flags = tel.state_flags;
  status_.exercise = active_ ? active_->id() : ExerciseId::kIdle;
  status_.paused = held_paused_;
  status_.q_rad = obs_.q_rad;
  status_.target_q_rad = out_.target_q_rad;
  status_.effort_measured = obs_.effort;
  status_.effort_command = out_.effort;
  status_.assist_gain = out_.assist_gain;
  status_.effort_max = limits_.effort_max;
  status_.flexion_rad = obs_.flexion_rad;
  status_.rom_min_rad = rom_min_;
  status_.rom_max_rad = rom_max_;
  status_.limited_cycles = limited_cycles_;
  status_mutex_.unlock();
}

void TherapyController::summarize(nlohmann::json& out) const {
  out["therapy"] = {{"cycles", cycles_},
                    {"limited_cycles", limited_cycles_},
                    {"max_abs_effort_command", max_abs_command_},
                    {"effort_unit", device_->effortUnit()}};
}

}  // namespace phalanx::host::therapy
