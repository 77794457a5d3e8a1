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

#include "rodfit/fit/covariance.h"
#include "rodfit/fit/motion_fit.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

// The motion fit's stop at the objective's resolution (docs/solvers.md, "The motion fit"): the
// quantile against the published table (NIST/SEMATECH e-Handbook of Statistical Methods,
// 1.3.6.7.4, "Critical values of the chi-square distribution", upper tail 0.05: 3.841, 5.991,
// 7.815, 9.488, 18.307 for 1, 2, 3, 4, 10 degrees of freedom), within the approximation's 1 %.
TEST(MotionFitResolution, ChiSquareQuantileMatchesTheTable) {
  const std::vector<std::pair<int, double>> table = {
      {1, 3.841}, {2, 5.991}, {3, 7.815}, {4, 9.488}, {10, 18.307}};
  for (const auto& [dof, quantile] : table)
    EXPECT_NEAR(fit_internal::ChiSquare95(dof), quantile, 0.01 * quantile) << dof;
  // 1 and 2 are exact.
  EXPECT_NEAR(fit_internal::ChiSquare95(1), 3.841, 1e-3);
  EXPECT_NEAR(fit_internal::ChiSquare95(2), 5.991, 1e-3);
}

// The region is the covariance's ellipsoid (J^T J)^-1 s^2 scaled by the quantile: along a
// parameter's own axis of an uncorrelated J, 2.4 of its sigmas lie inside for 2 unknowns
// (2.4^2 = 5.76 < 5.99), 2.5 outside; with correlated columns the narrow direction counts.
TEST(MotionFitResolution, ConfidenceRegionIsTheCovariancesEllipsoid) {
  const double variance = 4.0;              // s^2: the residual variance scales the region
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3, 2);
  J(0, 0) = 10.0;                            // sigma_0 = s / 10 = 0.2
  J(1, 1) = 0.5;                             // sigma_1 = s / 0.5 = 4
  EXPECT_TRUE(fit_internal::WithinConfidenceRegion(J, Eigen::Vector2d(2.4 * 0.2, 0.0), variance));
  EXPECT_FALSE(fit_internal::WithinConfidenceRegion(J, Eigen::Vector2d(2.5 * 0.2, 0.0), variance));
  EXPECT_TRUE(fit_internal::WithinConfidenceRegion(J, Eigen::Vector2d(0.0, -2.4 * 4.0), variance));
  EXPECT_FALSE(fit_internal::WithinConfidenceRegion(J, Eigen::Vector2d(0.0, -2.5 * 4.0), variance));
  // Two columns that nearly cancel: a step along their difference moves the residuals little
  // (inside), the same length along their sum a lot (outside).
  Eigen::MatrixXd K(2, 2);
  K << 1.0, 1.0, 1.0, 1.01;
  EXPECT_TRUE(fit_internal::WithinConfidenceRegion(K, Eigen::Vector2d(100.0, -100.0), 1.0));
  EXPECT_FALSE(fit_internal::WithinConfidenceRegion(K, Eigen::Vector2d(100.0, 100.0), 1.0));
}

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
                                                      double noise, unsigned seed,
                                                      const RolloutOptions& options = {}) {
  const std::vector<Eigen::Matrix3Xd> source =
      testing::Recording(seconds, 0.0, 0.0, 3, &truth.material, &truth.rod);
  const RolloutResult made = Rollout(truth, testing::kFrameInterval, source, options);
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

// The held ends the tests below were measured with (the default until the jaws): the pinned
// pairs. Their recordings are made by that model (SelfConsistentRecording) from frame 2 on.
RolloutOptions Pins() {
  RolloutOptions o;
  o.held_ends = RolloutOptions::HeldEnds::kPinnedPairs;
  return o;
}

TEST(MotionFit, LeastSquaresRecoversStiffnessAndDragWithinThreeStdInFewRollouts) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  const double noise = 5e-4;
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = SelfConsistentRecording(truth, 0.6, noise, 11, Pins());
  Scene start = truth;
  start.material.bend_stiffness = 2.5 * truth.material.bend_stiffness;
  start.material.damping = truth.material.damping / 3.0;
  const std::vector<std::string> names = {"bend_stiffness", "damping"};
  const std::vector<double> want = {truth.material.bend_stiffness, truth.material.damping};
  MotionFitOptions lm;
  lm.marker_sigma = noise;
  const MotionFitResult r = FitMotion(start, {rec}, names, Pins(), StaticsOptions(), lm);
  ASSERT_TRUE(r.converged) << r.message;
  MotionFitOptions bobyqa = lm;
  bobyqa.method = MotionFitMethod::kBobyqa;
  const MotionFitResult b = FitMotion(start, {rec}, names, Pins(), StaticsOptions(), bobyqa);
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
  rec.frames = SelfConsistentRecording(truth, 0.6, noise, 11, Pins());
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
  const MotionFitResult r = FitMotion(start, {rec}, names, Pins(), StaticsOptions(), lm);
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
  rec.frames = SelfConsistentRecording(truth, 1.0, noise, 11, Pins());
  Scene start = truth;
  start.rod.rest_curvature_s.clear();
  start.rod.rest_curvature_profile.clear();
  start.material.bend_stiffness *= 2.5;
  const std::vector<std::string> names = {"bend_stiffness", "rest_curvature"};
  MotionFitOptions options;
  options.rest_curvature_knots = 4;
  const MotionFitResult r = FitMotion(start, {rec}, names, Pins(), StaticsOptions(), options);
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
      FitMotion(truth, {rec}, names, Pins(), StaticsOptions(), at_truth);
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

// The grippers' tilt columns of the fit (central differences at 1e-3 rad, each run on the base
// run's steps) against central differences of the whole rollout at a tenth of that step, about
// tilts that are not 0: the same to 1e-4 of the largest entry. The start moves with them (the
// equilibrium is held by the turned frames), and each tilt moves the markers.
TEST(MotionFit, GripperTiltColumnsMatchCentralDifferencesOfTheRollout) {
  const Scene scene = testing::Cable();
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  rec.frames = testing::Recording(0.3, 0.0, 0.0, 3);
  RolloutOptions options;
  options.held_ends = RolloutOptions::HeldEnds::kGrippers;
  options.gripper_rotation = {Vec3(0.05, -0.1, 0.0), Vec3(0.1, 0.05, 0.0)};
  StepSchedule schedule;
  schedule.Record();
  const RolloutResult base = Rollout(scene, rec.frame_interval, rec.frames, options,
                                     StaticsOptions(), &schedule);
  ASSERT_TRUE(base.ok) << base.reason;
  std::vector<Eigen::MatrixXd> d;
  std::string why;
  ASSERT_TRUE(GripperTiltDerivatives(scene, rec, options, StaticsOptions(), 1e-3, &d, &why,
                                     &schedule)) << why;
  ASSERT_EQ(d.size(), rec.frames.size());
  const double h = 1e-4;
  double largest = 0.0, worst = 0.0;
  for (int j = 0; j < 4; ++j) {
    std::vector<Eigen::Matrix3Xd> side[2];
    for (int k = 0; k < 2; ++k) {
      RolloutOptions o = options;
      o.gripper_rotation[j / 2][j % 2] += k == 0 ? h : -h;
      schedule.Replay();
      const RolloutResult r = Rollout(scene, rec.frame_interval, rec.frames, o, StaticsOptions(),
                                      &schedule);
      ASSERT_TRUE(r.ok) << r.reason;
      side[k] = r.predicted;
    }
    double column = 0.0, start = 0.0;
    for (size_t f = 0; f < d.size(); ++f)
      for (int m = 0; m < static_cast<int>(base.held.size()); ++m) {
        if (base.held[m]) continue;
        const Vec3 want = (side[0][f].col(m) - side[1][f].col(m)) / (2 * h);
        const Vec3 got = d[f].block<3, 1>(3 * m, j);
        worst = std::max(worst, (got - want).cwiseAbs().maxCoeff());
        column = std::max(column, got.cwiseAbs().maxCoeff());
        if (f == 0) start = std::max(start, got.cwiseAbs().maxCoeff());
      }
    largest = std::max(largest, column);
    // [m/rad]: a turn of the gripper moves the free markers (9 cm and more from it) by
    // centimetres per radian, from the start on.
    EXPECT_GT(column, 1e-2) << "tilt " << j;
    EXPECT_GT(start, 1e-3) << "tilt " << j << ": the start does not move with the held frame";
  }
  std::printf("largest entry %.4g m/rad, largest difference %.3g m/rad\n", largest, worst);
  EXPECT_LT(worst, 1e-4 * largest);  // measured: 1.4e-8 against 0.10 m/rad
}

// The held frames fitted as nuisances: a recording the grippers model explains to 0.5 mm of
// noise with its grippers' frames the markers' tilted to the true grippers' at t = 0; the bending
// stiffness from 2x off and the four tilts (prior std 10 degrees) land within 3 std of the truth,
// at the noise (residual variance ~1); the tilts are reported apart from the parameters.
// Measured: B 0.4 std off; tilts (0.06, 6.59) and (-0.40, -6.40) deg fitted (0.06, 6.58) and
// (-0.40, -6.45) +- 0.006-0.02 deg; residual variance 1.045; 6 rollouts, 3.4 s.
TEST(MotionFit, FitsTheGrippersTiltsAsNuisancesWithThePrior) {
  Scene truth = testing::Cable();
  truth.material.bend_damping = 0.0;
  truth.material.damping = 0.2;
  truth.material.bend_stiffness = 2e-2;
  RolloutOptions made;
  made.held_ends = RolloutOptions::HeldEnds::kGrippers;
  const double deg = M_PI / 180.0;
  const double noise = 5e-4;
  MotionRecordingData rec;
  rec.frame_interval = testing::kFrameInterval;
  // The tilts that make the markers' frames the true grippers' at t = 0 (the rollout's start,
  // the equilibrium they hold, is then the sequence's first shape, whose frames 0 and 1 the
  // recording keeps), without their roll; the later frames' free markers the rollout's with them.
  const std::vector<Eigen::Matrix3Xd> sequence =
      testing::Recording(0.6, 0.0, 0.0, 3, &truth.material, &truth.rod);
  const std::vector<DrivenPoint> grippers = testing::GentleGrippers(0.6);
  RolloutOptions probe = made;
  probe.gripper_frame = [&](int g, double t, const Eigen::Matrix3d& from_markers) {
    if (t == 0.0) {
      const Vec3 b = grippers[g].path.b[0].normalized(), c = grippers[g].path.c[0];
      Eigen::Matrix3d T;
      T.col(2) = b;
      T.col(0) = (c - c.dot(b) * b).normalized();
      T.col(1) = b.cross(T.col(0));
      const Eigen::AngleAxisd turn(from_markers.transpose() * T);
      made.gripper_rotation[g] = turn.angle() * turn.axis();
      made.gripper_rotation[g][2] = 0.0;
    }
    return from_markers;
  };
  ASSERT_TRUE(Rollout(truth, testing::kFrameInterval, sequence, probe).ok);
  rec.frames = sequence;
  const RolloutResult own = Rollout(truth, rec.frame_interval, rec.frames, made);
  ASSERT_TRUE(own.ok) << own.reason;
  for (size_t k = 2; k < rec.frames.size(); ++k)
    for (int m = 0; m < testing::kMarkers; ++m)
      if (!own.held[m]) rec.frames[k].col(m) = own.predicted[k].col(m);
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, noise);
  for (size_t k = 2; k < rec.frames.size(); ++k)
    for (int m = 0; m < testing::kMarkers; ++m)
      if (!own.held[m]) rec.frames[k].col(m) += Vec3(gauss(rng), gauss(rng), gauss(rng));
  Scene start = truth;
  start.material.bend_stiffness *= 2.0;
  RolloutOptions options;
  options.held_ends = RolloutOptions::HeldEnds::kGrippers;
  MotionFitOptions fit;
  fit.marker_sigma = noise;
  fit.gripper_prior_deg = 10.0;
  const MotionFitResult r = FitMotion(start, {rec}, {"bend_stiffness"}, options, StaticsOptions(), fit);
  std::printf("%d rollouts, %d iterations, %.2f s, residual variance %.3f: %s\n", r.evaluations,
              r.iterations, r.seconds, r.residual_variance, r.message.c_str());
  ASSERT_TRUE(r.converged) << r.message;
  ASSERT_EQ(r.names.size(), 1u);
  ASSERT_EQ(r.gripper_rotation_deg.size(), 1u);
  EXPECT_EQ(r.gripper_prior_residuals, 4);
  ASSERT_TRUE(r.identifiable[0]) << r.reason[0];
  std::printf("bend_stiffness truth %.5g fitted %.5g +- %.3g\n", truth.material.bend_stiffness,
              r.values[0], r.std[0]);
  EXPECT_LT(std::abs(r.values[0] - truth.material.bend_stiffness), 3.0 * r.std[0]);
  for (int g = 0; g < 2; ++g)
    for (int a = 0; a < 3; ++a) {
      const double want = made.gripper_rotation[g][a] / deg;
      const double got = r.gripper_rotation_deg[0][g][a];
      if (a == 2) {
        EXPECT_EQ(got, 0.0);  // the roll is not fitted
        continue;
      }
      const double sd = r.gripper_rotation_std_deg[0][g][a];
      std::printf("gripper %d tilt about d%d: truth %.3f fitted %.3f +- %.3f deg\n", g, a + 1, want,
                  got, sd);
      ASSERT_TRUE(std::isfinite(sd));
      EXPECT_LT(std::abs(got - want), 3.0 * sd) << "gripper " << g << " d" << a + 1;
    }
  EXPECT_NEAR(r.residual_variance, 1.0, 0.3);
  // Pins carry no gripper frames: refused.
  EXPECT_THROW(FitMotion(start, {rec}, {"bend_stiffness"}, Pins(), StaticsOptions(), fit),
               std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
