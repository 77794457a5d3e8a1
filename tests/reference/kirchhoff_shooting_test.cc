// Self-tests of the continuous Kirchhoff-rod reference solver against closed forms and
// published tables (see kirchhoff_shooting.h for the model and sign conventions).
#include "rodfit/reference/kirchhoff_shooting.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace rodfit_reference {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using Vector6d = Eigen::Matrix<double, 6, 1>;

constexpr double kPi = 3.14159265358979323846;

// Total signed turning of d3 in the x-z plane, angle measured as atan2(z, x) (so a tangent
// that starts along +x and goes down first turns by a negative angle).
double TurningInXZ(const ShootingResult& r) {
  double total = 0.0;
  double prev = std::atan2(r.frames[0](2, 2), r.frames[0](0, 2));
  for (size_t i = 1; i < r.frames.size(); ++i) {
    const double a = std::atan2(r.frames[i](2, 2), r.frames[i](0, 2));
    double d = a - prev;
    while (d > kPi) d -= 2 * kPi;
    while (d < -kPi) d += 2 * kPi;
    total += d;
    prev = a;
  }
  return total;
}

double MaxOrthonormalityError(const ShootingResult& r) {
  double e = 0.0;
  for (const Matrix3d& R : r.frames) {
    e = std::max(e, (R.transpose() * R - Matrix3d::Identity()).cwiseAbs().maxCoeff());
    e = std::max(e, std::abs(R.determinant() - 1.0));
  }
  return e;
}

RodProperties UnitRod() {
  RodProperties p;
  p.length = 1.0;
  p.B1 = p.B2 = 1.0;
  p.GJ = 1.0;
  return p;
}

// ---------------------------------------------------------------------------------------------
// 1. Planar cantilever, tip load P perpendicular to the clamp.
// Reference values: K. Mattiasson, "Numerical results from large deflection beam and frame
// problems analysed by means of elliptic integrals", Int. J. Numer. Meth. Eng. 17 (1981)
// 145-153, Table I (same problem as Bisshopp & Drucker, Q. Appl. Math. 3 (1945) 272-275).
// alpha = P L^2 / EI; w = tip deflection along the load / L, u = shortening along the
// clamp axis / L, phi = tip rotation [rad]. Tolerance 2e-5 = the table's rounding.
TEST(KirchhoffShooting, CantileverTipLoadMattiasson) {
  struct Row {
    double alpha, w, u, phi;
  };
  const Row table[] = {{1, 0.30172, 0.05643, 0.46135},  {2, 0.49346, 0.16064, 0.78175},
                       {3, 0.60325, 0.25442, 0.98602},  {4, 0.66996, 0.32894, 1.12124},
                       {5, 0.71379, 0.38763, 1.21537},  {10, 0.81061, 0.55500, 1.430286}};
  const RodProperties p = UnitRod();
  ClampSpec clamp;  // origin, tangent +x, normal +z: bending in the x-z plane uses B2
  for (const Row& row : table) {
    ShootingOptions o;
    o.continuation_steps = 10;
    const ShootingResult r =
        SolveKirchhoff(p, clamp, EndCondition::Free(Vector3d(0, 0, -row.alpha), Vector3d::Zero()), o);
    ASSERT_TRUE(r.converged) << "alpha " << row.alpha << ": " << r.message;
    const Vector3d tip = r.r.back();
    const Vector3d d3 = r.frames.back().col(2);
    EXPECT_NEAR(-tip.z(), row.w, 2e-5) << "alpha " << row.alpha;
    EXPECT_NEAR(1.0 - tip.x(), row.u, 2e-5) << "alpha " << row.alpha;
    EXPECT_NEAR(std::atan2(-d3.z(), d3.x()), row.phi, 2e-5) << "alpha " << row.alpha;
    EXPECT_NEAR(tip.y(), 0.0, 1e-14);
    // Exact statics: n is constant = P, m(0) = r(L) x F (moment of the tip load about the clamp).
    EXPECT_LT((r.n0 - Vector3d(0, 0, -row.alpha)).norm(), 1e-12);
    EXPECT_LT((r.m0 - tip.cross(Vector3d(0, 0, -row.alpha))).norm(), 1e-9);
  }
}

