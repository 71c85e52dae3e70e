// The therapy layer on the SEA index-finger exoskeleton (seeds/001), closed loop in lockstep: the sea_finger
// firmware app and SEA plant (finger variant, eq 13–14, sensor noise on) with the therapy controller (exercises,
// patient limits) through the SeaTherapyDevice adapter (eq 3–6, 9).
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>

#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/metrics.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/therapy/exercise.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/report.h"
#include "phalanx/host/sea/sea_finger_controller.h"
#include "phalanx/host/therapy/sea_device.h"
#include "phalanx/host/therapy/therapy_controller.h"
#include "phalanx/host/therapy/therapy_session.h"

using namespace phalanx;
using namespace phalanx::host::therapy;
namespace record = phalanx::host::record;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Tight limits that bind: finger torque 0.06 N·m (PIP 0.03 N·m), and MCP/PIP ranges the random motion leaves
// (it spans about ±17° MCP and ±24° PIP around the rest pose).
const char* kProfile = R"(version: 1
patient: sea-sim-1
device: sea_finger
rom_deg: {mcp: [0, 40], pip: [0, 50]}
limits:
  effort_max: {default: 0.06, pip: 0.03}
  range_deg: {mcp: [-5, 10], pip: [0, 25]}
)";

sim::SeaPlantConfig plantConfig(sim::SeaUserMotion motion, uint32_t seed) {
  sim::SeaPlantConfig c;
  c.variant = sim::SeaVariant::kFinger;
  c.motion = motion;
  c.seed = seed;
  c.noise = true;
  return c;
}

}  // namespace

TEST(TherapySea, ProfilesForTheExoskeletonAreValidatedAgainstItsLimits) {
  Profile p;
  EXPECT_EQ(loadProfileText(kProfile, "sea.yaml", p), "");
  EXPECT_EQ(p.limits.channel_count, 2u);
  EXPECT_NEAR(p.limits.effort_max[1], 0.03, 1e-12);
  Profile q;
  // Above the device's 0.3 N·m finger torque: refused, naming the key.
  const std::string err = loadProfileText("version: 1\npatient: x\ndevice: sea_finger\nlimits: {effort_max: 0.5}\n",
                                          "bad.yaml", q);
  EXPECT_NE(err.find("effort_max"), std::string::npos) << err;
  // Glove joint names do not exist on the exoskeleton.
  EXPECT_NE(loadProfileText("version: 1\npatient: x\ndevice: sea_finger\nlimits: {effort_max: 0.1, range_deg: "
                            "{index_mcp: [0, 10]}}\n",
                            "bad.yaml", q),
            "");
  // Segment lengths are the glove's; the SEA's subject parameters come from sea-calibrate.
  EXPECT_NE(loadProfileText("version: 1\npatient: x\ndevice: sea_finger\nkinematics: {index: {p1_mm: 40, p2_mm: 25, "
                            "p3_mm: 20}}\nlimits: {effort_max: 0.1}\n",
                            "bad.yaml", q),
            "");
}

