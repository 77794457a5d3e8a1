// The rollout report (rollout_report.h).
#include "rodfit/report/rollout_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "rodfit/report/plotly_library.h"
#include "rodfit/report/svg_plot.h"
#include "rodfit/report/view3d.h"
#include "rodfit/version.h"

namespace rodfit {
namespace {

using svg::Escape;

const char* const kPalette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e",
                                "#8c564b", "#e377c2", "#17becf", "#7f7f7f", "#bcbd22"};
const char* Colour(size_t i) { return kPalette[i % (sizeof(kPalette) / sizeof(kPalette[0]))]; }
// A 3-D view's slider steps through at most this many frames (every k-th beyond), so that a
// long recording's page stays a few megabytes.
constexpr size_t kMaxViewFrames = 250;

std::string Num(double v, const char* format = "%.4g") {
  if (!std::isfinite(v)) return "—";
  char b[48];
  std::snprintf(b, sizeof(b), format, v);
  return b;
}
std::string Mm(double v_m) { return Num(v_m * 1e3, "%.3g") + "&nbsp;mm"; }
std::string FileName(const std::string& path) {
  return std::filesystem::path(path).filename().string();
}

class Page {
 public:
  std::ostringstream html;
  std::vector<std::pair<std::string, std::string>> figures;
  void Figure(const svg::Figure& f, const std::string& name, const std::string& caption) {
    const std::string svg = svg::RenderSvg(f, "f" + std::to_string(figures.size() + 1));
    html << "<figure class=\"fig\">\n" << svg << "<figcaption>" << caption
         << " <a class=\"svg-file\" href=\"figures/" << name << ".svg\">SVG</a></figcaption>\n"
         << "</figure>\n";
    figures.emplace_back(name + ".svg", svg);
  }
};

// The mean |coordinate error| of the predicted (not held) markers at each frame [m].
std::vector<double> ErrorPerFrame(const RolloutRecordingReport& r) {
  std::vector<double> out;
  for (size_t k = 0; k < r.result.predicted.size() && k < r.frames.size(); ++k) {
    double sum = 0.0;
    int n = 0;
    for (Eigen::Index m = 0; m < r.frames[k].cols(); ++m) {
      if (static_cast<size_t>(m) < r.result.held.size() && r.result.held[m]) continue;
      const Eigen::Vector3d e = r.result.predicted[k].col(m) - r.frames[k].col(m);
      if (!e.allFinite()) continue;
      sum += e.cwiseAbs().sum();
      n += 3;
    }
    out.push_back(n > 0 ? sum / n : NAN);
  }
  return out;
}

// The recording's 3-D view: per frame (of the first `frames`) the recorded and predicted
// markers, each set joined in marker order (the rod's vertices lie at the markers), the held ones
// apart.
void RecordingView(Page* page, const RolloutRecordingReport& r, size_t index, size_t frames) {
  const RolloutResult& res = r.result;
  const std::string name = FileName(r.file);
  const Eigen::Index markers = r.frames[0].cols();
  view3d::View view;
  view.id = "view3d-recording-" + std::to_string(index);
  view.title = "Recording " + Escape(name) + " in 3-D (drag to turn, scroll to zoom, slider or ▶ for the frames)";
  std::vector<Eigen::Vector3d> all;
  for (size_t k = 0; k < frames; ++k)
    for (Eigen::Index m = 0; m < markers; ++m)
      if (r.frames[k].col(m).allFinite()) all.push_back(r.frames[k].col(m));
  Eigen::Matrix3Xd paths(3, all.size());
  for (size_t i = 0; i < all.size(); ++i) paths.col(i) = all[i];
  view3d::Style faint;
  faint.colour = "#f4a3a3";
  faint.width = 2;
  faint.opacity = 0.5;
  view.traces.push_back(view3d::Points("all recorded samples", paths, {}, faint));
  const size_t every = (frames + kMaxViewFrames - 1) / kMaxViewFrames;
  for (size_t k = 0; k < frames; k += every) {
    const double t = k * r.frame_interval;
    std::vector<std::string> hover;
    for (Eigen::Index m = 0; m < markers; ++m) {
      const bool held = static_cast<size_t>(m) < res.held.size() && res.held[m];
      const Eigen::Vector3d e = res.predicted[k].col(m) - r.frames[k].col(m);
      hover.push_back("marker " + std::to_string(m) +
                      (static_cast<size_t>(m) < res.marker_s.size()
                           ? ", s = " + Num(res.marker_s[m]) + " m" : std::string()) +
                      (held ? " (held: driven from the recording)" : "") + ", t = " +
                      view3d::TimeLabel(t) +
                      (e.allFinite() ? "<br>error (predicted − recorded) " + Num(1e3 * e.norm(), "%.3g") + " mm"
                                     : std::string("<br>not seen in this frame")));
    }
    Eigen::Matrix3Xd held_points(3, markers);
    held_points.setConstant(NAN);
    for (Eigen::Index m = 0; m < markers; ++m)
      if (static_cast<size_t>(m) < res.held.size() && res.held[m])
        held_points.col(m) = res.predicted[k].col(m);
    std::vector<nlohmann::json> traces;
    view3d::Style predicted;
    predicted.colour = "#1f5fbf";
    predicted.width = 6;
    traces.push_back(view3d::Line("predicted (markers joined)", res.predicted[k], hover, predicted));
    view3d::Style recorded;
    recorded.colour = "#d62728";
    recorded.width = 3;
    recorded.dashed = true;
    traces.push_back(view3d::Line("recorded (markers joined)", r.frames[k], hover, recorded));
    view3d::Style seen;
    seen.colour = "#d62728";
    seen.symbol = "circle-open";
    seen.width = 7;
    seen.legend = false;
    seen.group = "recorded (markers joined)";
    traces.push_back(view3d::Points("recorded", r.frames[k], hover, seen));
    view3d::Style held;
    held.colour = "#222222";
    held.symbol = "square";
    held.width = 7;
    traces.push_back(view3d::Points("held markers (driven)", held_points, hover, held));
    view.frames.push_back({view3d::TimeLabel(t), std::move(traces)});
  }
  for (int i = 0; i < 4; ++i) view.animated.push_back(1 + i);
  view.traces.insert(view.traces.end(), view.frames.front().traces.begin(),
                     view.frames.front().traces.end());
  page->html << view3d::RenderView(view);
}

// Each predicted marker's coordinate that moves most, recorded and predicted, over time; and
// the predicted markers' error over time.
void RecordingPlots(Page* page, const RolloutRecordingReport& r, size_t index, size_t frames) {
  const RolloutResult& res = r.result;
  const std::string name = FileName(r.file);
  const Eigen::Index markers = r.frames[0].cols();
  int axis = 0;
  double widest = -1.0;
  for (int a = 0; a < 3; ++a) {
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < frames; ++k)
      for (Eigen::Index m = 0; m < markers; ++m)
        if (std::isfinite(r.frames[k](a, m))) {
          lo = std::min(lo, r.frames[k](a, m));
          hi = std::max(hi, r.frames[k](a, m));
        }
    if (hi - lo > widest) {
      widest = hi - lo;
      axis = a;
    }
  }
  std::vector<Eigen::Index> shown;
  for (Eigen::Index m = 0; m < markers; ++m)
    if (!(static_cast<size_t>(m) < res.held.size() && res.held[m])) shown.push_back(m);
  if (shown.size() > 6) {  // spread along the rod, so that the lines stay apart
    std::vector<Eigen::Index> spread;
    for (int i = 0; i < 6; ++i) spread.push_back(shown[i * (shown.size() - 1) / 5]);
    shown = spread;
  }
  svg::Figure f;
  const char* const axis_name = axis == 0 ? "x" : axis == 1 ? "y" : "z";
  f.title = name + ": " + axis_name + " of the predicted markers";
  f.width = 660;
  f.height = 420;
  f.x.label = "t [s]";
  f.y.label = std::string(axis_name) + " [mm]";
  for (size_t i = 0; i < shown.size(); ++i) {
    svg::Series rec, pred;
    const Eigen::Index m = shown[i];
    rec.label = "marker " + std::to_string(m) +
                (static_cast<size_t>(m) < res.marker_s.size() ? " (s = " + Num(res.marker_s[m], "%.3g") + " m)"
                                                              : std::string());
    rec.colour = pred.colour = Colour(i);
    rec.line = false;
    rec.marker = svg::Marker::kCircle;
    rec.hollow = true;
    rec.marker_size = 2.5;
    pred.line_width = 1.6;
    for (size_t k = 0; k < frames; ++k) {
      rec.x.push_back(k * r.frame_interval);
      rec.y.push_back(1e3 * r.frames[k](axis, m));
      pred.x.push_back(k * r.frame_interval);
      pred.y.push_back(1e3 * res.predicted[k](axis, m));
    }
    f.series.push_back(rec);
    f.series.push_back(pred);
  }
  page->Figure(f, "markers_" + std::to_string(index),
               "Recording <code>" + Escape(name) + "</code>: the " + axis_name +
                   " coordinate (the one that moves most) of the predicted markers as recorded "
                   "(circles) and as predicted open-loop (lines)" +
                   (markers > static_cast<Eigen::Index>(shown.size()) + 0
                        ? ", " + std::to_string(shown.size()) + " markers spread along the rod"
                        : std::string()) + ".");
  svg::Figure g;
  g.title = name + ": error over time";
  g.width = 660;
  g.height = 360;
  g.x.label = "t [s]";
  g.y.label = "mean |predicted − recorded| [mm]";
  svg::Series err;
  err.label = "predicted markers, mean absolute coordinate error";
  err.colour = "#d62728";
  const std::vector<double> per_frame = ErrorPerFrame(r);
  for (size_t k = 1; k < per_frame.size(); ++k) {
    err.x.push_back(k * r.frame_interval);
    err.y.push_back(1e3 * per_frame[k]);
  }
  g.series.push_back(err);
  page->Figure(g, "error_" + std::to_string(index),
               "Recording <code>" + Escape(name) + "</code>: the predicted markers' mean "
               "absolute coordinate error at each frame (from frame 1; the score averages it).");
}

