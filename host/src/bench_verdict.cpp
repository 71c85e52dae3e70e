#include "phalanx/host/bench_verdict.h"

#include <cmath>
#include <cstdio>
#include <limits>

namespace phalanx::host {

namespace {

using nlohmann::json;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The number at a "/"-separated path, NaN when it is absent or not a number.
double num(const json& j, const std::string& path) {
  const json* at = &j;
  std::size_t b = 0;
  while (b <= path.size()) {
    const std::size_t e = std::min(path.find('/', b), path.size());
    const std::string key = path.substr(b, e - b);
    if (!at->is_object() || !at->contains(key)) return kNaN;
    at = &(*at)[key];
    b = e + 1;
  }
  if (at->is_boolean()) return at->get<bool>() ? 1.0 : 0.0;
  return at->is_number() ? at->get<double>() : kNaN;
}

class Judge {
 public:
  explicit Judge(BenchVerdict& v) : v_(v) {}
  void figure(const std::string& name, double value, const std::string& unit = "") {
    if (std::isfinite(value)) v_.figures.push_back({name, value, unit});
  }
  BenchCheck& atMost(const std::string& what, double value, double limit, const std::string& unit = "") {
    return add({what, value, limit, false, false, std::isfinite(value) && value <= limit, unit, ""});
  }
  BenchCheck& atLeast(const std::string& what, double value, double limit, const std::string& unit = "") {
    return add({what, value, limit, true, false, std::isfinite(value) && value >= limit, unit, ""});
  }
  void yes(const std::string& what, double value) { add({what, value, 1.0, true, true, value == 1.0, "", ""}); }
  void noFaults(const std::string& who, double faults) {
    BenchCheck& c = add({who + "no device fault latched", faults == 0.0 ? 1.0 : 0.0, 1.0, true, true, faults == 0.0, "", ""});
    if (!std::isfinite(faults)) c.value = faults, c.pass = false;
  }
  void note(const std::string& n) { v_.notes.push_back(n); }

