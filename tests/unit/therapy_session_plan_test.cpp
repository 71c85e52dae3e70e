// Session plans (docs/therapy.md "Session plan"): the repetition counter, the plan parser's refusals word for word,
// the profile's presets and self_training sections, and the plan runner's clock and step changes.
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/session_plan.h"
#include "../support/counting_allocator.h"  // g_allocations

using namespace phalanx::host::therapy;

namespace {

constexpr double kDeg = M_PI / 180.0;

const char* kProfile = R"(version: 1
patient: p-1
device: glove5
rom_deg: {index_mcp: [0, 70], index_pip: [0, 90], index_dip: [0, 40]}
limits:
  effort_max: {default: 4}
presets:
  gentle: {exercise: resistance, params: {stiffness_per_rad: 0.5}}
  open-close: {exercise: assistance, params: {period_s: 5}}
self_training:
  allowed: [gentle, assessment]
  max_session_s: 600
  effort_scale: 0.5
)";

struct Fixture {
  Profile profile;
  std::unique_ptr<TherapyDevice> device;
  Fixture() {
    std::string err = loadProfileText(kProfile, "p-1.yaml", profile);
    EXPECT_EQ(err, "");
    device = makeTherapyDevice("glove5", profile.kinematics, err);
    EXPECT_NE(device, nullptr) << err;
  }
  std::string parse(const std::string& text, SessionPlan& out, const std::set<std::string>* allowed = nullptr) {
    return parsePlan(nlohmann::json::parse(text), *device, profile, allowed, out);
  }
};

/// A close/open of the channel coordinate: extended → `top` → extended, in `n` samples each way.
void swing(RepetitionCounter& c, double from, double top, int n = 50) {
  for (int i = 0; i <= n; ++i) c.update(from + (top - from) * i / n);
  for (int i = 0; i <= n; ++i) c.update(top + (from - top) * i / n);
}

}  // namespace

TEST(RepetitionCounter, CountsOneFlexExtendCycleOnItsReturn) {
  RepetitionCounter c;
  c.extend_rad = 0.5;
  c.flex_rad = 1.5;
  swing(c, 0.0, 2.0);
  EXPECT_EQ(c.count, 1u);
  swing(c, 0.0, 2.0);
  swing(c, 0.0, 2.0);
  EXPECT_EQ(c.count, 3u);
}

TEST(RepetitionCounter, ASwingThatMissesEitherThresholdCountsNothing) {
  RepetitionCounter c;
  c.extend_rad = 0.5;
  c.flex_rad = 1.5;
  c.update(0.0);
  swing(c, 0.0, 1.49);  // never flexed enough
  EXPECT_EQ(c.count, 0u);
  for (int i = 0; i < 20; ++i) c.update(i % 2 ? 1.6 : 0.51);  // never extended enough between flexions
  EXPECT_EQ(c.count, 0u);
  c.update(std::nan(""));  // a missing sample changes nothing
  c.update(0.4);
  EXPECT_EQ(c.count, 1u);  // the flexion above, then back to extended: one
}

TEST(RepetitionCounter, StartingFlexedTheFirstReturnOnlyArmsIt) {
  RepetitionCounter c;
  c.extend_rad = 0.5;
  c.flex_rad = 1.5;
  c.update(2.0);
  c.update(0.0);
  EXPECT_EQ(c.count, 0u);
  swing(c, 0.0, 2.0);
  EXPECT_EQ(c.count, 1u);
}

TEST(RepetitionCounter, NoiseInsideTheHysteresisNeverCountsOne) {
  RepetitionCounter c;
  c.extend_rad = 0.5;
  c.flex_rad = 1.5;
  for (int i = 0; i < 10000; ++i) c.update(1.0 + 0.45 * std::sin(i * 0.37) + 0.04 * std::sin(i * 7.1));
  EXPECT_EQ(c.count, 0u);
}

