// Adaptive time steps (DynamicsOptions::error_tolerance; solve/dynamics.cc StepAdaptive) with
// variable-step BDF2 (solve/integrator_bdf2.cc): the global error falls with the tolerance, every
// time_step ends on its time, a recorded step schedule replays the same trajectory bit for bit,
// and forward sensitivities through the substeps match finite differences of the replayed map.
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/dynamics.h"
#include "solve/test_util.h"

namespace rodfit {
namespace {

using testing::ModelOf;

// A 20-segment cantilever released under gravity: it swings through large rotations.
Scene Swing() {
  Scene s = testing::Cantilever(20, /*density=*/0.05);
  s.gravity = Vec3(0, 0, -9.81);
  s.material.bend_stiffness = 0.01;
  s.material.twist_stiffness = 0.008;
  s.material.stretch_stiffness = 1e4;
  return s;
}

struct Trajectory {
  Vec3 tip = Vec3::Zero();
  int substeps = 0;
  std::vector<double> times;
};

Trajectory Integrate(const RodModel& model, double dt, double tolerance, double duration,
              StepSchedule* schedule = nullptr) {
  DynamicsOptions o;
  o.time_step = dt;
  o.error_tolerance = tolerance;
  o.max_halvings = 0;
  DynamicsStepper stepper(model, o);
  stepper.SetSchedule(schedule);
  DynamicState s = stepper.AtRest(model.StraightState());
  Trajectory run;
  while (s.t < duration - 1e-9) {
    const DynamicsStepSummary r = stepper.Step(Drive(), &s);
    EXPECT_TRUE(r.ok) << r.reason;
    if (!r.ok) break;
    run.substeps += r.substeps;
    run.times.push_back(s.t);
  }
  run.tip = s.q.x.col(model.num_edges());
  return run;
}

TEST(AdaptiveSteps, GlobalErrorFallsWithTheToleranceAndStepsLandOnTheirTimes) {
  const RodModel model = ModelOf(Swing());
  const double T = 0.3;
  // The reference: fixed BDF2 steps of 1e-5 s (its error, ~(1e-5)^2 of the 1e-4 run's, is
  // below 1e-8 m: measured 8e-7 m between 1e-4 and 1e-5).
  const Vec3 reference = Integrate(model, 1e-5, 0.0, T).tip;
  double last_error = std::numeric_limits<double>::infinity();
  int last_substeps = 0;
  for (double tolerance : {1e-4, 1e-5, 1e-6}) {
    SCOPED_TRACE(tolerance);
    const Trajectory run = Integrate(model, 1e-2, tolerance, T);
    // Each 10 ms step ends exactly on its time (the outputs), however many substeps it took.
    for (size_t k = 0; k < run.times.size(); ++k) EXPECT_DOUBLE_EQ(run.times[k], (k + 1) * 1e-2);
    const double error = (run.tip - reference).norm();
    // The tolerance bounds each substep's local error; on a stable swing they add up at most
    // (measured: 6.7e-4, 2.3e-4 and 4.0e-5 m with 41, 93 and 204 substeps).
    EXPECT_LT(error, run.substeps * tolerance) << run.substeps << " substeps";
    EXPECT_LT(error, last_error);
    EXPECT_GT(run.substeps, last_substeps);
    last_error = error;
    last_substeps = run.substeps;
  }
}

TEST(AdaptiveSteps, ARecordedScheduleReplaysTheSameTrajectory) {
  const RodModel model = ModelOf(Swing());
  StepSchedule schedule;
  schedule.Record();
  const Trajectory recorded = Integrate(model, 1e-2, 1e-5, 0.2, &schedule);
  EXPECT_EQ(static_cast<int>(schedule.steps.size()), recorded.substeps);
  schedule.Replay();
  const Trajectory replayed = Integrate(model, 1e-2, 1e-5, 0.2, &schedule);
  EXPECT_FALSE(schedule.departed);
  EXPECT_EQ(schedule.next, schedule.steps.size());
  EXPECT_EQ(recorded.tip, replayed.tip);  // bit for bit: the same substeps
}

// The step's map with a replayed schedule is smooth in the parameters: its forward sensitivities
// through the adaptive substeps match central differences of the replayed trajectories.
TEST(AdaptiveSteps, SensitivitiesThroughSubstepsMatchDifferences) {
  const Scene scene = Swing();
  const RodModel model = ModelOf(scene);
  StepSchedule schedule;
  schedule.Record();
  DynamicsOptions o;
  o.time_step = 1e-2;
  o.error_tolerance = 1e-5;
  o.max_halvings = 0;
  o.integrator = Integrator::kBdf2;
  // Converged far below the differences' step.
  o.residual_tolerance = 1e-14;
  o.step_tolerance = 1e-16;
  const std::vector<ParameterDirection> directions = {ParameterDirection{1.0, 1.0}};
  const int steps = 8;
  Vec3 tip_sensitivity;
  {
    DynamicsStepper stepper(model, o);
    stepper.SetSchedule(&schedule);
    DynamicState s = stepper.AtRest(model.StraightState());
    DynamicSensitivity ds;
    ds.dq.setZero(model.num_free_dofs(), 1);
    ds.dv.setZero(model.num_free_dofs(), 1);
    for (int k = 0; k < steps; ++k) {
      const DynamicState before = s;
      const DynamicsStepSummary r = stepper.Step(Drive(), &s);
      ASSERT_TRUE(r.ok) << r.reason;
      std::string why;
      ASSERT_TRUE(stepper.StepSensitivity(Drive(), before, s, directions, &ds, &why)) << why;
    }
    EXPECT_GT(static_cast<int>(schedule.steps.size()), steps) << "substeps were taken";
    tip_sensitivity = ds.dq.block<3, 1>(RodModel::VertexDof(model.num_edges()), 0);
  }
  // d / d log B by central differences on the replayed schedule.
  const double h = 1e-5;
  Vec3 tips[2];
  for (int side = 0; side < 2; ++side) {
    Scene moved = scene;
    moved.material.bend_stiffness *= std::exp(side == 0 ? h : -h);
    const RodModel m = ModelOf(moved);
    DynamicsStepper stepper(m, o);
    schedule.Replay();
    stepper.SetSchedule(&schedule);
    DynamicState s = stepper.AtRest(m.StraightState());
    for (int k = 0; k < steps; ++k) ASSERT_TRUE(stepper.Step(Drive(), &s).ok);
    EXPECT_FALSE(schedule.departed);
    tips[side] = s.q.x.col(m.num_edges());
  }
  const Vec3 difference = (tips[0] - tips[1]) / (2.0 * h);
  EXPECT_LT((tip_sensitivity - difference).norm(), 1e-5 * difference.norm())
      << tip_sensitivity.transpose() << " vs " << difference.transpose();
}

}  // namespace
}  // namespace rodfit
