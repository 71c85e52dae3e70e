#include "phalanx/host/therapy/assessment_analysis.h"

#include <map>

#include "phalanx/host/therapy/guidance.h"
#include "phalanx/host/therapy/repeatability.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace phalanx::host::therapy {
namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr std::size_t kMinStretchCycles = 20;  // 20 ms: shorter decreasing runs are not a stretch
constexpr double kTailS = 0.1;                 // the finger still moves for a while after its target stopped
constexpr std::size_t kSlopeHalf = 10;         // ±10 cycles: the rate's least-squares window (±10 ms at 1 kHz)
// The samples fitted leave out the first 5° of a stretch (the device accelerating the finger) and its last 3°
// (decelerating it).
constexpr double kBaselineFrom = 5.0 * kDeg, kMargin = 3.0 * kDeg;

struct Span {
  std::size_t begin = 0, end = 0;  // [begin, end)
};

std::vector<Span> findStretches(const std::vector<double>& t, const std::vector<double>& target,
                                const std::vector<char>& in) {
  std::vector<Span> out;
  std::size_t i = 1;
  while (i < t.size()) {
    if (!(in[i] && in[i - 1] && target[i] < target[i - 1])) {
      ++i;
      continue;
    }
    Span s{i - 1, i};
    while (s.end < t.size() && in[s.end] && target[s.end] < target[s.end - 1]) ++s.end;
    i = s.end;
    while (s.end < t.size() && in[s.end] && t[s.end] - t[i - 1] < kTailS) ++s.end;
    if (i - s.begin >= kMinStretchCycles) out.push_back(s);
  }
  return out;
}

double rateAt(const std::vector<double>& t, const std::vector<double>& q, const Span& s, std::size_t i) {
  const std::size_t a = std::max(s.begin, i >= kSlopeHalf ? i - kSlopeHalf : 0);
  const std::size_t b = std::min(s.end - 1, i + kSlopeHalf);
  double mt = 0.0, mq = 0.0;
  for (std::size_t k = a; k <= b; ++k) mt += t[k], mq += q[k];
  mt /= static_cast<double>(b - a + 1);
  mq /= static_cast<double>(b - a + 1);
  double num = 0.0, den = 0.0;
  for (std::size_t k = a; k <= b; ++k) num += (t[k] - mt) * (q[k] - mq), den += (t[k] - mt) * (t[k] - mt);
  return den > 0.0 ? num / den : 0.0;
}

/// The passive reference: the slowest stretch's effort against q, in 1° bins (empty bins interpolated).
struct Reference {
  double lo = 0.0;
  std::vector<double> bin;
  double at(double q) const {
    const double x = std::clamp((q - lo) / kDeg, 0.0, static_cast<double>(bin.size() - 1));
    const auto i = static_cast<std::size_t>(x);
    const std::size_t j = std::min(i + 1, bin.size() - 1);
    return bin[i] + (bin[j] - bin[i]) * (x - static_cast<double>(i));
  }
};

Reference makeReference(const std::vector<double>& q, const std::vector<double>& effort, const Span& s) {
  Reference r;
  double hi = -1e9;
  r.lo = 1e9;
  for (std::size_t i = s.begin; i < s.end; ++i) r.lo = std::min(r.lo, q[i]), hi = std::max(hi, q[i]);
  const auto n = static_cast<std::size_t>((hi - r.lo) / kDeg) + 1;
  std::vector<double> sum(n, 0.0), count(n, 0.0);
  for (std::size_t i = s.begin; i < s.end; ++i) {
    const auto b = std::min(n - 1, static_cast<std::size_t>((q[i] - r.lo) / kDeg));
    sum[b] += effort[i];
    count[b] += 1.0;
  }
  r.bin.assign(n, kNaN);
  for (std::size_t b = 0; b < n; ++b) if (count[b] > 0) r.bin[b] = sum[b] / count[b];
  for (std::size_t b = 0; b < n; ++b) {  // fill gaps from the nearest filled bin below, else above
    if (!std::isnan(r.bin[b])) continue;
    for (std::size_t d = 1; d < n && std::isnan(r.bin[b]); ++d) {
      if (b >= d && !std::isnan(r.bin[b - d])) r.bin[b] = r.bin[b - d];
      else if (b + d < n && !std::isnan(r.bin[b + d])) r.bin[b] = r.bin[b + d];
    }
  }
  return r;
}

