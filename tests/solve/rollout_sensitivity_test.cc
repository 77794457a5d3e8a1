// Forward sensitivities through the implicit steps (solve/rollout.h, RolloutWithSensitivities;
// dynamics.h, StepSensitivity): the derivatives of the predicted markers over 25 steps (5 frames
// of the synthetic gripper recording) with respect to the log of each parameter the motion fit
// may change equal central differences of the rollout itself, for BDF2 and backward Euler, with
// every damping term switched on (the lagged internal damping's own derivative along the state
// included) and the linear density. Measured worst disagreement: 6e-6 relative (twist
// stiffness, whose effect on the markers is 1e-3 of the bending's), 4e-8..4e-7 for the others.
// The rest curvature (a fitted rest shape: its values at knots along the rod): the model's
// derivative of the energy gradient (ParameterGradient) against central differences of the
// gradient of rods built with the knot moved, and the rollout's sensitivities against central
// differences of the rollout.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/rollout.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

using testing::Cable;
using testing::kFrameInterval;
using testing::Recording;

// One parameter of the test: the field it scales in the scene.
struct Knob {
  const char* name;
  double* (*field)(Scene*);
};

const std::vector<Knob>& Knobs() {
  static const std::vector<Knob> knobs = {
      {"bend_stiffness", [](Scene* s) { return &s->material.bend_stiffness; }},
      {"twist_stiffness", [](Scene* s) { return &s->material.twist_stiffness; }},
      {"stretch_stiffness", [](Scene* s) { return &s->material.stretch_stiffness; }},
      {"damping", [](Scene* s) { return &s->material.damping; }},
      {"bend_damping", [](Scene* s) { return &s->material.bend_damping; }},
      {"twist_damping", [](Scene* s) { return &s->material.twist_damping; }},
      {"stretch_damping", [](Scene* s) { return &s->material.stretch_damping; }},
      {"linear_density", [](Scene* s) { return &s->rod.linear_density; }},
  };
  return knobs;
}

Scene Scaled(const Scene& s, const Knob& knob, double log_step) {
  Scene out = s;
  *knob.field(&out) *= std::exp(log_step);
  return out;
}

void CheckAgainstCentralDifferences(const std::string& integrator) {
  Scene scene = Cable();
  scene.dynamics->integrator = integrator;
  // Every damping term on, at rates comparable to the others' over this motion.
  scene.material.twist_damping = 1e-5;
  scene.material.stretch_damping = 2.0;
  const std::vector<Eigen::Matrix3Xd> frames = Recording(0.05, 0.0, 0.0, 3);
  RolloutOptions options;
  // The start's equilibrium converged far below its default step (1e-9 L): central differences
  // of the rollout would otherwise measure how the solver's last residual moves with the
  // parameters (1e-4 of the stretch stiffness's small effect), not the equilibrium's.
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  statics.step_tolerance = 1e-13;
  std::vector<ParameterDirection> directions;
  for (const Knob& k : Knobs()) {
    const Scene up = Scaled(scene, k, 1.0);
    directions.push_back(ParameterDirection::Between(scene.material, scene.rod.linear_density,
                                                     up.material, up.rod.linear_density, 1.0));
  }
  std::vector<Eigen::MatrixXd> d_predicted;
  const RolloutResult base = RolloutWithSensitivities(scene, kFrameInterval, frames, options,
                                                      statics, directions, &d_predicted);
  ASSERT_TRUE(base.ok) << base.reason;
  // The predictions are Rollout's own.
  const RolloutResult plain = Rollout(scene, kFrameInterval, frames, options, statics);
  ASSERT_TRUE(plain.ok) << plain.reason;
  ASSERT_EQ(plain.predicted.size(), base.predicted.size());
  for (size_t f = 0; f < base.predicted.size(); ++f)
    EXPECT_EQ((plain.predicted[f] - base.predicted[f]).cwiseAbs().maxCoeff(), 0.0) << f;
  // In log p. Measured: the agreement is the same at 1e-4 (no round-off yet) and 2x worse at
  // 1e-2 (truncation).
  const double h = 1e-3;
  for (size_t k = 0; k < Knobs().size(); ++k) {
    const Knob& knob = Knobs()[k];
    const RolloutResult up = Rollout(Scaled(scene, knob, h), kFrameInterval, frames, options, statics);
    const RolloutResult down = Rollout(Scaled(scene, knob, -h), kFrameInterval, frames, options, statics);
    ASSERT_TRUE(up.ok && down.ok) << knob.name;
    // Every frame, every marker: the largest disagreement against the largest derivative.
    double worst = 0.0, largest = 0.0;
    for (size_t f = 0; f < base.predicted.size(); ++f) {
      const Eigen::Matrix3Xd fd = (up.predicted[f] - down.predicted[f]) / (2.0 * h);
      const Eigen::Map<const Eigen::VectorXd> fd_flat(fd.data(), fd.size());
      const Eigen::VectorXd analytic = d_predicted[f].col(static_cast<int>(k));
      worst = std::max(worst, (analytic - fd_flat).cwiseAbs().maxCoeff());
      largest = std::max(largest, fd_flat.cwiseAbs().maxCoeff());
    }
    std::printf("%-14s %-17s largest |dx/dlog p| %.3e m, disagreement %.2e relative\n",
                integrator.c_str(), knob.name, largest, worst / largest);
    EXPECT_GT(largest, 0.0) << knob.name;
    EXPECT_LT(worst, 1e-5 * largest) << knob.name << ": largest " << largest;
  }
}