// Multiple shooting must give the same solution as single shooting.
TEST(KirchhoffShooting, MultipleShootingMatchesSingleShooting) {
  const RodProperties p = UnitRod();
  ClampSpec clamp;
  const EndCondition end = EndCondition::Free(Vector3d(0, 0.5, -5.0), Vector3d(0.3, 0, 0));
  ShootingOptions o;
  o.continuation_steps = 10;
  const ShootingResult single = SolveKirchhoff(p, clamp, end, o);
  o.segments = 5;
  const ShootingResult multi = SolveKirchhoff(p, clamp, end, o);
  ASSERT_TRUE(single.converged && multi.converged);
  for (int i = 0; i <= 50; ++i) {
    const double s = 0.0199 * i;
    EXPECT_LT((single.PositionAt(s) - multi.PositionAt(s)).norm(), 1e-10) << s;
  }
  EXPECT_LT((single.m0 - multi.m0).norm(), 1e-9);
}

// ---------------------------------------------------------------------------------------------
// 2. A dead end moment M = 2 pi B1 / L about d1 bends the rod into a full circle (m = M is
// constant, curvature 2 pi / L): the tip returns to the clamp with the clamp's tangent.
TEST(KirchhoffShooting, EndMomentClosesCircle) {
  RodProperties p = UnitRod();
  p.length = 0.8;
  p.B1 = 1.3;  // anisotropic: checks that the moment about d1 uses B1
  p.B2 = 0.7;
  p.GJ = 0.9;
  ClampSpec clamp;
  clamp.position = Vector3d(0.1, -0.2, 0.3);
  clamp.tangent = Vector3d(1, 0, 0);
  clamp.normal = Vector3d(0, 0, 1);  // d1 = +z: the circle lies in the plane z = 0.3
  const Vector3d M = 2 * kPi * p.B1 / p.length * Vector3d::UnitZ();
  const ShootingResult r = SolveKirchhoff(p, clamp, EndCondition::Free(Vector3d::Zero(), M));
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT((r.r.back() - clamp.position).norm(), 1e-8 * p.length);
  EXPECT_LT((r.frames.back().col(2) - Vector3d::UnitX()).norm(), 1e-8);
  EXPECT_LT((r.frames.back() - r.frames.front()).norm(), 1e-8);
  // Half-way round the circle (radius L / 2 pi) the rod is a diameter away, heading -x.
  const double radius = p.length / (2 * kPi);
  const Vector3d centre = clamp.position + radius * Vector3d::UnitY();
  for (int i = 0; i <= 40; ++i) {
    const double s = p.length * (i + 0.37) / 41.0;  // off-grid points test StateAt
    EXPECT_NEAR((r.PositionAt(s) - centre).norm(), radius, 1e-9 * p.length);
  }
  EXPECT_LT(MaxOrthonormalityError(r), 1e-13);
}

