// Observation sequences beyond 3-D markers (fit/motion_fit.h, EvaluateSequenceResiduals and
// FitSequences): a moving thread seen frame by frame through a camera (image_points with s:
// markers in pixels; without: centre-line pixels, closest-point residuals) or as 3-D centre-line
// points. The Jacobian the fit uses — each frame's closed-form vertex Jacobian chained with the
// trajectory's sensitivities — equals central differences of the residuals over the whole run,
// the closest-point kinds carry the noise of one residual less per sample, and one camera's
// centre-line pixels with 0.5 px of noise recover the bending stiffness and the drag of the
// swinging suture within about 2 of their standard deviations.
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fit/swing_fixture.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/solve/case_dynamics.h"

namespace rodfit {
namespace {

using testing::Swing;
using testing::SwingCamera;

enum class Kind { kPixelMarkers, kPixelCurve, kPoints3d };

const char* Name(Kind kind) {
  return kind == Kind::kPixelMarkers ? "pixel markers"
         : kind == Kind::kPixelCurve ? "centre-line pixels"
                                     : "3-D points";
}

// The swing seen every 10 ms (t = 0 included) at the middles of its 10 edges (a closest-point
// sample there has its foot inside an edge, away from the kinks of the foot rules at vertices),
// as `kind` with Gaussian noise of `sigma` [px or m] per coordinate.
ObservationSequence Observe(const Scene& truth, Kind kind, double sigma, unsigned seed) {
  const std::vector<double> arc = CaseVertexArcLengths(truth, 0);
  std::vector<double> t;
  for (int k = 0; k <= 25; ++k) t.push_back(0.01 * k);
  const CaseSamples run = SampleCaseDynamics(truth, 0, StaticsOptions(), arc, t, {});
  EXPECT_TRUE(run.ok) << run.reason;
  const Camera camera = SwingCamera();
  const int nv = static_cast<int>(arc.size());
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, sigma);
  ObservationSequence seq;
  for (size_t k = 0; k < run.x.size(); ++k) {
    std::vector<MarkerPixel> markers;
    std::vector<Eigen::Vector2d> pixels;
    std::vector<Eigen::Vector3d> points;
    for (int j = 0; j + 1 < nv; ++j) {
      const double s = 0.5 * (arc[j] + arc[j + 1]);
      const Eigen::Vector3d p = 0.5 * (run.x[k].col(j) + run.x[k].col(j + 1));
      if (kind == Kind::kPoints3d) {
        points.push_back(p + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)));
        continue;
      }
      Eigen::Vector2d uv;
      EXPECT_TRUE(Project(camera, p, &uv) && camera.InImage(uv)) << "t " << t[k] << " s " << s;
      uv += Eigen::Vector2d(gauss(rng), gauss(rng));
      markers.push_back({s, uv});
      pixels.push_back(uv);
    }
    std::shared_ptr<const Measurement> frame;
    if (kind == Kind::kPixelMarkers)
      frame = MakeShapeMeasurement("image_points", "image_points",
                                   ImageMarkersObservation(arc, camera, markers, sigma));
    else if (kind == Kind::kPixelCurve)
      frame = MakeShapeMeasurement("image_points", "image_points",
                                   ImageCurveObservation(nv, camera, pixels, sigma));
    else
      frame = MakeShapeMeasurement("points3d", "points3d", Points3dObservation(nv, points, sigma));
    seq.frames.push_back({t[k], frame, {}});
  }
  return seq;
}

Scene Scaled(const Scene& scene, const std::string& name, double log_step) {
  Scene out = scene;
  SetMotionParameter(name, MotionParameter(name, scene) * std::exp(log_step), &out);
  return out;
}

