// Values too large to represent end every solver on the one minimizer the same way: the statics
// and each integrator's step report the minimizer's kNonFinite message, never a converged state
// (tests/solve/newton_minimizer_test.cc injects NaNs into the residual, matrix and merit of the
// loop itself; here they arise in the rod's own assembly). Before the one engine, a NaN-dropping
// norm let a dynamic step "converge" through NaN rows with a hostile damping of 1e308.
#include <string>

#include <gtest/gtest.h>

#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

namespace rodfit {
namespace {

using testing::ModelOf;

bool SaysNonFinite(const std::string& reason) {
  return reason.find(TerminationMessage(Termination::kNonFinite)) != std::string::npos ||
         reason.find("non-finite") != std::string::npos;
}

TEST(NonFinite, StaticsFromAStateWhoseEnergyOverflowsFailsAsNonFinite) {
  // The model's parameters are refused beyond their ranges when it is built; a start state with
  // the tip 1e200 m away is finite, but its stretch energy EA l (|e| / l - 1)^2 / 2 is not.
  const Scene s = testing::HeavyCantilever();
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  state.x.col(model.num_edges()) *= 1e200;
  state.SyncEdges();
  const StaticsSummary r = SolveStatics(model, StaticsOptions(), &state);
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(SaysNonFinite(r.reason)) << r.reason;
}

class NonFiniteStep : public ::testing::TestWithParam<const char*> {};

// A hostile external damping of 1e308 overflows c drag to infinity, and infinity times a zero
// increment is NaN: every implicit scheme's step fails saying so, its state unchanged.
TEST_P(NonFiniteStep, OverflowingDampingFailsTheStep) {
  Scene s = testing::Cantilever(12, /*density=*/0.05);
  s.gravity = Vec3(0, 0, -9.81);
  s.material.damping = 1e308;
  const RodModel model = ModelOf(s);
  DynamicsOptions options;
  ASSERT_TRUE(ParseIntegrator(GetParam(), &options.integrator));
  options.max_halvings = 0;
  DynamicsStepper stepper(model, options);
  DynamicState state = stepper.AtRest(model.StraightState());
  const DynamicState before = state;
  const DynamicsStepSummary r = stepper.Step(Drive(), &state);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(SaysNonFinite(r.reason)) << r.reason;
  EXPECT_EQ(state.q.x, before.q.x);
}

INSTANTIATE_TEST_SUITE_P(Implicit, NonFiniteStep,
                         ::testing::Values("backward_euler", "midpoint", "bdf2"));

}  // namespace
}  // namespace rodfit
