// Tests of triangulation and epipolar polyline matching (observe/triangulate.h): exact recovery
// from noise-free projections, the stereo depth error under pixel noise against its first-order
// prediction, and matching of projected 3-D curves for a rectified and a verged, distorted pair.
#include "rodfit/observe/triangulate.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include <gtest/gtest.h>

#include "camera_fixtures.h"

namespace rodfit {
namespace {

using testing::DistortionSets;
using testing::Intrinsics;
using Curve = std::function<Eigen::Vector3d(double)>;

// Rectified pair: identical undistorted intrinsics, B displaced by the baseline along A's x axis.
constexpr double kBaseline = 0.1;  // [m]
std::pair<Camera, Camera> RectifiedPair() {
  Camera a, b;
  a.K = b.K = Intrinsics(0, 0, 0, 0, 0);
  b.cam_from_world_t = Eigen::Vector3d(-kBaseline, 0.0, 0.0);
  return {a, b};
}

// Verged pair, 0.24 m apart, both aimed at (0, 0, 0.5) with a slight roll between them, and a
// typical calibrated lens distortion: epipolar lines are neither rows nor parallel.
std::pair<Camera, Camera> VergedPair() {
  const CameraIntrinsics K = DistortionSets().back().K;
  const Eigen::Vector3d target(0.0, 0.0, 0.5);
  return {CameraLookingAt(K, {-0.12, -0.03, 0.0}, target, {0.0, -1.0, 0.0}),
          CameraLookingAt(K, {0.12, 0.02, 0.03}, target, {0.15, -1.0, 0.0})};
}

std::vector<Eigen::Vector2d> ProjectCurve(const Camera& cam, const Curve& r, int n, double t0,
                                          double t1) {
  std::vector<Eigen::Vector2d> uv(n);
  for (int i = 0; i < n; ++i) {
    EXPECT_TRUE(Project(cam, r(t0 + (t1 - t0) * i / (n - 1)), &uv[i]));
  }
  return uv;
}

// Curve parameter of the closest point of r on [t0, t1] to p (dense sampling + one refinement).
double ClosestParameter(const Curve& r, const Eigen::Vector3d& p, double t0, double t1) {
  const int n = 4000;
  double best_t = t0, best_d = INFINITY;
  for (int i = 0; i <= n; ++i) {
    const double t = t0 + (t1 - t0) * i / n;
    const double d = (r(t) - p).squaredNorm();
    if (d < best_d) best_d = d, best_t = t;
  }
  const double h = (t1 - t0) / n;
  for (int i = -100; i <= 100; ++i) {
    const double t = std::clamp(best_t + h * i / 100.0, t0, t1);
    const double d = (r(t) - p).squaredNorm();
    if (d < best_d) best_d = d, best_t = t;
  }
  return best_t;
}

TEST(Triangulate, ExactFromNoiseFreeProjections) {
  const auto [a, b] = VergedPair();
  const Camera c = CameraLookingAt(DistortionSets()[1].K, {0.0, 0.15, 0.05}, {0, 0, 0.5},
                                   {0, -1, 0});
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.08, 0.08);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p(u(rng), u(rng), 0.5 + u(rng));
    std::vector<PixelView> views;
    for (const Camera* cam : {&a, &b, &c}) {
      PixelView v{cam, {}};
      ASSERT_TRUE(Project(*cam, p, &v.uv));
      views.push_back(v);
    }
    Eigen::Vector3d p_dlt;
    ASSERT_TRUE(TriangulateLinear(views, &p_dlt));
    EXPECT_LT((p_dlt - p).norm(), 1e-11);
    const TriangulatedPoint two = Triangulate(a, views[0].uv, b, views[1].uv);
    const TriangulatedPoint three = Triangulate(views);
    for (const TriangulatedPoint& t : {two, three}) {
      ASSERT_TRUE(t.ok);
      EXPECT_LT((t.p_world - p).norm(), 1e-11);
      EXPECT_LT(t.max_error_px, 1e-8);
    }
  }
}

