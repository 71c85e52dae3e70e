#include "phalanx/host/therapy/exercise.h"

#include "phalanx/host/therapy/session_plan.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

namespace phalanx::host::therapy {

const char* exerciseName(ExerciseId id) {
  switch (id) {
    case ExerciseId::kIdle: return "idle";
    case ExerciseId::kAssessment: return "assessment";
    case ExerciseId::kResistance: return "resistance";
    case ExerciseId::kAssistance: return "assistance";
    case ExerciseId::kRecordPattern: return "record-pattern";
    case ExerciseId::kPlayback: return "playback";
    case ExerciseId::kGrasp: return "grasp";
    case ExerciseId::kTardieu: return "tardieu";
    case ExerciseId::kPassiveRom: return "passive-rom";
    case ExerciseId::kMaxForce: return "max-force";
  }
  return "unknown";
}

bool isExerciseName(const std::string& name) {
  for (int id = 0; id <= static_cast<int>(ExerciseId::kMaxForce); ++id) {
    if (name == exerciseName(static_cast<ExerciseId>(id))) return true;
  }
  return false;
}

bool Pattern::append(const std::array<double, kMaxChannels>& q) {
  const std::size_t n = length_.load(std::memory_order_relaxed);
  if (n >= kMaxSamples) return false;
  for (std::size_t c = 0; c < channels_; ++c) q_[n * channels_ + c] = q[c];
  length_.store(n + 1, std::memory_order_release);
  return true;
}

double AssistLaw::step(double target_rad, double q_rad, double dt_s) {
  const double e = target_rad - q_rad;
  const double outside = std::max(std::fabs(e) - deadband_rad, 0.0);
  // ġ = −g/τ + β·(|e| − w)⁺ (error-driven increase, forgetting decay), g ∈ [gain_min, 1].
  gain += dt_s * (-gain / forgetting_s + learning_per_rad_s * outside);
  gain = std::clamp(gain, gain_min, 1.0);
  // Needs more flexion (e > 0) → negative effort (assists flexion).
  return -gain * stiffness * std::copysign(outside, e);
}

namespace {

// One ramp from a to b at |rate|, then a hold: writes the target if t falls in it; returns its length.
double segment(double t, double a, double b, double rate, double hold, double& q, double& q_dot, bool& done) {
  const double ramp = std::fabs(b - a) / rate;
  if (!done && t < ramp) {
    q = a + std::copysign(rate * t, b - a);
    q_dot = std::copysign(rate, b - a);
    done = true;
  } else if (!done && t < ramp + hold) {
    q = b;
    q_dot = 0.0;
    done = true;
  }
  return ramp + hold;
}

}  // namespace

void TardieuPlan::targetAt(double t_s, double q0_rad, double& q_rad, double& q_dot_rad_s) const {
  bool done = false;
  double start = q0_rad;
  q_rad = to_rad;
  q_dot_rad_s = 0.0;
  for (std::size_t i = 0; i < count && !done; ++i) {
    t_s -= segment(t_s, start, from_rad, kApproach_rad_s, hold_s, q_rad, q_dot_rad_s, done);
    if (done) break;
    t_s -= segment(t_s, from_rad, to_rad, velocity_rad_s[i], 0.5 * hold_s, q_rad, q_dot_rad_s, done);
    start = to_rad;
  }
}

double TardieuPlan::durationS(double q0_rad) const {
  double t = 0.0, start = q0_rad;
  for (std::size_t i = 0; i < count; ++i) {
    t += std::fabs(from_rad - start) / kApproach_rad_s + hold_s;
    t += std::fabs(to_rad - from_rad) / velocity_rad_s[i] + 0.5 * hold_s;
    start = to_rad;
  }
  return t;
}

namespace {

constexpr double kDeg = M_PI / 180.0;

struct ParamSpec {
  double default_value;
  double lo;
  double hi;
  const char* unit;
};

/// Reads numeric parameters: unknown keys, non-numbers and out-of-range values are errors naming the key.
bool readParams(const nlohmann::json& in, const std::map<std::string, ParamSpec>& spec,
                std::map<std::string, double>& out, std::string& error) {
  if (!in.is_null() && !in.is_object()) {
    error = "params: expected an object";
    return false;
  }
  for (const auto& [k, s] : spec) out[k] = s.default_value;
  if (in.is_null()) return true;
  for (const auto& [k, v] : in.items()) {
    const auto it = spec.find(k);
    if (it == spec.end()) {
      std::string list;
      for (const auto& [name, s] : spec) list += (list.empty() ? "" : ", ") + name;
      error = "params." + k + ": unknown parameter (allowed: " + (list.empty() ? "none" : list) + ")";
      return false;
    }
    if (!v.is_number()) {
      error = "params." + k + ": expected a number";
      return false;
    }
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < it->second.lo || x > it->second.hi) {
      std::ostringstream os;
      os << "params." << k << ": " << x << " is outside [" << it->second.lo << ", " << it->second.hi << "] "
         << it->second.unit;
      error = os.str();
      return false;
    }
    out[k] = x;
  }
  return true;
}

/// The channel's close/open extremes: Σ over its joints of the measured ROM (profile) within the limits.
class Idle : public Exercise {
 public:
  ExerciseId id() const override { return ExerciseId::kIdle; }
  void update(const TelemetryFrame&, const Observation&, double, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSafe;
  }
  nlohmann::json params() const override { return nlohmann::json::object(); }
};

class Assessment : public Exercise {
 public:
  ExerciseId id() const override { return ExerciseId::kAssessment; }
  void update(const TelemetryFrame&, const Observation&, double, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kTransparent;
  }
  nlohmann::json params() const override { return nlohmann::json::object(); }
};

class Resistance : public Exercise {
 public:
  Resistance(std::size_t channels, double k, double b, double rest_rad)
      : channels_(channels), k_(k), b_(b), rest_rad_(rest_rad) {}
  ExerciseId id() const override { return ExerciseId::kResistance; }
  void update(const TelemetryFrame&, const Observation& obs, double, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSetpoint;
    for (std::size_t c = 0; c < channels_; ++c) {
      if (!obs.channel_valid[c]) continue;  // effort 0
      // 000 eq 1 on the channel coordinate: spring beyond the rest flexion, damper on any motion.
      out.effort[c] = k_ * std::max(obs.q_rad[c] - rest_rad_, 0.0) + b_ * obs.q_dot_rad_per_s[c];
      out.target_q_rad[c] = rest_rad_;
    }
  }
  nlohmann::json params() const override {
    return {{"stiffness_per_rad", k_}, {"damping_s_per_rad", b_}, {"rest_deg", rest_rad_ / kDeg}};
  }

