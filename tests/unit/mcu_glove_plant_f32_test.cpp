// The emulated boards' single-precision glove plant (firmware/boards/qemu/glove_plant_f32.cpp: hal/sim's GlovePlant
// compiled with float) against the double-precision GlovePlant every other test uses: same configuration, same
// actuator inputs (duty steps and reversals that drive the motor current through its transients, a grasp, a
// proportional force loop on the strain gauge), noise and calibration errors off so that the sensor counts are
// the plant's physics. The float plant must follow the double plant within a few counts on every channel.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "glove_plant_f32.h"
#include "phalanx/glove/board.h"
#include "phalanx/sim/glove_plant.h"

namespace board = phalanx::glove::board;
namespace sim = phalanx::sim;

/// The float plant's replacement for `throw` (plant_no_throw.h); its configuration here is valid, so never called.
extern "C" [[noreturn]] void phalanx_plant_throw(const char* file, int line) {
  ADD_FAILURE() << "single-precision glove plant rejected its configuration at " << file << ":" << line;
  std::abort();
}

namespace {

struct Diff {
  int hall = 0, strain = 0, current = 0;  ///< worst |counts difference| per kind
  double strain_ss = 0, current_ss = 0;   ///< sums of squared differences
  int samples = 0;
  double strainRms() const { return std::sqrt(strain_ss / samples); }
  double currentRms() const { return std::sqrt(current_ss / samples); }
  double strain_peak_counts = 0, current_peak_counts = 0;  ///< the double plant's excursion, for scale
};

/// Duty of finger f at time t: rest, an opening step, a hard reversal, a slow sine (the firmware's outputs span
/// ±1; the bridge regulates the current at 3 A).
float openLoopDuty(int f, double t) {
  if (t < 0.2) return 0.0f;
  if (t < 0.7) return 0.35f + 0.05f * static_cast<float>(f);
  if (t < 1.2) return -0.6f;
  return static_cast<float>(0.5 * std::sin(2.0 * 3.14159265358979 * 1.5 * (t - 1.2) + 0.3 * f));
}

Diff compare(sim::HandScenario scenario, uint32_t substep_us, bool force_loop, double seconds) {
  sim::GlovePlantConfig cd;
  cd.seed = 7;
  cd.noise = false;
  cd.calibration_errors = false;
  cd.scenario = scenario;
  sim::GlovePlant pd(cd);

  phx_glove_f32::Options of;
  of.seed = 7;
  of.noise = false;
  of.calibration_errors = false;
  of.scenario = static_cast<uint8_t>(scenario);
  of.substep_us = substep_us;
  alignas(phx_glove_f32::kPlantAlign) static unsigned char storage[phx_glove_f32::kPlantBytes];
  void* pf = phx_glove_f32::construct(storage, of);

  sim::SimIo iod;
  phx_glove_f32::Io iof;
  iod.pwm_enabled = iod.drive_enable = true;
  iof.pwm_enabled = iof.drive_enable = true;
  Diff d;
  const int steps = static_cast<int>(seconds * 1000.0);
  for (int k = 0; k < steps; ++k) {
    const double t = k * 1e-3;
    for (int f = 0; f < board::kFingerCount; ++f) {
      float duty = openLoopDuty(f, t);
      if (force_loop) {
        // Proportional force loop on each plant's own strain reading (0.5 N target: a light virtual contact).
        const float kp = 0.15f;
        const float fd = board::strainCountsToForce_N(iod.adc[static_cast<size_t>(board::strainAdcChannel(f))]);
        duty = std::clamp(kp * (0.5f - fd), -1.0f, 1.0f);
        const float ff = board::strainCountsToForce_N(iof.adc[board::strainAdcChannel(f)]);
        iof.pwm_duty[board::motorPwmChannel(f)] = std::clamp(kp * (0.5f - ff), -1.0f, 1.0f);
      } else {
        iof.pwm_duty[board::motorPwmChannel(f)] = duty;
      }
      iod.pwm_duty[static_cast<size_t>(board::motorPwmChannel(f))] = duty;
    }
    pd.step(1e-3, iod);
    phx_glove_f32::step(pf, 1e-3f, iof);
    for (int f = 0; f < board::kFingerCount; ++f) {
      for (int j = 0; j < board::kJointsPerFinger; ++j) {
        const int c = board::hallAdcChannel(f, j);
        d.hall = std::max(d.hall, std::abs(iod.adc[static_cast<size_t>(c)] - iof.adc[c]));
      }
      const int s = board::strainAdcChannel(f), i = board::currentAdcChannel(f);
      const int ds = iod.adc[static_cast<size_t>(s)] - iof.adc[s], di = iod.adc[static_cast<size_t>(i)] - iof.adc[i];
      d.strain = std::max(d.strain, std::abs(ds));
      d.current = std::max(d.current, std::abs(di));
      d.strain_ss += static_cast<double>(ds) * ds;
      d.current_ss += static_cast<double>(di) * di;
      ++d.samples;
      d.strain_peak_counts =
          std::max(d.strain_peak_counts, std::fabs(static_cast<double>(iod.adc[static_cast<size_t>(s)] - board::kStrainZeroCounts)));
      d.current_peak_counts =
          std::max(d.current_peak_counts, std::fabs(static_cast<double>(iod.adc[static_cast<size_t>(i)] - board::kCurrentZeroCounts)));
    }
  }
  return d;
}

void report(const char* what, const Diff& d) {
  std::printf("%s: |float - double| worst hall %d, strain %d (rms %.2f, peak %.0f), current %d (rms %.2f, peak %.0f)"
              " counts\n", what, d.hall, d.strain, d.strainRms(), d.strain_peak_counts, d.current, d.currentRms(),
              d.current_peak_counts);
}

}  // namespace

