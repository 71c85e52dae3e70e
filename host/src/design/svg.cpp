#include "phalanx/host/design/svg.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>

namespace phalanx::host::design {

SvgPlot::SvgPlot(std::string title, std::string x_label, std::string y_label, int width_px, int height_px)
    : title_(std::move(title)),
      x_label_(std::move(x_label)),
      y_label_(std::move(y_label)),
      width_px_(width_px),
      height_px_(height_px) {}

void SvgPlot::addScatter(const std::vector<std::array<double, 2>>& pts, const std::string& colour,
                         const std::string& label, double radius_px, double opacity) {
  series_.push_back(Series{pts, colour, label, radius_px, opacity, false, false});
}

void SvgPlot::addLine(const std::vector<std::array<double, 2>>& pts, const std::string& colour,
                      const std::string& label, bool markers) {
  series_.push_back(Series{pts, colour, label, 1.5, 1.0, true, markers});
}

void SvgPlot::addBand(double y_lo, double y_hi, const std::string& colour, double opacity, const std::string& label) {
  bands_.push_back(Band{std::min(y_lo, y_hi), std::max(y_lo, y_hi), colour, label, opacity});
}

void SvgPlot::addVLine(double x, const std::string& colour, const std::string& label) {
  vlines_.push_back(VLine{x, colour, label});
}

std::string markupEscape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      case '\'': o += "&#39;"; break;
      default: o += c;
    }
  }
  return o;
}

namespace {

/// "Nice" tick step (1, 2, 5 × 10^k) giving about 6 ticks over `span`.
double tickStep(double span) {
  if (!(span > 0)) return 1.0;
  const double raw = span / 6.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / mag;
  return (r < 1.5 ? 1.0 : r < 3.5 ? 2.0 : r < 7.5 ? 5.0 : 10.0) * mag;
}
}  // namespace