 private:
  std::size_t channels_;
  double k_, b_, rest_rad_;
};

/// Tracks a target trajectory with assist-as-needed; the target comes from a cosine close/open cycle
/// (assistance) or the recorded pattern (playback).
class Assist : public Exercise {
 public:
  Assist(ExerciseId id, std::size_t channels, const AssistLaw& law, nlohmann::json params)
      : id_(id), channels_(channels), params_(std::move(params)) {
    law_.fill(law);
  }
  ExerciseId id() const override { return id_; }
  void start(const Observation&, double t_s) override { t0_s_ = t_s; }
  void update(const TelemetryFrame&, const Observation& obs, double t_s, double dt_s, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSetpoint;
    for (std::size_t c = 0; c < channels_; ++c) {
      const double target = targetAt(c, t_s - t0_s_);
      out.target_q_rad[c] = target;
      out.assist_gain[c] = law_[c].gain;
      if (!obs.channel_valid[c]) continue;
      out.effort[c] = law_[c].step(target, obs.q_rad[c], dt_s);
      out.assist_gain[c] = law_[c].gain;
    }
  }
  nlohmann::json params() const override { return params_; }

 protected:
  virtual double targetAt(std::size_t c, double t_s) const = 0;

 private:
  ExerciseId id_;
  std::size_t channels_;
  std::array<AssistLaw, kMaxChannels> law_{};
  nlohmann::json params_;
  double t0_s_ = 0.0;
};

class CosineAssist : public Assist {
 public:
  CosineAssist(std::size_t channels, const AssistLaw& law, nlohmann::json params, double period_s,
               const std::array<double, kMaxChannels>& open, const std::array<double, kMaxChannels>& close)
      : Assist(ExerciseId::kAssistance, channels, law, std::move(params)), period_s_(period_s), open_(open),
        close_(close) {}

 protected:
  double targetAt(std::size_t c, double t_s) const override {
    // Raised cosine: open at t = 0, closed at T/2 (the 000 §4.3 close/open maneuver shape).
    const double s = 0.5 * (1.0 - std::cos(2.0 * M_PI * t_s / period_s_));
    return open_[c] + (close_[c] - open_[c]) * s;
  }

