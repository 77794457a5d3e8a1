// Validation of the discrete statics against exact and independent references, in full 3-D:
// closed forms (the isotropic helix, Euler's critical loads) and the continuous Kirchhoff-rod
// shooting solver of src/rodfit/reference/kirchhoff_shooting.h (RK4 + Newton, written independently
// of the discrete rod; its own self-tests are tests/reference/kirchhoff_shooting_test.cc).
//
// Conventions shared by both models (checked in the headers): the clamp has d3 = tangent and
// d1 = Gram-Schmidt(normal); B1 resists rotation about d1, B2 about d2, GJ about d3; body
// curvatures u = (k1, k2, tau) with d_i' = (R u) x d_i, so rest curvature (0, k, 0) bends d3
// towards d1 in both. The discrete vertex i sits at rest arc length model.arc_length(i) and is
// compared with the reference's r(s_i). The discrete rod is extensible (EA); every reference
// solve is given the same EA, so no stretch difference enters the comparison.
//
// Reaction signs: the reference's n(s), m(s) are the force and moment exerted ON [0, s] BY
// (s, L]; at s = 0 that is what the rod exerts on the clamp, so CaseSolution.reactions[0]
// (force, moment exerted BY the rod ON the clamp, moment about the clamp point) should equal
// (n(0), m(0)). At s = L, n(L), m(L) are exerted BY the end holder ON the rod, so the rod's
// reaction on an end clamp is (-n(L), -m(L)) about r(L).
//
// Measured errors are printed ("[measured] ...") so that the margins can be read off a run.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/reference/kirchhoff_shooting.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "shooting_compare.h"

