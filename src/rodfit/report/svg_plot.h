// Small SVG plots for the fit report (docs/formats.md, "Fit report"): 2-D figures with linear or
// log axes, ticks at 1, 2 or 5 x 10^k (powers of ten on log axes), axis labels that carry their
// units, lines, markers, bars, horizontal bands, a legend and an optional image under the data.
// A figure renders as one <svg> element that is valid both inline in an HTML page and as a file
// of its own (vector output a lab can put in a paper's supplement). Only finite data are drawn:
// a line breaks at a non-finite point, a log axis treats values <= 0 as missing, and a figure
// with no finite point renders as an explicit "no data" frame instead of a broken drawing. All
// text is escaped here, so labels may come straight from input files.
//
// This header holds plain data and two functions only, so that including it costs little.
#pragma once

#include <limits>
#include <string>
#include <vector>

namespace rodfit::svg {

/// `text` escaped for XML / HTML text and attribute values (& < > " ').
std::string Escape(const std::string& text);

/// The tick spacing for a linear axis over [lo, hi]: 1, 2 or 5 x 10^k, chosen so that about
/// `target` ticks fall inside. NaN when lo or hi is not finite or hi <= lo.
double TickStep(double lo, double hi, int target = 6);

/// The multiples of TickStep(lo, hi, target) inside [lo, hi] (with a tolerance of 1e-9 steps
/// at the ends); empty when TickStep is NaN.
std::vector<double> LinearTicks(double lo, double hi, int target = 6);

/// Powers of ten inside [lo, hi] (0 < lo < hi), every k-th decade so that at most about `target`
/// remain; at least the two ends' decades when the range spans less than one decade.
std::vector<double> LogTicks(double lo, double hi, int target = 6);

/// A tick label for `value` on an axis with spacing `step`: as many decimals as the step needs
/// ("0.25", "-3", "1500"), exponent form ("2e-07") when the step is below 1e-4 or the value's
/// magnitude 1e6 or more. Exact zero is "0".
std::string FormatTick(double value, double step);

enum class Marker { kNone, kCircle, kSquare, kTriangle, kCross, kDiamond };

/// One data set of a figure.
struct Series {
  std::string label;         ///< legend entry; empty: not in the legend
  std::vector<double> x, y;  ///< data coordinates; a point with a non-finite coordinate is skipped
  std::string colour = "#1f77b4";  ///< any CSS colour
  bool line = true;          ///< joined by a polyline, broken at non-finite points
  bool dashed = false;
  bool closed = false;       ///< the line returns to its first point (a ring)
  double line_width = 1.8;   ///< [px]
  Marker marker = Marker::kNone;
  bool hollow = false;       ///< marker outline only
  double marker_size = 4.0;  ///< [px] half-width
  /// Text beside each point (a marker's s): empty, or one entry per point ("" for none). A label
  /// that would overlap one placed before it (in this or an earlier series) is left out.
  std::vector<std::string> point_labels;
  /// Vertical bars from y = 0 to each y, centred on x and bar_width wide [x units] (a histogram).
  bool bars = false;
  double bar_width = 0.0;
};

/// A horizontal band low <= y <= high across the plot (e.g. +-1 sigma).
struct Band {
  double low = 0.0, high = 0.0;
  std::string colour = "#000000";
  double opacity = 0.1;
  std::string label;  ///< legend entry; empty: not in the legend
};

struct Axis {
  std::string label;      ///< with its unit, e.g. "u [px]"
  bool log = false;       ///< log10 scale; values <= 0 are missing
  bool reversed = false;  ///< values grow downwards (y) or leftwards (x), e.g. an image's v
  double min = std::numeric_limits<double>::quiet_NaN();  ///< fixed range; NaN: from the data
  double max = std::numeric_limits<double>::quiet_NaN();
};

/// A raster image (a camera frame) drawn under the data, filling [x0, x1] x [y0, y1] in data
/// coordinates; `href` is usually a data: URI.
struct Image {
  std::string href;  ///< empty: no image
  double x0 = 0.0, x1 = 0.0, y0 = 0.0, y1 = 0.0;
};

struct Figure {
  std::string title;
  int width = 640;   ///< [px] of the whole figure, legend included
  int height = 400;  ///< [px]; with height_from_data the largest height
  Axis x, y;
  /// One data unit is as long on both axes (shapes, images): the shorter range is widened.
  bool equal_aspect = false;
  /// With equal_aspect: the plot is made only as tall as the data need (at least 120 px).
  bool height_from_data = false;
  Image background;
  std::vector<Band> bands;
  std::vector<Series> series;
  std::string no_data_text = "no data";  ///< shown when no series has a finite point
};

/// True when some series has a point that can be drawn (finite, and > 0 on log axes).
bool HasData(const Figure& figure);

/// The figure as one <svg> element. `id` names its clip path and must be unique within a page
/// (letters, digits, '-' and '_'; other characters are replaced).
std::string RenderSvg(const Figure& figure, const std::string& id);

}  // namespace rodfit::svg
