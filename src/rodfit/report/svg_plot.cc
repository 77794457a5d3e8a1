// SVG plots (svg_plot.h). Layout, from the top: the title, the plot area with its frame, tick
// labels and axis labels, then the legend in rows under the x axis label. Data are mapped into
// the plot area after a log10 on log axes; everything drawn from data is clipped to the area.
#include "rodfit/report/svg_plot.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace rodfit::svg {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Approximate advance of a character at the fonts used (12-13 px sans-serif), for layout only.
constexpr double kCharWidth = 7.0;
constexpr int kTickFont = 12, kLabelFont = 13, kTitleFont = 15, kLegendFont = 12;
constexpr int kLegendRow = 20;     // [px]
constexpr int kMinPlotHeight = 120;
constexpr int kAxisBottom = 50;    // [px] below the plot: the tick labels and the x label

std::string Num(double v) {  // an SVG coordinate: 2 decimals are 0.01 px
  char b[32];
  std::snprintf(b, sizeof(b), "%.2f", v);
  std::string s = b;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s == "-0" ? "0" : s;
}

std::string SafeId(const std::string& id) {
  std::string out = id.empty() ? "fig" : id;
  for (char& c : out)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  return out;
}

// "10" followed by the exponent in Unicode superscripts: readable at tick size, no tspan.
std::string PowerOfTen(int k) {
  static const char* const kDigits[] = {"\u2070", "\u00b9", "\u00b2", "\u00b3", "\u2074",
                                        "\u2075", "\u2076", "\u2077", "\u2078", "\u2079"};
  if (k == 0) return "1";
  if (k == 1) return "10";
  std::string out = "10";
  if (k < 0) out += "\u207b";
  const std::string digits = std::to_string(std::abs(k));
  for (char d : digits) out += kDigits[d - '0'];
  return out;
}

// An axis after its range is known: data value -> pixel.
struct Scale {
  bool log = false, reversed = false;
  double lo = 0.0, hi = 1.0;     // in transformed units (log10 for log axes)
  double from = 0.0, to = 1.0;   // pixels of lo and hi before reversal
  double T(double v) const { return log ? (v > 0 ? std::log10(v) : kNaN) : v; }
  double Px(double v) const {
    const double t = T(v);
    if (!std::isfinite(t)) return kNaN;
    const double f = (t - lo) / (hi - lo);
    return reversed ? to - f * (to - from) : from + f * (to - from);
  }
};

bool Drawable(const Axis& a, double v) { return std::isfinite(v) && (!a.log || v > 0); }

// The data range of one axis in transformed units, widened by a margin when it comes from data.
void Range(const Axis& axis, const std::vector<double>& values, double margin, double* lo,
           double* hi) {
  auto t = [&](double v) { return axis.log ? std::log10(v) : v; };
  double a = kNaN, b = kNaN;
  for (double v : values) {
    if (!Drawable(axis, v)) continue;
    a = std::isfinite(a) ? std::min(a, t(v)) : t(v);
    b = std::isfinite(b) ? std::max(b, t(v)) : t(v);
  }
  if (!std::isfinite(a)) {  // no data: a unit range, so that the frame can still be drawn
    a = 0.0;
    b = 1.0;
  }
  if (b - a <= 1e-12 * std::max(std::abs(a), std::abs(b))) {
    const double pad = axis.log ? 0.5 : std::max(0.5 * std::abs(a), 1e-12);
    a -= pad;
    b += pad;
  } else {
    const double pad = margin * (b - a);
    a -= pad;
    b += pad;
  }
  if (Drawable(axis, axis.min)) a = t(axis.min);
  if (Drawable(axis, axis.max)) b = t(axis.max);
  if (!(b > a)) b = a + 1.0;
  *lo = a;
  *hi = b;
}

struct Tick {
  double value;  // transformed units
  std::string label;
};

std::vector<Tick> Ticks(const Axis& axis, double lo, double hi, int target) {
  std::vector<Tick> out;
  if (axis.log) {
    for (double v : LogTicks(std::pow(10.0, lo), std::pow(10.0, hi), target)) {
      const double k = std::log10(v);
      const double rk = std::round(k);
      out.push_back({k, std::abs(k - rk) < 1e-9 ? PowerOfTen(static_cast<int>(rk))
                                                 : FormatTick(v, v / 10.0)});
    }
    return out;
  }
  const double step = TickStep(lo, hi, target);
  for (double v : LinearTicks(lo, hi, target)) out.push_back({v, FormatTick(v, step)});
  return out;
}

