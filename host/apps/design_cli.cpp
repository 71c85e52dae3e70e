#include "design_cli.h"

#include "cli_args.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "phalanx/host/design/glove_design.h"
#include "phalanx/host/design/pen_gii.h"
#include "phalanx/host/design/pen_geometry.h"
#include "phalanx/host/design/svg.h"
#include "phalanx/host/progress.h"

namespace phalanx::host {

namespace d = phalanx::host::design;

namespace {
nlohmann::json vec3(const d::Vec3d& v) { return nlohmann::json::array({v[0], v[1], v[2]}); }

nlohmann::json analysisJson(const d::GloveAnalysis& a) {
  return {{"poses", a.poses},
          {"unreachable", a.unreachable},
          {"outside_mechanism_limits", a.outside_limits},
          {"colliding_per_pair", {a.colliding[0], a.colliding[1], a.colliding[2]}},
          {"colliding_any", a.colliding_any},
          {"collision_depth_sum_mm", a.collision_depth_mm},
          {"alpha_min_deg", vec3(a.alpha_min_deg)},
          {"alpha_max_deg", vec3(a.alpha_max_deg)},
          {"alpha_var_deg", vec3(a.alpha_var_deg)},
          {"z1_deg", a.z1_deg},
          {"z2_rms_mm", a.z2_rms_mm},
          {"z2_max_mm", a.z2_max_mm},
          {"min_abs_sin_alpha2", a.min_abs_sin_alpha2},
          {"alpha2_at_min_margin_deg", a.alpha2_at_min_margin_deg},
          {"finger_inside_mechanism", a.finger_inside_mechanism}};
}

glove::FingerId fingerId(const std::string& s) {
  if (s == "thumb") return glove::FingerId::kThumb;
  if (s == "middle") return glove::FingerId::kMiddle;
  if (s == "ring") return glove::FingerId::kRing;
  if (s == "little") return glove::FingerId::kLittle;
  return glove::FingerId::kIndex;
}

bool writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  if (!f) {
    std::fprintf(stderr, "phalanx design: error: cannot write '%s'\n", path.c_str());
    return false;
  }
  return true;
}
}  // namespace

struct DesignCommands::Impl {
  CLI::App* design = nullptr;
  // glove-workspace
  CLI::App* gw = nullptr;
  std::string finger = "index";
  std::string geometry_yaml;  // optional input geometry
  std::string svg_path, yaml_path;
  std::size_t grid = 41;
  std::size_t plot_grid = 15;
  // glove-optimize
  CLI::App* go = nullptr;
  double p1 = 0, p2 = 0, p3 = 0;
  std::vector<double> population_scales;
  std::size_t starts = 6, opt_grid = 13;
  bool slsqp = false, no_collision = false;
  double w1 = 1, w2 = 1;
  double corner_deg = 45;

  // pen-gii
  CLI::App* pg = nullptr;
  std::string r_l1, r_l2, r_l3, r_l6, r_q1, r_wi, r_wj, r_wk, mode = "force";
  double distance_cm = 25, tilt_deg = 45;
  std::size_t rings = 0;
  unsigned threads = 2;
  bool exhaustive = false, compare = false, velocity_literal_inverse = false;
  double progress_s = 5;
  std::vector<double> eval_design;
  std::string pen_yaml_path;

  // pen-gii-plot
  CLI::App* pp = nullptr;
  std::vector<std::string> plot_inputs;

  int runGloveWorkspace();
  int runPenGiiPlot();
  int runPenGii();
  int runGloveOptimize();
};

