// Stiffness and damping from recorded motion (fit/motion_fit.h). The recording: the held
// markers of a synthetic motion-capture sequence (solve/mocap_fixture.h: two grippers moving a
// cable), the free markers as the rollout's own model predicts them with known bending stiffness
// and drag. A fit started 3x off in both finds them again. (Fitted to the gripper sequence
// itself, whose clamps the rollout stands in for by pins at markers 1 and n-2, the same fit
// lands at 0.75 of the bending stiffness: that model difference, not the fit.) On a recording the
// rollout's model explains to the noise, the least-squares fit recovers them within 3 standard
// deviations in a quarter of BOBYQA's rollouts.
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/fit/motion_fit.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

TEST(MotionFit, RecoversBendingStiffnessAndDragFromARecording) {
  Material truth = testing::Cable().material;
  truth.bend_damping = 0.0;
  truth.damping = 0.2;
  truth.bend_stiffness = 2e-2;  // a stiff cable: bending length (B / rho g)^(1/3) = 0.37 m
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  Scene truth_scene = testing::Cable();
  truth_scene.material = truth;
  const RolloutResult made = Rollout(truth_scene, rec.frame_interval,
                                     testing::Recording(1.0, 0.0, 0.0, 3, &truth), RolloutOptions());
  ASSERT_TRUE(made.ok) << made.reason;
  rec.frames = made.predicted;
  Scene start = testing::Cable();
  start.material = truth;
  start.material.bend_stiffness = 3.0 * truth.bend_stiffness;
  start.material.damping = truth.damping / 3.0;
  const MotionFitResult r = FitToRecordings(start, {rec}, {"bend_stiffness", "damping"},
                                            RolloutOptions(), StaticsOptions(), 80);
  ASSERT_EQ(r.values.size(), 2u);
  EXPECT_LT(r.error_fitted, 0.5 * r.error_start);
  // Not exactly: the rollout rebuilds its start from the recording's first two frames (arc
  // lengths from frame 0's chords, velocities from a 10 ms difference), so even at the truth its
  // error is 0.43 mm, not 0; measured: B 0.965, drag 0.985 of the truth, error 4.4 -> 0.40 mm
  // (BOBYQA, the search before the least-squares fit, in 80 rollouts); the least-squares fit,
  // now the default: B 0.964, drag 0.985, 4.4 -> 0.40 mm in 11 rollouts.
  EXPECT_NEAR(r.values[0] / truth.bend_stiffness, 1.0, 0.05) << r.values[0];
  EXPECT_NEAR(r.values[1] / truth.damping, 1.0, 0.05) << r.values[1];
}

TEST(MotionFit, RefusesAParameterWithoutAStartValueOrUnknown) {
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = testing::Recording(0.05, 0.0, 0.0, 3);
  Scene s = testing::Cable();
  s.material.twist_damping = 0.0;
  EXPECT_THROW(FitToRecordings(s, {rec}, {"twist_damping"}, RolloutOptions(), StaticsOptions()),
               std::invalid_argument);
  EXPECT_THROW(FitToRecordings(s, {rec}, {"length"}, RolloutOptions(), StaticsOptions()),
               std::invalid_argument);
}

// A recording the rollout's own model explains to the noise: its frames 0 and 1 (the start the
// rollout rebuilds) and its held markers are the gripper sequence's, the free markers of later
// frames the rollout's prediction at the truth plus 0.5 mm of Gaussian noise. Only frame 1's
// free markers (the gripper model's, 10 ms in) are not the rollout's.
std::vector<Eigen::Matrix3Xd> SelfConsistentRecording(const Scene& truth, double seconds,
                                                      double noise, unsigned seed) {
  const std::vector<Eigen::Matrix3Xd> source =
      testing::Recording(seconds, 0.0, 0.0, 3, &truth.material, &truth.rod);
  const RolloutResult made = Rollout(truth, testing::kFrameInterval, source, RolloutOptions());
  EXPECT_TRUE(made.ok) << made.reason;
  std::vector<Eigen::Matrix3Xd> frames = source;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  for (size_t k = 2; k < frames.size(); ++k)
    for (int m = 0; m < static_cast<int>(frames[k].cols()); ++m) {
      if (made.held[m]) continue;
      frames[k].col(m) = made.predicted[k].col(m) + Vec3(gauss(rng), gauss(rng), gauss(rng));
    }
  return frames;
}

