#include "phalanx/host/design/svg.h"
#include "phalanx/host/benchrun/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace phalanx::host::benchrun {
namespace {

constexpr int kW = 760, kH = 260;                       // plot size, px
constexpr int kLeft = 64, kRight = 16, kTop = 16, kBottom = 40;

struct Series {
  std::string name, color;
  const std::vector<double>* x;
  const std::vector<double>* y;
};

const auto& esc = design::markupEscape;

std::string fmt(double v, const char* f = "%.4g") {
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

/// "Nice" tick step for a span.
double tickStep(double span, int target) {
  const double raw = span / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (raw <= m * mag) return m * mag;
  }
  return 10.0 * mag;
}

/// Line plot; x optionally logarithmic. hline: horizontal reference lines (value, label).
std::string plot(const std::vector<Series>& series, const std::string& xlabel, const std::string& ylabel, bool logx,
                 const std::vector<std::pair<double, std::string>>& hlines = {}) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  auto tx = [&](double x) { return logx ? std::log10(std::max(x, 1e-9)) : x; };
  for (const auto& s : series) {
    for (size_t i = 0; i < s.x->size(); ++i) {
      const double yv = (*s.y)[i];
      if (!std::isfinite(yv)) continue;
      x0 = std::min(x0, tx((*s.x)[i]));
      x1 = std::max(x1, tx((*s.x)[i]));
      y0 = std::min(y0, yv);
      y1 = std::max(y1, yv);
    }
  }
  for (const auto& h : hlines) {
    y0 = std::min(y0, h.first);
    y1 = std::max(y1, h.first);
  }
  if (!(x1 > x0)) x1 = x0 + 1.0;
  if (!(y1 > y0)) {
    y0 -= 1.0;
    y1 += 1.0;
  }
  const double pad = 0.05 * (y1 - y0);
  y0 -= pad;
  y1 += pad;
  const double pw = kW - kLeft - kRight, ph = kH - kTop - kBottom;
  auto X = [&](double x) { return kLeft + (tx(x) - x0) / (x1 - x0) * pw; };
  auto Y = [&](double y) { return kTop + (y1 - y) / (y1 - y0) * ph; };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << kW << "' height='" << kH << "' viewBox='0 0 " << kW << " "
    << kH << "' font-family='sans-serif' font-size='11'>";
  o << "<rect x='" << kLeft << "' y='" << kTop << "' width='" << pw << "' height='" << ph << "' fill='#fff' stroke='#999'/>";
  // y ticks
  const double ys = tickStep(y1 - y0, 6);
  for (double v = std::ceil(y0 / ys) * ys; v <= y1; v += ys) {
    o << "<line x1='" << kLeft << "' x2='" << kLeft + pw << "' y1='" << fmt(Y(v), "%.1f") << "' y2='" << fmt(Y(v), "%.1f")
      << "' stroke='#eee'/><text x='" << kLeft - 4 << "' y='" << fmt(Y(v) + 4, "%.1f") << "' text-anchor='end'>"
      << fmt(std::fabs(v) < ys * 1e-6 ? 0.0 : v) << "</text>";
  }
  // x ticks
  if (logx) {
    for (int e = static_cast<int>(std::floor(x0)); e <= static_cast<int>(std::ceil(x1)); ++e) {
      for (int m : {1, 2, 5}) {
        const double v = m * std::pow(10.0, e);
        if (std::log10(v) < x0 - 1e-9 || std::log10(v) > x1 + 1e-9) continue;
        o << "<line x1='" << fmt(X(v), "%.1f") << "' x2='" << fmt(X(v), "%.1f") << "' y1='" << kTop << "' y2='"
          << kTop + ph << "' stroke='#eee'/><text x='" << fmt(X(v), "%.1f") << "' y='" << kTop + ph + 14
          << "' text-anchor='middle'>" << fmt(v) << "</text>";
      }
    }
  } else {
    const double xs = tickStep(x1 - x0, 8);
    for (double v = std::ceil(x0 / xs) * xs; v <= x1; v += xs) {
      o << "<line x1='" << fmt(X(v), "%.1f") << "' x2='" << fmt(X(v), "%.1f") << "' y1='" << kTop << "' y2='" << kTop + ph
        << "' stroke='#eee'/><text x='" << fmt(X(v), "%.1f") << "' y='" << kTop + ph + 14 << "' text-anchor='middle'>"
        << fmt(v) << "</text>";
    }
  }
  for (const auto& h : hlines) {
    o << "<line x1='" << kLeft << "' x2='" << kLeft + pw << "' y1='" << fmt(Y(h.first), "%.1f") << "' y2='"
      << fmt(Y(h.first), "%.1f") << "' stroke='#c00' stroke-dasharray='4 3'/><text x='" << kLeft + pw - 4 << "' y='"
      << fmt(Y(h.first) - 3, "%.1f") << "' text-anchor='end' fill='#c00'>" << esc(h.second) << "</text>";
  }
  // series (decimated to ≤ 1500 points each: the report stays small)
  int legend_x = kLeft + 8;
  for (const auto& s : series) {
    const size_t n = s.x->size();
    const size_t stride = std::max<size_t>(1, n / 1500);
    o << "<polyline fill='none' stroke='" << s.color << "' stroke-width='1.2' points='";
    for (size_t i = 0; i < n; i += stride) {
      if (!std::isfinite((*s.y)[i])) continue;
      o << fmt(X((*s.x)[i]), "%.1f") << "," << fmt(Y((*s.y)[i]), "%.1f") << " ";
    }
    o << "'/>";
    o << "<rect x='" << legend_x << "' y='" << kTop + 6 << "' width='12' height='3' fill='" << s.color << "'/><text x='"
      << legend_x + 16 << "' y='" << kTop + 11 << "'>" << esc(s.name) << "</text>";
    legend_x += 24 + static_cast<int>(s.name.size()) * 6;
  }
  o << "<text x='" << kLeft + pw / 2 << "' y='" << kH - 6 << "' text-anchor='middle'>" << esc(xlabel) << "</text>";
  o << "<text transform='translate(14," << kTop + ph / 2 << ") rotate(-90)' text-anchor='middle'>" << esc(ylabel)
    << "</text></svg>";
  return o.str();
}

