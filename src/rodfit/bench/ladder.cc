// `rodfit bench`'s ladder and stress suite (bench.h; docs/cli.md, "bench"): reference problems
// with exact answers solved over a ladder of settings, each row its error against the exact
// answer, its time (median of repeats, with the spread), iterations, converged and stable; the
// stress suite, where a wrong answer returned as success is a row marked WRONG; and the tables
// and pages the rows are written as.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "rodfit/bench/bench.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/reference/cantilever_modes.h"
#include "rodfit/report/svg_plot.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "rodfit/version.h"

namespace {

using rodfit::Vec3;

using bench::Row;
using bench::Time;
using bench::Print;

// An isotropic cantilever (L = 1 m, B = 1 N m^2, GJ = 1/1.3, EA = 1e6 N unless changed) clamped
// at the origin along x with d1 = z.
struct Rod {
  rodfit::RodSpec rod;
  rodfit::Material material;
  rodfit::LoadCase load_case;
  explicit Rod(int segments) {
    rod.length = 1.0;
    rod.segments = segments;
    rod.radius = 0.01;
    material.bend_stiffness = 1.0;
    material.twist_stiffness = 1.0 / 1.3;
    material.stretch_stiffness = 1e6;
    load_case.clamp.tangent = Vec3::UnitX();
    load_case.clamp.normal = Vec3::UnitZ();
  }
};

// The exact centre-line of an isotropic rod under a dead end moment M (no other load): the
// internal moment is M everywhere, so d3' = (M / B) x d3, a helix about M (a circle when M is
// normal to the clamp tangent): x(s) = (d.m) m s + sin(k s)/k (d - (d.m) m) + (1 - cos k s)/k
// (m x d), m = M / |M|, k = |M| / B, d the clamp tangent.
Vec3 HelixPoint(const Vec3& d, const Vec3& M, double B, double s) {
  const double k = M.norm() / B;
  const Vec3 m = M.normalized();
  const Vec3 along = d.dot(m) * m;
  return along * s + std::sin(k * s) / k * (d - along) + (1.0 - std::cos(k * s)) / k * m.cross(d);
}

// Statics of an end-moment rod: error = max vertex distance to the exact helix / L.
Row EndMoment(const std::string& problem, const std::string& family, const std::string& setting,
              Rod r, const Vec3& moment, const rodfit::StaticsOptions& options, int repeats) {
  Row row;
  row.problem = problem;
  row.family = family;
  row.setting = setting;
  row.error_unit = "L";
  r.load_case.tip_moment = moment;
  try {
    const rodfit::RodModel model(r.rod, r.material, Vec3::Zero(), r.load_case);
    rodfit::RodState state;
    rodfit::StaticsSummary summary;
    Time(repeats, [&] {
      state = model.StraightState();
      summary = rodfit::SolveStatics(model, options, &state);
    }, &row);
    row.converged = summary.converged;
    row.stable = summary.stable;
    row.iterations = summary.iterations;
    double worst = 0.0;
    for (int i = 0; i <= model.num_edges(); ++i) {
      const Vec3 exact = HelixPoint(Vec3::UnitX(), moment, r.material.B1(), model.arc_length(i));
      worst = std::max(worst, (state.x.col(i) - exact).norm());
    }
    row.error = worst / r.rod.length;
    if (!summary.converged) row.note = summary.reason;
  } catch (const std::exception& e) {
    row.note = e.what();
  }
  return row;
}

// Mattiasson's large-deflection cantilever (a dead tip force P = alpha B / L^2 across a
// horizontal cantilever): the tip's deflection w / L and shortening u / L from Mattiasson
// (1981), Int. J. Numer. Meth. Eng. 17, Table 1 (5 digits, so errors below ~1e-5 L are the
// table's). Error: the tip's distance to the tabulated point / L.
struct MattiassonPoint {
  double alpha, w, u;
};
constexpr MattiassonPoint kMattiasson[] = {{1, 0.30172, 0.05643}, {3, 0.60325, 0.25442},
                                           {5, 0.71379, 0.38763}, {10, 0.81061, 0.55500}};

Row Mattiasson(const std::string& family, const std::string& setting, Rod r,
               const MattiassonPoint& point, int repeats) {
  Row row;
  row.problem = "mattiasson_alpha" + std::to_string(static_cast<int>(point.alpha));
  row.family = family;
  row.setting = setting;
  row.error_unit = "L";
  const double L = r.rod.length;
  r.load_case.tip_force = Vec3(0, 0, -point.alpha * r.material.B1() / (L * L));
  try {
    const rodfit::RodModel model(r.rod, r.material, Vec3::Zero(), r.load_case);
    rodfit::RodState state;
    rodfit::StaticsSummary summary;
    Time(repeats, [&] {
      state = model.StraightState();
      summary = rodfit::SolveStatics(model, rodfit::StaticsOptions(), &state);
    }, &row);
    row.converged = summary.converged;
    row.stable = summary.stable;
    row.iterations = summary.iterations;
    const Vec3 tip = state.x.col(model.num_edges());
    row.error = (tip - Vec3(L * (1 - point.u), 0, -L * point.w)).norm() / L;
    if (!summary.converged) row.note = summary.reason;
  } catch (const std::exception& e) {
    row.note = e.what();
  }
  return row;
}

// --- dynamics: the first bending mode of a cantilever (the suture of data/scenes) ---

using rodfit::reference::Suture;

// The rod bent into mode 1 (tip ~2e-5 m), edges at their rest lengths.
rodfit::RodState ModeState(const rodfit::RodModel& model) {
  rodfit::RodState q;
  rodfit::reference::CantileverModeState(model, 0, 1e-5, &q);
  return q;
}

// Free vibration for `periods`: the period from downward zero crossings of the modal
// coordinate, and the mean logarithmic decrement between successive maxima.
struct Vibration {
  double period = 0.0, decrement = 0.0;
  bool ok = false;
  std::string reason;
  int newton = 0;
};

Vibration Vibrate(const rodfit::RodModel& model, rodfit::DynamicsOptions options, double periods,
                  double period) {
  Vibration out;
  rodfit::DynamicsStepper stepper(model, options);
  rodfit::DynamicState s = stepper.AtRest(ModeState(model));
  const double dt = options.time_step;
  double first = -1.0, last = 0.0, p1 = 0.0, p2 = 0.0;
  int crossings = 0;
  std::vector<double> peaks;
  const int steps = static_cast<int>(std::lround(periods * period / dt));
  for (int k = 0; k < steps; ++k) {
    double p = 0.0;
    for (int i = 1; i <= model.num_edges(); ++i)
      p += model.vertex_mass(i) * s.q.x(2, i) *
           rodfit::reference::CantileverModeShape(0, model.arc_length(i) / model.length());
    if (k > 0 && p1 > 0 && p <= 0) {
      const double tc = s.t - dt * p / (p - p1);
      if (first < 0) {
        first = tc;
      } else {
        last = tc;
        ++crossings;
      }
    }
    if (k > 1 && p1 >= p2 && p1 > p && p1 > 0) {
      const double den = p2 - 2 * p1 + p;
      peaks.push_back(p1 - 0.125 * (p2 - p) * (p2 - p) / den);
    }
    p2 = p1;
    p1 = p;
    const rodfit::DynamicsStepSummary r = stepper.Step(rodfit::Drive(), &s);
    if (!r.ok) {
      out.reason = r.reason;
      return out;
    }
    out.newton += r.newton_iterations;
  }
  out.ok = crossings > 0;
  out.period = crossings > 0 ? (last - first) / crossings : 0.0;
  if (peaks.size() >= 2)
    out.decrement = std::log(peaks.front() / peaks.back()) / (peaks.size() - 1);
  return out;
}

Row Frequency(const std::string& integrator, double dt_fraction, bool quick) {
  Row row;
  row.problem = "cantilever_frequency";
  row.family = integrator;
  row.error_unit = "relative";
  const Suture suture(50);
  const rodfit::RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  const double period = 2 * M_PI / suture.Omega(0);
  rodfit::DynamicsOptions options;
  rodfit::ParseIntegrator(integrator, &options.integrator);
  if (options.integrator == rodfit::Integrator::kExplicit) {
    rodfit::DynamicsStepper probe(model, options);
    options.time_step = 0.8 * probe.StableTimeStep(ModeState(model));
    char text[64];
    std::snprintf(text, sizeof(text), "dt=%.3g s (0.8 x stable)", options.time_step);
    row.setting = text;
  } else {
    options.time_step = period * dt_fraction;
    char text[64];
    std::snprintf(text, sizeof(text), "dt=T/%.0f", 1.0 / dt_fraction);
    row.setting = text;
  }
  Vibration v;
  Time(quick ? 1 : 3, [&] { v = Vibrate(model, options, 1.3, period); }, &row);
  row.converged = v.ok;
  row.stable = v.ok;
  row.iterations = v.newton;
  row.error = v.ok ? std::abs(v.period / period - 1.0) : NAN;
  row.note = v.reason.empty() ? "Euler-Bernoulli beta1 L = 1.875104; 50 segments" : v.reason;
  return row;
}

Row Decay(const std::string& integrator, double dt_fraction) {
  Row row;
  row.problem = "damped_decay";
  row.family = integrator;
  row.error_unit = "relative";
  Suture suture(50);
  const double omega = suture.Omega(0), period = 2 * M_PI / omega, zeta = 0.02;
  suture.material.damping = 2 * zeta * suture.rod.linear_density * omega;
  const rodfit::RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  rodfit::DynamicsOptions options;
  rodfit::ParseIntegrator(integrator, &options.integrator);
  options.time_step = period * dt_fraction;
  char text[64];
  std::snprintf(text, sizeof(text), "dt=T/%.0f", 1.0 / dt_fraction);
  row.setting = text;
  Vibration v;
  Time(1, [&] { v = Vibrate(model, options, 4.2, period); }, &row);
  const double expected = 2 * M_PI * zeta / std::sqrt(1 - zeta * zeta);
  row.converged = v.ok;
  row.stable = v.ok;
  row.iterations = v.newton;
  row.error = v.ok ? std::abs(v.decrement / expected - 1.0) : NAN;
  row.note = "log decrement vs 2 pi zeta / sqrt(1 - zeta^2), zeta = 0.02 (drag)";
  return row;
}

// The suture swing: the suture of data/scenes (50 segments) released horizontal under gravity,
// its centre-line after 0.2 s (a large-rotation swing down) against a reference solution: the
// midpoint rule at dt = 1e-5 s, 25 times finer than the ladder's finest step. The ladder's
// errors fall at least in proportion to dt, so the reference's own error is below 1/25 of the
// finest row's. Error: max vertex distance / L.
constexpr double kSwingDuration = 0.2;  // [s]

rodfit::Mat3X Swing(const rodfit::RodModel& model, rodfit::DynamicsOptions options,
                    Vibration* status) {
  rodfit::DynamicsStepper stepper(model, options);
  rodfit::DynamicState s = stepper.AtRest(model.StraightState());
  const int steps = static_cast<int>(std::lround(kSwingDuration / options.time_step));
  for (int k = 0; k < steps; ++k) {
    const rodfit::DynamicsStepSummary r = stepper.Step(rodfit::Drive(), &s);
    if (!r.ok) {
      status->reason = r.reason;
      return s.q.x;
    }
    status->newton += r.newton_iterations;
  }
  status->ok = true;
  return s.q.x;
}

struct SwingReference {
  rodfit::Mat3X x;
  bool ok = false;
};

Row SutureSwing(const std::string& integrator, double dt, const SwingReference& reference,
               bool quick, int segments = 50) {
  Row row;
  row.problem = "suture_swing";
  row.family = integrator;
  row.error_unit = "L";
  const Suture suture(segments);
  const rodfit::RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), suture.load_case);
  rodfit::DynamicsOptions options;
  rodfit::ParseIntegrator(integrator, &options.integrator);
  char text[64];
  if (options.integrator == rodfit::Integrator::kExplicit) {
    rodfit::DynamicsStepper probe(model, options);
    options.time_step = 0.8 * probe.StableTimeStep(model.StraightState());
    std::snprintf(text, sizeof(text), "dt=%.3g s (0.8 x stable)", options.time_step);
  } else {
    options.time_step = dt;
    std::snprintf(text, sizeof(text), "dt=%.3g s", dt);
  }
  row.setting = text;
  Vibration v;
  rodfit::Mat3X x;
  Time(quick ? 1 : 3, [&] {
    v = Vibration();
    x = Swing(model, options, &v);
  }, &row);
  row.converged = v.ok;
  row.stable = v.ok;
  row.iterations = v.newton;
  const bool compared = v.ok && reference.ok && x.cols() == reference.x.cols();
  row.error = compared ? (x - reference.x).colwise().norm().maxCoeff() / suture.rod.length : NAN;
  row.note = v.ok ? "0.2 s of the swing down from horizontal; reference: midpoint at dt = 1e-5 s"
                  : v.reason;
  if (segments != 50) {
    // The cost of a step at other segment counts; no reference solution there.
    row.problem = "suture_swing_cost";
    row.setting = "n=" + std::to_string(segments) + ", " + row.setting;
    if (v.ok) row.note = "0.2 s of the swing; per-step cost only (no reference at this segment count)";
  }
  return row;
}

