#include <chrono>
#include <cmath>
#include <random>
#include <vector>

#include "phalanx/host/pen/force_split.h"
#include "phalanx/host/pen/pen_bench.h"

namespace phalanx::host::pen {
namespace {

namespace pp = phalanx::pen;
constexpr double kDeg = 3.14159265358979323846 / 180.0;

struct ClassStats {
  const char* name;
  double force_N;    ///< force magnitude bound per axis
  double torque_Nm;  ///< torque magnitude bound per axis
  long n = 0, ok = 0, redistributed = 0, scaled = 0;
  double max_err_force_N = 0.0, max_err_torque_Nm = 0.0;  // vs scale·desired
  double effort_sum = 0.0, effort_paper_sum = 0.0;        // Σ(τ/τmax)², effort-optimal μ vs μ = 0
  double min_scale = 1.0, scale_sum = 0.0;
  long paper_saturated = 0;  // the paper's μ = 0 split would exceed a limit (no redistribution)
  std::array<long, pp::kNumJoints> limit_active{};
};

}  // namespace

nlohmann::json homeCapabilities(const pp::Model<double>& model, const PenForceSplitter& splitter) {
  // Table X's rows that depend only on the geometry, the torque limits and the encoders, at home.
  pp::Data<double> kin;
  pp::computeForward(model, model.q_home_rad, kin);
  // Peak force/torque per axis: the largest multiple of a unit wrench along the axis the limits allow (the
  // split scales a huge request down to it, its effort-optimal internal force helping).
  std::array<double, 5> peak{};
  for (std::size_t k = 0; k < 5; ++k) {
    PenWrench w;
    const double big = 1e4;
    if (k < 3) w.force_N[k] = big;
    else w.torque_Nm[k == 3 ? 0 : 2] = big;
    SplitResult r;
    splitter.split(kin, w, r);
    peak[k] = r.scale * big;
  }
  // Spatial resolution: one count on each joint of both pantographs moving the two ends alike (translation) or
  // oppositely (rotation about the centre: 2·d / pen length), the coarsest joint along each axis.
  const double rad = 2.0 * 3.14159265358979323846 / model.counts_per_rev;
  const auto& J = kin.pantograph[pp::kBottom].J;
  const double res_x = std::fmax(std::fabs(J[0][1]), std::fabs(J[0][2])) * rad;
  const double res_y = std::fabs(J[1][0]) * rad;
  const double res_z = std::fmax(std::fabs(J[2][1]), std::fabs(J[2][2])) * rad;
  const double L = kin.length_m;
  const double deg = 180.0 / 3.14159265358979323846;
  return {{"pen_length_cm", L * 100.0},
          {"peak_force_N", {{"x", peak[0]}, {"y", peak[1]}, {"z", peak[2]}}},
          {"peak_torque_Ncm", {{"x", peak[3] * 100.0}, {"z", peak[4] * 100.0}}},
          {"table_x_peak", {{"x_N", 48}, {"y_N", 21}, {"z_N", 40}, {"rot_x_Ncm", 324}, {"rot_z_Ncm", 396}}},
          {"resolution_um", {{"x", res_x * 1e6}, {"y", res_y * 1e6}, {"z", res_z * 1e6}}},
          {"resolution_deg", {{"x", 2.0 * res_z / L * deg}, {"z", 2.0 * res_x / L * deg}}},
          {"table_x_resolution", {{"x_um", 142}, {"y_um", 314}, {"z_um", 175}, {"rot_x_deg", 0.122}, {"rot_z_deg", 0.099}}}};
}

nlohmann::json benchSplit(const PenSplitBenchOptions& o) {
  const pp::Model<double> model = pp::defaultModel<double>();
  const PenForceSplitter splitter;
  SplitConfig paper_cfg;
  paper_cfg.minimise_effort = false;
  paper_cfg.torque_limit_Nm = {1e12, 1e12, 1e12, 1e12, 1e12, 1e12};
  const PenForceSplitter paper(paper_cfg);
  const pp::JointVec<double>& lim = splitter.config().torque_limit_Nm;

  // Magnitude classes: Table X's continuous (5 N, 0.34–0.41 N·m) and peak (48 N, 3.2–4 N·m) capabilities, and a
  // class beyond peak that must always be scaled.
  std::array<ClassStats, 3> classes{{{"continuous", 5.0, 0.35}, {"peak", 40.0, 1.0}, {"beyond_peak", 150.0, 5.0}}};
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = o.grid < 2 ? 2 : o.grid;
  long poses = 0, unreachable = 0;
  double min_margin = 1.0;
  double cycle_ns_sum = 0.0;
  long cycles = 0;
  pp::Data<double> kin;
  SplitResult r, r0;
  for (int ix = 0; ix < n; ++ix)
    for (int iy = 0; iy < n; ++iy)
      for (int iz = 0; iz < n; ++iz)
        for (int ia = 0; ia < n; ++ia)
          for (int ib = 0; ib < n; ++ib) {
            auto lerp = [n](int i, double lo, double hi) { return lo + (hi - lo) * i / (n - 1); };
            pp::PenPose<double> pose;
            pose.centre_m = {lerp(ix, -0.06, 0.06), lerp(iy, -0.0375, 0.0375), lerp(iz, 0.1625, 0.2375)};
            pose.theta_x_rad = lerp(ia, -45, 45) * kDeg;
            pose.theta_z_rad = lerp(ib, -45, 45) * kDeg;
            pp::JointVec<double> q;
            if (pp::computeInverse(model, pose, q) != pp::Status::kOk) {
              ++unreachable;
              continue;
            }
            ++poses;
            const pp::JointVec<double> qm = pp::anglesFromCounts(model, pp::countsFromAngles(model, q));
            for (ClassStats& c : classes) {
              for (int k = 0; k < o.wrenches_per_pose; ++k) {
                PenWrench w;
                for (int i = 0; i < 3; ++i) {
                  w.force_N[i] = c.force_N * u(rng);
                  w.torque_Nm[i] = c.torque_Nm * u(rng);
                }
                const auto t0 = std::chrono::steady_clock::now();
                pp::computeForward(model, qm, kin);
                const SplitStatus s = splitter.split(kin, w, r);
                const auto t1 = std::chrono::steady_clock::now();
                cycle_ns_sum += static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count());
                ++cycles;
                min_margin = std::fmin(min_margin, kin.min_margin_sin);
                ++c.n;
                if (s == SplitStatus::kOk) ++c.ok;
                if (s == SplitStatus::kInternalForceRedistributed) ++c.redistributed;
                if (s == SplitStatus::kScaled) ++c.scaled;
                for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
                  if (r.limit_active_mask & (1u << i)) ++c.limit_active[i];
                }
                c.min_scale = std::fmin(c.min_scale, r.scale);
                c.scale_sum += r.scale;
                // Delivered wrench from the torques alone: f = J⁻ᵀτ per pantograph, statics at the centre.
                Vec3d fb{}, ft{};
                tipForceFromTorques(kin.pantograph[pp::kBottom].J, {r.tau_Nm[0], r.tau_Nm[1], r.tau_Nm[2]}, fb);
                tipForceFromTorques(kin.pantograph[pp::kTop].J, {r.tau_Nm[3], r.tau_Nm[4], r.tau_Nm[5]}, ft);
                PenWrench got;
                endForcesToWrench(kin, fb, ft, got);
                const double a_m = pp::dot(w.torque_Nm, kin.B_axis);
                for (int i = 0; i < 3; ++i) {
                  const double m_perp = w.torque_Nm[i] - a_m * kin.B_axis[i];
                  c.max_err_force_N = std::fmax(c.max_err_force_N, std::fabs(got.force_N[i] - r.scale * w.force_N[i]));
                  c.max_err_torque_Nm = std::fmax(c.max_err_torque_Nm, std::fabs(got.torque_Nm[i] - r.scale * m_perp));
                }
                // Effort comparison on the same (possibly scaled) wrench with the paper's μ = 0.
                PenWrench ws = w;
                for (int i = 0; i < 3; ++i) {
                  ws.force_N[i] *= r.scale;
                  ws.torque_Nm[i] *= r.scale;
                }
                paper.split(kin, ws, r0);
                double e0 = 0.0;
                for (std::size_t i = 0; i < pp::kNumJoints; ++i) e0 += (r0.tau_Nm[i] / lim[i]) * (r0.tau_Nm[i] / lim[i]);
                // Would the paper's split (μ = 0, no redistribution) of the full desired wrench exceed a limit?
                paper.split(kin, w, r0);
                bool sat_full = false;
                for (std::size_t i = 0; i < pp::kNumJoints; ++i) sat_full |= std::fabs(r0.tau_Nm[i]) > lim[i];
                if (sat_full) ++c.paper_saturated;
                c.effort_sum += r.effort;
                c.effort_paper_sum += e0;
              }
            }
          }

  nlohmann::json out;
  out["bench"] = "pen-split";
  out["seed"] = o.seed;
  out["workspace"] = {{"x_cm", {-6, 6}}, {"y_cm", {-3.75, 3.75}}, {"z_cm", {16.25, 23.75}}, {"theta_x_deg", {-45, 45}},
                      {"theta_z_deg", {-45, 45}}, {"grid_per_axis", n}, {"poses", poses}, {"unreachable", unreachable}};
  out["torque_limit_Nm"] = lim;
  out["home_vs_table_x"] = homeCapabilities(model, splitter);
  out["min_singularity_margin_sin"] = min_margin;
  out["mean_cycle_ns_fk_plus_split"] = cycles ? cycle_ns_sum / double(cycles) : 0.0;
  out["cycle_cost_note"] = "wall clock incl. timer overhead; the Google Benchmark pen_split_bench is the reference";
  for (const ClassStats& c : classes) {
    nlohmann::json j;
    j["force_bound_N"] = c.force_N;
    j["torque_bound_Nm"] = c.torque_Nm;
    j["wrenches"] = c.n;
    j["fraction_exact_unsaturated"] = c.n ? double(c.ok) / double(c.n) : 0.0;
    j["fraction_internal_force_redistributed"] = c.n ? double(c.redistributed) / double(c.n) : 0.0;
    j["fraction_scaled"] = c.n ? double(c.scaled) / double(c.n) : 0.0;
    j["fraction_paper_split_would_exceed_limit"] = c.n ? double(c.paper_saturated) / double(c.n) : 0.0;
    j["min_scale"] = c.min_scale;
    j["mean_scale"] = c.n ? c.scale_sum / double(c.n) : 0.0;
    j["max_wrench_error_force_N"] = c.max_err_force_N;
    j["max_wrench_error_torque_Nm"] = c.max_err_torque_Nm;
    j["mean_effort"] = c.n ? c.effort_sum / double(c.n) : 0.0;
    j["mean_effort_paper_mu0"] = c.n ? c.effort_paper_sum / double(c.n) : 0.0;
    j["limit_active_count_per_joint"] = c.limit_active;
    out["classes"][c.name] = j;
  }
  return out;
}

}  // namespace phalanx::host::pen