void MarkerShape(std::ostringstream& o, Marker m, double x, double y, double r) {
  switch (m) {
    case Marker::kNone: return;
    case Marker::kCircle:
      o << "<circle cx=\"" << Num(x) << "\" cy=\"" << Num(y) << "\" r=\"" << Num(r) << "\"/>";
      return;
    case Marker::kSquare:
      o << "<rect x=\"" << Num(x - r) << "\" y=\"" << Num(y - r) << "\" width=\"" << Num(2 * r)
        << "\" height=\"" << Num(2 * r) << "\"/>";
      return;
    case Marker::kTriangle:
      o << "<path d=\"M" << Num(x) << " " << Num(y - 1.2 * r) << "L" << Num(x + 1.1 * r) << " "
        << Num(y + 0.8 * r) << "L" << Num(x - 1.1 * r) << " " << Num(y + 0.8 * r) << "Z\"/>";
      return;
    case Marker::kDiamond:
      o << "<path d=\"M" << Num(x) << " " << Num(y - 1.3 * r) << "L" << Num(x + r) << " " << Num(y)
        << "L" << Num(x) << " " << Num(y + 1.3 * r) << "L" << Num(x - r) << " " << Num(y)
        << "Z\"/>";
      return;
    case Marker::kCross:
      o << "<path d=\"M" << Num(x - r) << " " << Num(y - r) << "L" << Num(x + r) << " "
        << Num(y + r) << "M" << Num(x - r) << " " << Num(y + r) << "L" << Num(x + r) << " "
        << Num(y - r) << "\"/>";
      return;
  }
}

// The attributes a marker group is drawn with: crosses are strokes only.
std::string MarkerStyle(const Series& s) {
  const std::string c = Escape(s.colour);
  if (s.marker == Marker::kCross || s.hollow)
    return "fill=\"none\" stroke=\"" + c + "\" stroke-width=\"1.6\"";
  return "fill=\"" + c + "\" stroke=\"#ffffff\" stroke-width=\"0.6\"";
}

struct Box {  // [px] a text's extent, for overlap tests
  double x, y, w, h;
  bool Overlaps(const Box& o) const {
    return x < o.x + o.w && o.x < x + w && y < o.y + o.h && o.y < y + h;
  }
  bool Contains(double px, double py) const {
    return px >= x && px <= x + w && py >= y && py <= y + h;
  }
  // Whether the segment (ax, ay)-(bx, by) passes through the box (Liang–Barsky clipping).
  bool Crosses(double ax, double ay, double bx, double by) const {
    double t0 = 0.0, t1 = 1.0;
    const double dx = bx - ax, dy = by - ay;
    const double p[4] = {-dx, dx, -dy, dy};
    const double q[4] = {ax - x, x + w - ax, ay - y, y + h - ay};
    for (int i = 0; i < 4; ++i) {
      if (p[i] == 0.0) {
        if (q[i] < 0.0) return false;
        continue;
      }
      const double r = q[i] / p[i];
      if (p[i] < 0.0) t0 = std::max(t0, r);
      else t1 = std::min(t1, r);
      if (t0 > t1) return false;
    }
    return true;
  }
};

struct LegendEntry {
  const Series* series = nullptr;
  const Band* band = nullptr;
  std::string label;
};

}  // namespace

std::string Escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

double TickStep(double lo, double hi, int target) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || !(hi > lo)) return kNaN;
  const double raw = (hi - lo) / std::max(1, target);
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  // The first of 1, 2, 5, 10 x decade that is at least raw / 1.25 (so at most about 1.25 x
  // `target` ticks), then smaller nice steps while fewer than two ticks would fall inside.
  const double nice[] = {0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0};
  int k = 3;
  while (k < 6 && raw > nice[k] * decade * 1.25) ++k;
  auto count = [&](double step) {
    return std::floor(hi / step + 1e-9) - std::ceil(lo / step - 1e-9) + 1;
  };
  while (k > 0 && count(nice[k] * decade) < 2) --k;
  return nice[k] * decade;
}