// ---------------------------------------------------------------------------------------------
// 3. Isotropic rod, dead end moment M in a general direction, no force. Then n = 0, so
// m(s) = M for all s and B d3' = (B w) x d3 = (M - GJ tau d3 + B tau d3) x d3 = M x d3: d3
// precesses about a = M/|M| at rate W = |M| / B, independently of GJ:
//   d3(s) = (a.d30) a + cos(W s) (d30 - (a.d30) a) + sin(W s) a x d30,
//   r(s)  = p0 + (a.d30) a s + sin(W s)/W (d30 - (a.d30) a) + (1 - cos(W s))/W a x d30,
// a helix of axis a (Kirchhoff's kinetic analogy: heavy top with no gravity).
TEST(KirchhoffShooting, IsotropicDeadMomentHelix) {
  RodProperties p;
  p.length = 2.0;
  p.B1 = p.B2 = 1.3;
  ClampSpec clamp;
  clamp.position = Vector3d(0.2, 0.1, -0.4);
  clamp.tangent = Vector3d(1, 2, 0.5);
  clamp.normal = Vector3d(0, 0, 1);
  const Vector3d M(1.4, -0.3, 2.1);
  const Vector3d a = M.normalized();
  const Vector3d d30 = clamp.tangent.normalized();
  ASSERT_GT(std::abs(a.dot(d30)), 0.1);  // neither perpendicular ...
  ASSERT_LT(std::abs(a.dot(d30)), 0.9);  // ... nor parallel
  const double W = M.norm() / p.B1;
  auto exact_r = [&](double s) {
    return Vector3d(clamp.position + a.dot(d30) * a * s +
                    std::sin(W * s) / W * (d30 - a.dot(d30) * a) +
                    (1 - std::cos(W * s)) / W * a.cross(d30));
  };
  auto exact_d3 = [&](double s) {
    return Vector3d(a.dot(d30) * a + std::cos(W * s) * (d30 - a.dot(d30) * a) +
                    std::sin(W * s) * a.cross(d30));
  };
  std::vector<ShootingResult> results;
  for (double GJ : {0.4, 2.5}) {
    p.GJ = GJ;
    const ShootingResult r = SolveKirchhoff(p, clamp, EndCondition::Free(Vector3d::Zero(), M));
    ASSERT_TRUE(r.converged) << r.message;
    for (int i = 0; i <= 60; ++i) {
      const double s = p.length * (i + 0.5) / 61.0;
      EXPECT_LT((r.PositionAt(s) - exact_r(s)).norm(), 1e-9 * p.length) << "GJ " << GJ;
      EXPECT_LT((r.FrameAt(s).col(2) - exact_d3(s)).norm(), 1e-9) << "GJ " << GJ;
    }
    for (size_t i = 0; i < r.s.size(); ++i) {
      EXPECT_LT((r.m[i] - M).norm(), 1e-12);
      EXPECT_LT((r.r[i] - exact_r(r.s[i])).norm(), 1e-9 * p.length);
    }
    // Full frame: tau = M.d3 / GJ is constant and w = W a + (M.d30)(1/GJ - 1/B) d3, whose
    // solution is R(s) = Rot(a, W s) R0 Rot(e3, (M.d30)(1/GJ - 1/B) s). This checks the
    // torsion (GJ) part of the constitutive law, which does not affect the centre-line.
    const Matrix3d R0 = FrameFromTangentNormal(clamp.tangent, clamp.normal);
    const double spin = M.dot(d30) * (1.0 / GJ - 1.0 / p.B1);
    for (int i = 0; i <= 30; ++i) {
      const double s = p.length * (i + 0.25) / 31.0;
      const Matrix3d exact = Eigen::AngleAxisd(W * s, a).toRotationMatrix() * R0 *
                             Eigen::AngleAxisd(spin * s, Vector3d::UnitZ()).toRotationMatrix();
      EXPECT_LT((r.FrameAt(s) - exact).norm(), 1e-9) << "GJ " << GJ;
    }
    EXPECT_LT(MaxOrthonormalityError(r), 1e-13);
    results.push_back(r);
  }
  for (int i = 0; i <= 20; ++i) {
    const double s = p.length * i / 20.0;
    EXPECT_LT((results[0].PositionAt(s) - results[1].PositionAt(s)).norm(), 1e-10);
  }
}