/// Per-stretch working data: excess over the reference, the stretch velocity, the start and end angles.
struct StretchData {
  Span span;
  double q_start = 0.0, q_end = 0.0;
  std::vector<double> excess, rate;
};

StretchData prepare(const std::vector<double>& t, const std::vector<double>& q, const std::vector<double>& effort,
                    const Span& s, const Reference& ref) {
  StretchData d;
  d.span = s;
  d.q_start = q[s.begin];
  d.q_end = *std::min_element(q.begin() + static_cast<long>(s.begin), q.begin() + static_cast<long>(s.end));
  for (std::size_t i = s.begin; i < s.end; ++i) {
    d.excess.push_back(effort[i] - ref.at(q[i]));
    d.rate.push_back(-rateAt(t, q, s, i));
  }
  return d;
}

/// One sample of a (non-reference) stretch: angle, stretch velocity, excess effort over the reference.
struct Sample {
  double q, v, excess;
};

/// The model every stretch sample is fitted to (least squares): excess = a + b·v + G·(v − v_th)⁺·[q < φ_c]
/// (a, b: the offset and viscous part of the excess; G, v_th, φ_c: the reflex). For a given (φ_c, v_th) it is
/// linear in (a, b, G); the pair is found by a grid search (0.25°, 1°/s).
struct ReflexModel {
  double a = 0.0, b = 0.0, gain = 0.0, threshold = 0.0, catch_q = 0.0, sse = 1e300;
};

bool solve3(double m[3][3], double r[3], double x[3]) {
  const double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  if (!(std::fabs(det) > 1e-18)) return false;
  for (int c = 0; c < 3; ++c) {
    double mc[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) mc[i][j] = j == c ? r[i] : m[i][j];
    x[c] = (mc[0][0] * (mc[1][1] * mc[2][2] - mc[1][2] * mc[2][1]) - mc[0][1] * (mc[1][0] * mc[2][2] - mc[1][2] * mc[2][0]) +
            mc[0][2] * (mc[1][0] * mc[2][1] - mc[1][1] * mc[2][0])) / det;
  }
  return true;
}

/// Least squares in (a, b, G) for one (φ_c, v_th); updates best when its residual is lower.
void fitAt(const std::vector<Sample>& s, double catch_q, double threshold, ReflexModel& best) {
  double m[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}, r[3] = {0, 0, 0}, x[3];
  for (const Sample& p : s) {
    const double f[3] = {1.0, p.v, p.q < catch_q ? std::max(0.0, p.v - threshold) : 0.0};
    for (int i = 0; i < 3; ++i) {
      r[i] += f[i] * p.excess;
      for (int j = 0; j < 3; ++j) m[i][j] += f[i] * f[j];
    }
  }
  if (!solve3(m, r, x) || !(x[2] > 0.0)) return;
  double sse = 0.0;
  for (const Sample& p : s) {
    const double e = p.excess - x[0] - x[1] * p.v - x[2] * (p.q < catch_q ? std::max(0.0, p.v - threshold) : 0.0);
    sse += e * e;
  }
  if (sse < best.sse) best = {x[0], x[1], x[2], threshold, catch_q, sse};
}

ReflexModel fitReflexModel(const std::vector<Sample>& s, double q_lo, double q_hi, double v_max) {
  ReflexModel best;
  for (double c = q_lo; c <= q_hi; c += 0.25 * kDeg) {
    for (double v = 0.0; v <= v_max; v += kDeg) fitAt(s, c, v, best);
  }
  return best;
}