 private:
  double period_s_;
  std::array<double, kMaxChannels> open_, close_;
};

class PlaybackAssist : public Assist {
 public:
  PlaybackAssist(std::size_t channels, const AssistLaw& law, nlohmann::json params, const Pattern& pattern,
                 double speed)
      : Assist(ExerciseId::kPlayback, channels, law, std::move(params)), channels_(channels),
        length_(pattern.length()), speed_(speed), q_(length_ * channels) {
    for (std::size_t i = 0; i < length_; ++i) {
      for (std::size_t c = 0; c < channels; ++c) q_[i * channels + c] = pattern.at(i, c);
    }
  }

 protected:
  double targetAt(std::size_t c, double t_s) const override {
    // The pattern loops; linear interpolation between its 100 Hz samples.
    const double x = std::fmod(t_s * speed_ * Pattern::kRateHz, static_cast<double>(length_));
    const auto i = static_cast<std::size_t>(x);
    const std::size_t k = (i + 1) % length_;
    const double f = x - static_cast<double>(i);
    return q_[i * channels_ + c] * (1.0 - f) + q_[k * channels_ + c] * f;
  }

 private:
  std::size_t channels_;
  std::size_t length_;
  double speed_;
  std::vector<double> q_;
};

class RecordPattern : public Exercise {
 public:
  explicit RecordPattern(std::shared_ptr<Pattern> pattern) : pattern_(std::move(pattern)) {}
  ExerciseId id() const override { return ExerciseId::kRecordPattern; }
  void start(const Observation&, double t_s) override {
    pattern_->reset();
    next_s_ = t_s;
  }
  void update(const TelemetryFrame&, const Observation& obs, double t_s, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kTransparent;  // the patient (or the therapist moving the hand) leads
    if (t_s >= next_s_) {
      pattern_->append(obs.q_rad);
      next_s_ += 1.0 / Pattern::kRateHz;
    }
  }
  nlohmann::json params() const override { return {{"rate_hz", Pattern::kRateHz}, {"max_s", 60}}; }

 private:
  std::shared_ptr<Pattern> pattern_;
  double next_s_ = 0.0;
};

class Grasp : public Exercise {
 public:
  Grasp(std::unique_ptr<Controller> inner, const TherapyDevice& device, std::string scene)
      : inner_(std::move(inner)), device_(device), scene_(std::move(scene)) {}
  ExerciseId id() const override { return ExerciseId::kGrasp; }
  void update(const TelemetryFrame& tel, const Observation&, double t_s, double dt_s, ExerciseOutput& out) override {
    inner_->update(tel, t_s, dt_s, cmd_);
    out.mode = cmd_.mode;
    for (std::size_t c = 0; c < device_.channelCount(); ++c) {
      out.effort[c] = device_.effortFromSetpoint(c, cmd_.setpoint[c]);
      out.gain_permille[c] = cmd_.gain_scale_permille[c];
    }
  }
  nlohmann::json params() const override { return {{"scene", scene_}}; }

 private:
  std::unique_ptr<Controller> inner_;
  const TherapyDevice& device_;
  std::string scene_;
  protocol::Command cmd_{};
};

nlohmann::json toJson(const std::map<std::string, double>& p);

/// Position control of one channel coordinate: effort = k·(q − q*) + b·(q̇ − q̇*) (+ resists flexion, so a
/// finger more flexed than its target is pushed towards extension).
double trackEffort(const Observation& obs, std::size_t c, double target, double target_dot, double k, double b) {
  return k * (obs.q_rad[c] - target) + b * (obs.q_dot_rad_per_s[c] - target_dot);
}

class Tardieu : public Exercise {
 public:
  Tardieu(const TardieuPlan& plan, double k, double b, nlohmann::json params)
      : plan_(plan), k_(k), b_(b), params_(std::move(params)) {}
  ExerciseId id() const override { return ExerciseId::kTardieu; }
  void start(const Observation& obs, double t_s) override {
    t0_s_ = t_s;
    q0_rad_ = obs.channel_valid[plan_.channel] ? obs.q_rad[plan_.channel] : plan_.from_rad;
  }
  void update(const TelemetryFrame&, const Observation& obs, double t_s, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSetpoint;  // the other channels: zero effort
    double q = 0.0, q_dot = 0.0;
    plan_.targetAt(t_s - t0_s_, q0_rad_, q, q_dot);
    out.target_q_rad[plan_.channel] = q;
    if (obs.channel_valid[plan_.channel]) out.effort[plan_.channel] = trackEffort(obs, plan_.channel, q, q_dot, k_, b_);
  }
  nlohmann::json params() const override { return params_; }