// ---------------------------------------------------------------------------------------------
// 4. Clamped-clamped rod, both ends at the same height with the same tangent, under gravity:
// the problem is symmetric under the reflection x -> D - x, s -> L - s, so the (sagging)
// solution must be too: x(L - s) = D - x(s), z(L - s) = z(s). Force balance (n' = -f):
// n(0) - n(L) = rho g L.
TEST(KirchhoffShooting, ClampedClampedSagSymmetry) {
  RodProperties p;
  p.length = 1.0;
  p.B1 = 1.0;
  p.B2 = 1.0;
  p.GJ = 0.8;
  p.linear_density = 1.0;
  p.gravity = Vector3d(0, 0, -20.0);
  ClampSpec clamp;
  const double D = 0.8;
  ShootingOptions o;
  o.continuation_steps = 20;
  o.segments = 4;
  Vector6d guess;
  guess << 0, 0, 0, 0, -3.0, 0;  // an arc; continuation moves its end to the clamp
  const ShootingResult r = SolveKirchhoff(
      p, clamp, EndCondition::Clamp(Vector3d(D, 0, 0), Vector3d::UnitX(), Vector3d::UnitZ()), o,
      &guess);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT(r.PositionAt(0.5).z(), -0.1);  // the sagging branch
  for (int i = 0; i <= 100; ++i) {
    const double s = 0.01 * i;
    const Vector3d a = r.PositionAt(s);
    const Vector3d b = r.PositionAt(p.length - s);
    EXPECT_NEAR(b.x(), D - a.x(), 1e-9) << s;
    EXPECT_NEAR(b.z(), a.z(), 1e-9) << s;
    EXPECT_NEAR(a.y(), 0.0, 1e-12);
  }
  const Vector3d weight = p.linear_density * p.gravity * p.length;
  EXPECT_LT((r.n0 - r.nL - weight).norm(), 1e-9);
  // Each clamp carries half the weight by symmetry.
  EXPECT_NEAR(r.n0.z(), 0.5 * weight.z(), 1e-9);
  // The end clamp is reached.
  EXPECT_LT((r.r.back() - Vector3d(D, 0, 0)).norm(), 1e-10);
  EXPECT_LT((r.frames.back() - Matrix3d(FrameFromTangentNormal(Vector3d::UnitX(), Vector3d::UnitZ()))).norm(), 1e-10);
}

// ---------------------------------------------------------------------------------------------
// 5. Follower moment. In the plane a follower moment about d1 equals the dead one (d1 stays
// fixed), so 2 pi B1 / L closes the circle; in 3-D they differ.
TEST(KirchhoffShooting, FollowerMomentPlanarCircle) {
  RodProperties p = UnitRod();
  p.B1 = 0.9;
  p.B2 = 1.4;
  ClampSpec clamp;
  clamp.tangent = Vector3d(0, 1, 0);
  clamp.normal = Vector3d(1, 0, 1);
  ShootingOptions o;
  o.continuation_steps = 8;
  const Vector3d mb(2 * kPi * p.B1 / p.length, 0, 0);
  const ShootingResult r = SolveKirchhoff(p, clamp, EndCondition::Follower(Vector3d::Zero(), mb), o);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_LT((r.r.back() - clamp.position).norm(), 1e-8 * p.length);
  EXPECT_LT((r.frames.back().col(2) - clamp.tangent.normalized()).norm(), 1e-8);
  EXPECT_LT((r.mL - r.frames.back() * mb).norm(), 1e-10);
}

TEST(KirchhoffShooting, FollowerVersusDeadMoment3D) {
  RodProperties p = UnitRod();
  p.B1 = 1.0;
  p.B2 = 1.6;
  p.GJ = 0.7;
  ClampSpec clamp;
  clamp.tangent = Vector3d(1, 0.3, -0.2);
  clamp.normal = Vector3d(0, 0, 1);
  const Vector3d F(0.2, -0.3, 0.4);
  const Vector3d mb(0.9, -1.4, 1.1);
  const Matrix3d R0 = FrameFromTangentNormal(clamp.tangent, clamp.normal);
  ShootingOptions o;
  o.continuation_steps = 10;
  const ShootingResult follower = SolveKirchhoff(p, clamp, EndCondition::Follower(F, mb), o);
  const ShootingResult dead = SolveKirchhoff(p, clamp, EndCondition::Free(F, R0 * mb), o);
  ASSERT_TRUE(follower.converged) << follower.message;
  ASSERT_TRUE(dead.converged) << dead.message;
  EXPECT_GT((follower.r.back() - dead.r.back()).norm(), 1e-3 * p.length);
  EXPECT_LT((follower.mL - follower.frames.back() * mb).norm(), 1e-10);
  EXPECT_LT((follower.nL - F).norm(), 1e-10);
  EXPECT_LT((dead.mL - R0 * mb).norm(), 1e-10);
}