/// The samples of a stretch inside its steady part (margins from its start and end).
void collect(const StretchData& d, const std::vector<double>& q, std::vector<Sample>& out) {
  for (std::size_t k = 0; k < d.excess.size(); ++k) {
    const double qi = q[d.span.begin + k];
    if (qi > d.q_start - kBaselineFrom || qi < d.q_end + kMargin) continue;
    out.push_back({qi, d.rate[k], d.excess[k]});
  }
}

/// A stretch's figures under the fitted model: the first angle past φ_c with v > v_th (its catch), the mean
/// velocity and the mean reflex excess (excess − a − b·v) past the catch.
StretchFigures figures(const StretchData& d, const std::vector<double>& q, const std::vector<double>& effort,
                       const ReflexModel& m) {
  StretchFigures f;
  f.catch_rad = kNaN;
  double n = 0.0, v = 0.0, ex = 0.0, res = 0.0, nv = 0.0, all_v = 0.0;
  for (std::size_t k = 0; k < d.excess.size(); ++k) {
    res += effort[d.span.begin + k] / static_cast<double>(d.excess.size());
    const double qi = q[d.span.begin + k];
    if (qi > d.q_start - kBaselineFrom || qi < d.q_end + kMargin) continue;
    all_v += d.rate[k], nv += 1.0;
    if (qi >= m.catch_q) continue;
    if (std::isnan(f.catch_rad) && d.rate[k] > m.threshold) f.catch_rad = qi;
    v += d.rate[k], ex += d.excess[k] - m.a - m.b * d.rate[k], n += 1.0;
  }
  f.resistance = res;
  f.velocity_rad_s = n > 0 ? v / n : (nv > 0 ? all_v / nv : kNaN);
  f.reflex = !std::isnan(f.catch_rad) && n > 0 ? ex / n : 0.0;
  return f;
}

}  // namespace

std::string analyseTardieu(const std::vector<double>& t, const std::vector<double>& q,
                           const std::vector<double>& effort, const std::vector<double>& target,
                           const std::vector<char>& in, TardieuFigures& out) {
  const std::size_t n = t.size();
  if (q.size() != n || effort.size() != n || target.size() != n || in.size() != n) {
    return "tardieu: the series differ in length";
  }
  const std::vector<Span> spans = findStretches(t, target, in);
  if (spans.size() < 3) return "tardieu: " + std::to_string(spans.size()) + " stretches found, need 3 or more";
  // The slowest stretch (the lowest mean target rate) is the passive reference.
  std::size_t slowest = 0;
  std::vector<double> nominal;
  for (const Span& s : spans) {
    std::size_t last = s.begin;  // the last cycle of the ramp itself (the tail holds the target)
    while (last + 1 < s.end && target[last + 1] < target[last]) ++last;
    nominal.push_back((target[s.begin] - target[last]) / std::max(t[last] - t[s.begin], 1e-9));
    if (nominal.back() < nominal[slowest]) slowest = nominal.size() - 1;
  }
  const Reference ref = makeReference(q, effort, spans[slowest]);
  std::vector<StretchData> data;
  for (const Span& s : spans) data.push_back(prepare(t, q, effort, s, ref));
  std::vector<Sample> samples;
  double v_max = 0.0, q_lo = 1e300, q_hi = -1e300;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (i == slowest) continue;
    collect(data[i], q, samples);
    q_lo = std::min(q_lo, data[i].q_end + kMargin);
    q_hi = std::max(q_hi, data[i].q_start - kBaselineFrom);
  }
  for (const Sample& p : samples) v_max = std::max(v_max, p.v);
  TardieuFigures f;
  f.catch_rad = f.threshold_rad_s = f.gain_per_rad_s = kNaN;
  const ReflexModel m = fitReflexModel(samples, q_lo, q_hi, v_max);
  f.residual = samples.size() > 3 ? std::sqrt(m.sse / static_cast<double>(samples.size() - 3)) : kNaN;
  for (std::size_t i = 0; i < data.size(); ++i) {
    f.stretches.push_back(figures(data[i], q, effort, m));
    f.stretches.back().nominal_rad_s = nominal[i];
    if (i == slowest) f.stretches.back().catch_rad = kNaN, f.stretches.back().reflex = 0.0;
  }
  // No reflex: the fit found none, or a gain whose effect stays within the residual at the fastest stretch.
  if (m.sse < 1e300 && m.gain * (v_max - m.threshold) > 3.0 * f.residual) {
    f.catch_rad = m.catch_q;
    f.threshold_rad_s = m.threshold;
    f.gain_per_rad_s = m.gain;
  } else {
    for (auto& st : f.stretches) st.catch_rad = kNaN, st.reflex = 0.0;
  }
  out = f;
  return "";
}