// Random therapist commands (exercise switches with random parameters, run-time limit reductions) on a randomly
// moving finger: the finger torque commanded through J_nᵀ never exceeds the profile's per-joint limit, the
// exoskeleton torque never the adapter's 0.5 N·m, and no joint beyond its allowed range is pushed further out.
TEST(TherapySea, RandomTherapistCommandsNeverExceedTheProfileLimits) {
  Profile profile;
  ASSERT_EQ(loadProfileText(kProfile, "sea.yaml", profile), "");
  std::string err;
  auto device = SeaTherapyDevice::make({}, err);
  ASSERT_TRUE(device) << err;
  auto checker = SeaTherapyDevice::make({}, err);  // independent observer of the same telemetry
  auto pattern = std::make_shared<Pattern>(2);
  auto initial = makeExercise("assessment", nullptr, *device, profile, pattern, err);
  ASSERT_TRUE(initial) << err;
  TherapyController controller(std::move(device), profile.limits, std::move(initial), nullptr);

  fw_sim::SeaFingerSimDevice sim_device(plantConfig(sim::SeaUserMotion::kRandom, 5));
  host::LockstepRig rig(sim_device, controller);
  ASSERT_EQ(rig.handshake(), "");

  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const char* names[] = {"assessment", "resistance", "assistance", "record-pattern", "playback", "idle"};
  PatientLimits in_force = profile.limits, pending = in_force;
  bool limits_pending = false;
  int commands = 0, refused = 0;
  long cycles = 0, effort_violations = 0, exo_violations = 0, range_checks = 0, range_violations = 0, driven = 0;
  double max_ratio = 0.0, max_exo = 0.0;
  double next_command_s = rig.timeS() + 0.5;
  const double end_s = rig.timeS() + 25.0;
  Observation obs{};
  while (rig.timeS() < end_s) {
    if (rig.timeS() >= next_command_s) {
      next_command_s += 0.3 + 1.2 * u(rng);
      ++commands;
      if (u(rng) < 0.25) {
        pending = controller.limits();
        const size_t c = static_cast<size_t>(rng() % 2);
        pending.effort_max[c] = profile.limits.effort_max[c] * (0.2 + 0.8 * u(rng));
        controller.offerLimits(pending);
        limits_pending = true;
      } else {
        const std::string name = names[rng() % 6];
        nlohmann::json params = nlohmann::json::object();
        // Up to the parameters' maxima (2·E per rad), far stiffer than the limits allow.
        if (name == "resistance") {
          params = {{"stiffness_per_rad", 0.6 * u(rng)}, {"damping_s_per_rad", 0.15 * u(rng)}, {"rest_deg", 40.0 * u(rng)}};
        } else if (name == "assistance" || name == "playback") {
          params = {{"stiffness_per_rad", 0.6 * u(rng)}, {"deadband_deg", 10.0 * u(rng)}, {"learning_per_rad_s", 5.0 * u(rng)}};
        }
        auto ex = makeExercise(name, params, controller.device(), profile, pattern, err);
        if (ex) controller.offerExercise(std::move(ex));
        else ++refused;
      }
      controller.collectRetired();
    }
    rig.step();
    const auto& tel = rig.session().latest();
    const auto& cmd = rig.lastCommand();
    if (limits_pending) {
      in_force = pending;
      limits_pending = false;
    }
    checker->observe(tel, obs);
    ++cycles;
    const host::sea::Vec2 tau_j{cmd.setpoint[0], cmd.setpoint[1]};
    for (size_t i = 0; i < 2; ++i) {
      max_exo = std::max(max_exo, std::fabs(tau_j[i]));
      if (std::fabs(tau_j[i]) > SeaTherapyDevice::kExoTorqueLimit_Nm + 1e-6) ++exo_violations;
    }
    if (cmd.mode != protocol::Mode::kSetpoint) continue;
    ++driven;
    // The finger torque this command applies: τ_f = J_n^{-T} τ_j,d (eq 9) at the pose it was computed for.
    const auto& d = checker->estimator().data();
    host::sea::Vec2 tau_f{};
    if (!d.J_valid || phalanx::sea::fingerTorqueFromExoTorque(d.J_n, tau_j, 1e-6, tau_f) != phalanx::sea::Status::kOk) {
      continue;
    }
    for (size_t c = 0; c < 2; ++c) {
      // float setpoints: 1e-6 N·m relative slack for the single-precision round trip.
      const double lim = in_force.effort_max[c];
      max_ratio = std::max(max_ratio, std::fabs(tau_f[c]) / lim);
      if (std::fabs(tau_f[c]) > lim * (1.0 + 1e-5) + 1e-7) ++effort_violations;
    }
    for (size_t j = 0; j < 3; ++j) {
      if (!obs.joint_valid[j]) continue;
      const double f = tau_f[j == 0 ? 0 : 1];
      if (obs.flexion_rad[j] > profile.limits.flexion_max_rad[j]) {
        ++range_checks;
        if (f < -1e-7) ++range_violations;  // flexing torque on a joint already beyond its flexion limit
      } else if (obs.flexion_rad[j] < profile.limits.flexion_min_rad[j]) {
        ++range_checks;
        if (f > 1e-7) ++range_violations;
      }
    }
  }
  const auto st = controller.status();
  std::printf("%ld cycles (%ld driven), %d therapist commands (%d refused), max |finger torque|/limit %.4f, max |exo "
              "torque| %.4f N·m, %ld cycles with a joint out of range, %ld limited cycles, faults 0x%x\n",
              cycles, driven, commands, refused, max_ratio, max_exo, range_checks,
              static_cast<long>(st.limited_cycles), rig.session().latest().fault_bits);
  EXPECT_EQ(effort_violations, 0);
  EXPECT_EQ(exo_violations, 0);
  EXPECT_EQ(range_violations, 0);
  // The test has teeth: the limits were reached and the range clamp had work to do.
  EXPECT_GT(max_ratio, 0.99);
  EXPECT_GT(range_checks, 1000);
  EXPECT_GT(driven, 5000);
  EXPECT_GT(commands, 15);
}