DesignCommands::DesignCommands(CLI::App& app) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.design = app.add_subcommand("design", "design tools: glove link lengths (000 §3), pen GII/culling (004 §IV-VI)");
  m.design->require_subcommand(1);
  m.design->option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);

  m.gw = m.design->add_subcommand("glove-workspace",
                                  "finger vs mechanism workspace, alpha ranges, collisions, eq 24 margin (000 §4.1)");
  m.gw->add_option("--finger", m.finger, "thumb|index|middle|ring|little (controller default geometry)")
      ->check(CLI::IsMember({"thumb", "index", "middle", "ring", "little"}));
  m.gw->add_option("--geometry", m.geometry_yaml, "geometry YAML written by glove-optimize (instead of --finger)")
      ->check(CLI::ExistingFile);
  m.gw->add_option("--grid", m.grid, "theta samples per finger joint")->check(cli::inRange(2, 201));
  m.gw->add_option("--svg", m.svg_path, "write the Fig. 6 workspace plot here");
  m.gw->add_option("--yaml", m.yaml_path, "write the device geometry YAML here");
  m.gw->add_option("--plot-grid", m.plot_grid, "samples per joint in the SVG point clouds")->check(cli::inRange(3, 61));

  m.go = m.design->add_subcommand("glove-optimize", "link-length optimisation, eq 17-23 (000 §3.7), NLopt");
  m.go->add_option("--p1", m.p1, "proximal phalanx (mm; default Table 2: 48.3)")->check(cli::inRange(10.0, 120.0))->default_str("");
  m.go->add_option("--p2", m.p2, "middle phalanx (mm; default 28.2)")->check(cli::inRange(5.0, 80.0))->default_str("");
  m.go->add_option("--p3", m.p3, "distal phalanx (mm; default 19.1)")->check(cli::inRange(5.0, 60.0))->default_str("");
  m.go->add_option("--population", m.population_scales,
                   "design for a population: finger scale factors, e.g. 0.9 1.0 1.1 (3.3 stochastic workspace)")
      ->check(cli::inRange(0.5, 1.5));
  m.go->add_option("--starts", m.starts, "multi-start count")->check(cli::inRange(1, 64));
  m.go->add_option("--grid", m.opt_grid, "theta samples per finger joint in the objective")->check(cli::inRange(3, 61));
  m.go->add_option("--w1", m.w1, "eq 23 weight of z1")->check(cli::inRange(0.0, 100.0));
  m.go->add_option("--w2", m.w2, "eq 23 weight of z2")->check(cli::inRange(0.0, 100.0));
  m.go->add_flag("--slsqp", m.slsqp, "SLSQP with finite-difference gradients instead of COBYLA");
  m.go->add_option("--link1-corner-deg", m.corner_deg, "L-shaped link 1 in the collision test (0: straight chord)")
      ->check(cli::inRange(0.0, 80.0));
  m.gw->add_option("--link1-corner-deg", m.corner_deg, "L-shaped link 1 in the collision test (0: straight chord)")
      ->check(cli::inRange(0.0, 80.0));
  m.go->add_flag("--no-collision", m.no_collision, "drop the 3.6 collision constraint");
  m.go->add_option("--svg", m.svg_path, "write the workspace plot of the optimum here");
  m.go->add_option("--yaml", m.yaml_path, "write the optimum device geometry YAML here");
  m.go->add_option("--plot-grid", m.plot_grid, "samples per joint in the SVG point clouds")->check(cli::inRange(3, 61));

  m.pg = m.design->add_subcommand("pen-gii", "Twin-Pantograph GII optimum by culling (004 eq 10-19, Tables VI-IX)");
  const char* range_help = "range min:max:step (cm; Q1 unitless)";
  m.pg->add_option("--l1", m.r_l1, range_help);
  m.pg->add_option("--l2", m.r_l2, range_help);
  m.pg->add_option("--l3", m.r_l3, range_help);
  m.pg->add_option("--l6", m.r_l6, range_help);
  m.pg->add_option("--q1", m.r_q1, range_help);
  m.pg->add_option("--wi", m.r_wi, "workspace i range (cm, default Table VI 0:8:0.5)");
  m.pg->add_option("--wj", m.r_wj, "workspace j range (cm, default 0:5:0.5)");
  m.pg->add_option("--wk", m.r_wk, "workspace k range around the centre (cm, default -5:5:0.5)");
  m.pg->add_option("--distance-cm", m.distance_cm, "workspace centre distance along k (Table VII: 25)")
      ->check(cli::inRange(5.0, 100.0));
  m.pg->add_option("--tilt-deg", m.tilt_deg, "orientation workspace half-angle")->check(cli::inRange(0.0, 80.0));
  m.pg->add_option("--rings", m.rings, "eq 16 rings N (0: eq 15)")->check(cli::inRange(0, 200));
  m.pg->add_option("--mode", m.mode, "force (eq 19) | velocity (eq 26-27, Table IX)")
      ->check(CLI::IsMember({"force", "velocity"}));
  m.pg->add_flag("--velocity-literal-inverse", m.velocity_literal_inverse,
                 "velocity mode: S_J J S_T^-1 with eq 27's S_T literally (default S_J J S_T)");
  m.pg->add_option("--threads", m.threads, "worker threads")->check(cli::inRange(1, 64));
  m.pg->add_option("--yaml", m.pen_yaml_path,
                   "write the optimum as a pen geometry YAML (phalanx run --pen-geometry / config pen.geometry)");
  m.pg->add_flag("--exhaustive", m.exhaustive, "exhaustive search instead of culling");
  m.pg->add_flag("--compare", m.compare, "run both and check they agree");
  m.pg->add_option("--progress-s", m.progress_s, "progress with the time left on stderr every N s, also inside a round (0: none)")
      ->check(cli::inRange(0.0, 3600.0));
  m.pg->add_option("--eval", m.eval_design, "also report the exact GII of this design: l1 l2 l3 l6 Q1")
      ->expected(5)
      ->multi_option_policy(CLI::MultiOptionPolicy::Throw);  // not the design's TakeLast: 2 or 6 values are an error

  m.pp = m.design->add_subcommand("pen-gii-plot", "plot GII vs workspace distance (004 Fig. 15) from pen-gii JSON outputs");
  m.pp->add_option("inputs", m.plot_inputs, "pen-gii JSON files (any distances, force or velocity mode)")
      ->required()
      ->check(CLI::ExistingFile);
  m.pp->add_option("--svg", m.svg_path, "output SVG")->required();
}

