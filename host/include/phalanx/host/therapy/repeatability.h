#pragma once
/// Test–retest repeatability of an assessment figure, as the instrumented-assessment literature reports it:
/// the intraclass correlation ICC(2,1) of Shrout & Fleiss 1979 (two-way random effects, absolute agreement,
/// single measures; Psychol Bull 86:420, "Case 2") and the minimum detectable change MDC95 = 1.96·√2·SEM with
/// SEM = SD·√(1 − ICC) (SD: of all the measurements pooled).
#include <string>
#include <vector>

namespace phalanx::host::therapy {

struct Repeatability {
  std::size_t subjects = 0;   ///< n: rows (simulated patients)
  std::size_t sessions = 0;   ///< k: columns (repeated sessions of each)
  double icc = 0.0;           ///< ICC(2,1)
  double sd = 0.0;            ///< SD of all n·k values (sample SD, n·k − 1)
  double sem = 0.0;           ///< SD·√(1 − ICC); ICC < 0 is taken as 0 here (SEM ≤ SD)
  double mdc95 = 0.0;         ///< 1.96·√2·SEM
  double ms_rows = 0.0, ms_cols = 0.0, ms_error = 0.0;  ///< the ANOVA mean squares behind the ICC
};

/// ICC(2,1) = (MSR − MSE) / (MSR + (k−1)·MSE + k·(MSC − MSE)/n) from y[subject][session] (n ≥ 2 subjects, k ≥ 2
/// sessions, every row the same length, every value finite). "" or an error naming what was wrong. An ICC is
/// undefined without between-subject spread (all of MSR, MSC, MSE zero): that is an error too.
std::string computeRepeatability(const std::vector<std::vector<double>>& y, Repeatability& out);

/// MDC95 from an SD and an ICC (ICC clamped to [0, 1]).
double mdc95(double sd, double icc);

}  // namespace phalanx::host::therapy