// Assessment (transparent) during full flexion–extension of MCP, PIP and DIP (001 §7.2 motion (iii)), recorded
// like a daemon session; the report computes 001 Table 2's Pearson r against the device-free motion (in the
// simulation: the simulated user's own intended trajectory, what motion capture without the device gives).
TEST(TherapySea, AssessmentTransparencyPearsonRInTheReport) {
  const std::string dir = ::testing::TempDir();
  const std::string stem = dir + "/therapy_sea_" + std::to_string(::getpid());
  TherapySessionConfig cfg;
  cfg.record_path = stem + ".phrec";
  cfg.report_path = stem + ".html";
  cfg.transparency_reference = stem + "-reference.csv";
  cfg.exercise = "assessment";
  std::remove(cfg.record_path.c_str());
  TherapySession session(cfg);
  std::string err;
  auto ctl = session.makeController(protocol::kSeaFingerLayout, err);
  ASSERT_TRUE(ctl) << err;
  fw_sim::SeaFingerSimDevice sim_device(plantConfig(sim::SeaUserMotion::kCloseOpen, 3));
  host::LockstepRig rig(sim_device, *ctl);
  ASSERT_EQ(rig.handshake(), "");
  ASSERT_EQ(session.onStart(protocol::kSeaFingerLayout, {{"sim", true}}), "");
  std::ofstream ref(cfg.transparency_reference);
  ref << "# device-free motion: the simulated user's intended MCP/PIP (DIP by the plant's coupling)\n"
         "t_s,mcp_deg,pip_deg,dip_deg\n";
  const double c_dip = sim::SeaPlantParams{}.finger.dip_pip_coupling;
  std::vector<double> true_flex[3], est_flex[3];
  const double end_s = rig.timeS() + 12.0;
  uint64_t ns = 0;
  Observation obs{};
  auto checker = SeaTherapyDevice::make({}, err);
  double sq_effort[2] = {0, 0};
  long n = 0;
  while (rig.timeS() < end_s) {
    rig.step();
    const double t = rig.timeS();
    ns += 1000000;
    session.onCycle(ns, t, rig.session().latest(), rig.lastCommand());
    const auto& f = sim_device.seaPlant().finger();
    char line[160];
    std::snprintf(line, sizeof line, "%.6f,%.5f,%.5f,%.5f\n", t, -f.intent_rad[0] / kDeg, -f.intent_rad[1] / kDeg,
                  -c_dip * f.intent_rad[1] / kDeg);
    ref << line;
    checker->observe(rig.session().latest(), obs);
    if (t > 2.0) {  // after the first close/open cycle
      for (size_t j = 0; j < 3; ++j) {
        true_flex[j].push_back(-f.theta_rad[j]);
        est_flex[j].push_back(obs.flexion_rad[j]);
      }
      for (size_t c = 0; c < 2; ++c) sq_effort[c] += f.applied_Nm[c] * f.applied_Nm[c];
      ++n;
    }
  }
  ref.close();
  session.finish({{"sim", true}});
  const nlohmann::json end = session.endSummary();
  ASSERT_TRUE(end.contains("report") && end["report"].contains("path")) << end.dump(2);

  record::SessionRecord rec;
  ASSERT_EQ(record::readRecord(cfg.record_path, rec), "");
  TransparencyReference reference;
  ASSERT_EQ(loadTransparencyReference(cfg.transparency_reference, reference), "");
  const nlohmann::json m = sessionMetrics(rec, &reference);
  ASSERT_TRUE(m.contains("transparency_r")) << m.dump(2);
  const char* joints[3] = {"mcp", "pip", "dip"};
  for (size_t j = 0; j < 3; ++j) {
    const auto& r = m["transparency_r"][joints[j]];
    ASSERT_TRUE(r["pearson_r"].is_number()) << m["transparency_r"].dump(2);
    const double rom_true = *std::max_element(true_flex[j].begin(), true_flex[j].end()) -
                            *std::min_element(true_flex[j].begin(), true_flex[j].end());
    std::printf("%s: transparency r %.4f (RMS difference %.2f°, %zu samples); estimator vs true angle r %.4f; true "
                "range %.1f°\n",
                joints[j], r["pearson_r"].get<double>(), r["rms_difference_deg"].get<double>(),
                r["samples"].get<std::size_t>(), host::pearson(true_flex[j], est_flex[j]), rom_true / kDeg);
    // 001 Table 2, motion (iii): MCP 0.8937, PIP 0.9852, DIP 0.9892; the simulated device must not be worse.
    const double paper[3] = {0.8937, 0.9852, 0.9892};
    EXPECT_GE(r["pearson_r"].get<double>(), paper[j]) << joints[j];
    EXPECT_GT(rom_true, 15.0 * kDeg) << joints[j];  // the finger really moved
  }
  for (size_t c = 0; c < 2; ++c) {
    std::printf("%s: applied finger torque RMS %.4f N·m (true, assessment)\n", joints[c], std::sqrt(sq_effort[c] / static_cast<double>(n)));
  }
  std::ifstream html(cfg.report_path);
  std::stringstream ss;
  ss << html.rdbuf();
  EXPECT_NE(ss.str().find("Kinematic transparency"), std::string::npos);
  EXPECT_NE(ss.str().find("sea_finger"), std::string::npos);
  std::remove(cfg.record_path.c_str());
  std::remove(cfg.report_path.c_str());
  std::remove(cfg.transparency_reference.c_str());
}