SwingReference MakeSwingReference() {
  const Suture suture(50);
  const rodfit::RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), suture.load_case);
  rodfit::DynamicsOptions options;
  options.integrator = rodfit::Integrator::kMidpoint;
  options.time_step = 1e-5;
  Vibration v;
  SwingReference r;
  r.x = Swing(model, options, &v);
  r.ok = v.ok;
  return r;
}

// Rows are printed as they come (a full ladder takes minutes).
struct Rows {
  std::vector<Row> rows;
  void push_back(const Row& r) {
    Print(r);
    rows.push_back(r);
  }
};

}  // namespace

namespace bench {

std::vector<Row> Ladder(bool quick) {
  Rows rows;
  const int repeats = quick ? 1 : 3;
  std::vector<int> segments = {10, 30, 100, 300, 1000};
  if (!quick) segments.insert(segments.end(), {3000, 10000});
  const Vec3 circle(0, -M_PI, 0);                    // a half circle in the x-z plane
  const Vec3 helix = Vec3(2.0, -3.0, 1.0).normalized() * 4.0;  // |M| L / B = 4 rad
  for (int n : segments) {
    rows.push_back(EndMoment("end_moment_circle", "segments", "n=" + std::to_string(n), Rod(n),
                             circle, rodfit::StaticsOptions(), repeats));
    rows.push_back(EndMoment("end_moment_helix", "segments", "n=" + std::to_string(n), Rod(n),
                             helix, rodfit::StaticsOptions(), repeats));
  }
  for (int n : segments) rows.push_back(Mattiasson("segments", "n=" + std::to_string(n), Rod(n), kMattiasson[1], repeats));
  for (const MattiassonPoint& p : kMattiasson) {
    if (p.alpha != 3) rows.push_back(Mattiasson("alpha (100 segments)", "n=100", Rod(100), p, repeats));
  }
  for (double tol : {1e-4, 1e-6, 1e-9, 1e-12}) {
    rodfit::StaticsOptions o;
    o.gradient_tolerance = tol;
    o.step_tolerance = std::max(tol, 1e-12);
    char text[32];
    std::snprintf(text, sizeof(text), "tol=%.0e", tol);
    rows.push_back(EndMoment("end_moment_helix", "tolerance (300 segments)", text, Rod(300), helix,
                             o, repeats));
  }
  // The references' families: the full segment ladder, or two cheap settings in --quick (two,
  // so that the order of convergence shows). The Winkler rod is 30 / beta long, so its error
  // falls at second order only once a segment is well below 1 / beta: from 100 segments.
  const std::vector<int> reference_segments = quick ? std::vector<int>{30, 100} : segments;
  for (int n : reference_segments) rows.push_back(bench::HeavyClampedClamped(n, repeats));
  for (int n : reference_segments) rows.push_back(bench::RestCurved3D(n, repeats));
  for (int n : quick ? std::vector<int>{100, 300} : segments)
    rows.push_back(bench::WinklerPointLoad(n, repeats));
  const std::vector<int> ring_nodes =
      quick ? std::vector<int>{32, 64} : std::vector<int>{16, 32, 64, 128, 256, 512};
  for (int n : ring_nodes) rows.push_back(bench::RingPointLoad(n, repeats));
  for (const char* integrator : {"bdf2", "midpoint", "backward_euler"}) {
    for (double f : {1.0 / 25, 1.0 / 50, 1.0 / 100, 1.0 / 200}) rows.push_back(Frequency(integrator, f, quick));
    rows.push_back(Decay(integrator, 1.0 / 100));
  }
  if (!quick) rows.push_back(Frequency("explicit", 0.0, quick));
  const SwingReference reference = MakeSwingReference();
  for (const char* integrator : {"bdf2", "midpoint", "backward_euler"})
    for (double dt : {2e-3, 1e-3, 5e-4, 2.5e-4}) rows.push_back(SutureSwing(integrator, dt, reference, quick));
  if (!quick) rows.push_back(SutureSwing("explicit", 0.0, reference, quick));
  for (const char* integrator : {"bdf2", "midpoint", "backward_euler"})
    for (int n : {100, 1000}) rows.push_back(SutureSwing(integrator, 1e-3, reference, quick, n));
  return rows.rows;
}

// The stress suite: each row right (converged and within its tolerance), or failed with a
// message; converged and wrong is WRONG.
std::vector<Row> Stress() {
  Rows rows;
  auto judge = [](Row row, double tolerance, bool must_fail = false) {
    if (must_fail) {
      row.verdict = row.converged ? "WRONG" : "ok";
      if (row.converged) row.note = "converged where it must fail: " + row.note;
    } else if (!row.converged) {
      row.verdict = row.note.empty() ? "WRONG" : "ok";  // a failure must say why
    } else {
      row.verdict = row.error <= tolerance ? "ok" : "WRONG";
    }
    return row;
  };
  const rodfit::StaticsOptions o;
  const Vec3 helix = Vec3(2.0, -3.0, 1.0).normalized() * 4.0;
  for (double ratio : {1e9, 1e12}) {
    Rod r(100);
    r.material.stretch_stiffness = ratio;  // EA L^2 / B
    char text[32];
    std::snprintf(text, sizeof(text), "EA/B=%.0e", ratio);
    Row m = Mattiasson("stress", text, r, kMattiasson[2], 1);
    m.problem = "stiff_stretch_mattiasson";
    rows.push_back(judge(m, 1e-3));
    rows.push_back(judge(EndMoment("stiff_stretch_helix", "stress", text, r, helix, o, 1), 1e-3));
  }
  {
    Rod r(100);
    r.material.twist_stiffness = 1e12;
    rows.push_back(judge(EndMoment("stiff_twist_helix", "stress", "GJ/B=1e12", r, helix, o, 1), 1e-3));
  }
  {
    Row m = Mattiasson("stress", "n=100000", Rod(100000), kMattiasson[2], 1);
    m.problem = "segments_1e5_mattiasson";
    rows.push_back(judge(m, 1e-3));
  }
  rows.push_back(judge(EndMoment("rollup_2pi", "stress", "M L/B=2 pi", Rod(200), Vec3(0, -2 * M_PI, 0), o, 1), 1e-3));
  {
    // An axial tip force 1.5 times Euler's load pi^2 B / (4 L^2) on the straight column: the
    // straight state is a saddle; right = a stable, buckled equilibrium.
    Row row;
    row.problem = "buckling_1.5_euler";
    row.family = "stress";
    row.setting = "P=1.5 P_E";
    row.error_unit = "L";
    Rod r(100);
    r.load_case.tip_force = Vec3(-1.5 * M_PI * M_PI / 4.0, 0, 0);
    const rodfit::RodModel model(r.rod, r.material, Vec3::Zero(), r.load_case);
    rodfit::RodState state = model.StraightState();
    rodfit::StaticsSummary summary;
    Time(1, [&] { summary = rodfit::SolveStatics(model, o, &state); }, &row);
    row.converged = summary.converged;
    row.stable = summary.stable;
    row.iterations = summary.iterations;
    const double lateral = state.x.col(model.num_edges()).tail<2>().norm();
    // A buckled column's tip leaves the axis (exact elastica at 1.5 P_E: ~0.6 L; here only
    // "not straight and stable" is judged).
    row.error = (summary.converged && summary.stable && lateral > 0.1) ? 0.0 : 1.0;
    row.note = summary.converged ? "tip off axis " + std::to_string(lateral) + " L" : summary.reason;
    rows.push_back(judge(row, 0.5));
  }
  {
    Rod r(50);
    rows.push_back(judge(EndMoment("load_1e200", "stress", "M=1e200", r, Vec3(0, -1e200, 0), o, 1), 1e-3, true));
  }
  {
    // The explicit integrator asked for a step 10x its stable step: refused with the limit.
    Row row;
    row.problem = "explicit_above_stable_step";
    row.family = "stress";
    row.setting = "dt=10 x stable";
    row.error_unit = "-";
    const Suture suture(50);
    const rodfit::RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), suture.load_case);
    rodfit::DynamicsOptions options;
    options.integrator = rodfit::Integrator::kExplicit;
    rodfit::DynamicsStepper probe(model, options);
    options.time_step = 10 * probe.StableTimeStep(model.StraightState());
    rodfit::DynamicsStepper stepper(model, options);
    rodfit::DynamicState s = stepper.AtRest(model.StraightState());
    const rodfit::DynamicsStepSummary r = stepper.Step(rodfit::Drive(), &s);
    row.converged = r.ok;
    row.note = r.reason;
    rows.push_back(judge(row, 0.0, true));
  }
  return rows.rows;
}