TEST(SessionPlan, AValidPlanResolvesPresetsChannelsAndThresholds) {
  Fixture f;
  SessionPlan plan;
  ASSERT_EQ(f.parse(R"({"steps": [{"exercise": "assessment", "duration_s": 30, "repetitions": 5},
                                   {"preset": "gentle", "duration_s": 60, "channel": "middle"},
                                   {"exercise": "resistance", "params": {"rest_deg": 10}, "duration_s": 5,
                                    "rep_range_deg": [20, 120]}]})",
                    plan),
            "");
  ASSERT_EQ(plan.steps.size(), 3u);
  EXPECT_EQ(plan.steps[0].exercise, "assessment");
  EXPECT_EQ(plan.steps[0].repetitions, 5u);
  EXPECT_EQ(f.device->channelName(plan.steps[0].channel), "index");  // the default counted channel
  // index: 0 + 0 + 0 … 70 + 90 + 40 = 200°: thresholds at 25 % and 75 %.
  EXPECT_NEAR(plan.steps[0].extend_rad / kDeg, 50.0, 1e-9);
  EXPECT_NEAR(plan.steps[0].flex_rad / kDeg, 150.0, 1e-9);
  EXPECT_EQ(plan.steps[1].preset, "gentle");
  EXPECT_EQ(plan.steps[1].exercise, "resistance");
  EXPECT_EQ(plan.steps[1].params["stiffness_per_rad"], 0.5);
  EXPECT_EQ(f.device->channelName(plan.steps[1].channel), "middle");
  EXPECT_NEAR(plan.steps[2].extend_rad / kDeg, 20.0, 1e-9);
  EXPECT_NEAR(plan.steps[2].flex_rad / kDeg, 120.0, 1e-9);
  EXPECT_DOUBLE_EQ(plan.totalS(), 95.0);
}

TEST(SessionPlan, EveryBadFieldIsRefusedByNameAndChangesNothing) {
  Fixture f;
  SessionPlan plan;
  ASSERT_EQ(f.parse(R"({"steps": [{"exercise": "assessment", "duration_s": 1}]})", plan), "");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"([])", "plan: expected an object {\"steps\": [...]}"},
      {R"({"steps": [], "x": 1})", "plan.x: unknown field (accepted: steps)"},
      {R"({"stpes": []})", "plan.stpes: unknown field (accepted: steps)"},
      {R"({"steps": 3})", "plan.steps: expected a list of steps"},
      {R"({"steps": []})", "plan.steps: expected 1 to 32 steps, got 0"},
      {R"({"steps": [{"exercise": "resistence", "duration_s": 5}]})",
       "plan.steps[0].exercise: 'resistence' is not one of idle, assessment, resistance, assistance, record-pattern, "
       "playback, grasp, tardieu, passive-rom, max-force"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5}, {"exercise": "assessment", "duration_s": 0}]})",
       "plan.steps[1].duration_s: must be in (0, 3600] s, got 0"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": -1}]})",
       "plan.steps[0].duration_s: must be in (0, 3600] s, got -1"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 1e9}]})",
       "plan.steps[0].duration_s: must be in (0, 3600] s, got 1e+09"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": "5"}]})", "plan.steps[0].duration_s: expected a number"},
      {R"({"steps": [{"exercise": "assessment"}]})", "plan.steps[0].duration_s: missing (every step has a duration)"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5, "repetitions": 2.5}]})",
       "plan.steps[0].repetitions: expected a whole number from 0 to 1000"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5, "repetitions": -1}]})",
       "plan.steps[0].repetitions: expected a whole number from 0 to 1000"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5, "repeats": 3}]})",
       "plan.steps[0].repeats: unknown field (accepted: channel, duration_s, exercise, params, preset, rep_range_deg, "
       "repetitions)"},
      {R"({"steps": [{"duration_s": 5}]})", "plan.steps[0]: give either an exercise or a preset"},
      {R"({"steps": [{"exercise": "assessment", "preset": "gentle", "duration_s": 5}]})",
       "plan.steps[0]: give either an exercise or a preset"},
      {R"({"steps": [{"preset": "strong", "duration_s": 5}]})",
       "plan.steps[0].preset: 'strong' is not a preset of patient p-1 (presets: gentle, open-close)"},
      {R"({"steps": [{"preset": "gentle", "params": {}, "duration_s": 5}]})",
       "plan.steps[0].params: a preset's parameters are the profile's (give an exercise to set them)"},
      {R"({"steps": [{"exercise": "resistance", "params": {"stiffness_per_rad": 99}, "duration_s": 5}]})",
       "plan.steps[0].params.stiffness_per_rad: 99 is outside [0, 20] effort/rad"},
      {R"({"steps": [{"exercise": "playback", "duration_s": 5}]})",
       "plan.steps[0].exercise: playback needs a pattern recorded in the session; it cannot be a plan step"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5, "channel": "toe"}]})",
       "plan.steps[0].channel: 'toe' is not a channel of glove5"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 5, "rep_range_deg": [40, 45]}]})",
       "plan.steps[0].rep_range_deg: flexed_deg must be at least 10° above extended_deg"},
      {R"({"steps": [{"exercise": "assessment", "duration_s": 3600}, {"exercise": "assessment", "duration_s": 3600},
                     {"exercise": "assessment", "duration_s": 3600}, {"exercise": "assessment", "duration_s": 3600},
                     {"exercise": "assessment", "duration_s": 1}]})",
       "plan.steps: the durations add up to 14401 s, more than the 14400 s a plan may last"},
  };
  for (const auto& [text, error] : cases) {
    EXPECT_EQ(f.parse(text, plan), error) << text;
    ASSERT_EQ(plan.steps.size(), 1u) << "a refused plan changed the plan: " << text;
  }
  std::string many = R"({"steps": [)";
  for (int i = 0; i < 33; ++i) many += std::string(i ? "," : "") + R"({"exercise": "assessment", "duration_s": 1})";
  EXPECT_EQ(f.parse(many + "]}", plan), "plan.steps: expected 1 to 32 steps, got 33");
}