PassiveRomFigures analysePassiveRom(const std::vector<double>& flexion, const std::vector<double>& effort_cmd,
                                    const std::vector<char>& in) {
  PassiveRomFigures f{kNaN, kNaN};
  for (int sign : {1, -1}) {
    std::vector<double> v;
    for (std::size_t i = 0; i < flexion.size(); ++i) {
      if (in[i] && effort_cmd[i] * sign > 0.0 && std::isfinite(flexion[i])) v.push_back(flexion[i]);
    }
    if (v.size() < 4) continue;
    double sum = 0.0;
    for (std::size_t i = v.size() * 3 / 4; i < v.size(); ++i) sum += v[i];
    (sign > 0 ? f.extension_rad : f.flexion_rad) = sum / static_cast<double>(v.size() - v.size() * 3 / 4);
  }
  return f;
}

double analyseMaxForce(const std::vector<double>& t, const std::vector<double>& effort, const std::vector<char>& in) {
  // The peak of the 5 Hz low-passed effort, less the relaxed baseline: the mean effort of the first
  // kMaxForceBaselineS of the phase (the patient is asked to push only after it; the hold may need some effort
  // against the passive torque of the pose).
  constexpr double kMaxForceBaselineS = 0.3;
  double y = 0.0, peak = kNaN, t_prev = kNaN, t_first = kNaN, base = 0.0, n_base = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    if (!in[i] || !std::isfinite(effort[i])) continue;
    if (std::isnan(t_first)) t_first = t[i];
    const double dt = std::isnan(t_prev) ? 0.0 : std::clamp(t[i] - t_prev, 0.0, 0.1);
    const double a = 1.0 - std::exp(-2.0 * M_PI * 5.0 * dt);  // 5 Hz one-pole low-pass
    y = std::isnan(t_prev) ? effort[i] : y + a * (effort[i] - y);
    t_prev = t[i];
    if (t[i] - t_first < kMaxForceBaselineS) base += effort[i], n_base += 1.0;
    peak = std::isnan(peak) ? y : std::max(peak, y);
  }
  return n_base > 0 ? peak - base / n_base : kNaN;
}

namespace {
void addFigure(std::vector<std::pair<std::string, double>>& out, const std::string& name, const nlohmann::json& v) {
  if (v.is_number() && std::isfinite(v.get<double>())) out.emplace_back(name, v.get<double>());
}
}  // namespace