/// Overlaid histograms of several error series on common bins.
std::string histogram(const std::vector<std::pair<std::string, std::vector<double>>>& errs, const std::string& unit) {
  double lo = 1e300, hi = -1e300;
  for (const auto& e : errs) {
    for (double v : e.second) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  if (!(hi > lo)) hi = lo + 1e-6;
  constexpr int kBins = 50;
  const double w = (hi - lo) / kBins;
  std::vector<std::vector<double>> frac(errs.size(), std::vector<double>(kBins, 0.0));
  double fmax = 0.0;
  for (size_t s = 0; s < errs.size(); ++s) {
    for (double v : errs[s].second) frac[s][std::min(kBins - 1, static_cast<int>((v - lo) / w))] += 1.0;
    for (double& c : frac[s]) {
      c /= static_cast<double>(std::max<size_t>(1, errs[s].second.size()));
      fmax = std::max(fmax, c);
    }
  }
  const char* colors[] = {"#1f77b4", "#d62728", "#2ca02c"};
  const double pw = kW - kLeft - kRight, ph = kH - kTop - kBottom;
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << kW << "' height='" << kH
    << "' font-family='sans-serif' font-size='11'><rect x='" << kLeft << "' y='" << kTop << "' width='" << pw
    << "' height='" << ph << "' fill='#fff' stroke='#999'/>";
  for (size_t s = 0; s < errs.size(); ++s) {
    for (int b = 0; b < kBins; ++b) {
      const double h = fmax > 0 ? frac[s][b] / fmax * ph : 0.0;
      o << "<rect x='" << fmt(kLeft + b * pw / kBins, "%.1f") << "' y='" << fmt(kTop + ph - h, "%.1f") << "' width='"
        << fmt(pw / kBins, "%.1f") << "' height='" << fmt(h, "%.1f") << "' fill='" << colors[s % 3]
        << "' fill-opacity='0.45'/>";
    }
    o << "<rect x='" << kLeft + 8 << "' y='" << kTop + 6 + 14 * static_cast<int>(s) << "' width='12' height='8' fill='"
      << colors[s % 3] << "' fill-opacity='0.6'/><text x='" << kLeft + 24 << "' y='" << kTop + 14 + 14 * static_cast<int>(s)
      << "'>" << esc(errs[s].first) << "</text>";
  }
  const double xs = tickStep(hi - lo, 8);
  for (double v = std::ceil(lo / xs) * xs; v <= hi; v += xs) {
    const double x = kLeft + (v - lo) / (hi - lo) * pw;
    o << "<text x='" << fmt(x, "%.1f") << "' y='" << kTop + ph + 14 << "' text-anchor='middle'>"
      << fmt(std::fabs(v) < xs * 1e-6 ? 0.0 : v) << "</text>";
  }
  o << "<text x='" << kLeft + pw / 2 << "' y='" << kH - 6 << "' text-anchor='middle'>error (" << esc(unit)
    << ")</text><text transform='translate(14," << kTop + ph / 2
    << ") rotate(-90)' text-anchor='middle'>share of samples (normalised)</text></svg>";
  return o.str();
}

/// bandwidth: the table has the −3 dB column (chirp steps only).
std::string metricRow(const char* pair, const PairMetrics& m, const std::string& unit, bool bandwidth) {
  std::ostringstream o;
  // A figure not defined for the step (fidelity off the SEA rig, NRMSE against a zero reference) is a dash.
  const auto cell = [](double v, const char* f, const std::string& u) {
    return "<td>" + (std::isfinite(v) ? fmt(v, f) + " " + u : std::string("&ndash;")) + "</td>";
  };
  o << "<tr><td>" << pair << "</td>" << cell(m.rmse, "%.4g", esc(unit)) << cell(m.nrmse_percent, "%.2f", "%")
    << cell(m.fidelity_percent, "%.2f", "%");
  if (bandwidth) {
    o << "<td>";
    if (m.bandwidth_hz < 0) o << "&ndash;";
    else if (m.bandwidth_beyond_band) o << "&ge; " << fmt(m.bandwidth_hz, "%.2f") << " Hz (&minus;3 dB not reached within the sweep)";
    else o << fmt(m.bandwidth_hz, "%.2f") << " Hz";
    o << "</td>";
  }
  o << "</tr>";
  return o.str();
}

/// The names a person reads for the runner's keys (checks and step figures); an unknown key is shown as it is.
std::string humanName(const std::string& key) {
  static const std::pair<const char*, const char*> kNames[] = {
      {"estimate_vs_instrument", "estimate vs instrument"},
      {"setpoint_vs_instrument", "setpoint vs instrument"},
      {"rmse", "RMSE"},
      {"nrmse_percent", "NRMSE (%)"},
      {"fidelity_percent", "fidelity, eq 15 (%)"},
      {"bandwidth_hz", "−3 dB bandwidth, eq 17 (Hz)"},
      {"penetration_mm", "deepest true penetration (mm)"},
      {"peak_tip_penetration_mm", "deepest true tip penetration (mm)"},
      {"wall_energy_generated_mJ", "energy the walls generated (mJ; ≤ 0: passive)"},
      {"wall_work_mJ", "work of the wall forces on the pen (mJ)"},
      {"peak_commanded_wall_force_N", "peak commanded wall force (N)"},
      {"braking_pulses", "braking pulses"},
      {"split_scaled_cycles", "cycles with the force split scaled down (saturation)"},
      {"stiffness_N_per_cm", "wall stiffness (N/cm)"},
      {"braking", "braking pulse at contact onset"},
  };
  const auto one = [](const std::string& k) {
    for (const auto& [raw, name] : kNames) {
      if (k == raw) return std::string(name);
    }
    return k;
  };
  const auto dot = key.find('.');
  if (dot == std::string::npos) return one(key);
  return one(key.substr(0, dot)) + ": " + one(key.substr(dot + 1));
}

std::string figureValue(const nlohmann::json& v) {
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_number_float()) return fmt(v.get<double>());
  return esc(v.dump());
}

