// SEA finger exoskeleton subject parameter estimation (eq 12): recovery from synthetic redundant-sensor data,
// CSV and YAML round trips (phalanx/host/sea/sea_calibrate.h).
#include "phalanx/host/sea/sea_calibrate.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

namespace {

using namespace phalanx::host::sea;
namespace ps = phalanx::sea;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

/// A range-of-motion recording on the subject `truth` (default 4 s at 500 Hz): MCP and PIP finger sines at
/// different frequencies so (θ1r, θ6r) cover the workspace; sensor noise σ (rad) and the wire's 1e-4 rad
/// quantisation.
std::vector<CalibrationSample> recording(const ps::Model<double>& truth, double noise_rad, unsigned seed,
                                         int rows = 2000, double dt_s = 0.002) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, noise_rad);
  std::vector<CalibrationSample> out;
  for (int k = 0; k < rows; ++k) {
    const double t = k * dt_s;
    const double mcp = -30 * kDeg + 28 * kDeg * std::sin(2 * M_PI * 0.5 * t);
    const double pip = -40 * kDeg + 38 * kDeg * std::sin(2 * M_PI * 0.8 * t + 1.0);
    ps::Data<double> d;
    if (!ps::isUsable(ps::computeFromFinger(truth, ps::FingerAngles<double>{mcp, pip, -20 * kDeg, 0.0}, d))) continue;
    auto q = [&](double v) { return std::round((v + n(rng)) / 1e-4) * 1e-4; };
    out.push_back({q(d.sensors_rad[ps::kSensorExoMcp]), q(d.sensors_rad[ps::kSensorExoPip]),
                   q(d.sensors_rad[ps::kSensorRedundant])});
  }
  return out;
}

/// Rows of recording() (1 kHz) in which the true mechanism is on the other assembly branch of the PIP chain than
/// the model's (it passed through the dead point F–H–C collinear) or cannot assemble: no P reproduces those rows.
/// A property of the synthetic data, printed by the sweeps next to the fit (the estimator never sees the truth).
int otherBranchRows(const ps::Model<double>& truth, int rows) {
  int n = 0;
  for (int k = 0; k < rows; ++k) {
    const double t = k * 0.001;
    const double mcp = -30 * kDeg + 28 * kDeg * std::sin(2 * M_PI * 0.5 * t);
    const double pip = -40 * kDeg + 38 * kDeg * std::sin(2 * M_PI * 0.8 * t + 1.0);
    ps::Data<double> d;
    ps::Data<double> e;
    if (!ps::isUsable(ps::computeFromFinger(truth, ps::FingerAngles<double>{mcp, pip, -20 * kDeg, 0.0}, d))) {
      ++n;
      continue;
    }
    ps::computeFromSensors(truth, d.sensors_rad, e);
    n += std::fabs(e.theta8_rad - d.theta8_rad) + std::fabs(e.theta4_rad - d.theta4_rad) > 1e-6 ? 1 : 0;
  }
  return n;
}

/// The recommended sweep's recording length in rows at 1 kHz: SEA_SWEEP_SECONDS (default: the recommended 60 s).
int sweepRows(int default_rows) {
  const char* env = std::getenv("SEA_SWEEP_SECONDS");
  const double s = env != nullptr ? std::atof(env) : 0.0;
  return s > 0.0 ? static_cast<int>(s * 1000.0) : default_rows;
}

/// The sweeps' subject seed: SEA_SWEEP_SEED (default 42, the subjects of docs/sea-model.md's first table). Another
/// seed draws another set of subjects (and other noise), to check that the procedure is not tuned to one set.
unsigned sweepSeed() {
  const char* env = std::getenv("SEA_SWEEP_SEED");
  return env != nullptr && *env != '\0' ? static_cast<unsigned>(std::strtoul(env, nullptr, 10)) : 42u;
}

/// Noise seed of trial k: 100 + k for the default set (as before), offset by 1000·seed for another set.
unsigned sweepNoiseSeed(int trial) {
  const unsigned seed = sweepSeed();
  return 100u + static_cast<unsigned>(trial) + (seed == 42u ? 0u : 1000u * seed);
}

