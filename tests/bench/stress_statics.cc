// The statics stress table: extreme stiffness ratios, a vanishing stiffness, absurd loads,
// 100 to 100,000 segments, a 2 pi roll-up and a column at ten times its Euler load, each solved
// from the straight rod as `rodfit simulate` would and checked against an independent reference
// (the continuous Kirchhoff-rod shooting solver of src/rodfit/reference, or a closed form). Each row
// ends "ok" (converged and right, or refused with a message) or "WRONG" (an answer returned as
// converged that is not the reference's, or stable when it is not); any WRONG row makes the
// program exit 1. Prints a Markdown table (the stress table of docs/performance.md).
// Run: build/stress_statics   (Release build, one core; ~1 minute)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "rodfit/reference/kirchhoff_shooting.h"
#include "../solve/shooting_compare.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit {
namespace {

namespace ref = rodfit_reference;

// A right answer is within this of the reference (relative to L): far above the discretisation
// error at 100 segments (~1e-4 L), far below any other equilibrium or an unloaded rod.
constexpr double kRightAnswer = 1e-2;

struct Row {
  std::string problem;
  int segments = 0;
  std::string converged, stable, error, time, verdict;
};

// A cantilever along +x (d1 = +z) of length 1 m, bending stiffness `ei`, GJ = EI / 1.3 and
// EA = ratio * EI / L^2.
Scene Cantilever(int segments, double ei, double ratio) {
  Scene s;
  s.rod.length = 1.0;
  s.rod.segments = segments;
  s.rod.radius = 0.01;
  s.material.bend_stiffness = ei;
  s.material.twist_stiffness = ei / 1.3;
  s.material.stretch_stiffness = ratio * ei;
  LoadCase c;
  c.name = "c";
  c.clamp.tangent = Vec3::UnitX();
  c.clamp.normal = Vec3::UnitZ();
  s.cases.push_back(c);
  return s;
}

ref::RodProperties Props(const Scene& s) {
  ref::RodProperties p;
  p.length = s.rod.length;
  p.B1 = s.material.B1();
  p.B2 = s.material.B2();
  p.GJ = s.material.twist_stiffness;
  p.EA = s.material.stretch_stiffness;
  p.linear_density = s.rod.linear_density;
  p.gravity = s.gravity;
  return p;
}

std::string Format(const char* fmt, double v) {
  char b[64];
  std::snprintf(b, sizeof(b), fmt, v);
  return b;
}

// Solves the scene's case from straight; `error` maps the solution to its error [L] against the
// reference. `expect_stable` is what a right answer reports (unset: not judged).
Row Run(const std::string& problem, const Scene& s,
        const std::function<double(const CaseSolution&)>& error,
        std::optional<bool> expect_stable = true) {
  Row row;
  row.problem = problem;
  row.segments = s.rod.segments;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const CaseSolution sol = SolveCase(s, 0, nullptr);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    row.time = seconds < 1 ? Format("%.1f ms", 1e3 * seconds) : Format("%.2f s", seconds);
    row.converged = sol.ok() ? "yes" : "no";
    if (!sol.ok()) {
      row.stable = "-";
      row.error = "-";
      row.verdict = "ok: fails with \"" + sol.summary.reason + "\"";
      return row;
    }
    row.stable = sol.summary.stable ? "yes" : "no";
    const double e = error(sol);
    row.error = Format("%.1e L", e);
    const bool right =
        e <= kRightAnswer && (!expect_stable || sol.summary.stable == *expect_stable);
    row.verdict = right ? "ok" : "WRONG";
  } catch (const std::exception& e) {
    row.converged = "refused";
    row.stable = row.error = row.time = "-";
    row.verdict = std::string("ok: \"") + e.what() + "\"";
  }
  return row;
}

// The largest vertex error relative to L.
double RelativeVertexError(const CaseSolution& sol, const ref::ShootingResult& r) {
  return testing::MaxVertexError(sol, r) / sol.model->length();
}

// The shooting reference of a cantilever case with a dead tip force and moment.
ref::ShootingResult Shoot(const Scene& s, int continuation_steps = 1) {
  ref::ShootingOptions o;
  o.continuation_steps = continuation_steps;
  const LoadCase& c = s.cases[0];
  const ref::ShootingResult r = ref::SolveKirchhoff(
      Props(s), testing::RefClamp(c.clamp), ref::EndCondition::Free(c.tip_force, c.tip_moment), o);
  if (!r.converged) std::fprintf(stderr, "reference did not converge: %s\n", r.message.c_str());
  return r;
}

// Complete elliptic integrals K(p), E(p) of modulus p by the arithmetic-geometric mean.
void Elliptic(double p, double* K, double* E) {
  double a = 1.0, b = std::sqrt(1.0 - p * p), sum = 0.5 * p * p, pow2 = 0.5;
  for (int k = 0; k < 40 && std::abs(a - b) > 1e-16 * a; ++k) {
    const double c = 0.5 * (a - b);
    const double an = 0.5 * (a + b);
    b = std::sqrt(a * b);
    a = an;
    pow2 *= 2.0;
    sum += pow2 * c * c;
  }
  *K = M_PI / (2.0 * a);
  *E = *K * (1.0 - sum);
}

}  // namespace
}  // namespace rodfit