std::vector<double> LinearTicks(double lo, double hi, int target) {
  std::vector<double> out;
  const double step = TickStep(lo, hi, target);
  if (!std::isfinite(step) || step <= 0) return out;
  const double first = std::ceil(lo / step - 1e-9);
  const double last = std::floor(hi / step + 1e-9);
  for (double k = first; k <= last && out.size() < 1000; k += 1.0) {
    const double v = k * step;
    out.push_back(std::abs(v) < 1e-9 * step ? 0.0 : v);
  }
  return out;
}

std::vector<double> LogTicks(double lo, double hi, int target) {
  std::vector<double> out;
  if (!(lo > 0) || !(hi > lo) || !std::isfinite(hi)) return out;
  const double a = std::log10(lo), b = std::log10(hi);
  const int first = static_cast<int>(std::ceil(a - 1e-9));
  const int last = static_cast<int>(std::floor(b + 1e-9));
  if (last - first + 1 >= 2) {
    const int stride = std::max(1, (last - first + target) / std::max(1, target));
    for (int k = first; k <= last; k += stride) out.push_back(std::pow(10.0, k));
    return out;
  }
  // Less than two decades inside: 1, 2 and 5 times the powers of ten.
  for (int k = first - 1; k <= last; ++k)
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, k);
      if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) out.push_back(v);
    }
  if (out.size() < 2) {  // a fraction of a decade: linear ticks in the values
    out.clear();
    for (double v : LinearTicks(lo, hi, 4))
      if (v > 0) out.push_back(v);
  }
  return out;
}

std::string FormatTick(double value, double step) {
  if (!std::isfinite(value)) return "";
  if (value == 0.0 || (std::isfinite(step) && step > 0 && std::abs(value) < 1e-9 * step))
    return "0";
  char b[48];
  const double s = std::isfinite(step) && step > 0 ? step : std::abs(value);
  if (s < 1e-4 || std::abs(value) >= 1e6) {
    // Significant digits: down to the step's decade.
    const int digits = std::clamp(static_cast<int>(std::floor(std::log10(std::abs(value))) -
                                                   std::floor(std::log10(s) + 1e-9)) + 1,
                                  1, 6);
    std::snprintf(b, sizeof(b), "%.*e", digits - 1, value);
    // "2.0e-07" -> "2e-7": no trailing zeros in the mantissa, no padded exponent.
    std::string t = b;
    const size_t e = t.find('e');
    std::string mant = t.substr(0, e), exp = t.substr(e + 1);
    if (mant.find('.') != std::string::npos) {
      while (mant.back() == '0') mant.pop_back();
      if (mant.back() == '.') mant.pop_back();
    }
    const bool neg = exp[0] == '-';
    exp = exp.substr(exp[0] == '-' || exp[0] == '+' ? 1 : 0);
    while (exp.size() > 1 && exp[0] == '0') exp.erase(0, 1);
    return mant + "e" + (neg ? "-" : "") + exp;
  }
  const int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(s) - 1e-9)));
  std::snprintf(b, sizeof(b), "%.*f", decimals, value);
  std::string t = b;
  if (t.find_first_not_of("-0.") == std::string::npos) return "0";
  return t;
}

bool HasData(const Figure& f) {
  for (const Series& s : f.series) {
    const size_t n = std::min(s.x.size(), s.y.size());
    for (size_t i = 0; i < n; ++i)
      if (Drawable(f.x, s.x[i]) && Drawable(f.y, s.y[i])) return true;
  }
  return false;
}

namespace {

// Where each legend entry goes: left to right, wrapped at the figure's width.
struct LegendPlace {
  double x;
  int row;
};

std::vector<LegendPlace> LayoutLegend(const std::vector<LegendEntry>& legend, double width) {
  std::vector<LegendPlace> placed;
  double x = 0;
  int row = 0;
  const double avail = width - 24.0;
  for (const LegendEntry& e : legend) {
    const double w = 34 + kCharWidth * e.label.size() + 18;
    if (x > 0 && x + w > avail) {
      x = 0;
      ++row;
    }
    placed.push_back({x, row});
    x += w;
  }
  return placed;
}

// Places the series' point labels: each where it lies inside the plot and covers no other
// label, and, if it can, no drawn line segment or marker (a label struck through by a curve
// cannot be read).
class PointLabels {
 public:
  PointLabels(const Figure& f, const Scale& sx, const Scale& sy, const Box& plot_box)
      : plot_box_(plot_box) {
    // Every drawn line segment and marker [px].
    for (const Series& s : f.series) {
      const size_t n = std::min(s.x.size(), s.y.size());
      bool have = false;
      double lx = 0, ly = 0;
      for (size_t i = 0; i < n; ++i) {
        if (!Drawable(f.x, s.x[i]) || !Drawable(f.y, s.y[i])) {
          have = false;
          continue;
        }
        const double x = sx.Px(s.x[i]), y = sy.Px(s.y[i]);
        if (s.line && !s.bars && have) drawn_segments_.push_back({lx, ly, x, y});
        if (s.marker != Marker::kNone) drawn_markers_.emplace_back(x, y);
        lx = x;
        ly = y;
        have = true;
      }
    }
  }