std::string SvgPlot::render() const {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const Series& s : series_) {
    for (const auto& p : s.pts) {
      if (!std::isfinite(p[0]) || !std::isfinite(p[1])) continue;
      x0 = std::min(x0, p[0]);
      x1 = std::max(x1, p[0]);
      y0 = std::min(y0, p[1]);
      y1 = std::max(y1, p[1]);
    }
  }
  for (const Band& b : bands_) {
    if (!std::isfinite(b.lo) || !std::isfinite(b.hi)) continue;
    y0 = std::min(y0, b.lo);
    y1 = std::max(y1, b.hi);
  }
  for (const auto& [x, label] : x_ticks_) {
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
  }
  if (!(x1 >= x0)) x0 = 0, x1 = 1;
  if (!(y1 >= y0)) y0 = 0, y1 = 1;
  if (x1 - x0 < 1e-12) x0 -= 0.5, x1 += 0.5;
  if (y1 - y0 < 1e-12) y0 -= 0.5, y1 += 0.5;
  const double pad_x = 0.05 * (x1 - x0), pad_y = 0.05 * (y1 - y0);
  x0 -= pad_x, x1 += pad_x, y0 -= pad_y, y1 += pad_y;
  const double left = 70, right = 20, top = 40, bottom = 55;
  double pw = width_px_ - left - right, ph = height_px_ - top - bottom;
  double sx = pw / (x1 - x0), sy = ph / (y1 - y0);
  if (equal_aspect_) {
    const double s = std::min(sx, sy);
    sx = sy = s;
  }
  auto X = [&](double x) { return left + (x - x0) * sx; };
  auto Y = [&](double y) { return top + ph - (y - y0) * sy; };

  std::ostringstream o;
  o.precision(6);
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width_px_ << "\" height=\"" << height_px_
    << "\" viewBox=\"0 0 " << width_px_ << " " << height_px_ << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  o << "<text x=\"" << width_px_ / 2 << "\" y=\"20\" text-anchor=\"middle\" font-size=\"14\">" << markupEscape(title_)
    << "</text>\n";
  // Axes box, ticks and labels.
  o << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << (x1 - x0) * sx << "\" height=\"" << ph
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  const double xs = tickStep(x1 - x0), ys = tickStep(y1 - y0);
  for (const auto& [t, label] : x_ticks_) {
    const auto nl = label.find('\n');
    o << "<line x1=\"" << X(t) << "\" y1=\"" << top + ph << "\" x2=\"" << X(t) << "\" y2=\"" << top + ph + 5
      << "\" stroke=\"black\"/><text x=\"" << X(t) << "\" y=\"" << top + ph + 18 << "\" text-anchor=\"middle\">"
      << markupEscape(label.substr(0, nl)) << "</text>\n";
    if (nl != std::string::npos) {
      o << "<text x=\"" << X(t) << "\" y=\"" << top + ph + 32 << "\" text-anchor=\"middle\" font-size=\"10\">"
        << markupEscape(label.substr(nl + 1)) << "</text>\n";
    }
  }
  for (double t = std::ceil(x0 / xs) * xs; x_ticks_.empty() && t <= x1; t += xs) {
    o << "<line x1=\"" << X(t) << "\" y1=\"" << top + ph << "\" x2=\"" << X(t) << "\" y2=\"" << top + ph + 5
      << "\" stroke=\"black\"/><text x=\"" << X(t) << "\" y=\"" << top + ph + 18 << "\" text-anchor=\"middle\">"
      << (std::fabs(t) < 1e-9 * xs ? 0.0 : t) << "</text>\n";
  }
  for (double t = std::ceil(y0 / ys) * ys; t <= y1; t += ys) {
    o << "<line x1=\"" << left - 5 << "\" y1=\"" << Y(t) << "\" x2=\"" << left << "\" y2=\"" << Y(t)
      << "\" stroke=\"black\"/><text x=\"" << left - 8 << "\" y=\"" << Y(t) + 4 << "\" text-anchor=\"end\">"
      << (std::fabs(t) < 1e-9 * ys ? 0.0 : t) << "</text>\n";
  }
  o << "<text x=\"" << left + pw / 2 << "\" y=\"" << height_px_ - 12 << "\" text-anchor=\"middle\">"
    << markupEscape(x_label_) << "</text>\n";
  o << "<text transform=\"translate(16," << top + ph / 2 << ") rotate(-90)\" text-anchor=\"middle\">"
    << markupEscape(y_label_) << "</text>\n";
  // Bands and vertical markers under the data.
  for (const Band& b : bands_) {
    if (!std::isfinite(b.lo) || !std::isfinite(b.hi)) continue;
    o << "<rect x=\"" << left << "\" y=\"" << Y(b.hi) << "\" width=\"" << (x1 - x0) * sx << "\" height=\""
      << std::max(Y(b.lo) - Y(b.hi), 0.5) << "\" fill=\"" << b.colour << "\" fill-opacity=\"" << b.opacity << "\"/>\n";
  }
  for (const VLine& v : vlines_) {
    o << "<line x1=\"" << X(v.x) << "\" y1=\"" << top << "\" x2=\"" << X(v.x) << "\" y2=\"" << top + ph
      << "\" stroke=\"" << v.colour << "\" stroke-width=\"1.5\" stroke-dasharray=\"4 3\"/>\n";
    if (!v.label.empty()) {
      o << "<text x=\"" << X(v.x) + 3 << "\" y=\"" << top + 11 << "\" font-size=\"10\" fill=\"" << v.colour << "\">"
        << markupEscape(v.label) << "</text>\n";
    }
  }
  // Data.
  for (const Series& s : series_) {
    if (s.line) {
      o << "<polyline fill=\"none\" stroke=\"" << s.colour << "\" stroke-width=\"" << s.radius_px << "\" points=\"";
      for (const auto& p : s.pts) o << X(p[0]) << ',' << Y(p[1]) << ' ';
      o << "\"/>\n";
      if (!s.markers) continue;
      o << "<g fill=\"" << s.colour << "\">\n";
      for (const auto& p : s.pts) {
        if (std::isfinite(p[0]) && std::isfinite(p[1])) o << "<circle cx=\"" << X(p[0]) << "\" cy=\"" << Y(p[1]) << "\" r=\"3.5\"/>\n";
      }
      o << "</g>\n";
    } else {
      o << "<g fill=\"" << s.colour << "\" fill-opacity=\"" << s.opacity << "\">\n";
      for (const auto& p : s.pts) {
        if (!std::isfinite(p[0]) || !std::isfinite(p[1])) continue;
        o << "<circle cx=\"" << X(p[0]) << "\" cy=\"" << Y(p[1]) << "\" r=\"" << s.radius_px << "\"/>\n";
      }
      o << "</g>\n";
    }
  }
  // Legend.
  double ly = top + 14;
  for (const Band& b : bands_) {
    if (b.label.empty()) continue;
    o << "<rect x=\"" << left + 10 << "\" y=\"" << ly - 9 << "\" width=\"10\" height=\"10\" fill=\"" << b.colour
      << "\" fill-opacity=\"" << std::min(1.0, 2.0 * b.opacity) << "\"/><text x=\"" << left + 26 << "\" y=\"" << ly
      << "\">" << markupEscape(b.label) << "</text>\n";
    ly += 16;
  }
  for (const Series& s : series_) {
    if (s.label.empty()) continue;
    o << "<rect x=\"" << left + 10 << "\" y=\"" << ly - 9 << "\" width=\"10\" height=\"10\" fill=\"" << s.colour
      << "\"/><text x=\"" << left + 26 << "\" y=\"" << ly << "\">" << markupEscape(s.label) << "</text>\n";
    ly += 16;
  }
  o << "</svg>\n";
  return o.str();
}

std::string SvgPlot::write(const std::string& path) const {
  std::ofstream f(path);
  if (!f) return "cannot open '" + path + "' for writing";
  f << render();
  return f ? "" : "write to '" + path + "' failed";
}

}  // namespace phalanx::host::design