int main() {
  using namespace rodfit;
  std::vector<Row> rows;

  // Stiffness ratios: a 3-D tip force F L^2 / EI = (0, 1, -3) on a 100-segment cantilever.
  for (double ratio : {1e4, 1e8, 1e12}) {
    Scene s = Cantilever(100, 1.0, ratio);
    s.cases[0].tip_force = Vec3(0, 1, -3);
    const ref::ShootingResult r = Shoot(s);
    rows.push_back(Run("EA L^2/EI = " + Format("%.0e", ratio) + ", 3-D tip force", s,
                       [&](const CaseSolution& sol) { return RelativeVertexError(sol, r); }));
  }
  // A vanishing stiffness: EI = 1e-12 N m^2 with the same dimensionless loads.
  {
    Scene s = Cantilever(100, 1e-12, 1e6);
    s.cases[0].tip_force = Vec3(0, 1, -3) * 1e-12;
    const ref::ShootingResult r = Shoot(s);
    rows.push_back(Run("EI = 1e-12 N m^2, same loads / EI", s,
                       [&](const CaseSolution& sol) { return RelativeVertexError(sol, r); }));
  }
  // Absurd loads: a 1e200 N tip force cannot be represented in the energy.
  {
    Scene s = Cantilever(100, 1.0, 1e6);
    s.cases[0].tip_force = Vec3(0, 0, -1e200);
    rows.push_back(Run("tip force 1e200 N", s, [](const CaseSolution&) { return INFINITY; }));
  }
  // Fine rods: a heavy, anisotropic, tilted 3-D cantilever with a sideways tip force.
  auto heavy = [](int n) {
    Scene s = Cantilever(n, 1.0, 1e6);
    s.rod.linear_density = 0.2;
    s.gravity = Vec3(0, 0, -9.81);
    s.material.bend_stiffness_2 = 1.4;
    s.cases[0].clamp.tangent = Vec3(std::cos(0.4), 0, std::sin(0.4));
    s.cases[0].tip_force = Vec3(0, 1.0, 0);
    return s;
  };
  const ref::ShootingResult heavy_reference = Shoot(heavy(100), 4);
  for (int n : {100, 10000, 100000}) {
    rows.push_back(Run("heavy 3-D cantilever", heavy(n), [&](const CaseSolution& sol) {
      return RelativeVertexError(sol, heavy_reference);
    }));
  }
  // 2 pi roll-up: an isotropic rod under the end moment 2 pi EI / L closes a circle (the shooting
  // reference is that circle to 3e-15 L). A dead moment is not conservative in 3-D, so "stable"
  // (the symmetric part of the tangent positive definite) is reported, not judged: it is not
  // the criterion for a non-conservative load.
  {
    Scene s = Cantilever(100, 1.0, 1e6);
    s.cases[0].tip_moment = Vec3(0, -2 * M_PI, 0);
    const ref::ShootingResult r = Shoot(s);
    rows.push_back(Run("2 pi roll-up (end moment)", s,
                       [&](const CaseSolution& sol) { return RelativeVertexError(sol, r); },
                       std::nullopt));
  }
  // A column at 10 x its Euler load (clamped-free, P_cr = pi^2 EI / 4 L^2): the straight column
  // is a saddle; the answer is the buckled elastica. Closed form (Timoshenko & Gere, "Theory of
  // Elastic Stability", sec. 2.7): k = sqrt(P / EI), p = sin(theta_tip / 2) with K(p) = k L;
  // the tip lies 2 p / k off the axis and at L (2 E(p) / K(p) - 1) along it.
  {
    Scene s = Cantilever(100, 1.0, 1e6);
    const double P = 10.0 * M_PI * M_PI / 4.0;
    s.cases[0].tip_force = Vec3(-P, 0, 0);
    const double kL = std::sqrt(P);
    double lo = 0.0, hi = 1.0 - 1e-15;
    for (int it = 0; it < 200; ++it) {  // K(p) grows from pi/2 to infinity on [0, 1)
      const double mid = 0.5 * (lo + hi);
      double K, E;
      Elliptic(mid, &K, &E);
      (K < kL ? lo : hi) = mid;
    }
    double K, E;
    Elliptic(lo, &K, &E);
    const double lateral = 2.0 * lo / kL, axial = 2.0 * E / K - 1.0;  // [L]
    rows.push_back(Run("axial compression 10 P_cr", s, [&](const CaseSolution& sol) {
      const Vec3 tip = sol.state.x.col(sol.model->num_edges());
      return std::hypot(std::hypot(tip.y(), tip.z()) - lateral, tip.x() - axial);
    }));
  }

  std::printf("| problem | segments | converged | stable | error vs reference | time | verdict |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  bool wrong = false;
  for (const Row& r : rows) {
    std::printf("| %s | %d | %s | %s | %s | %s | %s |\n", r.problem.c_str(), r.segments,
                r.converged.c_str(), r.stable.c_str(), r.error.c_str(), r.time.c_str(),
                r.verdict.c_str());
    wrong = wrong || r.verdict == "WRONG";
  }
  return wrong ? 1 : 0;
}
