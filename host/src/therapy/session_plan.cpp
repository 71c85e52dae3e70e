#include "phalanx/host/therapy/session_plan.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace phalanx::host::therapy {
namespace {

constexpr double kDeg = 180.0 / M_PI;
/// A repetition needs a flex-extend swing of at least this much of the channel coordinate: well above the
/// estimator's noise (≤ 1.6° per joint, docs/therapy.md "Measured"), so noise never counts one.
constexpr double kMinRepSwingDeg = 10.0;

struct PlanError {
  std::string message;
};

std::string fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

void allowKeys(const nlohmann::json& obj, const std::string& where, const std::set<std::string>& allowed) {
  for (const auto& [k, v] : obj.items()) {
    if (allowed.count(k) != 0) continue;
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
    throw PlanError{where + "." + k + ": unknown field (accepted: " + list + ")"};
  }
}

double numberField(const nlohmann::json& step, const std::string& key, const std::string& where) {
  const nlohmann::json& v = step[key];
  if (!v.is_number() || !std::isfinite(v.get<double>())) throw PlanError{where + "." + key + ": expected a number"};
  return v.get<double>();
}

const Preset* findPreset(const Profile& profile, const std::string& name) {
  for (const auto& p : profile.presets) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

std::string presetList(const Profile& profile) {
  std::string list;
  for (const auto& p : profile.presets) list += (list.empty() ? "" : ", ") + p.name;
  return list.empty() ? "none" : list;
}

/// What the step runs: a preset of the profile, or an exercise with its parameters.
void resolveWhat(const nlohmann::json& j, const std::string& where, const Profile& profile, PlanStep& s) {
  const bool has_preset = j.contains("preset"), has_exercise = j.contains("exercise");
  if (has_preset == has_exercise) throw PlanError{where + ": give either an exercise or a preset"};
  if (has_preset) {
    if (!j["preset"].is_string()) throw PlanError{where + ".preset: expected a string"};
    s.preset = j["preset"].get<std::string>();
    if (j.contains("params")) throw PlanError{where + ".params: a preset's parameters are the profile's (give an exercise to set them)"};
    const Preset* p = findPreset(profile, s.preset);
    if (p == nullptr) {
      throw PlanError{where + ".preset: '" + s.preset + "' is not a preset of " +
                      (profile.patient.empty() ? "this session (no patient profile)"
                                               : "patient " + profile.patient + " (presets: " + presetList(profile) + ")")};
    }
    s.exercise = p->exercise;
    s.params = p->params;
    return;
  }
  if (!j["exercise"].is_string()) throw PlanError{where + ".exercise: expected a string"};
  s.exercise = j["exercise"].get<std::string>();
  if (s.exercise == "playback") throw PlanError{where + ".exercise: playback needs a pattern recorded in the session; it cannot be a plan step"};
  if (j.contains("params")) {
    if (!j["params"].is_object()) throw PlanError{where + ".params: expected an object"};
    s.params = j["params"];
  }
}

/// Duration and repetition target.
void resolveAmounts(const nlohmann::json& j, const std::string& where, PlanStep& s) {
  if (!j.contains("duration_s")) throw PlanError{where + ".duration_s: missing (every step has a duration)"};
  s.duration_s = numberField(j, "duration_s", where);
  if (!(s.duration_s > 0.0 && s.duration_s <= kMaxPlanStepS)) {
    throw PlanError{where + ".duration_s: must be in (0, " + fmt(kMaxPlanStepS) + "] s, got " + fmt(s.duration_s)};
  }
  if (j.contains("repetitions")) {
    const nlohmann::json& r = j["repetitions"];
    if (!r.is_number_integer() || r.get<long long>() < 0 || r.get<long long>() > kMaxPlanRepetitions) {
      throw PlanError{where + ".repetitions: expected a whole number from 0 to " + std::to_string(kMaxPlanRepetitions)};
    }
    s.repetitions = static_cast<uint32_t>(r.get<long long>());
  }
}

/// The counted channel and its thresholds: rep_range_deg, else kRepExtendFraction/kRepFlexFraction of the patient's
/// range of that channel.
void resolveCounting(const nlohmann::json& j, const std::string& where, const TherapyDevice& device,
                     const Profile& profile, PlanStep& s) {
  int c = device.channelIndex("index");
  if (c < 0) c = 0;
  if (j.contains("channel")) {
    if (!j["channel"].is_string()) throw PlanError{where + ".channel: expected a channel name"};
    c = device.channelIndex(j["channel"].get<std::string>());
    if (c < 0) throw PlanError{where + ".channel: '" + j["channel"].get<std::string>() + "' is not a channel of " + device.name()};
  }
  s.channel = static_cast<std::size_t>(c);
  if (j.contains("rep_range_deg")) {
    const nlohmann::json& r = j["rep_range_deg"];
    if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number()) {
      throw PlanError{where + ".rep_range_deg: expected [extended_deg, flexed_deg]"};
    }
    const double lo = r[0].get<double>(), hi = r[1].get<double>();
    if (!std::isfinite(lo) || !std::isfinite(hi) || hi - lo < kMinRepSwingDeg) {
      throw PlanError{where + ".rep_range_deg: flexed_deg must be at least " + fmt(kMinRepSwingDeg) + "° above extended_deg"};
    }
    s.extend_rad = lo / kDeg;
    s.flex_rad = hi / kDeg;
    return;
  }
  std::array<double, kMaxChannels> lo{}, hi{};
  patientChannelRange(device, profile, lo, hi);
  const double span = hi[s.channel] - lo[s.channel];
  s.extend_rad = lo[s.channel] + kRepExtendFraction * span;
  s.flex_rad = lo[s.channel] + kRepFlexFraction * span;
  if (s.repetitions > 0 && (s.flex_rad - s.extend_rad) * kDeg < kMinRepSwingDeg) {
    throw PlanError{where + ".repetitions: the patient's range of channel " + device.channelName(s.channel) + " is " +
                    fmt(std::round(span * kDeg)) + "°, too small to count repetitions (give rep_range_deg)"};
  }
}

PlanStep parseStep(const nlohmann::json& j, const std::string& where, const TherapyDevice& device,
                   const Profile& profile, const std::set<std::string>* allowed) {
  if (!j.is_object()) throw PlanError{where + ": expected an object"};
  allowKeys(j, where, {"preset", "exercise", "params", "duration_s", "repetitions", "channel", "rep_range_deg"});
  PlanStep s;
  resolveWhat(j, where, profile, s);
  const std::string& name = s.preset.empty() ? s.exercise : s.preset;
  if (allowed != nullptr && allowed->count(name) == 0) {
    std::string list;
    for (const auto& a : *allowed) list += (list.empty() ? "" : ", ") + a;
    throw PlanError{where + ": '" + name + "' is not allowed in self-training for patient " + profile.patient +
                    " (allowed: " + list + ")"};
  }
  resolveAmounts(j, where, s);
  resolveCounting(j, where, device, profile, s);
  std::string err;
  auto pattern = std::make_shared<Pattern>(device.channelCount());
  if (!makeExercise(s.exercise, s.params, device, profile, pattern, err)) {
    throw PlanError{where + (s.preset.empty() ? "." : " (preset " + s.preset + ")." ) + err};
  }
  return s;
}

}  // namespace