DesignCommands::~DesignCommands() = default;

bool DesignCommands::parsed() const { return impl_->design->parsed(); }

int DesignCommands::run() {
  Impl& m = *impl_;
  if (m.gw->parsed()) return m.runGloveWorkspace();
  if (m.go->parsed()) return m.runGloveOptimize();
  if (m.pg->parsed()) return m.runPenGii();
  if (m.pp->parsed()) return m.runPenGiiPlot();
  return 2;
}

int DesignCommands::Impl::runGloveWorkspace() {
  d::GloveModel model = glove::defaultModel<double>(fingerId(finger));
  std::string source = "controller default (" + finger + ")";
  if (!geometry_yaml.empty()) {
    if (const std::string err = d::loadGloveGeometryYaml(geometry_yaml, model); !err.empty()) {
      std::fprintf(stderr, "phalanx design: error: %s\n", err.c_str());
      return 2;
    }
    source = geometry_yaml;
  }
  const std::size_t g3 = std::max<std::size_t>(2, grid * 2 / 3);
  const d::GloveAnalysis a = d::analyseGlove(model, d::SweepGrid{{grid, grid, g3}}, true, d::Link1Shape{corner_deg});
  nlohmann::json out = {{"geometry", source},
                        {"l_mm", {model.mech.l1_m * 1e3, model.mech.l2_m * 1e3, model.mech.l3_m * 1e3}},
                        {"analysis", analysisJson(a)}};
  if (!svg_path.empty()) {
    // Fig. 6's α box for the mechanism cloud: the mechanism's declared joint limits.
    const d::Vec3d lo{glove::radToDeg(model.mech.alpha_min_rad[0]), glove::radToDeg(model.mech.alpha_min_rad[1]),
                      glove::radToDeg(model.mech.alpha_min_rad[2])};
    const d::Vec3d hi{glove::radToDeg(model.mech.alpha_max_rad[0]), glove::radToDeg(model.mech.alpha_max_rad[1]),
                      glove::radToDeg(model.mech.alpha_max_rad[2])};
    const d::WorkspaceClouds c = d::sweepWorkspaces(model, d::SweepGrid{{plot_grid, plot_grid, plot_grid * 2 / 3 + 1}}, lo, hi, plot_grid);
    if (const std::string err = d::writeWorkspaceSvg(c, "Finger and glove workspaces (000 Fig. 6): " + source, svg_path);
        !err.empty()) {
      std::fprintf(stderr, "phalanx design: error: %s\n", err.c_str());
      return 1;
    }
    out["svg"] = svg_path;
  }
  if (!yaml_path.empty()) {
    if (!writeText(yaml_path, d::gloveGeometryYaml(model, a, "glove finger geometry from " + source))) return 1;
    out["yaml"] = yaml_path;
  }
  std::cout << out.dump(2) << std::endl;
  return a.finger_inside_mechanism ? 0 : 3;
}