void Recording(Page* page, const RolloutRecordingReport& r, size_t index, int* views) {
  const std::string name = FileName(r.file);
  page->html << "<h3 id=\"recording-" << index << "\">Recording <code>" << Escape(name)
             << "</code></h3>\n";
  const size_t frames = std::min(r.result.predicted.size(), r.frames.size());
  if (frames > 0) {
    RecordingView(page, r, index, frames);
    ++*views;
  }
  page->html << "<div class=\"figures\">\n";
  if (frames > 1) RecordingPlots(page, r, index, frames);
  page->html << "</div>\n";
}

// The summary: each recording's error and the mean over them, and the warnings.
void SummarySection(const RolloutReportInput& in, const std::vector<std::string>& warnings,
                    std::ostringstream* out) {
  std::ostringstream& h = *out;
  h << "<section id=\"summary\">\n<h2>Summary</h2>\n";
  h << "<table class=\"errors\">\n<tr><th>recording</th><th>frames</th><th>frame interval</th>"
       "<th>markers (held)</th><th>samples compared</th><th>error, all markers</th>"
       "<th>error, predicted markers</th><th>halved steps</th></tr>\n";
  double sum_all = 0.0, sum_predicted = 0.0;
  for (const RolloutRecordingReport& r : in.recordings) {
    const int held = static_cast<int>(std::count(r.result.held.begin(), r.result.held.end(), 1));
    h << "<tr><td><code>" << Escape(FileName(r.file)) << "</code></td><td class=\"num\">"
      << r.result.predicted.size() << "</td><td class=\"num\">" << Num(r.frame_interval, "%.4g")
      << "&nbsp;s</td><td class=\"num\">" << r.result.marker_s.size() << " (" << held
      << ")</td><td class=\"num\">" << r.result.samples << "</td><td class=\"num\">"
      << Mm(r.result.mae_all) << "</td><td class=\"num\">" << Mm(r.result.mae_predicted)
      << "</td><td class=\"num\">" << r.result.halved_steps << "</td></tr>\n";
    sum_all += r.result.mae_all;
    sum_predicted += r.result.mae_predicted;
  }
  if (in.recordings.size() > 1) {
    const double n = static_cast<double>(in.recordings.size());
    h << "<tr><th colspan=\"5\">mean over the recordings</th><td class=\"num\">" << Mm(sum_all / n)
      << "</td><td class=\"num\">" << Mm(sum_predicted / n) << "</td><td></td></tr>\n";
  }
  h << "</table>\n<p>Error: the mean absolute coordinate error against the recording, frames 1 "
       "on, where a marker was seen.</p>\n";
  if (!warnings.empty()) {
    h << "<h3 class=\"warn\">Warnings (" << warnings.size() << ")</h3>\n<ul class=\"warnings\">\n";
    for (const std::string& w : warnings) h << "<li>" << Escape(w) << "</li>\n";
    h << "</ul>\n";
  } else {
    h << "<p class=\"no-warnings\">No warnings.</p>\n";
  }
  h << "</section>\n";
}