  // The box [px] of a label `w` x `h` for the point (px, py) of a series with markers of
  // `marker_size`; false: the label is left out (no clear place, or the point is already
  // labelled).
  bool Place(double px, double py, double w, double h, double marker_size, Box* box) {
    // The first of sixteen places around the point (the width estimate generous by a few
    // pixels: a near miss reads as an overlap) that lies inside the plot and covers no
    // other label, line or marker; a label with no such place is left out (dense markers).
    // Near the point first, then a ring farther out.
    double places[16][2];
    for (int ring = 0; ring < 2; ++ring) {
      const double gap = 6.0 + marker_size + 12.0 * ring;
      const double ring_places[8][2] = {
          {gap, -gap - h},      {gap, gap},         {-gap - w, -gap - h}, {-gap - w, gap},
          {gap, -0.5 * h},      {-gap - w, -0.5 * h}, {-0.5 * w, -gap - h}, {-0.5 * w, gap}};
      for (int k = 0; k < 8; ++k) {
        places[8 * ring + k][0] = ring_places[k][0];
        places[8 * ring + k][1] = ring_places[k][1];
      }
    }
    // Where no place is clear of the lines and markers (a point in a corner that its line
    // leaves), the first inside the plot that covers no other label: the label's white halo
    // keeps it legible over a line.
    // A point on (or next to) one already labelled gets none: two labels beside one dot
    // would not say which is whose.
    const double near = 2.0 * marker_size + 2.0;
    if (std::any_of(labelled_points_.begin(), labelled_points_.end(), [&](const auto& q) {
          return std::hypot(q.first - px, q.second - py) < near;
        }))
      return false;
    for (int pass = 0; pass < 2; ++pass) {
      for (const auto& d : places) {
        *box = Box{px + d[0], py + d[1], w, h};
        if (box->x < plot_box_.x || box->y < plot_box_.y ||
            box->x + box->w > plot_box_.x + plot_box_.w ||
            box->y + box->h > plot_box_.y + plot_box_.h)
          continue;
        if (std::any_of(labels_.begin(), labels_.end(),
                        [&](const Box& b) { return b.Overlaps(*box); }))
          continue;
        if (pass == 0 &&
            std::any_of(drawn_segments_.begin(), drawn_segments_.end(), [&](const Segment& g) {
              return box->Crosses(g.ax, g.ay, g.bx, g.by);
            }))
          continue;
        if (pass == 0 &&
            std::any_of(drawn_markers_.begin(), drawn_markers_.end(), [&](const auto& m) {
              return Box{box->x - 3, box->y - 3, box->w + 6, box->h + 6}.Contains(m.first,
                                                                                   m.second);
            }))
          continue;
        labels_.push_back(*box);
        labelled_points_.emplace_back(px, py);
        return true;
      }
    }
    return false;
  }