int DesignCommands::Impl::runGloveOptimize() {
  d::GloveOptOptions opt = d::defaultGloveOptOptions();
  d::GloveFinger f = opt.fingers.front();
  if (p1 > 0) f.p1_m = p1 * 1e-3;
  if (p2 > 0) f.p2_m = p2 * 1e-3;
  if (p3 > 0) f.p3_m = p3 * 1e-3;
  opt.fingers = {f};
  if (!population_scales.empty()) {
    opt.fingers.clear();
    for (double s : population_scales) {
      d::GloveFinger g = f;
      g.p1_m *= s, g.p2_m *= s, g.p3_m *= s;
      opt.fingers.push_back(g);
    }
  }
  opt.starts = starts;
  opt.grid = d::SweepGrid{{opt_grid, opt_grid, std::max<std::size_t>(3, opt_grid * 2 / 3)}};
  opt.use_slsqp = slsqp;
  opt.collision_constraint = !no_collision;
  opt.w1 = w1;
  opt.w2 = w2;
  opt.link1.corner_deg = corner_deg;
  const d::GloveOptResult r = d::optimiseGlove(opt);
  nlohmann::json starts_j = nlohmann::json::array();
  for (const auto& s : r.starts) {
    starts_j.push_back({{"l0_mm", vec3(s.l0_mm)}, {"l_mm", vec3(s.l_mm)}, {"Z", s.Z}, {"feasible", s.feasible},
                        {"nlopt_result", s.nlopt_result}, {"evaluations", s.evals}});
  }
  nlohmann::json cons = nlohmann::json::object();
  for (std::size_t k = 0; k < r.constraint_names.size(); ++k) cons[r.constraint_names[k]] = r.constraint_values[k];
  nlohmann::json out = {{"algorithm", slsqp ? "SLSQP" : "COBYLA"},
                        {"fingers", opt.fingers.size()},
                        {"l_mm", vec3(r.l_mm)},
                        {"feasible", r.feasible},
                        {"Z", r.Z},
                        {"z1_deg", r.z1_deg},
                        {"z2_rms_mm", r.z2_mm},
                        {"constraints_le_0", cons},
                        {"analysis_first_finger", analysisJson(r.analysis)},
                        {"starts", starts_j}};
  d::GloveModel best = d::makeGloveModel(opt.fingers.front(), r.l_mm, opt);
  if (!svg_path.empty()) {
    const d::WorkspaceClouds c =
        d::sweepWorkspaces(best, d::SweepGrid{{plot_grid, plot_grid, plot_grid * 2 / 3 + 1}}, r.analysis.alpha_min_deg,
                            r.analysis.alpha_max_deg, plot_grid);
    if (const std::string err = d::writeWorkspaceSvg(c, "Optimised glove (000 eq 23) vs finger", svg_path); !err.empty()) {
      std::fprintf(stderr, "phalanx design: error: %s\n", err.c_str());
      return 1;
    }
    out["svg"] = svg_path;
  }
  if (!yaml_path.empty()) {
    const d::GloveAnalysis fine = d::analyseGlove(best, d::SweepGrid{{61, 61, 41}}, false, opt.link1);
    if (!writeText(yaml_path, d::gloveGeometryYaml(best, fine, "glove finger geometry, phalanx design glove-optimize")))
      return 1;
    out["yaml"] = yaml_path;
  }
  std::cout << out.dump(2) << std::endl;
  return r.feasible ? 0 : 3;
}