// The motion fit: its parameters, cost per iteration and time.
void FitSection(const MotionFitResult& fit, Page* out) {
  Page& page = *out;
  std::ostringstream& h = page.html;
  h << "<section id=\"fit\">\n<h2>Fitted parameters</h2>\n<p>" << Escape(fit.method)
    << (fit.converged ? ", converged: " : ", <span class=\"warn\">not converged</span>: ")
    << Escape(fit.message) << "; " << fit.iterations << " iterations, " << fit.evaluations
    << " rollouts of every recording; residual variance " << Num(fit.residual_variance, "%.3g")
    << " over " << fit.residuals << " residuals; error " << Mm(fit.error_start) << " at the start, "
    << Mm(fit.error_fitted) << " fitted.</p>\n";
  h << "<table class=\"parameters\">\n<tr><th>parameter</th><th>start</th><th>value ± std</th>"
       "<th>identifiable</th><th>at a bound</th></tr>\n";
  for (size_t k = 0; k < fit.names.size(); ++k) {
    h << "<tr><td><code>" << Escape(fit.names[k]) << "</code></td><td class=\"num\">"
      << Num(fit.start[k]) << "</td><td class=\"num\">" << Num(fit.values[k]);
    if (k < fit.identifiable.size() && fit.identifiable[k])
      h << " ± " << Num(fit.std[k], "%.2g") << "</td><td>yes</td>";
    else
      h << "</td><td class=\"warn\">no: " << Escape(k < fit.reason.size() ? fit.reason[k] : "")
        << "</td>";
    h << "<td>" << (k < fit.at_bound.size() && fit.at_bound[k] ? "<span class=\"warn\">yes</span>" : "no")
      << "</td></tr>\n";
  }
  h << "</table>\n<div class=\"figures\">\n";
  if (fit.cost_per_iteration.size() > 1) {
    svg::Figure f;
    f.title = "Cost per iteration";
    f.width = 560;
    f.height = 360;
    f.x.label = "Levenberg–Marquardt iteration";
    f.y.label = "cost, ½ Σ (residual/σ)²";
    f.y.log = true;
    svg::Series s;
    s.label = "cost";
    s.colour = "#1f5fbf";
    s.marker = svg::Marker::kCircle;
    for (size_t i = 0; i < fit.cost_per_iteration.size(); ++i) {
      s.x.push_back(static_cast<double>(i));
      s.y.push_back(fit.cost_per_iteration[i]);
    }
    f.series.push_back(s);
    page.Figure(f, "cost", "Ceres' cost at the start (iteration 0) and after each iteration.");
  }
  h << "</div>\n<table class=\"timing\">\n<tr><th>part</th><th>time</th></tr>\n"
    << "<tr><td>whole fit (wall time)</td><td class=\"num\"><span class=\"wall-time\">"
    << Num(fit.seconds, "%.3g") << "&nbsp;s</span></td></tr>\n"
    << "<tr><td>rollouts with their sensitivities (" << fit.evaluations
    << ")</td><td class=\"num\"><span class=\"wall-time\">" << Num(fit.run_seconds, "%.3g")
    << "&nbsp;s</span></td></tr>\n<tr><td>Ceres, covariance and the rest</td><td class=\"num\">"
    << "<span class=\"wall-time\">" << Num(std::max(0.0, fit.seconds - fit.run_seconds), "%.3g")
    << "&nbsp;s</span></td></tr>\n</table>\n</section>\n";
}

}  // namespace

