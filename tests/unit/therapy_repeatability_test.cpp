// ICC(2,1) and MDC95 (host/therapy/repeatability.h) against hand computations.
#include <gtest/gtest.h>

#include <cmath>

#include "phalanx/host/therapy/repeatability.h"

using namespace phalanx::host::therapy;

// n = 3 subjects, k = 2 sessions: y = [[1, 2], [3, 4], [5, 7]].
// Hand computation:
//   grand mean = 22/6 = 11/3; row means 3/2, 7/2, 6; column means 3, 13/3.
//   SS_total = Σ(y − 11/3)² = (64 + 25 + 4 + 1 + 16 + 100)/9 = 210/9 = 70/3
//   SS_rows  = k·Σ(row − 11/3)² = 2·((−13/6)² + (−1/6)² + (7/3)²) = 2·(169 + 1 + 196)/36 = 61/3
//   SS_cols  = n·Σ(col − 11/3)² = 3·((−2/3)² + (2/3)²) = 8/3
//   SS_error = 70/3 − 61/3 − 8/3 = 1/3
//   MSR = (61/3)/2 = 61/6; MSC = (8/3)/1 = 8/3; MSE = (1/3)/((n−1)(k−1)) = 1/6
//   ICC(2,1) = (MSR − MSE) / (MSR + (k−1)·MSE + k·(MSC − MSE)/n)
//            = (60/6) / (61/6 + 1/6 + 2·(15/6)/3) = 10 / (62/6 + 10/6) = 10/12 = 5/6
//   SD  = √(SS_total/(nk − 1)) = √(70/15) = √(14/3)
//   SEM = SD·√(1 − 5/6) = √(14/3 · 1/6) = √(7/9) = √7/3 = 0.881917…
//   MDC95 = 1.96·√2·√7/3 = 1.96·√14/3 = 2.444549…
TEST(Repeatability, IccAndMdcMatchTheHandComputation) {
  Repeatability r;
  ASSERT_EQ(computeRepeatability({{1, 2}, {3, 4}, {5, 7}}, r), "");
  EXPECT_NEAR(r.ms_rows, 61.0 / 6.0, 1e-12);
  EXPECT_NEAR(r.ms_cols, 8.0 / 3.0, 1e-12);
  EXPECT_NEAR(r.ms_error, 1.0 / 6.0, 1e-12);
  EXPECT_NEAR(r.icc, 5.0 / 6.0, 1e-12);
  EXPECT_NEAR(r.sd, std::sqrt(14.0 / 3.0), 1e-12);
  EXPECT_NEAR(r.sem, std::sqrt(7.0) / 3.0, 1e-12);
  EXPECT_NEAR(r.mdc95, 1.96 * std::sqrt(14.0) / 3.0, 1e-12);
  EXPECT_NEAR(mdc95(r.sd, r.icc), r.mdc95, 1e-12);
}

// Shrout & Fleiss 1979, Table 2 (6 targets × 4 judges), whose ICC(2,1) the paper gives as 0.29 (Table 4).
// Their mean squares (Table 3): BMS 11.24, JMS 32.49, EMS 1.02.
TEST(Repeatability, ReproducesShroutAndFleissTable4) {
  Repeatability r;
  ASSERT_EQ(computeRepeatability({{9, 2, 5, 8}, {6, 1, 3, 2}, {8, 4, 6, 8}, {7, 1, 2, 6}, {10, 5, 6, 9}, {6, 2, 4, 7}}, r),
            "");
  EXPECT_NEAR(r.ms_rows, 11.24, 0.005);
  EXPECT_NEAR(r.ms_cols, 32.49, 0.005);
  EXPECT_NEAR(r.ms_error, 1.02, 0.005);
  EXPECT_NEAR(r.icc, 0.29, 0.005);
}

// Identical sessions: ICC 1, SEM and MDC 0. A pure session offset (every subject +1 in session 2) lowers the
// absolute-agreement ICC below 1 (the consistency ICC would stay 1).
TEST(Repeatability, PerfectAgreementAndASessionBias) {
  Repeatability r;
  ASSERT_EQ(computeRepeatability({{1, 1}, {2, 2}, {4, 4}}, r), "");
  EXPECT_NEAR(r.icc, 1.0, 1e-12);
  EXPECT_NEAR(r.mdc95, 0.0, 1e-12);
  ASSERT_EQ(computeRepeatability({{1, 2}, {2, 3}, {4, 5}}, r), "");
  EXPECT_LT(r.icc, 0.95);
  EXPECT_GT(r.mdc95, 0.0);
}

TEST(Repeatability, RefusesWhatItCannotCompute) {
  Repeatability r;
  EXPECT_NE(computeRepeatability({{1, 2}}, r).find("2 subjects"), std::string::npos);
  EXPECT_NE(computeRepeatability({{1}, {2}}, r).find("2 sessions"), std::string::npos);
  EXPECT_NE(computeRepeatability({{1, 2}, {3}}, r).find("subject 1 has 1 sessions"), std::string::npos);
  EXPECT_NE(computeRepeatability({{1, NAN}, {3, 4}}, r).find("non-finite"), std::string::npos);
  EXPECT_NE(computeRepeatability({{2, 2}, {2, 2}}, r).find("undefined"), std::string::npos);
}