// ---------------------------------------------------------------------------------------------
// 6. Pinned end and clamp with free twist, in a loaded 3-D configuration with rest curvature.
TEST(KirchhoffShooting, PinAndClampFreeTwistResiduals) {
  RodProperties p;
  p.length = 1.0;
  p.B1 = 1.0;
  p.B2 = 1.4;
  p.GJ = 0.8;
  p.rest_curvature = Vector3d(0.3, -0.2, 0.1);
  p.linear_density = 0.5;
  p.gravity = Vector3d(0, -1.0, -9.81);
  ClampSpec clamp;
  clamp.tangent = Vector3d(1, 0.1, 0.2);
  clamp.normal = Vector3d(0, 0, 1);
  ShootingOptions o;
  o.continuation_steps = 10;

  const Vector3d pin(0.6, 0.3, -0.4);
  const ShootingResult rp = SolveKirchhoff(p, clamp, EndCondition::Pin(pin), o);
  ASSERT_TRUE(rp.converged) << rp.message;
  EXPECT_LT((rp.r.back() - pin).norm(), 1e-10);
  EXPECT_LT(rp.mL.norm(), 1e-10);
  EXPECT_LT(rp.m.back().norm(), 1e-10);
  EXPECT_LT((rp.n0 - rp.nL - p.linear_density * p.gravity * p.length).norm(), 1e-10);

  const Vector3d pe(0.5, 0.4, 0.3), te(0, 1, 1);
  const ShootingResult rt = SolveKirchhoff(p, clamp, EndCondition::ClampFreeTwist(pe, te), o);
  ASSERT_TRUE(rt.converged) << rt.message;
  const Vector3d d3L = rt.frames.back().col(2);
  EXPECT_LT((rt.r.back() - pe).norm(), 1e-10);
  EXPECT_LT((d3L - te.normalized()).norm(), 1e-10);
  EXPECT_LT(std::abs(rt.mL.dot(d3L)), 1e-10);
  // The bending moment at the end is not zero (the end is held in direction).
  EXPECT_GT((rt.mL - rt.mL.dot(d3L) * d3L).norm(), 1e-3);

  // Full clamp for comparison: all six conditions hold and the twist moment is non-zero in
  // general, which distinguishes it from kClampFreeTwist.
  const Vector3d ne(1, 0, 0);
  const ShootingResult rc = SolveKirchhoff(p, clamp, EndCondition::Clamp(pe, te, ne), o);
  ASSERT_TRUE(rc.converged) << rc.message;
  EXPECT_LT((rc.r.back() - pe).norm(), 1e-10);
  EXPECT_LT((rc.frames.back() - FrameFromTangentNormal(te, ne)).norm(), 1e-10);
  EXPECT_GT(std::abs(rc.mL.dot(rc.frames.back().col(2))), 1e-4);
}

// With no load the rod takes its rest shape, R(s) = R0 Rot(u0 / |u0|, |u0| s) (constant body
// curvature u0), and m vanishes identically.
TEST(KirchhoffShooting, RestCurvatureUnloadedShape) {
  RodProperties p;
  p.length = 1.7;
  p.B1 = 0.8;
  p.B2 = 1.9;
  p.GJ = 0.6;
  p.rest_curvature = Vector3d(1.1, -2.3, 0.7);
  ClampSpec clamp;
  clamp.tangent = Vector3d(0.2, -1, 0.4);
  clamp.normal = Vector3d(1, 0, 0);
  const Matrix3d R0 = FrameFromTangentNormal(clamp.tangent, clamp.normal);
  const double k = p.rest_curvature.norm();
  const Vector3d axis = p.rest_curvature / k;
  // Closed-form centre-line: r' = R(s) e3, integrated with Rodrigues' formula.
  auto exact_r = [&](double s) {
    const Vector3d e3 = Vector3d::UnitZ();
    const Vector3d integral = axis.dot(e3) * axis * s + std::sin(k * s) / k * (e3 - axis.dot(e3) * axis) +
                              (1 - std::cos(k * s)) / k * axis.cross(e3);
    return Vector3d(clamp.position + R0 * integral);
  };
  const ShootingResult r =
      SolveKirchhoff(p, clamp, EndCondition::Free(Vector3d::Zero(), Vector3d::Zero()));
  ASSERT_TRUE(r.converged) << r.message;
  for (int i = 0; i <= 30; ++i) {
    const double s = p.length * (i + 0.6) / 31.0;
    const Matrix3d exact = R0 * Eigen::AngleAxisd(k * s, axis).toRotationMatrix();
    EXPECT_LT((r.FrameAt(s) - exact).norm(), 1e-9);
    EXPECT_LT((r.PositionAt(s) - exact_r(s)).norm(), 1e-9 * p.length);
    EXPECT_LT(r.StateAt(s).m.norm(), 1e-14);
  }
}