std::vector<std::pair<std::string, double>> assessmentFigures(const nlohmann::json& m) {
  std::vector<std::pair<std::string, double>> out;
  const nlohmann::json in = m.value("instrumented", nlohmann::json::object());
  if (in.contains("tardieu")) {
    const auto& t = in["tardieu"];
    for (const char* k : {"catch_deg", "threshold_deg_s", "gain_per_rad_s"}) addFigure(out, std::string("tardieu.") + k, t.value(k, nlohmann::json()));
    const nlohmann::json stretches = t.value("stretches", nlohmann::json::array());
    for (const auto& s : stretches) {
      addFigure(out, "tardieu.reflex_at_" + std::to_string(s.value("nominal_deg_s", 0)) + "_deg_s", s.value("reflex", nlohmann::json()));
    }
  }
  const nlohmann::json passive = in.value("passive_rom_deg", nlohmann::json::object());
  const nlohmann::json force = in.value("max_force", nlohmann::json::object());
  const nlohmann::json rom = m.value("rom_deg", nlohmann::json::object());
  // Joints and channels in anatomical order (the JSON objects keep theirs alphabetical).
  for (const std::string& joint : anatomicalKeys(passive)) {
    const nlohmann::json& r = passive[joint];
    addFigure(out, "passive_rom." + joint + ".extension_deg", r.value("extension", nlohmann::json()));
    addFigure(out, "passive_rom." + joint + ".flexion_deg", r.value("flexion", nlohmann::json()));
  }
  for (const std::string& ch : anatomicalKeys(force)) addFigure(out, "max_force." + ch, force[ch]);
  for (const std::string& joint : anatomicalKeys(rom)) {
    const nlohmann::json& r = rom[joint];
    if (!r.is_array() || r.size() != 2) continue;
    addFigure(out, "rom." + joint + ".min_deg", r[0]);
    addFigure(out, "rom." + joint + ".max_deg", r[1]);
  }
  return out;
}

std::string figureUnit(const std::string& name, const std::string& unit) {
  if (name.rfind("tardieu.reflex", 0) == 0) return unit;
  if (name.find("_deg_s") != std::string::npos) return "°/s";
  if (name.find("_deg") != std::string::npos) return "°";
  if (name.rfind("tardieu.gain", 0) == 0) return unit + "·s/rad";
  return unit;
}

nlohmann::json repeatabilityOf(const std::vector<std::vector<nlohmann::json>>& sessions, const std::string& source,
                               std::string& error) {
  // figure → [patient][session], kept only when every session has it.
  std::map<std::string, std::vector<std::vector<double>>> y;
  std::map<std::string, std::size_t> seen;
  std::size_t total = 0;
  for (std::size_t p = 0; p < sessions.size(); ++p) {
    for (const nlohmann::json& m : sessions[p]) {
      ++total;
      for (const auto& [name, v] : assessmentFigures(m)) {
        auto& rows = y[name];
        rows.resize(sessions.size());
        rows[p].push_back(v);
        ++seen[name];
      }
    }
  }
  nlohmann::json out = {{"version", 1}, {"source", source}, {"figures", nlohmann::json::object()}};
  for (const auto& [name, rows] : y) {
    if (seen[name] != total) continue;
    Repeatability r;
    if (std::string e = computeRepeatability(rows, r); !e.empty()) {
      if (e.find("undefined") != std::string::npos) continue;  // a constant figure has no ICC
      error = name + ": " + e;
      return nullptr;
    }
    out["figures"][name] = {{"icc", r.icc}, {"sem", r.sem}, {"mdc95", r.mdc95}, {"sd", r.sd},
                            {"subjects", r.subjects}, {"sessions", r.sessions}};
  }
  return out;
}

std::string loadRepeatability(const std::string& path, nlohmann::json& out) {
  std::ifstream f(path);
  if (!f) return path + ": cannot read";
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    return path + ": not JSON: " + e.what();
  }
  if (!j.is_object() || j.value("version", 0) != 1) return path + ": version: must be 1";
  if (!j.contains("figures") || !j["figures"].is_object()) return path + ": figures: missing or not an object";
  for (const auto& [name, v] : j["figures"].items()) {
    for (const char* k : {"icc", "sem", "mdc95"}) {
      if (!v.is_object() || !v.contains(k) || !v[k].is_number() || !std::isfinite(v[k].get<double>())) {
        return path + ": figures." + name + "." + k + ": missing or not a finite number";
      }
    }
  }
  out = j;
  return "";
}

}  // namespace phalanx::host::therapy
