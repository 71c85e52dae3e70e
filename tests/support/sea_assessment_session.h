#pragma once
// The simulated SEA-finger patient and the instrumented-assessment session protocol shared by the assessment
// tests (tests/sim/therapy_assessment_test.cpp) and the progress/FHIR test (tests/integration/
// therapy_progress_test.cpp): the sea_finger firmware app and the SEA plant (finger variant, sensor noise on, a
// stretch reflex and a maximal voluntary effort configured as the simulated patient) in lockstep with the therapy
// session (record → report metrics). docs/therapy.md "Instrumented assessments".
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

#include "phalanx/fw_sim/sea_finger_sim.h"
#include "phalanx/host/lockstep.h"
#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/report.h"
#include "phalanx/host/therapy/therapy_session.h"

namespace phalanx::test::sea_assessment {

using namespace phalanx::host::therapy;

constexpr double kDeg = M_PI / 180.0;

/// The simulated patient: what differs between patients of the cohort.
struct Patient {
  double gain = 0.05;          // reflex G, N·m·s/rad (MCP)
  double threshold = 60.0;     // v_th, deg/s
  double catch_deg = 20.0;     // φ_catch, flexion
  double mvc_mcp = 0.12, mvc_pip = 0.06;  // N·m: a weak (paretic) finger, within what the device can hold
  double passive_scale = 1.0;  // eq 14 A and C scaled
};

// Session protocol (seconds after the handshake): passive-rom, tardieu, transparent rest, max-force.
constexpr double kPassiveS = 5.0, kTardieuS = 20.0, kRestS = 2.0, kForceS = 4.0, kEffortDelayS = 0.5;
constexpr double kPassiveEffort_Nm = 0.08;

inline sim::SeaPlantConfig plantFor(const Patient& p, uint32_t seed, double donning_sd_rad, double force_start_s) {
  sim::SeaPlantConfig c;
  c.variant = sim::SeaVariant::kFinger;
  c.motion = sim::SeaUserMotion::kRelaxed;
  c.seed = seed;
  c.noise = true;
  auto& f = c.params.finger;
  f.reflex_gain_Nm_s_per_rad = {p.gain, 0.0};  // the MCP is the joint stretched
  f.reflex_threshold_rad_s = {p.threshold * kDeg, 1.0};
  f.reflex_catch_flexion_rad = {p.catch_deg * kDeg, 0.5};
  f.max_voluntary_Nm = {p.mvc_mcp, p.mvc_pip};
  f.max_effort_start_s = force_start_s;
  f.max_effort_duration_s = kForceS - kEffortDelayS - 0.5;
  for (size_t j = 0; j < 2; ++j) f.A_Nm[j] *= p.passive_scale, f.C_Nm[j] *= p.passive_scale;
  c.params.donning_offset_sd_rad = donning_sd_rad;
  return c;
}

struct SessionRun {
  nlohmann::json metrics;
  std::array<double, 2> true_ext{}, true_flex{};  // plant's true MCP/PIP flexion at the end of each passive hold
  std::string record;
};

/// Called before every lockstep step with the time since the first cycle: fault injection (the rig's
/// setHostConnected, session().sendClearFaults()).
using SessionHook = std::function<void(double t_s, host::LockstepRig& rig)>;

/// One session of the protocol above; the record is `<stem>.phrec` (overwritten), of `patient_id`'s profile when
/// given (else anonymous).
inline SessionRun runSession(const Patient& p, uint32_t seed, double donning_sd_rad, const std::string& stem,
                             const std::string& patient_id = "", const SessionHook& hook = nullptr) {
  SessionRun out;
  TherapySessionConfig cfg;
  if (!patient_id.empty()) {
    const std::string text = "version: 1\npatient: " + patient_id + "\ndevice: sea_finger\nlimits: {effort_max: 0.3}\n";
    cfg.have_profile = loadProfileText(text, patient_id + ".yaml", cfg.profile).empty();
    EXPECT_TRUE(cfg.have_profile);
  }
  cfg.record_path = stem + ".phrec";
  cfg.exercise = "passive-rom";
  cfg.exercise_params = {{"effort", kPassiveEffort_Nm}, {"hold_s", 2.0}, {"channel", 0}};  // MCP (the PIP's passive
  // torque is weaker than the exoskeleton's PIP workspace: 0.08 N·m would flex it beyond 80°)
  std::remove(cfg.record_path.c_str());
  TherapySession session(cfg);
  std::string err;
  auto ctl = session.makeController(protocol::kSeaFingerLayout, err);
  EXPECT_TRUE(ctl) << err;
  // The plant's clock starts with the rig's; the handshake takes a few ms of it (printed below).
  const double t_force = kPassiveS + kTardieuS + kRestS;
  fw_sim::SeaFingerSimDevice dev(plantFor(p, seed, donning_sd_rad, t_force + kEffortDelayS));
  host::LockstepRig rig(dev, *ctl);
  EXPECT_EQ(rig.handshake(), "");
  EXPECT_EQ(session.onStart(protocol::kSeaFingerLayout, {{"sim", true}}), "");
  const double t0 = rig.timeS();
  uint64_t ns = 0;
  int stage = 0;
  while (rig.timeS() - t0 < t_force + kForceS) {
    const double t = rig.timeS() - t0;
    if (stage == 0 && t >= kPassiveS) {
      EXPECT_EQ(session.setExercise("tardieu", nlohmann::json::object()), "");
      ++stage;
    } else if (stage == 1 && t >= kPassiveS + kTardieuS) {
      EXPECT_EQ(session.setExercise("assessment", nullptr), "");
      ++stage;
    } else if (stage == 2 && t >= t_force) {
      EXPECT_EQ(session.setExercise("max-force", nlohmann::json::object()), "");
      ++stage;
    }
    if (hook) hook(t, rig);
    rig.step();
    ns += 1000000;
    session.onCycle(ns, rig.timeS(), rig.session().latest(), rig.lastCommand());
    const auto& f = dev.seaPlant().finger();
    const double tt = rig.timeS() - t0;
    for (size_t j = 0; j < 2; ++j) {
      if (tt < 2.0) out.true_ext[j] = -f.theta_rad[j];
      else if (tt < 4.0) out.true_flex[j] = -f.theta_rad[j];
    }
    session.housekeeping();
  }
  session.finish({{"sim", true}});
  host::record::SessionRecord rec;
  EXPECT_EQ(host::record::readRecord(cfg.record_path, rec), "");
  out.metrics = sessionMetrics(rec);
  out.record = cfg.record_path;
  return out;
}

}  // namespace phalanx::test::sea_assessment