/// The largest |estimate − truth| over the seven subject parameters (m).
double worstParamError(const SubjectParams& estimate, const SubjectParams& truth) {
  const auto pe = ps::toArray(estimate);
  const auto pt = ps::toArray(truth);
  double w = 0.0;
  for (std::size_t i = 0; i < pe.size(); ++i) w = std::fmax(w, std::fabs(pe[i] - pt[i]));
  return w;
}

/// A random subject uniform in the inner 80 % of the Table 4 box.
ps::Model<double> randomSubject(std::mt19937& rng) {
  const auto lo = ps::toArray(ps::table4Lower<double>());
  const auto hi = ps::toArray(ps::table4Upper<double>());
  std::array<double, 7> p{};
  for (std::size_t i = 0; i < 7; ++i) {
    std::uniform_real_distribution<double> u(lo[i] + 0.1 * (hi[i] - lo[i]), hi[i] - 0.1 * (hi[i] - lo[i]));
    p[i] = u(rng);
  }
  ps::Model<double> m = ps::defaultModel<double>();
  m.subject = ps::fromArray(p);
  return m;
}

/// The sweeps' subject filter: SEA_SWEEP_SUBJECTS="3,5,9" runs only those trials (all when unset). The subjects
/// are drawn in sequence either way, so subject k is the same subject with or without the filter.
bool sweepWants(int trial) {
  const char* env = std::getenv("SEA_SWEEP_SUBJECTS");
  if (env == nullptr || *env == '\0') return true;
  std::set<int> want;
  std::stringstream ss(env);
  std::string item;
  while (std::getline(ss, item, ',')) want.insert(std::atoi(item.c_str()));
  return want.count(trial) > 0;
}

ps::Model<double> perturbedSubject(double scale) {
  ps::Model<double> m = ps::defaultModel<double>();
  // A different hand than the paper's subject, inside the Table 4 caliper range.
  const double dp[7] = {0.004, 0.003, 0.003, -0.005, 0.004, -0.004, -0.005};
  auto p = ps::toArray(m.subject);
  for (std::size_t i = 0; i < 7; ++i) p[i] += scale * dp[i];
  m.subject = ps::fromArray(p);
  return m;
}

}  // namespace

TEST(SeaCalibrate, RecoversAPerturbedSubjectFromNoisyDataToTheNoiseFloor) {
  // Tolerances (docs/sea-model.md §Parameter estimation): 1 mm is the caliper tolerance of a joint-axis location.
  // l_CD, l_FG, l_GH are well determined (Cramér–Rao σ < 0.1 mm) and must be within 0.3 mm; l_AH within 1 mm;
  // x_A, y_A, l_BC lie along eq 12's weakly observable direction (σ ≈ 0.5–1.5 mm at this noise and length) and
  // are only required within 3 mm. On this subject and seed all seven come out within 1 mm, which is not true
  // for every subject (see the DISABLED_ sweep below).
  const ps::Model<double> truth = perturbedSubject(1.0);
  const auto lo = ps::toArray(ps::table4Lower<double>());
  const auto hi = ps::toArray(ps::table4Upper<double>());
  const auto pt = ps::toArray(truth.subject);
  for (std::size_t i = 0; i < 7; ++i) ASSERT_TRUE(pt[i] > lo[i] && pt[i] < hi[i]) << ps::kSubjectParamNames[i];
  const auto samples = recording(truth, 0.05 * kDeg, 3);
  ASSERT_GT(samples.size(), 1900u);
  CalibrationOptions opt;  // P0, LB, UB of Table 4
  opt.restarts = 12;       // fewer than the command's 24: the test must fit the sanitizer lane's time budget
  opt.stride = 2;
  CalibrationResult r;
  ASSERT_EQ(calibrate(samples, opt, r), "");
  const auto pe = ps::toArray(r.estimate);
  const double tol_m[7] = {0.003, 0.003, 0.003, 0.0003, 0.001, 0.0003, 0.0003};
  for (std::size_t i = 0; i < 7; ++i) {
    EXPECT_NEAR(pe[i], pt[i], tol_m[i]) << ps::kSubjectParamNames[i];
  }
  // The global minimum was found: the multistart's objective is no higher than that of a local refinement
  // started at the true parameters, and it is at the sensor noise floor.
  CalibrationOptions local = opt;
  local.initial = truth.subject;
  local.restarts = 0;
  local.valley_steps = 0;
  CalibrationResult from_truth;
  ASSERT_EQ(calibrate(samples, local, from_truth), "");
  EXPECT_LE(r.errors_in_variables_rms_rad, from_truth.errors_in_variables_rms_rad * (1.0 + 1e-6));
  EXPECT_LT(r.errors_in_variables_rms_rad, 0.8 * 0.05 * kDeg);  // floor ≈ σ/√3
  EXPECT_GT(r.fit_to_noise, 0.8);  // the model explains the recording to its (estimated) noise
  EXPECT_LT(r.fit_to_noise, 1.2);
  const double truth_rms = redundantResidualRms(samples, truth.subject, truth.fixed);
  EXPECT_LT(truth_rms, 4 * 0.05 * kDeg);
  EXPECT_GT(r.initial_rms_rad, 10 * r.final_rms_rad);
  EXPECT_EQ(r.samples_used, (samples.size() + 1) / 2);
}

