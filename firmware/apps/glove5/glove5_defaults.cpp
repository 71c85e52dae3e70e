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

    // Spool feed-forward: keep the tendon length constant as the finger moves. Tendon travel Σ r_i α̇_i at the
    // spool radius, through the gearbox, as back-EMF voltage over the supply (duty > 0 winds the release
    // tendon and opens the mechanism, board.h).
    glove::Vec3<float> r_m{};
    const auto model = glove::defaultModel<float>(static_cast<glove::FingerId>(f));
    if (glove::tendonMomentArms(model, glove::TendonDesign<float>{}, r_m)) {
      const float duty_per_m_per_s =
          board::kGearRatio * board::kMotorTorqueConstant_Nm_per_A / (board::kSpoolRadius_m * board::kSupply_V);
      for (int j = 0; j < kGloveJoints; ++j) c.ff_duty_per_rad_per_s[f][j] = duty_per_m_per_s * r_m[static_cast<size_t>(j)];
    }
  }
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
  c.force_pid.kp = 0.08f;
  c.force_pid.ki = 2.0f;
  c.force_pid.kd = 0.0f;
  c.force_pid.d_cutoff_hz = 100.0f;
  c.force_pid.i_limit = 0.3f;
  c.max_duty = 0.9f;
  c.current_limit_A = 2.5f;  // below the bridge's 3 A regulation (board.h)
  c.current_limit_ticks = 200;
  c.active_force_limit_N = board::kMaxActiveForce_N;
  c.strain_full_scale_N = board::kStrainFullScale_N;
  // 000 Table 3 mechanism ranges: α1 [−79.9, 60.0]°, α2 [−127.8, −58.3]°, α3 [−82.3, 81.6]°, with 15° margin
  // (each span stays ≤ 150° + margins, eq 22).
  const float deg = 3.14159265f / 180.0f;
  c.joint_min_rad[0] = -95.0f * deg;
  c.joint_max_rad[0] = 75.0f * deg;
  c.joint_min_rad[1] = -143.0f * deg;
  c.joint_max_rad[1] = -43.0f * deg;
  c.joint_min_rad[2] = -97.0f * deg;
  c.joint_max_rad[2] = 97.0f * deg;
  return c;
}

}  // namespace phalanx::apps