/// Agreement required of the float plant (counts): Hall 4 (0.1–0.2° of joint angle), strain worst 30 (0.32 N, at
/// a stick/slip or contact transition that the float plant reaches one substep apart) and rms 2, current worst 15
/// (30 mA against the firmware's 2.5 A limit) and rms 5.
bool faithful(const Diff& d) {
  return d.hall <= 4 && d.strain <= 30 && d.strainRms() <= 2.0 && d.current <= 15 && d.currentRms() <= 5.0;
}

TEST(McuGlovePlantF32, FollowsTheDoublePlantOpenLoopThroughCurrentTransients) {
  for (sim::HandScenario s : {sim::HandScenario::kGrasp, sim::HandScenario::kCloseOpen, sim::HandScenario::kStill}) {
    const Diff d = compare(s, 0, false, 3.0);
    report("open loop", d);
    EXPECT_GT(d.current_peak_counts, 500.0);  // the inputs do drive the current (> 1 A)
    EXPECT_GT(d.strain_peak_counts, 500.0);   // and the pad force (> 5 N)
    EXPECT_TRUE(faithful(d)) << static_cast<int>(s);
  }
}

TEST(McuGlovePlantF32, FollowsTheDoublePlantInAForceLoop) {
  const Diff d = compare(sim::HandScenario::kGrasp, 0, true, 3.0);
  report("force loop, grasp", d);
  EXPECT_GT(d.strain_peak_counts, 40.0);
  EXPECT_TRUE(faithful(d));
}

TEST(McuGlovePlantF32, TheAgreementCheckRejectsACoarserIntegration) {
  // The same float plant with a 500 µs substep (5× the plant's default) is measurably off the double plant: the
  // thresholds above are tight enough to tell a faithful model from a cheaper one.
  const Diff d = compare(sim::HandScenario::kGrasp, 500, false, 3.0);
  report("open loop, grasp, float substep 500 us", d);
  EXPECT_FALSE(faithful(d));
}
