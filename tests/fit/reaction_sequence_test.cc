// Force logs over time in a motion fit (fit/motion_fit.h, a ForceReadings per frame): a load cell
// at the clamp of a suture swinging down under its weight reads the force and moment the rod exerts
// on it. The residuals' Jacobian equals central differences of the residuals; and with its markers
// the log identifies the linear density besides the bending stiffness and the drag (markers alone
// see only their ratios: gravity moves every mass alike), each recovered within 3 of its standard
// deviations.
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/fit/motion_fit.h"
#include "rodfit/solve/case_dynamics.h"
#include "fit/swing_fixture.h"

namespace rodfit {
namespace {

using testing::Swing;

std::vector<double> Times() {
  std::vector<double> t;
  for (int k = 0; k <= 25; ++k) t.push_back(0.01 * k);
  return t;
}

// A frame's reading as a measurement, and back.
std::shared_ptr<const Measurement> AsFrame(const ForceMeasurement& reading) {
  return std::make_shared<ForceReadings>("reaction", "reaction clamp",
                                         std::vector<ForceMeasurement>{reading});
}
ForceMeasurement ReadingOf(const ObservationSequence::Frame& frame) {
  return dynamic_cast<const ForceReadings&>(*frame.measurement).readings().front();
}

// The clamp's readings every 10 ms with Gaussian noise of sigma [N] and sigma_moment [N m] per
// component (none when add_noise is false).
ObservationSequence ClampLog(const Scene& truth, double sigma, double sigma_moment, unsigned seed,
                             bool add_noise = true) {
  const std::vector<double> t = Times();
  const CaseSamples run = SampleCaseDynamics(truth, 0, StaticsOptions(), {0.1}, t, {}, true);
  EXPECT_TRUE(run.ok) << run.reason;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  ObservationSequence seq;
  for (size_t k = 0; k < run.reactions.size(); ++k) {
    ForceMeasurement reading;
    reading.point = "clamp";
    reading.sigma = sigma;
    reading.sigma_moment = sigma_moment;
    const HeldReaction& clamp = run.reactions[k][0];
    const double on = add_noise ? 1.0 : 0.0;
    reading.force = clamp.force + on * sigma * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    reading.moment =
        clamp.moment + on * sigma_moment * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    ObservationSequence::Frame frame;
    frame.t = t[k];
    frame.measurement = AsFrame(reading);
    seq.frames.push_back(frame);
  }
  return seq;
}

// Markers at 4 arc lengths every 10 ms with Gaussian noise of sigma [m] per coordinate.
ObservationSequence Markers(const Scene& truth, double sigma, unsigned seed) {
  const std::vector<double> s = {0.05, 0.1, 0.15, 0.2}, t = Times();
  const CaseSamples run = SampleCaseDynamics(truth, 0, StaticsOptions(), s, t, {});
  EXPECT_TRUE(run.ok) << run.reason;
  const std::vector<double> arc = CaseVertexArcLengths(truth, 0);
  std::mt19937 rng(seed + 1000);
  std::normal_distribution<double> gauss(0.0, sigma);
  ObservationSequence seq;
  for (size_t k = 0; k < run.x.size(); ++k) {
    std::vector<Marker3d> seen;
    for (size_t m = 0; m < s.size(); ++m)
      seen.push_back({s[m], run.x[k].col(m) + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng))});
    ObservationSequence::Frame frame;
    frame.t = t[k];
    frame.measurement =
        MakeShapeMeasurement("markers3d", "markers3d", Markers3dObservation(arc, seen, sigma));
    seq.frames.push_back(frame);
  }
  return seq;
}

TEST(ReactionSequence, JacobianEqualsCentralDifferences) {
  const Scene truth = Swing();
  const ObservationSequence log = ClampLog(truth, 1e-6, 1e-7, 1);
  const std::vector<std::string> names = {"bend_stiffness", "damping", "linear_density"};
  StaticsOptions statics;
  const SequenceEvaluation at = EvaluateSequenceResiduals(truth, {log}, names, statics);
  ASSERT_TRUE(at.ok) << at.reason;
  ASSERT_EQ(at.residuals.size(), 6 * static_cast<int>(log.frames.size()));
  EXPECT_EQ(at.noise_residuals, at.residuals.size());
  const double h = 1e-4;
  for (size_t j = 0; j < names.size(); ++j) {
    Scene plus = truth, minus = truth;
    SetMotionParameter(names[j], MotionParameter(names[j], truth) * std::exp(h), &plus);
    SetMotionParameter(names[j], MotionParameter(names[j], truth) * std::exp(-h), &minus);
    const SequenceEvaluation p = EvaluateSequenceResiduals(plus, {log}, {}, statics);
    const SequenceEvaluation m = EvaluateSequenceResiduals(minus, {log}, {}, statics);
    ASSERT_TRUE(p.ok && m.ok);
    const Eigen::VectorXd fd = (p.residuals - m.residuals) / (2.0 * h);
    const Eigen::VectorXd d = at.jacobian.col(static_cast<int>(j));
    EXPECT_LT((d - fd).norm(), 1e-5 * d.norm()) << names[j];
  }
}