 private:
  TardieuPlan plan_;
  double k_, b_;
  nlohmann::json params_;
  double t0_s_ = 0.0, q0_rad_ = 0.0;
};

/// Extends every channel with +effort for hold_s, then flexes it with −effort for hold_s, then effort 0: the
/// relaxed finger settles where its passive torque balances the test effort (a torque-defined passive ROM).
class PassiveRom : public Exercise {
 public:
  PassiveRom(std::size_t channels, int only, double effort, double hold_s)
      : channels_(channels), only_(only), effort_(effort), hold_s_(hold_s) {}
  ExerciseId id() const override { return ExerciseId::kPassiveRom; }
  void start(const Observation&, double t_s) override { t0_s_ = t_s; }
  void update(const TelemetryFrame&, const Observation&, double t_s, double, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSetpoint;
    const double t = t_s - t0_s_;
    const double e = t < hold_s_ ? effort_ : (t < 2.0 * hold_s_ ? -effort_ : 0.0);
    for (std::size_t c = 0; c < channels_; ++c) out.effort[c] = only_ < 0 || c == static_cast<std::size_t>(only_) ? e : 0.0;
  }
  nlohmann::json params() const override { return {{"effort", effort_}, {"hold_s", hold_s_}, {"channel", only_}}; }

 private:
  std::size_t channels_;
  int only_;  // −1: every channel
  double effort_, hold_s_;
  double t0_s_ = 0.0;
};

/// Holds every channel at the pose it started in (PI on q, the integral bounded by the effort limit), so the
/// effort it takes is the patient's isometric effort; the report takes its peak as the maximal voluntary force.
class MaxForce : public Exercise {
 public:
  MaxForce(std::size_t channels, double k, double ki, double i_max) : channels_(channels), k_(k), ki_(ki), i_max_(i_max) {}
  ExerciseId id() const override { return ExerciseId::kMaxForce; }
  void start(const Observation& obs, double) override {
    q0_ = obs.q_rad;
    integral_.fill(0.0);
  }
  void update(const TelemetryFrame&, const Observation& obs, double, double dt_s, ExerciseOutput& out) override {
    out.mode = protocol::Mode::kSetpoint;
    for (std::size_t c = 0; c < channels_; ++c) {
      out.target_q_rad[c] = q0_[c];
      if (!obs.channel_valid[c]) continue;
      const double e = obs.q_rad[c] - q0_[c];
      integral_[c] = std::clamp(integral_[c] + ki_ * e * dt_s, -i_max_, i_max_);
      out.effort[c] = k_ * e + integral_[c];
    }
  }
  nlohmann::json params() const override { return {{"stiffness_per_rad", k_}, {"integral_per_rad_s", ki_}}; }