TEST(SessionPlan, RepetitionsNeedARangeToCountIn) {
  Fixture f;
  // The thumb has no rom_deg in the profile and no allowed range below the device's own: counted within the
  // joint bounds. A profile whose range of the channel is tiny refuses a repetition target.
  Profile tight;
  ASSERT_EQ(loadProfileText("version: 1\npatient: p-2\ndevice: glove5\nrom_deg: {index_mcp: [10, 12], index_pip: [0, 1],"
                            " index_dip: [0, 1]}\nlimits: {effort_max: 4}\n",
                            "p-2.yaml", tight),
            "");
  SessionPlan plan;
  EXPECT_EQ(parsePlan(nlohmann::json::parse(R"({"steps": [{"exercise": "assessment", "duration_s": 5, "repetitions": 3}]})"),
                      *f.device, tight, nullptr, plan),
            "plan.steps[0].repetitions: the patient's range of channel index is 4°, too small to count repetitions "
            "(give rep_range_deg)");
  EXPECT_EQ(parsePlan(nlohmann::json::parse(R"({"steps": [{"exercise": "assessment", "duration_s": 5, "repetitions": 3,
                                                              "rep_range_deg": [0, 60]}]})"),
                      *f.device, tight, nullptr, plan),
            "");
}

TEST(SessionPlan, SelfTrainingAllowsOnlyTheProfilesList) {
  Fixture f;
  SessionPlan plan;
  const auto* allowed = &f.profile.self_training.steps;
  EXPECT_EQ(f.parse(R"({"steps": [{"preset": "gentle", "duration_s": 5}, {"exercise": "assessment", "duration_s": 5}]})",
                    plan, allowed),
            "");
  EXPECT_EQ(f.parse(R"({"steps": [{"preset": "open-close", "duration_s": 5}]})", plan, allowed),
            "plan.steps[0]: 'open-close' is not allowed in self-training for patient p-1 (allowed: assessment, gentle)");
  EXPECT_EQ(f.parse(R"({"steps": [{"exercise": "resistance", "duration_s": 5}]})", plan, allowed),
            "plan.steps[0]: 'resistance' is not allowed in self-training for patient p-1 (allowed: assessment, gentle)");
}

