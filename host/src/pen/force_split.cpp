#include "phalanx/host/pen/force_split.h"

#include <cmath>
#include <limits>
#include <utility>

namespace phalanx::host::pen {

namespace pp = phalanx::pen;

namespace {

bool finite3(const Vec3d& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

// A torque within this relative distance of its limit counts as "at the limit" in limit_active_mask.
constexpr double kAtLimitRel = 1e-9;

}  // namespace

PenForceSplitter::PenForceSplitter(const SplitConfig& config) : config_(config) {
  config_ok_ = true;
  for (double m : config_.torque_limit_Nm) {
    if (!(std::isfinite(m) && m > 0.0)) config_ok_ = false;
  }
}

SplitStatus PenForceSplitter::split(const pp::Data<double>& kin, const PenWrench& w, SplitResult& out) const {
  out = SplitResult{};
  if (!config_ok_) return out.status = SplitStatus::kBadConfig;
  if (!finite3(w.force_N) || !finite3(w.torque_Nm)) return out.status = SplitStatus::kNonFiniteInput;
  if (!pp::isUsable(kin.status) || !(kin.length_m > 0.0)) return out.status = SplitStatus::kKinematicsUnusable;

  const Vec3d& a = kin.B_axis;
  out.dropped_roll_torque_Nm = pp::dot(w.torque_Nm, a);
  // Fig. 18, solved for the two end forces. With r_t = −r_b = (L/2)·a:
  //   f_b + f_t = F,   (L/2)·a × (f_t − f_b) = M⊥   ⇒   f_t − f_b = (2/L)·(M × a) + 2μ·a
  // since a × (M × a) = M − a(a·M) = M⊥. Hence f_t = F/2 + (M × a)/L + μa, f_b = F/2 − (M × a)/L − μa.
  const Vec3d mxa = pp::cross(w.torque_Nm, a);
  const double inv_len = 1.0 / kin.length_m;
  Vec3d fb0{}, ft0{};
  for (std::size_t i = 0; i < 3; ++i) {
    ft0[i] = 0.5 * w.force_N[i] + mxa[i] * inv_len;
    fb0[i] = 0.5 * w.force_N[i] - mxa[i] * inv_len;
  }
  // τ(s, μ) = s·τ0 + μ·g with τ0 = [J_bᵀ f_b0; J_tᵀ f_t0] and g = [−J_bᵀ a; J_tᵀ a] (τ = Jᵀf per pantograph).
  const Vec3d tb0 = pp::mulTransposed(kin.pantograph[pp::kBottom].J, fb0);
  const Vec3d tt0 = pp::mulTransposed(kin.pantograph[pp::kTop].J, ft0);
  const Vec3d gb = pp::mulTransposed(kin.pantograph[pp::kBottom].J, a);
  const Vec3d gt = pp::mulTransposed(kin.pantograph[pp::kTop].J, a);
  const JointVecd tau0{tb0[0], tb0[1], tb0[2], tt0[0], tt0[1], tt0[2]};
  const JointVecd g{-gb[0], -gb[1], -gb[2], gt[0], gt[1], gt[2]};
  const JointVecd& lim = config_.torque_limit_Nm;

  // Effort optimum: min Σ((τ0_i + μ g_i)/m_i)²  ⇒  μ* = −Σ τ0_i g_i/m_i² / Σ g_i²/m_i².
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    const double w2 = 1.0 / (lim[i] * lim[i]);
    num += tau0[i] * g[i] * w2;
    den += g[i] * g[i] * w2;
  }
  const double mu_opt = (config_.minimise_effort && den > 0.0) ? -num / den : 0.0;

  // Feasible μ for a wrench fraction s: each joint bounds μ between two lines in s, lo_i(s) ≤ μ ≤ hi_i(s).
  // Joints with g_i = 0 (numerically) bound s directly: |s·τ0_i| ≤ m_i.
  // g_i this small (relative to the largest |g_j|) cannot move τ_i: treat it as zero.
  double g_max = 0.0;
  for (double gi : g) g_max = std::fabs(gi) > g_max ? std::fabs(gi) : g_max;
  const double g_eps = 1e-12 * g_max;
  auto interval = [&](double s, double& lo, double& hi) {
    lo = -std::numeric_limits<double>::infinity();
    hi = std::numeric_limits<double>::infinity();
    bool ok = true;
    for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
      if (std::fabs(g[i]) <= g_eps) {
        if (std::fabs(s * tau0[i]) > lim[i]) ok = false;
        continue;
      }
      double l = (-lim[i] - s * tau0[i]) / g[i];
      double h = (lim[i] - s * tau0[i]) / g[i];
      if (g[i] < 0.0) std::swap(l, h);
      lo = l > lo ? l : lo;
      hi = h < hi ? h : hi;
    }
    return ok && lo <= hi;
  };