// Resistance pushes towards extension when the finger flexes beyond the rest angle; assistance moves a relaxed
// finger along the close/open target (it assists flexion and extension alike, so its mean is not signed).
TEST(TherapySea, ResistanceResistsAndAssistanceMovesARelaxedFinger) {
  const char* profile_text = R"(version: 1
patient: sea-sim-2
device: sea_finger
rom_deg: {mcp: [0, 50], pip: [0, 60], dip: [0, 40]}
limits:
  effort_max: 0.2
)";
  Profile profile;
  ASSERT_EQ(loadProfileText(profile_text, "sea.yaml", profile), "");
  std::string err;
  auto run = [&](const std::string& exercise, const nlohmann::json& params, sim::SeaUserMotion motion,
                 std::vector<double>* target, std::vector<double>* q, double* mean_effort) {
    auto device = SeaTherapyDevice::make({}, err);
    auto pattern = std::make_shared<Pattern>(2);
    auto ex = makeExercise(exercise, params, *device, profile, pattern, err);
    EXPECT_TRUE(ex) << err;
    TherapyController controller(std::move(device), profile.limits, std::move(ex), nullptr);
    fw_sim::SeaFingerSimDevice sim_device(plantConfig(motion, 9));
    host::LockstepRig rig(sim_device, controller);
    EXPECT_EQ(rig.handshake(), "");
    double sum = 0.0;
    long n = 0;
    std::array<float, record::kMaxAux> aux{};
    const double end_s = rig.timeS() + 10.0;
    while (rig.timeS() < end_s) {
      rig.step();
      if (rig.timeS() < 2.0) continue;
      controller.fillAux(aux);
      sum += static_cast<double>(aux[6]);  // effort_cmd_mcp (auxNames: q×2, target×2, gain×2, effort×2)
      ++n;
      if (target != nullptr) {
        target->push_back(static_cast<double>(aux[2]));
        q->push_back(static_cast<double>(aux[0]));
      }
    }
    EXPECT_EQ(rig.session().latest().fault_bits, 0) << exercise;
    *mean_effort = sum / static_cast<double>(n);
  };
  double mean_res = 0.0, mean_assist = 0.0;
  // Rest at 0°: any flexion is resisted (positive = extension torque).
  run("resistance", {{"stiffness_per_rad", 0.3}, {"rest_deg", 0.0}}, sim::SeaUserMotion::kCloseOpen, nullptr, nullptr,
      &mean_res);
  std::vector<double> tg, q, tg0, q0;
  run("assistance", {{"stiffness_per_rad", 0.4}, {"deadband_deg", 3.0}, {"period_s", 4.0}},
      sim::SeaUserMotion::kRelaxed, &tg, &q, &mean_assist);
  double unused = 0.0;
  run("assistance", {{"stiffness_per_rad", 0.4}, {"deadband_deg", 3.0}, {"period_s", 4.0}, {"gain_initial", 0.0},
                     {"learning_per_rad_s", 0.0}},
      sim::SeaUserMotion::kRelaxed, &tg0, &q0, &unused);
  auto rms = [](const std::vector<double>& a, const std::vector<double>& b) {
    double s = 0.0;
    for (size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(s / static_cast<double>(a.size()));
  };
  const double r = host::pearson(tg, q);
  std::printf("resistance mean MCP finger torque %.4f N·m; assistance mean %.4f N·m, MCP tracking RMS %.1f° "
              "(unassisted %.1f°), r %.3f\n",
              mean_res, mean_assist, rms(tg, q) / kDeg, rms(tg0, q0) / kDeg, r);
  EXPECT_GT(mean_res, 0.005);
  EXPECT_LT(rms(tg, q), 0.8 * rms(tg0, q0));
  EXPECT_GT(r, 0.8);
}