 private:
  std::size_t channels_;
  double k_, ki_, i_max_;
  std::array<double, kMaxChannels> q0_{}, integral_{};
};

std::unique_ptr<Exercise> makeTardieu(const std::map<std::string, double>& p, const TherapyDevice& device,
                                      std::string& error) {
  TardieuPlan plan;
  plan.channel = static_cast<std::size_t>(p.at("channel"));
  if (plan.channel >= device.channelCount()) {
    error = "params.channel: " + std::to_string(plan.channel) + " is not a channel of " + device.name();
    return nullptr;
  }
  for (const char* k : {"v1_deg_s", "v2_deg_s", "v3_deg_s", "v4_deg_s"}) {
    if (p.at(k) > 0.0) plan.velocity_rad_s[plan.count++] = p.at(k) * kDeg;
  }
  plan.from_rad = p.at("from_deg") * kDeg;
  plan.to_rad = p.at("to_deg") * kDeg;
  plan.hold_s = p.at("hold_s");
  if (plan.count < 2 || plan.from_rad - plan.to_rad < 10.0 * kDeg) {
    error = "params: the tardieu test needs at least 2 velocities and from_deg at least 10° above to_deg";
    return nullptr;
  }
  return std::make_unique<Tardieu>(plan, p.at("stiffness_per_rad"), p.at("damping_s_per_rad"), toJson(p));
}

std::unique_ptr<Exercise> makeInstrumented(const std::string& name, const nlohmann::json& params,
                                           const TherapyDevice& device, std::string& error) {
  std::map<std::string, double> p;
  const double emax = device.effortLimit(0);
  const std::size_t n = device.channelCount();
  if (name == "passive-rom") {
    if (!readParams(params, {{"effort", {0.3 * emax, 0.05 * emax, emax, "effort"}}, {"hold_s", {2.0, 0.5, 10.0, "s"}},
                             {"channel", {-1.0, -1.0, static_cast<double>(n) - 1.0, "index (-1: all)"}}},
                    p, error)) {
      return nullptr;
    }
    return std::make_unique<PassiveRom>(n, static_cast<int>(p["channel"]), p["effort"], p["hold_s"]);
  }
  if (name == "max-force") {
    // 1·E/rad and 3·E/(rad·s): on the SEA finger 3·E/rad with 20·E/(rad·s) on both channels is a limit cycle
    // (measured in therapy_assessment_test); these hold the pose to the MVF within 1 % there.
    if (!readParams(params, {{"stiffness_per_rad", {1.0 * emax, 0.0, 50.0 * emax, "effort/rad"}},
                             {"integral_per_rad_s", {3.0 * emax, 0.0, 1000.0 * emax, "effort/(rad·s)"}}},
                    p, error)) {
      return nullptr;
    }
    return std::make_unique<MaxForce>(n, p["stiffness_per_rad"], p["integral_per_rad_s"], emax);
  }
  if (!readParams(params,
                  {{"channel", {0.0, 0.0, static_cast<double>(kMaxChannels - 1), "index"}},
                   {"v1_deg_s", {15.0, 5.0, 400.0, "deg/s"}},
                   {"v2_deg_s", {90.0, 5.0, 400.0, "deg/s"}},
                   {"v3_deg_s", {150.0, 0.0, 400.0, "deg/s (0: unused)"}},
                   {"v4_deg_s", {210.0, 0.0, 400.0, "deg/s (0: unused)"}},
                   {"from_deg", {50.0, -30.0, 120.0, "deg"}},
                   {"to_deg", {5.0, -30.0, 120.0, "deg"}},
                   {"hold_s", {1.0, 0.2, 10.0, "s"}},
                   {"stiffness_per_rad", {3.0 * emax, 0.0, 50.0 * emax, "effort/rad"}},
                   {"damping_s_per_rad", {0.05 * emax, 0.0, 2.0 * emax, "effort·s/rad"}}},
                  p, error)) {
    return nullptr;
  }
  return makeTardieu(p, device, error);
}

AssistLaw assistLawFrom(const std::map<std::string, double>& p) {
  AssistLaw law;
  law.stiffness = p.at("stiffness_per_rad");
  law.deadband_rad = p.at("deadband_deg") * kDeg;
  law.forgetting_s = p.at("forgetting_s");
  law.learning_per_rad_s = p.at("learning_per_rad_s");
  law.gain_min = p.at("gain_min");
  law.gain = std::max(p.at("gain_initial"), law.gain_min);
  return law;
}

// Defaults and ranges: docs/therapy.md "Constants" gives the reasoning behind each.
std::map<std::string, ParamSpec> assistSpec(const TherapyDevice& device) {
  const double emax = device.effortLimit(0);
  return {{"stiffness_per_rad", {0.2 * emax, 0.0, 2.0 * emax, "effort/rad"}},
          {"deadband_deg", {5.0, 0.0, 45.0, "deg"}},
          {"forgetting_s", {10.0, 0.5, 600.0, "s"}},
          {"learning_per_rad_s", {0.5, 0.0, 50.0, "1/(rad·s)"}},
          {"gain_min", {0.0, 0.0, 1.0, ""}},
          {"gain_initial", {1.0, 0.0, 1.0, ""}}};
}

nlohmann::json toJson(const std::map<std::string, double>& p) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [k, v] : p) j[k] = v;
  return j;
}

}  // namespace