// ---------------------------------------------------------------------------------------------
// 7. The hanging loop: L = 1.5 m, B = 1e-3 N m^2, GJ = 8e-4, rho = 0.05 kg/m, g = -9.81 z;
// both clamps head +x with normal +z, the end clamp at (-0.12, 0, 0). Gravity parameter
// rho g L^3 / B ~ 1.7e3: single shooting is ill-conditioned (growth ~ e^19), so we use
// 8 segments and continuation in gravity from a circle (m0 = 2 pi B / L about +y: the circle
// that goes down first; its end is at the origin, the continuation moves it to -0.12 x).
ShootingResult SolveHangingLoop(int steps) {
  RodProperties p;
  p.length = 1.5;
  p.B1 = p.B2 = 1e-3;
  p.GJ = 8e-4;
  p.linear_density = 0.05;
  p.gravity = Vector3d(0, 0, -9.81);
  ClampSpec clamp;  // origin, +x, normal +z
  ShootingOptions o;
  o.steps = steps;
  o.segments = 8;
  o.continuation_steps = 20;
  Vector6d guess;
  guess << 0, 0, 0, 0, 2 * kPi * p.B2 / p.length, 0;
  return SolveKirchhoff(
      p, clamp, EndCondition::Clamp(Vector3d(-0.12, 0, 0), Vector3d::UnitX(), Vector3d::UnitZ()),
      o, &guess);
}

TEST(KirchhoffShooting, HangingLoop) {
  const ShootingResult r = SolveHangingLoop(4000);
  ASSERT_TRUE(r.converged) << r.message;
  EXPECT_NEAR(TurningInXZ(r), -2 * kPi, 1e-6);
  EXPECT_LT(r.frames[1](2, 2), 0.0);  // goes down first
  double zmin = 0.0, ymax = 0.0;
  for (const Vector3d& x : r.r) {
    zmin = std::min(zmin, x.z());
    ymax = std::max(ymax, std::abs(x.y()));
  }
  EXPECT_LT(ymax, 1e-9);
  EXPECT_LT(zmin, -0.2);
  EXPECT_LT((r.r.back() - Vector3d(-0.12, 0, 0)).norm(), 1e-10);
  EXPECT_LT((r.frames.back() - r.frames.front()).norm(), 1e-10);
  // Mirror symmetry x -> -0.12 - x, s -> L - s; each clamp carries half the weight.
  const double L = 1.5;
  for (int i = 0; i <= 60; ++i) {
    const double s = L * i / 60.0;
    const Vector3d a = r.PositionAt(s), b = r.PositionAt(L - s);
    EXPECT_NEAR(b.x(), -0.12 - a.x(), 1e-9) << s;
    EXPECT_NEAR(b.z(), a.z(), 1e-9) << s;
  }
  EXPECT_NEAR(r.n0.z(), -0.5 * 0.05 * 9.81 * L, 1e-10);
  std::printf("hanging loop: lowest z %.10f, n0 (%.10g, %.3g, %.10g), m0 (%.3g, %.10g, %.3g), "
              "Newton iterations %d, residual %.2e\n",
              zmin, r.n0.x(), r.n0.y(), r.n0.z(), r.m0.x(), r.m0.y(), r.m0.z(),
              r.newton_iterations, r.residual);
}

