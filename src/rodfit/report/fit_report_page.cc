// The fit report's page (fit_report_page.h). Residuals are shown in sigmas, one value per noisy
// dimension of a measurement: every component for markers, pixels with s, forces and moments;
// for the closest-point observations (image curves, points3d, surface points) only the
// components across the curve, since the one along it is zero by construction (observations.h)
// and would pile up at 0 in the histogram. Positions are shown in mm, pixels in px, forces in N.
#include "rodfit/report/fit_report_page.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/image_files.h"
#include "rodfit/model/rod.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/report/fit_report.h"
#include "rodfit/report/fit_views3d.h"
#include "rodfit/report/plotly_library.h"
#include "rodfit/report/svg_plot.h"
#include "rodfit/report/view3d.h"
#include "rodfit/version.h"

namespace rodfit {
namespace {

using svg::Escape;

constexpr double kMm = 1e3;  // [mm/m]: positions are plotted in millimetres
constexpr double kPi = 3.14159265358979323846;
const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e",
                                "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"};
const char* Colour(size_t i) { return kPalette[i % (sizeof(kPalette) / sizeof(kPalette[0]))]; }
const char* const kObserved = "#d62728";  // measurements: red markers
const char* const kFitted = "#1f5fbf";    // the model at the fit: blue lines and crosses
const char* const kComponent[] = {"#1f77b4", "#2ca02c", "#d62728"};  // x, y, z
constexpr size_t kMaxPixelsDrawn = 80;  // per entry in a camera view, so the image shows
// Residual plots show at most this many sigmas; values beyond are drawn at the edge.
constexpr double kMaxSigmasShown = 12.0;

// ---------------------------------------------------------------------------------------------
// Numbers and units.

// "2.463×10⁻⁶" in HTML (a <sup> exponent) outside [1e-3, 1e5); "%.{digits}g" inside.
std::string HtmlNumber(double v, int digits = 4) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "∞" : "−∞";
  char b[64];
  const double a = std::abs(v);
  if (a == 0.0 || (a >= 1e-3 && a < 1e5)) {
    std::snprintf(b, sizeof(b), "%.*g", digits, v);
    std::string s = b;
    if (!s.empty() && s[0] == '-') s = "−" + s.substr(1);
    return s;
  }
  int e = static_cast<int>(std::floor(std::log10(a)));
  double m = v / std::pow(10.0, e);
  std::snprintf(b, sizeof(b), "%.*f", std::max(0, digits - 1), m);
  if (std::abs(std::stod(b)) >= 10.0) {  // 9.9996 rounded up to 10.000
    ++e;
    m = v / std::pow(10.0, e);
    std::snprintf(b, sizeof(b), "%.*f", std::max(0, digits - 1), m);
  }
  std::string s = b;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s[0] == '-') s = "−" + s.substr(1);
  return s + "×10<sup>" + (e < 0 ? "−" + std::to_string(-e) : std::to_string(e)) + "</sup>";
}

// "N m^2" -> "N m<sup>2</sup>", escaped.
std::string HtmlUnit(const std::string& unit) {
  std::string out;
  for (size_t i = 0; i < unit.size(); ++i) {
    if (unit[i] == '^') {
      size_t j = i + 1;
      if (j < unit.size() && unit[j] == '-') ++j;
      while (j < unit.size() && std::isdigit(static_cast<unsigned char>(unit[j]))) ++j;
      out += "<sup>" + Escape(unit.substr(i + 1, j - i - 1)) + "</sup>";
      i = j - 1;
    } else {
      out += Escape(std::string(1, unit[i]));
    }
  }
  return out;
}

std::string WithUnit(double v, const std::string& unit, int digits = 4) {
  return HtmlNumber(v, digits) + (unit.empty() ? "" : "&nbsp;" + HtmlUnit(unit));
}

// Wall times are the only part of the page that changes from run to run: each is marked
// (class "wall-time") so that a comparison of two runs can leave them out.
std::string Duration(double seconds) {
  char b[96];
  if (seconds < 1.0)
    std::snprintf(b, sizeof(b), "<span class=\"wall-time\">%.3g&nbsp;ms</span>", seconds * 1e3);
  else
    std::snprintf(b, sizeof(b), "<span class=\"wall-time\">%.3g&nbsp;s</span>", seconds);
  return b;
}

std::string Percent(double fraction) {
  char b[32];
  std::snprintf(b, sizeof(b), "%.1f&nbsp;%%", 100.0 * fraction);
  return b;
}

// A name for a figure file: letters, digits, '-' and '_' only.
std::string FileSafe(const std::string& s) {
  std::string out = s;
  for (char& c : out)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  return out.substr(0, 80);
}

