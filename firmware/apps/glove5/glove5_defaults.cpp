// Default calibration and configuration of the glove5 app: the board's nominal transfers (glove/board.h) and
// the tendon routing (glove/tendon.h). A calibrated board overrides these from its stored calibration.
#include "phalanx/apps/glove5.h"
#include "phalanx/glove/board.h"
#include "phalanx/glove/tendon.h"

namespace phalanx::apps {

namespace board = glove::board;

Glove5Calibration glove5DefaultCalibration() {
  Glove5Calibration c;
  for (int f = 0; f < kGloveFingers; ++f) {
    for (int j = 0; j < kGloveJoints; ++j) {
      HallTable& t = c.hall[board::hallAdcChannel(f, j)];
      t.points = board::kHallTablePoints;
      for (int i = 0; i < board::kHallTablePoints; ++i) {
        t.counts[i] = static_cast<float>(board::kHallTableCounts[static_cast<size_t>(i)]);
        t.angle_rad[i] = board::hallTableAngle_rad(j, i);
      }
    }
    c.strain_counts_per_N[f] = board::kStrainCountsPerNewton;
    c.strain_zero_counts[f] = static_cast<float>(board::kStrainZeroCounts);

    // Tendon transmission r(α) needs the mechanism geometry (duty > 0 winds the release tendon and opens the
    // mechanism, board.h, so a positive r·α̇ needs a positive tendon velocity).
    c.mech[f] = glove::defaultModel<float>(static_cast<glove::FingerId>(f)).mech;
  }
  c.pad_transmission = glove::TendonDesign<float>{}.pad_transmission;
  c.motor_rad_per_tendon_m = board::kGearRatio / board::kSpoolRadius_m;
  // K_e = K_t in SI units for a DC motor.
  c.duty_per_motor_rad_per_s = board::kMotorTorqueConstant_Nm_per_A / board::kSupply_V;
  c.duty_per_A = (board::kMotorResistance_Ohm + board::kBridgeOnResistance_Ohm) / board::kSupply_V;
  c.hall_valid_min = board::kHallPlausibleMinCounts;
  c.hall_valid_max = board::kHallPlausibleMaxCounts;
  c.strain_saturation_min = board::kStrainMinCounts;
  c.strain_saturation_max = board::kStrainMaxCounts;
  c.current_counts_per_A = board::kCurrentCountsPerAmp;
  c.current_zero_counts = static_cast<float>(board::kCurrentZeroCounts);
  c.force_per_duty_sign = 1.0f;  // board.h: positive duty → positive pad force
  return c;
}

Glove5Config glove5DefaultConfig() {
  Glove5Config c;
  // Gains in (m/s of tendon) per N of force error, chosen in the lockstep benches (`phalanx bench glove-free-motion`
  // and `glove-grasp`, with sensor noise and drift; sweep in docs/glove-firmware.md): kp = 2 is at the minimum
  // of the free-motion peak (0.036-0.047 N true over seeds 1-15; 2.25 within 2 mN of it, 2.5 and more higher): more
  // gain turns gauge noise into force. In contact the
  // host scales the gain down by the rendered stiffness (GloveControllerConfig::contact_gain_ref_N_per_m). The
  // feed-forward carries the finger's motion, the P term the residual.
  // No integral term: the self-locking worm already integrates (duty sets spool speed), and an integrator
  // limit-cycles against the worm's dead band (glove-plant.md).
  c.force_pid.kp = 2.0f;
  c.force_pid.ki = 0.0f;
  c.force_pid.kd = 0.0f;
  c.force_pid.d_cutoff_hz = 100.0f;
  c.force_pid.out_min = -1.0f;  // m/s: must be able to cancel the feed-forward of the fastest finger motion
  c.force_pid.out_max = 1.0f;
  c.force_pid.i_limit = 0.0f;
  c.ir_compensation = 0.6f;
  c.force_filter_hz = 100.0f;
  c.velocity_filter_hz = 20.0f;
  c.max_duty = 1.0f;  // transients only: the bridge's current regulation protects the motor (board.h)
  c.current_limit_A = 2.5f;  // below the bridge's 3 A regulation (board.h)
  c.current_limit_ticks = 200;
  c.active_force_limit_N = board::kMaxActiveForce_N;
  c.strain_full_scale_N = board::kStrainFullScale_N;
  // The mechanism's joint range over the finger's whole Table 2 range (kinematics.h model; 000 Table 3 for the
  // index), widened by 15° of margin: the simulated hand pushes slightly past Table 2 when squeezing.
  const float margin_rad = 15.0f * 3.14159265f / 180.0f;
  for (int f = 0; f < kGloveFingers; ++f) {
    const auto model = glove::defaultModel<float>(static_cast<glove::FingerId>(f));
    for (int j = 0; j < kGloveJoints; ++j) {
      c.joint_min_rad[f][j] = model.mech.alpha_min_rad[static_cast<size_t>(j)] - margin_rad;
      c.joint_max_rad[f][j] = model.mech.alpha_max_rad[static_cast<size_t>(j)] + margin_rad;
    }
  }
  return c;
}

}  // namespace phalanx::apps
