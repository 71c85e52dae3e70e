#pragma once
/// The bench runner's HTML report: one self-contained file (inline SVG plots drawn here, inline CSS, no scripts,
/// nothing fetched): summary with pass/fail per limit, and per step the time series, the magnitude response
/// (chirp steps) and the error distributions.
#include <string>

#include "phalanx/host/benchrun/runner.h"

namespace phalanx::host::benchrun {

std::string renderHtml(const Plan& plan, const PlanResult& result);
/// Write renderHtml() to path; "" or the problem.
std::string writeHtml(const std::string& path, const Plan& plan, const PlanResult& result);

}  // namespace phalanx::host::benchrun
