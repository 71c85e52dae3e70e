// Instrumented assessments on the SEA finger in lockstep (docs/therapy.md "Instrumented assessments"): the
// sea_finger firmware app and the SEA plant (finger variant, sensor noise on, a stretch reflex and a maximal
// voluntary effort configured as the simulated patient) with the therapy session (record → report metrics).
// 1. One patient: passive ROM, the Modified Tardieu figures and the maximal voluntary force recover the plant's
//    truth within the tolerances derived in docs/therapy.md.
// 2. A cohort of simulated patients, each in repeated sessions (seeds: noise and donning variation): ICC(2,1)
//    and MDC95 of every figure, printed, written as a repeatability file and shown beside the figures in a report.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "phalanx/host/record/record_reader.h"
#include "phalanx/host/therapy/assessment_analysis.h"
#include "phalanx/host/therapy/profile.h"
#include "phalanx/host/therapy/repeatability.h"
#include "phalanx/host/therapy/report.h"
#include "phalanx/host/therapy/therapy_session.h"

#include "../support/sea_assessment_session.h"

using namespace phalanx;
using namespace phalanx::host::therapy;

namespace {

using namespace phalanx::test::sea_assessment;

/// Flexion (rad) where eq 14 balances an applied finger torque (+ extends): passive(θ) + applied = 0.
double passiveEquilibrium(const sim::SeaPlant& plant, int joint, double applied_Nm) {
  double lo = -1.0, hi = 2.5;  // flexion
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    // passiveTorque_Nm is +θ (extension); more flexion → more extending passive torque.
    (plant.passiveTorque_Nm(joint, -mid) + applied_Nm > 0.0 ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

double figure(const nlohmann::json& m, const std::string& name) {
  for (const auto& [n, v] : assessmentFigures(m)) {
    if (n == name) return v;
  }
  return std::nan("");
}

}  // namespace

// Without spasticity (the plant's default: reflex gain 0) the same protocol reports no catch and no threshold.
TEST(TherapyAssessment, FindsNoReflexInAFingerWithoutOne) {
  Patient p;
  p.gain = 0.0;
  const std::string stem = ::testing::TempDir() + "/assess_none_" + std::to_string(::getpid());
  const SessionRun r = runSession(p, 12, 0.0, stem);
  const auto& t = r.metrics["instrumented"]["tardieu"];
  std::printf("no reflex: %s\n", t.dump().c_str());
  ASSERT_TRUE(t.contains("catch_deg")) << t.dump(1);
  EXPECT_TRUE(t["catch_deg"].is_null());
  EXPECT_TRUE(t["threshold_deg_s"].is_null());
  for (const auto& s : t["stretches"]) EXPECT_TRUE(s["catch_deg"].is_null());
  std::remove(r.record.c_str());
}

TEST(TherapyAssessment, RecoversTheSimulatedFingersTruth) {
  const Patient p;
  const std::string stem = ::testing::TempDir() + "/assess_truth_" + std::to_string(::getpid());
  const SessionRun r = runSession(p, 11, 0.0, stem);
  const nlohmann::json& in = r.metrics["instrumented"];
  std::printf("%s\n", in.dump(1).c_str());
  ASSERT_TRUE(in.contains("tardieu")) << r.metrics.dump(1);
  ASSERT_FALSE(in["tardieu"].contains("error")) << in["tardieu"].dump(1);
  sim::SeaPlant model(plantFor(p, 11, 0.0, -1.0));
  const char* joints[2] = {"mcp", "pip"};
  for (int j = 0; j < 1; ++j) {
    const double ext = passiveEquilibrium(model, j, kPassiveEffort_Nm) / kDeg;
    const double flex = passiveEquilibrium(model, j, -kPassiveEffort_Nm) / kDeg;
    const auto& m = in["passive_rom_deg"][joints[j]];
    std::printf("passive ROM %s: extension %.2f° (plant %.2f°, eq 14 %.2f°), flexion %.2f° (plant %.2f°, eq 14 %.2f°)\n",
                joints[j], m["extension"].get<double>(), r.true_ext[j] / kDeg, ext, m["flexion"].get<double>(),
                r.true_flex[j] / kDeg, flex);
  }
  const auto& t = in["tardieu"];
  std::printf("tardieu: catch %.2f° (truth %.1f°), threshold %.1f°/s (truth %.1f), gain %.4f (truth %.4f)\n",
              t["catch_deg"].get<double>(), p.catch_deg, t["threshold_deg_s"].get<double>(), p.threshold,
              t["gain_per_rad_s"].get<double>(), p.gain);
  std::printf("max force: mcp %.4f (truth %.3f), pip %.4f (truth %.3f)\n", in["max_force"]["mcp"].get<double>(),
              p.mvc_mcp, in["max_force"]["pip"].get<double>(), p.mvc_pip);
  // Tolerances (docs/therapy.md "Instrumented assessments", "Tolerances").
  const auto& mcp = in["passive_rom_deg"]["mcp"];
  EXPECT_NEAR(mcp["extension"].get<double>(), passiveEquilibrium(model, 0, kPassiveEffort_Nm) / kDeg, 1.0);
  EXPECT_NEAR(mcp["flexion"].get<double>(), passiveEquilibrium(model, 0, -kPassiveEffort_Nm) / kDeg, 1.0);
  EXPECT_NEAR(t["catch_deg"].get<double>(), p.catch_deg, 2.0);
  EXPECT_NEAR(t["threshold_deg_s"].get<double>(), p.threshold, 10.0);
  EXPECT_NEAR(t["gain_per_rad_s"].get<double>(), p.gain, 0.2 * p.gain);
  EXPECT_NEAR(in["max_force"]["mcp"].get<double>(), p.mvc_mcp, 0.1 * p.mvc_mcp);
  EXPECT_NEAR(in["max_force"]["pip"].get<double>(), p.mvc_pip, 0.1 * p.mvc_pip);
  // The slowest stretch is below the threshold (the passive reference); the faster ones above it caught.
  const auto& st = t["stretches"];
  ASSERT_EQ(st.size(), 4u);
  EXPECT_TRUE(st[0]["catch_deg"].is_null());
  for (size_t i = 1; i < st.size(); ++i) {
    if (st[i]["velocity_deg_s"].get<double>() > p.threshold + 10.0) {
      EXPECT_TRUE(st[i]["catch_deg"].is_number()) << i;
    }
  }
  std::remove(r.record.c_str());
}

// A cohort of simulated patients (different reflex, catch angle, strength and passive stiffness), each in three
// sessions with different seeds (sensor noise, and a donning offset of every joint sensor drawn with σ = 1°):
// ICC(2,1) and MDC95 for every figure. The reflex figures, the passive ROM and the maximal force must be
// repeatable as instrumented assessments are in the literature (ICC > 0.9; J NeuroEng Rehabil 2019,
// doi 10.1186/s12984-019-0634-5). The repeatability file then puts them beside the figures in a report.
TEST(TherapyAssessment, RepeatabilityOfEveryFigureAcrossSessions) {
  const std::vector<Patient> cohort = {
      {0.03, 45.0, 15.0, 0.08, 0.04, 0.8}, {0.05, 60.0, 20.0, 0.12, 0.06, 1.0}, {0.07, 80.0, 28.0, 0.10, 0.05, 1.2},
      {0.04, 70.0, 24.0, 0.14, 0.07, 0.9}, {0.06, 50.0, 32.0, 0.09, 0.05, 1.1}};
  constexpr int kSessions = 3;
  const double donning_sd = 1.0 * kDeg;
  const std::string stem = ::testing::TempDir() + "/assess_rep_" + std::to_string(::getpid());
  std::vector<std::string> records;
  for (size_t i = 0; i < cohort.size(); ++i) {
    for (int k = 0; k < kSessions; ++k) {
      const SessionRun r = runSession(cohort[i], static_cast<uint32_t>(100 + 10 * i + k), donning_sd,
                                      stem + "-" + std::to_string(i) + "-" + std::to_string(k), "sim-" + std::to_string(i));
      records.push_back(r.record);
      std::printf("patient %zu session %d: passive MCP %.2f…%.2f°, catch %.2f°, v_th %.1f°/s, G %.4f, MVF mcp %.4f\n", i, k,
                  figure(r.metrics, "passive_rom.mcp.extension_deg"), figure(r.metrics, "passive_rom.mcp.flexion_deg"),
                  figure(r.metrics, "tardieu.catch_deg"), figure(r.metrics, "tardieu.threshold_deg_s"),
                  figure(r.metrics, "tardieu.gain_per_rad_s"), figure(r.metrics, "max_force.mcp"));
    }
  }
  // The records, grouped by the patient in their headers (phalanx record repeatability).
  const std::string rep_path = stem + "-repeatability.json", html = stem + ".html";
  nlohmann::json rep;
  ASSERT_EQ(writeRepeatability(records, rep_path, rep), "");
  EXPECT_EQ(rep["source"], "5 patients x 3 sessions");
  nlohmann::json back;
  ASSERT_EQ(loadRepeatability(rep_path, back), "");
  std::printf("%-36s %8s %8s %8s\n", "figure", "ICC(2,1)", "SEM", "MDC95");
  for (const auto& [name, v] : rep["figures"].items()) {
    std::printf("%-36s %8.3f %8.4f %8.4f\n", name.c_str(), v["icc"].get<double>(), v["sem"].get<double>(),
                v["mdc95"].get<double>());
  }
  // Measured, not required: the torque-defined passive flexion end (0.08 N·m) lies where eq 14 is flat
  // (0.28 N·m/rad at 52°), so the few mN·m by which a donning offset changes the finger torque J_nᵀ applies move
  // it by several degrees (ICC 0.08, MDC95 12.4° here; docs/therapy.md). The active ROM of the short transparent
  // rest is no designed measurement either.
  ASSERT_TRUE(rep["figures"].contains("passive_rom.mcp.flexion_deg"));
  for (const char* name : {"tardieu.catch_deg", "tardieu.threshold_deg_s", "tardieu.gain_per_rad_s",
                           "tardieu.reflex_at_150_deg_s", "tardieu.reflex_at_210_deg_s",
                           "passive_rom.mcp.extension_deg", "max_force.mcp", "max_force.pip"}) {
    ASSERT_TRUE(rep["figures"].contains(name)) << name << " missing: " << rep.dump(1);
    EXPECT_GT(rep["figures"][name]["icc"].get<double>(), 0.9) << name;
    EXPECT_GT(rep["figures"][name]["mdc95"].get<double>(), 0.0) << name;  // noise and donning are there
  }
  // The report shows each figure with its ICC and MDC95.
  ASSERT_EQ(writeReport(records[3], "", html, nullptr, "", rep_path), "");
  std::stringstream ss;
  ss << std::ifstream(html).rdbuf();
  const std::string page = ss.str();
  EXPECT_NE(page.find("Assessment figures and their repeatability"), std::string::npos);
  char cell[64];
  std::snprintf(cell, sizeof cell, "<td>%.3f</td>", rep["figures"]["tardieu.catch_deg"]["icc"].get<double>());
  EXPECT_NE(page.find("<td>tardieu.catch_deg</td>"), std::string::npos);
  EXPECT_NE(page.find(cell), std::string::npos) << cell;
  // Unequal numbers of sessions are refused, naming the patients.
  nlohmann::json unused;
  const std::string uneven = writeRepeatability({records[0], records[1], records[3]}, rep_path, unused);
  EXPECT_NE(uneven.find("same number of sessions"), std::string::npos) << uneven;
  for (const std::string& f : records) std::remove(f.c_str());
  for (const std::string& f : {rep_path, html}) std::remove(f.c_str());
}