TEST(SeaCalibrate, SmoothingAnOversampledRecordingReducesTheResidualToTheThetaSevenNoise) {
  // 1 kHz recording of a ≤ 0.8 Hz motion, 25-row centred Savitzky–Golay smoothing (opt.smooth_samples): the residual falls
  // from the propagated input noise to below the single-sensor noise, and the parameters stay within tolerance.
  const ps::Model<double> truth = perturbedSubject(1.0);
  std::vector<CalibrationSample> samples;
  {
    std::mt19937 rng(11);
    std::normal_distribution<double> n(0.0, 0.05 * kDeg);
    for (int k = 0; k < 4000; ++k) {
      const double t = k * 0.001;
      const double mcp = -30 * kDeg + 28 * kDeg * std::sin(2 * M_PI * 0.5 * t);
      const double pip = -40 * kDeg + 38 * kDeg * std::sin(2 * M_PI * 0.8 * t + 1.0);
      ps::Data<double> d;
      ASSERT_EQ(ps::computeFromFinger(truth, ps::FingerAngles<double>{mcp, pip, -20 * kDeg, 0.0}, d), ps::Status::kOk);
      samples.push_back({d.sensors_rad[0] + n(rng), d.sensors_rad[1] + n(rng), d.sensors_rad[2] + n(rng)});
    }
  }
  CalibrationOptions opt;
  opt.smooth_samples = 25;
  opt.stride = 8;  // after smoothing over 25 rows, neighbouring rows carry little new information
  opt.restarts = 12;
  CalibrationResult r;
  ASSERT_EQ(calibrate(samples, opt, r), "");
  EXPECT_LT(r.final_rms_rad, 0.05 * kDeg);
  // The noise estimate (the Huber corner's unit): a 25-row quadratic Savitzky–Golay filter keeps √w0 = √0.0874 of
  // the white noise's σ (w0 = 3(3·144+36−1)/(23·25·27), the centre weight).
  EXPECT_NEAR(r.noise_rad, 0.05 * kDeg * std::sqrt(3.0 * (3 * 144 + 36 - 1) / (23.0 * 25 * 27)), 0.05 * 0.05 * kDeg);
  const auto pe = ps::toArray(r.estimate);
  const auto pt = ps::toArray(truth.subject);
  const double tol_m[7] = {0.003, 0.003, 0.003, 0.0003, 0.001, 0.0003, 0.0003};
  for (std::size_t i = 0; i < 7; ++i) EXPECT_NEAR(pe[i], pt[i], tol_m[i]) << ps::kSubjectParamNames[i];
  opt.smooth_samples = 0;
  EXPECT_NE(calibrate(samples, opt, r), "");
}