 private:
  struct Segment {
    double ax, ay, bx, by;
  };
  Box plot_box_;
  std::vector<Box> labels_;                                 // point labels placed so far
  std::vector<std::pair<double, double>> labelled_points_;  // [px] the points they label
  std::vector<Segment> drawn_segments_;
  std::vector<std::pair<double, double>> drawn_markers_;
};

// One series: its bars or line, its markers and its point labels, clipped to the plot.
void DrawSeries(std::ostringstream& o, const Figure& f, const Series& s, const Scale& sx,
                const Scale& sy, const std::string& clip, double plot_bottom,
                PointLabels* point_labels) {
  const size_t n = std::min(s.x.size(), s.y.size());
  std::vector<double> px(n, kNaN), py(n, kNaN);
  for (size_t i = 0; i < n; ++i) {
    if (!Drawable(f.x, s.x[i]) || !Drawable(f.y, s.y[i])) continue;
    px[i] = sx.Px(s.x[i]);
    py[i] = sy.Px(s.y[i]);
  }
  o << "<g class=\"series\" data-label=\"" << Escape(s.label) << "\"" << clip << ">";
  if (s.bars) {
    const double base = f.y.log ? plot_bottom : sy.Px(0.0);
    o << "<g fill=\"" << Escape(s.colour) << "\" fill-opacity=\"0.55\" stroke=\""
      << Escape(s.colour) << "\">";
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(px[i])) continue;
      const double xa = sx.Px(s.x[i] - 0.5 * s.bar_width), xb = sx.Px(s.x[i] + 0.5 * s.bar_width);
      if (!std::isfinite(xa) || !std::isfinite(xb)) continue;
      o << "<rect x=\"" << Num(std::min(xa, xb)) << "\" y=\"" << Num(std::min(base, py[i]))
        << "\" width=\"" << Num(std::abs(xb - xa)) << "\" height=\""
        << Num(std::abs(py[i] - base))
        << "\"/>";
    }
    o << "</g>";
  } else if (s.line) {
    std::string d;
    bool pen = false, broken = false;
    size_t drawn = 0;
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(px[i])) {
        pen = false;
        broken = true;
        continue;
      }
      d += (pen ? "L" : "M") + Num(px[i]) + " " + Num(py[i]);
      pen = true;
      ++drawn;
    }
    if (s.closed && !broken && drawn > 2) d += "Z";
    if (!d.empty())
      o << "<path d=\"" << d << "\" fill=\"none\" stroke=\"" << Escape(s.colour)
        << "\" stroke-width=\"" << Num(s.line_width) << "\" stroke-linejoin=\"round\""
        << (s.dashed ? " stroke-dasharray=\"6 4\"" : "") << "/>";
  }
  if (s.marker != Marker::kNone) {
    o << "<g " << MarkerStyle(s) << ">";
    for (size_t i = 0; i < n; ++i)
      if (std::isfinite(px[i])) MarkerShape(o, s.marker, px[i], py[i], s.marker_size);
    o << "</g>";
  }
  if (!s.point_labels.empty()) {
    o << "<g font-size=\"" << kTickFont << "\" fill=\"" << Escape(s.colour)
      << "\" stroke=\"#ffffff\" stroke-width=\"3\" paint-order=\"stroke\">";
    for (size_t i = 0; i < n && i < s.point_labels.size(); ++i) {
      if (!std::isfinite(px[i]) || s.point_labels[i].empty()) continue;
      const double w = (kCharWidth + 0.6) * s.point_labels[i].size() + 4, h = kTickFont + 4.0;
      Box box{};
      if (!point_labels->Place(px[i], py[i], w, h, s.marker_size, &box)) continue;
      // The box's baseline: its bottom less the descent.
      o << "<text x=\"" << Num(box.x + 2) << "\" y=\"" << Num(box.y + box.h - 3) << "\">"
        << Escape(s.point_labels[i]) << "</text>";
    }
    o << "</g>";
  }
  o << "</g>\n";
}

// The legend's rows below the plot, from `y0` [px].
void DrawLegend(std::ostringstream& o, const std::vector<LegendEntry>& legend,
                const std::vector<LegendPlace>& placed, double y0) {
  o << "<g class=\"legend\" font-size=\"" << kLegendFont << "\">";
  for (size_t i = 0; i < legend.size(); ++i) {
    const double x = 12 + placed[i].x, y = y0 + placed[i].row * kLegendRow;
    const LegendEntry& e = legend[i];
    if (e.band) {
      o << "<rect x=\"" << Num(x) << "\" y=\"" << Num(y - 6) << "\" width=\"26\" height=\"12\" "
        << "fill=\"" << Escape(e.band->colour) << "\" fill-opacity=\""
        << Num(std::max(e.band->opacity, 0.15)) << "\" stroke=\"#999999\"/>";
    } else {
      const Series& s = *e.series;
      if (s.bars) {
        o << "<rect x=\"" << Num(x + 4) << "\" y=\"" << Num(y - 6) << "\" width=\"18\" "
          << "height=\"12\" fill=\"" << Escape(s.colour) << "\" fill-opacity=\"0.55\" stroke=\""
          << Escape(s.colour) << "\"/>";
      } else if (s.line) {
        o << "<path d=\"M" << Num(x) << " " << Num(y) << "h26\" stroke=\"" << Escape(s.colour)
          << "\" stroke-width=\"" << Num(s.line_width) << "\""
          << (s.dashed ? " stroke-dasharray=\"6 4\"" : "") << "/>";
      }
      if (s.marker != Marker::kNone) {
        o << "<g " << MarkerStyle(s) << ">";
        MarkerShape(o, s.marker, x + 13, y, s.marker_size);
        o << "</g>";
      }
    }
    o << "<text x=\"" << Num(x + 34) << "\" y=\"" << Num(y + 4) << "\">" << Escape(e.label)
      << "</text>";
  }
  o << "</g>\n";
}