namespace rodfit {
namespace {

namespace ref = rodfit_reference;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using Vector6d = Eigen::Matrix<double, 6, 1>;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// Builders shared by the tests.

struct RodParams {
  double L = 1.0;
  double B1 = 1.0, B2 = 1.0, GJ = 1.0;
  double EA = 1e6;  // EA L^2 / B ~ 1e6: nearly inextensible; the reference gets the same EA
  double rho = 0.0;
  Vector3d gravity = Vector3d::Zero();
  Vector3d rest_curvature = Vector3d::Zero();
};

Scene MakeScene(const RodParams& p, int segments, const Clamp& clamp) {
  Scene s;
  s.rod.length = p.L;
  s.rod.segments = segments;
  s.rod.radius = 0.01 * p.L;
  s.rod.linear_density = p.rho;
  s.rod.rest_curvature = p.rest_curvature;
  s.material.bend_stiffness = p.B1;
  s.material.bend_stiffness_2 = p.B2;
  s.material.twist_stiffness = p.GJ;
  s.material.stretch_stiffness = p.EA;
  s.gravity = p.gravity;
  LoadCase c;
  c.name = "c";
  c.clamp = clamp;
  s.cases.push_back(c);
  return s;
}

ref::RodProperties RefProps(const RodParams& p) {
  ref::RodProperties r;
  r.length = p.L;
  r.B1 = p.B1;
  r.B2 = p.B2;
  r.GJ = p.GJ;
  r.EA = p.EA;
  r.rest_curvature = p.rest_curvature;
  r.linear_density = p.rho;
  r.gravity = p.gravity;
  return r;
}

using testing::MaxVertexError;
using testing::RefClamp;

CaseSolution Solve(const Scene& s) { return SolveCase(s, 0, nullptr); }

const HeldReaction* FindReaction(const CaseSolution& sol, const std::string& point) {
  for (const HeldReaction& h : sol.reactions)
    if (h.point == point) return &h;
  return nullptr;
}

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// ---------------------------------------------------------------------------------------------
// a. Isotropic rod, dead end moment M in a general 3-D direction, no force, no gravity.
// Derivation (Kirchhoff's kinetic analogue: a rod held by terminal couples only takes a helical
// form; A. E. H. Love, "A Treatise on the Mathematical Theory of Elasticity"): with no force n = 0,
// so m' = -r' x n = 0 and m(s) = M everywhere. For B1 = B2 = B, m = B (w - tau d3) + GJ tau d3,
// and d3' = w x d3 = (m x d3) / B = (M x d3) / B: d3 precesses about a = M / |M| at the rate
// W = |M| / B, whatever GJ is. Integrating r' = d3:
//   r(s) = r0 + (a.d30) a s + sin(W s) / W (d30 - (a.d30) a) + (1 - cos(W s)) / W a x d30,
// a helix of axis a. (GJ sets only the spin of d1, d2 about d3, not the centre-line.)
// Tolerance 1e-4 L at 200 segments. Expected discrete error: the discrete bending
// moment conjugate to a vertex's turning phi is (2B/l) tan(phi/2) / cos^2(phi/2) (tan-form
// curvature), so each vertex turns by W l (1 - (W l)^2 / 3 + ...): a relative turning error of
// (W l)^2 / 3 = 5.2e-5 for W L = 2.5, l = L / 200, i.e. a tip rotation error of ~1.3e-4 rad and a
// centre-line error below ~1e-4 L. W L = 2.5 rad (143 degrees of precession) is chosen so that
// this second-order error sits below the 1e-4 L tolerance at 200 segments.
TEST(ExactReferences, IsotropicDeadMomentHelixIndependentOfGJ) {
  RodParams p;
  p.L = 1.2;
  p.B1 = p.B2 = 0.8;
  Clamp clamp;
  clamp.position = Vector3d(0.2, 0.1, -0.4);
  clamp.tangent = Vector3d(1, 2, 0.5);
  clamp.normal = Vector3d(0, 0, 1);
  const double W = 2.5 / p.L;
  const Vector3d a = Vector3d(1.4, -0.3, 2.1).normalized();
  const Vector3d M = W * p.B1 * a;
  const Vector3d d30 = clamp.tangent.normalized();
  ASSERT_GT(std::abs(a.dot(d30)), 0.1);  // a genuine helix: neither perpendicular ...
  ASSERT_LT(std::abs(a.dot(d30)), 0.9);  // ... nor parallel
  auto exact_r = [&](double s) {
    return Vector3d(clamp.position + a.dot(d30) * a * s +
                    std::sin(W * s) / W * (d30 - a.dot(d30) * a) +
                    (1 - std::cos(W * s)) / W * a.cross(d30));
  };
  const int n = 200;
  std::vector<Mat3X> shapes;
  for (double GJ : {0.3, 3.0}) {  // 10x apart
    p.GJ = GJ;
    Scene s = MakeScene(p, n, clamp);
    s.cases[0].tip_moment = M;
    const CaseSolution sol = Solve(s);
    ASSERT_TRUE(sol.ok()) << "GJ " << GJ << ": " << sol.summary.BriefReport();
    double err = 0.0;
    for (int i = 0; i <= n; ++i)
      err = std::max(err, (sol.state.x.col(i) - exact_r(sol.model->arc_length(i))).norm());
    std::printf("[measured] a. helix GJ = %.1f: max vertex error %.3e L (stable %d)\n", GJ,
                err / p.L, sol.summary.stable);
    EXPECT_LT(err, 1e-4 * p.L) << "GJ " << GJ;
    // The clamp carries the end moment unchanged (n = 0): reactions[0] = (n(0), m(0)) = (0, M).
    ASSERT_FALSE(sol.reactions.empty());
    EXPECT_LT(sol.reactions[0].force.norm(), 1e-9 * M.norm() / p.L);
    EXPECT_LT((sol.reactions[0].moment - M).norm(), 1e-9 * M.norm());
    shapes.push_back(sol.state.x);
  }
  // The centre-line does not depend on GJ; in the discrete rod the two differ only by the
  // discretisation error's dependence on GJ (bounded by the sum of the two errors above).
  const double gj_diff = (shapes[0] - shapes[1]).colwise().norm().maxCoeff();
  std::printf("[measured] a. helix: GJ 0.3 vs 3.0 max vertex difference %.3e L\n", gj_diff / p.L);
  EXPECT_LT(gj_diff, 1e-4 * p.L);
}

// ---------------------------------------------------------------------------------------------
// b. Anisotropic (B2 = 2 B1), rest-curved (k1, k2, tau all nonzero), general 3-D clamp, dead tip
// moment; in the second case also a tip force and gravity. Reference: SolveKirchhoff kFree
// (dead F, M) with the same B1, B2, GJ, EA and rest curvature.
// Tolerance 2e-3 L on every vertex at 100 segments (the discrete rod is second
// order, so the expected error is O((L / 100)^2 |u|^2 L); measured ~1e-5 L).
// Reactions: the clamp force is the total load in both models (exact statics), so it must agree
// to round-off (1e-9 of the load). The clamp moment is m(0) = M + int_0^L (r(s) - r0) x f ds +
// (r(L) - r0) x F: in the discrete rod it is the same sum over vertex positions (lumped
// weights: trapezoid rule, O(l^2)), so its error is bounded by the position error times the
// total force: |dm| <= 2e-3 L (|F| + rho g L) + 1e-9 |M|.
// The discrete solve starts from the rod's rest shape (start: the centre-line of
// RodModel::RestState()); the default straight start is tested separately below
// (RestCurvedRodWithTipMomentSolvesFromStraightStart), because it fails for the first case.
struct Case3D {
  const char* name;
  RodParams p;
  Clamp clamp;
  Vector3d F, M;
};

std::vector<Case3D> AnisotropicCases() {
  RodParams p;
  p.L = 1.0;
  p.B1 = 1.0;
  p.B2 = 2.0;
  p.GJ = 0.7;
  p.rest_curvature = Vector3d(0.6, -0.9, 0.4);
  Clamp clamp;
  clamp.position = Vector3d(0.1, -0.2, 0.3);
  clamp.tangent = Vector3d(1, 0.3, -0.2);
  clamp.normal = Vector3d(0, 0.2, 1);
  Case3D moment_only{"dead moment", p, clamp, Vector3d::Zero(), Vector3d(0.5, -0.8, 0.6)};
  RodParams heavy = p;
  heavy.rho = 0.1;
  heavy.gravity = Vector3d(0, 0, -9.81);
  Case3D loaded{"dead moment + tip force + gravity", heavy, clamp, Vector3d(0.3, -0.5, -1.2),
                Vector3d(0.5, -0.8, 0.6)};
  return {moment_only, loaded};
}

Scene Case3DScene(const Case3D& c, int n) {
  Scene s = MakeScene(c.p, n, c.clamp);
  s.cases[0].tip_force = c.F;
  s.cases[0].tip_moment = c.M;
  return s;
}

// start: the rest shape's centre-line at the vertices' arc lengths.
void StartFromRestShape(Scene* s) {
  const RodModel model(s->rod, s->material, s->gravity, s->cases[0]);
  s->cases[0].start.kind = StartShape::Kind::kPoints;
  s->cases[0].start.points = model.RestState().x;
  s->cases[0].start.s = model.arc_lengths();
}

TEST(ExactReferences, AnisotropicRestCurvedDeadMomentAgainstShooting) {
  for (const Case3D& c : AnisotropicCases()) {
    SCOPED_TRACE(c.name);
    const auto t0 = std::chrono::steady_clock::now();
    ref::ShootingOptions o;
    o.steps = 1000;  // RK4 at 1000 steps: < 1e-11 L on these smooth shapes (self-tests: 4000
                     // steps are exact to 1e-13), far below the 2e-3 L under test
    o.continuation_steps = 8;
    const ref::ShootingResult r =
        ref::SolveKirchhoff(RefProps(c.p), RefClamp(c.clamp), ref::EndCondition::Free(c.F, c.M), o);
    ASSERT_TRUE(r.converged) << r.message;
    Scene s = Case3DScene(c, 100);
    StartFromRestShape(&s);
    const CaseSolution sol = Solve(s);
    ASSERT_TRUE(sol.ok()) << sol.summary.BriefReport();
    const double err = MaxVertexError(sol, r);
    ASSERT_FALSE(sol.reactions.empty());
    const HeldReaction& cl = sol.reactions[0];
    const double total_force = c.F.norm() + c.p.rho * c.p.gravity.norm() * c.p.L;
    const double df = (cl.force - r.n0).norm(), dm = (cl.moment - r.m0).norm();
    std::printf("[measured] b. %s: max vertex error %.3e L, clamp force error %.2e N "
                "(|n0| %.3f), clamp moment error %.2e N m (|m0| %.3f), stable %d, %.2f s\n",
                c.name, err / c.p.L, df, r.n0.norm(), dm, r.m0.norm(), sol.summary.stable,
                Seconds(t0));
    EXPECT_LT(err, 2e-3 * c.p.L);
    EXPECT_LT(df, 1e-9 * std::max(1.0, total_force));
    EXPECT_LT(dm, 2e-3 * c.p.L * total_force + 1e-9 * c.M.norm());
  }
}

// The same two cases from the default start (the straight rod), as a user would solve them, at
// 20, 50 and 100 segments: each must converge (to the equilibrium the rest-shape start finds,
// within 1e-8 L).
// Why this is a test of its own: from the straight state at full load, a non-symmetric Newton
// with a line search on the residual merit once stalled here at 60-200 segments (the merit
// falling from 4.3e8 only to 3.8e8 with steps cut to 1e-9), and the load continuation failed
// at its first step; the loaded case (tip force and gravity too) converged throughout.
TEST(ExactReferences, RestCurvedRodWithTipMomentSolvesFromStraightStart) {
  for (const Case3D& c : AnisotropicCases()) {
    for (int n : {20, 50, 100}) {
      SCOPED_TRACE(std::string(c.name) + ", " + std::to_string(n) + " segments");
      const Scene straight = Case3DScene(c, n);
      Scene rest = straight;
      StartFromRestShape(&rest);
      const CaseSolution a = Solve(straight);
      const CaseSolution b = Solve(rest);
      ASSERT_TRUE(b.ok()) << b.summary.BriefReport();
      std::printf("[measured] b'. %s, n = %d, straight start: %s\n", c.name, n,
                  a.summary.BriefReport().c_str());
      EXPECT_TRUE(a.ok()) << "straight start: " << a.summary.BriefReport();
      if (a.ok()) {
        EXPECT_LT((a.state.x - b.state.x).colwise().norm().maxCoeff(), 1e-8 * c.p.L);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// c. Heavy rod clamped at both ends (planar elastica): both clamps head +x with normal +z, the
// end clamp at (D, 0, 0) with D = 0.8 L < L, gravity -z, rho g L^3 / EI = 20. In-plane bending
// (about d2 = -y) uses B2 = EI = 1; B1 = 1.5 and GJ = 0.8 act out of the plane. Reference:
// SolveKirchhoff kClamp (4 shooting segments, continuation from an arc; its self-test checks
// the mirror symmetry of this very solution), on the sagging branch.
// Tolerances: vertices 2e-3 L (as b.). End reactions: both are statically indeterminate here
// (they depend on the shape), so they carry the discretisation error of the internal forces,
// which is second order like the positions; we allow 2e-3 of the force scale rho g L (= 20 N)
// and of the moment scale rho g L^2, and check that the errors fall ~4x (> 3x) from 50 to 100
// segments.
// Two starts: (1) the straight rod, as `rodfit simulate` starts (the solver moves the end
// clamp from (L, 0, 0) to (D, 0, 0) by continuation); (2) a sag-shaped guess (a cosine dip of
// 0.25 L, independent of the reference) which selects the sagging branch, so that the
// discretisation accuracy is tested whatever branch (1) lands on.
RodParams ClampedClampedParams() {
  RodParams p;
  p.L = 1.0;
  p.B1 = 1.5;
  p.B2 = 1.0;
  p.GJ = 0.8;
  p.rho = 1.0;
  p.gravity = Vector3d(0, 0, -20.0);
  return p;
}
constexpr double kSpan = 0.8;

const ref::ShootingResult& ClampedClampedReference() {
  static const ref::ShootingResult r = [] {
    ref::ShootingOptions o;
    o.steps = 2000;
    o.segments = 4;
    o.continuation_steps = 20;
    Vector6d guess;
    guess << 0, 0, 0, 0, -3.0, 0;
    return ref::SolveKirchhoff(RefProps(ClampedClampedParams()), ref::ClampSpec(),
                               ref::EndCondition::Clamp(Vector3d(kSpan, 0, 0), Vector3d::UnitX(),
                                                        Vector3d::UnitZ()),
                               o, &guess);
  }();
  return r;
}

Scene ClampedClampedScene(int n, bool sag_start) {
  Scene s = MakeScene(ClampedClampedParams(), n, Clamp());
  s.cases[0].end_clamp = EndClamp{Vector3d(kSpan, 0, 0), Vector3d::UnitX(), Vector3d::UnitZ()};
  if (sag_start) {
    const int m = 50;
    Eigen::Matrix3Xd pts(3, m + 1);
    for (int k = 0; k <= m; ++k) {
      const double x = kSpan * k / m;
      pts.col(k) = Vector3d(x, 0, -0.125 * (1 - std::cos(2 * kPi * x / kSpan)));
    }
    s.cases[0].start.kind = StartShape::Kind::kPoints;
    s.cases[0].start.points = pts;  // no s: chord lengths scaled to L
  }
  return s;
}

struct ClampedClampedErrors {
  double vertex = 0.0;    // [m]
  double reaction = 0.0;  // relative to rho g L (forces) and rho g L^2 (moments)
  double zmid = 0.0;      // z of the middle vertex
};

ClampedClampedErrors CompareClampedClamped(const CaseSolution& sol, const char* what, int n) {
  const ref::ShootingResult& r = ClampedClampedReference();
  const RodParams p = ClampedClampedParams();
  const double force_scale = p.rho * p.gravity.norm() * p.L;
  ClampedClampedErrors e;
  e.vertex = MaxVertexError(sol, r);
  e.zmid = sol.state.x(2, n / 2);
  const HeldReaction* c0 = FindReaction(sol, "clamp");
  const HeldReaction* cL = FindReaction(sol, "end_clamp");
  EXPECT_TRUE(c0 && cL);
  if (!c0 || !cL) return e;
  const double df0 = (c0->force - r.n0).norm(), dm0 = (c0->moment - r.m0).norm();
  const double dfL = (cL->force + r.nL).norm(), dmL = (cL->moment + r.mL).norm();
  e.reaction = std::max({df0 / force_scale, dfL / force_scale, dm0 / (force_scale * p.L),
                         dmL / (force_scale * p.L)});
  std::printf("[measured] c. clamped-clamped, %s, n = %d: z(L/2) %.5f (reference %.5f), max "
              "vertex error %.3e L, clamp force/moment error %.2e N / %.2e N m, end clamp "
              "%.2e N / %.2e N m, |y| max %.1e, stable %d, Pi %.6f J, %d continuation steps\n",
              what, n, e.zmid, r.PositionAt(0.5).z(), e.vertex / p.L, df0, dm0, dfL, dmL,
              sol.state.x.row(1).cwiseAbs().maxCoeff(), sol.summary.stable,
              PotentialEnergy(*sol.model, sol.state), sol.summary.continuation_steps);
  return e;
}

TEST(ExactReferences, HeavyClampedClampedElasticaAgainstShooting) {
  const ref::ShootingResult& r = ClampedClampedReference();
  ASSERT_TRUE(r.converged) << r.message;
  ASSERT_LT(r.PositionAt(0.5).z(), -0.1);  // the sagging branch
  // Exact statics of the reference: n(0) - n(L) = weight.
  const RodParams p = ClampedClampedParams();
  ASSERT_LT((r.n0 - r.nL - p.rho * p.gravity * p.L).norm(), 1e-9);
  ClampedClampedErrors prev;
  for (int n : {50, 100}) {
    const CaseSolution sol = Solve(ClampedClampedScene(n, /*sag_start=*/true));
    ASSERT_TRUE(sol.ok()) << "n " << n << ": " << sol.summary.BriefReport();
    const ClampedClampedErrors e = CompareClampedClamped(sol, "sag start", n);
    EXPECT_LT(sol.state.x.row(1).cwiseAbs().maxCoeff(), 1e-9 * p.L);  // stays in its plane
    EXPECT_TRUE(sol.summary.stable);
    if (n == 100) {
      EXPECT_LT(e.vertex, 2e-3 * p.L);
      EXPECT_LT(e.reaction, 2e-3);
      EXPECT_GT(prev.vertex / e.vertex, 3.0);  // second order: ~4x per doubling
      EXPECT_GT(prev.reaction / e.reaction, 3.0);
    }
    prev = e;
  }
}

// A wire hanging between two clamps, solved from the straight start as a user would: it must
// end on the sag (z(L/2) = -0.267, Pi = 5.64 J), which a quasi-static shortening under gravity
// follows, not on the hogging arch (z(L/2) = +0.265, Pi = 10.96 J), the other stable equilibrium
// (the reference solver finds it too, from an upward arc). Why it is hard: moving the end clamp
// in by 0.1 L at once compresses the straight rod ~2500 times past Euler buckling (an axial
// force ~1e5 N against a weight of 20 N), and the Newton iteration rather than gravity then
// decides which way the column buckles; a held-point continuation in such steps once ended on
// the arch at 60 and 100 segments.
TEST(ExactReferences, HeavyClampedClampedFromStraightStartSags) {
  const ref::ShootingResult& r = ClampedClampedReference();
  ASSERT_TRUE(r.converged) << r.message;
  for (int n : {50, 100}) {
    const CaseSolution sol = Solve(ClampedClampedScene(n, /*sag_start=*/false));
    ASSERT_TRUE(sol.ok()) << "n " << n << ": " << sol.summary.BriefReport();
    const ClampedClampedErrors e = CompareClampedClamped(sol, "straight start", n);
    EXPECT_LT(e.zmid, -0.1) << "n " << n << ": the straight start ended on another branch";
    EXPECT_LT(e.vertex, (n == 50 ? 8e-3 : 2e-3)) << "n " << n;  // 4 x 2e-3 L at 50 segments
  }
}

// ---------------------------------------------------------------------------------------------
// c'. Both ends held, in full 3-D: a heavy, anisotropic (B2 = 2 B1), rest-curved rod (k1, k2, tau
// all nonzero) whose clamp is tilted out of the horizontal and whose far end is held at a point
// off the clamp's plane, with a tangent out of that plane too. Three holders at s = L: a clamp
// (position and frame), a clamp free to turn about its tangent (no normal: m(L).d3(L) = 0) and
// a pin (position only: m(L) = 0). Reference: the shooting solver (RK4 + Newton, multiple
// shooting) with the matching end condition, reached by continuation of the end target and the
// loads from the unloaded rest shape. Expected: second order in the segment length for the
// centre-line and both holders' reactions, as for the planar case above; every discrete solve
// from the straight start, as a user would run it.
struct HeldEnd3D {
  const char* name;
  ref::EndCondition reference;
};

RodParams BothEndsHeld3DParams() {
  RodParams p;
  p.B1 = 1.0;
  p.B2 = 2.0;
  p.GJ = 0.7;
  p.rho = 1.0;
  p.gravity = Vector3d(0, 0, -10.0);  // rho g L^3 / B1 = 10
  p.rest_curvature = Vector3d(0.4, -0.3, 0.5);
  return p;
}

Clamp BothEndsHeld3DClamp() {
  Clamp c;
  c.tangent = Vector3d(1, 0, 0.2);
  c.normal = Vector3d(0, 0, 1);
  return c;
}

const Vector3d kEnd3D(0.6, 0.35, -0.15);
const Vector3d kEndTangent3D(0.3, 1.0, -0.2);
const Vector3d kEndNormal3D(0.0, 0.0, 1.0);

std::vector<HeldEnd3D> HeldEnds3D() {
  return {{"end clamp", ref::EndCondition::Clamp(kEnd3D, kEndTangent3D, kEndNormal3D)},
          {"end clamp free to twist", ref::EndCondition::ClampFreeTwist(kEnd3D, kEndTangent3D)},
          {"end pin", ref::EndCondition::Pin(kEnd3D)}};
}

Scene BothEndsHeld3DScene(const HeldEnd3D& end, int n) {
  Scene s = MakeScene(BothEndsHeld3DParams(), n, BothEndsHeld3DClamp());
  LoadCase& c = s.cases[0];
  if (end.reference.kind == ref::EndCondition::kPin) {
    c.end_pin = kEnd3D;
  } else {
    EndClamp e;
    e.position = kEnd3D;
    e.tangent = kEndTangent3D;
    if (end.reference.kind == ref::EndCondition::kClamp) e.normal = kEndNormal3D;
    c.end_clamp = e;
  }
  return s;
}

TEST(ExactReferences, BothEndsHeldIn3DAgainstShooting) {
  const RodParams p = BothEndsHeld3DParams();
  const double force_scale = p.rho * p.gravity.norm() * p.L;
  for (const HeldEnd3D& end : HeldEnds3D()) {
    SCOPED_TRACE(end.name);
    ref::ShootingOptions o;
    o.steps = 2000;  // RK4: ~1e-12 L against the 1e-5 L compared
    o.segments = 4;
    o.continuation_steps = 20;
    const ref::ShootingResult r = ref::SolveKirchhoff(RefProps(p), RefClamp(BothEndsHeld3DClamp()),
                                                      end.reference, o);
    ASSERT_TRUE(r.converged) << r.message;
    // Exact statics of the reference: n(0) - n(L) = weight; the end condition holds.
    ASSERT_LT((r.n0 - r.nL - p.rho * p.gravity * p.L).norm(), 1e-9);
    ASSERT_LT((r.PositionAt(p.L) - kEnd3D).norm(), 1e-9);
    double prev_vertex = 0.0, prev_reaction = 0.0;
    for (int n : {50, 100, 200}) {
      const CaseSolution sol = Solve(BothEndsHeld3DScene(end, n));
      ASSERT_TRUE(sol.ok()) << "n " << n << ": " << sol.summary.BriefReport();
      EXPECT_TRUE(sol.summary.stable);
      const double vertex = MaxVertexError(sol, r);
      const HeldReaction* c0 = FindReaction(sol, "clamp");
      const HeldReaction* cL =
          FindReaction(sol, end.reference.kind == ref::EndCondition::kPin ? "end_pin" : "end_clamp");
      ASSERT_TRUE(c0 && cL);
      // The rod's reaction on the end holder is (-n(L), -m(L)) about r(L) (file comment).
      const double df0 = (c0->force - r.n0).norm(), dm0 = (c0->moment - r.m0).norm();
      const double dfL = (cL->force + r.nL).norm(), dmL = (cL->moment + r.mL).norm();
      const double reaction = std::max({df0 / force_scale, dfL / force_scale,
                                        dm0 / (force_scale * p.L), dmL / (force_scale * p.L)});
      const double out_of_plane = sol.state.x.row(1).cwiseAbs().maxCoeff();
      std::printf("[measured] c'. %s, n = %d: max vertex error %.3e L, reactions (clamp %.2e N / "
                  "%.2e N m, end %.2e N / %.2e N m) %.2e of rho g L, |y| max %.3f, %d iterations, "
                  "%d continuation steps\n",
                  end.name, n, vertex / p.L, df0, dm0, dfL, dmL, reaction, out_of_plane,
                  sol.summary.iterations, sol.summary.continuation_steps);
      EXPECT_GT(out_of_plane, 0.1 * p.L);  // a 3-D shape, not a planar one
      if (n == 200) {
        EXPECT_LT(vertex, 1e-4 * p.L);
        EXPECT_LT(reaction, 1e-3);
      }
      if (n > 50) {
        EXPECT_GT(prev_vertex / vertex, 3.0) << "n " << n;  // second order: ~4x per doubling
        EXPECT_GT(prev_reaction / reaction, 3.0) << "n " << n;
      }
      prev_vertex = vertex;
      prev_reaction = reaction;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// d. Euler buckling with a held end. Source: S. P. Timoshenko, J. M. Gere, "Theory of Elastic
// Stability", 2nd ed. (1961), ch. 2: clamped-clamped P_cr = 4 pi^2 EI / L^2; clamped-pinned
// P_cr = (kL)^2 EI / L^2 with tan(kL) = kL, kL = 4.4934, (kL)^2 = 20.19 = 2.046 pi^2.
// Method: the straight column with its end held (end_clamp with tangent along the axis, or
// end_pin) at a shortened position x_n = (1 - eps) L e_x is an equilibrium at every eps (all
// edges compressed equally, no bending); its axial force is P = EA eps. It is stable while the
// Hessian with the held rows (AssembleHessian at that state) is positive definite; bisect the
// eps at which BandedCholesky::Factor starts to fail. Tolerance 1 % (the discrete
// critical load is second order in l: measured 3e-4 relative at 100 segments).
double CriticalLoad(bool end_clamp, int n) {
  RodParams p;  // L = 1, B1 = B2 = 1, GJ = 1/1.3 like test_util's Cantilever; EA = 1e6
  p.GJ = 1.0 / 1.3;
  Clamp clamp;
  auto stable = [&](double P) {
    const double eps = P / p.EA;
    Scene s = MakeScene(p, n, clamp);
    const Vector3d end((1.0 - eps) * p.L, 0, 0);
    if (end_clamp) {
      s.cases[0].end_clamp = EndClamp{end, Vector3d::UnitX(), Vector3d::UnitZ()};
    } else {
      s.cases[0].end_pin = end;
    }
    const RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
    RodState state = model.StraightState();
    state.x *= 1.0 - eps;  // clamp at the origin: a uniform shortening
    state.SyncEdges();
    model.InitialiseFrames(&state);
    VecX g;
    BandedSymmetric H;
    AssembleHessian(model, state, EnergyTerms(), &g, &H);
    // An equilibrium up to the stretch round-off eps_mach EA |x| / l ~ 2e-8 N.
    EXPECT_LT(g.cwiseAbs().maxCoeff(), 1e-7);
    BandedCholesky chol;
    return chol.Factor(H);
  };
  double lo = 1.0, hi = 100.0;
  EXPECT_TRUE(stable(lo));
  EXPECT_FALSE(stable(hi));
  for (int it = 0; it < 30; ++it) {
    const double mid = 0.5 * (lo + hi);
    (stable(mid) ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(ExactReferences, EulerBucklingClampedClampedAndClampedPinned) {
  // The clamped-pinned constant from its characteristic equation tan(x) = x in (pi, 3 pi / 2)
  // (Newton on sin x - x cos x), checked against the quoted 20.19.
  double x = 4.5;
  for (int it = 0; it < 50; ++it) x -= (std::sin(x) - x * std::cos(x)) / (x * std::sin(x));
  const double cp_exact = x * x;
  ASSERT_NEAR(cp_exact, 20.19, 0.005);
  const double cc_exact = 4 * kPi * kPi;
  const double cc = CriticalLoad(true, 100);
  const double cp = CriticalLoad(false, 100);
  std::printf("[measured] d. clamped-clamped P_cr = %.4f (4 pi^2 = %.4f, %.2e rel), "
              "clamped-pinned P_cr = %.4f (%.4f, %.2e rel)\n",
              cc, cc_exact, cc / cc_exact - 1, cp, cp_exact, cp / cp_exact - 1);
  EXPECT_NEAR(cc, cc_exact, 0.01 * cc_exact);
  EXPECT_NEAR(cp, cp_exact, 0.01 * cp_exact);
}

// ---------------------------------------------------------------------------------------------
// e. Follower moments.
// (1) Planar: a follower moment about d2 keeps its direction while the rod bends about d2 (d2
// stays fixed in the plane), so it equals the dead moment of the same vector and 2 pi EI / L
// closes the circle. The discrete circle misses closing by (4/3)(pi / N)^2 L (the tan-form
// turning, see references_test.cc EndMoment.FullCircleClosesWithExpectedError) = 1.3e-3 L at
// N = 100: checked within 30 %, and the vertices against the exact circle within 2e-3 L. The
// section is stiff out of the plane and in twist (B1 = GJ = 10 B2) as in references_test.cc: a
// soft ring bent that far is laterally unstable, which is physics, not the planar reference.
// The follower and dead solutions solve the same planar equations: they must agree to solver
// precision (1e-8 L).
TEST(ExactReferences, FollowerMomentPlanarClosesCircleLikeDeadMoment) {
  RodParams p;
  p.B1 = 10.0;
  p.B2 = 1.0;
  p.GJ = 10.0;
  Clamp clamp;  // origin, +x, d1 = +z, d2 = d3 x d1 = -y
  const int n = 100;
  const double M = 2 * kPi * p.B2 / p.L;
  Scene follower = MakeScene(p, n, clamp);
  follower.cases[0].tip_moment_follower = Vector3d(0, M, 0);  // +d2
  Scene dead = MakeScene(p, n, clamp);
  dead.cases[0].tip_moment = Vector3d(0, -M, 0);  // the same vector at the clamp: +d2 = -y
  const CaseSolution fs = Solve(follower);
  const CaseSolution ds = Solve(dead);
  ASSERT_TRUE(fs.ok()) << fs.summary.BriefReport();
  ASSERT_TRUE(ds.ok()) << ds.summary.BriefReport();
  // Curvature about d2 > 0 turns d3 towards +d1 = +z: a circle in the x-z plane centred at
  // (0, 0, R), R = L / (2 pi).
  const double R = p.L / (2 * kPi);
  double err = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double s = fs.model->arc_length(i);
    const Vector3d exact(R * std::sin(s / R), 0, R - R * std::cos(s / R));
    err = std::max(err, (fs.state.x.col(i) - exact).norm());
  }
  const double gap = fs.state.x.col(n).norm();
  const double expected_gap = 4.0 / 3.0 * std::pow(kPi / n, 2) * p.L;
  const double diff = (fs.state.x - ds.state.x).colwise().norm().maxCoeff();
  std::printf("[measured] e1. planar follower circle: max vertex error %.3e L, gap %.3e L "
              "(expected %.3e), follower vs dead %.1e L\n",
              err / p.L, gap / p.L, expected_gap / p.L, diff / p.L);
  EXPECT_LT(err, 2e-3 * p.L);
  EXPECT_NEAR(gap, expected_gap, 0.3 * expected_gap);
  EXPECT_LT(diff, 1e-8 * p.L);
  EXPECT_LT(fs.state.x.row(1).cwiseAbs().maxCoeff(), 1e-12 * p.L);
  // The clamp holds the moment: reactions[0].moment = m(0) = M along +d2 = -y, no force.
  EXPECT_LT((fs.reactions[0].moment - Vector3d(0, -M, 0)).norm(), 1e-6 * M);
  EXPECT_LT(fs.reactions[0].force.norm(), 1e-9 * M / p.L);
}

// (2) 3-D: anisotropic, rest-curved, a follower moment with all three components and a dead tip
// force, against SolveKirchhoff kFollower (m(L) = R(L) mb). Tolerance 2e-3 L at 100 segments;
// the clamp force is exactly the tip force (1e-9); the clamp moment m(0) = R(L) mb + r(L) x F
// depends on the end frame and position, so its error is bounded by |mb| times the end frame's
// rotation error plus |F| times the tip error; both are allowed 2e-3 (rad, L): |dm| <=
// 2e-3 (|mb| + |F| L). (Measured 3.5e-3 N m against 5.1e-3. The last edge's frame, in which the
// discrete follower acts, is in fact 1.3e-2 rad off R(L), see the next test; the moment error
// stays small only because that rotation is about u(L), which is nearly parallel to mb here.)
struct Follower3D {
  RodParams p;
  Clamp clamp;
  Vector3d F{0.2, -0.3, 0.4};
  Vector3d mb{0.9, -1.4, 1.1};
  Follower3D() {
    p.B1 = 1.0;
    p.B2 = 1.6;
    p.GJ = 0.7;
    p.rest_curvature = Vector3d(0.3, -0.5, 0.2);
    clamp.tangent = Vector3d(1, 0.3, -0.2);
    clamp.normal = Vector3d(0, 0, 1);
  }
  ref::ShootingResult Reference(bool follower) const {
    ref::ShootingOptions o;
    o.steps = 1000;
    o.continuation_steps = 10;
    const ref::EndCondition end =
        follower ? ref::EndCondition::Follower(F, mb)
                 : ref::EndCondition::Free(
                       F, ref::FrameFromTangentNormal(clamp.tangent, clamp.normal) * mb);
    return ref::SolveKirchhoff(RefProps(p), RefClamp(clamp), end, o);
  }
  CaseSolution Discrete(int n) const {
    Scene s = MakeScene(p, n, clamp);
    s.cases[0].tip_force = F;
    s.cases[0].tip_moment_follower = mb;
    return Solve(s);
  }
};

TEST(ExactReferences, FollowerMoment3DAgainstShooting) {
  const Follower3D c;
  const ref::ShootingResult r = c.Reference(true);
  ASSERT_TRUE(r.converged) << r.message;
  // For contrast: the dead moment of the clamp-frame vector gives a visibly different shape.
  const ref::ShootingResult rd = c.Reference(false);
  ASSERT_TRUE(rd.converged) << rd.message;
  ASSERT_GT((r.r.back() - rd.r.back()).norm(), 2e-2 * c.p.L);
  const int n = 100;
  const CaseSolution sol = c.Discrete(n);
  ASSERT_TRUE(sol.ok()) << sol.summary.BriefReport();
  const double err = MaxVertexError(sol, r);
  const double df = (sol.reactions[0].force - r.n0).norm();
  const double dm = (sol.reactions[0].moment - r.m0).norm();
  std::printf("[measured] e2. 3-D follower n = %d: max vertex error %.3e L (dead-moment shape "
              "differs by %.3f L), clamp force error %.1e N, clamp moment error %.2e N m, "
              "stable %d\n",
              n, err / c.p.L, (r.r.back() - rd.r.back()).norm() / c.p.L, df, dm,
              sol.summary.stable);
  EXPECT_LT(err, 2e-3 * c.p.L);
  EXPECT_LT(df, 1e-9 * std::max(1.0, c.F.norm()));
  EXPECT_LT(dm, 2e-3 * (c.mb.norm() + c.F.norm() * c.p.L));
}

// Convergence order of the 3-D follower case: second order, as every other case here (errors
// fall ~4x per doubling). The last edge's material frame represents the continuum frame at
// s = L - l/2, not R(L): it lags R(L) by |u(L)| l / 2 (1.3e-2 rad at 100 segments). At a
// follower end the body moment is R^T m = mb, so the end curvature u(L) = u_rest + K^-1 mb is
// known in advance, and the model applies the moment with components exp((l/2) [u(L)]x) mb in
// the last edge's frame (model/rod.cc). Taken in the edge's own frame, the moment would be off
// by an O(l) rotation and the error would fall only ~1.9x per doubling (measured before that
// change: 1.1e-3 L -> 5.7e-4 L).
TEST(ExactReferences, FollowerMoment3DConvergesAtSecondOrder) {
  const Follower3D c;
  const ref::ShootingResult r = c.Reference(true);
  ASSERT_TRUE(r.converged) << r.message;
  double errs[2];
  int k = 0;
  for (int n : {100, 200}) {
    const CaseSolution sol = c.Discrete(n);
    ASSERT_TRUE(sol.ok()) << sol.summary.BriefReport();
    errs[k] = MaxVertexError(sol, r);
    std::printf("[measured] e2'. 3-D follower n = %d: max vertex error %.3e L, clamp moment "
                "error %.2e N m\n",
                n, errs[k] / c.p.L, (sol.reactions[0].moment - r.m0).norm());
    ++k;
  }
  std::printf("[measured] e2'. error ratio 100 -> 200 segments: %.2f\n", errs[0] / errs[1]);
  EXPECT_GT(errs[0] / errs[1], 3.0) << "first-order convergence of the follower moment";
}

// ---------------------------------------------------------------------------------------------
// f. The hanging loop: L = 1.5 m, B1 = B2 = 1e-3 N m^2, GJ = 8e-4,
// rho = 0.05 kg/m, g = -9.81 z; clamped at the origin heading +x (normal +z), end-clamped at
// (-0.12, 0, 0) heading +x, normal +z. The straight start cannot reach the planar loop: both
// ends keep their frames while they are brought together, so the rod's link (twist + writhe)
// stays 0, and a loop (writhe about 1) formed that way carries about a turn of twist (measured:
// from straight the solver converges to a stable 3-D loop, |y| up to 3.2e-2 m, Pi = -0.2083 J,
// against -0.2180 J for the planar one).
// So the case starts from a circle of circumference L below the clamps (it goes down first and
// turns -360 degrees, untwisted) and the solver moves its end from the origin to -0.12 x by
// continuation.
// Reference: SolveKirchhoff kClamp, 8 shooting segments (rho g L^3 / B ~ 1.7e3 makes single
// shooting ill-conditioned), continuation in gravity from the circle m0 = 2 pi B / L about +y,
// as in the reference self-test (which checks its mirror symmetry and 1e-10 L RK4 accuracy);
// 2000 RK4 steps here (RK4 error ~ 16x the 4000-step error, still < 1e-10 L).
// Tolerance: 2e-3 L at 150 segments. The discretisation error is
// second order, so it must fall ~4x (accept > 3x) from 75 to 150 segments. EA = 1e4 N
// (EA L^2 / B = 2.25e7), given to the reference too.
ref::ShootingResult HangingLoopReference(const RodParams& p) {
  ref::ShootingOptions o;
  o.steps = 2000;
  o.segments = 8;
  o.continuation_steps = 20;
  Vector6d guess;
  guess << 0, 0, 0, 0, 2 * kPi * p.B2 / p.L, 0;
  ref::ClampSpec clamp;
  return ref::SolveKirchhoff(
      RefProps(p), clamp,
      ref::EndCondition::Clamp(Vector3d(-0.12, 0, 0), Vector3d::UnitX(), Vector3d::UnitZ()), o,
      &guess);
}

// Signed turning of the tangent in the x-z plane, angle atan2(z, x): from the clamp's tangent
// through every edge to the end clamp's tangent.
double TurningInXZ(const CaseSolution& sol, const Vector3d& t_start, const Vector3d& t_end) {
  std::vector<Vector3d> t{t_start};
  for (int j = 0; j < sol.state.num_edges(); ++j) t.push_back(sol.state.e.col(j).normalized());
  t.push_back(t_end);
  double total = 0.0;
  for (size_t i = 1; i < t.size(); ++i) {
    double d = std::atan2(t[i].z(), t[i].x()) - std::atan2(t[i - 1].z(), t[i - 1].x());
    while (d > kPi) d -= 2 * kPi;
    while (d < -kPi) d += 2 * kPi;
    total += d;
  }
  return total;
}

TEST(ExactReferences, HangingLoopFromCircleStartAgainstShooting) {
  RodParams p;
  p.L = 1.5;
  p.B1 = p.B2 = 1e-3;
  p.GJ = 8e-4;
  p.EA = 1e4;
  p.rho = 0.05;
  p.gravity = Vector3d(0, 0, -9.81);
  const auto t0 = std::chrono::steady_clock::now();
  const ref::ShootingResult r = HangingLoopReference(p);
  ASSERT_TRUE(r.converged) << r.message;
  const double t_ref = Seconds(t0);
  Clamp clamp;  // origin, +x, normal +z
  // The start: a circle of circumference L below the clamp, going down first.
  const double R = p.L / (2 * kPi);
  const int m = 60;
  Eigen::Matrix3Xd circle(3, m + 1);
  std::vector<double> cs(m + 1);
  for (int k = 0; k <= m; ++k) {
    const double th = 2 * kPi * k / m;
    circle.col(k) = Vector3d(R * std::sin(th), 0, R * std::cos(th) - R);
    cs[k] = R * th;
  }
  double prev_err = 0.0;
  for (int n : {75, 150}) {
    const auto t1 = std::chrono::steady_clock::now();
    Scene s = MakeScene(p, n, clamp);
    s.cases[0].end_clamp = EndClamp{Vector3d(-0.12, 0, 0), Vector3d::UnitX(), Vector3d::UnitZ()};
    s.cases[0].start.kind = StartShape::Kind::kPoints;
    s.cases[0].start.points = circle;
    s.cases[0].start.s = cs;
    const CaseSolution sol = Solve(s);
    ASSERT_TRUE(sol.ok()) << "n " << n << ": " << sol.summary.BriefReport();
    const double turning = TurningInXZ(sol, Vector3d::UnitX(), Vector3d::UnitX());
    const double ymax = sol.state.x.row(1).cwiseAbs().maxCoeff();
    const double zmin = sol.state.x.row(2).minCoeff();
    const double err = MaxVertexError(sol, r);
    const HeldReaction* c0 = FindReaction(sol, "clamp");
    const HeldReaction* cL = FindReaction(sol, "end_clamp");
    ASSERT_TRUE(c0 && cL);
    std::printf("[measured] f. hanging loop n = %d: turning %.6f deg, |y| max %.1e, lowest z "
                "%.5f (reference %.5f), max vertex error %.3e L, clamp force error %.2e N "
                "(|n0| %.4f), end clamp force error %.2e N, stable %d, %d continuation steps, "
                "%.2f s (reference %.2f s)\n",
                n, turning * 180 / kPi, ymax, zmin,
                std::min_element(r.r.begin(), r.r.end(),
                                 [](const Vector3d& a, const Vector3d& b) { return a.z() < b.z(); })
                    ->z(),
                err / p.L, (c0->force - r.n0).norm(), r.n0.norm(), (cL->force + r.nL).norm(),
                sol.summary.stable, sol.summary.continuation_steps, Seconds(t1), t_ref);
    // Reactions (statically indeterminate, like c.): 2e-3 of the weight rho g L = 0.74 N and of
    // the weight times L for moments.
    const double weight = p.rho * p.gravity.norm() * p.L;
    const double rerr = std::max({(c0->force - r.n0).norm() / weight,
                                  (cL->force + r.nL).norm() / weight,
                                  (c0->moment - r.m0).norm() / (weight * p.L),
                                  (cL->moment + r.mL).norm() / (weight * p.L)});
    std::printf("[measured] f. hanging loop n = %d: largest reaction error %.2e of the weight\n",
                n, rerr);
    if (n == 150) {
      EXPECT_LT(rerr, 2e-3);
    }
    EXPECT_NEAR(turning, -2 * kPi, 1e-9);  // a full turn down and round: -360 degrees
    EXPECT_LT(ymax, 1e-9 * p.L);           // planar
    EXPECT_LT(zmin, -0.2);
    EXPECT_TRUE(sol.summary.stable);
    EXPECT_LT((sol.state.x.col(n) - Vector3d(-0.12, 0, 0)).norm(), 1e-12);
    if (n == 150) {
      EXPECT_LT(err, 2e-3 * p.L);
      EXPECT_GT(prev_err / err, 3.0);  // second order: ~4x per doubling
    }
    prev_err = err;
  }
}

// ---------------------------------------------------------------------------------------------
// g. Reactions close the balance: a heavy rod with an end clamp, an interior pin and a grasp.
// (1) Statics of the whole rod: the holders' forces on the rod (minus the reactions) plus the
// weight sum to zero, and so do their moments about the origin (a reaction's moment is about
// its own position): sum_k (f_k, p_k x f_k + m_k) = (W, sum_i x_i x w_i), to 1e-8 of the weight
// (and of the weight times the rod's size for moments). The clamp's reaction is computed as the
// rest of the balance, so (1) mainly checks the bookkeeping (signs, the moment points, the end
// clamp's ghost edge and couple).
// (2) An independent check of the other holders' reactions by virtual work: for this
// conservative case the equilibrium energy Pi*(p) as a function of a holder's position p has
// dPi*/dp = dPi/dx_k = minus the reaction force at the held vertex (envelope theorem: the free
// dofs are at a stationary point), and turning the end clamp by a small angle phi about an axis
// a through its point gives dPi*/dphi = -(reaction moment).a. Derivatives by central
// differences, Richardson-extrapolated from steps h = 1e-5 and h / 2 (m, rad): the plain
// central difference has a truncation error ~ h^2 |Pi*'''| / 6, measured at ~1e-5 N for the pin
// at h = 1e-5 (falling as h^2 down to 2e-7 N at 1e-6), which the extrapolation removes to
// O(h^4); the round-off is ~eps |Pi| / h ~ 1e-10 N. Each perturbed equilibrium is solved to a
// gradient tolerance of 1e-12 (its energy error is quadratic in that). We ask 1e-6 of the
// weight.
Scene HeldScene(int n) {
  RodParams p;
  p.L = 1.0;
  p.B1 = 1.0;
  p.B2 = 1.3;
  p.GJ = 0.8;
  p.rho = 0.5;
  p.gravity = Vector3d(0.5, -1.0, -9.81);
  p.rest_curvature = Vector3d(0.2, -0.3, 0.1);
  Clamp clamp;
  clamp.tangent = Vector3d(1, 0.2, 0.3);
  clamp.normal = Vector3d(0, 0, 1);
  Scene s = MakeScene(p, n, clamp);
  LoadCase& c = s.cases[0];
  c.end_clamp = EndClamp{Vector3d(0.55, 0.25, -0.1), Vector3d(0, 1, -0.5), Vector3d(1, 0, 0)};
  c.pins.push_back(Pin{0.3, Vector3d(0.28, 0.02, 0.0)});
  c.grasp = Grasp{0.65, Vector3d(0.45, 0.1, -0.25)};
  return s;
}

TEST(ExactReferences, ReactionsCloseTheBalance) {
  const int n = 40;
  Scene s = HeldScene(n);
  const CaseSolution sol = Solve(s);
  ASSERT_TRUE(sol.ok()) << sol.summary.BriefReport();
  const RodModel& model = *sol.model;
  ASSERT_EQ(sol.reactions.size(), 4u);  // clamp, pins[0], grasp, end_clamp
  Vector3d weight = Vector3d::Zero(), weight_moment = Vector3d::Zero();
  for (int i = 0; i <= n; ++i) {
    weight += model.vertex_weight(i);
    weight_moment += sol.state.x.col(i).cross(model.vertex_weight(i));
  }
  Vector3d f_on_rod = Vector3d::Zero(), m_on_rod = Vector3d::Zero();
  for (const HeldReaction& h : sol.reactions) {
    f_on_rod -= h.force;
    m_on_rod -= h.position.cross(h.force) + h.moment;
    if (!h.holds_moment) {
      EXPECT_EQ(h.moment.norm(), 0.0) << h.point;
    }
  }
  const double W = s.rod.linear_density * s.gravity.norm() * s.rod.length;
  const double size = 1.0;  // every point lies within 1 m of the origin
  const double fres = (f_on_rod + weight).norm(), mres = (m_on_rod + weight_moment).norm();
  std::printf("[measured] g. balance residual: force %.1e N, moment %.1e N m (weight %.3f N)\n",
              fres, mres, W);
  EXPECT_LT(fres, 1e-8 * W);
  EXPECT_LT(mres, 1e-8 * W * size);
  for (const HeldReaction& h : sol.reactions)  // every holder carries a real share
    EXPECT_GT(h.force.norm(), 1e-2 * W) << h.point;

  // (2) Virtual work. Each perturbed case restarts from the solution (start: previous) and the
  // solver moves the holder by continuation; Pi* is the potential at the new equilibrium.
  StaticsOptions tight;
  tight.gradient_tolerance = 1e-12;
  // Richardson-extrapolated central difference of t -> Pi*(perturb(t)).
  auto derivative = [&](const std::function<void(double, LoadCase*)>& perturb) {
    auto energy = [&](double t) {
      Scene sc = s;
      sc.cases[0].start.kind = StartShape::Kind::kPrevious;
      perturb(t, &sc.cases[0]);
      const CaseSolution ps = SolveCase(sc, 0, &sol, tight);
      EXPECT_TRUE(ps.ok()) << ps.summary.BriefReport();
      return PotentialEnergy(*ps.model, ps.state);
    };
    const double h = 1e-5;
    const double d1 = (energy(h) - energy(-h)) / (2 * h);
    const double d2 = (energy(h / 2) - energy(-h / 2)) / h;
    return (4 * d2 - d1) / 3;
  };
  for (const std::string point : {"pins[0]", "grasp", "end_clamp"}) {
    const HeldReaction* hr = FindReaction(sol, point);
    ASSERT_NE(hr, nullptr) << point;
    Vector3d grad;
    for (int k = 0; k < 3; ++k) {
      grad[k] = derivative([&](double t, LoadCase* c) {
        const Vector3d d = t * Vector3d::Unit(k);
        if (point == "pins[0]") {
          c->pins[0].position += d;
        } else if (point == "grasp") {
          c->grasp->position += d;
        } else {
          c->end_clamp->position += d;
        }
      });
    }
    const double d = (grad + hr->force).norm();
    std::printf("[measured] g. virtual work, %s: |dPi*/dp + reaction| %.1e N (|reaction| %.3f N)\n",
                point.c_str(), d, hr->force.norm());
    EXPECT_LT(d, 1e-6 * W) << point << ": dPi*/dp " << grad.transpose() << ", reaction "
                           << hr->force.transpose();
  }
  const HeldReaction* ec = FindReaction(sol, "end_clamp");
  Vector3d dphi;
  for (int k = 0; k < 3; ++k) {
    dphi[k] = derivative([&](double t, LoadCase* c) {
      const Matrix3d Q = Eigen::AngleAxisd(t, Vector3d::Unit(k)).toRotationMatrix();
      c->end_clamp->tangent = Q * c->end_clamp->tangent;
      c->end_clamp->normal = Q * *c->end_clamp->normal;
    });
  }
  const double dmo = (dphi + ec->moment).norm();
  std::printf("[measured] g. virtual work, end clamp moment: |dPi*/dphi + reaction| %.1e N m "
              "(|reaction| %.3f N m)\n", dmo, ec->moment.norm());
  EXPECT_LT(dmo, 1e-6 * W * s.rod.length) << "dPi*/dphi " << dphi.transpose() << ", reaction "
                                          << ec->moment.transpose();
}

}  // namespace
}  // namespace rodfit