/// Statistics over random subjects (not run by ctest; minutes):
///   sea_calibrate_test --gtest_also_run_disabled_tests --gtest_filter='*DISABLED_RandomSubjects*'
TEST(SeaCalibrate, DISABLED_RandomSubjectsSweep) {
  std::mt19937 rng(sweepSeed());
  int within_1mm = 0;
  int run = 0;
  const int trials = 12;
  for (int trial = 0; trial < trials; ++trial) {
    const ps::Model<double> truth = randomSubject(rng);
    if (!sweepWants(trial)) continue;
    ++run;
    const auto p = ps::toArray(truth.subject);
    const auto samples = recording(truth, 0.05 * kDeg, sweepNoiseSeed(trial));
    CalibrationOptions opt;
    CalibrationResult r;
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(calibrate(samples, opt, r), "");
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto pe = ps::toArray(r.estimate);
    const double worst = worstParamError(r.estimate, truth.subject);
    std::printf("subject %2d  error mm:", trial);
    for (std::size_t i = 0; i < 7; ++i) std::printf(" %+5.2f", (pe[i] - p[i]) * 1e3);
    // Finger-angle error of the estimator with P̂ over the workspace, on noise-free sensors.
    ps::Model<double> est = truth;
    est.subject = r.estimate;
    double e_mcp = 0.0;
    double e_pip = 0.0;
    for (double a = -60; a <= 0; a += 5) {
      for (double b = -80; b <= 0; b += 5) {
        ps::Data<double> d;
        ps::Data<double> e;
        ps::computeFromFinger(truth, ps::FingerAngles<double>{a * kDeg, b * kDeg, -0.3, 0.0}, d);
        ps::computeFromSensors(est, d.sensors_rad, e);
        e_mcp = std::fmax(e_mcp, std::fabs(e.theta4_rad - d.theta4_rad));
        e_pip = std::fmax(e_pip, std::fabs(e.theta8_rad - d.theta8_rad));
      }
    }
    std::printf(" | worst %.2f mm, finger MCP %.1f° PIP %.1f°, rms %.2e (truth %.2e), eiv %.4e, %.1f s\n",
                worst * 1e3, e_mcp / kDeg, e_pip / kDeg, r.final_rms_rad,
                redundantResidualRms(samples, truth.subject, truth.fixed), r.errors_in_variables_rms_rad, secs);
    within_1mm += worst < 0.001 ? 1 : 0;
  }
  std::printf("%d/%d subjects with all seven parameters within 1 mm\n", within_1mm, run);
}

/// The recommended procedure over the same random subjects (not run by ctest; 4–60 s per subject, minutes):
///   sea_calibrate_test --gtest_also_run_disabled_tests --gtest_filter='*DISABLED_RandomSubjectsRecommended*'
/// 60 s range-of-motion recording at 1 kHz (SEA_SWEEP_SECONDS), 0.05° noise on all three sensors, `--smooth 51
/// --stride 10`; SEA_SWEEP_SEED draws another set of subjects, SEA_SWEEP_ROBUST_SIGMAS overrides the Huber corner
/// (CalibrationOptions::robust_sigmas) for comparisons. Each
/// subject is also fitted from its true parameters ("from truth"): when both fits agree, the remaining error is
/// the data's, not the search's.
TEST(SeaCalibrate, DISABLED_RandomSubjectsRecommendedProcedureSweep) {
  std::mt19937 rng(sweepSeed());
  int within_1mm = 0;
  int run = 0;
  const int trials = 12;
  for (int trial = 0; trial < trials; ++trial) {
    const ps::Model<double> truth = randomSubject(rng);
    if (!sweepWants(trial)) continue;
    ++run;
    const auto p = ps::toArray(truth.subject);
    const auto samples = recording(truth, 0.05 * kDeg, sweepNoiseSeed(trial), sweepRows(60000), 0.001);
    CalibrationOptions opt;
    opt.smooth_samples = 51;
    opt.stride = 10;
    if (const char* k = std::getenv("SEA_SWEEP_ROBUST_SIGMAS"); k != nullptr && *k != '\0') opt.robust_sigmas = std::atof(k);
    if (const char* b = std::getenv("SEA_SWEEP_BOTH_BRANCHES"); b != nullptr && *b != '\0') opt.both_branches = *b == '1';
    CalibrationResult r;
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(calibrate(samples, opt, r), "");
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    CalibrationOptions from_truth = opt;
    from_truth.initial = truth.subject;
    from_truth.restarts = 0;
    from_truth.valley_steps = 0;  // a local refinement from the truth
    CalibrationResult rt;
    ASSERT_EQ(calibrate(samples, from_truth, rt), "");
    auto worstOf = [&](const CalibrationResult& res) { return worstParamError(res.estimate, truth.subject); };
    const auto pe = ps::toArray(r.estimate);
    std::printf("subject %2d  error mm:", trial);
    for (std::size_t i = 0; i < 7; ++i) std::printf(" %+5.2f", (pe[i] - p[i]) * 1e3);
    // eiv: the minimised errors-in-variables objective (RMS rad); lower is a better fit of the data.
    std::printf(" | worst %.2f mm, eiv %.4e, fit/noise %.2f, open chains %zu, %.1f s | from truth: worst %.2f mm, eiv %.4e",
                worstOf(r) * 1e3, r.errors_in_variables_rms_rad, r.fit_to_noise, r.least_squares_samples, secs,
                worstOf(rt) * 1e3, rt.errors_in_variables_rms_rad);
    if (const int other = otherBranchRows(truth, std::min(10000, sweepRows(60000))); other > 0) {
      std::printf(" | recording crosses the PIP dead point: %d of the 10000 rows of one 10 s period on the other branch",
                  other);
    }
    std::printf("\n");
    within_1mm += worstOf(r) < 0.001 ? 1 : 0;
  }
  std::printf("%d/%d subjects with all seven parameters within 1 mm\n", within_1mm, run);
}