/// The sentence on what the simulated instrument serves, for the plan's device.
std::string instrumentTruth(const std::string& device) {
  if (device == "sim:sea_rig") return "the plant's true joint torque of SEA 0 (the rig's load cell)";
  if (device == "sim:glove5") return "the plant's true fingertip pad force";
  if (device == "sim:pantograph") return "the force the pen truly puts on the walls";
  return "the plant's ground truth";
}

}  // namespace

std::string renderHtml(const Plan& plan, const PlanResult& res) {
  const bool has_chirp = std::any_of(plan.steps.begin(), plan.steps.end(), [](const Step& s) { return s.kind == "sea-rig-chirp"; });
  std::ostringstream o;
  o << "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>Phalanx bench report: " << esc(plan.source)
    << "</title><style>body{font-family:sans-serif;max-width:900px;margin:2em auto;color:#222}"
       "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}"
       ".pass{color:#fff;background:#2a7d2a;padding:1px 6px;border-radius:3px}"
       ".fail{color:#fff;background:#b22;padding:1px 6px;border-radius:3px}"
       "h2{border-bottom:1px solid #ccc;padding-bottom:2px}.note{color:#555;font-size:90%}</style></head><body>";
  o << "<h1>Bench report <span class='" << (res.pass ? "pass'>PASS" : "fail'>FAIL") << "</span></h1>";
  o << "<p>Plan <code>" << esc(plan.source) << "</code> on <code>" << esc(plan.device) << "</code>"
    << (plan.device == "sim:sea_rig" ? ", controller <code>" + esc(plan.controller) + "</code>" : std::string())
    << ", seed " << plan.seed << (plan.noise ? "" : ", sensors without noise") << "; " << res.steps.size()
    << " steps in " << fmt(res.wall_s, "%.1f") << " s.</p>";
  o << "<p class='note'>Reference instrument: Modbus " << esc(plan.instrument.transport) << ", " << esc(plan.instrument.table)
    << " register " << plan.instrument.address << " (" << esc(plan.instrument.type) << ", scale " << fmt(plan.instrument.scale)
    << ", offset " << fmt(plan.instrument.offset) << "), polled at " << fmt(plan.instrument.poll_hz) << " Hz; "
    << "in simulation a simulated amplifier serves " << instrumentTruth(plan.device) << ". "
    << "Metrics (seeds/001): RMSE; NRMSE = RMSE / peak |reference|; fidelity F = (1 − var(y − y<sub>ref</sub>)/var(y))·100 % "
       "(eq 15)"
    << (has_chirp ? "; −3 dB bandwidth of |Y(jω)|/|R(jω)| (eq 17) on a linear chirp (eq 16)" : "") << ". "
    << "<i>estimate vs instrument</i>: y = the device's own estimate, reference = the instrument; "
       "<i>setpoint vs instrument</i>: y = the instrument, reference = the setpoint.</p>";
  o << "<table><tr><th>step</th><th>result</th><th>checks</th></tr>";
  for (const StepResult& s : res.steps) {
    o << "<tr><td><a href='#s" << &s - res.steps.data() << "'>" << esc(s.name) << "</a></td><td><span class='"
      << (s.pass ? "pass'>pass" : "fail'>fail") << "</span></td><td>";
    if (!s.error.empty()) o << esc(s.error) << "<br>";
    for (const Check& c : s.checks) {
      o << (c.pass ? "&#10003; " : "&#10007; ") << esc(humanName(c.what)) << " = " << fmt(c.value)
        << (c.is_min ? ", limit &ge; " : ", limit &le; ") << fmt(c.limit);
      if (!c.note.empty()) o << " <i>(" << esc(c.note) << ")</i>";
      o << "<br>";
    }
    o << "</td></tr>";
  }
  o << "</table>";
  for (const StepResult& s : res.steps) {
    o << "<h2 id='s" << &s - res.steps.data() << "'>" << esc(s.name) << " <span class='" << (s.pass ? "pass'>pass" : "fail'>fail")
      << "</span></h2><p class='note'>" << esc(s.kind) << "; " << s.samples_total << " samples scored after settling, "
      << s.samples_stale << " without a fresh instrument reading";
    if (s.samples_excluded > 0) o << "; " << s.samples_excluded << " not scored by design (braking pulses)";
    if (s.faults) o << "; device faults 0x" << std::hex << s.faults << std::dec;
    o << ".</p>";
    if (!s.error.empty()) o << "<p><b>Error:</b> " << esc(s.error) << "</p>";
    if (s.step_metrics.is_object() && !s.step_metrics.empty()) {
      o << "<table><tr><th>step figure</th><th>value</th></tr>";
      for (const auto& [key, v] : s.step_metrics.items()) {
        o << "<tr><td>" << esc(humanName(key)) << "</td><td>" << figureValue(v) << "</td></tr>";
      }
      o << "</table>";
    }
    if (s.instrument.empty()) continue;
    const bool bandwidth = s.est.bandwidth_hz >= 0 || s.sp.bandwidth_hz >= 0;
    o << "<table><tr><th>comparison</th><th>RMSE</th><th>NRMSE</th><th>fidelity (eq 15)</th>"
      << (bandwidth ? "<th>−3 dB bandwidth (eq 17)</th>" : "") << "</tr>"
      << metricRow("estimate vs instrument", s.est, s.unit, bandwidth)
      << metricRow("setpoint vs instrument", s.sp, s.unit, bandwidth) << "</table>";
    // Time series: the whole step, and its last two seconds for detail.
    o << "<h3>Time series</h3>"
      << plot({{"setpoint", "#2ca02c", &s.t, &s.setpoint},
               {"device estimate", "#1f77b4", &s.t, &s.estimate},
               {"instrument", "#d62728", &s.t, &s.instrument}},
              "time (s)", s.unit, false);
    const double t_end = s.t.back();
    std::vector<double> tz, a, b, c;
    for (size_t i = 0; i < s.t.size(); ++i) {
      if (s.t[i] < t_end - 2.0) continue;
      tz.push_back(s.t[i]);
      a.push_back(s.setpoint[i]);
      b.push_back(s.estimate[i]);
      c.push_back(s.instrument[i]);
    }
    o << plot({{"setpoint", "#2ca02c", &tz, &a}, {"device estimate", "#1f77b4", &tz, &b}, {"instrument", "#d62728", &tz, &c}},
              "time (s), last 2 s", s.unit, false);
    if (!s.sp.freq_hz.empty()) {
      o << "<h3>Magnitude response (eq 17, moving average over 0.5 Hz)</h3>"
        << plot({{"instrument / setpoint", "#d62728", &s.sp.freq_hz, &s.sp.magnitude_db},
                 {"estimate / instrument", "#1f77b4", &s.est.freq_hz, &s.est.magnitude_db}},
                "frequency (Hz)", "magnitude (dB)", true, {{-3.0, "-3 dB"}, {0.0, ""}});
    }
    std::vector<double> e_est(s.t.size()), e_sp(s.t.size());
    for (size_t i = 0; i < s.t.size(); ++i) {
      e_est[i] = s.estimate[i] - s.instrument[i];
      e_sp[i] = s.instrument[i] - s.setpoint[i];
    }
    o << "<h3>Error distribution</h3>"
      << histogram({{"estimate − instrument", e_est}, {"instrument − setpoint", e_sp}}, s.unit);
  }
  o << "<p class='note'>Generated by <code>phalanx bench run</code>. Self-contained: no scripts, nothing fetched.</p></body></html>\n";
  return o.str();
}

std::string writeHtml(const std::string& path, const Plan& plan, const PlanResult& result) {
  std::ofstream f(path);
  if (!f) return "cannot write the report " + path;
  f << renderHtml(plan, result);
  return f ? "" : "error writing the report " + path;
}

}  // namespace phalanx::host::benchrun
