// The rod's natural shape (RodSpec::rest_curvature_s / rest_curvature_profile; rod.rest_shape,
// RestCurvatureOfCentreline): a centre-line at rest becomes an intrinsic curvature profile whose
// rest state is that centre-line again — a circular arc and a helix (3-D, curvature and torsion
// of the curve in both bending components), to the discretisation's second order — and a
// uniform profile is the uniform rest_curvature.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/model/rod.h"

namespace rodfit {
namespace {

// A helix of radius a and pitch 2 pi b about z, by arc length: r(s) = (a cos w s, a sin w s,
// b w s), w = 1 / sqrt(a^2 + b^2); b = 0 is a circle of radius a.
Vec3 Helix(double a, double b, double s) {
  const double w = 1.0 / std::sqrt(a * a + b * b);
  return Vec3(a * std::cos(w * s), a * std::sin(w * s), b * w * s);
}
Vec3 HelixTangent(double a, double b, double s) {
  const double w = 1.0 / std::sqrt(a * a + b * b);
  return Vec3(-a * w * std::sin(w * s), a * w * std::cos(w * s), b * w);
}

// The largest distance between the rest state of a rod built from the curve's profile (clamped
// at the curve's start along its tangent, d1 the principal normal there) and the curve itself.
double RoundTrip(double a, double b, double length, int points, int segments) {
  Mat3X x(3, points);
  for (int k = 0; k < points; ++k) x.col(k) = Helix(a, b, length * k / (points - 1));
  const Vec3 normal = -Helix(a, 0.0, 0.0).normalized();  // towards the axis: the principal normal
  RodSpec rod;
  rod.length = length;
  rod.segments = segments;
  rod.radius = 1e-3;
  RestCurvatureOfCentreline({}, x, normal, length, &rod.rest_curvature_s,
                            &rod.rest_curvature_profile);
  Material m;
  m.bend_stiffness = 1.0;
  m.twist_stiffness = 1.0;
  m.stretch_stiffness = 1e6;
  LoadCase c;
  c.clamp.position = x.col(0);
  c.clamp.tangent = HelixTangent(a, b, 0.0);
  c.clamp.normal = normal;
  const RodModel model(rod, m, Vec3::Zero(), c);
  const RodState rest = model.RestState();
  double worst = 0.0;
  for (int i = 0; i <= segments; ++i)
    worst = std::max(worst, (rest.x.col(i) - Helix(a, b, model.arc_length(i))).norm());
  return worst;
}

TEST(RestShape, ACircularArcBendsTowardsTheClampNormalWithCurvatureOneOverR) {
  const double R = 0.2;
  Mat3X x(3, 41);
  for (int k = 0; k <= 40; ++k) {
    const double phi = 1.2 * k / 40.0;
    x.col(k) = Vec3(R * std::sin(phi), 0.0, R * (1.0 - std::cos(phi)));  // starts along +x, bends to +z
  }
  std::vector<double> s;
  std::vector<Vec3> k;
  RestCurvatureOfCentreline({}, x, Vec3::UnitZ(), 1.2 * R, &s, &k);
  // [0, k, 0] with k > 0 bends the unloaded rod towards the clamp's normal (docs/model.md): the
  // tan-form curvature of a chord turning by dphi over l is 2 tan(dphi / 2) / l, 1 / R to
  // O(dphi^2).
  for (size_t j = 0; j < k.size(); ++j) {
    EXPECT_NEAR(k[j][0], 0.0, 1e-12);
    EXPECT_NEAR(k[j][1], 1.0 / R, 1e-3 / R);
    EXPECT_EQ(k[j][2], 0.0);
  }
}

TEST(RestShape, RestStateReproducesTheCurveToSecondOrder) {
  for (double b : {0.0, 0.05}) {
    SCOPED_TRACE(b);
    const double e1 = RoundTrip(0.15, b, 0.6, 301, 30);
    const double e2 = RoundTrip(0.15, b, 0.6, 601, 60);
    const double e3 = RoundTrip(0.15, b, 0.6, 1201, 120);
    // Measured: circle 1.24e-3, 3.12e-4, 7.83e-5 m; helix 9.57e-4, 2.41e-4, 6.03e-5 m (0.6 m
    // of rod at 30, 60 and 120 segments).
    EXPECT_NEAR(e1 / e2, 4.0, 0.6) << e1 << " " << e2;  // second order in the segment length
    EXPECT_NEAR(e2 / e3, 4.0, 0.6) << e2 << " " << e3;
  }
}

TEST(RestShape, AUniformProfileIsTheUniformRestCurvature) {
  RodSpec a;
  a.length = 0.5;
  a.segments = 25;
  a.radius = 1e-3;
  a.rest_curvature = Vec3(0.3, 1.5, 0.2);
  RodSpec b = a;
  b.rest_curvature.setZero();
  b.rest_curvature_s = {0.1, 0.4};
  b.rest_curvature_profile = {a.rest_curvature, a.rest_curvature};
  Material m;
  m.bend_stiffness = 1.0;
  m.twist_stiffness = 0.8;
  m.stretch_stiffness = 1e6;
  LoadCase c;
  const RodModel ma(a, m, Vec3::Zero(), c), mb(b, m, Vec3::Zero(), c);
  for (int i = 0; i <= a.segments; ++i) EXPECT_EQ(ma.rest_curvature(i), mb.rest_curvature(i));
  EXPECT_EQ(ma.RestState().x, mb.RestState().x);
  EXPECT_EQ(ma.hessian_digest(), mb.hessian_digest());
  EXPECT_TRUE(mb.curved_at_rest());
}

TEST(RestShape, RefusesUnusableCurves) {
  std::vector<double> s;
  std::vector<Vec3> k;
  Mat3X two(3, 2);
  two << 0, 1, 0, 0, 0, 0;
  EXPECT_THROW(RestCurvatureOfCentreline({}, two, Vec3::UnitZ(), 1.0, &s, &k), std::invalid_argument);
  Mat3X repeated(3, 3);
  repeated << 0, 0, 1, 0, 0, 0, 0, 0, 0;
  EXPECT_THROW(RestCurvatureOfCentreline({}, repeated, Vec3::UnitZ(), 1.0, &s, &k),
               std::invalid_argument);
  Mat3X line(3, 3);
  line << 0, 0.5, 1, 0, 0, 0, 0, 0, 0;
  EXPECT_THROW(RestCurvatureOfCentreline({}, line, Vec3::UnitX(), 1.0, &s, &k),
               std::invalid_argument);  // the normal along the tangent
}

}  // namespace
}  // namespace rodfit
