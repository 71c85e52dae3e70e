#pragma once
/// Minimal SVG writer for the design reports: scatter plots and line plots in data coordinates, with axes,
/// ticks and a legend. No dependencies; the output opens in any browser.
#include <array>
#include <string>
#include <utility>
#include <vector>

namespace phalanx::host::design {

class SvgPlot {
 public:
  SvgPlot(std::string title, std::string x_label, std::string y_label, int width_px = 640, int height_px = 480);

  /// Points (x, y) in data units drawn as small dots.
  void addScatter(const std::vector<std::array<double, 2>>& pts, const std::string& colour, const std::string& label,
                  double radius_px = 1.2, double opacity = 0.6);
  /// A polyline in data units; markers: also a dot at every point (so that a single point, which no line can
  /// show, is seen).
  void addLine(const std::vector<std::array<double, 2>>& pts, const std::string& colour, const std::string& label,
               bool markers = false);
  /// A horizontal band y_lo…y_hi across the plot (drawn under the data; e.g. a minimal-detectable-change band).
  void addBand(double y_lo, double y_hi, const std::string& colour, double opacity, const std::string& label = "");
  /// A dashed vertical line at x (drawn under the data), labelled at its top.
  void addVLine(double x, const std::string& colour, const std::string& label = "");
  /// Labelled x ticks at these positions instead of the automatic numeric ones (categories such as sessions);
  /// a label may hold two lines separated by '\n'.
  void setXTicks(std::vector<std::pair<double, std::string>> ticks) { x_ticks_ = std::move(ticks); }
  /// Equal scaling of x and y (workspace plots).
  void setEqualAspect(bool on) { equal_aspect_ = on; }

  std::string render() const;
  /// Writes render() to `path`; returns an error message or "".
  std::string write(const std::string& path) const;

 private:
  struct Series {
    std::vector<std::array<double, 2>> pts;
    std::string colour, label;
    double radius_px = 1.2, opacity = 0.6;
    bool line = false;
    bool markers = false;
  };
  std::string title_, x_label_, y_label_;
  int width_px_, height_px_;
  bool equal_aspect_ = false;
  std::vector<Series> series_;
  struct Band {
    double lo, hi;
    std::string colour, label;
    double opacity;
  };
  std::vector<Band> bands_;
  struct VLine {
    double x;
    std::string colour, label;
  };
  std::vector<VLine> vlines_;
  std::vector<std::pair<double, std::string>> x_ticks_;
};

/// Text made safe for HTML/SVG text and attribute values: < > & " ' as entities.
std::string markupEscape(const std::string& s);

}  // namespace phalanx::host::design