// The adapter's last stage: exoskeleton torque J_nᵀ·τ_f above 0.5 N·m is scaled down with the finger torques by
// one factor (direction kept), and what it reports as commanded is exactly what the setpoints apply (eq 9).
TEST(TherapySea, ExoskeletonTorqueSaturationKeepsTheFingerTorqueDirection) {
  std::string err;
  auto device = SeaTherapyDevice::make({}, err);
  ASSERT_TRUE(device) << err;
  auto observer = SeaTherapyDevice::make({}, err);
  fw_sim::SeaFingerSimDevice sim_device(plantConfig(sim::SeaUserMotion::kCloseOpen, 4));
  host::sea::SeaFingerControllerConfig idle_cfg;
  idle_cfg.mode = host::sea::SeaFingerMode::kTransparent;
  host::sea::SeaFingerController idle(idle_cfg);
  host::LockstepRig rig(sim_device, idle);
  ASSERT_EQ(rig.handshake(), "");
  Observation obs{};
  int saturated = 0, checked = 0;
  for (int k = 0; k < 40; ++k) {
    rig.run(0.1);
    device->observe(rig.session().latest(), obs);
    const auto& d = device->estimator().data();
    if (!d.J_valid) continue;
    for (const auto& y : {std::array<double, 2>{3.0, 3.0}, std::array<double, 2>{-3.0, 1.0}, std::array<double, 2>{0.01, -0.02}}) {
      std::array<double, kMaxChannels> effort{};
      effort[0] = y[0];
      effort[1] = y[1];
      std::array<float, kMaxChannels> sp{};
      device->commandFromEffort(effort, sp);
      ++checked;
      EXPECT_LE(std::fabs(sp[0]), SeaTherapyDevice::kExoTorqueLimit_Nm + 1e-6);
      EXPECT_LE(std::fabs(sp[1]), SeaTherapyDevice::kExoTorqueLimit_Nm + 1e-6);
      const double s0 = effort[0] / y[0], s1 = effort[1] / y[1];
      EXPECT_NEAR(s0, s1, 1e-12);  // one factor for both: direction kept
      EXPECT_LE(s0, 1.0 + 1e-12);
      EXPECT_GE(s0, 0.0);
      if (s0 < 1.0) ++saturated;
      host::sea::Vec2 tau_f{};
      ASSERT_EQ(phalanx::sea::fingerTorqueFromExoTorque(d.J_n, host::sea::Vec2{sp[0], sp[1]}, 1e-6, tau_f),
                phalanx::sea::Status::kOk);
      EXPECT_NEAR(tau_f[0], effort[0], 1e-5 * std::max(1.0, std::fabs(effort[0])));
      EXPECT_NEAR(tau_f[1], effort[1], 1e-5 * std::max(1.0, std::fabs(effort[1])));
    }
  }
  EXPECT_GT(checked, 60);
  EXPECT_GE(saturated, checked / 3);  // the 3 N·m requests always saturate
}
