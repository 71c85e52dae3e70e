// Closed loop in lockstep: the therapy controller (every exercise, the patient profile's limits) on the simulated
// glove and hand, with a therapist issuing random commands. The profile's limits must never be exceeded.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "phalanx/fw_sim/glove5_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/glove_device.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/therapy_controller.h"

using namespace phalanx;
using namespace phalanx::host::therapy;

namespace {

// Tight limits so that they bind: 2.5 N (thumb 1.5 N) and a narrow index MCP / PIP range the simulated hand's
// random motion leaves.
const char* kProfile = R"(version: 1
patient: sim-1
device: glove5
rom_deg: {index_mcp: [0, 60], index_pip: [0, 80]}
limits:
  effort_max: {default: 2.5, thumb: 1.5}
  range_deg: {index_mcp: [0, 35], index_pip: [5, 50], middle_pip: [0, 45]}
)";

struct Stats {
  long cycles = 0;
  long effort_violations = 0;
  long range_violations = 0;
  long range_checks = 0;        // cycles with a joint beyond its range (the clamp had something to do)
  long limited_cycles = 0;
  double max_ratio = 0.0;       // max |setpoint| / limit
  double peak_measured_N = 0.0;
  std::string peak_exercise;
  int peak_mode = 0;
  double peak_setpoint = 0.0;
};

}  // namespace

TEST(TherapyLimits, RandomTherapistCommandsNeverExceedTheProfileLimits) {
  Profile profile;
  ASSERT_EQ(loadProfileText(kProfile, "sim.yaml", profile), "");
  std::string err;
  auto device = GloveTherapyDevice::make({}, err);
  ASSERT_TRUE(device) << err;
  GloveTherapyDevice checker = *GloveTherapyDevice::make({}, err);  // independent observer for the checks
  const TherapyDevice& dev = *device;
  auto pattern = std::make_shared<Pattern>(5);
  auto initial = makeExercise("assessment", nullptr, dev, profile, pattern, err);
  ASSERT_TRUE(initial) << err;
  TherapyController controller(std::move(device), profile.limits, std::move(initial), nullptr);

  sim::GlovePlantConfig plant;
  plant.scenario = sim::HandScenario::kRandom;
  plant.seed = 11;
  fw_sim::Glove5SimDevice sim_device(plant);
  host::LockstepRig rig(sim_device, controller);
  ASSERT_EQ(rig.handshake(), "");

  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const char* names[] = {"assessment", "resistance", "assistance", "record-pattern", "playback", "grasp", "idle"};
  PatientLimits in_force = profile.limits;
  PatientLimits pending = in_force;
  bool limits_pending = false;
  Stats s;
  int commands = 0, refused = 0;
  double next_command_s = rig.timeS() + 0.5;
  const double end_s = rig.timeS() + 40.0;
  Observation obs{};
  while (rig.timeS() < end_s) {
    if (rig.timeS() >= next_command_s) {
      next_command_s += 0.3 + 1.2 * u(rng);
      ++commands;
      if (u(rng) < 0.25) {
        // Lower (never raise) a random channel's limit, as the API's "limits" request does.
        pending = controller.limits();
        const size_t c = static_cast<size_t>(rng() % 5);
        pending.effort_max[c] = profile.limits.effort_max[c] * (0.2 + 0.8 * u(rng));
        controller.offerLimits(pending);
        limits_pending = true;
      } else {
        const std::string name = names[rng() % 7];
        nlohmann::json params = nlohmann::json::object();
        if (name == "resistance") {
          params = {{"stiffness_per_rad", 20.0 * u(rng)}, {"damping_s_per_rad", 5.0 * u(rng)}, {"rest_deg", 60.0 * u(rng)}};
        } else if (name == "assistance" || name == "playback") {
          params = {{"stiffness_per_rad", 20.0 * u(rng)}, {"deadband_deg", 10.0 * u(rng)}, {"learning_per_rad_s", 5.0 * u(rng)}};
        } else if (name == "grasp") {
          params = {{"scene", u(rng) < 0.5 ? "rigid-ball" : "wall"}};
        }
        auto ex = makeExercise(name, params, controller.device(), profile, pattern, err);
        if (ex) controller.offerExercise(std::move(ex));
        else ++refused;  // playback before any pattern: refused, as the API would
      }
      controller.collectRetired();
    }
    rig.step();
    const auto& tel = rig.session().latest();
    const auto& cmd = rig.lastCommand();
    if (limits_pending) {  // the loop took them at this cycle (they were offered before it)
      in_force = pending;
      limits_pending = false;
    }
    checker.observe(tel, obs);
    ++s.cycles;
    for (size_t c = 0; c < 5; ++c) {
      const double sp = static_cast<double>(cmd.setpoint[c]);
      const double lim = in_force.effort_max[c];
      s.max_ratio = std::max(s.max_ratio, std::fabs(sp) / lim);
      if (std::fabs(sp) > lim + 1e-6) ++s.effort_violations;
      const double f = std::fabs(static_cast<double>(tel.value[15 + c]));
      if (f > s.peak_measured_N) {
        s.peak_measured_N = f;
        s.peak_exercise = exerciseName(controller.status().exercise);
        s.peak_mode = static_cast<int>(cmd.mode);
        s.peak_setpoint = sp;
      }
    }
    for (size_t j = 0; j < 15; ++j) {
      if (!obs.joint_valid[j]) continue;
      const double sp = static_cast<double>(cmd.setpoint[j / 3]);
      if (obs.flexion_rad[j] > profile.limits.flexion_max_rad[j]) {
        ++s.range_checks;
        if (sp < 0.0) ++s.range_violations;  // pushing a joint further into flexion beyond its limit
      } else if (obs.flexion_rad[j] < profile.limits.flexion_min_rad[j]) {
        ++s.range_checks;
        if (sp > 0.0) ++s.range_violations;
      }
    }
  }
  const auto st = controller.status();
  std::printf("%ld cycles, %d therapist commands (%d refused), max |setpoint|/limit %.3f, %ld cycles with a joint "
              "out of range, %llu limited cycles, peak measured pad force %.2f N (in %s, mode %d, setpoint %.2f N)\n",
              s.cycles, commands, refused, s.max_ratio, s.range_checks,
              static_cast<unsigned long long>(st.limited_cycles), s.peak_measured_N, s.peak_exercise.c_str(), s.peak_mode,
              s.peak_setpoint);
  EXPECT_EQ(s.effort_violations, 0);
  EXPECT_EQ(s.range_violations, 0);
  // The test must exercise the limits, not pass vacuously.
  EXPECT_GT(commands, 25);
  EXPECT_GT(s.max_ratio, 0.99) << "the effort limit never bound";
  EXPECT_GT(s.range_checks, 1000) << "no joint left its range: the range clamp was not exercised";
  EXPECT_GT(st.limited_cycles, 1000u);
}
