// The reports' 3-D views (view3d.h): plotly.js trace objects as JSON, and the page script.
#include "rodfit/report/view3d.h"

#include <cmath>
#include <cstdio>

namespace rodfit::view3d {
namespace {

using nlohmann::json;

// A coordinate in mm for the JSON, or null (plotly.js breaks a line at a null).
json Mm(double v_m) {
  if (!std::isfinite(v_m)) return nullptr;
  // 4 decimals of a millimetre (0.1 um) is below any marker noise; shorter JSON than %.17g.
  return std::round(v_m * kMmPerM * 1e4) / 1e4;
}

// The hover template: the point's text, its coordinates in mm, the trace's name.
const char* const kHover =
    "%{text}<br>x %{x:.2f} mm, y %{y:.2f} mm, z %{z:.2f} mm<extra>%{fullData.name}</extra>";

json Base(const std::string& name, const Style& style) {
  json t;
  t["type"] = "scatter3d";
  t["name"] = name;
  t["showlegend"] = style.legend;
  t["legendgroup"] = style.group.empty() ? name : style.group;
  if (style.opacity < 1.0) t["opacity"] = style.opacity;
  t["hovertemplate"] = kHover;
  return t;
}

void Coordinates(const Eigen::Matrix3Xd& p, json* t) {
  json x = json::array(), y = json::array(), z = json::array();
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    x.push_back(Mm(p(0, i)));
    y.push_back(Mm(p(1, i)));
    z.push_back(Mm(p(2, i)));
  }
  (*t)["x"] = std::move(x);
  (*t)["y"] = std::move(y);
  (*t)["z"] = std::move(z);
}

json Texts(const std::vector<std::string>& hover, Eigen::Index n) {
  json text = json::array();
  for (Eigen::Index i = 0; i < n; ++i)
    text.push_back(static_cast<size_t>(i) < hover.size() ? hover[i] : std::string());
  return text;
}

// `text` safe inside <script>: no "</" that could end the element early.
std::string ScriptSafe(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size(); ++i) {
    out += text[i];
    if (text[i] == '<' && i + 1 < text.size() && text[i + 1] == '/') out += '\\';
  }
  return out;
}

}  // namespace

json Line(const std::string& name, const Eigen::Matrix3Xd& points_m,
          const std::vector<std::string>& hover, const Style& style) {
  json t = Base(name, style);
  t["mode"] = "lines";
  Coordinates(points_m, &t);
  t["text"] = Texts(hover, points_m.cols());
  t["line"] = {{"color", style.colour}, {"width", style.width}};
  if (style.dashed) t["line"]["dash"] = "dash";
  return t;
}

json Points(const std::string& name, const Eigen::Matrix3Xd& points_m,
            const std::vector<std::string>& hover, const Style& style) {
  json t = Base(name, style);
  t["mode"] = "markers";
  Coordinates(points_m, &t);
  t["text"] = Texts(hover, points_m.cols());
  t["marker"] = {{"color", style.colour}, {"size", style.width}, {"symbol", style.symbol}};
  if (style.symbol.find("open") != std::string::npos)
    t["marker"]["line"] = {{"color", style.colour}, {"width", 2}};
  return t;
}

json Segments(const std::string& name, const Eigen::Matrix3Xd& from_m, const Eigen::Matrix3Xd& to_m,
              const std::vector<std::string>& hover, const Style& style) {
  const Eigen::Index n = std::min(from_m.cols(), to_m.cols());
  Eigen::Matrix3Xd p(3, 3 * n);
  std::vector<std::string> text;
  for (Eigen::Index i = 0; i < n; ++i) {
    p.col(3 * i) = from_m.col(i);
    p.col(3 * i + 1) = to_m.col(i);
    p.col(3 * i + 2).setConstant(NAN);  // the break between segments
    const std::string h = static_cast<size_t>(i) < hover.size() ? hover[i] : std::string();
    text.insert(text.end(), {h, h, std::string()});
  }
  return Line(name, p, text, style);
}