TEST(ReactionSequence, ZeroAtTheTruthAndTheErrorsInNewtonsAndNewtonMetres) {
  const Scene truth = Swing();
  const ObservationSequence log = ClampLog(truth, 1e-6, 1e-7, 1, /*add_noise=*/false);
  EXPECT_EQ(log.num_samples(), 2 * static_cast<int>(log.frames.size()));
  const SequenceResiduals r = EvaluateSequences(truth, {log}, StaticsOptions());
  ASSERT_TRUE(r.ok) << r.reason;
  ASSERT_EQ(static_cast<int>(r.error[0].size()), log.num_samples());
  for (const Eigen::Vector3d& e : r.error[0]) EXPECT_LT(e.norm(), 1e-15);
  // Another density: the force errors are the weights' and inertias' difference [N].
  Scene heavier = truth;
  heavier.rod.linear_density *= 1.1;
  const SequenceResiduals off = EvaluateSequences(heavier, {log}, StaticsOptions());
  ASSERT_TRUE(off.ok);
  // At t = 0 the rod is at rest: its clamp carries 10 % more weight (0.1 m g L), and a moment
  // 10 % more (the straight rod's weight at L / 2).
  const double weight = truth.rod.linear_density * truth.rod.length * 9.81;
  EXPECT_NEAR(off.error[0][0].norm(), 0.1 * weight, 1e-9 * weight);
  EXPECT_NEAR(off.error[0][1].norm(), 0.1 * weight * 0.5 * truth.rod.length, 1e-9 * weight);
}

TEST(ReactionSequence, ForcesAndMarkersIdentifyTheDensityWithCredibleStd) {
  const Scene truth = Swing();
  const std::vector<std::string> names = {"bend_stiffness", "damping", "linear_density"};
  const double true_values[3] = {truth.material.bend_stiffness, truth.material.damping,
                                 truth.rod.linear_density};
  Scene start = truth;
  start.material.bend_stiffness *= 3.0;
  start.material.damping /= 3.0;
  start.rod.linear_density *= 2.0;
  // 1 % of the suture's weight (1.1e-4 N) per component; the moment's the same at L / 2.
  const double sigma = 1e-6, sigma_moment = 1e-7;
  double sum_z2 = 0.0;
  int estimates = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    const std::vector<ObservationSequence> data = {Markers(truth, 1e-3, seed),
                                                   ClampLog(truth, sigma, sigma_moment, seed)};
    const MotionFitResult r = FitSequences(start, data, names, StaticsOptions(), MotionFitOptions());
    ASSERT_TRUE(r.converged) << r.message;
    EXPECT_NEAR(r.residual_variance, 1.0, 0.3);
    for (int k = 0; k < 3; ++k) {
      ASSERT_TRUE(r.identifiable[k]) << names[k] << ": " << r.reason[k];
      const double z = (r.values[k] - true_values[k]) / r.std[k];
      std::printf("seed %u  %-15s truth %.4g  fitted %.4g +- %.2g  (%+.2f std)  %.2f s\n", seed,
                  names[k].c_str(), true_values[k], r.values[k], r.std[k], z, r.seconds);
      EXPECT_LT(std::abs(z), 3.0) << names[k];
      EXPECT_LT(r.std[k], 0.1 * true_values[k]) << names[k];
      sum_z2 += z * z;
      ++estimates;
    }
  }
  // chi-square(9) / 9 lies below 2.4 with probability 0.99.
  EXPECT_LT(sum_z2 / estimates, 2.4);
}

TEST(ReactionSequence, RefusesAReadingAtAPointTheCaseDoesNotHold) {
  const Scene truth = Swing();
  ObservationSequence log = ClampLog(truth, 1e-6, 1e-7, 1);
  ForceMeasurement at_pin = ReadingOf(log.frames[0]);
  at_pin.point = "end_pin";
  for (auto& frame : log.frames) frame.measurement = AsFrame(at_pin);
  EXPECT_THROW(EvaluateSequenceResiduals(truth, {log}, {}, StaticsOptions()), std::invalid_argument);
  ObservationSequence mixed = ClampLog(truth, 1e-6, 1e-7, 1);
  ForceMeasurement other_sigma = ReadingOf(mixed.frames[1]);
  other_sigma.sigma = 2e-6;
  mixed.frames[1].measurement = AsFrame(other_sigma);
  EXPECT_THROW(EvaluateSequenceResiduals(truth, {mixed}, {}, StaticsOptions()), std::invalid_argument);
}

// Found by the fuzz corpus (tests/cli/fuzz_corpus_test.cc): residuals too large to be squared
// and summed (a sigma of 1e-300 N) made the fit fail "at the start values: " with no reason, or,
// each residual finite but their sum of squares not, return a fit of NaN values whose parameters
// "the observations do not depend on". The fit now fails saying why.
TEST(ReactionSequence, ResidualsThatOverflowFailTheFitSayingWhy) {
  const Scene truth = Swing();
  // A residual of 1e309 (inf), and residuals of ~1e164 each, finite, whose squares are not.
  for (const bool one_huge : {true, false}) {
    ObservationSequence log = ClampLog(truth, 1e-6, 1e-7, 1);
    for (size_t k = 0; k < log.frames.size(); ++k) {
      ForceMeasurement reading = ReadingOf(log.frames[k]);
      if (one_huge && k == 3) reading.force.x() = 1e303;
      if (!one_huge) reading.sigma = 1e-170;
      log.frames[k].measurement = AsFrame(reading);
    }
    const MotionFitResult r =
        FitSequences(truth, {log}, {"linear_density"}, StaticsOptions(), MotionFitOptions());
    EXPECT_FALSE(r.converged) << one_huge;
    EXPECT_THAT(r.message, ::testing::HasSubstr("the residuals (model - measured) / sigma "
                                                "overflow")) << one_huge;
  }
}

}  // namespace
}  // namespace rodfit
