// Tests of the observation models (observe/observations.h): for each model the closed-form
// Jacobian against Jet autodiff and central differences on a seeded random bent rod, with the
// special measurements (marker at s = 0 and s = L and on a vertex; closest point at a vertex and
// beyond each end); zero residual on noise-free data and offset / sigma for a known offset;
// rejection of arc lengths outside [0, L]; failure for points behind the camera.
#include "rodfit/observe/observations.h"

#include <cmath>
#include <random>
#include <string>

#include <ceres/jet.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "camera_fixtures.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr int kEdges = 10;
constexpr int kVertices = kEdges + 1;
constexpr int kDofs = 3 * kVertices;
constexpr double kLength = 0.2;  // [m]
using JetX = ceres::Jet<double, kDofs>;

// Rest arc lengths as RodModel builds them: uniform edges.
std::vector<double> RestArcLengths() {
  std::vector<double> s(kVertices);
  for (int i = 0; i < kVertices; ++i) s[i] = i * (kLength / kEdges);
  return s;
}

// A bent, twisted rod near the origin: an arc of radius 0.15 m (1.3 rad of turning) rising out of
// its plane, with seeded random vertex perturbations of up to 2 mm (edges are 20 mm), so every
// interior vertex turns by a different angle about a different axis.
Mat3X BentRod() {
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> jitter(-2e-3, 2e-3);
  const double radius = 0.15;
  Mat3X x(3, kVertices);
  for (int i = 0; i < kVertices; ++i) {
    const double s = i * (kLength / kEdges);
    x.col(i) = Vector3d(radius * std::sin(s / radius), radius * (1.0 - std::cos(s / radius)),
                        0.8 * s * s / kLength);
    if (i > 0) x.col(i) += Vector3d(jitter(rng), jitter(rng), jitter(rng));
  }
  return x;
}

Vector3d Interpolate(const Mat3X& x, const std::vector<double>& arc, double s) {
  const ArcLocation at = LocateArcLength(arc, s);
  return (1.0 - at.a) * x.col(at.edge) + at.a * x.col(at.edge + 1);
}

Vector3d UnitTangent(const Mat3X& x, int edge) {
  return (x.col(edge + 1) - x.col(edge)).normalized();
}

// A unit vector perpendicular to v.
Vector3d Perpendicular(const Vector3d& v, const Vector3d& hint) {
  return v.cross(hint).normalized();
}

// Camera 0.5 m from the rod, looking at its middle, with a typical calibrated lens distortion.
Camera RodCamera() {
  const CameraIntrinsics K = testing::DistortionSets().back().K;
  return CameraLookingAt(K, Vector3d(0.08, -0.25, 0.45), Vector3d(0.1, 0.03, 0.05),
                         Vector3d(0.0, 0.0, 1.0));
}

Eigen::Matrix2Xd ProjectVertices(const Camera& camera, const Mat3X& x) {
  Eigen::Matrix2Xd uv(2, x.cols());
  for (int i = 0; i < x.cols(); ++i) {
    Vector2d uv_i;
    EXPECT_TRUE(Project(camera, Vector3d(x.col(i)), &uv_i));
    uv.col(i) = uv_i;
  }
  return uv;
}

// The rod with its tip swung behind the camera (0.1 m behind the optical centre).
Mat3X RodWithTipBehind(const Camera& camera) {
  Mat3X x = BentRod();
  const Vector3d axis_world = camera.cam_from_world_R.row(2).transpose();
  x.col(kEdges) = camera.CentreWorld() - 0.1 * axis_world;
  return x;
}