// Where a figure's plot lies in the SVG [px], and its axes' mappings.
struct Layout {
  Scale sx, sy;
  double left = 0.0, top = 0.0;        // the plot's top left corner
  double plot_w = 0.0, plot_h = 0.0;   // the plot's size
  double plot_bottom = 0.0;            // top + plot_h
  double total_h = 0.0;                // the figure's height, legend included
};

// The layout: the data's ranges (points, bars' extents, bands, the background image), the
// margins (the y tick labels decide the left one), and an equal aspect's widened range.
Layout PlaceFigure(const Figure& f, bool has_data, int legend_rows) {
  // Ranges in transformed units.
  std::vector<double> xs, ys;
  for (const Series& s : f.series) {
    const size_t n = std::min(s.x.size(), s.y.size());
    for (size_t i = 0; i < n; ++i) {
      if (!Drawable(f.x, s.x[i]) || !Drawable(f.y, s.y[i])) continue;
      xs.push_back(s.x[i]);
      ys.push_back(s.y[i]);
      if (s.bars) {
        xs.push_back(s.x[i] - 0.5 * s.bar_width);
        xs.push_back(s.x[i] + 0.5 * s.bar_width);
        if (!f.y.log) ys.push_back(0.0);
      }
    }
  }
  if (has_data)
    for (const Band& b : f.bands) {
      ys.push_back(b.low);
      ys.push_back(b.high);
    }
  const bool has_image = !f.background.href.empty();
  if (has_image) {
    xs.push_back(f.background.x0);
    xs.push_back(f.background.x1);
    ys.push_back(f.background.y0);
    ys.push_back(f.background.y1);
  }
  const double margin = has_image ? 0.0 : 0.06;
  Layout l;
  Scale& sx = l.sx;
  Scale& sy = l.sy;
  sx.log = f.x.log;
  sx.reversed = f.x.reversed;
  sy.log = f.y.log;
  sy.reversed = !f.y.reversed;  // SVG's y grows downwards: an upright axis is "reversed" there
  Range(f.x, xs, margin, &sx.lo, &sx.hi);
  Range(f.y, ys, margin, &sy.lo, &sy.hi);

  // Margins: y tick labels decide the left one.
  int max_tick_chars = 1;
  if (has_data)
    for (const Tick& t : Ticks(f.y, sy.lo, sy.hi, 6))
      max_tick_chars = std::max<int>(max_tick_chars, static_cast<int>(t.label.size()));
  const double left = 30 + kCharWidth * std::min(max_tick_chars, 12) + 8;
  const double right = 18, top = f.title.empty() ? 14 : 34;
  const double legend_h = legend_rows * kLegendRow + (legend_rows ? 6 : 0);
  const double plot_w = std::max(60.0, f.width - left - right);
  double plot_h = std::max<double>(kMinPlotHeight, f.height - top - kAxisBottom);

  if (f.equal_aspect && has_data && !f.x.log && !f.y.log) {
    const double xr = sx.hi - sx.lo, yr = sy.hi - sy.lo;
    if (f.height_from_data)
      plot_h = std::clamp(plot_w * yr / xr, double(kMinPlotHeight), plot_h);
    // Widen the range that has fewer data units per pixel, about its centre.
    const double upp = std::max(xr / plot_w, yr / plot_h);  // units per pixel
    const double cx = 0.5 * (sx.lo + sx.hi), cy = 0.5 * (sy.lo + sy.hi);
    sx.lo = cx - 0.5 * upp * plot_w;
    sx.hi = cx + 0.5 * upp * plot_w;
    sy.lo = cy - 0.5 * upp * plot_h;
    sy.hi = cy + 0.5 * upp * plot_h;
  }
  sx.from = left;
  sx.to = left + plot_w;
  sy.from = top;
  sy.to = top + plot_h;
  l.left = left;
  l.top = top;
  l.plot_w = plot_w;
  l.plot_h = plot_h;
  l.total_h = top + plot_h + kAxisBottom + legend_h;
  l.plot_bottom = top + plot_h;
  return l;
}

