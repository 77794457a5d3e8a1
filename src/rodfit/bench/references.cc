// The statics rows of `rodfit bench` (docs/cli.md, "bench") whose reference is not a one-line
// closed form: a heavy rod clamped at both ends and a rest-curved anisotropic rod in 3-D, both
// against the independent shooting solver of the continuous Kirchhoff rod
// (rodfit/reference/kirchhoff_shooting.h); a rod on tissue springs under a point load against
// Hetenyi's beam on an elastic foundation; and the cross-section ring under a point load against
// the thin-ring closed form.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "rodfit/bench/bench.h"
#include "rodfit/reference/kirchhoff_shooting.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/ring.h"
#include "rodfit/solve/statics.h"

namespace bench {
namespace {

namespace ref = rodfit_reference;
using rodfit::Vec3;

constexpr double kPi = 3.14159265358979323846;

Row NewRow(const std::string& problem, const std::string& family, const std::string& setting,
           const std::string& unit) {
  Row row;
  row.problem = problem;
  row.family = family;
  row.setting = setting;
  row.error_unit = unit;
  return row;
}

// The largest distance between the vertices and the reference centre-line at the vertices' rest
// arc lengths, / L.
double MaxVertexError(const rodfit::CaseSolution& sol, const ref::ShootingResult& r, double L) {
  double worst = 0.0;
  for (int i = 0; i < sol.model->num_vertices(); ++i)
    worst = std::max(worst, (sol.state.x.col(i) - r.PositionAt(sol.model->arc_length(i))).norm());
  return worst / L;
}

// Runs a scene's one case `repeats` times; fills the row's time and solver figures.
rodfit::CaseSolution SolveTimed(const rodfit::Scene& scene, int repeats, Row* row) {
  rodfit::CaseSolution sol;
  Time(repeats, [&] { sol = rodfit::SolveCase(scene, 0, nullptr); }, row);
  row->converged = sol.summary.converged;
  row->stable = sol.summary.stable;
  row->iterations = sol.summary.iterations;
  if (!sol.summary.converged) row->note = sol.summary.reason;
  return sol;
}

// --- heavy rod clamped at both ends --------------------------------------------------------
// L = 1 m, in-plane bending stiffness B2 = 1 N m^2 (B1 = 1.5, GJ = 0.8 act out of the plane),
// EA = 1e6 N, rho g L^3 / B2 = 20, the end clamp at (0.8 L, 0, 0), both clamps heading +x with
// d1 = +z: a visible sag (the middle 0.267 L below the clamps). The same case as
// tests/solve/exact_references_test.cc, whose comment explains why the start is a sag: from the
// straight rod the solve may reach the hogging arch, a second genuine equilibrium.
constexpr double kSpan = 0.8;

rodfit::Scene ClampedClampedScene(int segments) {
  rodfit::Scene s;
  s.rod.length = 1.0;
  s.rod.segments = segments;
  s.rod.radius = 0.01;
  s.rod.linear_density = 1.0;
  s.material.bend_stiffness = 1.5;
  s.material.bend_stiffness_2 = 1.0;
  s.material.twist_stiffness = 0.8;
  s.material.stretch_stiffness = 1e6;
  s.gravity = Vec3(0, 0, -20.0);
  rodfit::LoadCase c;
  c.name = "sag";
  c.end_clamp = rodfit::EndClamp{Vec3(kSpan, 0, 0), Vec3::UnitX(), Vec3::UnitZ()};
  // The start: a cosine dip of 0.25 L between the clamps (its chord lengths are scaled to L),
  // chosen without the reference, so that the solve starts near the sagging branch.
  const int m = 50;
  Eigen::Matrix3Xd pts(3, m + 1);
  for (int k = 0; k <= m; ++k) {
    const double x = kSpan * k / m;
    pts.col(k) = Vec3(x, 0, -0.125 * (1 - std::cos(2 * kPi * x / kSpan)));
  }
  c.start.kind = rodfit::StartShape::Kind::kPoints;
  c.start.points = pts;
  s.cases.push_back(c);
  return s;
}

// The shooting solver's rod: the scene's length, stiffnesses, rest curvature and weight.
ref::RodProperties ShootingProperties(const rodfit::Scene& s) {
  ref::RodProperties p;
  p.length = s.rod.length;
  p.B1 = s.material.bend_stiffness;
  p.B2 = s.material.B2();
  p.GJ = s.material.twist_stiffness;
  p.EA = s.material.stretch_stiffness;
  p.rest_curvature = s.rod.rest_curvature;
  p.linear_density = s.rod.linear_density;
  p.gravity = s.gravity;
  return p;
}

// Shooting at 2000 RK4 steps in 4 segments, continued from an arc in 10 steps (20, as in
// tests/solve/exact_references_test.cc, give the same solution to 1e-15 L; its self-test in
// tests/reference checks the solution's mirror symmetry): 4000 steps change it by < 1e-13 L, far
// below the finest row.
const ref::ShootingResult& ClampedClampedReference() {
  static const ref::ShootingResult r = [] {
    const rodfit::Scene s = ClampedClampedScene(2);
    ref::RodProperties p = ShootingProperties(s);
    ref::ShootingOptions o;
    o.steps = 2000;
    o.segments = 4;
    o.continuation_steps = 10;
    Eigen::Matrix<double, 6, 1> guess;
    guess << 0, 0, 0, 0, -3.0, 0;  // a clamp moment that bends the rod downwards
    return ref::SolveKirchhoff(
        p, ref::ClampSpec(),
        ref::EndCondition::Clamp(Vec3(kSpan, 0, 0), Vec3::UnitX(), Vec3::UnitZ()), o, &guess);
  }();
  return r;
}

// --- a rest-curved anisotropic rod in 3-D ---------------------------------------------------
// B1 = 1, B2 = 2, GJ = 0.7 N m^2, EA = 1e6 N, rest curvature (0.6, -0.9, 0.4) / m, a clamp
// tilted out of every coordinate plane, a dead tip force (0.3, -0.5, -1.2) N and moment
// (0.5, -0.8, 0.6) N m and its weight (rho = 0.1 kg/m, g = 9.81 m/s^2): no plane, no symmetry.
rodfit::Scene RestCurvedScene(int segments) {
  rodfit::Scene s;
  s.rod.length = 1.0;
  s.rod.segments = segments;
  s.rod.radius = 0.01;
  s.rod.linear_density = 0.1;
  s.rod.rest_curvature = Vec3(0.6, -0.9, 0.4);
  s.material.bend_stiffness = 1.0;
  s.material.bend_stiffness_2 = 2.0;
  s.material.twist_stiffness = 0.7;
  s.material.stretch_stiffness = 1e6;
  s.gravity = Vec3(0, 0, -9.81);
  rodfit::LoadCase c;
  c.name = "3d";
  c.clamp.position = Vec3(0.1, -0.2, 0.3);
  c.clamp.tangent = Vec3(1, 0.3, -0.2);
  c.clamp.normal = Vec3(0, 0.2, 1);
  c.tip_force = Vec3(0.3, -0.5, -1.2);
  c.tip_moment = Vec3(0.5, -0.8, 0.6);
  s.cases.push_back(c);
  // Start from the rest shape (from the straight rod this rest-curved case may fail: see
  // tests/solve/exact_references_test.cc).
  const rodfit::RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
  s.cases[0].start.kind = rodfit::StartShape::Kind::kPoints;
  s.cases[0].start.points = model.RestState().x;
  s.cases[0].start.s = model.arc_lengths();
  return s;
}

// Shooting at 1000 RK4 steps with 8 continuation steps; 4000 steps change it by ~1e-14 L.
const ref::ShootingResult& RestCurvedReference() {
  static const ref::ShootingResult r = [] {
    const rodfit::Scene s = RestCurvedScene(2);
    ref::RodProperties p = ShootingProperties(s);
    ref::ClampSpec clamp;
    clamp.position = s.cases[0].clamp.position;
    clamp.tangent = s.cases[0].clamp.tangent;
    clamp.normal = s.cases[0].clamp.normal;
    ref::ShootingOptions o;
    o.steps = 1000;
    o.continuation_steps = 8;
    return ref::SolveKirchhoff(
        p, clamp, ref::EndCondition::Free(s.cases[0].tip_force, s.cases[0].tip_moment), o);
  }();
  return r;
}

Row AgainstShooting(const std::string& problem, const rodfit::Scene& scene,
                    const ref::ShootingResult& reference, const std::string& note, int repeats) {
  Row row = NewRow(problem, "segments", "n=" + std::to_string(scene.rod.segments), "L");
  try {
    if (!reference.converged) {
      row.error = NAN;
      row.note = "reference did not converge: " + reference.message;
      return row;
    }
    const rodfit::CaseSolution sol = SolveTimed(scene, repeats, &row);
    row.error = MaxVertexError(sol, reference, scene.rod.length);
    if (sol.summary.converged) row.note = note;
  } catch (const std::exception& e) {
    row.note = e.what();
  }
  return row;
}

}  // namespace

Row HeavyClampedClamped(int segments, int repeats) {
  return AgainstShooting("clamped_clamped_sag", ClampedClampedScene(segments),
                         ClampedClampedReference(),
                         "rho g L^3/B = 20, span 0.8 L, sag start; reference: Kirchhoff shooting",
                         repeats);
}

Row RestCurved3D(int segments, int repeats) {
  return AgainstShooting("rest_curved_3d", RestCurvedScene(segments), RestCurvedReference(),
                         "B2 = 2 B1, rest curvature, tip force, moment and weight; reference: "
                         "Kirchhoff shooting",
                         repeats);
}

// Hetenyi, "Beams on Elastic Foundation" (1946): an infinite beam of bending stiffness B on a
// Winkler foundation of modulus K [N/m^2] under a point load P deflects by
// w(x) = P beta / (2 K) exp(-beta |x|) (cos beta |x| + sin beta |x|), beta = (K / (4 B))^(1/4).
// Here B = 1 N m^2, beta = 7.5 / m, the rod L = 4 m on springs along its whole length, clamped at
// s = 0 (as every rodfit rod) and loaded at s = L/2: both ends 15 / beta from the load, where the
// infinite beam's deflection and slope have fallen by exp(-15) = 3e-7, the floor of this ladder
// set by the finite rod. P = 0.1 N: peak 3.0e-5 m, slopes at most P beta^2 / K e^(-pi/4)
// sin(pi/4) = 1.4e-4, so the geometric nonlinearity (relative ~ slope^2) is ~2e-8, below that
// floor. Error: max over the vertices of |w - w_exact| / the exact peak.
Row WinklerPointLoad(int segments, int repeats) {
  Row row = NewRow("winkler_point_load", "segments", "n=" + std::to_string(segments), "relative");
  const double B = 1.0, beta = 7.5, K = 4 * B * std::pow(beta, 4), L = 4.0, P = 0.1;
  try {
    rodfit::RodSpec rod;
    rod.length = L;
    rod.segments = segments;
    rod.radius = 0.01;
    rodfit::Material material;
    material.bend_stiffness = B;
    material.twist_stiffness = 1.0 / 1.3;
    material.stretch_stiffness = 1e8;
    material.spring_stiffness = K;
    rodfit::LoadCase load_case;
    load_case.clamp.tangent = Vec3::UnitX();
    load_case.clamp.normal = Vec3::UnitZ();
    load_case.point_forces.push_back({L / 2, Vec3(0, 0, -P)});
    const rodfit::RodModel model(rod, material, Vec3::Zero(), load_case, {{0.0, L, ""}});
    rodfit::RodState state;
    rodfit::StaticsSummary summary;
    Time(repeats, [&] {
      state = model.StraightState();
      summary = rodfit::SolveStatics(model, rodfit::StaticsOptions(), &state);
    }, &row);
    row.converged = summary.converged;
    row.stable = summary.stable;
    row.iterations = summary.iterations;
    const double peak = P * beta / (2 * K);
    double worst = 0.0;
    for (int i = 0; i <= model.num_edges(); ++i) {
      const double x = std::abs(model.arc_length(i) - L / 2);
      const double exact = peak * std::exp(-beta * x) * (std::cos(beta * x) + std::sin(beta * x));
      worst = std::max(worst, std::abs(-state.x(2, i) - exact));
    }
    row.error = worst / peak;
    row.note = summary.converged ? "beta = 7.5/m, L = 30/beta, P = 0.1 N; Hetenyi (1946)"
                                 : summary.reason;
  } catch (const std::exception& e) {
    row.note = e.what();
  }
  return row;
}

// The cross-section ring (R = 1 m, bend stiffness EI = 1 N m^2, stretch EA = 1e7 N) under an
// inward point load P at node 0, held as a poke holds it (the mass centre and rotation fixed:
// the load is balanced by a uniform body force). Linear thin-ring theory gives the change of
// the diameter along the load line -(pi/8 - 1/pi) P R^3 / EI and across it (1/pi - 1/4) P R^3 /
// EI: Roark's Formulas for Stress and Strain, thin-ring table, "ring supported at the base and
// loaded by its own weight" (Delta D_V = -0.4674 w R^4 / EI, Delta D_H = +0.4292 w R^4 / EI with
// w = P / (2 pi R)); the stretch adds -P R / (pi EA) to both. P = 1e-6 EI / R^2: the geometric
// nonlinearity is ~1e-6 relative, the floor of this ladder (the stretch's other corrections are
// O(EI / (EA R^2)) = 1e-7). Error: the larger relative error of the two diameter changes.
Row RingPointLoad(int nodes, int repeats) {
  Row row = NewRow("ring_point_load", "nodes", "N=" + std::to_string(nodes), "relative");
  const double R = 1.0, EI = 1.0, EA = 1e7, P = 1e-6 * EI / (R * R);
  try {
    rodfit::SectionSpec spec;
    spec.radius = R;
    spec.nodes = nodes;
    rodfit::RingSolveOptions options;
    options.compute_sensitivities = false;  // the solve only
    rodfit::RingResult r;
    Time(repeats, [&] { r = rodfit::SolveRing(spec, {EI, EA}, Eigen::Vector2d(-P, 0), options); },
         &row);
    row.converged = r.summary.converged;
    row.stable = r.summary.stable;
    row.iterations = r.summary.iterations;
    const double along = -(kPi / 8 - 1 / kPi) * P * R * R * R / EI - P * R / (kPi * EA);
    const double across = (1 / kPi - 0.25) * P * R * R * R / EI - P * R / (kPi * EA);
    const int N = nodes;
    const double d_along = (r.nodes.col(0) - r.nodes.col(N / 2)).norm() - 2 * R;
    const double d_across = (r.nodes.col(N / 4) - r.nodes.col(3 * N / 4)).norm() - 2 * R;
    row.error = std::max(std::abs(d_along / along - 1), std::abs(d_across / across - 1));
    row.note = r.summary.converged ? "R = 1 m, P = 1e-6 EI/R^2; thin-ring closed form (Roark)"
                                   : r.summary.BriefReport();
  } catch (const std::exception& e) {
    row.note = e.what();
  }
  return row;
}

}  // namespace bench