namespace {
bool parseRange(const std::string& s, d::GridRange& r) {
  if (s.empty()) return true;
  double a = 0, b = 0, c = 0;
  char x = 0, y = 0;
  std::istringstream in(s);
  if (!(in >> a >> x >> b >> y >> c) || x != ':' || y != ':' || !(c > 0) || b < a) {
    std::fprintf(stderr, "phalanx design: error: range '%s' is not min:max:step with step > 0 and max >= min\n",
                 s.c_str());
    return false;
  }
  r = {a, b, c};
  return true;
}

/// One progress line on stderr. The exhaustive search knows its total; culling's depends on how fast the bounds
/// cull, so its estimate is for the pass under way.
void printSearchProgress(const d::SearchProgress& p) {
  std::string line = std::string("pen-gii ") + p.search + ": ";
  char b[256];
  if (std::string(p.search) == "exhaustive") {
    std::snprintf(b, sizeof b, "%.0f %% of %zu candidates, %.1f s elapsed", 100.0 * p.fraction, p.candidates,
                  p.elapsed_s);
    line += b;
    if (p.fraction > 0 && p.fraction < 1) line += ", ~" + ProgressLine::duration(p.elapsed_s * (1 - p.fraction) / p.fraction) + " left";
  } else {
    std::snprintf(b, sizeof b, "round %zu, %zu of %zu candidates alive, best GII ", p.round, p.alive, p.candidates);
    line += b;
    if (p.best_gii >= 0) {
      std::snprintf(b, sizeof b, "%.4f", p.best_gii);
      line += b;
    } else {
      line += "none yet";
    }
    std::snprintf(b, sizeof b, "; pass '%s' %.0f %%, %.1f s elapsed", p.pass, 100.0 * std::max(0.0, p.fraction),
                  p.elapsed_s);
    line += b;
    if (p.fraction > 0 && p.fraction < 1) {
      line += ", ~" + ProgressLine::duration(p.pass_elapsed_s * (1 - p.fraction) / p.fraction) + " left in this pass";
    }
  }
  std::fprintf(stderr, "%s\n", line.c_str());
  std::fflush(stderr);
}

nlohmann::json designJson(const d::PenDesign& p) {
  return {{"l1_cm", p.l1}, {"l2_cm", p.l2}, {"l3_cm", p.l3}, {"l6_cm", p.l6}, {"Q1", p.q1}};
}

nlohmann::json searchJson(const d::SearchResult& r, const d::TwinPantographGii& pb) {
  return {{"optimum", designJson(pb.design(r.best))}, {"candidate", r.best},      {"gii", r.gii},
          {"jacobian_evals", r.jacobian_evals},      {"sigma_evals", r.sigma_evals}, {"rounds", r.rounds},
          {"critical_samples", r.critical_samples},  {"seconds", r.seconds}};
}
}  // namespace

int DesignCommands::Impl::runPenGii() {
  d::PenGiiSpec spec;
  if (!parseRange(r_l1, spec.l1) || !parseRange(r_l2, spec.l2) || !parseRange(r_l3, spec.l3) ||
      !parseRange(r_l6, spec.l6) || !parseRange(r_q1, spec.q1) || !parseRange(r_wi, spec.wi) ||
      !parseRange(r_wj, spec.wj) || !parseRange(r_wk, spec.wk))
    return 2;
  spec.distance_cm = distance_cm;
  spec.tilt_max_deg = tilt_deg;
  spec.rings = rings;
  spec.mode = mode == "velocity" ? d::PenGiiMode::kVelocity : d::PenGiiMode::kForce;
  spec.velocity_literal_inverse = velocity_literal_inverse;
  std::unique_ptr<d::TwinPantographGii> pb;
  try {
    pb = std::make_unique<d::TwinPantographGii>(spec);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "phalanx design: error: %s\n", e.what());
    return 2;
  }
  nlohmann::json out = {{"mode", mode},
                        {"l6_reading", "centre to universal joint (pen length 2 l6), pen::endOffset"},
                        {"distance_cm", distance_cm},
                        {"candidates", pb->numCandidates()},
                        {"geometries", pb->numGroups()},
                        {"positions", pb->numPositions()},
                        {"orientations", pb->numOrientations()},
                        {"rings", pb->rings()},
                        {"workspace_samples", pb->numSamples()},
                        {"threads", threads}};
  d::SearchOptions so;
  so.threads = threads;
  so.progress_s = progress_s;
  so.progress = printSearchProgress;
  int rc = 0;
  if (exhaustive || compare) out["exhaustive"] = searchJson(d::exhaustiveSearch(*pb, so), *pb);
  if (!exhaustive || compare) out["culling"] = searchJson(d::cullingSearch(*pb, so), *pb);
  if (compare) {
    const bool same = out["exhaustive"]["candidate"] == out["culling"]["candidate"] &&
                      out["exhaustive"]["gii"] == out["culling"]["gii"];
    out["identical_optimum"] = same;
    if (!same) rc = 1;
  }
  if (!pen_yaml_path.empty()) {
    const nlohmann::json& best = out.contains("culling") ? out["culling"] : out["exhaustive"];
    const d::PenDesign o = pb->design(best["candidate"].get<std::size_t>());
    const double cm = 0.01;
    const phalanx::pen::Geometry<double> g{o.l1 * cm, o.l2 * cm, o.l3 * cm, spec.l4_cm * cm, o.l6 * cm,
                                           distance_cm * cm};
    const std::map<std::string, double> analysis{{"gii", best["gii"].get<double>()},
                                                 {"Q1_waist_to_shoulder", o.q1},
                                                 {"workspace_distance_cm", distance_cm},
                                                 {"workspace_samples", static_cast<double>(pb->numSamples())}};
    char comment[160];
    std::snprintf(comment, sizeof comment, "pen geometry, phalanx design pen-gii (%s GII optimum at %.1f cm)",
                  mode.c_str(), distance_cm);
    if (!writeText(pen_yaml_path, d::penGeometryYaml(g, comment, analysis))) return 1;
    // Read it back through the controller's loader: a file the controller would refuse is an error here.
    phalanx::pen::Geometry<double> back{};
    if (const std::string err = d::loadPenGeometryYaml(pen_yaml_path, back); !err.empty()) {
      std::fprintf(stderr, "phalanx design: error: the optimum is not a usable pen: %s\n", err.c_str());
      return 3;
    }
    out["yaml"] = pen_yaml_path;
  }
  if (eval_design.size() == 5) {
    const d::PenDesign e{eval_design[0], eval_design[1], eval_design[2], eval_design[3], eval_design[4]};
    out["evaluated"] = {{"design", designJson(e)}, {"gii", d::penGii(*pb, e)}};
  }
  std::cout << out.dump(2) << std::endl;
  return rc;
}

