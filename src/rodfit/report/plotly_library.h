// Where the reports find plotly.js, the library that draws their 3-D views (report/view3d.h):
// its gl3d bundle from the npm registry (`plotly.js-gl3d-dist-min`), which
// scripts/install_deps.sh installs outside the repository and CMake's RODFIT_PLOTLY_JS finds at
// configure time. A report inlines the file, so the page needs no network when it is opened.
#pragma once

#include <string>

namespace rodfit {

struct PlotlyLibrary {
  std::string script;  ///< the file's text; empty when none was found
  std::string path;    ///< where it was read from
  /// Why there is none, with what to do about it (empty when `script` is set).
  std::string missing;
};

/// Reads plotly.js from, in order: the file named by the environment variable RODFIT_PLOTLY_JS,
/// the file CMake found (RODFIT_PLOTLY_JS at configure time), share/rodfit/plotly-gl3d.min.js
/// beside the running executable's bin/ (an installed rodfit), and the configured install
/// prefix's. Read once per process.
const PlotlyLibrary& FindPlotlyLibrary();

}  // namespace rodfit
