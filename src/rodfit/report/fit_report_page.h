// The fit report's page, DIR/index.html (docs/formats.md, "Fit report"): one self-contained HTML
// file a lab opens in a browser — the parameter and correlation tables, per case the camera
// views, 3-D projections, poked sections, force logs and residuals, the residual histogram,
// the cost per iteration and the timing split — with every figure an inline SVG
// (report/svg_plot.h) and every camera image a data: URI inside its figure. Each figure is also
// returned as a standalone SVG file for papers. Internal to the io layer (fit_report.cc).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"

namespace rodfit {

struct FitReportPage {
  std::string html;  ///< index.html
  /// (file name, SVG) of every figure on the page, e.g. ("camera_flat_cam_front.svg", "<svg...").
  std::vector<std::pair<std::string, std::string>> figures;
  /// The page's own warnings (e.g. no plotly.js for the 3-D views), also in its summary.
  std::vector<std::string> warnings;
};

/// Builds the page. Reads the camera images of `images` entries (InputError when one cannot be
/// read) and the haptic logs of `grasp_force` entries (for their full force-versus-time curves).
/// `warnings`: the run's warnings, each with what to do about it, listed in the summary.
FitReportPage BuildFitReportPage(const Experiment& experiment, const FitInput& input,
                                 const FitResult& result,
                                 const std::vector<std::string>& warnings = {});

}  // namespace rodfit