// Closed-form Jacobian vs Jet autodiff vs central differences at x, and the double and Jet
// values against Evaluate. All residuals and derivatives must be finite.
template <typename Obs>
void ExpectJacobiansAgree(const Obs& obs, const Mat3X& x) {
  ASSERT_EQ(x.size(), kDofs);
  const int m = obs.num_residuals();
  VecX r;
  VertexJacobian jacobian;
  ASSERT_TRUE(obs.Evaluate(x, &r, &jacobian));
  ASSERT_EQ(r.size(), m);
  ASSERT_TRUE(r.allFinite());
  ASSERT_EQ(jacobian.num_residuals, m);
  ASSERT_EQ(jacobian.num_vertices, kVertices);
  const MatrixXd analytic = jacobian.ToDense();
  ASSERT_TRUE(analytic.allFinite());

  // The templated double path returns the same bits as Evaluate.
  VecX r_double(m);
  ASSERT_TRUE(obs.Residuals(x.data(), r_double.data()));
  EXPECT_EQ((r_double - r).cwiseAbs().maxCoeff(), 0.0);

  std::vector<JetX> x_jet(kDofs), r_jet(m);
  for (int i = 0; i < kDofs; ++i) x_jet[i] = JetX(x.data()[i], i);
  ASSERT_TRUE(obs.Residuals(x_jet.data(), r_jet.data()));
  MatrixXd autodiff(m, kDofs);
  for (int i = 0; i < m; ++i) {
    // Jets take the same branches but Eigen orders (vectorises) their arithmetic differently.
    EXPECT_NEAR(r_jet[i].a, r(i), 1e-13 * (1.0 + std::abs(r(i)))) << "residual " << i;
    autodiff.row(i) = r_jet[i].v.transpose();
  }
  ASSERT_TRUE(autodiff.allFinite());

  // h = 1e-7 m against a geometry of 20 mm edges: truncation ~ h^2 / |e|^2 ~ 1e-11 relative,
  // rounding ~ 1e-16 |r| / h ~ 1e-9 of the Jacobian's scale; no foot crosses a region boundary
  // within h (the test samples keep a margin of 1e-4 or more).
  const double h = 1e-7;
  MatrixXd numeric(m, kDofs);
  for (int c = 0; c < kDofs; ++c) {
    Mat3X plus = x, minus = x;
    plus.data()[c] += h;
    minus.data()[c] -= h;
    VecX r_plus, r_minus;
    ASSERT_TRUE(obs.Evaluate(plus, &r_plus));
    ASSERT_TRUE(obs.Evaluate(minus, &r_minus));
    numeric.col(c) = (r_plus - r_minus) / (2.0 * h);
  }
  const double scale = analytic.norm();
  ASSERT_GT(scale, 0.0);
  // Closed form and Jets evaluate the same formula in a different order: rounding only.
  EXPECT_LT((analytic - autodiff).norm(), 1e-12 * scale)
      << "closed form\n" << analytic << "\nautodiff\n" << autodiff;
  EXPECT_LT((analytic - numeric).norm(), 1e-6 * scale)
      << "closed form\n" << analytic << "\ncentral differences\n" << numeric;
}

// ---------------------------------------------------------------------------------------------
// Arc-length location and the sparse Jacobian.

TEST(LocateArcLength, EndsAndVerticesAreExact) {
  const std::vector<double> arc = RestArcLengths();
  ArcLocation at = LocateArcLength(arc, 0.0);
  EXPECT_EQ(at.edge, 0);
  EXPECT_EQ(at.a, 0.0);
  at = LocateArcLength(arc, kLength);
  EXPECT_EQ(at.edge, kEdges - 1);
  EXPECT_EQ(at.a, 1.0);
  at = LocateArcLength(arc, arc[4]);
  EXPECT_EQ(at.edge, 4);
  EXPECT_EQ(at.a, 0.0);
  at = LocateArcLength(arc, 0.5 * (arc[6] + arc[7]));
  EXPECT_EQ(at.edge, 6);
  EXPECT_NEAR(at.a, 0.5, 1e-12);
  // L typed differently from n (L / n) by rounding is still the end.
  at = LocateArcLength(arc, arc.back() * (1.0 + 4e-16));
  EXPECT_EQ(at.edge, kEdges - 1);
  EXPECT_EQ(at.a, 1.0);
}