TEST(ProfilePresets, PresetsAndSelfTrainingAreValidatedKeyByKey) {
  Fixture f;
  ASSERT_EQ(f.profile.presets.size(), 2u);
  EXPECT_TRUE(f.profile.self_training.allowed);
  EXPECT_DOUBLE_EQ(f.profile.self_training.effort_scale, 0.5);
  EXPECT_DOUBLE_EQ(f.profile.self_training.max_session_s, 600.0);
  const std::string base = "version: 1\npatient: p-3\ndevice: glove5\nlimits: {effort_max: 4}\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"presets: {a: {exercise: resistance, params: {stiffness_per_rad: 50}}}",
       "p-3.yaml: presets.a.params.stiffness_per_rad: 50 is outside [0, 20] effort/rad"},
      {"presets: {a: {exercise: resistence}}",
       "p-3.yaml: presets.a.exercise: 'resistence' is not one of idle, assessment, resistance, assistance, "
       "record-pattern, playback, grasp, tardieu, passive-rom, max-force"},
      {"presets: {a: {exercise: resistance, parms: {}}}",
       "p-3.yaml: presets.a.parms: unknown key (allowed: exercise, params)"},
      {"presets: {a: {params: {}}}", "p-3.yaml: presets.a.exercise: missing"},
      {"presets: {a: {exercise: playback}}",
       "p-3.yaml: presets.a.exercise: playback needs a pattern recorded in the session; it cannot be a preset"},
      {"presets: {\"a b\": {exercise: assessment}}",
       "p-3.yaml: presets.a b: a preset name is 1-32 letters, digits, '-' or '_'"},
      {"presets: [a]", "p-3.yaml: presets: expected a mapping <name>: {exercise, params}"},
      {"self_training: {allowed: [gentle], max_session_s: 60}",
       "p-3.yaml: self_training.allowed[0]: 'gentle' is neither a preset of this profile nor an exercise"},
      {"self_training: {allowed: [], max_session_s: 60}",
       "p-3.yaml: self_training.allowed: expected a non-empty list of presets or exercises"},
      {"self_training: {allowed: [assessment]}",
       "p-3.yaml: self_training.max_session_s: missing (how long the patient may train alone)"},
      {"self_training: {allowed: [assessment], max_session_s: 0}",
       "p-3.yaml: self_training.max_session_s: must be in (0, 7200] s"},
      {"self_training: {allowed: [assessment], max_session_s: 60, effort_scale: 1.5}",
       "p-3.yaml: self_training.effort_scale: must be in (0, 1] (it can only lower the profile's effort_max)"},
      {"self_training: {allowed: [assessment], max_session_s: 60, effort: 0.5}",
       "p-3.yaml: self_training.effort: unknown key (allowed: allowed, effort_scale, max_session_s)"},
  };
  for (const auto& [extra, error] : cases) {
    Profile p;
    p.patient = "unchanged";
    EXPECT_EQ(loadProfileText(base + extra + "\n", "p-3.yaml", p), error) << extra;
    EXPECT_EQ(p.patient, "unchanged");
  }
}

// A profile's plans (`plans:`) go through the plan parser at load: the same steps as an inline plan, errors naming
// the file, the plan and the field.
TEST(ProfilePlans, APlanOfTheProfileParsesAsTheSameInlinePlanAndIsListed) {
  Profile p;
  ASSERT_EQ(loadProfileText(std::string(kProfile) +
                                "plans:\n  warmup:\n    steps:\n"
                                "      - {exercise: assessment, duration_s: 30, repetitions: 5}\n"
                                "      - {preset: gentle, duration_s: 60, channel: middle}\n"
                                "  test: {steps: [{exercise: resistance, params: {rest_deg: 10}, duration_s: 5, "
                                "rep_range_deg: [20, 120]}]}\n",
                            "p-1.yaml", p),
            "");
  ASSERT_EQ(p.plans.size(), 2u);
  const NamedPlan* warmup = findPlan(p, "warmup");
  ASSERT_NE(warmup, nullptr);
  EXPECT_EQ(findPlan(p, "warm-up"), nullptr);
  EXPECT_EQ(warmup->step_count, 2u);
  EXPECT_DOUBLE_EQ(warmup->total_s, 90.0);
  EXPECT_EQ(plansJson(p), nlohmann::json::parse(R"({"warmup": {"steps": 2, "duration_s": 90.0},
                                                     "test": {"steps": 1, "duration_s": 5.0}})"));
  EXPECT_EQ(planList(p), "warmup, test");  // the file's order
  // Parsed again (as `start` does): the steps an inline plan of the same fields gives.
  Fixture f;
  SessionPlan from_profile, from_inline;
  ASSERT_EQ(parsePlan(warmup->plan, *f.device, p, nullptr, from_profile, "plans.warmup"), "");
  ASSERT_EQ(f.parse(R"({"steps": [{"exercise": "assessment", "duration_s": 30, "repetitions": 5},
                                   {"preset": "gentle", "duration_s": 60, "channel": "middle"}]})",
                    from_inline),
            "");
  EXPECT_EQ(from_profile.toJson(*f.device), from_inline.toJson(*f.device));
  EXPECT_EQ(from_profile.steps[0].repetitions, 5u);
  EXPECT_EQ(from_profile.steps[1].preset, "gentle");
  // Self-training's list is applied when the plan starts, not at load: checked against a narrower list, the same
  // stored plan is refused naming the profile's plan and its step.
  std::set<std::string> only_assessment = {"assessment"};
  EXPECT_EQ(parsePlan(warmup->plan, *f.device, p, &only_assessment, from_profile, "plans.warmup"),
            "plans.warmup.steps[1]: 'gentle' is not allowed in self-training for patient p-1 (allowed: assessment)");
}