// Integration accuracy: the RK4 error is O(h^4), so the difference between N and 2N steps
// bounds the error of the N-step solution (error(N) ~ 16/15 |x_N - x_2N|).
TEST(KirchhoffShooting, IntegrationAccuracyHangingLoop) {
  const ShootingResult a = SolveHangingLoop(4000);
  const ShootingResult b = SolveHangingLoop(8000);
  ASSERT_TRUE(a.converged && b.converged);
  double diff = 0.0;
  for (int i = 0; i <= 300; ++i) {
    const double s = 1.5 * (i + 0.3) / 301.0;
    diff = std::max(diff, (a.PositionAt(s) - b.PositionAt(s)).norm());
  }
  EXPECT_LT(diff, 1e-10 * 1.5);
}

TEST(KirchhoffShooting, IntegrationAccuracyCantilever) {
  const RodProperties p = UnitRod();
  ClampSpec clamp;
  const EndCondition end = EndCondition::Free(Vector3d(0, 0, -10.0), Vector3d::Zero());
  ShootingOptions o;
  o.continuation_steps = 10;
  const ShootingResult a = SolveKirchhoff(p, clamp, end, o);
  o.steps = 8000;
  const ShootingResult b = SolveKirchhoff(p, clamp, end, o);
  ASSERT_TRUE(a.converged && b.converged);
  double diff = 0.0;
  for (int i = 0; i <= 300; ++i) {
    const double s = (i + 0.3) / 301.0;
    diff = std::max(diff, (a.PositionAt(s) - b.PositionAt(s)).norm());
  }
  EXPECT_LT(diff, 1e-10);
}

// ---------------------------------------------------------------------------------------------
// 8. Extensibility. (a) Axial tip tension F along the tangent: n = F d3 everywhere, so the
// rod stays straight and stretches by F L / EA. (b) A rod hanging from a downward clamp under
// its own weight: n.d3 = rho g (L - s), stretch = rho g L^2 / (2 EA).
TEST(KirchhoffShooting, ExtensibleAxialStretch) {
  RodProperties p = UnitRod();
  p.length = 1.2;
  p.EA = 50.0;
  ClampSpec clamp;
  clamp.position = Vector3d(0.1, 0.2, 0.3);
  clamp.tangent = Vector3d(0.3, 0.4, 1.2);
  clamp.normal = Vector3d(1, 0, 0);
  const Vector3d t = clamp.tangent.normalized();
  const double F = 7.0;
  const ShootingResult r = SolveKirchhoff(p, clamp, EndCondition::Free(F * t, Vector3d::Zero()));
  ASSERT_TRUE(r.converged) << r.message;
  const Vector3d expected = clamp.position + (p.length + F * p.length / p.EA) * t;
  EXPECT_LT((r.r.back() - expected).norm(), 1e-12);
  EXPECT_NEAR(r.tangent.back().norm(), 1.0 + F / p.EA, 1e-13);

  RodProperties h = UnitRod();
  h.EA = 100.0;
  h.linear_density = 2.0;
  h.gravity = Vector3d(0, 0, -9.81);
  ClampSpec top;
  top.tangent = Vector3d(0, 0, -1);
  top.normal = Vector3d(1, 0, 0);
  const ShootingResult hr = SolveKirchhoff(h, top, EndCondition::Free(Vector3d::Zero(), Vector3d::Zero()));
  ASSERT_TRUE(hr.converged) << hr.message;
  const double stretch = h.linear_density * 9.81 * h.length * h.length / (2 * h.EA);
  EXPECT_LT((hr.r.back() - Vector3d(0, 0, -(h.length + stretch))).norm(), 1e-12);
  EXPECT_NEAR(hr.PositionAt(0.5).z(),
              -(0.5 + h.linear_density * 9.81 * (h.length * 0.5 - 0.125) / h.EA), 1e-12);
}

}  // namespace
}  // namespace rodfit_reference