TEST(VertexJacobian, SparseDenseAndProductAgree) {
  const Mat3X x = BentRod();
  const std::vector<double> arc = RestArcLengths();
  std::vector<Marker3d> markers;
  for (double s : {0.0, 0.031, 0.1, kLength}) markers.push_back({s, Interpolate(x, arc, s)});
  const Markers3dObservation obs(arc, markers, 1e-3);
  VecX r;
  VertexJacobian jacobian;
  ASSERT_TRUE(obs.Evaluate(x, &r, &jacobian));
  const MatrixXd dense = jacobian.ToDense();
  EXPECT_EQ((MatrixXd(jacobian.ToSparse()) - dense).norm(), 0.0);
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  MatrixXd d_x_d_p(kDofs, 4);
  for (int i = 0; i < d_x_d_p.size(); ++i) d_x_d_p.data()[i] = normal(rng);
  EXPECT_LT((jacobian.Multiply(d_x_d_p) - dense * d_x_d_p).norm(),
            1e-12 * (dense * d_x_d_p).norm());
  EXPECT_THROW(jacobian.Multiply(MatrixXd::Zero(kDofs + 3, 1)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// markers3d

std::vector<double> MarkerArcLengths() {
  // s = 0, s = L, a marker exactly on vertex 3, and interior ones.
  const std::vector<double> arc = RestArcLengths();
  return {0.0, arc[3], 0.0137, 0.0921, 0.1555, kLength};
}

TEST(Markers3d, ZeroResidualOnTheSameRodAndOffsetOverSigma) {
  const Mat3X x = BentRod();
  const std::vector<double> arc = RestArcLengths();
  const double sigma = 3e-4;
  std::vector<Marker3d> exact, shifted;
  const Vector3d offset(1e-3, -2e-3, 0.5e-3);
  for (double s : MarkerArcLengths()) {
    exact.push_back({s, Interpolate(x, arc, s)});
    shifted.push_back({s, Interpolate(x, arc, s) + offset});
  }
  // The ends and the vertex marker are the vertices themselves.
  EXPECT_EQ(exact.front().p_world, Vector3d(x.col(0)));
  EXPECT_EQ(exact[1].p_world, Vector3d(x.col(3)));
  EXPECT_EQ(exact.back().p_world, Vector3d(x.col(kEdges)));

  VecX r;
  ASSERT_TRUE(Markers3dObservation(arc, exact, sigma).Evaluate(x, &r));
  EXPECT_EQ(r.cwiseAbs().maxCoeff(), 0.0);

  const Markers3dObservation obs(arc, shifted, sigma);
  ASSERT_TRUE(obs.Evaluate(x, &r));
  ASSERT_EQ(r.size(), 3 * static_cast<int>(shifted.size()));
  for (int k = 0; k < obs.num_measurements(); ++k) {
    // Residual = model - measured = -offset / sigma; rounding of ~0.2 m / 3e-4 m.
    EXPECT_LT((r.segment<3>(3 * k) + offset / sigma).norm(), 1e-10) << "marker " << k;
  }
  double rms = 0.0;
  ASSERT_TRUE(obs.RmsError(x, &rms));
  EXPECT_NEAR(rms, offset.norm(), 1e-15);
}

TEST(Markers3d, JacobianMatchesJetsAndCentralDifferences) {
  const Mat3X x = BentRod();
  const std::vector<double> arc = RestArcLengths();
  std::vector<Marker3d> markers;
  for (double s : MarkerArcLengths()) {
    markers.push_back({s, Interpolate(x, arc, s) + Vector3d(2e-4, 1e-4, -3e-4)});
  }
  ExpectJacobiansAgree(Markers3dObservation(arc, markers, 3e-4), x);
}

TEST(Markers3d, RejectsArcLengthOutsideTheRod) {
  const std::vector<double> arc = RestArcLengths();
  const Vector3d p = Vector3d::Zero();
  auto message = [&](double s) -> std::string {
    try {
      Markers3dObservation(arc, {{0.05, p}, {s, p}}, 1e-3);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no exception";
  };
  EXPECT_THAT(message(0.201), HasSubstr("s = 0.201"));
  EXPECT_THAT(message(0.201), HasSubstr("marker 1"));
  EXPECT_THAT(message(-0.003), HasSubstr("s = -0.003"));
  EXPECT_THAT(message(std::nan("")), HasSubstr("s = nan"));
  EXPECT_EQ(message(kLength), "no exception");
  EXPECT_EQ(message(0.0), "no exception");
  EXPECT_THROW(ImageMarkersObservation(arc, RodCamera(), {{0.25, Vector2d(1, 2)}}, 0.5),
               std::invalid_argument);
}

TEST(Markers3d, RejectsBadSigmaEmptyInputAndWrongStateSize) {
  const std::vector<double> arc = RestArcLengths();
  const std::vector<Marker3d> one = {{0.1, Vector3d::Zero()}};
  EXPECT_THROW(Markers3dObservation(arc, one, 0.0), std::invalid_argument);
  EXPECT_THROW(Markers3dObservation(arc, one, -1.0), std::invalid_argument);
  EXPECT_THROW(Markers3dObservation(arc, {}, 1e-3), std::invalid_argument);
  const Markers3dObservation obs(arc, one, 1e-3);
  VecX r;
  EXPECT_THROW(obs.Evaluate(Mat3X::Zero(3, kVertices - 1), &r), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// points3d

// Samples exercising every foot kind, with the foot each one must have (checked in the tests).
struct Sample3 {
  Vector3d q;
  int edge;    // expected foot edge (interior feet)
  int vertex;  // expected foot vertex, -1 for interior
};

std::vector<Sample3> FootCases(const Mat3X& x) {
  std::vector<Sample3> samples;
  const Vector3d up(0.0, 0.0, 1.0);
  // Interior feet, 0.3 mm off the rod perpendicular to the edge, and one exactly on the rod.
  const int edges[] = {1, 4, 6, 8};
  const double ts[] = {0.35, 0.6, 0.45, 0.5};
  for (int i = 0; i < 4; ++i) {
    const int j = edges[i];
    const Vector3d p = (1.0 - ts[i]) * x.col(j) + ts[i] * x.col(j + 1);
    const Vector3d n = Perpendicular(UnitTangent(x, j), i % 2 ? up : Vector3d(1, 1, 0));
    samples.push_back({p + 3e-4 * n, j, -1});
  }
  samples.push_back({0.5 * (x.col(2) + x.col(3)), 2, -1});
  // Foot exactly at vertex 5: 1 mm out along the outer bisector of the bend (t_4 - t_5),
  // strictly inside the vertex's normal cone.
  const Vector3d out = (UnitTangent(x, 4) - UnitTangent(x, 5)).normalized();
  samples.push_back({x.col(5) + 1e-3 * out, 4, 5});
  // Beyond each end: 3 mm past the end along the end edge, 0.5 mm to the side.
  const Vector3d t0 = UnitTangent(x, 0), tn = UnitTangent(x, kEdges - 1);
  samples.push_back({x.col(0) - 3e-3 * t0 + 5e-4 * Perpendicular(t0, up), 0, 0});
  samples.push_back(
      {x.col(kEdges) + 3e-3 * tn + 5e-4 * Perpendicular(tn, up), kEdges - 1, kEdges});
  return samples;
}

TEST(Points3d, FootSearchFindsEachKind) {
  const Mat3X x = BentRod();
  for (const Sample3& sample : FootCases(x)) {
    const PolylineFoot foot = ClosestPointOnPolyline<3>(x, sample.q);
    EXPECT_EQ(foot.vertex, sample.vertex) << sample.q.transpose();
    if (sample.vertex < 0) {
      EXPECT_EQ(foot.edge, sample.edge);
      EXPECT_GT(foot.t, 0.0);
      EXPECT_LT(foot.t, 1.0);
    }
  }
}

TEST(Points3d, JacobianMatchesJetsAndCentralDifferences) {
  const Mat3X x = BentRod();
  std::vector<Vector3d> samples;
  for (const Sample3& sample : FootCases(x)) samples.push_back(sample.q);
  ExpectJacobiansAgree(Points3dObservation(kVertices, samples, 1e-3), x);
}

TEST(Points3d, ZeroResidualOnTheRodAndOffsetOverSigma) {
  const Mat3X x = BentRod();
  const double sigma = 5e-4;
  // On the rod: interior points and vertices (ends included).
  std::vector<Vector3d> on_rod;
  for (int j = 0; j < kEdges; ++j) on_rod.push_back(0.3 * x.col(j) + 0.7 * x.col(j + 1));
  for (int i = 0; i <= kEdges; ++i) on_rod.push_back(x.col(i));
  VecX r;
  ASSERT_TRUE(Points3dObservation(kVertices, on_rod, sigma).Evaluate(x, &r));
  EXPECT_LT(r.cwiseAbs().maxCoeff(), 1e-12);  // rounding of ~0.2 m / 5e-4 m

  // Known offsets: perpendicular to an interior edge, and along the end edge past the tip.
  const double d = 4e-4;
  const Vector3d n = Perpendicular(UnitTangent(x, 3), Vector3d::UnitZ());
  const Vector3d tn = UnitTangent(x, kEdges - 1);
  const Points3dObservation obs(
      kVertices, {0.5 * (x.col(3) + x.col(4)) + d * n, Vector3d(x.col(kEdges) + d * tn)}, sigma);
  ASSERT_TRUE(obs.Evaluate(x, &r));
  EXPECT_LT((r.segment<3>(0) + d * n / sigma).norm(), 1e-10);
  EXPECT_LT((r.segment<3>(3) + d * tn / sigma).norm(), 1e-10);
  double rms = 0.0;
  ASSERT_TRUE(obs.RmsError(x, &rms));
  EXPECT_NEAR(rms, d, 1e-15);
}

TEST(Points3d, FootOnTheBoundaryOfAVertexConeIsOneSided) {
  // An L-shaped polyline with dyadic coordinates, so that the sample's projection onto edge 0 is
  // exactly t = 1: the sample lies on the boundary of vertex 1's normal cone, where the residual
  // has a kink. The value must be the vector to the vertex, the Jacobian finite, and each of its
  // columns one of the one-sided derivatives (forward or backward difference; continuity makes
  // them agree along directions tangent to the boundary).
  Mat3X x(3, 3);
  x.col(0) = Vector3d(0.0, 0.0, 0.0);
  x.col(1) = Vector3d(0.5, 0.0, 0.0);
  x.col(2) = Vector3d(0.5, 0.5, 0.25);
  const Vector3d q(0.5, -0.25, 0.125);
  const Points3dObservation obs(3, {q}, 1.0);
  const PolylineFoot foot = ClosestPointOnPolyline<3>(x, q);
  EXPECT_EQ(foot.vertex, 1);
  VecX r;
  VertexJacobian jacobian;
  ASSERT_TRUE(obs.Evaluate(x, &r, &jacobian));
  EXPECT_EQ((r - (x.col(1) - q)).norm(), 0.0);
  const MatrixXd analytic = jacobian.ToDense();
  ASSERT_TRUE(analytic.allFinite());
  // One-sided differences err by ~ h |d2 r| ~ h / |e| = 2e-6 with h = 1e-6 and |e| = 0.5.
  const double h = 1e-6;
  for (int c = 0; c < 9; ++c) {
    Mat3X plus = x, minus = x;
    plus.data()[c] += h;
    minus.data()[c] -= h;
    VecX r_plus, r_minus;
    ASSERT_TRUE(obs.Evaluate(plus, &r_plus));
    ASSERT_TRUE(obs.Evaluate(minus, &r_minus));
    const VecX forward = (r_plus - r) / h, backward = (r - r_minus) / h;
    const double error = std::min((analytic.col(c) - forward).norm(),
                                  (analytic.col(c) - backward).norm());
    EXPECT_LT(error, 1e-5) << "column " << c << "\nclosed form " << analytic.col(c).transpose()
                           << "\nforward " << forward.transpose() << "\nbackward "
                           << backward.transpose();
  }
  // The Jet path takes the same side.
  std::vector<ceres::Jet<double, 9>> x_jet(9), r_jet(3);
  for (int i = 0; i < 9; ++i) x_jet[i] = ceres::Jet<double, 9>(x.data()[i], i);
  ASSERT_TRUE(obs.Residuals(x_jet.data(), r_jet.data()));
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT((r_jet[i].v - analytic.row(i).transpose()).norm(), 1e-14);
  }
}

TEST(Points3d, NonFiniteVerticesFailTheEvaluation) {
  Mat3X x = BentRod();
  x.fill(std::numeric_limits<double>::quiet_NaN());
  const Points3dObservation obs(kVertices, {Vector3d::Zero()}, 1e-3);
  VecX r;
  EXPECT_FALSE(obs.Evaluate(x, &r));
  EXPECT_TRUE(r.array().isNaN().all());
}

// ---------------------------------------------------------------------------------------------
// image_points with s (markers in pixels)

TEST(ImageMarkers, ZeroResidualOnTheSameRodAndOffsetOverSigma) {
  const Mat3X x = BentRod();
  const std::vector<double> arc = RestArcLengths();
  const Camera camera = RodCamera();
  const double sigma = 0.5;  // [px]
  const Vector2d offset(3.0, -2.0);
  std::vector<MarkerPixel> exact, shifted;
  for (double s : MarkerArcLengths()) {
    Vector2d uv;
    ASSERT_TRUE(Project(camera, Interpolate(x, arc, s), &uv));
    ASSERT_TRUE(camera.InImage(uv)) << "s = " << s;
    exact.push_back({s, uv});
    shifted.push_back({s, uv + offset});
  }
  VecX r;
  ASSERT_TRUE(ImageMarkersObservation(arc, camera, exact, sigma).Evaluate(x, &r));
  EXPECT_LT(r.cwiseAbs().maxCoeff(), 1e-12);  // rounding of ~1000 px / 0.5 px

  const ImageMarkersObservation obs(arc, camera, shifted, sigma);
  ASSERT_TRUE(obs.Evaluate(x, &r));
  for (int k = 0; k < obs.num_measurements(); ++k) {
    EXPECT_LT((r.segment<2>(2 * k) + offset / sigma).norm(), 1e-11) << "marker " << k;
  }
  double rms = 0.0;
  ASSERT_TRUE(obs.RmsError(x, &rms));
  EXPECT_NEAR(rms, offset.norm(), 1e-12);
}

TEST(ImageMarkers, JacobianMatchesJetsAndCentralDifferences) {
  const Mat3X x = BentRod();
  const std::vector<double> arc = RestArcLengths();
  const Camera camera = RodCamera();
  std::vector<MarkerPixel> markers;
  for (double s : MarkerArcLengths()) {
    Vector2d uv;
    ASSERT_TRUE(Project(camera, Interpolate(x, arc, s), &uv));
    markers.push_back({s, uv + Vector2d(1.5, -0.7)});
  }
  ExpectJacobiansAgree(ImageMarkersObservation(arc, camera, markers, 0.5), x);
}

TEST(ImageMarkers, PointBehindTheCameraFailsTheEvaluation) {
  const std::vector<double> arc = RestArcLengths();
  const Camera camera = RodCamera();
  const Mat3X x = RodWithTipBehind(camera);
  const ImageMarkersObservation sees_tip(arc, camera, {{0.05, {600, 400}}, {kLength, {640, 480}}},
                                         0.5);
  VecX r;
  VertexJacobian jacobian;
  EXPECT_FALSE(sees_tip.Evaluate(x, &r, &jacobian));
  ASSERT_EQ(r.size(), sees_tip.num_residuals());
  EXPECT_TRUE(r.array().isNaN().all());
  double rms = 0.0;
  EXPECT_FALSE(sees_tip.RmsError(x, &rms));
  VecX r_double(sees_tip.num_residuals());
  EXPECT_FALSE(sees_tip.Residuals(x.data(), r_double.data()));
  std::vector<JetX> x_jet(kDofs), r_jet(sees_tip.num_residuals());
  for (int i = 0; i < kDofs; ++i) x_jet[i] = JetX(x.data()[i], i);
  EXPECT_FALSE(sees_tip.Residuals(x_jet.data(), r_jet.data()));

  // Markers away from the tip still evaluate.
  const ImageMarkersObservation misses_tip(arc, camera, {{0.05, {600, 400}}}, 0.5);
  EXPECT_TRUE(misses_tip.Evaluate(x, &r));
  EXPECT_TRUE(r.allFinite());
}

// ---------------------------------------------------------------------------------------------
// image_points without s (distance to the projected centre-line)

struct Sample2 {
  Vector2d m;
  int edge;
  int vertex;
};

Vector2d Normal2(const Vector2d& t) { return Vector2d(-t.y(), t.x()).normalized(); }

std::vector<Sample2> ImageFootCases(const Eigen::Matrix2Xd& uv) {
  auto tangent = [&](int j) { return Vector2d((uv.col(j + 1) - uv.col(j)).normalized()); };
  std::vector<Sample2> samples;
  // Interior feet 1.5 px off the projected edge, and one exactly on it.
  const int edges[] = {0, 3, 5, 9};
  const double ts[] = {0.4, 0.55, 0.5, 0.35};
  for (int i = 0; i < 4; ++i) {
    const int j = edges[i];
    const Vector2d p = (1.0 - ts[i]) * uv.col(j) + ts[i] * uv.col(j + 1);
    samples.push_back({p + (i % 2 ? 1.5 : -1.5) * Normal2(tangent(j)), j, -1});
  }
  samples.push_back({Vector2d(0.4 * uv.col(7) + 0.6 * uv.col(8)), 7, -1});
  // Foot exactly at vertex 6: 2 px out along the outer bisector of the image bend.
  const Vector2d out = (tangent(5) - tangent(6)).normalized();
  samples.push_back({uv.col(6) + 2.0 * out, 5, 6});
  // Beyond each end: 6 px past the end along the end edge, 1 px to the side.
  samples.push_back({uv.col(0) - 6.0 * tangent(0) + Normal2(tangent(0)), 0, 0});
  samples.push_back({uv.col(kEdges) + 6.0 * tangent(kEdges - 1) + Normal2(tangent(kEdges - 1)),
                     kEdges - 1, kEdges});
  return samples;
}

TEST(ImageCurve, FootSearchFindsEachKind) {
  const Eigen::Matrix2Xd uv = ProjectVertices(RodCamera(), BentRod());
  for (const Sample2& sample : ImageFootCases(uv)) {
    const PolylineFoot foot = ClosestPointOnPolyline<2>(uv, sample.m);
    EXPECT_EQ(foot.vertex, sample.vertex) << sample.m.transpose();
    if (sample.vertex < 0) {
      EXPECT_EQ(foot.edge, sample.edge);
      EXPECT_GT(foot.t, 0.0);
      EXPECT_LT(foot.t, 1.0);
    }
  }
}

TEST(ImageCurve, JacobianMatchesJetsAndCentralDifferences) {
  const Mat3X x = BentRod();
  const Camera camera = RodCamera();
  std::vector<Vector2d> pixels;
  for (const Sample2& sample : ImageFootCases(ProjectVertices(camera, x))) {
    pixels.push_back(sample.m);
  }
  ExpectJacobiansAgree(ImageCurveObservation(kVertices, camera, pixels, 0.5), x);
}

TEST(ImageCurve, ZeroResidualOnTheCurveAndOffsetOverSigma) {
  const Mat3X x = BentRod();
  const Camera camera = RodCamera();
  const Eigen::Matrix2Xd uv = ProjectVertices(camera, x);
  const double sigma = 0.8;
  std::vector<Vector2d> on_curve;
  for (int j = 0; j < kEdges; ++j) on_curve.push_back(0.25 * uv.col(j) + 0.75 * uv.col(j + 1));
  for (int i = 0; i <= kEdges; ++i) on_curve.push_back(uv.col(i));
  VecX r;
  ASSERT_TRUE(ImageCurveObservation(kVertices, camera, on_curve, sigma).Evaluate(x, &r));
  EXPECT_LT(r.cwiseAbs().maxCoeff(), 1e-11);  // rounding of ~1000 px / 0.8 px

  const double d = 2.5;  // [px]
  const Vector2d t4 = (uv.col(5) - uv.col(4)).normalized();
  const Vector2d t0 = (uv.col(1) - uv.col(0)).normalized();
  const ImageCurveObservation obs(
      kVertices, camera,
      {Vector2d(0.5 * (uv.col(4) + uv.col(5)) + d * Normal2(t4)), Vector2d(uv.col(0) - d * t0)},
      sigma);
  ASSERT_TRUE(obs.Evaluate(x, &r));
  EXPECT_LT((r.segment<2>(0) + d * Normal2(t4) / sigma).norm(), 1e-10);
  EXPECT_LT((r.segment<2>(2) - d * t0 / sigma).norm(), 1e-10);  // vector to the first vertex
  double rms = 0.0;
  ASSERT_TRUE(obs.RmsError(x, &rms));
  EXPECT_NEAR(rms, d, 1e-11);
}

TEST(ImageCurve, VertexBehindTheCameraFailsTheEvaluation) {
  const Camera camera = RodCamera();
  const ImageCurveObservation obs(kVertices, camera, {Vector2d(640, 480)}, 0.5);
  const Mat3X x = RodWithTipBehind(camera);
  VecX r;
  VertexJacobian jacobian;
  EXPECT_FALSE(obs.Evaluate(x, &r, &jacobian));
  EXPECT_TRUE(r.array().isNaN().all());
  VecX r_double(obs.num_residuals());
  EXPECT_FALSE(obs.Residuals(x.data(), r_double.data()));
  std::vector<JetX> x_jet(kDofs), r_jet(obs.num_residuals());
  for (int i = 0; i < kDofs; ++i) x_jet[i] = JetX(x.data()[i], i);
  EXPECT_FALSE(obs.Residuals(x_jet.data(), r_jet.data()));
  double rms = 0.0;
  EXPECT_FALSE(obs.RmsError(x, &rms));
  EXPECT_TRUE(obs.Evaluate(BentRod(), &r));
}

TEST(ImageCurve, RejectsAnInvalidCamera) {
  Camera camera = RodCamera();
  camera.K.fx = -1.0;
  EXPECT_THROW(ImageCurveObservation(kVertices, camera, {Vector2d(1, 2)}, 0.5),
               std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