TEST(ProfilePlans, EveryBadPlanIsRefusedNamingTheFileThePlanAndTheField) {
  const std::string base = "version: 1\npatient: p-3\ndevice: glove5\nlimits: {effort_max: 4}\n"
                           "presets: {gentle: {exercise: resistance}}\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"plans: {w: {steps: [{exercise: assessment, duration_s: 0}]}}",
       "p-3.yaml: plans.w.steps[0].duration_s: must be in (0, 3600] s, got 0"},
      {"plans: {w: {steps: [{exercise: assessment, duration_s: 5}, {preset: gentel, duration_s: 5}]}}",
       "p-3.yaml: plans.w.steps[1].preset: 'gentel' is not a preset of patient p-3 (presets: gentle)"},
      {"plans: {w: {steps: [{preset: gentle, params: {}, duration_s: 5}]}}",
       "p-3.yaml: plans.w.steps[0].params: a preset's parameters are the profile's (give an exercise to set them)"},
      {"plans: {w: {steps: [{exercise: resistance, params: {stiffness_per_rad: 99}, duration_s: 5}]}}",
       "p-3.yaml: plans.w.steps[0].params.stiffness_per_rad: 99 is outside [0, 20] effort/rad"},
      {"plans: {w: {steps: [{exercise: assessment, duration_s: 5, repetitions: 2.5}]}}",
       "p-3.yaml: plans.w.steps[0].repetitions: expected a whole number from 0 to 1000"},
      {"plans: {w: {steps: [{exercise: assessment, duration_s: '5'}]}}",
       "p-3.yaml: plans.w.steps[0].duration_s: expected a number"},
      {"plans: {w: {steps: [{exercise: assessment, duration_s: 5, repeats: 3}]}}",
       "p-3.yaml: plans.w.steps[0].repeats: unknown field (accepted: channel, duration_s, exercise, params, preset, "
       "rep_range_deg, repetitions)"},
      {"plans: {w: {steps: [{exercise: playback, duration_s: 5}]}}",
       "p-3.yaml: plans.w.steps[0].exercise: playback needs a pattern recorded in the session; it cannot be a plan step"},
      {"plans: {w: {steps: []}}", "p-3.yaml: plans.w.steps: expected 1 to 32 steps, got 0"},
      {"plans: {w: {stpes: []}}", "p-3.yaml: plans.w.stpes: unknown field (accepted: steps)"},
      {"plans: {w: [a]}", "p-3.yaml: plans.w: expected an object {\"steps\": [...]}"},
      {"plans: {w: }", "p-3.yaml: plans.w: expected an object {\"steps\": [...]}"},
      {"plans: [w]", "p-3.yaml: plans: expected a mapping <name>: {steps: [...]}"},
      {"plans: {\"a b\": {steps: [{exercise: assessment, duration_s: 5}]}}",
       "p-3.yaml: plans.a b: a plan name is 1-32 letters, digits, '-' or '_'"},
      {"plans:\n  w: {steps: [{exercise: assessment, duration_s: 5}]}\n  w: {steps: [{exercise: idle, duration_s: 5}]}",
       "p-3.yaml: plans.w: duplicate key (line 8; first at line 7)"},
  };
  for (const auto& [extra, error] : cases) {
    Profile p;
    p.patient = "unchanged";
    EXPECT_EQ(loadProfileText(base + extra + "\n", "p-3.yaml", p), error) << extra;
    EXPECT_EQ(p.patient, "unchanged");
    EXPECT_TRUE(p.plans.empty());
  }
}