 private:
  BenchCheck& add(BenchCheck c) {
    v_.checks.push_back(std::move(c));
    return v_.checks.back();
  }
  BenchVerdict& v_;
};

/// The SEA benches' targets are for this project's controller ("ours"); the paper's plain PID is the baseline.
bool judgesOurs(const json& r, Judge& j) {
  if (r.contains("controllers") && r["controllers"].contains("ours")) return true;
  j.note("targets are for this project's controller ('ours'); the paper's PID (--controller paper) is the 001 "
         "baseline and is not judged");
  return false;
}

void gloveFreeMotion(const json& r, Judge& j) {
  j.figure("Pearson r of the joint angles, mean", num(r, "pearson_r_alpha_mean"));
  j.atMost("peak contact force at zero force command, worst finger", num(r, "peak_contact_force_N_max"),
           num(r, "target/peak_contact_force_N"), "N");
  j.noFaults("", num(r, "faults"));
}

void gloveGrasp(const json& r, Judge& j) {
  j.atMost("largest relative force error in the steady window", num(r, "relative_error_max"),
           num(r, "target/relative_error"));
  // Without a finger on the ball the error above is over no finger at all.
  j.atLeast("fingers in steady contact with the ball", num(r, "fingers_in_steady_contact"), 1.0);
  j.noFaults("", num(r, "faults"));
}

void seaFigures(const json& r, Judge& j, const std::vector<std::pair<std::string, std::string>>& keys) {
  if (!r.contains("controllers")) return;
  for (const auto& [name, c] : r["controllers"].items()) {
    for (const auto& [key, label] : keys) j.figure(name + ": " + label, num(c, key), "");
  }
}

void seaRigSine(const json& r, Judge& j) {
  seaFigures(r, j, {{"fidelity_percent", "fidelity (eq 15), %"}, {"nrmse_percent", "NRMSE, %"}, {"rmse_Nm", "RMSE, N·m"}});
  if (!judgesOurs(r, j)) return;
  const double peak = num(r, "peak_Nm"), hz = num(r, "hz");
  if (peak != num(r, "target/peak_Nm") || hz != num(r, "target/hz")) {
    char b[200];
    std::snprintf(b, sizeof b, "the target is set at %.2g N·m and %.2g Hz (this run: %.2g N·m, %.2g Hz): not judged",
                  num(r, "target/peak_Nm"), num(r, "target/hz"), peak, hz);
    j.note(b);
    return;
  }
  j.atLeast("ours: fidelity (eq 15)", num(r, "controllers/ours/fidelity_percent"), num(r, "target/fidelity_percent_min"), "%");
  j.atMost("ours: NRMSE", num(r, "controllers/ours/nrmse_percent"), num(r, "target/nrmse_percent_max"), "%");
  j.noFaults("ours: ", num(r, "controllers/ours/faults"));
}

void seaRigChirp(const json& r, Judge& j) {
  if (r.contains("controllers")) {
    for (const auto& [name, c] : r["controllers"].items()) {
      const bool beyond = c.value("bandwidth_beyond_band", false);
      j.figure(name + (beyond ? ": -3 dB bandwidth (not reached within the sweep: at least), Hz" : ": -3 dB bandwidth, Hz"),
               num(c, "bandwidth_hz"));
    }
  }
  if (!judgesOurs(r, j)) return;
  BenchCheck& c = j.atLeast("ours: -3 dB bandwidth (eq 17)", num(r, "controllers/ours/bandwidth_hz"),
                            num(r, "target/bandwidth_hz_min"), "Hz");
  if (r["controllers"]["ours"].value("bandwidth_beyond_band", false)) {
    c.note = c.pass ? "-3 dB not reached within the sweep: the bandwidth is at least this, the top of the evaluated band"
                    : "-3 dB not reached within the sweep, which ends below the target: the target cannot be shown; "
                      "sweep further (--fmax-hz)";
  }
  j.noFaults("ours: ", num(r, "controllers/ours/faults"));
}

void seaFingerTorque(const json& r, Judge& j) {
  seaFigures(r, j, {{"mcp/nrmse_percent", "MCP NRMSE, %"}, {"pip/nrmse_percent", "PIP NRMSE, %"}});
  if (!judgesOurs(r, j)) return;
  j.atMost("ours: MCP torque NRMSE", num(r, "controllers/ours/mcp/nrmse_percent"), num(r, "target/mcp_nrmse_percent_max"), "%");
  j.atMost("ours: PIP torque NRMSE", num(r, "controllers/ours/pip/nrmse_percent"), num(r, "target/pip_nrmse_percent_max"), "%");
  j.noFaults("ours: ", num(r, "controllers/ours/faults"));
}

void seaTransparency(const json& r, Judge& j) {
  seaFigures(r, j, {{"mcp/residual_rmse_Nm", "MCP residual torque RMS, N·m"}, {"pip/residual_rmse_Nm", "PIP residual torque RMS, N·m"}});
  if (!judgesOurs(r, j)) return;
  j.atMost("ours: MCP residual torque RMS", num(r, "controllers/ours/mcp/residual_rmse_Nm"),
           num(r, "target/mcp_residual_rmse_Nm_max"), "N·m");
  j.atMost("ours: PIP residual torque RMS", num(r, "controllers/ours/pip/residual_rmse_Nm"),
           num(r, "target/pip_residual_rmse_Nm_max"), "N·m");
  j.noFaults("ours: ", num(r, "controllers/ours/faults"));
}

void penWallRun(const json& r, Judge& j, const std::string& who) {
  j.figure(who + "wall stiffness, N/cm", num(r, "stiffness_N_per_cm"));
  j.figure(who + "peak tip penetration, mm", num(r, "peak_tip_penetration_mm"));
  j.figure(who + "peak tip force, N", num(r, "peak_tip_force_N"));
  j.figure(who + "energy the walls generated, mJ", num(r, "wall_energy_generated_J") * 1e3);
  j.yes(who + "passive (the walls generated no net energy)", num(r, "passive"));
  j.yes(who + "stable (every press, the hands-off impact, passive, no fault)", num(r, "stable"));
}

void penWall(const json& r, Judge& j) {
  if (!r.contains("requested")) {
    penWallRun(r, j, "");
    return;
  }
  penWallRun(r["requested"], j, "requested: ");
  j.figure("largest stable stiffness with braking, N/cm", num(r, "with_braking/largest_stable_K_N_per_cm"));
  j.figure("largest stable stiffness without braking, N/cm", num(r, "without_braking/largest_stable_K_N_per_cm"));
}

void penSplit(const json& r, Judge& j) {
  j.figure("continuous class: share split exactly without saturation", num(r, "classes/continuous/fraction_exact_unsaturated"));
  j.figure("peak class: share split exactly without saturation", num(r, "classes/peak/fraction_exact_unsaturated"));
  j.figure("largest wrench error, continuous class, N", num(r, "classes/continuous/max_wrench_error_force_N"));
  j.figure("smallest singularity margin (sin)", num(r, "min_singularity_margin_sin"));
  j.figure("mean cycle: forward kinematics + split, ns", num(r, "mean_cycle_ns_fk_plus_split"));
  j.note("pen-split declares no target: its figures are for comparison with 004 Fig. 18");
}

std::string value(double v, const std::string& unit) {
  char b[64];
  std::snprintf(b, sizeof b, "%.4g", v);
  return unit.empty() || unit == "%" ? std::string(b) + unit : std::string(b) + " " + unit;
}

}  // namespace

bool BenchVerdict::pass() const {
  for (const BenchCheck& c : checks) {
    if (!c.pass) return false;
  }
  return true;
}

BenchVerdict judgeBench(const std::string& bench, const nlohmann::json& result) {
  BenchVerdict v;
  v.bench = bench;
  Judge j(v);
  if (bench == "glove-free-motion") gloveFreeMotion(result, j);
  else if (bench == "glove-grasp") gloveGrasp(result, j);
  else if (bench == "sea-rig-sine") seaRigSine(result, j);
  else if (bench == "sea-rig-chirp") seaRigChirp(result, j);
  else if (bench == "sea-finger-torque") seaFingerTorque(result, j);
  else if (bench == "sea-transparency") seaTransparency(result, j);
  else if (bench == "pen-wall") penWall(result, j);
  else if (bench == "pen-split") penSplit(result, j);
  else j.note("no verdict is defined for the bench '" + bench + "'");
  return v;
}

std::string benchSummaryText(const BenchVerdict& v) {
  std::string s = v.bench + ": " + (v.checks.empty() ? "no target judged" : v.pass() ? "PASS" : "FAIL (a target was missed)") + "\n";
  for (const BenchFigure& f : v.figures) s += "  " + f.name + ": " + value(f.value, f.unit) + "\n";
  for (const BenchCheck& c : v.checks) {
    s += std::string("  ") + (c.pass ? "ok    " : "MISSED") + " " + c.what + ": ";
    if (c.is_flag) {
      s += c.value == 1.0 ? "yes" : std::isfinite(c.value) ? "no" : "not reported";
    } else {
      s += (std::isfinite(c.value) ? value(c.value, c.unit) : std::string("not reported")) + (c.is_min ? " (target >= " : " (target <= ") +
           value(c.limit, c.unit) + ")";
    }
    if (!c.note.empty()) s += "; " + c.note;
    s += "\n";
  }
  for (const std::string& n : v.notes) s += "  note: " + n + "\n";
  s += "  (every figure: --json)\n";
  return s;
}

}  // namespace phalanx::host
