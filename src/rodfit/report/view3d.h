// The reports' interactive 3-D views (docs/formats.md, "Fit report", "3-D view"): a rod's
// centre-line, markers and points with their residual vectors, held ends with their frames,
// forces as arrows and tube meshes, turned, zoomed and hovered in the browser, and for motions a
// time slider over the recorded frames. Drawn by plotly.js's gl3d bundle (a dependency from the
// npm registry, report/plotly_library.h), which the page inlines, so the page needs no network.
//
// A view is plain data here: traces (plotly.js's scatter3d, cone and mesh3d objects) built as
// JSON, positions given in metres and shown in millimetres, each point's hover text with its
// units. A view renders as a <div> with its JSON beside it; one script per page
// (View3dScript) draws every view of the page, or says in the view's place why it cannot.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace rodfit::view3d {

/// [mm/m]: a view's axes are in millimetres.
inline constexpr double kMmPerM = 1e3;

/// The style of a trace.
struct Style {
  std::string colour = "#1f5fbf";  ///< any CSS colour
  double width = 5.0;              ///< [px] line width, or marker size
  bool dashed = false;
  /// markers: circle, circle-open, diamond, square (drawn as the font's glyphs: "x" and
  /// "cross" show as boxes where the font lacks them, e.g. headless Chromium's)
  std::string symbol = "circle";
  double opacity = 1.0;
  bool legend = true;              ///< listed in the legend
  std::string group;               ///< legend group: traces toggled together (default: the name)
};

/// A polyline through the columns of `points_m` [m] (a NaN column breaks it). `hover`: one text
/// per point (HTML allowed: "s = 0.05 m"), or empty; the coordinates in mm follow it.
nlohmann::json Line(const std::string& name, const Eigen::Matrix3Xd& points_m,
                    const std::vector<std::string>& hover, const Style& style);

/// Markers at the columns of `points_m` [m].
nlohmann::json Points(const std::string& name, const Eigen::Matrix3Xd& points_m,
                      const std::vector<std::string>& hover, const Style& style);

/// Straight segments from each column of `from_m` to the same column of `to_m` [m] as one trace
/// (residual vectors, frame axes); `hover` per segment, shown at both ends.
nlohmann::json Segments(const std::string& name, const Eigen::Matrix3Xd& from_m,
                        const Eigen::Matrix3Xd& to_m, const std::vector<std::string>& hover,
                        const Style& style);

/// Arrows from `tail_m` [m] along `direction` (any length: drawn `length_m` long), with their
/// hover texts: a shaft (one line trace) and a head (one cone trace). Appended to *traces.
void Arrows(const std::string& name, const Eigen::Matrix3Xd& tail_m,
            const Eigen::Matrix3Xd& direction, double length_m,
            const std::vector<std::string>& hover, const Style& style,
            std::vector<nlohmann::json>* traces);

/// A triangle mesh (vertices [m], 0-based triangles), shaded.
nlohmann::json Mesh(const std::string& name, const Eigen::Matrix3Xd& vertices_m,
                    const std::vector<Eigen::Vector3i>& triangles, const Style& style);

/// One interactive 3-D view. The traces of `traces` are drawn at once; with frames, the traces
/// listed in `animated` are replaced by each frame's (in that order) as the slider moves.
struct View {
  std::string id;       ///< unique on the page: letters, digits, '-' and '_'
  std::string title;
  int height = 560;     ///< [px]
  std::vector<nlohmann::json> traces;
  std::vector<int> animated;  ///< indices into traces
  struct Frame {
    std::string label;                  ///< the slider's text, e.g. "0.150 s"
    std::vector<nlohmann::json> traces;  ///< one per entry of `animated`
  };
  std::vector<Frame> frames;
  std::string slider_prefix = "t = ";  ///< before a frame's label on the slider
};

/// The view as HTML: a <div class="view3d"> and its JSON in a <script type="application/json">.
std::string RenderView(const View& view);

/// The page's script that draws every view (include it once, after plotly.js): each view gets
/// rotation, zoom and hover; a view that cannot be drawn (no WebGL, no plotly.js) says so in its
/// place. With "#check3d" in the page's address it also writes, into <pre id="rodfit-check3d">,
/// a JSON summary a test reads: per view, the number of drawn (non-background) pixels of its
/// image (Plotly.toImage), and every script error of the page.
std::string ViewScript();

/// The head's first script: records the page's script errors for the "#check3d" summary.
std::string ErrorRecorderScript();

/// "0.165 s" for a case or frame time: 3 decimals below 10 s, enough for frames at up to 1 kHz,
/// without the float noise of the sum that made it (0.16500000000000001).
std::string TimeLabel(double t_s);

}  // namespace rodfit::view3d