std::string Stem(const std::string& path) { return std::filesystem::path(path).stem().string(); }
std::string FileName(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

// The views of entries whose measurement is a centre-line observation.
bool IsCentreLine(const ObservationSpec& spec) {
  const ReportView view = KindOf(spec).view;
  return view == ReportView::kMarkers3d || view == ReportView::kPoints3d ||
         view == ReportView::kPixels || view == ReportView::kImage;
}

// ---------------------------------------------------------------------------------------------
// The page being built.

class Page {
 public:
  std::ostringstream html;
  std::vector<std::pair<std::string, std::string>> figures;

  /// Appends `figure` inline as <figure class="fig CLS" ATTRS> with its caption (HTML) and keeps
  /// it as figures/NAME.svg.
  void Figure(const svg::Figure& figure, const std::string& cls, const std::string& name,
              const std::string& attributes, const std::string& caption_html) {
    std::string file = FileSafe(name);
    if (!used_.insert(file).second) file += "_" + std::to_string(figures.size());
    used_.insert(file);
    const std::string svg = svg::RenderSvg(figure, "f" + std::to_string(figures.size() + 1));
    html << "<figure class=\"fig " << cls << "\"" << attributes << ">\n"
         << svg << "<figcaption>" << caption_html << " <a class=\"svg-file\" href=\"figures/"
         << file << ".svg\">SVG</a></figcaption>\n</figure>\n";
    figures.emplace_back(file + ".svg", svg);
  }

 private:
  std::set<std::string> used_;
};

// ---------------------------------------------------------------------------------------------
// Residuals.

// Unit vectors n1, n2 across a 3-D tangent t (any right-handed pair).
void Across(const Eigen::Vector3d& t, Eigen::Vector3d* n1, Eigen::Vector3d* n2) {
  const Eigen::Vector3d u = t.normalized();
  Eigen::Index axis;
  u.cwiseAbs().minCoeff(&axis);
  *n1 = u.cross(Eigen::Vector3d::Unit(axis)).normalized();
  *n2 = u.cross(*n1);
}

// The noisy residual components in sigmas of a 3-D closest-point residual e (already / sigma) at
// the foot of q on `polyline`: the two across the foot's edge, or all three when the foot is a
// vertex (beyond an end, where e need not be perpendicular to an edge).
void AcrossComponents(const Eigen::Matrix3Xd& polyline, const Eigen::Vector3d& q,
                      const Eigen::Vector3d& e, std::vector<double>* out) {
  const PolylineFoot foot = ClosestPointOnPolyline<3>(polyline, q);
  if (foot.edge < 0 || foot.vertex >= 0) {
    for (int i = 0; i < 3; ++i) out->push_back(e[i]);
    return;
  }
  const Eigen::Vector3d t = polyline.col(foot.edge + 1) - polyline.col(foot.edge);
  if (!(t.norm() > 0)) {
    for (int i = 0; i < 3; ++i) out->push_back(e[i]);
    return;
  }
  Eigen::Vector3d n1, n2;
  Across(t, &n1, &n2);
  out->push_back(e.dot(n1));
  out->push_back(e.dot(n2));
}

// Per measurement of a centre-line observation at `shape`: its noisy components in sigmas.
// Empty when the observation cannot be evaluated there.
std::vector<std::vector<double>> NoisyComponents(const Measurement& obs, const Mat3X& shape) {
  std::vector<std::vector<double>> out;
  SolvedCase at;
  at.x = &shape;
  VecX r(obs.num_residuals());
  std::string why;
  if (!obs.Evaluate(at, r.data(), nullptr, &why)) return out;
  const int n = obs.num_measurements();
  const int dim = n > 0 ? obs.num_residuals() / n : 0;
  out.resize(n);
  if (const auto* points = ModelOf<Points3dObservation>(obs)) {
    for (int m = 0; m < n; ++m)
      AcrossComponents(shape, points->samples()[m], r.segment<3>(3 * m), &out[m]);
    return out;
  }
  if (const auto* curve = ModelOf<ImageCurveObservation>(obs)) {
    Eigen::Matrix2Xd uv(2, shape.cols());
    bool projected = true;
    for (int i = 0; i < shape.cols() && projected; ++i) {
      Eigen::Vector2d p;
      projected = Project(curve->camera(), Eigen::Vector3d(shape.col(i)), &p);
      uv.col(i) = p;
    }
    for (int m = 0; m < n; ++m) {
      const Eigen::Vector2d e = r.segment<2>(2 * m);
      const PolylineFoot foot =
          projected ? ClosestPointOnPolyline<2>(uv, curve->pixels()[m]) : PolylineFoot();
      if (foot.edge < 0 || foot.vertex >= 0) {
        out[m] = {e.x(), e.y()};
        continue;
      }
      const Eigen::Vector2d t = uv.col(foot.edge + 1) - uv.col(foot.edge);
      if (!(t.norm() > 0)) {
        out[m] = {e.x(), e.y()};
        continue;
      }
      out[m] = {e.dot(Eigen::Vector2d(-t.y(), t.x()).normalized())};  // signed, across
    }
    return out;
  }
  for (int m = 0; m < n; ++m)
    for (int i = 0; i < dim; ++i) out[m].push_back(r[m * dim + i]);
  return out;
}

// One observation's residuals for the plots: x and the values. x is the arc length of each
// measurement on the fitted rod for centre-line entries (markers at their s, points and pixels
// at their closest point's), the angle around the section for a poke's surface points, and the
// reading's number for forces and moments.
struct ResidualSeries {
  enum class Along { kArc, kAngle, kReading };
  std::string label;
  Along along = Along::kArc;
  std::vector<double> x, sigmas;  // one entry per noisy component
};

// ---------------------------------------------------------------------------------------------
// Figures.

// A closed polyline for a ring: the first node repeated.
Eigen::Matrix3Xd Closed(const Eigen::Matrix3Xd& ring) {
  Eigen::Matrix3Xd out(3, ring.cols() + 1);
  out.leftCols(ring.cols()) = ring;
  out.col(ring.cols()) = ring.col(0);
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char* const kTable =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                       (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                       static_cast<unsigned char>(bytes[i + 2]);
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += kTable[(v >> 6) & 63];
    out += kTable[v & 63];
  }
  if (i + 1 == bytes.size()) {
    const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += "==";
  } else if (i + 2 == bytes.size()) {
    const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                       (static_cast<unsigned char>(bytes[i + 1]) << 8);
    out += kTable[(v >> 18) & 63];
    out += kTable[(v >> 12) & 63];
    out += kTable[(v >> 6) & 63];
    out += '=';
  }
  return out;
}

// The part [u0, u1) x [v0, v1) of `image` as a data: URI (JPEG for 8-bit photographs, PNG
// otherwise), at most kMaxImageSide pixels on its longer side so the page stays small.
std::string ImageDataUri(const std::string& path, const cv::Mat& image, const cv::Rect& crop) {
  constexpr int kMaxImageSide = 1200;
  cv::Mat part = image(crop).clone();
  const int side = std::max(part.cols, part.rows);
  if (side > kMaxImageSide) {
    const double f = double(kMaxImageSide) / side;
    cv::resize(part, part, cv::Size(), f, f, cv::INTER_AREA);
  }
  const bool jpeg = part.depth() == CV_8U && (part.channels() == 1 || part.channels() == 3);
  const std::string ext = jpeg ? ".jpg" : ".png";
  const std::string bytes =
      EncodeImage((std::filesystem::path(path).parent_path() / ("report" + ext)).string(), part);
  return std::string("data:image/") + (jpeg ? "jpeg" : "png") + ";base64," + Base64(bytes);
}

// Text of an arc length for a marker's label: "s = 0.12 m".
std::string ArcLabel(double s) {
  char b[40];
  std::snprintf(b, sizeof(b), "s = %.3g m", s);
  return b;
}

// The world axes of the two long views of a 3-D shape: the axis of largest extent a, with each
// of the other two. Returns {{a, c}, {a, b}} (b < c) so that a rod along x is seen from the side
// (x-z) and from above (x-y).
std::array<std::array<int, 2>, 2> LongViews(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  Eigen::Index a = 0;
  if ((hi - lo).allFinite()) (hi - lo).maxCoeff(&a);
  const int b = a == 0 ? 1 : 0, c = a == 2 ? 1 : 2;
  return {{{static_cast<int>(a), c}, {static_cast<int>(a), b}}};
}

const char* AxisName(int i) { return i == 0 ? "x" : i == 1 ? "y" : "z"; }

// ---------------------------------------------------------------------------------------------
// The builder.

// A camera view's zoom [px]: every observed and fitted pixel on the sensor (then a margin).
struct PixelBox {
  double u0 = INFINITY, u1 = -INFINITY, v0 = INFINITY, v1 = -INFINITY;
  void Grow(const Camera& cam, const Eigen::Vector2d& p) {
    if (!p.allFinite() || !cam.InImage(p, -50.0)) return;
    u0 = std::min(u0, p.x());
    u1 = std::max(u1, p.x());
    v0 = std::min(v0, p.y());
    v1 = std::max(v1, p.y());
  }
  bool empty() const { return !(u1 >= u0); }
};

// A centre-line entry of a case and its measurement.
using CameraEntry = std::pair<const ObservationSpec*, const Measurement*>;

// What a camera's entries draw: their series, the fitted markers, the image file (the last
// image entry's) and the pixels extracted from images.
struct CameraPixels {
  std::vector<svg::Series> observed;
  svg::Series fitted_markers;
  std::string image_file;
  std::vector<Eigen::Vector2d> curve_pixels;  // observed without s
};

// A force reading of a fit case with its residual.
struct ForceReading {
  double x;  // time [s] or reading number
  Vec3 measured, error;
  double sigma;
};

class Builder {
 public:
  Builder(const Experiment& e, const FitInput& in, const FitResult& r,
          const std::vector<std::string>& warnings)
      : e_(e), in_(in), r_(r), shapes_ok_(r.shapes.size() == in.cases.size()),
        warnings_(warnings), plotly_(FindPlotlyLibrary()) {
    if (!plotly_.missing.empty()) own_warnings_.push_back(plotly_.missing);
    warnings_.insert(warnings_.end(), own_warnings_.begin(), own_warnings_.end());
  }

  FitReportPage Build() {
    Head();
    Summary();
    Parameters();
    Cases();
    AllResiduals();
    Convergence();
    // The 3-D views' library and script last, so the tables and figures show at once.
    if (views_ > 0) {
      if (!plotly_.script.empty()) {
        std::string library = plotly_.script;
        // Inside <script> nothing may read as its end tag.
        for (size_t at = library.find("</"); at != std::string::npos; at = library.find("</", at + 3))
          library.insert(at + 1, "\\");
        page_.html << "<script>/* plotly.js, from " << Escape(FileName(plotly_.path))
                   << " (MIT license) */\n" << library << "\n</script>\n";
      }
      page_.html << view3d::ViewScript();
    }
    page_.html << "<footer>Tables beside this page: <a href=\"summary.csv\">summary.csv</a> (RMS "
                  "per observation), <a href=\"residuals.csv\">residuals.csv</a> (every "
                  "measurement's residual); each figure as SVG in <code>figures/</code>. Written "
                  "by rodfit "
               << Escape(RODFIT_VERSION) << ".</footer>\n</body>\n</html>\n";
    return {page_.html.str(), std::move(page_.figures), own_warnings_};
  }

 private:
  // The experiment case a fit case belongs to: itself, or for the grasped case of a haptic
  // sample ("drag@t=1.25", fit_input.cc) the case it was made from. -1 when none.
  int ExperimentCase(size_t ci) const {
    if (ci < e_.cases.size()) return static_cast<int>(ci);
    const std::string& name = in_.cases[ci].load_case.name;
    int best = -1;
    size_t best_len = 0;
    for (size_t c = 0; c < e_.scene.cases.size(); ++c) {
      const std::string prefix = e_.scene.cases[c].name + "@t=";
      if (name.compare(0, prefix.size(), prefix) == 0 && prefix.size() > best_len) {
        best = static_cast<int>(c);
        best_len = prefix.size();
      }
    }
    return best;
  }

  void Head() {
    const std::string name = FileName(e_.path);
    page_.html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
               << "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
               << "<meta name=\"generator\" content=\"rodfit " << Escape(RODFIT_VERSION)
               << "\">\n<title>rodfit fit report: " << Escape(name) << "</title>\n<style>\n"
               << "body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;font-size:15px;"
                  "margin:24px auto;max-width:1400px;padding:0 16px;color:#222;line-height:1.4}\n"
                  "h1{font-size:24px}h2{font-size:20px;border-bottom:1px solid #ccc;"
                  "padding-bottom:4px;margin-top:36px}h3{font-size:17px;margin-top:24px}\n"
                  "table{border-collapse:collapse;margin:8px 0 16px}\n"
                  "th,td{border:1px solid #ccc;padding:4px 8px;text-align:left;"
                  "vertical-align:top}th{background:#f2f2f2}\n"
                  "td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}\n"
                  "tr.not-identifiable td{background:#fff1e6}\n"
                  ".verdict-no{color:#b34700;font-weight:bold}\n"
                  ".figures{display:flex;flex-wrap:wrap;gap:16px;align-items:flex-start}\n"
                  "figure{margin:0;border:1px solid #ddd;padding:6px;background:#fff}\n"
                  "figure svg{display:block;max-width:100%;height:auto}\n"
                  "figcaption{font-size:13px;color:#444;max-width:640px;margin-top:4px}\n"
                  "table.correlation td{text-align:center;min-width:64px}\n"
                  ".warn{color:#b30000;font-weight:bold}\n"
                  "nav a{margin-right:12px}footer{margin-top:40px;font-size:13px;color:#555}\n"
                  "div.view3d{border:1px solid #ddd;margin:8px 0 16px;background:#fff}\n"
                  "p.view3d-note{padding:8px;margin:0}\n"
                  "ul.warnings li{margin-bottom:6px}\n"
                  ".colour-legend{display:flex;align-items:center;gap:8px;font-size:13px}\n"
                  ".colour-legend span.bar{display:inline-block;width:240px;height:14px;"
                  "border:1px solid #999;background:linear-gradient(to right,rgb(31,119,180),"
                  "#fff,rgb(214,39,40))}\n"
                  // Save as PDF: the tables and the SVG figures, one figure never split over
                  // two pages; the interactive 3-D views and the navigation stay on screen.
                  "@media print{body{max-width:none;margin:0;font-size:11px}nav,div.view3d,"
                  "a.svg-file{display:none}.figures{display:block}figure{break-inside:avoid;"
                  "page-break-inside:avoid;margin-bottom:8px;border:none}h2,h3{break-after:avoid}"
                  "table{break-inside:auto}tr{break-inside:avoid}.print-only{display:block}}\n"
                  ".print-only{display:none}\n"
               << "</style>\n" << view3d::ErrorRecorderScript() << "</head>\n<body>\n"
               << "<h1>Fit report: <code>" << Escape(name) << "</code></h1>\n"
               << "<p class=\"meta\">Experiment <code>" << Escape(e_.path) << "</code>; "
               << e_.cases.size() << " case" << (e_.cases.size() == 1 ? "" : "s")
               << "; rodfit " << Escape(RODFIT_VERSION) << ".</p>\n"
               << "<nav><a href=\"#summary\">Summary</a><a href=\"#parameters\">Parameters</a>"
                  "<a href=\"#cases\">Cases</a><a href=\"#residuals\">Residuals</a>"
                  "<a href=\"#convergence\">Convergence and timing</a></nav>\n";
  }

  void Summary() {
    std::ostringstream& h = page_.html;
    const VarianceBand band = ResidualVarianceBand(r_.residual_dof);
    h << "<section id=\"summary\">\n<h2>Summary</h2>\n<table class=\"summary\">\n";
    h << "<tr><th>result</th><td>"
      << (r_.success ? "converged" : "<span class=\"warn\">failed</span>")
      << ": " << Escape(r_.message) << "</td></tr>\n";
    h << "<tr><th>iterations</th><td class=\"num\">" << r_.iterations << "</td></tr>\n";
    if (r_.global_evaluations > 0)
      h << "<tr><th>global search</th><td class=\"num\">" << r_.global_evaluations
        << " evaluations</td></tr>\n";
    h << "<tr><th>cost, start → end</th><td class=\"num\">" << HtmlNumber(r_.initial_cost)
      << " → " << HtmlNumber(r_.final_cost) << "</td></tr>\n";
    h << "<tr><th>residuals</th><td class=\"num\">" << r_.num_residuals << " ("
      << r_.residual_dof << " degrees of freedom)</td></tr>\n";
    const bool plausible = r_.residual_variance >= band.low && r_.residual_variance <= band.high;
    h << "<tr><th>residual variance (χ²/dof)</th><td class=\"num\">"
      << HtmlNumber(r_.residual_variance, 3) << " (expected " << HtmlNumber(band.low, 2) << " to "
      << HtmlNumber(band.high, 2) << " for correct sigmas"
      << (plausible ? ")" : ") <span class=\"warn\">outside</span>") << "</td></tr>\n";
    h << "<tr><th>loss</th><td>" << RobustLossName(e_.fit.loss);
    if (e_.fit.loss != RobustLoss::kNone)
      h << ", scale " << HtmlNumber(e_.fit.loss_scale, 3) << "&nbsp;σ";
    h << (e_.fit.trusted_sigmas ? "; sigmas trusted (covariance not rescaled)" : "")
      << "</td></tr>\n";
    h << "<tr><th>wall time</th><td class=\"num\">" << Duration(r_.seconds) << "</td></tr>\n";
    h << "</table>\n";
    // Every warning of the run, with what to do about it: what a terminal showed on stderr.
    if (!warnings_.empty()) {
      h << "<h3 class=\"warn\">Warnings (" << warnings_.size() << ")</h3>\n<ul class=\"warnings\">\n";
      for (const std::string& w : warnings_) h << "<li>" << Escape(w) << "</li>\n";
      h << "</ul>\n";
    } else {
      h << "<p class=\"no-warnings\">No warnings.</p>\n";
    }
    h << "</section>\n";
  }

  void Parameters() {
    std::ostringstream& h = page_.html;
    h << "<section id=\"parameters\">\n<h2>Parameters</h2>\n";
    h << "<table class=\"parameters\">\n<tr><th>parameter</th><th>value ± std</th><th>unit</th>"
         "<th>relative std</th><th>identifiable</th><th>start</th><th>bounds</th>"
         "<th>at a bound</th></tr>\n";
    std::vector<const Parameter*> held;
    for (const Parameter& p : r_.parameters) {
      if (!p.fit) {
        held.push_back(&p);
        continue;
      }
      h << "<tr class=\"parameter" << (p.identifiable ? "" : " not-identifiable")
        << "\" data-name=\"" << Escape(p.name) << "\"><td><code>" << Escape(p.name)
        << "</code></td>";
      if (p.identifiable && p.std) {
        h << "<td class=\"num\">" << HtmlNumber(p.value) << " ± " << HtmlNumber(*p.std, 2)
          << "</td><td>" << HtmlUnit(p.unit()) << "</td><td class=\"num\">"
          << (p.value != 0 ? Percent(*p.std / std::abs(p.value)) : "—") << "</td>"
          << "<td>yes</td>";
      } else {
        // Where the fit stopped is not a measurement: no number an importer could mistake.
        h << "<td class=\"num\">not determined</td><td>" << HtmlUnit(p.unit())
          << "</td><td class=\"num\">—</td><td><span class=\"verdict-no\">no</span>: "
          << Escape(p.reason) << "</td>";
      }
      h << "<td class=\"num\">" << WithUnit(p.start, "") << "</td><td class=\"num\">";
      if (p.min || p.max)
        h << "[" << (p.min ? HtmlNumber(*p.min) : "0") << ", "
          << (p.max ? HtmlNumber(*p.max) : "∞") << "]";
      else
        h << "none";
      h << "</td><td>" << (p.at_bound ? "<span class=\"warn\">yes</span>" : "no") << "</td></tr>\n";
    }
    h << "</table>\n";
    if (!held.empty()) {
      h << "<p>Held at their given values:</p>\n<table class=\"held\">\n<tr><th>parameter</th>"
           "<th>value</th><th>unit</th></tr>\n";
      for (const Parameter* p : held)
        h << "<tr><td><code>" << Escape(p->name) << "</code></td><td class=\"num\">"
          << HtmlNumber(p->value) << "</td><td>" << HtmlUnit(p->unit()) << "</td></tr>\n";
      h << "</table>\n";
    }
    // Correlations among the fitted parameters (of their logs), coloured: red positive, blue
    // negative, the stronger the deeper.
    const Eigen::MatrixXd& c = r_.correlation;
    if (c.rows() > 0 && c.rows() == c.cols() &&
        c.rows() == static_cast<Eigen::Index>(r_.fitted_names.size())) {
      h << "<h3>Correlation (of the logs of the fitted parameters)</h3>\n<table "
           "class=\"correlation\">\n<tr><th></th>";
      for (const std::string& n : r_.fitted_names) h << "<th><code>" << Escape(n) << "</code></th>";
      h << "</tr>\n";
      for (Eigen::Index i = 0; i < c.rows(); ++i) {
        h << "<tr><th><code>" << Escape(r_.fitted_names[i]) << "</code></th>";
        for (Eigen::Index j = 0; j < c.cols(); ++j) {
          const double rho = c(i, j);
          if (!std::isfinite(rho)) {
            h << "<td>—</td>";
            continue;
          }
          const double a = std::min(1.0, std::abs(rho));
          // White blended towards red (214, 39, 40) or blue (31, 119, 180) by |rho|.
          const int full[3] = {rho >= 0 ? 214 : 31, rho >= 0 ? 39 : 119, rho >= 0 ? 40 : 180};
          int rgb[3];
          for (int k = 0; k < 3; ++k) rgb[k] = 255 - static_cast<int>(a * (255 - full[k]));
          char style[96];
          std::snprintf(style, sizeof(style), "background:rgb(%d,%d,%d);color:%s", rgb[0], rgb[1],
                        rgb[2], a > 0.6 ? "#fff" : "#000");
          char v[32];
          std::snprintf(v, sizeof(v), "%+.3f", rho);
          h << "<td class=\"num\" style=\"" << style << "\">" << v << "</td>";
        }
        h << "</tr>\n";
      }
      h << "</table>\n<div class=\"colour-legend\">correlation: <span>−1</span><span "
           "class=\"bar\" title=\"blue: negative, white: none, red: positive\"></span><span>+1"
           "</span> (|ρ| near 1: the data tell the two apart poorly)</div>\n";
    }
    h << "</section>\n";
  }

  void Cases() {
    page_.html << "<section id=\"cases\">\n<h2>Cases</h2>\n";
    if (e_.scene.dynamics) {
      // A moving experiment has no static fit cases: its cases are seen through sequences.
      for (size_t c = 0; c < e_.cases.size(); ++c) {
        page_.html << "<h3 class=\"case\" id=\"case-" << c << "\">Case <code>"
                   << Escape(e_.scene.cases[c].name) << "</code></h3>\n";
        view3d::View view;
        if (MovingCaseView(e_, r_, c, RecordedSamples(c), RecordedForces(c),
                           "view3d-case-" + std::to_string(c), &view))
          View(view);
        page_.html << "<div class=\"figures\">\n";
        SequenceViews(c);
        page_.html << "</div>\n";
      }
      page_.html << "</section>\n";
      return;
    }
    if (!shapes_ok_)
      page_.html << "<p class=\"warn\">Some cases could not be evaluated at the fitted "
                    "parameters: their shapes are not shown.</p>\n";
    for (size_t c = 0; c < e_.cases.size() && c < in_.cases.size(); ++c) {
      page_.html << "<h3 class=\"case\" id=\"case-" << c << "\">Case <code>"
                 << Escape(e_.scene.cases[c].name) << "</code></h3>\n";
      if (shapes_ok_) {
        std::vector<size_t> samples;  // the case's haptic samples (grasped fit cases)
        for (size_t ci = e_.cases.size(); ci < in_.cases.size(); ++ci)
          if (ExperimentCase(ci) == static_cast<int>(c)) samples.push_back(ci);
        View(StaticCaseView(e_, in_, r_, c, samples, "view3d-case-" + std::to_string(c)));
      }
      page_.html << "<div class=\"figures\">\n";
      if (shapes_ok_) {
        CameraViews(c);
        ShapeViews(c);
        SectionView(c);
      }
      ForcePlots(c);
      CaseResiduals(c);
      page_.html << "</div>\n";
    }
    page_.html << "</section>\n";
  }

  // A 3-D view in the page (drawn by the script Build() adds once there is one).
  void View(const view3d::View& view) {
    page_.html << view3d::RenderView(view)
               << "<p class=\"print-only\">(The interactive 3-D view of this case is in the "
                  "page on screen.)</p>\n";
    ++views_;
  }

  // A moving case's 3-D samples (markers and points, not pixels), with the fitted run's.
  std::vector<RecordedSample> RecordedSamples(size_t c) const {
    std::vector<RecordedSample> out;
    const std::string& case_name = e_.scene.cases[c].name;
    for (const ObservationSpec& spec : e_.cases[c].observations) {
      const ReportView view = KindOf(spec).view;
      if (view != ReportView::kMarkers3d && view != ReportView::kPoints3d) continue;
      const std::string label = EntryLabel(spec);
      std::vector<SequenceSample> samples;
      try {
        samples = SequenceSamples(spec);
      } catch (const InputError&) {
        continue;  // the file changed since the fit read it
      }
      std::vector<const MeasurementResidual*> errors(samples.size(), nullptr);
      for (const MeasurementResidual& mr : r_.measurement_residuals)
        if (mr.case_name == case_name && mr.observation == label && mr.measurement >= 0 &&
            static_cast<size_t>(mr.measurement) < errors.size())
          errors[mr.measurement] = &mr;
      for (size_t k = 0; k < samples.size(); ++k) {
        RecordedSample rs;
        rs.t = samples[k].t;
        rs.s = samples[k].s;
        rs.observed = samples[k].value;
        if (errors[k]) {
          rs.model = samples[k].value + errors[k]->error;
          rs.sigma = errors[k]->sigma;
        }
        rs.entry = label;
        out.push_back(rs);
      }
    }
    return out;
  }

  // A moving case's load cell readings (its `reaction` entries), with the fitted run's force.
  std::vector<RecordedForce> RecordedForces(size_t c) const {
    std::vector<RecordedForce> out;
    const std::string& case_name = e_.scene.cases[c].name;
    for (const ObservationSpec& spec : e_.cases[c].observations) {
      if (KindOf(spec).view != ReportView::kReaction) continue;
      const std::string label = EntryLabel(spec);
      std::map<double, Vec3> recorded;  // as ReactionSequenceViews reads them
      try {
        const CsvTable table = CsvTable::Read(spec.file);
        const bool by_time = table.HasColumn("t");
        const std::vector<double> key = table.Column(by_time ? "t" : "frame");
        std::vector<std::vector<std::string>> text;
        for (const char* col : {"fx", "fy", "fz"}) text.push_back(table.TextColumn(col));
        for (int row = 0; row < table.num_rows(); ++row) {
          Vec3 f;
          bool taken = true;
          for (int i = 0; i < 3; ++i) taken = taken && ParseDouble(text[i][row], &f[i]);
          if (taken) recorded[by_time ? key[row] : key[row] / spec.frame_rate] = f;
        }
      } catch (const InputError&) {
        continue;
      }
      std::vector<const MeasurementResidual*> force(recorded.size(), nullptr);
      for (const MeasurementResidual& mr : r_.measurement_residuals)
        if (mr.case_name == case_name && mr.observation == label && mr.unit == "N" &&
            mr.measurement >= 0 && static_cast<size_t>(mr.measurement) < force.size())
          force[mr.measurement] = &mr;
      size_t k = 0;
      for (const auto& [t, value] : recorded) {
        RecordedForce rf;
        rf.t = t;
        rf.point = spec.point;
        rf.measured = value;
        if (force[k]) rf.model = value + force[k]->error;
        out.push_back(rf);
        ++k;
      }
    }
    return out;
  }

  // The centre-line entries of case c seen by a camera, grouped by camera in the order
  // fit_input.cc loaded them.
  std::vector<std::pair<std::string, std::vector<CameraEntry>>> EntriesByCamera(size_t c) const {
    const FitCase& fc = in_.cases[c];
    std::vector<std::pair<std::string, std::vector<CameraEntry>>> out;
    size_t j = 0;
    for (const ObservationSpec& spec : e_.cases[c].observations) {
      if (!IsCentreLine(spec)) continue;
      const Measurement* obs = j < fc.measurements.size() ? fc.measurements[j].get() : nullptr;
      ++j;
      if (spec.camera.empty() || !obs) continue;
      const std::string key = CameraKey(spec);
      auto it = std::find_if(out.begin(), out.end(), [&](const auto& e) { return e.first == key; });
      if (it == out.end()) it = out.insert(out.end(), {key, {}});
      it->second.push_back({&spec, obs});
    }
    return out;
  }

  // One figure per camera of the case: the image (or a blank frame) zoomed to the thread, the
  // observed pixels of every entry of that camera, the fitted centre-line projected, and the
  // fitted position of each marker with s.
  void CameraViews(size_t c) {
    for (const auto& [camera_key, entries] : EntriesByCamera(c)) CameraView(c, camera_key, entries);
  }

  void CameraView(size_t c, const std::string& camera_key,
                  const std::vector<CameraEntry>& entries) {
    const Mat3X& shape = r_.shapes[c];
    // A camera of a stereo file is "FILE[i]": its name is the file's stem with the index.
    const size_t bracket = camera_key.back() == ']' ? camera_key.rfind('[') : std::string::npos;
    const std::string camera_path = camera_key.substr(0, bracket);
    const std::string camera_index = bracket == std::string::npos ? "" : camera_key.substr(bracket);
    const Camera* cam = nullptr;
    for (const auto& [spec, obs] : entries) {
      if (const auto* m = ModelOf<ImageMarkersObservation>(*obs)) cam = &m->camera();
      if (const auto* m = ModelOf<ImageCurveObservation>(*obs)) cam = &m->camera();
    }
    if (!cam) return;
    svg::Figure f;
    f.title = e_.scene.cases[c].name + ", camera " + Stem(camera_path) + camera_index;
    f.width = 660;
    f.height = 560;
    f.x.label = "u [px]";
    f.y.label = "v [px]";
    f.y.reversed = true;  // image rows grow downwards
    f.equal_aspect = true;
    f.height_from_data = true;
    PixelBox box;
    const svg::Series fitted = ProjectedCentreLine(*cam, shape, &box);
    CameraPixels seen = ObservedPixels(*cam, shape, entries, &box);
    if (box.empty())  // the fitted line is not on the sensor: zoom to what was observed
      for (const Eigen::Vector2d& p : seen.curve_pixels) box.Grow(*cam, p);
    const double W = cam->K.width, H = cam->K.height;
    if (box.empty()) box = {0, W - 1, 0, H - 1};  // nothing on the sensor: the whole frame
    const double pad = 0.08 * std::max(box.u1 - box.u0, box.v1 - box.v0) + 20.0;
    box.u0 = std::max(-0.5, box.u0 - pad);
    box.u1 = std::min(W - 0.5, box.u1 + pad);
    box.v0 = std::max(-0.5, box.v0 - pad);
    box.v1 = std::min(H - 0.5, box.v1 + pad);
    f.x.min = box.u0;
    f.x.max = box.u1;
    f.y.min = box.v0;
    f.y.max = box.v1;
    const std::string what = CameraBackground(seen.image_file, box, W, H, &f);
    // Observations first, the model drawn over them.
    for (svg::Series& s : seen.observed) f.series.push_back(std::move(s));
    f.series.push_back(fitted);
    if (!seen.fitted_markers.x.empty()) f.series.push_back(seen.fitted_markers);
    int outside = 0;
    for (const Eigen::Vector2d& p : seen.curve_pixels)
      if (!(p.x() >= box.u0 && p.x() <= box.u1 && p.y() >= box.v0 && p.y() <= box.v1)) ++outside;
    page_.Figure(f, "camera-view",
                 "camera_" + e_.scene.cases[c].name + "_" + Stem(camera_path) +
                     (camera_index.empty() ? "" : "_" + camera_index.substr(1, 1)),
                 " data-case=\"" + Escape(e_.scene.cases[c].name) + "\" data-camera=\"" +
                     Escape(Stem(camera_path) + camera_index) + "\"",
                 "Camera <code>" + Escape(FileName(camera_path) + camera_index) + "</code> over the " + what +
                     ", zoomed to the thread: observed pixels (circles, with the markers' arc "
                     "length s) and the fitted centre-line projected (line)." +
                     (outside > 0 ? " " + std::to_string(outside) +
                                        " observed pixels lie outside this view."
                                  : std::string()));
  }

  // The fitted centre-line projected into the camera (broken where the rod is behind it), its
  // pixels in the zoom.
  static svg::Series ProjectedCentreLine(const Camera& cam, const Mat3X& shape, PixelBox* box) {
    svg::Series fitted;
    fitted.label = "fitted centre-line";
    fitted.colour = kFitted;
    for (int i = 0; i < shape.cols(); ++i) {
      Eigen::Vector2d uv;
      if (Project(cam, Eigen::Vector3d(shape.col(i)), &uv)) {
        fitted.x.push_back(uv.x());
        fitted.y.push_back(uv.y());
        box->Grow(cam, uv);
      } else {
        fitted.x.push_back(NAN);  // the line breaks where the rod is behind the camera
        fitted.y.push_back(NAN);
      }
    }
    return fitted;
  }

  // The camera's entries as series: observed markers (in the zoom, with their fitted positions)
  // and pixels extracted from an image (a sample of them drawn, not in the zoom).
  static CameraPixels ObservedPixels(const Camera& cam, const Mat3X& shape,
                                     const std::vector<CameraEntry>& entries, PixelBox* box) {
    CameraPixels out;
    size_t colour = 0;
    svg::Series& fitted_markers = out.fitted_markers;
    fitted_markers.label = "fitted marker positions";
    fitted_markers.colour = kFitted;
    fitted_markers.line = false;
    fitted_markers.marker = svg::Marker::kCross;
    for (const auto& [spec, obs] : entries) {
      const bool image = KindOf(*spec).view == ReportView::kImage;
      if (image) out.image_file = spec->file;
      svg::Series s;
      s.label = image ? "pixels extracted from " + FileName(spec->file)
                      : "observed " + FileName(spec->file);
      s.colour = colour++ == 0 ? kObserved : "#e377c2";
      s.line = false;
      s.marker = svg::Marker::kCircle;
      s.hollow = true;
      s.marker_size = 3.5;
      if (const auto* m = ModelOf<ImageMarkersObservation>(*obs)) {
        VecX r;
        const bool ok = m->Evaluate(shape, &r);
        for (size_t k = 0; k < m->markers().size(); ++k) {
          const MarkerPixel& px = m->markers()[k];
          s.x.push_back(px.uv.x());
          s.y.push_back(px.uv.y());
          s.point_labels.push_back(ArcLabel(px.s));
          box->Grow(cam, px.uv);
          if (ok) {
            const Eigen::Vector2d model = px.uv + r.segment<2>(2 * k) * m->sigma();
            fitted_markers.x.push_back(model.x());
            fitted_markers.y.push_back(model.y());
          }
        }
      } else if (const auto* m = ModelOf<ImageCurveObservation>(*obs)) {
        // Thousands of pixels extracted from an image would hide the image and the fitted
        // line: every k-th is drawn, as the legend says. Not in the zoom (an outlier far
        // from the thread would zoom out to the whole frame); the figure says how many lie
        // outside the view.
        const size_t n = m->pixels().size();
        const size_t every = (n + kMaxPixelsDrawn - 1) / kMaxPixelsDrawn;
        s.marker_size = 2.5;
        if (every > 1)
          s.label += " (1 in " + std::to_string(every) + " of " + std::to_string(n) + " shown)";
        for (size_t k = 0; k < n; k += every) {
          s.x.push_back(m->pixels()[k].x());
          s.y.push_back(m->pixels()[k].y());
        }
        out.curve_pixels.insert(out.curve_pixels.end(), m->pixels().begin(), m->pixels().end());
      }
      out.observed.push_back(std::move(s));
    }
    return out;
  }

  // The figure's background: the image cropped to the zoom, or a blank frame with the sensor's
  // edge (W x H px). Returns what the caption calls it.
  static std::string CameraBackground(const std::string& image_file, const PixelBox& box,
                                      double W, double H, svg::Figure* f) {
    if (image_file.empty()) {
      // The sensor's edge, where the zoom reaches it.
      svg::Series edge;
      edge.label = "image border";
      edge.colour = "#999999";
      edge.dashed = true;
      edge.line_width = 1.2;
      edge.closed = true;
      edge.x = {-0.5, W - 0.5, W - 0.5, -0.5};
      edge.y = {-0.5, -0.5, H - 0.5, H - 0.5};
      f->series.push_back(edge);
      return "blank frame (no image in the experiment)";
    }
    const cv::Mat image = ReadImageFile(image_file);
    const int cx0 = std::clamp(static_cast<int>(std::floor(box.u0 + 0.5)), 0, image.cols - 1);
    const int cy0 = std::clamp(static_cast<int>(std::floor(box.v0 + 0.5)), 0, image.rows - 1);
    const int cx1 = std::clamp(static_cast<int>(std::ceil(box.u1 + 0.5)), cx0 + 1, image.cols);
    const int cy1 = std::clamp(static_cast<int>(std::ceil(box.v1 + 0.5)), cy0 + 1, image.rows);
    f->background.href = ImageDataUri(image_file, image, cv::Rect(cx0, cy0, cx1 - cx0, cy1 - cy0));
    f->background.x0 = cx0 - 0.5;
    f->background.x1 = cx1 - 0.5;
    f->background.y0 = cy0 - 0.5;
    f->background.y1 = cy1 - 0.5;
    return "image <code>" + Escape(FileName(image_file)) + "</code>";
  }

  // Two orthogonal projections of the fitted centre-line with the case's 3-D markers and points.
  void ShapeViews(size_t c) {
    const FitCase& fc = in_.cases[c];
    const Mat3X& shape = r_.shapes[c];
    std::vector<const Markers3dObservation*> markers;
    std::vector<const Points3dObservation*> points;
    for (const auto& o : fc.measurements) {
      if (const auto* m = ModelOf<Markers3dObservation>(*o)) markers.push_back(m);
      if (const auto* p = ModelOf<Points3dObservation>(*o)) points.push_back(p);
    }
    if (markers.empty() && points.empty()) return;
    std::vector<Eigen::Vector3d> all;
    for (int i = 0; i < shape.cols(); ++i) all.push_back(shape.col(i));
    for (const auto* m : markers)
      for (const Marker3d& k : m->markers()) all.push_back(k.p_world);
    for (const auto* p : points)
      for (const Eigen::Vector3d& q : p->samples()) all.push_back(q);
    for (const auto& axes : LongViews(all)) {
      const int a = axes[0], b = axes[1];
      svg::Figure f;
      f.title = e_.scene.cases[c].name + ": " + AxisName(a) + "–" + AxisName(b) + " projection";
      f.width = 620;
      f.height = 420;
      f.x.label = std::string(AxisName(a)) + " [mm]";
      f.y.label = std::string(AxisName(b)) + " [mm]";
      f.equal_aspect = true;
      f.height_from_data = true;
      svg::Series line;
      line.label = "fitted centre-line";
      line.colour = kFitted;
      for (int i = 0; i < shape.cols(); ++i) {
        line.x.push_back(kMm * shape(a, i));
        line.y.push_back(kMm * shape(b, i));
      }
      f.series.push_back(line);
      for (const auto* m : markers) {
        svg::Series obs, model;
        obs.label = "observed markers";
        obs.colour = kObserved;
        obs.line = false;
        obs.marker = svg::Marker::kCircle;
        obs.hollow = true;
        model.label = "fitted marker positions";
        model.colour = kFitted;
        model.line = false;
        model.marker = svg::Marker::kCross;
        VecX r;
        const bool ok = m->Evaluate(shape, &r);
        for (size_t k = 0; k < m->markers().size(); ++k) {
          const Marker3d& mk = m->markers()[k];
          obs.x.push_back(kMm * mk.p_world[a]);
          obs.y.push_back(kMm * mk.p_world[b]);
          obs.point_labels.push_back(ArcLabel(mk.s));
          if (ok) {
            const Eigen::Vector3d model_p = mk.p_world + r.segment<3>(3 * k) * m->sigma();
            model.x.push_back(kMm * model_p[a]);
            model.y.push_back(kMm * model_p[b]);
          }
        }
        f.series.push_back(obs);
        if (!model.x.empty()) f.series.push_back(model);
      }
      for (const auto* p : points) {
        svg::Series obs;
        obs.label = "observed points";
        obs.colour = "#e377c2";
        obs.line = false;
        obs.marker = svg::Marker::kCircle;
        obs.marker_size = 2.5;
        for (const Eigen::Vector3d& q : p->samples()) {
          obs.x.push_back(kMm * q[a]);
          obs.y.push_back(kMm * q[b]);
        }
        f.series.push_back(obs);
      }
      page_.Figure(f, "shape-view",
                   "shape_" + e_.scene.cases[c].name + "_" + AxisName(a) + AxisName(b),
                   " data-case=\"" + Escape(e_.scene.cases[c].name) + "\" data-plane=\"" +
                       AxisName(a) + AxisName(b) + "\"",
                   std::string("The case's 3-D data projected on the ") + AxisName(a) + "–" +
                       AxisName(b) + " plane (equal scales): observed markers (circles, with s), "
                       "their fitted positions (crosses) and the fitted centre-line.");
    }
  }

  // The poked cross-section in its plane: rest ring, fitted deformed ring, measured points.
  void SectionView(size_t c) {
    const FitCase& fc = in_.cases[c];
    std::vector<const SurfacePointSet*> surface;
    for (const auto& o : fc.measurements)
      if (const auto* set = dynamic_cast<const SurfacePointSet*>(o.get())) surface.push_back(set);
    if (surface.empty() || c >= r_.sections.size() || r_.sections[c].cols() < 3) return;
    const Eigen::Matrix3Xd& rest = r_.rest_sections[c];
    const Eigen::Matrix3Xd& ring = r_.sections[c];
    // The section's plane: normal = the rest ring's least-spread direction; in-plane axes are
    // the world axes most in the plane, so that a section across a rod along x shows y and z.
    const Eigen::Vector3d centre = rest.rowwise().mean();
    const Eigen::Matrix3d cov = (rest.colwise() - centre) * (rest.colwise() - centre).transpose();
    Eigen::Vector3d normal = Eigen::Vector3d::UnitX();
    {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
      if (eig.info() == Eigen::Success) normal = eig.eigenvectors().col(0);
    }
    std::array<int, 3> order = {0, 1, 2};
    std::sort(order.begin(), order.end(),
              [&](int i, int j) { return std::abs(normal[i]) < std::abs(normal[j]); });
    const int ia = std::min(order[0], order[1]), ib = std::max(order[0], order[1]);
    Eigen::Vector3d u = Eigen::Vector3d::Unit(ia) - normal[ia] * normal;
    u.normalize();
    Eigen::Vector3d v = normal.cross(u);
    if (v[ib] < 0) v = -v;
    // Where the section is tilted (the rod is not along a world axis there), the axes are the
    // world axes projected on its plane, primed.
    const bool aligned = std::abs(u[ia]) > 0.9999 && std::abs(v[ib]) > 0.9999;
    svg::Figure f;
    f.title = e_.scene.cases[c].name + ": poked section";
    f.width = 560;
    f.height = 520;
    const std::string prime = aligned ? "" : "′";
    f.x.label = std::string(AxisName(ia)) + prime + " [mm]";
    f.y.label = std::string(AxisName(ib)) + prime + " [mm]";
    f.equal_aspect = true;
    auto add_ring = [&](const Eigen::Matrix3Xd& nodes, const std::string& label, const char* colour,
                        bool dashed) {
      svg::Series s;
      s.label = label;
      s.colour = colour;
      s.dashed = dashed;
      s.closed = true;
      for (int i = 0; i < nodes.cols(); ++i) {
        s.x.push_back(kMm * u.dot(nodes.col(i)));
        s.y.push_back(kMm * v.dot(nodes.col(i)));
      }
      f.series.push_back(s);
    };
    add_ring(rest, "rest section", "#888888", true);
    add_ring(ring, "fitted deformed section", kFitted, false);
    // A dent of a fraction of a millimetre on a ring of centimetres: also drawn magnified.
    const double k = DentMagnification(rest, ring);
    if (k > 1)
      add_ring(rest + k * (ring - rest),
               "fitted dent magnified × " + svg::FormatTick(k, k), "#9467bd", false);
    for (const SurfacePointSet* sp : surface) {
      svg::Series s;
      s.label = "measured " + sp->label().substr(sp->label().find(' ') + 1);
      s.colour = kObserved;
      s.line = false;
      s.marker = svg::Marker::kCircle;
      s.hollow = true;
      s.marker_size = 3.5;
      for (const Eigen::Vector3d& q : sp->points()) {
        s.x.push_back(kMm * u.dot(q));
        s.y.push_back(kMm * v.dot(q));
      }
      f.series.push_back(s);
    }
    page_.Figure(f, "section-view", "section_" + e_.scene.cases[c].name,
                 " data-case=\"" + Escape(e_.scene.cases[c].name) + "\"",
                 std::string("The poked cross-section in its plane (equal scales): the ring at "
                             "rest (dashed), the ring deformed at the fitted parameters, and the "
                             "measured surface points.") +
                     (DentMagnification(rest, ring) > 1
                          ? " The dent is small against the ring: its displacement is also drawn "
                            "magnified (purple), to show its shape; the measured points compare "
                            "with the unmagnified ring."
                          : "") +
                     (aligned ? "" : " Axes: the world's " + std::string(AxisName(ia)) + " and " +
                                         AxisName(ib) + " projected on the section's plane, "
                                         "which the rod's tangent tilts."));
  }

  // A sequence entry's recorded samples as the reader numbers them (the rows seen, in the
  // file's order): time, arc length (NaN without s), and the measured coordinates.
  struct SequenceSample {
    double t = 0.0, s = NAN;
    Eigen::Vector3d value = Eigen::Vector3d::Constant(NAN);
  };
  static std::vector<SequenceSample> SequenceSamples(const ObservationSpec& spec) {
    const CsvTable table = CsvTable::Read(spec.file);
    const bool by_time = table.HasColumn("t");
    const std::vector<double> key = table.Column(by_time ? "t" : "frame");
    const bool pixels = KindOf(spec).view == ReportView::kPixels;
    const std::vector<std::string> cols = pixels ? std::vector<std::string>{"u", "v"}
                                                 : std::vector<std::string>{"x", "y", "z"};
    std::vector<std::vector<std::string>> text;
    for (const std::string& col : cols) text.push_back(table.TextColumn(col));
    const std::vector<double> arc = table.HasColumn("s") ? table.Column("s") : std::vector<double>();
    std::vector<SequenceSample> out;
    for (int r = 0; r < table.num_rows(); ++r) {
      SequenceSample sample;
      bool seen = true;
      for (size_t i = 0; i < cols.size(); ++i) seen = seen && ParseDouble(text[i][r], &sample.value[i]);
      if (!seen) continue;  // empty or nan: not seen (the reader refuses anything else)
      if (pixels) sample.value[2] = 0.0;
      sample.t = by_time ? key[r] : key[r] / spec.frame_rate;
      if (!arc.empty()) sample.s = arc[r];
      out.push_back(sample);
    }
    return out;
  }

  // Per sequence entry of a moving case: the recorded and fitted trajectories of its markers
  // (entries with s: the coordinate that moves most, per marker) and every sample's misfit in
  // sigmas over time.
  void SequenceViews(size_t c) {
    const std::string& case_name = e_.scene.cases[c].name;
    for (const ObservationSpec& spec : e_.cases[c].observations) {
      const std::string label = EntryLabel(spec);
      if (KindOf(spec).view == ReportView::kReaction) {
        ReactionSequenceViews(c, spec, label);
        continue;
      }
      std::vector<const MeasurementResidual*> errors;  // by sample number
      for (const MeasurementResidual& mr : r_.measurement_residuals) {
        if (mr.case_name != case_name || mr.observation != label || mr.measurement < 0) continue;
        if (static_cast<size_t>(mr.measurement) >= errors.size()) errors.resize(mr.measurement + 1, nullptr);
        errors[mr.measurement] = &mr;
      }
      if (errors.empty()) continue;
      std::vector<SequenceSample> samples;
      try {
        samples = SequenceSamples(spec);
      } catch (const InputError&) {
        continue;  // the file changed since the fit read it: nothing to draw from
      }
      if (samples.size() != errors.size()) continue;
      const std::string attrs = " data-case=\"" + Escape(case_name) + "\" data-entry=\"" + Escape(label) + "\"";
      if (std::isfinite(samples.front().s)) MarkerTrajectoryFigure(c, spec, samples, errors, attrs);
      SequenceMisfitFigure(c, spec, samples, errors, attrs);
    }
  }

  // Each marker's coordinate that moves most, as recorded and along the fitted trajectory (at
  // most 8 markers, spread along the rod). errors: the samples' residuals, by sample number.
  void MarkerTrajectoryFigure(size_t c, const ObservationSpec& spec,
                              const std::vector<SequenceSample>& samples,
                              const std::vector<const MeasurementResidual*>& errors,
                              const std::string& attrs) {
    const std::string& case_name = e_.scene.cases[c].name;
    const bool pixels = KindOf(spec).view == ReportView::kPixels;
    const std::string unit = pixels ? "px" : "mm";
    const double scale = pixels ? 1.0 : 1e3;
    // The coordinate with the largest range over the sequence.
    const int dims = pixels ? 2 : 3;
    int axis = 0;
    double widest = -1.0;
    for (int a = 0; a < dims; ++a) {
      double lo = INFINITY, hi = -INFINITY;
      for (const SequenceSample& sm : samples) lo = std::min(lo, sm.value[a]), hi = std::max(hi, sm.value[a]);
      if (hi - lo > widest) widest = hi - lo, axis = a;
    }
    std::map<double, std::vector<size_t>> by_marker;
    for (size_t k = 0; k < samples.size(); ++k) by_marker[samples[k].s].push_back(k);
    // At most 8 markers, spread along the rod, so that the lines stay apart.
    std::vector<double> shown;
    for (const auto& [arc, list] : by_marker) shown.push_back(arc);
    if (shown.size() > 8) {
      std::vector<double> spread;
      for (int i = 0; i < 8; ++i) spread.push_back(shown[i * (shown.size() - 1) / 7]);
      shown = spread;
    }
    svg::Figure f;
    const char* const axis_name = pixels ? (axis == 0 ? "u" : "v") : AxisName(axis);
    f.title = case_name + ": " + axis_name + " of the markers, " + FileName(spec.file);
    f.width = 660;
    f.height = 400;
    f.x.label = "t [s]";
    f.y.label = std::string(axis_name) + " [" + unit + "]";
    for (size_t i = 0; i < shown.size(); ++i) {
      svg::Series recorded, fitted;
      recorded.label = ArcLabel(shown[i]);
      recorded.colour = fitted.colour = Colour(i);
      recorded.line = false;
      recorded.marker = svg::Marker::kCircle;
      recorded.hollow = true;
      recorded.marker_size = 3;
      fitted.line_width = 1.4;
      for (size_t k : by_marker[shown[i]]) {
        const MeasurementResidual* mr = errors[k];
        recorded.x.push_back(samples[k].t);
        recorded.y.push_back(scale * samples[k].value[axis]);
        fitted.x.push_back(samples[k].t);
        fitted.y.push_back(mr ? scale * (samples[k].value[axis] + mr->error[axis]) : NAN);
      }
      f.series.push_back(recorded);
      f.series.push_back(fitted);
    }
    page_.Figure(f, "sequence-trajectories", "sequence_" + case_name + "_" + Stem(spec.file), attrs,
                 "Entry <code>" + Escape(FileName(spec.file)) + "</code>: each marker's " +
                     axis_name + " (the coordinate that moves most) as recorded (circles) and "
                     "along the fitted trajectory (lines)" +
                     (by_marker.size() > shown.size() ? ", 8 of the " + std::to_string(by_marker.size()) + " markers" : std::string()) +
                     ".");
  }

  // Every sample's misfit in units of its sigma, and their RMS at each time.
  void SequenceMisfitFigure(size_t c, const ObservationSpec& spec,
                            const std::vector<SequenceSample>& samples,
                            const std::vector<const MeasurementResidual*>& errors,
                            const std::string& attrs) {
    const std::string& case_name = e_.scene.cases[c].name;
  svg::Figure f;
  f.title = case_name + ": misfit over time, " + FileName(spec.file);
  f.width = 660;
  f.height = 360;
  f.x.label = "t [s]";
  f.y.label = "|model − measured| [σ]";
  svg::Series each, rms;
  each.label = "each sample";
  each.line = false;
  each.marker = svg::Marker::kCircle;
  each.marker_size = 2.5;
  each.colour = "#7f7f7f";
  rms.label = "RMS per time";
  rms.colour = "#d62728";
  std::map<double, std::pair<double, int>> per_time;  // sum of squares, count
  for (size_t k = 0; k < samples.size(); ++k) {
    if (!errors[k]) continue;
    const double norm = errors[k]->error.norm() / errors[k]->sigma;
    each.x.push_back(samples[k].t);
    each.y.push_back(norm);
    auto& acc = per_time[samples[k].t];
    acc.first += norm * norm;
    ++acc.second;
  }
  for (const auto& [t, acc] : per_time) {
    rms.x.push_back(t);
    rms.y.push_back(std::sqrt(acc.first / acc.second));
  }
  f.series = {each, rms};
  page_.Figure(f, "sequence-misfit", "sequence_misfit_" + case_name + "_" + Stem(spec.file), attrs,
               "Entry <code>" + Escape(FileName(spec.file)) + "</code>: every recorded "
               "sample's misfit at the fitted values in units of its sigma, and their RMS at "
               "each time (about 1 when the model explains the motion to its noise; a rise "
               "over time is a prediction drifting away).");
  }

  // A moving case's load cell log: the force components as recorded and along the fitted
  // trajectory over time, and each reading's misfit in sigmas (force and moment apart).
  void ReactionSequenceViews(size_t c, const ObservationSpec& spec, const std::string& label) {
    const std::string& case_name = e_.scene.cases[c].name;
    // The readings taken, in time order (as the reader numbers them).
    std::map<double, Vec3> recorded;
    try {
      const CsvTable table = CsvTable::Read(spec.file);
      const bool by_time = table.HasColumn("t");
      const std::vector<double> key = table.Column(by_time ? "t" : "frame");
      std::vector<std::vector<std::string>> text;
      for (const char* col : {"fx", "fy", "fz"}) text.push_back(table.TextColumn(col));
      for (int r = 0; r < table.num_rows(); ++r) {
        Vec3 f;
        bool taken = true;
        for (int i = 0; i < 3; ++i) taken = taken && ParseDouble(text[i][r], &f[i]);
        if (taken) recorded[by_time ? key[r] : key[r] / spec.frame_rate] = f;
      }
    } catch (const InputError&) {
      return;  // the file changed since the fit read it: nothing to draw from
    }
    std::vector<const MeasurementResidual*> force(recorded.size(), nullptr), moment = force;
    for (const MeasurementResidual& mr : r_.measurement_residuals) {
      if (mr.case_name != case_name || mr.observation != label || mr.measurement < 0 ||
          static_cast<size_t>(mr.measurement) >= recorded.size())
        continue;
      (mr.unit == "N m" ? moment : force)[mr.measurement] = &mr;
    }
    if (std::none_of(force.begin(), force.end(), [](const auto* p) { return p != nullptr; })) return;
    const std::string attrs = " data-case="" + Escape(case_name) + "" data-entry="" + Escape(label) + """;
    svg::Figure f;
    f.title = case_name + ": force on the " + spec.point + ", " + FileName(spec.file);
    f.width = 660;
    f.height = 400;
    f.x.label = "t [s]";
    f.y.label = "force [mN]";
    for (int a = 0; a < 3; ++a) {
      svg::Series rec, fit;
      rec.label = std::string("f") + AxisName(a);
      rec.colour = fit.colour = Colour(a);
      rec.line = false;
      rec.marker = svg::Marker::kCircle;
      rec.hollow = true;
      rec.marker_size = 3;
      fit.line_width = 1.4;
      size_t k = 0;
      for (const auto& [t, value] : recorded) {
        rec.x.push_back(t);
        rec.y.push_back(1e3 * value[a]);
        fit.x.push_back(t);
        fit.y.push_back(force[k] ? 1e3 * (value[a] + force[k]->error[a]) : NAN);
        ++k;
      }
      f.series.push_back(rec);
      f.series.push_back(fit);
    }
    page_.Figure(f, "sequence-trajectories", "sequence_" + case_name + "_" + Stem(spec.file), attrs,
                 "Entry <code>" + Escape(FileName(spec.file)) + "</code>: the force the rod exerts "
                 "on the " + Escape(spec.point) + ", as read (circles) and along the fitted "
                 "trajectory (lines).");
    svg::Figure m;
    m.title = case_name + ": misfit over time, " + FileName(spec.file);
    m.width = 660;
    m.height = 360;
    m.x.label = "t [s]";
    m.y.label = "|model − measured| [σ]";
    for (int part = 0; part < 2; ++part) {
      const std::vector<const MeasurementResidual*>& list = part == 0 ? force : moment;
      svg::Series each;
      each.label = part == 0 ? "force" : "moment";
      each.line = false;
      each.marker = svg::Marker::kCircle;
      each.marker_size = 2.5;
      each.colour = part == 0 ? "#7f7f7f" : "#d62728";
      size_t k = 0;
      for (const auto& [t, value] : recorded) {
        if (list[k]) {
          each.x.push_back(t);
          each.y.push_back(list[k]->error.norm() / list[k]->sigma);
        }
        ++k;
      }
      if (!each.x.empty()) m.series.push_back(each);
    }
    page_.Figure(m, "sequence-misfit", "sequence_misfit_" + case_name + "_" + Stem(spec.file), attrs,
                 "Entry <code>" + Escape(FileName(spec.file)) + "</code>: each reading's misfit at "
                 "the fitted values in units of its sigma (about 1 when the model explains the "
                 "forces to their noise).");
  }

  // Per force entry of the case: force versus time (haptic logs) and the force residuals.
  void ForcePlots(size_t c) {
    // Readings of each force entry of this case, with their residuals and fit cases.
    std::map<std::string, std::vector<ForceReading>> readings;
    std::map<std::string, const ObservationSpec*> spec_of;
    std::vector<std::string> order;
    for (const ObservationSpec& spec : e_.cases[c].observations)
      if (KindOf(spec).view == ReportView::kHapticLog ||
          KindOf(spec).view == ReportView::kReaction) {
        const std::string label = EntryLabel(spec);
        if (!spec_of.count(label)) order.push_back(label);
        spec_of[label] = &spec;
      }
    if (order.empty()) return;
    std::map<std::pair<int, std::string>, int> seen;  // force readings per (fit case, entry)
    for (const MeasurementResidual& mr : r_.measurement_residuals) {
      if (mr.unit != "N" || ExperimentCase(mr.case_index) != static_cast<int>(c)) continue;
      if (!spec_of.count(mr.observation)) continue;
      // The k-th force reading of this entry in the fit case: its ForceMeasurement.
      const FitCase& fc = in_.cases[mr.case_index];
      int k = seen[{mr.case_index, mr.observation}]++;
      const ForceMeasurement* fm = nullptr;
      for (const auto& meas : fc.measurements) {
        const auto* forces = dynamic_cast<const ForceReadings*>(meas.get());
        if (!forces || forces->label() != mr.observation) continue;
        for (const ForceMeasurement& g : forces->readings())
          if (k-- == 0) {
            fm = &g;
            break;
          }
        if (fm) break;
      }
      if (!fm) continue;
      auto& list = readings[mr.observation];
      const double x = std::isfinite(fm->time) ? fm->time : static_cast<double>(list.size() + 1);
      list.push_back({x, fm->force, mr.error, mr.sigma});
    }
    for (const std::string& label : order) {
      auto& list = readings[label];
      std::sort(list.begin(), list.end(),
                [](const ForceReading& a, const ForceReading& b) { return a.x < b.x; });
      const ObservationSpec& spec = *spec_of[label];
      const bool haptic = KindOf(spec).view == ReportView::kHapticLog;
      const std::string xlabel = haptic ? "t [s]" : "reading";
      const std::string attrs = " data-case=\"" + Escape(e_.scene.cases[c].name) +
                                "\" data-entry=\"" + Escape(label) + "\"";
      if (haptic) HapticLogFigure(c, spec, list, attrs);
      ForceResidualFigure(c, spec, list, xlabel, attrs);
    }
  }

  // A haptic log's figure: the whole log as recorded, then the quasi-static samples the fit used
  // (`list`), measured and fitted.
  void HapticLogFigure(size_t c, const ObservationSpec& spec, const std::vector<ForceReading>& list,
                       const std::string& attrs) {
    svg::Figure f;
    f.title = e_.scene.cases[c].name + ": force of " + FileName(spec.file);
    f.width = 660;
    f.height = 400;
    f.x.label = "t [s]";
    f.y.label = "force on the instrument [N]";
    const CsvTable t = CsvTable::Read(spec.file);
    const std::vector<double> time = t.Column("t");
    const char* const cols[] = {"fx", "fy", "fz"};
    for (int i = 0; i < 3; ++i) {
      svg::Series s;
      s.label = std::string(cols[i]) + " log";
      s.colour = kComponent[i];
      s.line_width = 1.0;
      s.x = time;
      s.y = t.Column(cols[i]);
      f.series.push_back(s);
    }
    for (int i = 0; i < 3; ++i) {
      svg::Series m, model;
      m.label = std::string(cols[i]) + " used (measured)";
      m.colour = kComponent[i];
      m.line = false;
      m.marker = svg::Marker::kCircle;
      m.hollow = true;
      m.marker_size = 5;
      model.label = std::string(cols[i]) + " fitted";
      model.colour = kComponent[i];
      model.line = false;
      model.marker = svg::Marker::kCross;
      model.marker_size = 5;
      for (const ForceReading& rd : list) {
        m.x.push_back(rd.x);
        m.y.push_back(rd.measured[i]);
        model.x.push_back(rd.x);
        model.y.push_back(rd.measured[i] + rd.error[i]);
      }
      f.series.push_back(m);
      f.series.push_back(model);
    }
    page_.Figure(f, "force-time", "force_" + e_.scene.cases[c].name + "_" + Stem(spec.file),
                 attrs,
                 "Haptic log <code>" + Escape(FileName(spec.file)) +
                     "</code>: the force components as recorded (lines), the quasi-static "
                     "samples the fit used (circles) and the model's force there (crosses).");
  }

  // A force entry's residuals per reading, with the ±1 σ and ±3 σ bands.
  void ForceResidualFigure(size_t c, const ObservationSpec& spec,
                           const std::vector<ForceReading>& list, const std::string& xlabel,
                           const std::string& attrs) {
  svg::Figure f;
  f.title = e_.scene.cases[c].name + ": force residuals, " + FileName(spec.file);
  f.width = 660;
  f.height = 360;
  f.x.label = xlabel;
  f.y.label = "force residual, model − measured [N]";
  const double sigma = list.empty() ? spec.sigma : list.front().sigma;
  f.bands.push_back({-3 * sigma, 3 * sigma, "#2ca02c", 0.08,
                     "±3 σ (" + svg::FormatTick(3 * sigma, sigma) + " N)"});
  f.bands.push_back({-sigma, sigma, "#2ca02c", 0.18, "±1 σ"});
  const char* const names[] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    svg::Series s;
    s.label = std::string("f") + names[i] + " residual";
    s.colour = kComponent[i];
    s.line = false;
    s.marker = svg::Marker::kCircle;
    s.marker_size = 4;
    for (const ForceReading& rd : list) {
      s.x.push_back(rd.x);
      s.y.push_back(rd.error[i]);
    }
    f.series.push_back(s);
  }
  page_.Figure(f, "force-residuals",
               "force_residuals_" + e_.scene.cases[c].name + "_" + Stem(spec.file), attrs,
               "Force residuals of <code>" + Escape(FileName(spec.file)) +
                   "</code> per reading, with the ±1 σ and ±3 σ bands of the entry's "
                   "sigma.");
  }

  // The case's residuals in sigmas (all its entries, haptic samples included), per entry; for a
  // moving case every recorded sample's (its sequences).
  std::vector<ResidualSeries> ResidualsOfCase(size_t c) const {
    std::vector<ResidualSeries> out;
    std::map<std::string, size_t> index;
    auto series = [&](const std::string& label, ResidualSeries::Along along) -> ResidualSeries& {
      auto it = index.find(label);
      if (it == index.end()) {
        it = index.emplace(label, out.size()).first;
        out.push_back({label, along, {}, {}});
      }
      return out[it->second];
    };
    if (e_.scene.dynamics) {
      // Every sample's error over its sigma: the components of markers and readings, the two of
      // pixels (along the order the reader numbered them).
      for (const MeasurementResidual& mr : r_.measurement_residuals) {
        if (mr.case_name != e_.scene.cases[c].name) continue;
        const std::string label = mr.unit == "N m" ? mr.observation + " (moments)" : mr.observation;
        ResidualSeries& s = series(label, ResidualSeries::Along::kReading);
        const int dims = mr.unit == "px" ? 2 : 3;
        for (int i = 0; i < dims; ++i) {
          s.x.push_back(mr.measurement + 1);
          s.sigmas.push_back(mr.error[i] / mr.sigma);
        }
      }
      return out;
    }
    for (size_t ci = 0; ci < in_.cases.size(); ++ci) {
      if (ExperimentCase(ci) != static_cast<int>(c)) continue;
      const FitCase& fc = in_.cases[ci];
      if (shapes_ok_) {
        const Mat3X& shape = r_.shapes[ci];
        const std::vector<double> arc = VertexArcLengths(fc, shape.cols());
        for (const auto& meas : fc.measurements) {
          if (!meas->reads_vertices_only()) continue;  // listed below, from the fit
          ResidualSeries& s = series(meas->label(), ResidualSeries::Along::kArc);
          const auto comps = NoisyComponents(*meas, shape);
          const std::vector<double> where = MeasurementArcLengths(*meas, shape, arc);
          for (size_t m = 0; m < comps.size() && m < where.size(); ++m)
            for (double v : comps[m]) {
              s.x.push_back(where[m]);
              s.sigmas.push_back(v);
            }
        }
      }
      // Forces, moments and surface points. A force or moment reading is drawn at the arc
      // length of the held point it was read at (the k-th reading of an entry in the case is its
      // k-th ForceMeasurement).
      std::map<std::pair<std::string, std::string>, int> readings;  // (entry, unit) -> count
      for (const MeasurementResidual& mr : r_.measurement_residuals) {
        if (mr.case_index != static_cast<int>(ci)) continue;
        const std::string label = mr.unit == "N m" ? mr.observation + " (moments)" : mr.observation;
        const Eigen::Vector3d e = mr.error / mr.sigma;
        std::vector<double> comps;
        double x = NAN;
        ResidualSeries::Along along = ResidualSeries::Along::kReading;
        if (mr.unit == "N" || mr.unit == "N m") {
          int k = readings[{mr.observation, mr.unit}]++;
          for (const auto& meas : fc.measurements) {
            const auto* forces = dynamic_cast<const ForceReadings*>(meas.get());
            if (!forces || forces->label() != mr.observation) continue;
            for (const ForceMeasurement& fm : forces->readings()) {
              if (k-- != 0) continue;
              x = HeldArcLength(fc.load_case, fm.point);
              if (std::isfinite(x)) along = ResidualSeries::Along::kArc;
              break;
            }
            break;
          }
        }
        if (mr.unit == "m" && shapes_ok_ && ci < r_.sections.size() && r_.sections[ci].cols() > 2) {
          // A surface point: across the ring, as the centre-line points, at its angle around
          // the section.
          for (const auto& meas : fc.measurements)
            if (const auto* sp = dynamic_cast<const SurfacePointSet*>(meas.get()))
              if (sp->label() == mr.observation &&
                  mr.measurement < static_cast<int>(sp->points().size())) {
                const Eigen::Vector3d& q = sp->points()[mr.measurement];
                AcrossComponents(Closed(r_.sections[ci]), q, e, &comps);
                x = AngleAroundSection(r_.rest_sections[ci], q);
                along = ResidualSeries::Along::kAngle;
              }
        }
        ResidualSeries& s = series(label, along);
        if (along == ResidualSeries::Along::kReading)
          x = static_cast<double>(s.x.empty() ? 1 : s.x.back() + 1);
        else if (s.along != along)
          continue;  // an entry drawn against another axis (cannot happen: one kind per entry)
        if (comps.empty()) comps.assign(e.data(), e.data() + mr.components);
        for (double v : comps) {
          s.x.push_back(x);
          s.sigmas.push_back(v);
        }
      }
    }
    return out;
  }

  // The arc length [m] of a case's held point as a ForceMeasurement names it (clamp, end_clamp,
  // end_pin, pins[k], grasp); NaN for another.
  double HeldArcLength(const LoadCase& lc, const std::string& point) const {
    if (point == "clamp") return 0.0;
    if (point == "end_clamp" || point == "end_pin") return in_.rod.length;
    if (point == "grasp" && lc.grasp) return lc.grasp->s;
    if (point.rfind("pins[", 0) == 0) {
      const size_t k = std::strtoul(point.c_str() + 5, nullptr, 10);
      if (k < lc.pins.size()) return lc.pins[k].s;
    }
    return NAN;
  }

  // The rest arc lengths of a fit case's fitted vertices: its rod model's (held points move the
  // vertex nearest them), or spread evenly when the model's count differs.
  std::vector<double> VertexArcLengths(const FitCase& fc, Eigen::Index n) const {
    try {
      LoadCase whole = fc.load_case;
      whole.symmetry.reset();
      const RodModel model(in_.rod, in_.material, in_.gravity, whole, in_.springs);
      if (static_cast<Eigen::Index>(model.arc_lengths().size()) == n) return model.arc_lengths();
    } catch (const std::invalid_argument&) {
    }
    std::vector<double> s(n);
    for (Eigen::Index i = 0; i < n; ++i) s[i] = in_.rod.length * i / std::max<Eigen::Index>(1, n - 1);
    return s;
  }

  // Where on the rod each measurement of a centre-line observation lies [m]: a marker's s, a
  // point's or pixel's closest point on the fitted centre-line (projected, for pixels).
  static std::vector<double> MeasurementArcLengths(const Measurement& obs, const Mat3X& shape,
                                                   const std::vector<double>& arc) {
    std::vector<double> out;
    auto at_foot = [&](const PolylineFoot& foot) {
      if (foot.vertex >= 0 && static_cast<size_t>(foot.vertex) < arc.size()) return arc[foot.vertex];
      if (foot.edge < 0 || static_cast<size_t>(foot.edge + 1) >= arc.size())
        return std::numeric_limits<double>::quiet_NaN();
      return arc[foot.edge] + foot.t * (arc[foot.edge + 1] - arc[foot.edge]);
    };
    if (const auto* m = ModelOf<Markers3dObservation>(obs)) {
      for (const Marker3d& k : m->markers()) out.push_back(k.s);
    } else if (const auto* m = ModelOf<ImageMarkersObservation>(obs)) {
      for (const MarkerPixel& k : m->markers()) out.push_back(k.s);
    } else if (const auto* p = ModelOf<Points3dObservation>(obs)) {
      for (const Eigen::Vector3d& q : p->samples())
        out.push_back(at_foot(ClosestPointOnPolyline<3>(shape, q)));
    } else if (const auto* curve = ModelOf<ImageCurveObservation>(obs)) {
      Eigen::Matrix2Xd uv(2, shape.cols());
      bool projected = true;
      for (int i = 0; i < shape.cols() && projected; ++i) {
        Eigen::Vector2d p;
        projected = Project(curve->camera(), Eigen::Vector3d(shape.col(i)), &p);
        uv.col(i) = p;
      }
      for (const Eigen::Vector2d& q : curve->pixels())
        out.push_back(projected ? at_foot(ClosestPointOnPolyline<2>(uv, q)) : NAN);
    } else {
      out.assign(obs.num_measurements(), NAN);
    }
    return out;
  }

  // A surface point's angle around the poked section [deg], from the rest ring's first node
  // (the d1 direction) towards its second.
  static double AngleAroundSection(const Eigen::Matrix3Xd& rest, const Eigen::Vector3d& q) {
    if (rest.cols() < 3) return NAN;
    const Eigen::Vector3d centre = rest.rowwise().mean();
    const Eigen::Vector3d a = (rest.col(0) - centre).normalized();
    const Eigen::Vector3d n = a.cross(rest.col(1) - centre).normalized();
    const Eigen::Vector3d b = n.cross(a);
    const Eigen::Vector3d d = q - centre;
    double angle = std::atan2(d.dot(b), d.dot(a)) * 180.0 / kPi;
    return angle < 0 ? angle + 360.0 : angle;
  }

  void CaseResiduals(size_t c) {
    const std::vector<ResidualSeries> all = ResidualsOfCase(c);
    // One figure per kind of x: along the rod (centre-line entries, and force readings at
    // their held point), around the section (surface points).
    for (const ResidualSeries::Along along :
         {ResidualSeries::Along::kArc, ResidualSeries::Along::kAngle}) {
      std::vector<const ResidualSeries*> shown;
      for (const ResidualSeries& rs : all)
        if (rs.along == along && !rs.sigmas.empty()) shown.push_back(&rs);
      if (shown.empty()) continue;
      const bool arc = along == ResidualSeries::Along::kArc;
      svg::Figure f;
      f.title = e_.scene.cases[c].name + (arc ? ": residuals along the rod"
                                              : ": surface residuals around the section");
      f.width = 660;
      f.height = 380;
      f.x.label = arc ? "arc length s [m]" : "angle around the section from d1 [°]";
      if (arc) {  // a little beyond the rod, so that markers at its ends are not on the frame
        f.x.min = -0.03 * in_.rod.length;
        f.x.max = 1.03 * in_.rod.length;
      } else {
        f.x.min = 0.0;
        f.x.max = 360.0;
      }
      f.y.label = "residual, model − measured [σ]";
      f.bands.push_back({-3, 3, "#2ca02c", 0.08, "±3 σ"});
      f.bands.push_back({-1, 1, "#2ca02c", 0.18, "±1 σ"});
      const svg::Marker shapes[] = {svg::Marker::kCircle, svg::Marker::kSquare,
                                    svg::Marker::kTriangle, svg::Marker::kDiamond};
      // A few gross outliers (hundreds of sigmas) would flatten everything else to a line: the
      // axis stops at kMaxSigmasShown and such points sit on its edge, as their own series.
      double extent = 4.0;
      for (const ResidualSeries* rs : shown)
        for (double v : rs->sigmas)
          if (std::isfinite(v)) extent = std::max(extent, std::min(kMaxSigmasShown, std::abs(v)));
      extent *= 1.05;
      f.y.min = -extent;
      f.y.max = extent;
      svg::Series beyond;
      beyond.colour = "#000000";
      beyond.line = false;
      beyond.marker = svg::Marker::kTriangle;
      beyond.hollow = true;
      beyond.marker_size = 5;
      for (size_t i = 0; i < shown.size(); ++i) {
        svg::Series s;
        s.label = shown[i]->label;
        s.colour = Colour(i);
        s.line = false;
        s.marker = shapes[i % 4];
        s.marker_size = 3.5;
        for (size_t k = 0; k < shown[i]->sigmas.size(); ++k) {
          const double v = shown[i]->sigmas[k];
          if (std::abs(v) > kMaxSigmasShown) {
            beyond.x.push_back(shown[i]->x[k]);
            beyond.y.push_back(std::copysign(extent, v));
          } else {
            s.x.push_back(shown[i]->x[k]);
            s.y.push_back(v);
          }
        }
        f.series.push_back(s);
      }
      if (!beyond.x.empty()) {
        beyond.label = std::to_string(beyond.x.size()) + " beyond ±" +
                       svg::FormatTick(kMaxSigmasShown, 1) + " σ (at the edge)";
        f.series.push_back(beyond);
      }
      page_.Figure(f, "residual-plot",
                   std::string(arc ? "residuals_" : "surface_residuals_") + e_.scene.cases[c].name,
                   " data-case=\"" + Escape(e_.scene.cases[c].name) + "\"",
                   arc ? "Every residual component of the case divided by its entry's sigma, "
                         "against where on the rod it was measured (a marker's s; a point's or "
                         "pixel's closest point on the fitted centre-line; a force reading at its "
                         "held point; "
                         "closest-point entries: the components across the curve only). About 68 % "
                         "should lie in the ±1 σ band and nearly all in ±3 σ when the model and "
                         "the sigmas are right; a trend along s is a model error there."
                       : "Every surface point's residual across the fitted section in sigmas, "
                         "against its angle around the section. A trend with the angle is a "
                         "section model error (e.g. at the instrument's contact).");
    }
  }

  void AllResiduals() {
    std::ostringstream& h = page_.html;
    h << "<section id=\"residuals\">\n<h2>Residuals</h2>\n<div class=\"figures\">\n";
    std::vector<double> values;
    for (size_t c = 0; c < e_.cases.size(); ++c)
      for (const ResidualSeries& s : ResidualsOfCase(c))
        for (double v : s.sigmas)
          if (std::isfinite(v)) values.push_back(v);
    double extent = 4.0;
    for (double v : values) extent = std::max(extent, std::min(10.0, std::ceil(std::abs(v))));
    const double bin = extent > 6 ? 1.0 : 0.5;
    const int bins = static_cast<int>(std::lround(2 * extent / bin));
    std::vector<double> centres(bins), counts(bins, 0.0);
    int outside = 0;
    for (int b = 0; b < bins; ++b) centres[b] = -extent + (b + 0.5) * bin;
    for (double v : values) {
      const int b = static_cast<int>(std::floor((v + extent) / bin));
      if (b < 0 || b >= bins) {
        ++outside;
        continue;
      }
      counts[b] += 1.0;
    }
    svg::Figure f;
    f.title = "Residuals of all cases against the normal density";
    f.width = 660;
    f.height = 400;
    f.x.label = "residual, model − measured [σ]";
    f.y.label = "count per " + svg::FormatTick(bin, 0.1) + " σ bin";
    svg::Series hist;
    hist.label = "residual components (" + std::to_string(values.size()) + ")";
    hist.colour = "#1f77b4";
    hist.bars = true;
    hist.bar_width = bin;
    hist.line = false;
    hist.x = centres;
    hist.y = counts;
    f.series.push_back(hist);
    svg::Series normal;
    normal.label = "N(0, 1) × count × bin";
    normal.colour = "#d62728";
    normal.line_width = 2.0;
    for (int i = 0; i <= 200; ++i) {
      const double x = -extent + 2 * extent * i / 200.0;
      normal.x.push_back(x);
      normal.y.push_back(values.size() * bin * std::exp(-0.5 * x * x) / std::sqrt(2 * kPi));
    }
    if (!values.empty()) f.series.push_back(normal);
    page_.Figure(f, "histogram", "histogram", "",
                 "Histogram of every residual component in sigmas (closest-point entries: across "
                 "the curve only) with the standard normal density scaled to the count" +
                     (outside > 0 ? "; " + std::to_string(outside) + " beyond ±" +
                                        svg::FormatTick(extent, 1) + " σ not shown"
                                  : std::string()) +
                     ".");
    h << "</div>\n";
    // RMS per entry, as summary.csv.
    h << "<h3>RMS per observation entry</h3>\n<table class=\"rms\">\n<tr><th>case</th>"
         "<th>entry</th><th>type</th><th>count</th><th>RMS</th></tr>\n";
    for (const ObservationFit& o : r_.observations) {
      h << "<tr><td>" << Escape(DisplayCaseName(o.case_name)) << "</td><td>" << Escape(o.label) << "</td><td>"
        << Escape(o.type) << "</td><td class=\"num\">" << o.num_measurements
        << "</td><td class=\"num\">" << WithUnit(o.rms, o.unit, 3);
      if (std::isfinite(o.rms_moment)) h << "; moments " << WithUnit(o.rms_moment, "N m", 3);
      if (std::isfinite(o.rms_roll)) h << "; roll " << WithUnit(o.rms_roll, "deg", 3);
      if (!o.warning.empty()) h << "; " << Escape(o.warning);
      h << "</td></tr>\n";
    }
    h << "</table>\n";
    // The cases' nuisances (held frames, points, gravity; never material): values and std.
    if (!r_.nuisances.empty()) {
      h << "<h3>Fitted nuisances (per case, not material)</h3>\n<table class=\"rms\">\n"
           "<tr><th>case</th><th>held</th><th>fitted (world x, y, z)</th><th>std</th>"
           "<th>prior</th></tr>\n";
      for (const NuisanceEstimate& n : r_.nuisances) {
        char b[240];
        std::snprintf(b, sizeof(b), "%s %.3g, %.3g, %.3g %s</td><td class=\"num\">%.2g, %.2g, %.2g",
                      n.quantity.c_str(), n.value[0], n.value[1], n.value[2], n.unit.c_str(),
                      n.std[0], n.std[1], n.std[2]);
        h << "<tr><td>" << Escape(DisplayCaseName(n.case_name)) << "</td><td>" << Escape(n.held)
          << "</td><td class=\"num\">" << b << "</td><td class=\"num\">" << n.prior << " "
          << n.unit << "</td></tr>\n";
      }
      h << "</table>\n";
    }
    h << "</section>\n";
  }

  void Convergence() {
    std::ostringstream& h = page_.html;
    h << "<section id=\"convergence\">\n<h2>Convergence and timing</h2>\n<div class=\"figures\">\n";
    svg::Figure f;
    f.title = "Cost per iteration";
    f.width = 560;
    f.height = 360;
    f.x.label = "Levenberg–Marquardt iteration";
    f.y.label = "cost, ½ Σ (residual/σ)² after the loss";
    f.y.log = true;
    svg::Series s;
    s.label = "cost";
    s.colour = kFitted;
    s.marker = svg::Marker::kCircle;
    for (size_t i = 0; i < r_.cost_per_iteration.size(); ++i) {
      s.x.push_back(static_cast<double>(i));
      s.y.push_back(r_.cost_per_iteration[i]);
    }
    f.series.push_back(s);
    f.no_data_text = "no iteration recorded (or a zero cost)";
    page_.Figure(f, "cost-plot", "cost", "",
                 "Ceres' cost at the start (iteration 0) and after each iteration (log scale).");
    h << "</div>\n";
    // The timing split. Case evaluations run in parallel, so their times are summed over threads
    // and may add up to more than the wall time.
    const double evaluations = r_.solve_seconds + r_.jacobian_seconds + r_.observation_seconds;
    h << "<table class=\"timing\">\n<tr><th>part</th><th>time</th><th>share of the wall "
         "time</th></tr>\n";
    auto row = [&](const std::string& part, double seconds) {
      h << "<tr><td>" << part << "</td><td class=\"num\">" << Duration(seconds)
        << "</td><td class=\"num\"><span class=\"wall-time\">"
        << (r_.seconds > 0 ? Percent(seconds / r_.seconds) : "—") << "</span>"
        << "</td></tr>\n";
    };
    row("whole fit (wall time)", r_.seconds);
    if (e_.scene.dynamics) {
      // A moving fit integrates each case with its sensitivities per evaluation: the forward
      // solves and the Jacobians are one run.
      row("runs of the moving cases with their sensitivities (" + std::to_string(r_.forward_solves) +
              " evaluations)",
          r_.solve_seconds);
      row("Ceres, covariance and the rest", std::max(0.0, r_.seconds - r_.solve_seconds));
      h << "</table>\n</section>\n";
      return;
    }
    if (r_.global_seconds > 0)
      row("global search (NLopt; its evaluations are in the rows below)", r_.global_seconds);
    row("forward solves (" + std::to_string(r_.forward_solves) + ")", r_.solve_seconds);
    row("exact Jacobians (sensitivities)", r_.jacobian_seconds);
    row("observation models", r_.observation_seconds);
    row(r_.global_seconds > 0 ? "NLopt, Ceres, covariance and the rest"
                              : "Ceres, covariance and the rest",
        std::max(0.0, r_.seconds - evaluations));
    h << "</table>\n<p>Forward solves, Jacobians and observation models are summed over the "
         "threads that evaluate cases in parallel.</p>\n</section>\n";
  }

  const Experiment& e_;
  const FitInput& in_;
  const FitResult& r_;
  const bool shapes_ok_;  // one fitted shape per fit case (else shape figures are left out)
  std::vector<std::string> warnings_;      // the run's and the page's own
  std::vector<std::string> own_warnings_;  // the page's own (returned to the caller)
  const PlotlyLibrary& plotly_;
  int views_ = 0;  // 3-D views on the page
  Page page_;
};

}  // namespace

FitReportPage BuildFitReportPage(const Experiment& experiment, const FitInput& input,
                                 const FitResult& result, const std::vector<std::string>& warnings) {
  return Builder(experiment, input, result, warnings).Build();
}

}  // namespace rodfit