TEST(PlanRunner, StepsEndAtTheirDurationOrRepetitionsCountingOnlyCountedTime) {
  Fixture f;
  SessionPlan plan;
  ASSERT_EQ(f.parse(R"({"steps": [{"exercise": "assessment", "duration_s": 10, "repetitions": 2, "rep_range_deg": [30, 90]},
                                   {"exercise": "idle", "duration_s": 0.5}]})",
                    plan),
            "");
  std::vector<std::unique_ptr<Exercise>> later(2);
  std::string err;
  auto pattern = std::make_shared<Pattern>(5);
  later[1] = makeExercise("idle", nullptr, *f.device, f.profile, pattern, err);
  Exercise* idle = later[1].get();
  PlanRunner runner(plan, std::move(later));
  Observation obs{};
  obs.channel_valid.fill(true);
  const std::size_t index = plan.steps[0].channel;
  const double dt = 0.001;
  // 1 s close/open swings of the index, 0 → 120° → 0; uncounted (paused) cycles count neither time nor swings.
  auto run = [&](double seconds, bool counts) {
    PlanRunner::Ended e = PlanRunner::Ended::kNo;
    for (int i = 0; i < static_cast<int>(std::lround(seconds / dt)) && e == PlanRunner::Ended::kNo; ++i) {
      static int k = 0;
      obs.q_rad[index] = 60.0 * kDeg * (1.0 - std::cos(2.0 * M_PI * (k++) * dt));
      e = runner.cycle(obs, dt, counts);
    }
    return e;
  };
  EXPECT_EQ(run(3.0, false), PlanRunner::Ended::kNo);
  EXPECT_EQ(runner.elapsedS(), 0.0);
  EXPECT_EQ(runner.repetitions(), 0u);
  EXPECT_EQ(run(1.2, true), PlanRunner::Ended::kNo);
  EXPECT_EQ(runner.repetitions(), 1u);
  EXPECT_EQ(run(1.0, true), PlanRunner::Ended::kRepetitions);
  EXPECT_EQ(runner.step(), 1u);
  EXPECT_EQ(runner.result(0).repetitions.load(), 2u);
  // The second return through 30°: 60·(1 − cos 2πt) = 30 at t = 2 − 1/6 s of counted time.
  EXPECT_NEAR(static_cast<double>(runner.result(0).elapsed_us.load()) * 1e-6, 2.0 - 1.0 / 6.0, 0.002);
  EXPECT_EQ(runner.takeNextExercise(), idle);
  delete idle;  // ownership passed on, as the controller takes it
  EXPECT_EQ(run(0.3, true), PlanRunner::Ended::kNo);
  EXPECT_EQ(run(1.0, true), PlanRunner::Ended::kDuration);
  EXPECT_TRUE(runner.finished());
  EXPECT_NEAR(static_cast<double>(runner.result(1).elapsed_us.load()) * 1e-6, 0.5, 0.0015);
  EXPECT_EQ(runner.takeNextExercise(), nullptr);
}

TEST(PlanRunner, ItsCyclesAndStepChangesAllocateNothing) {
  Fixture f;
  SessionPlan plan;
  ASSERT_EQ(f.parse(R"({"steps": [{"exercise": "assessment", "duration_s": 1, "repetitions": 50},
                                   {"exercise": "assessment", "duration_s": 1}]})",
                    plan),
            "");
  std::vector<std::unique_ptr<Exercise>> later(2);
  std::string err;
  later[1] = makeExercise("assessment", nullptr, *f.device, f.profile, std::make_shared<Pattern>(5), err);
  PlanRunner runner(plan, std::move(later));
  Observation obs{};
  obs.channel_valid.fill(true);
  Exercise* next = nullptr;
  int ended = 0;
  const long before = g_allocations.load();
  for (int i = 0; i < 3200; ++i) {  // 2/3 counted: 2133 ms of plan time
    obs.q_rad[1] = 2.0 * (1.0 - std::cos(2.0 * M_PI * i * 0.001));
    if (runner.cycle(obs, 0.001, i % 3 != 0) != PlanRunner::Ended::kNo) {
      ++ended;
      if (Exercise* e = runner.takeNextExercise()) next = e;
    }
  }
  const long after = g_allocations.load();
  EXPECT_EQ(after, before);
  EXPECT_EQ(ended, 2);
  EXPECT_TRUE(runner.finished());
  delete next;
}