TEST(SeaCalibrate, QuantisedNoiseFreeDataRecoversTheParametersToTwoTenthsOfAMillimetre) {
  const ps::Model<double> truth = perturbedSubject(0.6);
  const auto samples = recording(truth, 0.0, 1);
  CalibrationOptions opt;
  opt.stride = 4;
  opt.restarts = 12;
  CalibrationResult r;
  ASSERT_EQ(calibrate(samples, opt, r), "");
  const auto pe = ps::toArray(r.estimate);
  const auto pt = ps::toArray(truth.subject);
  // Only the 1e-4 rad wire quantisation remains: 0.2 mm on the weakest parameter combination.
  for (std::size_t i = 0; i < 7; ++i) EXPECT_NEAR(pe[i], pt[i], 2e-4) << ps::kSubjectParamNames[i];
  EXPECT_LT(r.final_rms_rad, 1e-4);
}

TEST(SeaCalibrate, RejectsTooFewOrNonFiniteSamplesAndBadBounds) {
  CalibrationOptions opt;
  CalibrationResult r;
  std::vector<CalibrationSample> few(10, CalibrationSample{0.0, 1.0, 0.5});
  EXPECT_NE(calibrate(few, opt, r).find("at least 20"), std::string::npos);
  std::vector<CalibrationSample> bad(50, CalibrationSample{0.0, 1.0, 0.5});
  bad[7].theta7r_rad = std::nan("");
  EXPECT_NE(calibrate(bad, opt, r).find("sample 7"), std::string::npos);
  opt.lower.l_BC_m = 0.06;
  EXPECT_NE(calibrate(std::vector<CalibrationSample>(50, CalibrationSample{0.0, 1.0, 0.5}), opt, r).find("l_BC_m"),
            std::string::npos);
}