TEST(RolloutSensitivity, Bdf2MatchesCentralDifferences) { CheckAgainstCentralDifferences("bdf2"); }

TEST(RolloutSensitivity, BackwardEulerMatchesCentralDifferences) {
  CheckAgainstCentralDifferences("backward_euler");
}

// A curved cable: its rest curvature's profile at three knots (both bending components).
Scene CurvedCable() {
  Scene scene = Cable();
  scene.rod.rest_curvature_s = {0.0, 0.5, 1.0};
  scene.rod.rest_curvature_profile = {Vec3(0.5, 2.0, 0.0), Vec3(-1.0, 3.0, 0.0), Vec3(0.8, 1.0, 0.0)};
  return scene;
}

// The direction of knot `knot`'s component `a` (1/m per unit).
ParameterDirection KnotDirection(const Scene& scene, int knot, int a) {
  ParameterDirection d;
  d.rest_curvature_s = scene.rod.rest_curvature_s;
  d.rest_curvature_profile.assign(d.rest_curvature_s.size(), Vec3::Zero());
  d.rest_curvature_profile[knot][a] = 1.0;
  return d;
}

Scene KnotMoved(const Scene& scene, int knot, int a, double h) {
  Scene out = scene;
  out.rod.rest_curvature_profile[knot][a] += h;
  return out;
}

TEST(RestCurvatureSensitivity, EnergyGradientMatchesCentralDifferences) {
  const Scene scene = CurvedCable();
  LoadCase c;
  c.name = "bent";
  EndClamp end;
  end.position = Vec3(0.6, 0.1, -0.05);
  end.tangent = Vec3(1, 0.3, 0);
  end.normal = Vec3(0, 0, 1);
  c.end_clamp = end;
  const RodModel model(scene.rod, scene.material, scene.gravity, c);
  // A deformed state: the rest state with its vertices and twists moved.
  RodState q = model.RestState();
  for (int i = 1; i <= model.num_edges(); ++i)
    q.x.col(i) += 0.01 * Vec3(std::sin(3.0 * i), std::cos(2.0 * i), std::sin(0.7 * i));
  q.SyncEdges();
  for (int j = 0; j < model.num_edges(); ++j) q.theta[j] += 0.05 * std::sin(1.3 * j);
  const double h = 1e-3;
  for (int knot = 0; knot < 3; ++knot)
    for (int a = 0; a < 2; ++a) {
      VecX analytic, up, down;
      ParameterGradient(model, q, KnotDirection(scene, knot, a), &analytic);
      const Scene sp = KnotMoved(scene, knot, a, h), sm = KnotMoved(scene, knot, a, -h);
      const RodModel mp(sp.rod, sp.material, sp.gravity, c), mm(sm.rod, sm.material, sm.gravity, c);
      AssembleGradient(mp, q, EnergyTerms::Elastic(), &up);
      AssembleGradient(mm, q, EnergyTerms::Elastic(), &down);
      const VecX fd = (up - down) / (2.0 * h);
      const double largest = fd.cwiseAbs().maxCoeff();
      const double worst = (analytic - fd).cwiseAbs().maxCoeff();
      std::printf("knot %d k%d: largest |dg/dk| %.3e, disagreement %.2e relative\n", knot, a + 1,
                  largest, worst / largest);
      EXPECT_GT(largest, 0.0);
      EXPECT_LT(worst, 1e-7 * largest) << knot << " " << a;
    }
}