std::string Csv(const std::vector<Row>& rows) {
  std::string out =
      "problem,family,setting,error,error_unit,time_median_s,time_min_s,time_max_s,iterations,"
      "converged,stable,verdict,note\n";
  for (const Row& r : rows) {
    std::string note;
    for (char c : r.note) note += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
    out += r.problem + "," + r.family + ",\"" + r.setting + "\"," + rodfit::FormatDouble(r.error) +
           "," + r.error_unit + "," + rodfit::FormatDouble(r.t_median) + "," +
           rodfit::FormatDouble(r.t_min) + "," + rodfit::FormatDouble(r.t_max) + "," +
           std::to_string(r.iterations) + "," + (r.converged ? "1" : "0") + "," +
           (r.stable ? "1" : "0") + "," + r.verdict + ",\"" + note + "\"\n";
  }
  return out;
}

// The skips (--skips) as a table: each comparison's two timings, the saving and whether the
// answers agree.
std::string SkipTable(const std::vector<Row>& rows) {
  std::string table;
  for (size_t k = 0; k < rows.size(); ++k) {
    const Row& r = rows[k];
    if (r.problem.rfind("skip/", 0) != 0) continue;
    char cells[256];
    if (r.family == "with skip" && k + 1 < rows.size() && rows[k + 1].family == "without skip") {
      const Row& w = rows[k + 1];
      std::snprintf(cells, sizeof(cells),
                    "<td>%.4g</td><td>%.4g</td><td>%.1f %%</td><td>%.2g %s</td><td>%s</td>",
                    r.t_median, w.t_median, 100.0 * (1.0 - r.t_median / w.t_median), r.error,
                    r.error_unit.c_str(), r.verdict.c_str());
    } else if (r.family == "without skip") {
      continue;
    } else {
      std::snprintf(cells, sizeof(cells), "<td colspan=\"5\">%s</td>", r.verdict.c_str());
    }
    table += "<tr><td>" + rodfit::svg::Escape(r.problem.substr(5)) + "</td><td>" +
             rodfit::svg::Escape(r.setting) + "</td>" + cells + "<td style=\"text-align:left\">" +
             rodfit::svg::Escape(r.note) + "</td></tr>\n";
  }
  if (table.empty()) return "";
  return "<h2>Skips</h2>\n<p>Each skip timed with and without it on the same problem (median "
         "of repeats); max diff is the largest difference between the two answers.</p>\n"
         "<table><tr><th>skip</th><th>problem</th><th>with [s]</th><th>without [s]</th>"
         "<th>saving</th><th>max diff</th><th>answer</th><th>note</th></tr>\n" +
         table + "</table>\n";
}

