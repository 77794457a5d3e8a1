// Moments as generalised forces (solve/moment_loads.h): the tangent of the balance against
// central differences of the residual along the solver's retraction, for dead, follower and
// interior moments on a bent, twisted, loaded rod; the virtual work of the generalised force
// against the rotation of the edge it acts on.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

namespace rodfit {
namespace {

Scene MomentScene(int n) {
  Scene s = testing::Cantilever(n, 0.3);
  s.material.bend_stiffness_2 = 1.7;
  s.material.stretch_stiffness = 1e3;
  s.rod.rest_curvature = Vec3(0.4, -0.7, 0.3);
  s.gravity = Vec3(0.5, -1.0, -9.81);
  s.cases[0].clamp.tangent = Vec3(1, 0.3, 0.2);
  s.cases[0].clamp.normal = Vec3(0, 0.2, 1);
  s.cases[0].tip_force = Vec3(0.3, -0.8, -1.1);
  return s;
}

RodState RandomState(const RodModel& model, std::mt19937* rng, double amplitude) {
  std::normal_distribution<double> N(0.0, 1.0);
  RodState state = model.StraightState();
  for (int k = 0; k < 4; ++k) {
    VecX step(model.num_free_dofs());
    for (int i = 0; i < step.size(); ++i)
      step[i] = amplitude * N(*rng) * ((i % 4 == 3) ? 1.0 : model.rest_edge_length(0));
    RodState next;
    double alpha = 1.0;
    while (!ApplyStep(model, state, step, alpha, &next)) alpha *= 0.5;
    state = next;
  }
  return state;
}

void ExpectTangentMatchesResidual(const Scene& s, const char* what) {
  SCOPED_TRACE(what);
  const RodModel model = testing::ModelOf(s);
  std::mt19937 rng(7);
  const RodState state = RandomState(model, &rng, 0.3);
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  VecX r;
  BandedMatrix J;
  BandedSymmetric H;
  AssembleBalance(model, state, frames, 1.0, &r, &J, &H);
  const Eigen::MatrixXd Jd = J.ToDense();
  std::normal_distribution<double> N(0.0, 1.0);
  for (int trial = 0; trial < 6; ++trial) {
    VecX d(model.num_free_dofs());
    for (int i = 0; i < d.size(); ++i) d[i] = N(rng) * ((i % 4 == 3) ? 1.0 : 0.01);
    const double h = 1e-6;
    RodState plus, minus;
    ASSERT_TRUE(ApplyStep(model, state, d, h, &plus));
    ASSERT_TRUE(ApplyStep(model, state, d, -h, &minus));
    VecX rp, rm;
    BalanceResidual(model, plus, &rp);
    BalanceResidual(model, minus, &rm);
    const VecX fd = (rp - rm) / (2 * h);
    const VecX lin = Jd * d;
    const double scale = fd.cwiseAbs().maxCoeff();
    EXPECT_LT((lin - fd).cwiseAbs().maxCoeff(), 2e-6 * scale)
        << "largest entry " << scale << "\nJ d  " << lin.transpose().head(24)
        << "\nfd   " << fd.transpose().head(24);
  }
}

TEST(MomentLoads, TangentMatchesCentralDifferencesOfTheResidual) {
  Scene dead = MomentScene(12);
  dead.cases[0].tip_moment = Vec3(0.2, -0.5, 0.4);
  ExpectTangentMatchesResidual(dead, "dead tip moment");
  Scene follower = MomentScene(12);
  follower.cases[0].tip_moment_follower = Vec3(0.3, -0.2, 0.5);
  ExpectTangentMatchesResidual(follower, "follower tip moment");
  Scene interior = MomentScene(12);
  interior.cases[0].point_moments.push_back({0.43, Vec3(-0.4, 0.6, 0.3)});
  interior.cases[0].point_moments.push_back({0.0, Vec3(0.1, 0.2, -0.3)});
  ExpectTangentMatchesResidual(interior, "interior moments");
}

}  // namespace
}  // namespace rodfit