// A tick's pixel (tick values are in transformed units).
double TickPx(const Scale& s, double t) { return s.Px(s.log ? std::pow(10.0, t) : t); }

// Under the series: the background image, or the grid; the bands.
void DrawBackground(std::ostringstream& o, const Figure& f, const Layout& l,
                    const std::string& clip, const std::vector<Tick>& xt,
                    const std::vector<Tick>& yt) {
  if (!f.background.href.empty()) {
    const double x0 = l.sx.Px(f.background.x0), x1 = l.sx.Px(f.background.x1);
    const double y0 = l.sy.Px(f.background.y0), y1 = l.sy.Px(f.background.y1);
    o << "<image" << clip << " x=\"" << Num(std::min(x0, x1)) << "\" y=\"" << Num(std::min(y0, y1))
      << "\" width=\"" << Num(std::abs(x1 - x0)) << "\" height=\"" << Num(std::abs(y1 - y0))
      << "\" preserveAspectRatio=\"none\" href=\"" << Escape(f.background.href) << "\"/>\n";
  } else {
    o << "<g stroke=\"#e3e3e3\" stroke-width=\"1\">";
    for (const Tick& t : xt)
      o << "<path d=\"M" << Num(TickPx(l.sx, t.value)) << " " << Num(l.top) << "V"
        << Num(l.plot_bottom) << "\"/>";
    for (const Tick& t : yt)
      o << "<path d=\"M" << Num(l.left) << " " << Num(TickPx(l.sy, t.value)) << "H"
        << Num(l.left + l.plot_w) << "\"/>";
    o << "</g>\n";
  }
  for (const Band& b : f.bands) {
    const double y0 = l.sy.Px(b.low), y1 = l.sy.Px(b.high);
    if (!std::isfinite(y0) || !std::isfinite(y1)) continue;
    o << "<rect class=\"band\"" << clip << " x=\"" << Num(l.left) << "\" y=\""
      << Num(std::min(y0, y1)) << "\" width=\"" << Num(l.plot_w) << "\" height=\""
      << Num(std::abs(y1 - y0)) << "\" fill=\"" << Escape(b.colour) << "\" fill-opacity=\""
      << Num(b.opacity) << "\"/>\n";
  }
}

// Over the series: the frame, ticks and tick labels.
void DrawFrame(std::ostringstream& o, const Layout& l, const std::vector<Tick>& xt,
               const std::vector<Tick>& yt) {
  o << "<rect x=\"" << Num(l.left) << "\" y=\"" << Num(l.top) << "\" width=\"" << Num(l.plot_w)
    << "\" height=\"" << Num(l.plot_h) << "\" fill=\"none\" stroke=\"#444444\"/>\n";
  o << "<g class=\"ticks\" font-size=\"" << kTickFont << "\" fill=\"#222222\">";
  for (const Tick& t : xt) {
    const double x = TickPx(l.sx, t.value);
    o << "<path d=\"M" << Num(x) << " " << Num(l.plot_bottom) << "v5\" stroke=\"#444444\"/>"
      << "<text x=\"" << Num(x) << "\" y=\"" << Num(l.plot_bottom + 19)
      << "\" text-anchor=\"middle\">" << Escape(t.label) << "</text>";
  }
  for (const Tick& t : yt) {
    const double y = TickPx(l.sy, t.value);
    o << "<path d=\"M" << Num(l.left) << " " << Num(y) << "h-5\" stroke=\"#444444\"/>"
      << "<text x=\"" << Num(l.left - 8) << "\" y=\"" << Num(y + 4) << "\" text-anchor=\"end\">"
      << Escape(t.label) << "</text>";
  }
  o << "</g>\n";
}

}  // namespace