  double s = 1.0;
  double mu = mu_opt;
  double lo = 0.0, hi = 0.0;
  bool within = true;
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    if (std::fabs(tau0[i] + mu_opt * g[i]) > lim[i]) within = false;
  }
  if (within) {
    out.status = SplitStatus::kOk;
  } else if (interval(1.0, lo, hi)) {
    mu = mu_opt < lo ? lo : (mu_opt > hi ? hi : mu_opt);
    out.status = SplitStatus::kInternalForceRedistributed;
  } else {
    // Largest s ∈ [0, 1] with max_i lo_i(s) ≤ min_j hi_j(s). Both bounds are lines α + β·s, and a max of lines
    // is ≤ a min of lines iff every pair is, so s* is the smallest crossing over all (lower i, upper j) pairs
    // that close with growing s. At s = 0 every lo < 0 < hi (limits > 0), so s* > 0.
    double s_max = 1.0;
    std::array<double, pp::kNumJoints> la{}, lb{}, ha{}, hb{};
    std::array<bool, pp::kNumJoints> has{};
    for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
      if (std::fabs(g[i]) <= g_eps) {
        if (std::fabs(tau0[i]) > 0.0) {
          const double si = lim[i] / std::fabs(tau0[i]);
          s_max = si < s_max ? si : s_max;
        }
        continue;
      }
      has[i] = true;
      // (±m_i − s·τ0_i)/g_i
      const double a_minus = -lim[i] / g[i], a_plus = lim[i] / g[i], b = -tau0[i] / g[i];
      if (g[i] > 0.0) {
        la[i] = a_minus;
        ha[i] = a_plus;
      } else {
        la[i] = a_plus;
        ha[i] = a_minus;
      }
      lb[i] = b;
      hb[i] = b;
    }
    for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
      if (!has[i]) continue;
      for (std::size_t j = 0; j < pp::kNumJoints; ++j) {
        if (!has[j]) continue;
        const double slope = lb[i] - hb[j];
        if (slope > 0.0) {
          const double sc = (ha[j] - la[i]) / slope;
          s_max = sc < s_max ? sc : s_max;
        }
      }
    }
    s = s_max > 0.0 ? s_max : 0.0;
    interval(s, lo, hi);
    const double mu_s = s * mu_opt;  // the effort optimum of the scaled wrench
    mu = lo <= hi ? (mu_s < lo ? lo : (mu_s > hi ? hi : mu_s)) : 0.5 * (lo + hi);
    out.status = SplitStatus::kScaled;
  }

  out.scale = s;
  out.internal_force_N = mu;
  out.optimal_internal_force_N = s * mu_opt;
  double effort = 0.0;
  for (std::size_t i = 0; i < pp::kNumJoints; ++i) {
    double t = s * tau0[i] + mu * g[i];
    // Rounding only (≤ a few ulp): the feasibility above already holds to machine precision.
    if (t > lim[i]) t = lim[i];
    if (t < -lim[i]) t = -lim[i];
    out.tau_Nm[i] = t;
    effort += (t / lim[i]) * (t / lim[i]);
    if (std::fabs(t) >= lim[i] * (1.0 - kAtLimitRel)) out.limit_active_mask |= static_cast<std::uint8_t>(1u << i);
  }
  out.effort = effort;
  for (std::size_t i = 0; i < 3; ++i) {
    out.f_bottom_N[i] = s * fb0[i] - mu * a[i];
    out.f_top_N[i] = s * ft0[i] + mu * a[i];
  }
  return out.status;
}

void endForcesToWrench(const pp::Data<double>& kin, const Vec3d& f_bottom_N, const Vec3d& f_top_N, PenWrench& out) {
  const Vec3d& pb = kin.pantograph[pp::kBottom].B_p_tip;
  const Vec3d& pt = kin.pantograph[pp::kTop].B_p_tip;
  const Vec3d& c = kin.B_p_centre;
  const Vec3d rb{pb[0] - c[0], pb[1] - c[1], pb[2] - c[2]};
  const Vec3d rt{pt[0] - c[0], pt[1] - c[1], pt[2] - c[2]};
  const Vec3d mb = pp::cross(rb, f_bottom_N);
  const Vec3d mt = pp::cross(rt, f_top_N);
  for (std::size_t i = 0; i < 3; ++i) {
    out.force_N[i] = f_bottom_N[i] + f_top_N[i];
    out.torque_Nm[i] = mb[i] + mt[i];
  }
}

bool tipForceFromTorques(const pp::Mat3<double>& J, const Vec3d& tau_Nm, Vec3d& f_N) {
  // Jᵀ f = τ: solve with Cramer's rule on A = Jᵀ.
  pp::Mat3<double> A{};
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) A[r][c] = J[c][r];
  }
  const double det = pp::det3(A);
  if (!(std::fabs(det) > 1e-15)) return false;
  for (std::size_t k = 0; k < 3; ++k) {
    pp::Mat3<double> Ak = A;
    for (std::size_t r = 0; r < 3; ++r) Ak[r][k] = tau_Nm[r];
    f_N[k] = pp::det3(Ak) / det;
  }
  return true;
}

}  // namespace phalanx::host::pen
