#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>

#include "phalanx/host/benchrun/report.h"
#include "phalanx/host/benchrun/runner.h"
#include "phalanx/host/progress.h"

namespace phalanx::host::benchrun {

namespace {

/// --device and --lockstep against the plan: "" or the problem (exit 2, nothing runs).
std::string chooseDevice(Plan& plan, const std::string& device, bool lockstep) {
  if (!device.empty()) {
    if (std::string err = setPlanDevice(plan, device); !err.empty()) return err;
  }
  if (lockstep) {
    if (plan.device.rfind("sim:", 0) != 0) return "--lockstep: only sim: devices run in lockstep, not " + plan.device;
    if (!plan.sim_instrument || plan.sim_instrument_delay_ms > 0) {
      return "--lockstep: the lockstep runner serves its own instrument (sim_instrument: false and sim_instrument_delay_ms "
             "are for the real-time run)";
    }
    return {};
  }
  if (std::string why = realtimeUnsupported(plan); !why.empty()) return plan.source + ": " + why;
  return {};
}

}  // namespace

int benchRunMain(const std::string& plan_path, const std::string& report_path, const std::string& device, bool lockstep,
                 bool realtime) {
  Plan plan;
  std::string err = loadPlanFile(plan_path, plan);
  if (err.empty()) err = chooseDevice(plan, device, lockstep);
  if (!err.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", err.c_str());
    return 2;
  }
  std::string report = report_path.empty() ? plan.report : report_path;
  if (report.empty()) {
    const auto dot = plan_path.rfind('.');
    report = (dot == std::string::npos ? plan_path : plan_path.substr(0, dot)) + ".html";
  }
  const bool tty = isatty(STDERR_FILENO) != 0;
  int last_pct = -1;
  size_t last_step = static_cast<size_t>(-1);
  // The plan's share done, by step length (steps run paced to real time): the estimate of the time left.
  double plan_s = 0.0;
  for (const Step& st : plan.steps) plan_s += st.seconds;
  double before_s = 0.0;  // length of the steps already run
  const auto t0 = std::chrono::steady_clock::now();
  const Progress show = [&](size_t i, size_t n, const std::string& name, double frac) {
    const int pct = static_cast<int>(frac * 100.0);
    if (i != last_step) {
      if (last_step != static_cast<size_t>(-1)) before_s += plan.steps[last_step].seconds;
      last_step = i;
      last_pct = -1;
    }
    // On a terminal: one line updated in place; in a log: a line every 25 % of a step.
    if (tty ? pct != last_pct : (pct / 25 != last_pct / 25 || last_pct < 0)) {
      const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const double plan_frac = plan_s > 0 ? (before_s + frac * plan.steps[i].seconds) / plan_s : 0.0;
      char step[256];
      std::snprintf(step, sizeof step, "[%zu/%zu] %s %3d %%, plan", i + 1, n, name.c_str(), pct);
      const std::string line = ProgressLine::format(step, elapsed_s, plan_frac, "");
      std::fprintf(stderr, tty ? "\r\033[K%s" : "%s\n", line.c_str());
      std::fflush(stderr);
    }
    last_pct = pct;
  };
  DeviceRunOptions on_device;
  on_device.realtime = realtime;
  const PlanResult result = lockstep ? runPlan(plan, show) : runPlanOnDevice(plan, show, on_device);
  if (tty) std::fputc('\n', stderr);
  for (const StepResult& s : result.steps) {
    std::fprintf(stderr, "%s  %s%s%s\n", s.pass ? "PASS" : "FAIL", s.name.c_str(), s.error.empty() ? "" : ": ",
                 s.error.c_str());
    for (const Check& c : s.checks) {
      if (!c.pass) {
        std::fprintf(stderr, "      %s = %.4g, limit %s %.4g%s%s\n", c.what.c_str(), c.value, c.is_min ? "≥" : "≤", c.limit,
                     c.note.empty() ? "" : "; ", c.note.c_str());
      }
    }
  }
  nlohmann::json j = toJson(result);
  j["plan"] = plan_path;
  j["report"] = report;
  std::cout << j.dump(2) << std::endl;
  if (std::string werr = writeHtml(report, plan, result); !werr.empty()) {
    std::fprintf(stderr, "phalanx: error: %s\n", werr.c_str());
    return 3;
  }
  std::fprintf(stderr, "report: %s  (%s)\n", report.c_str(), result.pass ? "PASS" : "FAIL");
  return result.pass ? 0 : 1;
}

}  // namespace phalanx::host::benchrun