TEST(Triangulate, RejectsDegenerateInput) {
  const auto [a, b] = RectifiedPair();
  Eigen::Vector2d uv;
  ASSERT_TRUE(Project(a, Eigen::Vector3d(0.01, 0.02, 0.5), &uv));
  EXPECT_FALSE(Triangulate(std::vector<PixelView>{{&a, uv}}).ok) << "one view";
  // The same pixel in both cameras of a rectified pair: parallel rays, point at infinity.
  EXPECT_FALSE(Triangulate(a, uv, b, uv).ok);
  // Negative disparity: the rays meet behind the cameras.
  EXPECT_FALSE(Triangulate(a, uv, b, uv + Eigen::Vector2d(20.0, 0.0)).ok);
  EXPECT_THROW(Triangulate(std::vector<PixelView>{{nullptr, uv}, {&b, uv}}),
               std::invalid_argument);
}

TEST(Triangulate, DepthErrorUnderPixelNoiseMatchesTheStereoPrediction) {
  // Rectified pair: Z = f B / d, so to first order sigma_Z = Z^2 / (f B) * sqrt(2) sigma_px
  // (the disparity is the difference of two noisy u's). The RMS of the error divided by the
  // prediction is 1 up to sampling: with N = 1000 its relative spread is 1/sqrt(2N) = 2.2%, so
  // +-10% is a 4.5-sigma band.
  const auto [a, b] = RectifiedPair();
  const double sigma_px = 0.5;
  std::mt19937 rng(20240611);
  std::normal_distribution<double> noise(0.0, sigma_px);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const int n = 1000;
  double sum_sq = 0.0, sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double z = 0.3 + 0.4 * unit(rng);
    const Eigen::Vector3d p((unit(rng) - 0.3) * 0.3 * z, (unit(rng) - 0.5) * 0.5 * z, z);
    Eigen::Vector2d ua, ub;
    ASSERT_TRUE(Project(a, p, &ua) && Project(b, p, &ub));
    ua += Eigen::Vector2d(noise(rng), noise(rng));
    ub += Eigen::Vector2d(noise(rng), noise(rng));
    const TriangulatedPoint t = Triangulate(a, ua, b, ub);
    ASSERT_TRUE(t.ok);
    const double predicted = z * z / (a.K.fx * kBaseline) * std::sqrt(2.0) * sigma_px;
    const double normalized = (t.p_world.z() - z) / predicted;
    sum += normalized;
    sum_sq += normalized * normalized;
  }
  EXPECT_NEAR(std::sqrt(sum_sq / n), 1.0, 0.1);
  EXPECT_NEAR(sum / n, 0.0, 0.15);  // bias is second order; 0.15 is ~4.7 standard errors
}

// Checks a match result against the curve r sampled for polyline A at n_a points on [t0, t1].
void ExpectMatchesFollowTheCurve(const PolylineMatchResult& m, const Curve& r, int n_a, double t0,
                                 double t1, double min_fraction) {
  ASSERT_FALSE(m.points.empty());
  EXPECT_GE(static_cast<double>(m.points.size()), min_fraction * n_a)
      << "no crossing " << m.num_no_crossing << ", failed " << m.num_failed << ", unordered "
      << m.num_unordered;
  double previous_t = -INFINITY;
  int previous_index = -1;
  std::vector<double> errors;
  for (const PolylineMatch& p : m.points) {
    EXPECT_GT(p.index_a, previous_index);
    previous_index = p.index_a;
    EXPECT_LT(p.error_px, 1e-6);
    const double t = ClosestParameter(r, p.p_world, t0, t1);
    // Order along A is order along the curve (small tolerance for the sampling of the search).
    EXPECT_GT(t, previous_t - 1e-6) << "index_a " << p.index_a;
    previous_t = t;
    // Distance to the curve: the chord of B between samples deviates from the projected curve
    // by ~ h^2 kappa / 8 ~ 1e-3 px, i.e. ~1e-5 m in depth; where the curve runs along the
    // epipolar line the point slides along the curve instead, which stays close to it.
    EXPECT_LT((r(t) - p.p_world).norm(), 1e-4) << "index_a " << p.index_a;
    errors.push_back((r(t0 + (t1 - t0) * p.index_a / (n_a - 1)) - p.p_world).norm());
  }
  // Most points land at the very sample of A that produced them.
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() * 9 / 10], 1e-4);
}

