// The fit report's 3-D views (fit_views3d.h).
#include "rodfit/report/fit_views3d.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <stdexcept>

#include "rodfit/model/rod.h"
#include "rodfit/observe/observations.h"
#include "rodfit/report/fit_report.h"
#include "rodfit/report/svg_plot.h"

namespace rodfit {
namespace {

using nlohmann::json;
using view3d::Style;
// Text from the input (case names, file names) is escaped: plotly.js renders names, titles and
// hover texts as a subset of HTML.
std::string Text(const std::string& s) { return svg::Escape(s); }

const char* const kFitted = "#1f5fbf";     // the model: blue
const char* const kObserved = "#d62728";   // measurements: red
const char* const kResidual = "#ff7f0e";   // model - measured: orange
const char* const kHeld = "#222222";       // held points: black
const char* const kLoad = "#2ca02c";       // applied loads: green
const char* const kAxes[] = {"#d62728", "#2ca02c", "#1f77b4"};  // d1, d2, d3 (tangent)

std::string Num(double v, const char* format = "%.4g") {
  char b[48];
  std::snprintf(b, sizeof(b), format, v);
  return b;
}
std::string Mm(double v_m) { return Num(v_m * 1e3, "%.3g") + " mm"; }
std::string Arc(double s) { return "s = " + Num(s, "%.4g") + " m"; }
std::string Vector(const Eigen::Vector3d& v, const std::string& unit) {
  return "(" + Num(v.x(), "%.3g") + ", " + Num(v.y(), "%.3g") + ", " + Num(v.z(), "%.3g") + ") " +
         unit;
}

Eigen::Matrix3Xd Columns(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Matrix3Xd m(3, points.size());
  for (size_t i = 0; i < points.size(); ++i) m.col(i) = points[i];
  return m;
}

// The vertices' rest arc lengths of a fitted shape: the case's rod model's when it has the
// shape's vertex count, else spread evenly over the rod (a shape the model cannot be built for).
std::vector<double> ArcLengths(const FitInput& in, const LoadCase& load_case, Eigen::Index n) {
  try {
    LoadCase whole = load_case;
    whole.symmetry.reset();
    const RodModel model(in.rod, in.material, in.gravity, whole, in.springs);
    if (static_cast<Eigen::Index>(model.arc_lengths().size()) == n) return model.arc_lengths();
  } catch (const std::invalid_argument&) {
  }
  std::vector<double> s(n);
  for (Eigen::Index i = 0; i < n; ++i) s[i] = in.rod.length * i / std::max<Eigen::Index>(1, n - 1);
  return s;
}

// The point of a polyline at arc length s (linear between the vertices around it).
Eigen::Vector3d At(const Eigen::Matrix3Xd& shape, const std::vector<double>& arc, double s) {
  if (shape.cols() == 0) return Eigen::Vector3d::Constant(NAN);
  const auto it = std::upper_bound(arc.begin(), arc.end(), s);
  const size_t i = std::clamp<size_t>(it - arc.begin(), 1, arc.size() - 1);
  const double w = arc[i] > arc[i - 1] ? (s - arc[i - 1]) / (arc[i] - arc[i - 1]) : 0.0;
  return (1 - std::clamp(w, 0.0, 1.0)) * shape.col(i - 1) + std::clamp(w, 0.0, 1.0) * shape.col(i);
}

json CentreLine(const std::string& name, const Eigen::Matrix3Xd& shape,
                const std::vector<double>& arc, const Style& style) {
  std::vector<std::string> hover;
  for (size_t i = 0; i < arc.size(); ++i) hover.push_back(Arc(arc[i]) + ", vertex " + std::to_string(i));
  return view3d::Line(name, shape, hover, style);
}

// A clamp's frame (d1, d2, d3 = tangent) at `position`, each axis `length` long.
void Frame(const std::string& name, const Eigen::Vector3d& position, const Eigen::Vector3d& tangent,
           const Eigen::Vector3d* normal, double length, std::vector<json>* traces) {
  const Eigen::Vector3d d3 = tangent.normalized();
  std::vector<Eigen::Vector3d> axes;
  if (normal) {
    const Eigen::Vector3d d1 = (*normal - normal->dot(d3) * d3).normalized();
    axes = {d1, d3.cross(d1), d3};
  } else {
    axes = {Eigen::Vector3d::Constant(NAN), Eigen::Vector3d::Constant(NAN), d3};
  }
  const char* const names[] = {"d1 (normal)", "d2", "d3 (tangent)"};
  for (int a = 0; a < 3; ++a) {
    if (!axes[a].allFinite()) continue;
    Style style;
    style.colour = kAxes[a];
    style.width = 6;
    style.group = "held frames";
    style.legend = false;
    traces->push_back(view3d::Segments(name + " " + names[a], position,
                                       Eigen::Vector3d(position + length * axes[a]),
                                       {name + ": " + names[a]}, style));
  }
}

// Held points of a static case: the clamp and an end clamp with their frames, an end pin, pins.
// The grasp is drawn with the case's forces.
void HeldPoints(const LoadCase& lc, double L, std::vector<json>* traces) {
  std::vector<Eigen::Vector3d> at;
  std::vector<std::string> hover;
  at.push_back(lc.clamp.position);
  hover.push_back("clamp at s = 0");
  Frame("clamp", lc.clamp.position, lc.clamp.tangent, &lc.clamp.normal, 0.12 * L, traces);
  if (lc.end_clamp) {
    at.push_back(lc.end_clamp->position);
    hover.push_back("end clamp at s = L");
    Frame("end clamp", lc.end_clamp->position, lc.end_clamp->tangent,
          lc.end_clamp->normal ? &*lc.end_clamp->normal : nullptr, 0.12 * L, traces);
  }
  if (lc.end_pin) {
    at.push_back(*lc.end_pin);
    hover.push_back("end pin at s = L");
  }
  for (const Pin& p : lc.pins) {
    at.push_back(p.position);
    hover.push_back("pin at " + Arc(p.s));
  }
  Style style;
  style.colour = kHeld;
  style.symbol = "square";
  style.width = 7;
  style.group = "held frames";
  traces->insert(traces->begin(), view3d::Points("held points (frames: d1 red, d2 green, "
                                                 "d3 = tangent blue)",
                                                 Columns(at), hover, style));
}

struct ArrowSet {
  std::vector<Eigen::Vector3d> tail, force;
  std::vector<std::string> hover;
  void Add(const Eigen::Vector3d& t, const Eigen::Vector3d& f, const std::string& h) {
    if (!t.allFinite() || !f.allFinite() || !(f.norm() > 0)) return;
    tail.push_back(t);
    force.push_back(f);
    hover.push_back(h + "<br>F = " + Vector(f, "N") + ", |F| = " + Num(f.norm(), "%.3g") + " N");
  }
};

// Arrows of a set, each as long as its force at `metres_per_newton` (at least a tenth of
// `shortest`, so that a small force still shows its direction).
void DrawArrows(const std::string& name, const ArrowSet& set, double metres_per_newton,
                double shortest, const Style& style, std::vector<json>* traces) {
  // One trace pair per arrow: plotly's cones take one size per trace.
  for (size_t i = 0; i < set.tail.size(); ++i) {
    Style s = style;
    s.legend = style.legend && i == 0;
    s.group = name;
    view3d::Arrows(name, set.tail[i], set.force[i],
                   std::max(shortest, set.force[i].norm() * metres_per_newton), {set.hover[i]}, s,
                   traces);
  }
  if (set.tail.empty()) {  // an empty pair keeps the trace count of a slider's frames
    Style s = style;
    s.legend = false;
    view3d::Arrows(name, Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xd(3, 0), 0.0, {}, s, traces);
  }
}

// The case's force readings in residual order (each ForceReadings' readings in turn).
std::vector<const ForceMeasurement*> Readings(const FitCase& fc) {
  std::vector<const ForceMeasurement*> out;
  for (const auto& meas : fc.measurements)
    if (const auto* forces = dynamic_cast<const ForceReadings*>(meas.get()))
      for (const ForceMeasurement& m : forces->readings()) out.push_back(&m);
  return out;
}

double LargestForce(const FitCase& fc, const FitResult& r, size_t ci) {
  double f = fc.load_case.tip_force.norm();
  for (const PointForce& p : fc.load_case.point_forces) f = std::max(f, p.force.norm());
  if (fc.load_case.poke) f = std::max(f, fc.load_case.poke->force.norm());
  for (const ForceMeasurement* m : Readings(fc)) f = std::max(f, m->force.norm());
  for (const MeasurementResidual& mr : r.measurement_residuals)
    if (mr.case_index == static_cast<int>(ci) && mr.unit == "N") f = std::max(f, mr.error.norm());
  return f;
}

// The force residuals of fit case ci, in the order of its ForceMeasurements.
std::vector<const MeasurementResidual*> ForceResiduals(const FitResult& r, size_t ci) {
  std::vector<const MeasurementResidual*> out;
  for (const MeasurementResidual& mr : r.measurement_residuals)
    if (mr.case_index == static_cast<int>(ci) && mr.unit == "N") out.push_back(&mr);
  return out;
}

// The traces of fit case ci that move with a slider: the centre-line, the grasp and the
// measured and fitted forces on the held points: for a slider's frames 2 + 2 x 2 traces (the
// first reading of each), which every frame must have the same number of.
std::vector<json> MovingPart(const FitInput& in, const FitResult& r, size_t ci, double L,
                             double metres_per_newton, bool for_slider) {
  const FitCase& fc = in.cases[ci];
  const Eigen::Matrix3Xd& shape = r.shapes[ci];
  const std::vector<double> arc = ArcLengths(in, fc.load_case, shape.cols());
  std::vector<json> traces;
  Style line;
  line.colour = kFitted;
  line.width = 7;
  traces.push_back(CentreLine("fitted centre-line", shape, arc, line));
  Style grasp;
  grasp.colour = kHeld;
  grasp.symbol = "diamond";
  grasp.width = 8;
  Eigen::Matrix3Xd where(3, 0);
  std::vector<std::string> hover;
  if (fc.load_case.grasp) {
    where = fc.load_case.grasp->position;
    hover.push_back("instrument's grasp at " + Arc(fc.load_case.grasp->s));
  }
  traces.push_back(view3d::Points("instrument (grasp)", where, hover, grasp));
  ArrowSet measured, fitted;
  const std::vector<const MeasurementResidual*> errors = ForceResiduals(r, ci);
  const std::vector<const ForceMeasurement*> readings = Readings(fc);
  for (size_t k = 0; k < readings.size(); ++k) {
    const ForceMeasurement& m = *readings[k];
    // Where the reading was taken: the grasp, or another held point (a reaction entry).
    Eigen::Vector3d at = fc.load_case.grasp && m.point == "grasp" ? fc.load_case.grasp->position
                                                                   : Eigen::Vector3d(shape.col(0));
    if (m.point == "end_clamp" || m.point == "end_pin") at = shape.col(shape.cols() - 1);
    if (m.point.rfind("pins[", 0) == 0) {
      const size_t pin = std::strtoul(m.point.c_str() + 5, nullptr, 10);
      if (pin < fc.load_case.pins.size()) at = fc.load_case.pins[pin].position;
    }
    measured.Add(at, m.force, "measured force on the " + m.point);
    if (k < errors.size())
      fitted.Add(at, m.force + errors[k]->error,
                 "fitted force on the " + m.point + "<br>residual " + Vector(errors[k]->error, "N"));
  }
  Style fm;
  fm.colour = kObserved;
  fm.width = 5;
  DrawArrows("measured force on the rod's holder", measured, metres_per_newton, 0.02 * L, fm,
             &traces);
  Style ff = fm;
  ff.colour = kFitted;
  DrawArrows("fitted force", fitted, metres_per_newton, 0.02 * L, ff, &traces);
  // A set with several arrows adds pairs; a slider needs one count in every frame: only the
  // first reading of each set is drawn in a frame (a haptic sample has one).
  if (for_slider)
    while (traces.size() > 6) traces.pop_back();
  return traces;
}

// The tube with the poke's dent, and the poked section at rest, fitted and its dent
// magnified: under everything else.
void SectionTraces(const FitResult& r, size_t c, std::vector<json>* traces) {
  if (c < r.tube_vertices.size() && r.tube_vertices[c].cols() > 0) {
    Style tube;
    tube.colour = "#e6a37e";
    tube.opacity = 0.55;
    traces->push_back(view3d::Mesh("tissue surface with the poke's dent (fitted)",
                                   r.tube_vertices[c], r.tube_triangles[c], tube));
  }
  if (c < r.sections.size() && r.sections[c].cols() > 2) {
    auto closed = [](const Eigen::Matrix3Xd& ring) {
      Eigen::Matrix3Xd out(3, ring.cols() + 1);
      out << ring, ring.col(0);
      return out;
    };
    Style rest;
    rest.colour = "#888888";
    rest.width = 4;
    rest.dashed = true;
    traces->push_back(view3d::Line("poked section at rest", closed(r.rest_sections[c]), {}, rest));
    Style ring;
    ring.colour = kFitted;
    ring.width = 6;
    traces->push_back(view3d::Line("poked section, fitted", closed(r.sections[c]), {}, ring));
    const double k = DentMagnification(r.rest_sections[c], r.sections[c]);
    if (k > 1) {
      Style dent;
      dent.colour = "#9467bd";
      dent.width = 8;
      traces->push_back(view3d::Line(
          "the dent magnified × " + Num(k, "%g") + " (section displacement)",
          closed(r.rest_sections[c] + k * (r.sections[c] - r.rest_sections[c])), {}, dent));
    }
  }
}

// Markers and points with their residual vectors.
void MeasurementTraces(const FitCase& fc, const Eigen::Matrix3Xd& shape,
                       std::vector<json>* traces) {
  for (const auto& meas : fc.measurements) {
    if (!meas->reads_vertices_only()) continue;
    const Measurement& obs = *meas;
    const std::string label = Text(obs.label());
    SolvedCase at;
    at.x = &shape;
    VecX res(obs.num_residuals());
    std::string why;
    const bool ok = obs.Evaluate(at, res.data(), nullptr, &why);
    std::vector<Eigen::Vector3d> seen, model;
    std::vector<std::string> hover;
    auto add = [&](const Eigen::Vector3d& q, const Eigen::Vector3d& e_sigma, const std::string& what) {
      const Eigen::Vector3d e = e_sigma * obs.sample_sigma(0);
      seen.push_back(q);
      model.push_back(ok ? Eigen::Vector3d(q + e) : Eigen::Vector3d::Constant(NAN));
      hover.push_back(what + (ok ? "<br>residual (model − measured) " + Mm(e.norm()) + " = " +
                                       Num(e_sigma.norm(), "%.2f") + " σ"
                                 : std::string()));
    };
    if (const auto* m = ModelOf<Markers3dObservation>(obs)) {
      for (size_t i = 0; i < m->markers().size(); ++i)
        add(m->markers()[i].p_world, ok ? Eigen::Vector3d(res.segment<3>(3 * i)) : Eigen::Vector3d::Zero(),
            "marker at " + Arc(m->markers()[i].s));
    } else if (const auto* p = ModelOf<Points3dObservation>(obs)) {
      for (size_t i = 0; i < p->samples().size(); ++i)
        add(p->samples()[i], ok ? Eigen::Vector3d(res.segment<3>(3 * i)) : Eigen::Vector3d::Zero(),
            "point " + std::to_string(i + 1));
    } else {
      continue;  // pixels: in the camera views
    }
    Style observed;
    observed.colour = kObserved;
    observed.symbol = "circle-open";
    observed.width = 6;
    traces->push_back(view3d::Points("observed: " + label, Columns(seen), hover, observed));
    Style fitted;
    fitted.colour = kFitted;
    fitted.symbol = "diamond";
    fitted.width = 4;
    fitted.group = "residual vectors";
    traces->push_back(view3d::Points("model at the fit", Columns(model), hover, fitted));
    Style arrow;
    arrow.colour = kResidual;
    arrow.width = 4;
    arrow.group = "residual vectors";
    traces->push_back(view3d::Segments("residual vectors (measured → model)", Columns(seen),
                                       Columns(model), hover, arrow));
  }
}

// Surface points of a poke, with their residuals to the fitted section.
void SurfacePointTraces(const FitCase& fc, const FitResult& r, size_t c,
                        std::vector<json>* traces) {
  for (const auto& meas : fc.measurements) {
    const auto* set = dynamic_cast<const SurfacePointSet*>(meas.get());
    if (!set) continue;
    const std::vector<Eigen::Vector3d>& points = set->points();
    std::vector<Eigen::Vector3d> seen, model;
    std::vector<std::string> hover;
    size_t i = 0;
    for (const MeasurementResidual& mr : r.measurement_residuals) {
      if (mr.case_index != static_cast<int>(c) || mr.observation != set->label() || mr.unit != "m")
        continue;
      if (mr.measurement < 0 || mr.measurement >= static_cast<int>(points.size())) continue;
      const Eigen::Vector3d q = points[mr.measurement];
      seen.push_back(q);
      model.push_back(q + mr.error);
      hover.push_back("surface point " + std::to_string(++i) + "<br>residual " + Mm(mr.error.norm()) +
                      " = " + Num(mr.error.norm() / mr.sigma, "%.2f") + " σ");
    }
    Style observed;
    observed.colour = kObserved;
    observed.symbol = "circle";
    observed.width = 2;
    traces->push_back(
        view3d::Points("measured: " + Text(set->label()), Columns(seen), hover, observed));
    Style arrow;
    arrow.colour = kResidual;
    arrow.width = 4;
    arrow.group = "residual vectors";
    traces->push_back(view3d::Segments("surface residuals (measured → section)", Columns(seen),
                                       Columns(model), hover, arrow));
  }
}

// Loads applied by the case: tip, point and poke forces, at the view's force scale.
void LoadTraces(const FitCase& fc, const Eigen::Matrix3Xd& shape, const std::vector<double>& arc,
                double L, double metres_per_newton, std::vector<json>* traces) {
  ArrowSet loads;
  if (shape.cols() > 0) loads.Add(shape.col(shape.cols() - 1), fc.load_case.tip_force, "tip force at s = L");
  for (const PointForce& p : fc.load_case.point_forces)
    loads.Add(At(shape, arc, p.s), p.force, "point force at " + Arc(p.s));
  if (fc.load_case.poke) {
    // Drawn ending on the rod: the instrument pushes from outside.
    const Eigen::Vector3d f = fc.load_case.poke->force;
    const double length = std::max(0.02 * L, f.norm() * metres_per_newton);
    const Eigen::Vector3d at = At(shape, arc, fc.load_case.poke->s) - length * f.normalized();
    loads.Add(at, f, "instrument's poke at " + Arc(fc.load_case.poke->s));
  }
  Style load;
  load.colour = kLoad;
  load.width = 6;
  DrawArrows("applied loads", loads, metres_per_newton, 0.02 * L, load, traces);
}

}  // namespace

double DentMagnification(const Eigen::Matrix3Xd& rest, const Eigen::Matrix3Xd& deformed) {
  if (rest.cols() < 3 || rest.cols() != deformed.cols()) return 1.0;
  const Eigen::Vector3d centre = rest.rowwise().mean();
  const double radius = (rest.colwise() - centre).colwise().norm().mean();
  const double largest = (deformed - rest).colwise().norm().maxCoeff();
  if (!(largest > 0) || !(radius > 0) || largest >= 0.1 * radius) return 1.0;
  const double want = 0.2 * radius / largest;
  double k = std::pow(10.0, std::floor(std::log10(want)));
  for (double m : {5.0, 2.0})
    if (m * std::pow(10.0, std::floor(std::log10(want))) <= want) {
      k = m * std::pow(10.0, std::floor(std::log10(want)));
      break;
    }
  return std::max(1.0, k);
}

view3d::View StaticCaseView(const Experiment& /*experiment: the static case is in.cases[c]*/,
                            const FitInput& in, const FitResult& r, size_t c,
                            const std::vector<size_t>& samples, const std::string& id) {
  view3d::View view;
  view.id = id;
  const FitCase& fc = in.cases[c];
  view.title = "Case " + Text(fc.load_case.name) + " in 3-D (drag to turn, scroll to zoom, hover for values)";
  const Eigen::Matrix3Xd& shape = r.shapes[c];
  const std::vector<double> arc = ArcLengths(in, fc.load_case, shape.cols());
  const double L = in.rod.length;
  // The scale of every force arrow of the view: the largest as long as a quarter of the rod.
  double largest = LargestForce(fc, r, c);
  for (size_t k : samples) largest = std::max(largest, LargestForce(in.cases[k], r, k));
  const double metres_per_newton = largest > 0 ? 0.25 * L / largest : 0.0;

  SectionTraces(r, c, &view.traces);
  HeldPoints(fc.load_case, L, &view.traces);
  MeasurementTraces(fc, shape, &view.traces);
  SurfacePointTraces(fc, r, c, &view.traces);
  LoadTraces(fc, shape, arc, L, metres_per_newton, &view.traces);

  // The centre-line, grasp and forces: moving with the slider when the case has samples.
  std::vector<json> moving = MovingPart(in, r, c, L, metres_per_newton, !samples.empty());
  if (!samples.empty()) {
    const int first = static_cast<int>(view.traces.size());
    for (size_t i = 0; i < moving.size(); ++i) view.animated.push_back(first + static_cast<int>(i));
    view.frames.push_back({Text(fc.load_case.name), moving});
    for (size_t k : samples) {
      if (k >= r.shapes.size()) continue;
      const std::string name = DisplayCaseName(in.cases[k].load_case.name);
      const size_t at = name.find("@t=");
      view.frames.push_back({Text(at == std::string::npos ? name : name.substr(at + 3) + " s"),
                             MovingPart(in, r, k, L, metres_per_newton, true)});
    }
    view.slider_prefix = "haptic sample: ";
  }
  view.traces.insert(view.traces.end(), moving.begin(), moving.end());
  return view;
}

bool MovingCaseView(const Experiment& e, const FitResult& r, size_t c,
                    const std::vector<RecordedSample>& samples,
                    const std::vector<RecordedForce>& forces, const std::string& id,
                    view3d::View* view) {
  const FittedRun* run = nullptr;
  for (const FittedRun& tr : r.trajectories)
    if (tr.case_index == static_cast<int>(c) && !tr.t.empty()) run = &tr;
  if (!run) return false;
  const LoadCase& lc = e.scene.cases[c];
  const double L = e.scene.rod.length;
  view->id = id;
  view->title = "Case " + Text(lc.name) + " in 3-D over time (drag to turn, scroll to zoom, slider or ▶ "
                "for the recorded frames)";
  // What stays: the held points at the start, and every recorded sample faintly (the paths).
  HeldPoints(lc, L, &view->traces);
  std::map<std::string, std::vector<const RecordedSample*>> by_entry;
  for (const RecordedSample& s : samples) by_entry[s.entry].push_back(&s);
  for (const auto& [entry, list] : by_entry) {
    std::vector<Eigen::Vector3d> seen;
    for (const RecordedSample* s : list) seen.push_back(s->observed);
    Style paths;
    paths.colour = "#f4a3a3";
    paths.width = 2;
    paths.opacity = 0.6;
    view->traces.push_back(view3d::Points("all recorded samples: " + Text(entry), Columns(seen), {}, paths));
  }
  // What moves: per recorded time, the fitted centre-line, the samples seen then and the
  // model's positions of them, with the residual vectors.
  const int first = static_cast<int>(view->traces.size());
  // 4 traces of the rod and its samples, and with a load cell 2 arrows (shaft and head each).
  const int animated = forces.empty() ? 4 : 8;
  for (int i = 0; i < animated; ++i) view->animated.push_back(first + i);
  double largest = 0.0;
  for (const RecordedForce& f : forces)
    largest = std::max({largest, f.measured.norm(), f.model.allFinite() ? f.model.norm() : 0.0});
  const double metres_per_newton = largest > 0 ? 0.25 * L / largest : 0.0;
  for (size_t k = 0; k < run->t.size(); ++k) {
    const double t = run->t[k];
    std::vector<json> traces;
    Style line;
    line.colour = kFitted;
    line.width = 7;
    traces.push_back(CentreLine("fitted centre-line at t", run->x[k], run->s, line));
    std::vector<Eigen::Vector3d> seen, model;
    std::vector<std::string> hover;
    for (const RecordedSample& s : samples) {
      if (std::abs(s.t - t) > 1e-9 * std::max(1.0, std::abs(t))) continue;
      seen.push_back(s.observed);
      model.push_back(s.model);
      const Eigen::Vector3d e = s.model - s.observed;
      hover.push_back((std::isfinite(s.s) ? "marker at " + Arc(s.s) : std::string("point")) +
                      ", t = " + view3d::TimeLabel(t) +
                      (e.allFinite() ? "<br>residual " + Mm(e.norm()) + " = " +
                                           Num(e.norm() / s.sigma, "%.2f") + " σ"
                                     : std::string()));
    }
    Style observed;
    observed.colour = kObserved;
    observed.symbol = "circle-open";
    observed.width = 7;
    traces.push_back(view3d::Points("recorded at t", Columns(seen), hover, observed));
    Style predicted;
    predicted.colour = kFitted;
    predicted.symbol = "diamond";
    predicted.width = 5;
    traces.push_back(view3d::Points("predicted at t (fitted run)", Columns(model), hover, predicted));
    Style arrow;
    arrow.colour = kResidual;
    arrow.width = 4;
    traces.push_back(view3d::Segments("residual vectors (recorded → predicted)", Columns(seen),
                                      Columns(model), hover, arrow));
    if (!forces.empty()) {
      // The first load cell reading at this time, at its held point on the run's rod.
      ArrowSet measured, fitted;
      for (const RecordedForce& f : forces) {
        if (std::abs(f.t - t) > 1e-9 * std::max(1.0, std::abs(t))) continue;
        const Eigen::Vector3d at = f.point == "clamp" ? Eigen::Vector3d(run->x[k].col(0))
                                                      : Eigen::Vector3d(run->x[k].col(run->x[k].cols() - 1));
        measured.Add(at, f.measured, "force on the " + Text(f.point) + " read at t = " + view3d::TimeLabel(t));
        if (f.model.allFinite())
          fitted.Add(at, f.model, "force on the " + Text(f.point) + " of the fitted run");
        break;
      }
      Style fm;
      fm.colour = kObserved;
      fm.width = 5;
      DrawArrows("load cell: measured force", measured, metres_per_newton, 0.02 * L, fm, &traces);
      Style ff = fm;
      ff.colour = kFitted;
      DrawArrows("load cell: fitted force", fitted, metres_per_newton, 0.02 * L, ff, &traces);
    }
    view->frames.push_back({view3d::TimeLabel(t), std::move(traces)});
  }
  view->traces.insert(view->traces.end(), view->frames.front().traces.begin(),
                      view->frames.front().traces.end());
  return true;
}

}  // namespace rodfit