TEST(PixelSequences, JacobianMatchesCentralDifferences) {
  const Scene truth = Swing();
  // Away from the truth, so that every residual moves with every parameter.
  const Scene scene = Scaled(Scaled(truth, "bend_stiffness", std::log(1.3)), "damping",
                             std::log(0.7));
  const std::vector<std::string> names = {"bend_stiffness", "damping", "linear_density"};
  for (const Kind kind : {Kind::kPixelMarkers, Kind::kPixelCurve, Kind::kPoints3d}) {
    const double sigma = kind == Kind::kPoints3d ? 3e-4 : 0.5;
    const ObservationSequence seq = Observe(truth, kind, sigma, 11);
    const SequenceEvaluation at = EvaluateSequenceResiduals(scene, {seq}, names, StaticsOptions());
    ASSERT_TRUE(at.ok) << Name(kind) << ": " << at.reason;
    const int samples = seq.num_samples();
    ASSERT_EQ(at.residuals.size(), (kind == Kind::kPoints3d ? 3 : 2) * samples) << Name(kind);
    ASSERT_EQ(at.jacobian.cols(), 3);
    // A closest-point residual lies across the curve: one of its components carries no noise.
    EXPECT_EQ(at.noise_residuals, kind == Kind::kPixelMarkers ? 2 * samples
                                  : kind == Kind::kPixelCurve ? samples
                                                              : 2 * samples)
        << Name(kind);
    // In log p; the step of tests/solve/rollout_sensitivity_test.cc (no round-off at 1e-4,
    // truncation 2x worse at 1e-2).
    const double h = 1e-3;
    for (size_t k = 0; k < names.size(); ++k) {
      const SequenceEvaluation up =
          EvaluateSequenceResiduals(Scaled(scene, names[k], h), {seq}, {}, StaticsOptions());
      const SequenceEvaluation down =
          EvaluateSequenceResiduals(Scaled(scene, names[k], -h), {seq}, {}, StaticsOptions());
      ASSERT_TRUE(up.ok && down.ok) << names[k];
      const Eigen::VectorXd fd = (up.residuals - down.residuals) / (2.0 * h);
      const Eigen::VectorXd analytic = at.jacobian.col(static_cast<int>(k));
      const double largest = fd.cwiseAbs().maxCoeff();
      const double worst = (analytic - fd).cwiseAbs().maxCoeff();
      std::printf("%-18s %-15s largest |dr/dlog p| %.3e, disagreement %.2e relative\n",
                  Name(kind), names[k].c_str(), largest, worst / largest);
      EXPECT_GT(largest, 1.0) << Name(kind) << " " << names[k];  // in sigmas: the data see it
      EXPECT_LT(worst, 1e-5 * largest) << Name(kind) << " " << names[k];
    }
  }
}

TEST(PixelSequences, OneCameraRecoversBendingStiffnessAndDrag) {
  const Scene truth = Swing();
  const std::vector<std::string> names = {"bend_stiffness", "damping"};
  const double true_values[2] = {truth.material.bend_stiffness, truth.material.damping};
  const Scene start =
      Scaled(Scaled(truth, "bend_stiffness", std::log(3.0)), "damping", -std::log(3.0));
  double sum_z2 = 0.0;
  int estimates = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    const ObservationSequence seq = Observe(truth, Kind::kPixelCurve, 0.5, seed);
    const MotionFitResult r =
        FitSequences(start, {seq}, names, StaticsOptions(), MotionFitOptions());
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_EQ(r.residuals, 2 * seq.num_samples());
    EXPECT_EQ(r.noise_residuals, seq.num_samples());
    // The variance counts the residuals that carry noise: 1 within its spread (sqrt(2 / 258)
    // = 0.09); counted over all it would be about 0.5.
    EXPECT_NEAR(r.residual_variance, 1.0, 0.3);
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(r.identifiable[k]) << names[k] << ": " << r.reason[k];
      const double z = (r.values[k] - true_values[k]) / r.std[k];
      std::printf("seed %u  %-15s truth %.4g  fitted %.4g +- %.2g  (%+.2f std)  %d iterations, "
                  "%.2f s\n",
                  seed, names[k].c_str(), true_values[k], r.values[k], r.std[k], z, r.iterations,
                  r.seconds);
      EXPECT_LT(std::abs(z), 2.5) << names[k];
      EXPECT_LT(r.std[k], 0.1 * true_values[k]) << names[k];
      sum_z2 += z * z;
      ++estimates;
    }
  }
  // Credible std: the mean squared error in std over 6 estimates is chi-square(6) / 6, below
  // 2.8 with probability 0.99.
  EXPECT_LT(sum_z2 / estimates, 2.8);
}

TEST(PixelSequences, RefusesFramesItCannotPlace) {
  const Scene truth = Swing();
  ObservationSequence seq = Observe(truth, Kind::kPixelMarkers, 0.5, 1);
  const std::vector<std::string> names = {"damping"};
  {
    ObservationSequence late = seq;
    late.frames.back().t = 0.3;  // after dynamics.duration
    EXPECT_THROW(FitSequences(truth, {late}, names, StaticsOptions(), MotionFitOptions()),
                 std::invalid_argument);
  }
  {
    ObservationSequence swapped = seq;
    std::swap(swapped.frames[1], swapped.frames[2]);  // times out of order
    EXPECT_THROW(FitSequences(truth, {swapped}, names, StaticsOptions(), MotionFitOptions()),
                 std::invalid_argument);
  }
  {
    ObservationSequence coarse = seq;  // a frame on another rod's vertices
    coarse.frames[3].measurement = MakeShapeMeasurement(
        "points3d", "points3d",
        Points3dObservation(5, std::vector<Eigen::Vector3d>{Eigen::Vector3d::Zero()}, 1e-3));
    EXPECT_THROW(FitSequences(truth, {coarse}, names, StaticsOptions(), MotionFitOptions()),
                 std::invalid_argument);
  }
  {
    ObservationSequence numbered = seq;  // sample numbers in one frame only
    numbered.frames[0].sample.assign(numbered.frames[0].measurement->num_measurements(), 0);
    EXPECT_THROW(FitSequences(truth, {numbered}, names, StaticsOptions(), MotionFitOptions()),
                 std::invalid_argument);
  }
}

}  // namespace
}  // namespace rodfit