TEST(MatchPolylines, RectifiedPairWithTwoCrossingsPerRow) {
  // A U-shaped thread in the image: every row crosses both branches, so the choice between
  // crossings must come from the order along B. Depth varies so the curve is truly 3-D.
  const auto [a, b] = RectifiedPair();
  const Curve r = [](double t) {
    return Eigen::Vector3d(0.08 * t, -0.05 + 0.1 * t * t, 0.5 + 0.04 * t + 0.02 * std::sin(3 * t));
  };
  const int n_a = 300;
  const auto poly_a = ProjectCurve(a, r, n_a, -1.0, 1.0);
  const auto poly_b = ProjectCurve(b, r, 701, -1.0, 1.0);
  const PolylineMatchResult m = MatchPolylines(a, poly_a, b, poly_b);
  ExpectMatchesFollowTheCurve(m, r, n_a, -1.0, 1.0, 0.95);
  for (const PolylineMatch& p : m.points) {
    EXPECT_NEAR(p.uv_b.y(), poly_a[p.index_a].y(), 1e-9) << "rectified: same row";
  }

  // B listed in reverse order: the same points, positions along B decreasing.
  std::vector<Eigen::Vector2d> reversed(poly_b.rbegin(), poly_b.rend());
  const PolylineMatchResult m_rev = MatchPolylines(a, poly_a, b, reversed);
  ASSERT_EQ(m_rev.points.size(), m.points.size());
  for (size_t i = 0; i < m.points.size(); ++i) {
    EXPECT_LT((m_rev.points[i].p_world - m.points[i].p_world).norm(), 1e-9);
    if (i > 0) {
      EXPECT_LE(m_rev.points[i].position_b, m_rev.points[i - 1].position_b);
    }
  }
}

TEST(MatchPolylines, VergedDistortedPairOfAHelix) {
  // A helix about the x axis seen by verged cameras with lens distortion: epipolar lines are
  // oblique and cross the projected helix several times.
  const auto [a, b] = VergedPair();
  const Curve r = [](double t) {
    return Eigen::Vector3d(0.1 * t, 0.04 * std::cos(4 * t), 0.5 + 0.04 * std::sin(4 * t));
  };
  const int n_a = 400;
  const auto poly_a = ProjectCurve(a, r, n_a, -1.0, 1.0);
  const auto poly_b = ProjectCurve(b, r, 900, -1.0, 1.0);
  const PolylineMatchResult m = MatchPolylines(a, poly_a, b, poly_b);
  ExpectMatchesFollowTheCurve(m, r, n_a, -1.0, 1.0, 0.9);
}

TEST(MatchPolylines, DropsPixelsWithoutACrossingOrAboveTheErrorThreshold) {
  // B sees only the lower part of a thread that runs down the image: the upper pixels of A have
  // no crossing and are dropped; the rest match.
  const auto [a, b] = RectifiedPair();
  const Curve r = [](double t) {
    return Eigen::Vector3d(0.02 * std::sin(2 * t), 0.08 * t, 0.45 + 0.05 * t * t);
  };
  const int n_a = 200;
  const auto poly_a = ProjectCurve(a, r, n_a, -1.0, 1.0);
  const auto poly_b = ProjectCurve(b, r, 300, 0.0, 1.0);
  const PolylineMatchResult m = MatchPolylines(a, poly_a, b, poly_b);
  EXPECT_GE(m.num_no_crossing, 95);
  EXPECT_LE(m.num_no_crossing, 101);
  EXPECT_EQ(static_cast<int>(m.points.size()) + m.num_no_crossing, n_a);
  for (const PolylineMatch& p : m.points) EXPECT_GT(p.p_world.y(), -1e-4) << "outside B's part";
  ExpectMatchesFollowTheCurve(m, r, n_a, -1.0, 1.0, 0.45);

  PolylineMatchOptions strict;
  strict.max_reprojection_error_px = -1.0;  // nothing can pass
  const PolylineMatchResult none = MatchPolylines(a, poly_a, b, poly_b, strict);
  EXPECT_TRUE(none.points.empty());
  EXPECT_EQ(none.num_rejected, n_a - none.num_no_crossing);
}

}  // namespace
}  // namespace rodfit