TEST(SeaCalibrate, ReadsTheRecorderCsvColumnsAndReportsBadCells) {
  const std::string path = ::testing::TempDir() + "sea_cal.csv";
  {
    std::ofstream f(path);
    f << "t_s,device_time_us,seq,cmd_seq_echo,mode,fault_bits,sample0,sample1,sample2,sample3,sample4\n";
    f << "0.001,1000,1,0,1,0,-0.1,1.2,0.5,0.3,0\n";
    f << "0.002,2000,2,1,1,0,-0.11,1.21,nan,0.3,0\n";  // skipped: not finite
    f << "0.003,3000,3,2,1,0,-0.12,1.22,0.52,0.3,0\n";
  }
  std::vector<CalibrationSample> s;
  ASSERT_EQ(readCalibrationCsv(path, s), "");
  ASSERT_EQ(s.size(), 2u);
  EXPECT_DOUBLE_EQ(s[1].theta1r_rad, -0.12);
  EXPECT_DOUBLE_EQ(s[1].theta6r_rad, 1.22);
  EXPECT_DOUBLE_EQ(s[1].theta7r_rad, 0.52);
  {
    std::ofstream f(path);
    f << "theta1r_rad,theta6r_rad,theta7r_rad\n0.1,abc,0.3\n";
  }
  const std::string err = readCalibrationCsv(path, s);
  EXPECT_NE(err.find(":2: column theta6r_rad"), std::string::npos) << err;
  {
    std::ofstream f(path);
    f << "a,b,c\n1,2,3\n";
  }
  EXPECT_NE(readCalibrationCsv(path, s).find("header needs"), std::string::npos);
  std::remove(path.c_str());
}

TEST(SeaCalibrate, SubjectYamlRoundTripKeepsOtherKeysAndRejectsUnknownOnes) {
  const std::string path = ::testing::TempDir() + "sea_subject.yaml";
  {
    std::ofstream f(path);
    f << "name: subject-7\nsea_subject:\n  l_CE_m: 0.051\n";
  }
  CalibrationResult r;
  r.estimate = perturbedSubject(1.0).subject;
  r.final_rms_rad = 1e-3;
  r.samples_used = 123;
  ps::FixedGeometry<double> fixed = ps::defaultModel<double>().fixed;
  SubjectParams sp = ps::table4Initial<double>();
  ASSERT_EQ(loadSubjectYaml(path, sp, fixed), "");
  EXPECT_DOUBLE_EQ(fixed.l_CE_m, 0.051);
  ASSERT_EQ(writeSubjectYaml(path, r, fixed, "test.csv"), "");
  SubjectParams back = ps::table4Initial<double>();
  ps::FixedGeometry<double> fixed_back = ps::defaultModel<double>().fixed;
  ASSERT_EQ(loadSubjectYaml(path, back, fixed_back), "");
  const auto a = ps::toArray(back);
  const auto b = ps::toArray(r.estimate);
  for (std::size_t i = 0; i < 7; ++i) EXPECT_NEAR(a[i], b[i], 1e-6);
  EXPECT_DOUBLE_EQ(fixed_back.l_CE_m, 0.051);
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("subject-7"), std::string::npos);
  EXPECT_NE(text.find("rms_residual_rad"), std::string::npos);
  {
    std::ofstream f(path);
    f << "sea_subject:\n  l_XY_m: 0.01\n";
  }
  EXPECT_NE(loadSubjectYaml(path, back, fixed_back).find("sea_subject.l_XY_m: unknown key"), std::string::npos);
  {
    std::ofstream f(path);
    f << "sea_subject:\n  l_BC_m: long\n";
  }
  EXPECT_NE(loadSubjectYaml(path, back, fixed_back).find("sea_subject.l_BC_m: not a number"), std::string::npos);
  std::remove(path.c_str());
}

TEST(SeaCalibrate, ASubjectFileWithARepeatedKeyIsRefusedOnReadAndBeforeItIsRewritten) {
  const std::string path = ::testing::TempDir() + "sea_subject_dup.yaml";
  {
    std::ofstream f(path);
    f << "sea_subject:\n  l_CE_m: 0.051\n  l_CE_m: 0.06\n";
  }
  SubjectParams sp = ps::table4Initial<double>();
  ps::FixedGeometry<double> fixed = ps::defaultModel<double>().fixed;
  EXPECT_NE(loadSubjectYaml(path, sp, fixed).find("sea_subject.l_CE_m: duplicate key"), std::string::npos);
  {
    std::ofstream f(path);
    f << "name: a\nname: b\n";
  }
  CalibrationResult r;
  r.estimate = ps::table4Initial<double>();
  EXPECT_NE(writeSubjectYaml(path, r, fixed, "test.csv").find("name: duplicate key"), std::string::npos);
  std::remove(path.c_str());
}

