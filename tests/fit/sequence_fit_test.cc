// Stiffness and damping from marker sequences of a moving case (fit/motion_fit.h,
// FitSequences): a suture released straight from its clamp swings down under its weight, its
// markers recorded over time with Gaussian noise and missing samples. The fit, started 3x off,
// recovers the bending stiffness and the drag within 3 of its standard deviations, and over
// several noise draws the errors in standard deviations scatter as a unit normal would.
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/solve/case_dynamics.h"
#include "fit/swing_fixture.h"

namespace rodfit {
namespace {

using testing::Swing;

// Markers at 4 arc lengths every 10 ms (t = 0 included), Gaussian noise of `sigma` per
// coordinate (unless told not to add it), every 7th sample missing: one markers3d observation
// per time.
ObservationSequence Record(const Scene& truth, double sigma, unsigned seed, bool add_noise = true) {
  const std::vector<double> s = {0.05, 0.1, 0.15, 0.2};
  std::vector<double> t;
  for (int k = 0; k <= 25; ++k) t.push_back(0.01 * k);
  const CaseSamples run = SampleCaseDynamics(truth, 0, StaticsOptions(), s, t, {});
  EXPECT_TRUE(run.ok) << run.reason;
  const std::vector<double> arc = CaseVertexArcLengths(truth, 0);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, sigma);
  ObservationSequence seq;
  int n = 0;
  for (size_t k = 0; k < t.size() && k < run.x.size(); ++k) {
    std::vector<Marker3d> seen;
    for (size_t m = 0; m < s.size(); ++m) {
      const Eigen::Vector3d noise(gauss(rng), gauss(rng), gauss(rng));
      if (++n % 7 == 0) continue;  // not seen
      seen.push_back({s[m], run.x[k].col(m) + (add_noise ? noise : Eigen::Vector3d::Zero())});
    }
    if (!seen.empty())
      seq.frames.push_back({t[k],
                            MakeShapeMeasurement("markers3d", "markers3d",
                                                 Markers3dObservation(arc, seen, sigma)),
                            {}});
  }
  return seq;
}

TEST(SequenceFit, RecoversBendingStiffnessAndDragWithCredibleStd) {
  const Scene truth = Swing();
  const std::vector<std::string> names = {"bend_stiffness", "damping"};
  const double true_values[2] = {truth.material.bend_stiffness, truth.material.damping};
  Scene start = truth;
  start.material.bend_stiffness = 3.0 * truth.material.bend_stiffness;
  start.material.damping = truth.material.damping / 3.0;
  double sum_z2 = 0.0;
  int fits = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u}) {
    const ObservationSequence seq = Record(truth, 1e-3, seed);
    const MotionFitResult r =
        FitSequences(start, {seq}, names, StaticsOptions(), MotionFitOptions());
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_EQ(r.residuals, 3 * seq.num_samples());
    EXPECT_EQ(r.noise_residuals, r.residuals);
    // The noise is what the sigma says: the residual variance is 1 within its spread
    // (sqrt(2 / dof) = 0.07 for 264 residuals).
    EXPECT_NEAR(r.residual_variance, 1.0, 0.3);
    for (int k = 0; k < 2; ++k) {
      ASSERT_TRUE(r.identifiable[k]) << names[k] << ": " << r.reason[k];
      const double z = (r.values[k] - true_values[k]) / r.std[k];
      std::printf("seed %u  %-15s truth %.4g  fitted %.4g +- %.2g  (%+.2f std)  %.2f s\n", seed,
                  names[k].c_str(), true_values[k], r.values[k], r.std[k], z, r.seconds);
      EXPECT_LT(std::abs(z), 3.0) << names[k];
      // The data determine it to better than 10 %: the std is not made small by a wide range.
      EXPECT_LT(r.std[k], 0.1 * true_values[k]) << names[k];
      sum_z2 += z * z;
    }
    ++fits;
  }
  // Credible std: the mean squared error in std over 8 estimates is chi-square(8) / 8, below
  // 2.5 with probability 0.99 (too small a std would give errors of many std).
  EXPECT_LT(sum_z2 / (2 * fits), 2.5);
}

TEST(SequenceFit, RefusesAnIntegratorItCannotDifferentiate) {
  Scene s = Swing();
  const ObservationSequence seq = Record(s, 1e-3, 1);
  s.dynamics->integrator = "midpoint";
  EXPECT_THROW(FitSequences(s, {seq}, {"damping"}, StaticsOptions(), MotionFitOptions()),
               std::invalid_argument);
}

TEST(SequenceFit, EvaluateSequencesIsZeroAtTheTruthWithoutNoise) {
  const Scene truth = Swing();
  const ObservationSequence seq = Record(truth, 1e-3, 5, /*add_noise=*/false);
  const SequenceResiduals r = EvaluateSequences(truth, {seq}, StaticsOptions());
  ASSERT_TRUE(r.ok) << r.reason;
  ASSERT_EQ(r.error.size(), 1u);
  ASSERT_EQ(static_cast<int>(r.error[0].size()), seq.num_samples());
  // The predictions come from the vertices at each time (a marker interpolated between two),
  // the recording from the markers' own interpolation: equal to round-off of a 0.2 m rod.
  for (const Eigen::Vector3d& e : r.error[0]) EXPECT_LT(e.norm(), 1e-11);
}

}  // namespace
}  // namespace rodfit
