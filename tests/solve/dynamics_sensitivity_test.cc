// The step's sensitivities (dynamics.h, StepSensitivity) against central differences of the
// stepper itself, on a rod whipped in 3-D so that it bends and twists: a cantilever with a pin
// at mid-length dragged along a path, random start velocities, gravity out of its plane, every
// damping term on. A random perturbation of the whole state (positions, twist angles, rates and
// BDF2's history) is carried 25 steps by the sensitivities and by the stepper; the positions and
// the material frames' twist (measured physically: the turn of d1 about the tangent against its
// transport) agree. Also: a parameter direction against rescaled constants, and the refusals.
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/model/frames.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/rod_energy.h"
#include "solve/mocap_fixture.h"

namespace rodfit {
namespace {

// q moved by eps dq in the sensitivities' chart: positions added, twist angles added against
// reference directors transported to the new tangents.
RodState MovedState(const RodModel& model, const RodState& q, const VecX& dq, double eps) {
  const std::vector<char>& held = HeldDofs(model);
  RodState out = q;
  for (int i = 1; i <= model.num_edges(); ++i)
    for (int r = 0; r < 3; ++r) {
      const int k = RodModel::VertexDof(i) + r;
      if (!held[k]) out.x(r, i) += eps * dq[k];
    }
  for (int j = 0; j < model.num_edges(); ++j) out.theta[j] += eps * dq[RodModel::TwistDof(j)];
  out.SyncEdges();
  EXPECT_TRUE(UpdateReferenceFrames(model, q, &out));
  return out;
}

struct Whip {
  Scene scene;
  LoadCase load_case;
};

Whip WhippedCantilever(const std::string& integrator) {
  Whip w;
  w.scene = testing::Cable();
  w.scene.rod.segments = 10;
  w.scene.gravity = Vec3(0, 3, -9.81);
  w.scene.material.bend_damping = 2e-5;
  w.scene.material.twist_damping = 1e-5;
  w.scene.material.stretch_damping = 2.0;
  w.scene.dynamics->integrator = integrator;
  LoadCase& c = w.load_case;
  c.name = "whip";
  c.clamp.tangent = Vec3(1, 0, 0);
  c.clamp.normal = Vec3(0, 0, 1);
  Pin pin;
  pin.s = 0.5;
  pin.position = Vec3(0.5, 0, 0);
  c.pins.push_back(pin);
  DrivenPoint d;
  d.point = "pins[0]";
  d.path.t = {0.0, 1.0};
  d.path.a = {Vec3(0.5, 0, 0), Vec3(0.5, 0.2, 0.1)};
  c.drives.push_back(d);
  w.scene.cases = {c};
  return w;
}

// Halving: with max_halvings > 0 and a Newton budget of max_newton_iterations, steps that
// need more iterations are taken in halves; *halved counts the steps of the 25 that were.
void CheckStateSensitivities(const std::string& integrator, double time_step = 2e-3,
                             int max_newton_iterations = 100, int max_halvings = 0,
                             int* halved = nullptr) {
  const Whip w = WhippedCantilever(integrator);
  const RodModel model(w.scene.rod, w.scene.material, w.scene.gravity, CaseAtStart(w.load_case));
  DynamicsOptions options;
  options.time_step = time_step;
  ASSERT_TRUE(ParseIntegrator(integrator, &options.integrator));
  // Converged far below the differences' step, so that they measure the map, not its tolerance.
  options.residual_tolerance = 1e-14;
  options.step_tolerance = 1e-16;
  options.max_newton_iterations = max_newton_iterations;
  options.max_halvings = max_halvings;
  DynamicsStepper stepper(model, options);
  const CaseDrive drive(model, w.scene.cases[0]);
  const std::vector<char>& held = HeldDofs(model);
  const int N = model.num_free_dofs();
  // A seeded generator, not Eigen's Random (std::rand's global state): the draw, and so the
  // measured agreement, is the same whether the test runs alone (ctest) or after others.
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto free_random = [&](double size) {
    VecX v(N);
    for (int k = 0; k < N; ++k) v[k] = size * uniform(rng);
    for (int k = 0; k < N; ++k)
      if (held[k]) v[k] = 0.0;
    return v;
  };
  DynamicState s = stepper.AtRest(model.StraightState());
  s.v = free_random(0.3);
  for (int k = 0; k < 20 * 2e-3 / time_step; ++k) ASSERT_TRUE(stepper.Step(drive, &s).ok);
  // The perturbation, and the sensitivities that carry it (no parameter moves).
  const VecX dq = free_random(1e-2), dv = free_random(1.0), dls = free_random(1e-3),
             dlv = free_random(1.0);
  DynamicSensitivity ds;
  ds.dq = dq;
  ds.dv = dv;
  if (s.has_history) {
    ds.dlast_step = dls;
    ds.dlast_v = dlv;
  }
  const double eps = 1e-5;
  DynamicState plus = s, minus = s;
  plus.q = MovedState(model, s.q, dq, eps);
  minus.q = MovedState(model, s.q, dq, -eps);
  plus.v += eps * dv;
  minus.v -= eps * dv;
  if (s.has_history) {
    plus.last_step += eps * dls;
    minus.last_step -= eps * dls;
    plus.last_v += eps * dlv;
    minus.last_v -= eps * dlv;
  }
  if (halved) *halved = 0;
  for (int k = 0; k < 25; ++k) {
    const DynamicState before = s;
    const DynamicsStepSummary step = stepper.Step(drive, &s);
    ASSERT_TRUE(step.ok) << step.reason;
    std::string why;
    ASSERT_TRUE(stepper.StepSensitivity(drive, before, s, {ParameterDirection()}, &ds, &why)) << why;
    const DynamicsStepSummary step_plus = stepper.Step(drive, &plus);
    const DynamicsStepSummary step_minus = stepper.Step(drive, &minus);
    ASSERT_TRUE(step_plus.ok && step_minus.ok);
    // The differences compare like with like only when the neighbours were halved alike.
    ASSERT_EQ(step_plus.substeps, step.substeps) << "step " << k;
    ASSERT_EQ(step_minus.substeps, step.substeps) << "step " << k;
    if (halved && step.substeps > 1) ++*halved;
  }
  double worst_x = 0.0, largest_x = 0.0, worst_t = 0.0, largest_t = 0.0;
  for (int i = 1; i <= model.num_edges(); ++i) {
    const Vec3 fd = (plus.q.x.col(i) - minus.q.x.col(i)) / (2.0 * eps);
    const Vec3 analytic = ds.dq.col(0).segment<3>(RodModel::VertexDof(i));
    worst_x = std::max(worst_x, (fd - analytic).cwiseAbs().maxCoeff());
    largest_x = std::max(largest_x, fd.cwiseAbs().maxCoeff());
  }
  for (int j = 0; j < model.num_edges(); ++j) {
    auto turn = [&](const RodState& q) {
      const EdgeFrame a = model.MaterialFrame(s.q, j), b = model.MaterialFrame(q, j);
      return SignedAngle<double>(ParallelTransport<double, double>(a.d3, b.d3, a.d1), b.d1, b.d3);
    };
    const double fd = (turn(plus.q) - turn(minus.q)) / (2.0 * eps);
    worst_t = std::max(worst_t, std::abs(fd - ds.dq(RodModel::TwistDof(j), 0)));
    largest_t = std::max(largest_t, std::abs(fd));
  }
  std::printf("%s, 25 steps: positions %.2e, twist %.2e relative\n", integrator.c_str(),
              worst_x / largest_x, worst_t / largest_t);
  // Measured with this draw: positions 5.5e-8 / 2.8e-8, twist 3.0e-7 / 3.4e-7 (BDF2 / backward
  // Euler); other draws gave 1e-8 to 6e-7 for the twist, which the differences of states
  // converged to the round-off floor resolve least well. With the assembled bending and twist
  // Hessians alone: 3e-5 and 4e-4.
  EXPECT_LT(worst_x, 1e-6 * largest_x);
  EXPECT_LT(worst_t, 1e-6 * largest_t);
}

TEST(DynamicsSensitivity, Bdf2CarriesAStatePerturbationLikeTheStepper) {
  CheckStateSensitivities("bdf2");
}

TEST(DynamicsSensitivity, BackwardEulerCarriesAStatePerturbationLikeTheStepper) {
  CheckStateSensitivities("backward_euler");
}

// A step whose Newton iterations do not converge is taken in halves (DynamicsOptions::
// max_halvings); its sensitivities follow the substeps, BDF2's included (whose first substep
// after a change of step is backward Euler's). 10 ms steps of the whip, with a budget of 6
// Newton iterations at the tolerance above: most steps need more, and are halved.
TEST(DynamicsSensitivity, HalvedStepsCarryAStatePerturbationLikeTheStepper) {
  for (const std::string integrator : {"bdf2", "backward_euler"}) {
    SCOPED_TRACE(integrator);
    int halved = 0;
    CheckStateSensitivities(integrator, 1e-2, 6, 8, &halved);
    std::printf("%s: %d of 25 steps halved\n", integrator.c_str(), halved);
    EXPECT_GT(halved, 0);
  }
}

// Without halving the same steps fail and say so; with it they cover the step exactly.
TEST(DynamicsSensitivity, HalvingCoversTheStepOrFailsAsBefore) {
  const Whip w = WhippedCantilever("bdf2");
  const RodModel model(w.scene.rod, w.scene.material, w.scene.gravity, CaseAtStart(w.load_case));
  DynamicsOptions options;
  options.time_step = 1e-2;
  options.integrator = Integrator::kBdf2;
  options.residual_tolerance = 1e-14;
  options.step_tolerance = 1e-16;
  options.max_newton_iterations = 6;
  options.max_halvings = 0;  // the plain stepper does not halve (the library's default is 4)
  const CaseDrive drive(model, w.scene.cases[0]);
  DynamicsStepper plain(model, options);
  DynamicState a = plain.AtRest(model.StraightState());
  a.v.setConstant(model.num_free_dofs(), 0.3);
  const DynamicState start = a;
  DynamicsStepSummary r;
  int k = 0;
  for (; k < 25 && (r = plain.Step(drive, &a)).ok; ++k) {
  }
  ASSERT_LT(k, 25) << "the setting needs no halving";
  EXPECT_NE(r.reason.find("did not converge"), std::string::npos) << r.reason;
  options.max_halvings = 8;
  DynamicsStepper halving(model, options);
  DynamicState b = start;
  for (int j = 0; j <= k; ++j) {
    const double t = b.t;
    r = halving.Step(drive, &b);
    ASSERT_TRUE(r.ok) << r.reason;
    EXPECT_DOUBLE_EQ(b.t, t + 1e-2);
  }
  EXPECT_GT(r.substeps, 1);
  // The history after a halved step is its last substep's: the next full step starts again
  // with backward Euler, as BDF2 does at its first step.
  EXPECT_LT(b.last_dt, 0.75e-2);
  EXPECT_TRUE(b.has_history);
}

TEST(DynamicsSensitivity, DirectionsFollowTheConstantsAParameterMoves) {
  Material a = testing::Cable().material;
  Material b = a;
  b.bend_stiffness *= 2.0;  // B2 tied: both bending stiffnesses move
  const ParameterDirection d = ParameterDirection::Between(a, 0.04, b, 0.04, std::log(2.0));
  EXPECT_DOUBLE_EQ(d.bend1, 1.0);
  EXPECT_DOUBLE_EQ(d.bend2, 1.0);
  EXPECT_EQ(d.twist, 0.0);
  EXPECT_EQ(d.drag, 0.0);
  EXPECT_EQ(d.density, 0.0);
  a.bend_stiffness_2 = a.bend_stiffness;
  b = a;
  b.bend_stiffness *= 2.0;  // untied: B1 alone
  const ParameterDirection e = ParameterDirection::Between(a, 0.04, b, 0.04, std::log(2.0));
  EXPECT_DOUBLE_EQ(e.bend1, 1.0);
  EXPECT_EQ(e.bend2, 0.0);
  const ParameterDirection f = ParameterDirection::Between(a, 0.04, a, 0.08, std::log(2.0));
  EXPECT_DOUBLE_EQ(f.density, 1.0);
}

TEST(DynamicsSensitivity, RefusesTheMidpointRule) {
  const Whip w = WhippedCantilever("midpoint");
  const RodModel model(w.scene.rod, w.scene.material, w.scene.gravity, CaseAtStart(w.load_case));
  DynamicsOptions options;
  options.time_step = 2e-3;
  options.integrator = Integrator::kMidpoint;
  DynamicsStepper stepper(model, options);
  const CaseDrive drive(model, w.scene.cases[0]);
  DynamicState s = stepper.AtRest(model.StraightState());
  const DynamicState before = s;
  ASSERT_TRUE(stepper.Step(drive, &s).ok);
  DynamicSensitivity ds;
  ds.dq.setZero(model.num_free_dofs(), 1);
  std::string why;
  EXPECT_FALSE(stepper.StepSensitivity(drive, before, s, {ParameterDirection()}, &ds, &why));
  EXPECT_NE(why.find("midpoint"), std::string::npos) << why;
}

}  // namespace
}  // namespace rodfit