// The figure in painting order (frame, grid, bands, series, axes, legend), sharing one
// coordinate mapping (PlaceFigure's); the parts are drawn by the functions above.
std::string RenderSvg(const Figure& f, const std::string& raw_id) {
  const std::string id = SafeId(raw_id);
  const bool has_data = HasData(f);

  // Legend entries and their rows (laid out left to right, wrapped at the figure's width).
  std::vector<LegendEntry> legend;
  for (const Series& s : f.series)
    if (!s.label.empty()) legend.push_back({&s, nullptr, s.label});
  for (const Band& b : f.bands)
    if (!b.label.empty()) legend.push_back({nullptr, &b, b.label});
  const std::vector<LegendPlace> placed = LayoutLegend(legend, f.width);
  const int legend_rows = legend.empty() ? 0 : placed.back().row + 1;
  const Layout l = PlaceFigure(f, has_data, legend_rows);
  const double left = l.left, top = l.top, plot_w = l.plot_w, plot_h = l.plot_h;
  const double plot_bottom = l.plot_bottom, total_h = l.total_h;

  std::ostringstream o;
  o << "<svg xmlns=\"http://www.w3.org/2000/svg\" class=\"plot\" width=\"" << f.width
    << "\" height=\"" << Num(total_h) << "\" viewBox=\"0 0 " << f.width << " " << Num(total_h)
    << "\" font-family=\"DejaVu Sans, Helvetica, Arial, sans-serif\" role=\"img\" aria-label=\""
    << Escape(f.title) << "\">\n";
  o << "<title>" << Escape(f.title) << "</title>\n";
  o << "<defs><clipPath id=\"" << id << "-clip\"><rect x=\"" << Num(left) << "\" y=\"" << Num(top)
    << "\" width=\"" << Num(plot_w) << "\" height=\"" << Num(plot_h) << "\"/></clipPath></defs>\n";
  o << "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
  if (!f.title.empty())
    o << "<text x=\"" << Num(left) << "\" y=\"22\" font-size=\"" << kTitleFont
      << "\" font-weight=\"bold\">" << Escape(f.title) << "</text>\n";

  // Axis labels (always, so that even an empty figure says what it would show).
  o << "<text class=\"axis-label\" x=\"" << Num(left + 0.5 * plot_w) << "\" y=\""
    << Num(plot_bottom + 40) << "\" font-size=\"" << kLabelFont << "\" text-anchor=\"middle\">"
    << Escape(f.x.label) << "</text>\n";
  o << "<text class=\"axis-label\" transform=\"translate(16 " << Num(top + 0.5 * plot_h)
    << ") rotate(-90)\" font-size=\"" << kLabelFont << "\" text-anchor=\"middle\">"
    << Escape(f.y.label) << "</text>\n";

  if (!has_data) {
    o << "<rect x=\"" << Num(left) << "\" y=\"" << Num(top) << "\" width=\"" << Num(plot_w)
      << "\" height=\"" << Num(plot_h) << "\" fill=\"#f7f7f7\" stroke=\"#444444\"/>\n";
    o << "<text class=\"no-data\" x=\"" << Num(left + 0.5 * plot_w) << "\" y=\""
      << Num(top + 0.5 * plot_h) << "\" font-size=\"14\" text-anchor=\"middle\" fill=\"#555555\">"
      << Escape(f.no_data_text) << "</text>\n</svg>\n";
    return o.str();
  }

  const std::string clip = " clip-path=\"url(#" + id + "-clip)\"";
  const std::vector<Tick> xt =
      Ticks(f.x, l.sx.lo, l.sx.hi, std::max(3, static_cast<int>(plot_w / 90)));
  const std::vector<Tick> yt =
      Ticks(f.y, l.sy.lo, l.sy.hi, std::max(3, static_cast<int>(plot_h / 50)));
  DrawBackground(o, f, l, clip, xt, yt);
  // Series: bars, lines, markers, point labels.
  PointLabels point_labels(f, l.sx, l.sy, Box{left, top, plot_w, plot_bottom - top});
  for (const Series& s : f.series)
    DrawSeries(o, f, s, l.sx, l.sy, clip, plot_bottom, &point_labels);
  DrawFrame(o, l, xt, yt);
  if (!legend.empty()) DrawLegend(o, legend, placed, plot_bottom + kAxisBottom + 4);
  o << "</svg>\n";
  return o.str();
}

}  // namespace rodfit::svg