void Arrows(const std::string& name, const Eigen::Matrix3Xd& tail_m,
            const Eigen::Matrix3Xd& direction, double length_m,
            const std::vector<std::string>& hover, const Style& style, std::vector<json>* traces) {
  const Eigen::Index n = std::min(tail_m.cols(), direction.cols());
  Eigen::Matrix3Xd shaft_end(3, n), head(3, n), head_dir(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double norm = direction.col(i).norm();
    const Eigen::Vector3d u =
        norm > 0 && std::isfinite(norm) ? Eigen::Vector3d(direction.col(i) / norm)
                                        : Eigen::Vector3d::Zero();
    // The head is the last quarter of the arrow; the cone's anchor is its tip.
    shaft_end.col(i) = tail_m.col(i) + 0.75 * length_m * u;
    head.col(i) = tail_m.col(i) + length_m * u;
    head_dir.col(i) = u;
  }
  Style shaft = style;
  shaft.group = style.group.empty() ? name : style.group;
  traces->push_back(Segments(name, tail_m, shaft_end, hover, shaft));
  json cone;
  cone["type"] = "cone";
  cone["name"] = name;
  cone["legendgroup"] = shaft.group;
  cone["showlegend"] = false;
  cone["anchor"] = "tip";
  cone["sizemode"] = "absolute";
  // plotly.js scales a cone to `sizeref` times its vector's length in axis units: unit vectors
  // and a quarter of the arrow's length in mm make a head as long as that.
  cone["sizeref"] = 0.25 * length_m * kMmPerM;
  cone["showscale"] = false;
  cone["colorscale"] = json::array({json::array({0, style.colour}), json::array({1, style.colour})});
  cone["hovertemplate"] = "%{text}<extra>" + name + "</extra>";
  Coordinates(head, &cone);
  json u = json::array(), v = json::array(), w = json::array();
  for (Eigen::Index i = 0; i < n; ++i) {
    u.push_back(head_dir(0, i));
    v.push_back(head_dir(1, i));
    w.push_back(head_dir(2, i));
  }
  cone["u"] = std::move(u);
  cone["v"] = std::move(v);
  cone["w"] = std::move(w);
  cone["text"] = Texts(hover, n);
  traces->push_back(std::move(cone));
}

json Mesh(const std::string& name, const Eigen::Matrix3Xd& vertices_m,
          const std::vector<Eigen::Vector3i>& triangles, const Style& style) {
  json t;
  t["type"] = "mesh3d";
  t["name"] = name;
  t["showlegend"] = style.legend;
  t["legendgroup"] = style.group.empty() ? name : style.group;
  t["color"] = style.colour;
  t["opacity"] = style.opacity;
  t["flatshading"] = false;
  t["lighting"] = {{"ambient", 0.55}, {"diffuse", 0.8}, {"specular", 0.15}, {"roughness", 0.6}};
  t["hovertemplate"] = std::string("x %{x:.2f} mm, y %{y:.2f} mm, z %{z:.2f} mm<extra>") + name +
                       "</extra>";
  Coordinates(vertices_m, &t);
  json i = json::array(), j = json::array(), k = json::array();
  for (const Eigen::Vector3i& tri : triangles) {
    i.push_back(tri[0]);
    j.push_back(tri[1]);
    k.push_back(tri[2]);
  }
  t["i"] = std::move(i);
  t["j"] = std::move(j);
  t["k"] = std::move(k);
  return t;
}

std::string RenderView(const View& view) {
  json spec;
  spec["data"] = view.traces;
  json axis = {{"showspikes", false}, {"zeroline", false}};
  json layout;
  layout["title"] = {{"text", view.title}, {"font", {{"size", 15}}}, {"x", 0.01}};
  layout["height"] = view.height;
  layout["margin"] = {{"l", 0}, {"r", 0}, {"t", 36}, {"b", 0}};
  layout["legend"] = {{"x", 0.0}, {"y", 1.0}, {"bgcolor", "rgba(255,255,255,0.8)"}};
  layout["hoverlabel"] = json::object({{"align", "left"}});
  // Equal scales on the three axes: the rod's shape as it is.
  json scene = json::object();
  scene["aspectmode"] = "data";
  for (const char* name : {"x", "y", "z"}) {
    json a = axis;
    a["title"] = json::object({{"text", std::string(name) + " [mm]"}});
    scene[std::string(name) + "axis"] = a;
  }
  scene["camera"] = json::object({{"eye", json::object({{"x", 1.1}, {"y", -2.1}, {"z", 1.0}})}});
  layout["scene"] = scene;
  // Keep the user's camera while the slider moves.
  layout["uirevision"] = view.id;
  json frames = json::array();
  if (!view.frames.empty()) {
    json steps = json::array();
    for (size_t f = 0; f < view.frames.size(); ++f) {
      const std::string name = "f" + std::to_string(f);
      frames.push_back({{"name", name}, {"data", view.frames[f].traces}, {"traces", view.animated}});
      steps.push_back(
          {{"label", view.frames[f].label},
           {"method", "animate"},
           {"args", json::array({json::array({name}),
                                 {{"mode", "immediate"},
                                  {"frame", {{"duration", 0}, {"redraw", true}}},
                                  {"transition", {{"duration", 0}}}}})}});
    }
    layout["sliders"] = json::array(
        {{{"active", 0},
          {"steps", steps},
          {"x", 0.12},
          {"len", 0.88},
          {"y", 0.0},
          {"pad", {{"t", 30}}},
          {"currentvalue",
           {{"prefix", view.slider_prefix}, {"font", {{"size", 13}, {"color", "#222222"}}}}}}});
    // More steps than fit their labels side by side: the labels hidden (transparent), the
    // current one shown above the slider.
    if (view.frames.size() > 12)
      layout["sliders"][0]["font"] = json::object({{"color", "rgba(0,0,0,0)"}});
    layout["updatemenus"] = json::array(
        {{{"type", "buttons"},
          {"showactive", false},
          {"x", 0.0},
          {"y", 0.0},
          {"xanchor", "left"},
          {"yanchor", "top"},
          {"pad", {{"t", 40}, {"r", 10}}},
          {"buttons",
           json::array({{{"label", "▶ play"},
                         {"method", "animate"},
                         {"args", json::array({nullptr,
                                               {{"mode", "immediate"},
                                                {"fromcurrent", true},
                                                {"frame", {{"duration", 80}, {"redraw", true}}},
                                                {"transition", {{"duration", 0}}}}})}},
                        {{"label", "❚❚ pause"},
                         {"method", "animate"},
                         {"args", json::array({json::array({nullptr}),
                                               {{"mode", "immediate"},
                                                {"frame", {{"duration", 0}, {"redraw", false}}}}})}}})}}});
    layout["margin"]["b"] = 90;
    layout["height"] = view.height + 90;
  }
  spec["layout"] = layout;
  spec["frames"] = frames;
  return "<div class=\"view3d\" id=\"" + view.id + "\" style=\"height:" +
         std::to_string(layout["height"].get<int>()) +
         "px\"><p class=\"view3d-note\">The interactive 3-D view needs JavaScript.</p></div>\n"
         "<script type=\"application/json\" id=\"" + view.id + "-data\">" +
         ScriptSafe(spec.dump(-1, ' ', false, json::error_handler_t::replace)) + "</script>\n";
}

