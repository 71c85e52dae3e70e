#include "phalanx/host/design/glove_design.h"

#include <nlopt.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "phalanx/host/design/svg.h"
#include "phalanx/host/yaml_keys.h"

namespace phalanx::host::design {

namespace {
using P2 = std::array<double, 2>;
constexpr double kMm = 1e-3;

double gridValue(double lo, double hi, std::size_t i, std::size_t n) {
  return n < 2 ? lo : lo + (hi - lo) * static_cast<double>(i) / static_cast<double>(n - 1);
}

double cross2(const P2& a, const P2& b, const P2& c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

double pointSegmentDistance(const P2& p, const P2& a, const P2& b) {
  const double dx = b[0] - a[0], dy = b[1] - a[1];
  const double len2 = dx * dx + dy * dy;
  double t = len2 > 0 ? ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double ex = a[0] + t * dx - p[0], ey = a[1] + t * dy - p[1];
  return std::sqrt(ex * ex + ey * ey);
}
}  // namespace

double segmentCrossingDepth(const P2& p, const P2& q, const P2& r, const P2& s) {
  const double d1 = cross2(p, q, r), d2 = cross2(p, q, s), d3 = cross2(r, s, p), d4 = cross2(r, s, q);
  const bool crossing = ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
  if (!crossing) return 0.0;
  return std::min(std::min(pointSegmentDistance(p, r, s), pointSegmentDistance(q, r, s)),
                  std::min(pointSegmentDistance(r, p, q), pointSegmentDistance(s, p, q)));
}

GloveAnalysis analyseGlove(const GloveModel& model, const SweepGrid& g, bool check_mech_limits,
                           const Link1Shape& link1) {
  const double beta = glove::degToRad(link1.corner_deg);
  GloveAnalysis a;
  const GloveFinger& f = model.finger;
  const glove::MechanismGeometry<double>& m = model.mech;
  for (std::size_t i = 0; i < 3; ++i) {
    a.alpha_min_deg[i] = std::numeric_limits<double>::infinity();
    a.alpha_max_deg[i] = -std::numeric_limits<double>::infinity();
  }
  a.min_abs_sin_alpha2 = 1.0;
  double z2_sum2 = 0;
  std::size_t reachable = 0;
  for (std::size_t i0 = 0; i0 < g.n[0]; ++i0) {
    for (std::size_t i1 = 0; i1 < g.n[1]; ++i1) {
      for (std::size_t i2 = 0; i2 < g.n[2]; ++i2) {
        const Vec3d th{gridValue(f.theta_min_rad[0], f.theta_max_rad[0], i0, g.n[0]),
                       gridValue(f.theta_min_rad[1], f.theta_max_rad[1], i1, g.n[1]),
                       gridValue(f.theta_min_rad[2], f.theta_max_rad[2], i2, g.n[2])};
        ++a.poses;
        Vec3d al{};
        const glove::Status st = glove::alphaFromTheta(model, th, al);
        // Finger points A0..A3 (eq 3–4 right-hand side, link by link).
        const double t1 = th[0], t12 = t1 + th[1], phi = t12 + th[2];
        const P2 A0{0, 0}, A1{f.p1_m * std::cos(t1), f.p1_m * std::sin(t1)};
        const P2 A2{A1[0] + f.p2_m * std::cos(t12), A1[1] + f.p2_m * std::sin(t12)};
        const P2 A3{A2[0] + f.p3_m * std::cos(phi), A2[1] + f.p3_m * std::sin(phi)};
        if (!glove::isUsable(st)) {
          ++a.unreachable;
          // B2 from the finger side (eq 3–4: A3 = B3 + l_p n_φ, B3 = B2 + l3 d_φ), distance to the (l1, l2)
          // annulus around B0.
          const double bx = A3[0] - m.l3_m * std::cos(phi) + m.l_p_m * std::sin(phi) - m.x_B0_m;
          const double by = A3[1] - m.l3_m * std::sin(phi) - m.l_p_m * std::cos(phi) - m.y_B0_m;
          const double d = std::hypot(bx, by);
          a.reach_violation_mm += (std::max(0.0, d - (m.l1_m + m.l2_m)) + std::max(0.0, std::fabs(m.l1_m - m.l2_m) - d)) / kMm;
          continue;
        }
        ++reachable;
        bool outside = false;
        for (std::size_t k = 0; k < 3; ++k) {
          const double deg = glove::radToDeg(al[k]);
          a.alpha_min_deg[k] = std::min(a.alpha_min_deg[k], deg);
          a.alpha_max_deg[k] = std::max(a.alpha_max_deg[k], deg);
          if (check_mech_limits && (al[k] < m.alpha_min_rad[k] - 1e-9 || al[k] > m.alpha_max_rad[k] + 1e-9)) outside = true;
        }
        if (outside) ++a.outside_limits;
        // z2 (eq 19): second row of J_α^u (eq 18 with f_x = f_z = 0).
        const glove::Mat3<double> J = glove::jacobianAlphaU(m, al);
        const double z2 = std::sqrt(J[1][0] * J[1][0] + J[1][1] * J[1][1] + J[1][2] * J[1][2]) / kMm;
        z2_sum2 += z2 * z2;
        a.z2_max_mm = std::max(a.z2_max_mm, z2);
        // Eq 24 margin.
        const double s2 = std::fabs(std::sin(al[1]));
        if (s2 < a.min_abs_sin_alpha2) {
          a.min_abs_sin_alpha2 = s2;
          a.alpha2_at_min_margin_deg = glove::radToDeg(al[1]);
        }
        // Mechanism points B0..B3 and the §3.6 segment pairs.
        const double a1 = al[0], a12 = a1 + al[1], a123 = a12 + al[2];
        const P2 B0{m.x_B0_m, m.y_B0_m}, B1{B0[0] + m.l1_m * std::cos(a1), B0[1] + m.l1_m * std::sin(a1)};
        const P2 B2{B1[0] + m.l2_m * std::cos(a12), B1[1] + m.l2_m * std::sin(a12)};
        const P2 B3{B2[0] + m.l3_m * std::cos(a123), B2[1] + m.l3_m * std::sin(a123)};
        double d1 = 0;
        if (beta > 0) {
          const P2 K{B0[0] + m.l1_m * std::cos(beta) * std::cos(a1 + beta),
                     B0[1] + m.l1_m * std::cos(beta) * std::sin(a1 + beta)};
          d1 = std::max(segmentCrossingDepth(B0, K, A0, A1), segmentCrossingDepth(K, B1, A0, A1));
        } else {
          d1 = segmentCrossingDepth(B0, B1, A0, A1);
        }
        const std::array<double, 3> depth{d1, segmentCrossingDepth(B1, B2, A1, A2),
                                          segmentCrossingDepth(B2, B3, A2, A3)};
        bool any = false;
        for (std::size_t k = 0; k < 3; ++k) {
          if (depth[k] > 0) {
            ++a.colliding[k];
            any = true;
            a.collision_depth_mm += depth[k] / kMm;
          }
        }
        if (any) ++a.colliding_any;
      }
    }
  }
  if (reachable == 0) {
    a.alpha_min_deg = a.alpha_max_deg = Vec3d{};
    a.min_abs_sin_alpha2 = 0;
  }
  double z1sq = 0;
  for (std::size_t k = 0; k < 3; ++k) {
    a.alpha_var_deg[k] = a.alpha_max_deg[k] - a.alpha_min_deg[k];
    z1sq += a.alpha_var_deg[k] * a.alpha_var_deg[k];
  }
  a.z1_deg = std::sqrt(z1sq);  // eq 17
  a.z2_rms_mm = reachable ? std::sqrt(z2_sum2 / static_cast<double>(reachable)) : 0.0;
  a.finger_inside_mechanism = a.unreachable == 0 && a.outside_limits == 0;
  return a;
}

WorkspaceClouds sweepWorkspaces(const GloveModel& model, const SweepGrid& fg, const Vec3d& lo, const Vec3d& hi,
                                std::size_t steps) {
  WorkspaceClouds c;
  const GloveFinger& f = model.finger;
  for (std::size_t i0 = 0; i0 < fg.n[0]; ++i0)
    for (std::size_t i1 = 0; i1 < fg.n[1]; ++i1)
      for (std::size_t i2 = 0; i2 < fg.n[2]; ++i2) {
        const Vec3d th{gridValue(f.theta_min_rad[0], f.theta_max_rad[0], i0, fg.n[0]),
                       gridValue(f.theta_min_rad[1], f.theta_max_rad[1], i1, fg.n[1]),
                       gridValue(f.theta_min_rad[2], f.theta_max_rad[2], i2, fg.n[2])};
        const Vec3d u = glove::tipPoseFromTheta(f, th);
        c.finger_mm.push_back({u[0] / kMm, u[1] / kMm});
      }
  for (std::size_t i0 = 0; i0 < steps; ++i0)
    for (std::size_t i1 = 0; i1 < steps; ++i1)
      for (std::size_t i2 = 0; i2 < steps; ++i2) {
        const Vec3d al{glove::degToRad(gridValue(lo[0], hi[0], i0, steps)),
                       glove::degToRad(gridValue(lo[1], hi[1], i1, steps)),
                       glove::degToRad(gridValue(lo[2], hi[2], i2, steps))};
        const Vec3d u = glove::tipPoseFromAlpha(model.mech, al);
        c.mechanism_mm.push_back({u[0] / kMm, u[1] / kMm});
      }
  return c;
}

std::string writeWorkspaceSvg(const WorkspaceClouds& clouds, const std::string& title, const std::string& path) {
  SvgPlot plot(title, "x_O (mm, distal)", "y_O (mm, dorsal)", 640, 560);
  plot.setEqualAspect(true);
  plot.addScatter(clouds.mechanism_mm, "#b0b0b0", "glove mechanism (alpha sweep)", 1.0, 0.35);
  plot.addScatter(clouds.finger_mm, "#1f5fbf", "finger (theta sweep, Table 2)", 1.0, 0.6);
  return plot.write(path);
}

// -------------------------------------------------------------------------------------------------------------
// Optimisation
// -------------------------------------------------------------------------------------------------------------

GloveOptOptions defaultGloveOptOptions() {
  GloveOptOptions o;
  const GloveModel m = glove::defaultIndexModel<double>();
  o.fingers = {m.finger};
  o.l_p_m = m.mech.l_p_m;
  o.x_B0_m = m.mech.x_B0_m;
  o.y_B0_m = m.mech.y_B0_m;
  return o;
}

GloveModel makeGloveModel(const GloveFinger& finger, const Vec3d& l_mm, const GloveOptOptions& opt) {
  GloveModel m{};
  m.finger = finger;
  m.mech.l1_m = l_mm[0] * kMm;
  m.mech.l2_m = l_mm[1] * kMm;
  m.mech.l3_m = l_mm[2] * kMm;
  m.mech.l_p_m = opt.l_p_m;
  m.mech.x_B0_m = opt.x_B0_m;
  m.mech.y_B0_m = opt.y_B0_m;
  return m;
}

std::vector<std::string> gloveConstraintNames() {
  return {"g1 (eq 20) sum(p) - sum(l) [mm]",   "g2 (eq 21) p1 - l1 [mm]",
          "g3 (eq 22) alpha1_var - max [deg]", "g3 (eq 22) alpha2_var - max [deg]",
          "g3 (eq 22) alpha3_var - max [deg]", "reach: sum of out-of-reach distances [mm]",
          "collision (3.6): sum of crossing depths [mm]"};
}

double gloveObjective(const Vec3d& l_mm, const GloveOptOptions& opt, std::vector<double>* c, double* z1_out,
                      double* z2_out) {
  const std::size_t nc = gloveConstraintNames().size();
  std::vector<double> cons(nc, -std::numeric_limits<double>::infinity());
  double Z = 0, z1m = 0, z2m = 0;
  for (const GloveFinger& f : opt.fingers) {
    const GloveAnalysis a = analyseGlove(makeGloveModel(f, l_mm, opt), opt.grid, false, opt.link1);
    const double p_sum = (f.p1_m + f.p2_m + f.p3_m) / kMm;
    const double vals[] = {p_sum - (l_mm[0] + l_mm[1] + l_mm[2]),
                           f.p1_m / kMm - l_mm[0],
                           a.alpha_var_deg[0] - opt.max_joint_range_deg,
                           a.alpha_var_deg[1] - opt.max_joint_range_deg,
                           a.alpha_var_deg[2] - opt.max_joint_range_deg,
                           a.reach_violation_mm,
                           opt.collision_constraint ? a.collision_depth_mm : 0.0};
    for (std::size_t k = 0; k < nc; ++k) cons[k] = std::max(cons[k], vals[k]);
    z1m += a.z1_deg;
    z2m += a.z2_rms_mm;
  }
  const double nf = static_cast<double>(std::max<std::size_t>(1, opt.fingers.size()));
  z1m /= nf;
  z2m /= nf;
  Z = opt.w1 * z1m + opt.w2 * z2m;  // eq 23
  if (c) *c = cons;
  if (z1_out) *z1_out = z1m;
  if (z2_out) *z2_out = z2m;
  return Z;
}

namespace {
struct SolveContext {
  const GloveOptOptions* opt = nullptr;
  std::size_t evals = 0;
  // Memo of the last point: NLopt asks for objective and constraints at the same x.
  Vec3d last_x{-1, -1, -1};
  double last_Z = 0;
  std::vector<double> last_c;
  void eval(const double* x) {
    const Vec3d l{x[0], x[1], x[2]};
    if (l == last_x) return;
    ++evals;
    last_Z = gloveObjective(l, *opt, &last_c);
    last_x = l;
  }
};

double objectiveFn(unsigned n, const double* x, double* grad, void* data) {
  auto* ctx = static_cast<SolveContext*>(data);
  ctx->eval(x);
  if (grad) {
    // Central differences, 0.05 mm (SLSQP only).
    const double f0 = ctx->last_Z;
    for (unsigned i = 0; i < n; ++i) {
      double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
      xp[i] += 0.05;
      xm[i] -= 0.05;
      grad[i] = (gloveObjective({xp[0], xp[1], xp[2]}, *ctx->opt, nullptr) -
                 gloveObjective({xm[0], xm[1], xm[2]}, *ctx->opt, nullptr)) / 0.1;
    }
    ctx->eval(x);
    (void)f0;
  }
  return ctx->last_Z;
}

void constraintFn(unsigned m, double* result, unsigned n, const double* x, double* grad, void* data) {
  auto* ctx = static_cast<SolveContext*>(data);
  ctx->eval(x);
  for (unsigned k = 0; k < m; ++k) result[k] = ctx->last_c[k];
  if (grad) {
    std::vector<double> cp, cm;
    for (unsigned i = 0; i < n; ++i) {
      double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
      xp[i] += 0.05;
      xm[i] -= 0.05;
      gloveObjective({xp[0], xp[1], xp[2]}, *ctx->opt, &cp);
      gloveObjective({xm[0], xm[1], xm[2]}, *ctx->opt, &cm);
      for (unsigned k = 0; k < m; ++k) grad[k * n + i] = (cp[k] - cm[k]) / 0.1;
    }
    ctx->eval(x);
  }
}

double halton(std::size_t i, std::size_t base) {
  double f = 1, r = 0;
  while (i > 0) {
    f /= static_cast<double>(base);
    r += f * static_cast<double>(i % base);
    i /= base;
  }
  return r;
}

bool feasible(const std::vector<double>& c) {
  // 1e-6 mm / deg: the tolerance handed to NLopt below.
  for (double v : c)
    if (!(v <= 1e-6)) return false;
  return true;
}
}  // namespace

GloveOptResult optimiseGlove(const GloveOptOptions& opt) {
  GloveOptResult res;
  res.constraint_names = gloveConstraintNames();
  // §3.7: bounds p ≤ l ≤ 2p, initial guess 1.5 p (element-wise largest finger for a population).
  Vec3d p_mm{};
  for (const GloveFinger& f : opt.fingers) {
    p_mm[0] = std::max(p_mm[0], f.p1_m / kMm);
    p_mm[1] = std::max(p_mm[1], f.p2_m / kMm);
    p_mm[2] = std::max(p_mm[2], f.p3_m / kMm);
  }
  double lb[3], ub[3];
  for (int i = 0; i < 3; ++i) lb[i] = p_mm[i], ub[i] = 2 * p_mm[i];
  const unsigned nc = static_cast<unsigned>(res.constraint_names.size());
  std::vector<double> tol(nc, 1e-6);
  double best_Z = std::numeric_limits<double>::infinity();
  for (std::size_t s = 0; s < std::max<std::size_t>(1, opt.starts); ++s) {
    double x[3];
    for (int i = 0; i < 3; ++i) {
      x[i] = s == 0 ? 1.5 * p_mm[i] : lb[i] + (ub[i] - lb[i]) * halton(s + opt.seed, i == 0 ? 2 : i == 1 ? 3 : 5);
    }
    GloveOptStart st;
    st.l0_mm = {x[0], x[1], x[2]};
    SolveContext ctx;
    ctx.opt = &opt;
    nlopt_opt o = nlopt_create(opt.use_slsqp ? NLOPT_LD_SLSQP : NLOPT_LN_COBYLA, 3);
    nlopt_set_lower_bounds(o, lb);
    nlopt_set_upper_bounds(o, ub);
    nlopt_set_min_objective(o, objectiveFn, &ctx);
    nlopt_add_inequality_mconstraint(o, nc, constraintFn, &ctx, tol.data());
    nlopt_set_xtol_rel(o, opt.xtol_rel);
    nlopt_set_maxeval(o, static_cast<int>(opt.max_evals));
    const double step[3] = {0.1 * p_mm[0], 0.1 * p_mm[1], 0.1 * p_mm[2]};
    nlopt_set_initial_step(o, step);
    double f = 0;
    st.nlopt_result = nlopt_optimize(o, x, &f);
    nlopt_destroy(o);
    st.l_mm = {x[0], x[1], x[2]};
    std::vector<double> c;
    st.Z = gloveObjective(st.l_mm, opt, &c);
    st.feasible = feasible(c);
    st.evals = ctx.evals;
    res.starts.push_back(st);
    if (st.feasible && st.Z < best_Z) {
      best_Z = st.Z;
      res.l_mm = st.l_mm;
      res.feasible = true;
    }
  }
  if (!res.feasible) {
    // Report the least-infeasible start so the caller can see why.
    double least = std::numeric_limits<double>::infinity();
    for (const GloveOptStart& st : res.starts) {
      std::vector<double> c;
      gloveObjective(st.l_mm, opt, &c);
      double v = 0;
      for (double ci : c) v += std::max(0.0, ci);
      if (v < least) least = v, res.l_mm = st.l_mm;
    }
  }
  res.Z = gloveObjective(res.l_mm, opt, &res.constraint_values, &res.z1_deg, &res.z2_mm);
  res.analysis = analyseGlove(makeGloveModel(opt.fingers.front(), res.l_mm, opt), opt.grid, false, opt.link1);
  return res;
}

// -------------------------------------------------------------------------------------------------------------
// YAML
// -------------------------------------------------------------------------------------------------------------

std::string gloveGeometryYaml(const GloveModel& m, const GloveAnalysis& a, const std::string& comment) {
  YAML::Emitter e;
  e.SetDoublePrecision(8);
  e << YAML::Comment(comment);
  e << YAML::BeginMap;
  e << YAML::Key << "glove_finger_geometry" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "units" << YAML::Value << "mm, deg";
  e << YAML::Key << "finger" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "p_mm" << YAML::Value << YAML::Flow
    << std::vector<double>{m.finger.p1_m / kMm, m.finger.p2_m / kMm, m.finger.p3_m / kMm};
  e << YAML::Key << "theta_min_deg" << YAML::Value << YAML::Flow
    << std::vector<double>{glove::radToDeg(m.finger.theta_min_rad[0]), glove::radToDeg(m.finger.theta_min_rad[1]),
                           glove::radToDeg(m.finger.theta_min_rad[2])};
  e << YAML::Key << "theta_max_deg" << YAML::Value << YAML::Flow
    << std::vector<double>{glove::radToDeg(m.finger.theta_max_rad[0]), glove::radToDeg(m.finger.theta_max_rad[1]),
                           glove::radToDeg(m.finger.theta_max_rad[2])};
  e << YAML::EndMap;
  e << YAML::Key << "mechanism" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "l_mm" << YAML::Value << YAML::Flow
    << std::vector<double>{m.mech.l1_m / kMm, m.mech.l2_m / kMm, m.mech.l3_m / kMm};
  e << YAML::Key << "l_p_mm" << YAML::Value << m.mech.l_p_m / kMm;
  e << YAML::Key << "B0_mm" << YAML::Value << YAML::Flow << std::vector<double>{m.mech.x_B0_m / kMm, m.mech.y_B0_m / kMm};
  // Joint limits: the swept range rounded outwards to whole degrees (as glove::defaultModel stores them).
  e << YAML::Key << "alpha_min_deg" << YAML::Value << YAML::Flow
    << std::vector<double>{std::floor(a.alpha_min_deg[0]), std::floor(a.alpha_min_deg[1]), std::floor(a.alpha_min_deg[2])};
  e << YAML::Key << "alpha_max_deg" << YAML::Value << YAML::Flow
    << std::vector<double>{std::ceil(a.alpha_max_deg[0]), std::ceil(a.alpha_max_deg[1]), std::ceil(a.alpha_max_deg[2])};
  e << YAML::EndMap;
  e << YAML::Key << "analysis" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "alpha_var_deg" << YAML::Value << YAML::Flow
    << std::vector<double>{a.alpha_var_deg[0], a.alpha_var_deg[1], a.alpha_var_deg[2]};
  e << YAML::Key << "z1_deg" << YAML::Value << a.z1_deg;
  e << YAML::Key << "z2_rms_mm" << YAML::Value << a.z2_rms_mm;
  e << YAML::Key << "min_abs_sin_alpha2" << YAML::Value << a.min_abs_sin_alpha2;
  e << YAML::Key << "unreachable_poses" << YAML::Value << a.unreachable;
  e << YAML::Key << "colliding_poses" << YAML::Value << a.colliding_any;
  e << YAML::Key << "poses" << YAML::Value << a.poses;
  e << YAML::EndMap;
  e << YAML::EndMap << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

std::string loadGloveGeometryYaml(const std::string& path, GloveModel& out) {
  std::ifstream in(path);
  std::stringstream text;
  if (!in || !(text << in.rdbuf())) return "cannot read '" + path + "': bad file: " + path;
  return loadGloveGeometryText(text.str(), path, out);
}

std::string loadGloveGeometryText(const std::string& yaml_text, const std::string& path, GloveModel& out) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const std::exception& ex) {
    return "cannot read '" + path + "': " + ex.what();
  }
  if (std::string dup = findDuplicateKey(root); !dup.empty()) return path + ": " + dup;
  // Mappings checked before they are indexed: yaml-cpp throws on operator[] of a scalar.
  const YAML::Node g = root.IsMap() ? root["glove_finger_geometry"] : YAML::Node();
  if (!g) return path + ": missing 'glove_finger_geometry'";
  if (!g.IsMap()) return path + ": 'glove_finger_geometry' must be a mapping";
  auto requireMapping = [&](const char* section) -> std::string {
    if (g[section] && g[section].IsMap()) return "";
    return path + ": 'glove_finger_geometry." + section + "' must be a mapping";
  };
  auto vec = [&](const YAML::Node& n, std::size_t size, const char* name, std::vector<double>& v) -> std::string {
    if (!n || !n.IsSequence() || n.size() != size) return path + ": '" + name + "' must be a list of " + std::to_string(size);
    v.clear();
    for (const auto& x : n) {
      double d = 0;
      try {
        d = x.as<double>();
      } catch (const std::exception&) {
        return path + ": '" + name + "' has a non-number";
      }
      if (!std::isfinite(d)) return path + ": '" + name + "' has a non-finite value";
      v.push_back(d);
    }
    return "";
  };
  std::vector<double> p, tmin, tmax, l, b0, amin, amax;
  std::string err;
  if (!(err = requireMapping("finger")).empty()) return err;
  if (!(err = vec(g["finger"]["p_mm"], 3, "finger.p_mm", p)).empty()) return err;
  if (!(err = vec(g["finger"]["theta_min_deg"], 3, "finger.theta_min_deg", tmin)).empty()) return err;
  if (!(err = vec(g["finger"]["theta_max_deg"], 3, "finger.theta_max_deg", tmax)).empty()) return err;
  if (!(err = requireMapping("mechanism")).empty()) return err;
  if (!(err = vec(g["mechanism"]["l_mm"], 3, "mechanism.l_mm", l)).empty()) return err;
  if (!(err = vec(g["mechanism"]["B0_mm"], 2, "mechanism.B0_mm", b0)).empty()) return err;
  if (!(err = vec(g["mechanism"]["alpha_min_deg"], 3, "mechanism.alpha_min_deg", amin)).empty()) return err;
  if (!(err = vec(g["mechanism"]["alpha_max_deg"], 3, "mechanism.alpha_max_deg", amax)).empty()) return err;
  double lp = 0;
  try {
    lp = g["mechanism"]["l_p_mm"].as<double>();
  } catch (const std::exception&) {
    return path + ": 'mechanism.l_p_mm' missing or not a number";
  }
  if (!std::isfinite(lp)) return path + ": 'mechanism.l_p_mm' has a non-finite value";
  for (int i = 0; i < 3; ++i) {
    if (!(p[i] > 0) || !(l[i] > 0)) return path + ": link lengths must be > 0 mm";
    if (!(tmin[i] < tmax[i]) || !(amin[i] < amax[i])) return path + ": every joint range needs min < max";
  }
  GloveModel m{};
  m.finger.p1_m = p[0] * kMm, m.finger.p2_m = p[1] * kMm, m.finger.p3_m = p[2] * kMm;
  for (std::size_t i = 0; i < 3; ++i) {
    m.finger.theta_min_rad[i] = glove::degToRad(tmin[i]);
    m.finger.theta_max_rad[i] = glove::degToRad(tmax[i]);
    m.mech.alpha_min_rad[i] = glove::degToRad(amin[i]);
    m.mech.alpha_max_rad[i] = glove::degToRad(amax[i]);
  }
  m.mech.l1_m = l[0] * kMm, m.mech.l2_m = l[1] * kMm, m.mech.l3_m = l[2] * kMm;
  m.mech.l_p_m = lp * kMm;
  m.mech.x_B0_m = b0[0] * kMm, m.mech.y_B0_m = b0[1] * kMm;
  out = m;
  return "";
}

}  // namespace phalanx::host::design