// Error against time for one problem's rows (those of `family` only, unless empty), one series
// per setting family, log-log.
rodfit::svg::Figure ParetoFigure(const std::vector<Row>& rows, const std::string& problem,
                                 const std::string& family, const std::string& title) {
  const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  rodfit::svg::Figure f;
  f.title = title;
  f.x.label = "time [s]";
  f.x.log = true;
  f.y.log = true;
  std::map<std::string, int> index;
  for (const Row& r : rows) {
    if (r.problem != problem || (!family.empty() && r.family != family)) continue;
    f.y.label = "error [" + r.error_unit + "]";
    if (!index.count(r.family)) {
      index[r.family] = static_cast<int>(f.series.size());
      rodfit::svg::Series s;
      s.label = r.family;
      s.colour = colours[f.series.size() % 6];
      s.marker = rodfit::svg::Marker::kCircle;
      f.series.push_back(s);
    }
    rodfit::svg::Series& s = f.series[index[r.family]];
    s.x.push_back(r.t_median);
    s.y.push_back(r.error);
    s.point_labels.push_back(r.setting);
  }
  return f;
}

// The README's Pareto figure (docs/images/pareto.svg, scripts/performance_table.sh): the
// cantilever (Mattiasson alpha = 3 over the segment ladder) and the suture swing (per
// integrator over the time-step ladder) side by side. Empty without their rows.
std::string ParetoSvg(const std::vector<Row>& rows) {
  const rodfit::svg::Figure left =
      ParetoFigure(rows, "mattiasson_alpha3", "segments", "cantilever (Mattiasson alpha = 3): segments");
  const rodfit::svg::Figure right =
      ParetoFigure(rows, "suture_swing", "", "suture swing, 0.2 s: integrator and time step");
  if (left.series.empty() || right.series.empty()) return "";
  std::string a = rodfit::svg::RenderSvg(left, "cantilever");
  std::string b = rodfit::svg::RenderSvg(right, "swing");
  // The rendered heights (a legend may add to Figure::height), from each <svg>'s attribute.
  auto height = [](const std::string& svg) {
    const size_t at = svg.find("height=\"");
    return at == std::string::npos ? 0 : std::atoi(svg.c_str() + at + 8);
  };
  b.insert(4, " x=\"" + std::to_string(left.width) + "\"");
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" +
         std::to_string(left.width + right.width) + "\" height=\"" +
         std::to_string(std::max(height(a), height(b))) + "\">\n" + a + "\n" + b + "\n</svg>\n";
}