TEST(SeaCalibrate, CommandReadsARecorderCsvAndWritesTheSubjectFile) {
  // `phalanx sea-calibrate --recording <csv> --subject <yaml>` end to end, on the columns phalanx run --record
  // writes for sea_finger.
  ps::Model<double> truth = ps::defaultModel<double>();
  truth.subject = {0.003, -0.032, 0.046, 0.028, 0.046, 0.022, 0.020};  // another hand inside Table 4's box
  const auto samples = recording(truth, 0.02 * kDeg, 5);
  const std::string csv = ::testing::TempDir() + "sea_cmd.csv";
  const std::string yaml = ::testing::TempDir() + "sea_cmd_subject.yaml";
  std::remove(yaml.c_str());
  {
    std::ofstream f(csv);
    f << "t_s,device_time_us,seq,cmd_seq_echo,mode,fault_bits";
    for (int i = 0; i < 11; ++i) f << ",sample" << i;
    f << ",setpoint0,setpoint1\n";
    for (std::size_t k = 0; k < samples.size(); ++k) {
      f << 0.002 * double(k) << "," << 2000 * k << "," << k << "," << k << ",1,0," << samples[k].theta1r_rad << ","
        << samples[k].theta6r_rad << "," << samples[k].theta7r_rad << ",0.1,0,0,0,0,0,0,0,0,0\n";
    }
  }
  ASSERT_EQ(seaCalibrateCommand(csv, yaml, true, 4), 0);
  SubjectParams est = ps::table4Initial<double>();
  FixedGeometry fixed = ps::defaultModel<double>().fixed;
  ASSERT_EQ(loadSubjectYaml(yaml, est, fixed), "");
  const auto pe = ps::toArray(est);
  const auto pt = ps::toArray(truth.subject);
  for (std::size_t i = 0; i < 7; ++i) EXPECT_NEAR(pe[i], pt[i], 0.001) << ps::kSubjectParamNames[i];
  // A missing file is an error with exit code 2, not a crash.
  EXPECT_EQ(seaCalibrateCommand(csv + ".missing", yaml, true, 1), 2);
  std::remove(csv.c_str());
  std::remove(yaml.c_str());
}

TEST(SeaCalibrate, OtherBranchPredictionReproducesARecordingThatPassedThroughTheDeadPoint) {
  // Subject 1 of SEA_SWEEP_SEED=1234: the sweep's motion drives its PIP four-bar through the dead point (F, H, C
  // collinear) onto the other assembly branch (docs/sea-model.md §Both branches). There the estimator's branch
  // cannot reproduce θ7r and the other branch (predictRedundant(…, other_branch = true)) must, exactly.
  std::mt19937 rng(1234);
  randomSubject(rng);
  const ps::Model<double> truth = randomSubject(rng);
  int other = 0;
  for (int k = 0; k < 10000; k += 5) {
    const double t = k * 0.001;
    const double mcp = -30 * kDeg + 28 * kDeg * std::sin(2 * M_PI * 0.5 * t);
    const double pip = -40 * kDeg + 38 * kDeg * std::sin(2 * M_PI * 0.8 * t + 1.0);
    ps::Data<double> d;
    if (!ps::isUsable(ps::computeFromFinger(truth, ps::FingerAngles<double>{mcp, pip, -20 * kDeg, 0.0}, d))) continue;
    const double s1 = d.sensors_rad[ps::kSensorExoMcp];
    const double s6 = d.sensors_rad[ps::kSensorExoPip];
    const double s7 = d.sensors_rad[ps::kSensorRedundant];
    const double mine = std::remainder(s7 - ps::predictRedundant(truth.subject, truth.fixed, s1, s6), 2 * M_PI);
    const double theirs =
        std::remainder(s7 - ps::predictRedundant<double>(truth.subject, truth.fixed, s1, s6, nullptr, true), 2 * M_PI);
    EXPECT_LT(std::fmin(std::fabs(mine), std::fabs(theirs)), 1e-9) << "row " << k;  // one branch explains every row
    other += std::fabs(mine) > 1e-6 ? 1 : 0;
  }
  EXPECT_GT(other, 50);  // ≈ 5.6 % of the 2000 rows checked
}