bool RepetitionCounter::update(double q_rad) {
  if (!std::isfinite(q_rad)) return false;
  if (q_rad <= extend_rad) {
    const bool done = armed && flexed;
    armed = true;
    flexed = false;
    if (done) ++count;
    return done;
  }
  if (armed && q_rad >= flex_rad) flexed = true;
  return false;
}

double SessionPlan::totalS() const {
  double t = 0.0;
  for (const auto& s : steps) t += s.duration_s;
  return t;
}

nlohmann::json SessionPlan::toJson(const TherapyDevice& device) const {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& s : steps) {
    nlohmann::json j{{"exercise", s.exercise}, {"params", s.params}, {"duration_s", s.duration_s},
                     {"repetitions", s.repetitions}, {"channel", device.channelName(s.channel)},
                     {"rep_range_deg", {s.extend_rad * kDeg, s.flex_rad * kDeg}}};
    if (!s.preset.empty()) j["preset"] = s.preset;
    out.push_back(std::move(j));
  }
  return out;
}

nlohmann::json presetsJson(const Profile& profile) {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& p : profile.presets) out[p.name] = {{"exercise", p.exercise}, {"params", p.params}};
  return out;
}

nlohmann::json plansJson(const Profile& profile) {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& p : profile.plans) out[p.name] = {{"steps", p.step_count}, {"duration_s", p.total_s}};
  return out;
}

