// Reactions at held points as fit observations (fit.h ForceMeasurement): the forward map's
// Jacobian (forces and moments at the clamp, an end clamp, a pin and a grasp; a case with dead
// and follower moments, whose tangent is not symmetric) against central differences, and
// recovery of the stiffness from reactions.
#include <cmath>

#include <gtest/gtest.h>

#include "rodfit/fit/fit.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit {
namespace {

FitInput Wire() {
  FitInput in;
  in.rod.length = 0.3;
  in.rod.segments = 30;
  in.rod.radius = 5e-4;
  in.rod.linear_density = 2e-3;
  in.material.bend_stiffness = 2e-5;
  in.material.bend_stiffness_2 = 3e-5;
  in.material.twist_stiffness = 1.5e-5;
  in.material.stretch_stiffness = 2e3;
  in.gravity = Vec3(0, 0, -9.81);
  return in;
}

// A wire sagging between a clamp and an end clamp, pinned on the way: slack by 5 %, with the
// clamps tilted into the sag so that the sagging shape is the one equilibrium near the path
// (a bistable bow would let central differences jump between branches).
LoadCase Bridge() {
  LoadCase c;
  c.name = "bridge";
  c.clamp.tangent = Vec3(1, 0, -0.3);
  c.clamp.normal = Vec3(0, 0, 1);
  EndClamp ec;
  ec.position = Vec3(0.285, 0.01, -0.02);
  ec.tangent = Vec3(1, 0.05, 0.3);
  ec.normal = Vec3(0, 0, 1);
  c.end_clamp = ec;
  c.pins.push_back({0.1, Vec3(0.097, 0.002, -0.025)});
  return c;
}

// A cantilever under dead and follower moments whose tip an instrument holds 1 cm off where the
// free rod's tip would hang (a bent rod held near its own shape: one equilibrium near the path).
LoadCase Twisted(const FitInput& truth) {
  LoadCase c;
  c.name = "twisted";
  c.clamp.tangent = Vec3(1, 0, 0.3);
  c.clamp.normal = Vec3(0, 1, 0);
  c.tip_moment = Vec3(1e-5, 2e-6, 0);
  c.tip_moment_follower = Vec3(0, 0, 2e-6);
  Scene scene;
  scene.rod = truth.rod;
  scene.material = truth.material;
  scene.gravity = truth.gravity;
  scene.cases = {c};
  const CaseSolution free = SolveCase(scene, 0, nullptr);
  EXPECT_TRUE(free.ok()) << free.summary.BriefReport();
  c.grasp = Grasp{truth.rod.length, free.state.x.col(truth.rod.segments) + Vec3(0, 0.01, 0.005)};
  return c;
}

// The truth's reactions as noise-free measurements.
FitCase Measured(const FitInput& truth, const LoadCase& c, const std::vector<std::string>& points) {
  Scene scene;
  scene.rod = truth.rod;
  scene.material = truth.material;
  scene.gravity = truth.gravity;
  scene.cases = {c};
  const CaseSolution s = SolveCase(scene, 0, nullptr);
  EXPECT_TRUE(s.ok()) << s.summary.BriefReport();
  FitCase fc;
  fc.load_case = c;
  for (const HeldReaction& r : s.reactions) {
    if (std::find(points.begin(), points.end(), r.point) == points.end()) continue;
    ForceMeasurement f;
    f.point = r.point;
    f.force = r.force;
    f.sigma = 1e-4;
    f.label = "reaction " + r.point;
    if (r.holds_moment) {
      f.moment = r.moment;
      f.sigma_moment = 1e-5;
    }
    fc.measurements.push_back(
        std::make_shared<ForceReadings>("reaction", f.label, std::vector<ForceMeasurement>{f}));
  }
  return fc;
}

void AddParameters(FitInput* in, double factor) {
  const Material& m = in->material;
  in->parameters = {{"bend_stiffness", m.bend_stiffness * factor, true, {}, {}},
                    {"bend_stiffness_2", *m.bend_stiffness_2 * factor, true, {}, {}},
                    {"twist_stiffness", m.twist_stiffness * factor, true, {}, {}},
                    {"stretch_stiffness", m.stretch_stiffness, false, {}, {}}};
}

TEST(ReactionFit, JacobianMatchesCentralDifferencesOfTheForwardMap) {
  const FitInput truth = Wire();
  FitInput in = truth;
  in.cases.push_back(Measured(truth, Bridge(), {"clamp", "pins[0]", "end_clamp"}));
  in.cases.push_back(Measured(truth, Twisted(truth), {"clamp", "grasp"}));
  AddParameters(&in, 1.3);
  in.statics.gradient_tolerance = 1e-12;
  std::vector<double> lp;
  for (const Parameter& p : in.parameters)
    if (p.fit) lp.push_back(std::log(p.value));
  VecX r;
  Eigen::MatrixXd J;
  ASSERT_TRUE(EvaluateForwardMap(in, lp, &r, &J));
  ASSERT_EQ(r.size(), 2 * 6 + 3 + 6 + 3);  // clamp, pin, end clamp; clamp, grasp
  for (size_t k = 0; k < lp.size(); ++k) {
    // h = 1e-3 in log space: truncation ~1e-6 of the column; the solves' force noise
    // (~1e-11 N at the tightened tolerance, 1e-7 in sigmas) over 2h stays below 1e-4.
    const double h = 1e-3;
    std::vector<double> a = lp, b = lp;
    a[k] += h;
    b[k] -= h;
    VecX ra, rb;
    ASSERT_TRUE(EvaluateForwardMap(in, a, &ra, nullptr));
    ASSERT_TRUE(EvaluateForwardMap(in, b, &rb, nullptr));
    const VecX fd = (ra - rb) / (2 * h);
    const double scale = fd.cwiseAbs().maxCoeff();
    EXPECT_LT((J.col(k) - fd).cwiseAbs().maxCoeff(), 1e-4 * scale)
        << in.parameters[k].name << "\nJ  " << J.col(k).transpose() << "\nfd " << fd.transpose();
  }
}

TEST(ReactionFit, RecoversBendingAndTwistFromReactionsAlone) {
  const FitInput truth = Wire();
  FitInput in = truth;
  in.cases.push_back(Measured(truth, Bridge(), {"clamp", "pins[0]", "end_clamp"}));
  in.cases.push_back(Measured(truth, Twisted(truth), {"clamp", "grasp"}));
  AddParameters(&in, 1.8);
  FitOptions options;
  options.trusted_sigmas = true;  // noise-free data
  const FitResult r = Fit(in, options);
  ASSERT_TRUE(r.success) << r.message;
  for (const Parameter& e : r.parameters) {
    if (!e.fit) continue;
    const double t = e.name == "bend_stiffness"     ? truth.material.bend_stiffness
                     : e.name == "bend_stiffness_2" ? *truth.material.bend_stiffness_2
                                                    : truth.material.twist_stiffness;
    EXPECT_NEAR(e.value, t, 1e-6 * t) << e.name;
  }
}

}  // namespace
}  // namespace rodfit