int DesignCommands::Impl::runPenGiiPlot() {
  std::vector<std::array<double, 2>> force, velocity;
  for (const std::string& path : plot_inputs) {
    std::ifstream f(path);
    nlohmann::json j;
    try {
      f >> j;
      const double dist = j.at("distance_cm").get<double>();
      const nlohmann::json& r = j.contains("culling") ? j.at("culling") : j.at("exhaustive");
      (j.at("mode") == "velocity" ? velocity : force).push_back({dist, r.at("gii").get<double>()});
    } catch (const std::exception& e) {
      std::fprintf(stderr, "phalanx design: error: %s is not a pen-gii output: %s\n", path.c_str(), e.what());
      return 2;
    }
  }
  auto byX = [](const std::array<double, 2>& a, const std::array<double, 2>& b) { return a[0] < b[0]; };
  std::sort(force.begin(), force.end(), byX);
  std::sort(velocity.begin(), velocity.end(), byX);
  d::SvgPlot plot("GII vs workspace distance (004 Table VIII/IX, Fig. 15)", "workspace distance (cm)", "GII");
  // Paper: Table VIII (force/torque) and Table IX (position sensing).
  plot.addLine({{15, 0.089}, {20, 0.182}, {25, 0.234}, {30, 0.262}, {35, 0.280}, {40, 0.292}}, "#999999",
               "paper Table VIII (force)");
  plot.addLine({{15, 0.105}, {20, 0.186}, {25, 0.232}, {30, 0.269}, {35, 0.285}, {40, 0.303}}, "#cccccc",
               "paper Table IX (velocity)");
  // Dots as well as a line: one finished run is one point, which a polyline alone does not show.
  if (!force.empty()) plot.addLine(force, "#1f5fbf", "this model, force (eq 19)", true);
  if (!velocity.empty()) plot.addLine(velocity, "#d9541e", "this model, velocity (eq 26-27)", true);
  if (const std::string err = plot.write(svg_path); !err.empty()) {
    std::fprintf(stderr, "phalanx design: error: %s\n", err.c_str());
    return 1;
  }
  std::cout << nlohmann::json{{"svg", svg_path}, {"force_points", force.size()}, {"velocity_points", velocity.size()}}.dump(2)
            << std::endl;
  return 0;
}

}  // namespace phalanx::host