const NamedPlan* findPlan(const Profile& profile, const std::string& name) {
  for (const auto& p : profile.plans) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

std::string planList(const Profile& profile) {
  std::string list;
  for (const auto& p : profile.plans) list += (list.empty() ? "" : ", ") + p.name;
  return list.empty() ? "none" : list;
}

std::string parsePlan(const nlohmann::json& j, const TherapyDevice& device, const Profile& profile,
                      const std::set<std::string>* allowed, SessionPlan& out, const std::string& where) {
  Profile resolved = profile;  // a session without a profile counts within the device's own joint bounds
  if (resolved.limits.joint_count != device.jointCount()) resolved.limits = PatientLimits::deviceDefaults(device);
  try {
    if (!j.is_object()) throw PlanError{where + ": expected an object {\"steps\": [...]}"};
    allowKeys(j, where, {"steps"});
    if (!j.contains("steps") || !j["steps"].is_array()) throw PlanError{where + ".steps: expected a list of steps"};
    const std::size_t n = j["steps"].size();
    if (n == 0 || n > kMaxPlanSteps) {
      throw PlanError{where + ".steps: expected 1 to " + std::to_string(kMaxPlanSteps) + " steps, got " + std::to_string(n)};
    }
    SessionPlan plan;
    for (std::size_t i = 0; i < n; ++i) {
      plan.steps.push_back(parseStep(j["steps"][i], where + ".steps[" + std::to_string(i) + "]", device, resolved, allowed));
    }
    if (plan.totalS() > kMaxPlanTotalS) {
      throw PlanError{where + ".steps: the durations add up to " + fmt(plan.totalS()) + " s, more than the " +
                      fmt(kMaxPlanTotalS) + " s a plan may last"};
    }
    out = std::move(plan);
  } catch (const PlanError& e) {
    return e.message;
  }
  return {};
}

PlanRunner::PlanRunner(SessionPlan plan, std::vector<std::unique_ptr<Exercise>> later_steps)
    : plan_(std::move(plan)), later_(std::move(later_steps)) {
  later_.resize(plan_.steps.size());
  beginStep(0);
}

void PlanRunner::beginStep(std::size_t i) {
  const PlanStep& s = plan_.steps[i];
  counter_.reset();
  counter_.extend_rad = s.extend_rad;
  counter_.flex_rad = s.flex_rad;
  elapsed_s_ = 0.0;
  elapsed_us_.store(0, std::memory_order_relaxed);
  reps_.store(0, std::memory_order_relaxed);
  step_.store(i, std::memory_order_relaxed);
}

PlanRunner::Ended PlanRunner::cycle(const Observation& obs, double dt_s, bool counts) {
  if (finished()) return Ended::kNo;
  const std::size_t i = step();
  const PlanStep& s = plan_.steps[i];
  if (counts) {
    elapsed_s_ += dt_s;
    if (obs.channel_valid[s.channel] && counter_.update(obs.q_rad[s.channel])) reps_.store(counter_.count, std::memory_order_relaxed);
    elapsed_us_.store(std::llround(elapsed_s_ * 1e6), std::memory_order_relaxed);
  }
  Ended e = Ended::kNo;
  if (s.repetitions > 0 && counter_.count >= s.repetitions) e = Ended::kRepetitions;
  else if (elapsed_s_ >= s.duration_s) e = Ended::kDuration;
  if (e == Ended::kNo) return e;
  results_[i].repetitions.store(counter_.count, std::memory_order_relaxed);
  results_[i].elapsed_us.store(std::llround(elapsed_s_ * 1e6), std::memory_order_relaxed);
  results_[i].ended.store(static_cast<uint8_t>(e), std::memory_order_relaxed);
  ended_step_ = i;
  if (i + 1 < plan_.steps.size()) beginStep(i + 1);
  else finished_.store(true, std::memory_order_relaxed);
  return e;
}

Exercise* PlanRunner::takeNextExercise() { return finished() ? nullptr : later_[step()].release(); }

}  // namespace phalanx::host::therapy