TEST(MotionFit, LeastSquaresRecoversStiffnessAndDragWithinThreeStdInFewRollouts) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  const double noise = 5e-4;
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = SelfConsistentRecording(truth, 0.6, noise, 11);
  Scene start = truth;
  start.material.bend_stiffness = 2.5 * truth.material.bend_stiffness;
  start.material.damping = truth.material.damping / 3.0;
  const std::vector<std::string> names = {"bend_stiffness", "damping"};
  const std::vector<double> want = {truth.material.bend_stiffness, truth.material.damping};
  MotionFitOptions lm;
  lm.marker_sigma = noise;
  const MotionFitResult r = FitMotion(start, {rec}, names, RolloutOptions(), StaticsOptions(), lm);
  ASSERT_TRUE(r.converged) << r.message;
  MotionFitOptions bobyqa = lm;
  bobyqa.method = MotionFitMethod::kBobyqa;
  const MotionFitResult b = FitMotion(start, {rec}, names, RolloutOptions(), StaticsOptions(), bobyqa);
  for (int k = 0; k < 2; ++k) {
    std::printf("%-15s truth %.5g  LM %.5g +- %.3g (%.2f std off)  BOBYQA %.5g\n", names[k].c_str(),
                want[k], r.values[k], r.std[k], (r.values[k] - want[k]) / r.std[k], b.values[k]);
    ASSERT_TRUE(r.identifiable[k]) << r.reason[k];
    EXPECT_LT(std::abs(r.values[k] - want[k]), 3.0 * r.std[k]) << names[k];
    EXPECT_LT(r.std[k], 0.05 * want[k]) << names[k];  // the data do pin them down
  }
  std::printf("LM: %d rollouts, %d iterations, %.2f s, residual variance %.3f; BOBYQA: %d "
              "rollouts, %.2f s\n",
              r.evaluations, r.iterations, r.seconds, r.residual_variance, b.evaluations, b.seconds);
  // Measured: B 0.02006 +- 0.00011, drag 0.1996 +- 0.0014 (0.5 and 0.3 std from the truth);
  // 9 rollouts with sensitivities (~1.1 s) against BOBYQA's 44 (~2.4 s; each of its rollouts
  // costs about half as much). The noise is the markers' sigma, so the residual variance is ~1 (1.12).
  EXPECT_NEAR(r.residual_variance, 1.0, 0.2);
  EXPECT_LT(r.error_fitted, 0.5 * r.error_start);
  EXPECT_LT(3 * r.evaluations, b.evaluations);
}

// The same recording with the linear density and the twist stiffness fitted too: the density
// (the masses and the weights) is determined as well as the others, the twist stiffness, which
// barely moves the markers of an isotropic cable, is reported as not identifiable, with the
// reason, and no standard deviation.
TEST(MotionFit, FitsTheLinearDensityAndReportsTheTwistStiffnessNotIdentifiable) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  const double noise = 5e-4;
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = SelfConsistentRecording(truth, 0.6, noise, 11);
  Scene start = truth;
  start.material.bend_stiffness *= 2.0;
  start.material.twist_stiffness *= 2.0;
  start.rod.linear_density *= 1.5;
  MotionFitOptions lm;
  lm.marker_sigma = noise;
  const std::vector<std::string> names = {"bend_stiffness", "damping", "linear_density",
                                          "twist_stiffness"};
  const std::vector<double> want = {truth.material.bend_stiffness, truth.material.damping,
                                    truth.rod.linear_density};
  const MotionFitResult r = FitMotion(start, {rec}, names, RolloutOptions(), StaticsOptions(), lm);
  ASSERT_TRUE(r.converged) << r.message;
  // Measured: B 0.01947 +- 0.00076, drag 0.1938 +- 0.0076, density 0.03881 +- 0.0016 (0.7 to
  // 0.8 std from the truth) in 46 rollouts; the twist stiffness ran to its bound along its flat
  // direction, the std of its log 3e4.
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE(r.identifiable[k]) << names[k] << ": " << r.reason[k];
    EXPECT_LT(std::abs(r.values[k] - want[k]), 3.0 * r.std[k]) << names[k];
  }
  EXPECT_FALSE(r.identifiable[3]);
  EXPECT_TRUE(std::isnan(r.std[3]));
  EXPECT_NE(r.reason[3].find("determined only within a factor"), std::string::npos) << r.reason[3];
}