TEST(RestCurvatureSensitivity, RolloutMatchesCentralDifferences) {
  const Scene scene = CurvedCable();
  const std::vector<Eigen::Matrix3Xd> frames = Recording(0.05, 0.0, 0.0, 3);
  RolloutOptions options;
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  statics.step_tolerance = 1e-13;
  std::vector<ParameterDirection> directions;
  for (int knot = 0; knot < 3; ++knot)
    for (int a = 0; a < 2; ++a) directions.push_back(KnotDirection(scene, knot, a));
  // The adaptive steps of the base run, replayed by the differences (as the motion fit does).
  StepSchedule schedule;
  std::vector<Eigen::MatrixXd> d_predicted;
  const RolloutResult base = RolloutWithSensitivities(scene, kFrameInterval, frames, options,
                                                      statics, directions, &d_predicted, &schedule);
  ASSERT_TRUE(base.ok) << base.reason;
  {
    // The predictions are Rollout's own, curved at rest too.
    StepSchedule replay = schedule;
    replay.Replay();
    const RolloutResult plain = Rollout(scene, kFrameInterval, frames, options, statics, &replay);
    const RolloutResult fresh = Rollout(scene, kFrameInterval, frames, options, statics);
    ASSERT_TRUE(plain.ok && fresh.ok);
    ASSERT_EQ(plain.predicted.size(), base.predicted.size());
    for (size_t f = 0; f < base.predicted.size(); ++f) {
      EXPECT_EQ((plain.predicted[f] - base.predicted[f]).cwiseAbs().maxCoeff(), 0.0) << f;
      EXPECT_EQ((fresh.predicted[f] - base.predicted[f]).cwiseAbs().maxCoeff(), 0.0) << f;
    }
  }
  const double h = 1e-3;  // [1/m]
  for (int knot = 0; knot < 3; ++knot)
    for (int a = 0; a < 2; ++a) {
      schedule.Replay();
      const RolloutResult up =
          Rollout(KnotMoved(scene, knot, a, h), kFrameInterval, frames, options, statics, &schedule);
      schedule.Replay();
      const RolloutResult down =
          Rollout(KnotMoved(scene, knot, a, -h), kFrameInterval, frames, options, statics, &schedule);
      ASSERT_TRUE(up.ok && down.ok);
      double worst = 0.0, largest = 0.0;
      for (size_t f = 0; f < base.predicted.size(); ++f) {
        const Eigen::Matrix3Xd fd = (up.predicted[f] - down.predicted[f]) / (2.0 * h);
        const Eigen::Map<const Eigen::VectorXd> fd_flat(fd.data(), fd.size());
        const Eigen::VectorXd analytic = d_predicted[f].col(2 * knot + a);
        worst = std::max(worst, (analytic - fd_flat).cwiseAbs().maxCoeff());
        largest = std::max(largest, fd_flat.cwiseAbs().maxCoeff());
      }
      std::printf("rollout knot %d k%d: largest |dx/dk| %.3e m^2, disagreement %.2e relative\n",
                  knot, a + 1, largest, worst / largest);
      EXPECT_GT(largest, 0.0);
      EXPECT_LT(worst, 1e-5 * largest) << knot << " " << a;
    }
}

}  // namespace
}  // namespace rodfit