void patientChannelRange(const TherapyDevice& device, const Profile& profile, std::array<double, kMaxChannels>& open,
                         std::array<double, kMaxChannels>& close) {
  open.fill(0.0);
  close.fill(0.0);
  for (std::size_t j = 0; j < device.jointCount(); ++j) {
    double lo = std::max(profile.limits.flexion_min_rad[j], 0.0);
    double hi = profile.limits.flexion_max_rad[j];
    for (const auto& [name, r] : profile.rom_rad) {
      if (name == device.jointName(j)) {
        lo = std::max(lo, r.first);
        hi = std::min(hi, r.second);
      }
    }
    if (hi < lo) hi = lo;
    open[device.jointChannel(j)] += lo;
    close[device.jointChannel(j)] += hi;
  }
}

std::unique_ptr<Exercise> makeExercise(const std::string& name, const nlohmann::json& params,
                                       const TherapyDevice& device, const Profile& profile,
                                       const std::shared_ptr<Pattern>& pattern, std::string& error) {
  std::map<std::string, double> p;
  const std::size_t n = device.channelCount();
  if (name == "idle" || name == "assessment" || name == "record-pattern") {
    if (!readParams(params, {}, p, error)) return nullptr;
    if (name == "idle") return std::make_unique<Idle>();
    if (name == "assessment") return std::make_unique<Assessment>();
    return std::make_unique<RecordPattern>(pattern);
  }
  if (name == "resistance") {
    const double emax = device.effortLimit(0);
    if (!readParams(params,
                    {{"stiffness_per_rad", {0.2 * emax, 0.0, 2.0 * emax, "effort/rad"}},
                     {"damping_s_per_rad", {0.02 * emax, 0.0, 0.5 * emax, "effort·s/rad"}},
                     {"rest_deg", {0.0, -90.0, 360.0, "deg"}}},
                    p, error)) {
      return nullptr;
    }
    return std::make_unique<Resistance>(n, p["stiffness_per_rad"], p["damping_s_per_rad"], p["rest_deg"] * kDeg);
  }
  if (name == "assistance") {
    auto spec = assistSpec(device);
    spec["period_s"] = {4.0, 1.0, 60.0, "s"};
    spec["open_fraction"] = {0.1, 0.0, 1.0, ""};
    spec["close_fraction"] = {0.8, 0.0, 1.0, ""};
    if (!readParams(params, spec, p, error)) return nullptr;
    if (p["open_fraction"] >= p["close_fraction"]) {
      error = "params.open_fraction: must be below close_fraction";
      return nullptr;
    }
    std::array<double, kMaxChannels> lo{}, hi{}, open{}, close{};
    patientChannelRange(device, profile, lo, hi);
    for (std::size_t c = 0; c < n; ++c) {
      open[c] = lo[c] + p["open_fraction"] * (hi[c] - lo[c]);
      close[c] = lo[c] + p["close_fraction"] * (hi[c] - lo[c]);
    }
    return std::make_unique<CosineAssist>(n, assistLawFrom(p), toJson(p), p["period_s"], open, close);
  }
  if (name == "playback") {
    auto spec = assistSpec(device);
    spec["speed"] = {1.0, 0.25, 2.0, "x"};
    if (!readParams(params, spec, p, error)) return nullptr;
    if (!pattern || pattern->length() < 100) {
      error = "playback: no grip/release pattern recorded yet (run record-pattern for at least 1 s first)";
      return nullptr;
    }
    auto j = toJson(p);
    j["pattern_s"] = static_cast<double>(pattern->length()) / Pattern::kRateHz;
    return std::make_unique<PlaybackAssist>(n, assistLawFrom(p), j, *pattern, p["speed"]);
  }
  if (name == "grasp") {
    std::string scene = "rigid-ball";
    if (!params.is_null()) {
      if (!params.is_object()) {
        error = "params: expected an object";
        return nullptr;
      }
      for (const auto& [k, v] : params.items()) {
        if (k != "scene") {
          error = "params." + k + ": unknown parameter (allowed: scene)";
          return nullptr;
        }
        if (!v.is_string()) {
          error = "params.scene: expected a string";
          return nullptr;
        }
        scene = v.get<std::string>();
      }
    }
    auto inner = device.makeGraspController(scene, error);
    if (!inner) return nullptr;
    return std::make_unique<Grasp>(std::move(inner), device, scene);
  }
  if (name == "tardieu" || name == "passive-rom" || name == "max-force") return makeInstrumented(name, params, device, error);
  error = "exercise: '" + name +
          "' is not one of idle, assessment, resistance, assistance, record-pattern, playback, grasp, tardieu, "
          "passive-rom, max-force";
  return nullptr;
}

}  // namespace phalanx::host::therapy