std::vector<std::string> WriteRolloutReport(StagedDirectory* out, const RolloutReportInput& in) {
  const PlotlyLibrary& plotly = FindPlotlyLibrary();
  std::vector<std::string> own, warnings = in.warnings;
  if (!plotly.missing.empty()) {
    own.push_back(plotly.missing);
    warnings.push_back(plotly.missing);
  }
  Page page;
  std::ostringstream& h = page.html;
  h << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
    << "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
    << "<meta name=\"generator\" content=\"rodfit " << Escape(RODFIT_VERSION) << "\">\n"
    << "<title>rodfit rollout report: " << Escape(FileName(in.scene_path)) << "</title>\n<style>\n"
    << "body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;font-size:15px;margin:24px auto;"
       "max-width:1400px;padding:0 16px;color:#222;line-height:1.4}\n"
       "h1{font-size:24px}h2{font-size:20px;border-bottom:1px solid #ccc;padding-bottom:4px;"
       "margin-top:36px}h3{font-size:17px;margin-top:24px}\n"
       "table{border-collapse:collapse;margin:8px 0 16px}th,td{border:1px solid #ccc;"
       "padding:4px 8px;text-align:left;vertical-align:top}th{background:#f2f2f2}\n"
       "td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}\n"
       ".figures{display:flex;flex-wrap:wrap;gap:16px;align-items:flex-start}\n"
       "figure{margin:0;border:1px solid #ddd;padding:6px;background:#fff}\n"
       "figure svg{display:block;max-width:100%;height:auto}\n"
       "figcaption{font-size:13px;color:#444;max-width:640px;margin-top:4px}\n"
       ".warn{color:#b30000;font-weight:bold}ul.warnings li{margin-bottom:6px}\n"
       "div.view3d{border:1px solid #ddd;margin:8px 0 16px;background:#fff}\n"
       "p.view3d-note{padding:8px;margin:0}footer{margin-top:40px;font-size:13px;color:#555}\n"
       "@media print{body{max-width:none;margin:0;font-size:11px}div.view3d,a.svg-file"
       "{display:none}.figures{display:block}figure{break-inside:avoid;page-break-inside:avoid;"
       "border:none}h2,h3{break-after:avoid}tr{break-inside:avoid}}\n"
    << "</style>\n" << view3d::ErrorRecorderScript() << "</head>\n<body>\n"
    << "<h1>Rollout report: <code>" << Escape(FileName(in.scene_path)) << "</code></h1>\n"
    << "<p>Scene <code>" << Escape(in.scene_path) << "</code>; " << in.recordings.size()
    << " recording" << (in.recordings.size() == 1 ? "" : "s")
    << ", each predicted open-loop from its first two frames, its held markers driven from the "
       "recording; rodfit " << Escape(RODFIT_VERSION) << ".</p>\n";

  SummarySection(in, warnings, &h);
  if (in.fit) FitSection(*in.fit, &page);

  h << "<section id=\"recordings\">\n<h2>Recordings</h2>\n";
  int views = 0;
  for (size_t i = 0; i < in.recordings.size(); ++i) Recording(&page, in.recordings[i], i, &views);
  h << "</section>\n";
  if (views > 0) {
    if (!plotly.script.empty()) {
      std::string library = plotly.script;
      for (size_t at = library.find("</"); at != std::string::npos; at = library.find("</", at + 3))
        library.insert(at + 1, "\\");
      h << "<script>/* plotly.js, from " << Escape(FileName(plotly.path)) << " (MIT license) */\n"
        << library << "\n</script>\n";
    }
    h << view3d::ViewScript();
  }
  h << "<footer>Beside this page: <code>rollout.csv</code> (every marker's recorded and predicted "
       "position per frame)"
    << (in.fit ? ", <code>motion_fit.json</code> (the fit)" : "")
    << "; each figure as SVG in <code>figures/</code>. Written by rodfit " << Escape(RODFIT_VERSION)
    << ".</footer>\n</body>\n</html>\n";
  for (const auto& [name, svg] : page.figures) out->Write("figures/" + name, svg, "figure name");
  out->Write("index.html", page.html.str());
  return own;
}

std::vector<std::string> WriteRolloutRunReport(StagedDirectory* out, const RolloutRun& run) {
  RolloutReportInput report;
  report.scene_path = run.scene_path;
  for (size_t r = 0; r < run.results.size(); ++r)
    report.recordings.push_back({run.recordings[r].file, run.recordings[r].frame_interval,
                                 run.recordings[r].frames, run.results[r]});
  report.fit = run.fit.get();
  report.warnings = run.warnings;
  return WriteRolloutReport(out, report);
}

}  // namespace rodfit