// The rest shape from motion: a cable curved at rest (its bending curvature at 5 knots, both
// components, smooth within the prior), a recording its own rollout model explains to 0.5 mm of
// noise (its held markers and first two frames those of the same cable between two grippers);
// fitted together with the bending stiffness from a straight start 2.5x too stiff, without the
// noise given (estimated from the recording). Every knot and the stiffness land within 3 std
// of the truth (measured: B 0.76 std off, the knots within 1.9 std, the noise estimated at
// 0.501 mm); the largest |correlation| of a knot with the stiffness is 0.41.
TEST(MotionFit, FitsTheRestCurvatureWithTheBendingStiffness) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  truth.rod.rest_curvature_s = {0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0};
  truth.rod.rest_curvature_profile = {Vec3(0.5, 2.0, 0), Vec3(1.0, 2.5, 0), Vec3(1.2, 2.0, 0),
                                      Vec3(1.0, 1.0, 0)};
  const double noise = 5e-4;
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = SelfConsistentRecording(truth, 1.0, noise, 11);
  Scene start = truth;
  start.rod.rest_curvature_s.clear();
  start.rod.rest_curvature_profile.clear();
  start.material.bend_stiffness *= 2.5;
  const std::vector<std::string> names = {"bend_stiffness", "rest_curvature"};
  MotionFitOptions options;
  options.rest_curvature_knots = 4;
  const MotionFitResult r = FitMotion(start, {rec}, names, RolloutOptions(), StaticsOptions(), options);
  std::printf("%d rollouts, %d iterations, %.2f s: %s\n", r.evaluations, r.iterations, r.seconds,
              r.message.c_str());
  ASSERT_TRUE(r.converged) << r.message;
  ASSERT_EQ(r.values.size(), 9u);
  ASSERT_EQ(r.rest_curvature_s.size(), 4u);
  EXPECT_TRUE(r.marker_sigma_estimated);
  EXPECT_NEAR(r.marker_sigma / noise, 1.0, 0.2);
  std::vector<double> want = {truth.material.bend_stiffness};
  for (const Vec3& k : truth.rod.rest_curvature_profile) want.push_back(k[0]), want.push_back(k[1]);
  double worst_correlation = 0.0;
  for (size_t k = 0; k < r.values.size(); ++k) {
    std::printf("%-20s truth %8.4g  fitted %8.4g +- %.3g (%.2f std)\n", r.names[k].c_str(),
                want[k], r.values[k], r.std[k], (r.values[k] - want[k]) / r.std[k]);
    ASSERT_TRUE(r.identifiable[k]) << r.names[k] << ": " << r.reason[k];
    EXPECT_LT(std::abs(r.values[k] - want[k]), 3.0 * r.std[k]) << r.names[k];
    if (k > 0)
      worst_correlation = std::max(
          worst_correlation, std::abs(r.covariance_log(0, k)) /
                                 std::sqrt(r.covariance_log(0, 0) * r.covariance_log(k, k)));
  }
  std::printf("%d rollouts, %.2f s, residual variance %.3f, sigma %.3g mm (estimated), largest "
              "|correlation| with bend_stiffness %.2f\n",
              r.evaluations, r.seconds, r.residual_variance, 1e3 * r.marker_sigma,
              worst_correlation);
  // The fit's minimum is at least as low as the truth's cost. Neither is at the noise: frame 1's
  // free markers are the gripper model's, not the rollout's (measured: residual variance 6.4;
  // cost 7652 at the fit, 7921 at the truth, 2.7e6 at the start; 28 rollouts).
  MotionFitOptions at_truth = options;
  at_truth.max_evaluations = 1;
  at_truth.rest_start_from_first_frames = false;  // the truth's own rest shape, not a start
  const MotionFitResult z =
      FitMotion(truth, {rec}, names, RolloutOptions(), StaticsOptions(), at_truth);
  std::printf("cost at the truth %.6g, at the fit %.6g (start %.6g)\n", z.initial_cost,
              r.final_cost, r.initial_cost);
  EXPECT_LE(r.final_cost, z.initial_cost);
  EXPECT_EQ(r.prior_residuals, 4);
}