std::string ErrorRecorderScript() {
  return "<script>window.rodfitErrors=[];window.addEventListener('error',function(e){"
         "window.rodfitErrors.push(String(e.message||e));});"
         "(function(){var ce=console.error;console.error=function(){"
         "window.rodfitErrors.push(Array.prototype.join.call(arguments,' '));"
         "return ce.apply(console,arguments);};})();</script>\n";
}

std::string ViewScript() {
  // Plain ES5, no library but plotly.js. Views are drawn one after the other (each gets its own
  // WebGL context; drawing them together spikes the memory of a page with many cases).
  return R"JS(<script>
(function () {
  var views = Array.prototype.slice.call(document.querySelectorAll('div.view3d'));
  var check = location.hash === '#check3d';
  function note(div, text) {
    div.innerHTML = '';
    var p = document.createElement('p');
    p.className = 'view3d-note warn';
    p.textContent = text;
    div.appendChild(p);
    div.style.height = 'auto';
  }
  function report(results) {
    if (!check) return;
    var pre = document.createElement('pre');
    pre.id = 'rodfit-check3d';
    pre.textContent = JSON.stringify({views: views.length, drawn: results,
                                      errors: window.rodfitErrors || []});
    document.body.appendChild(pre);
  }
  if (typeof Plotly === 'undefined') {
    views.forEach(function (div) {
      note(div, 'The 3-D view is not available: this report was written without plotly.js ' +
                '(see the summary\'s warnings); the 2-D projections below show the same data.');
    });
    report(views.map(function () { return 0; }));
    return;
  }
  // Pixels of an image (a data: URL) that differ from the white background.
  function drawnPixels(url) {
    return new Promise(function (resolve) {
      var img = new Image();
      img.onload = function () {
        var c = document.createElement('canvas');
        c.width = img.width; c.height = img.height;
        var g = c.getContext('2d', {willReadFrequently: true});
        g.drawImage(img, 0, 0);
        var d = g.getImageData(0, 0, c.width, c.height).data, n = 0;
        for (var i = 0; i < d.length; i += 4)
          if (d[i + 3] > 0 && (d[i] < 235 || d[i + 1] < 235 || d[i + 2] < 235)) n++;
        resolve(n);
      };
      img.onerror = function () { resolve(0); };
      img.src = url;
    });
  }
  var results = [];
  function draw(k) {
    if (k === views.length) { report(results); return; }
    var div = views[k];
    var spec = JSON.parse(document.getElementById(div.id + '-data').textContent);
    div.innerHTML = '';
    Plotly.newPlot(div, {data: spec.data, layout: spec.layout, frames: spec.frames,
                         config: {displaylogo: false, responsive: true,
                                  toImageButtonOptions: {filename: div.id}}})
      .then(function (gd) {
        if (!check) return 1;
        // A view's own image: its scene drawn by WebGL, then read back.
        return Plotly.toImage(gd, {format: 'png', width: 480, height: 360}).then(drawnPixels);
      })
      .then(function (n) { results.push(n); draw(k + 1); },
            function (e) {
              note(div, 'The 3-D view could not be drawn (' + e + '): the browser may have ' +
                        'WebGL turned off. The 2-D projections below show the same data.');
              (window.rodfitErrors || []).push('3-D view ' + div.id + ': ' + e);
              results.push(0);
              draw(k + 1);
            });
  }
  draw(0);
})();
</script>
)JS";
}

std::string TimeLabel(double t_s) {
  char b[48];
  std::snprintf(b, sizeof(b), "%.6g s", t_s);
  return b;
}

}  // namespace rodfit::view3d