std::string Html(const std::vector<Row>& rows) {
  std::string page =
      "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>rodfit bench</title>"
      "<style>body{font-family:sans-serif;margin:2em}td,th{padding:2px 8px;text-align:right}"
      "</style></head><body>\n<h1>rodfit bench</h1>\n<p>rodfit " +
      rodfit::svg::Escape(RODFIT_VERSION) +
      ". Error against each problem's exact answer against wall time (median of repeats); one "
      "curve per setting family.</p>\n";
  std::map<std::string, std::vector<const Row*>> by_problem;
  std::vector<std::string> order;
  for (const Row& r : rows) {
    if (r.problem.rfind("skip/", 0) == 0) continue;  // a table of their own below
    if (!by_problem.count(r.problem)) order.push_back(r.problem);
    by_problem[r.problem].push_back(&r);
  }
  page += SkipTable(rows);
  const char* colours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  int id = 0;
  // A problem with fewer than two points that a log-log chart can show (one setting, or errors
  // of exactly 0 or not measured) gets no chart, which would be empty or a lone dot: its rows
  // are listed in a table after the charts instead.
  std::vector<const Row*> unplotted;
  for (const std::string& problem : order) {
    int drawable = 0;
    for (const Row* r : by_problem[problem])
      if (std::isfinite(r->error) && r->error > 0 && std::isfinite(r->t_median) && r->t_median > 0)
        ++drawable;
    if (drawable < 2) {
      unplotted.insert(unplotted.end(), by_problem[problem].begin(), by_problem[problem].end());
      continue;
    }
    rodfit::svg::Figure f;
    f.title = problem;
    f.x.label = "time [s]";
    f.x.log = true;
    f.y.label = "error [" + by_problem[problem].front()->error_unit + "]";
    f.y.log = true;
    std::map<std::string, int> family_index;
    for (const Row* r : by_problem[problem]) {
      if (!family_index.count(r->family)) {
        family_index[r->family] = static_cast<int>(f.series.size());
        rodfit::svg::Series s;
        s.label = r->family;
        s.colour = colours[f.series.size() % 6];
        s.marker = rodfit::svg::Marker::kCircle;
        f.series.push_back(s);
      }
      rodfit::svg::Series& s = f.series[family_index[r->family]];
      s.x.push_back(r->t_median);
      s.y.push_back(r->error);
      s.point_labels.push_back(r->setting);
    }
    page += "<h2>" + rodfit::svg::Escape(problem) + "</h2>\n" +
            rodfit::svg::RenderSvg(f, "p" + std::to_string(id++)) + "\n";
  }
  if (!unplotted.empty()) {
    page += "<h2>Problems with fewer than two points to plot</h2>\n<p>Measured at one setting, "
            "or with an error of exactly 0 or not measured (not drawable on log axes):</p>\n"
            "<table><tr><th>problem</th><th>setting</th><th>error</th><th>time [s]</th>"
            "<th>verdict</th></tr>\n";
    for (const Row* r : unplotted) {
      char e[64], t[64];
      std::snprintf(e, sizeof(e), "%.3g %s", r->error, r->error_unit.c_str());
      std::snprintf(t, sizeof(t), "%.3g", r->t_median);
      page += "<tr><td>" + rodfit::svg::Escape(r->problem) + "</td><td>" +
              rodfit::svg::Escape(r->setting) + "</td><td>" + e + "</td><td>" + t + "</td><td>" +
              rodfit::svg::Escape(r->verdict) + "</td></tr>\n";
    }
    page += "</table>\n";
  }
  page += "<h2>All rows</h2>\n<table><tr><th>problem</th><th>setting</th><th>error</th>"
          "<th>time [s]</th><th>iterations</th><th>converged</th><th>verdict</th></tr>\n";
  for (const Row& r : rows) {
    char e[64], t[64];
    std::snprintf(e, sizeof(e), "%.3g %s", r.error, r.error_unit.c_str());
    std::snprintf(t, sizeof(t), "%.3g", r.t_median);
    page += "<tr><td>" + rodfit::svg::Escape(r.problem) + "</td><td>" + rodfit::svg::Escape(r.setting) +
            "</td><td>" + e + "</td><td>" + t + "</td><td>" + std::to_string(r.iterations) +
            "</td><td>" + (r.converged ? "yes" : "no") + "</td><td>" + rodfit::svg::Escape(r.verdict) +
            "</td></tr>\n";
  }
  return page + "</table>\n</body></html>\n";
}

void Print(const Row& r) {
  char line[512];
  std::snprintf(line, sizeof(line), "%-28s %-26s %-24s error %-10.3g %-8s %9.3g s  %s%s%s\n",
                r.problem.c_str(), r.family.c_str(), r.setting.c_str(), r.error,
                r.error_unit.c_str(), r.t_median, r.converged ? "converged" : "failed",
                r.verdict.empty() ? "" : "  ", r.verdict.c_str());
  std::cout << line;
  if (r.verdict == "WRONG") std::cout << "    " << r.note << "\n";
  std::cout.flush();
}

}  // namespace bench