// The rest shape's start from the recordings' first frames (MotionFitOptions::
// rest_start_from_first_frames): the cable of the test above, its recording's free
// markers at frame 0 (the rod at rest) and the stiffness at the truth, fitted from straight. The
// frame-0 equilibrium then matches the first frame better than the truth's rest shape does
// (frame 0 here is the grippers' recording, not the rollout's equilibrium) and far better than
// the straight start. Measured: 71 mm straight, 2.4 mm from the first frames (145 short runs),
// 17 mm with the truth's rest shape.
TEST(MotionFit, StartsTheRestShapeFromTheFirstFrames) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  truth.rod.rest_curvature_s = {0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0};
  truth.rod.rest_curvature_profile = {Vec3(0.5, 2.0, 0), Vec3(1.0, 2.5, 0), Vec3(1.2, 2.0, 0),
                                      Vec3(1.0, 1.0, 0)};
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = SelfConsistentRecording(truth, 0.3, 5e-4, 11);
  // The truth's own frame-0 equilibrium against the first frame.
  std::vector<Eigen::Matrix3Xd> first = {rec.frames[0], rec.frames[1]};
  const RolloutResult at_truth = Rollout(truth, rec.frame_interval, first, RolloutOptions());
  ASSERT_TRUE(at_truth.ok) << at_truth.reason;
  double truth_misfit = 0.0;
  int free_markers = 0;
  for (size_t m = 0; m < at_truth.held.size(); ++m) {
    if (at_truth.held[m]) continue;
    truth_misfit += (at_truth.predicted[0].col(m) - rec.frames[0].col(m)).norm();
    ++free_markers;
  }
  truth_misfit /= free_markers;
  Scene start = truth;
  start.rod.rest_curvature_s.clear();
  start.rod.rest_curvature_profile.clear();
  MotionFitOptions options;
  options.rest_curvature_knots = 4;
  options.max_evaluations = 1;  // the start is what is tested
  options.rest_start_from_first_frames = true;
  const MotionFitResult r = FitMotion(start, {rec}, {"bend_stiffness", kRestCurvatureParameter},
                                      RolloutOptions(), StaticsOptions(), options);
  std::printf("frame-0 misfit: straight %.3f mm, rest start %.3f mm (%d runs: %s), truth %.3f mm\n",
              1e3 * r.rest_start_misfit_before, 1e3 * r.rest_start_misfit_after,
              r.rest_start_runs, r.rest_start_message.c_str(), 1e3 * truth_misfit);
  ASSERT_TRUE(std::isfinite(r.rest_start_misfit_after)) << r.rest_start_message;
  EXPECT_LT(r.rest_start_misfit_after, 0.2 * r.rest_start_misfit_before);
  EXPECT_LT(r.rest_start_misfit_after, 1.5 * truth_misfit);
  // The motion fit starts there: the knots' start values are the first frames'.
  ASSERT_EQ(r.start.size(), 9u);
  EXPECT_NE(r.start[1], 0.0);
}

}  // namespace
}  // namespace rodfit
