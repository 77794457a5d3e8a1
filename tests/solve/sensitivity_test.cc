// dx/dlog(p) from the implicit-function theorem against central differences of the whole
// forward map (solve at p e^{+-h}), for every stiffness, on a 3-D loaded anisotropic rod.
#include <cmath>

#include <gtest/gtest.h>

#include "rodfit/solve/sensitivity.h"
#include "test_util.h"

namespace rodfit {
namespace {

Scene LoadedScene() {
  Scene s = testing::Cantilever(30, 0.4);
  s.material.bend_stiffness_2 = 1.6;
  s.material.stretch_stiffness = 2e3;  // soft enough that EA's effect is well above round-off
  s.rod.rest_curvature = Vec3(0.5, 0.2, 0.6);
  s.gravity = Vec3(0, 0, -9.81);
  s.cases[0].clamp.tangent = Vec3(1, 0, 0.4);
  s.cases[0].tip_force = Vec3(0.2, 1.1, -0.6);
  s.cases[0].tip_moment = Vec3(0.3, 0.0, 0.2);
  return s;
}

Mat3X SolveWith(Scene s, Stiffness which, double factor) {
  Material& m = s.material;
  switch (which) {
    case Stiffness::kBend1: m.bend_stiffness *= factor; break;
    case Stiffness::kBend2: *m.bend_stiffness_2 *= factor; break;
    case Stiffness::kTwist: m.twist_stiffness *= factor; break;
    case Stiffness::kStretch: m.stretch_stiffness *= factor; break;
  }
  const RodModel model = testing::ModelOf(s);
  RodState state = model.StraightState();
  StaticsOptions options;
  options.gradient_tolerance = 1e-12;
  const StaticsSummary summary = SolveStatics(model, options, &state);
  EXPECT_TRUE(summary.converged) << summary.BriefReport();
  return state.x;
}

TEST(Sensitivity, MatchesCentralDifferencesOfTheForwardMap) {
  const Scene s = LoadedScene();
  const RodModel model = testing::ModelOf(s);
  RodState state = model.StraightState();
  StaticsWorkspace ws;
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &state, &ws).converged);
  const std::vector<Stiffness> all = {Stiffness::kBend1, Stiffness::kBend2, Stiffness::kTwist,
                                      Stiffness::kStretch};
  Eigen::MatrixXd dq;
  ASSERT_TRUE(StiffnessSensitivities(model, state, ws, all, &dq));
  const Eigen::MatrixXd dx = VertexSensitivities(model, dq);
  const double h = 1e-4;
  for (size_t k = 0; k < all.size(); ++k) {
    const Mat3X xp = SolveWith(s, all[k], std::exp(h)), xm = SolveWith(s, all[k], std::exp(-h));
    const Mat3X fd = (xp - xm) / (2 * h);
    const Eigen::Map<const Eigen::VectorXd> fd_flat(fd.data(), fd.size());
    const double scale = fd_flat.cwiseAbs().maxCoeff();
    ASSERT_GT(scale, 1e-8) << StiffnessName(all[k]) << " has no visible effect in this case";
    // Central differences carry O(h^2) ~ 1e-8 relative truncation.
    EXPECT_LT((dx.col(k) - fd_flat).cwiseAbs().maxCoeff(), 1e-5 * scale)
        << StiffnessName(all[k]) << "\nIFT\n" << dx.col(k).transpose() << "\ncentral\n"
        << fd_flat.transpose();
  }
}

TEST(Sensitivity, RefusesWithoutAFactorisation) {
  const Scene s = LoadedScene();
  const RodModel model = testing::ModelOf(s);
  const RodState state = model.StraightState();
  StaticsWorkspace ws;  // never solved
  Eigen::MatrixXd dq;
  EXPECT_FALSE(StiffnessSensitivities(model, state, ws, {Stiffness::kBend1}, &dq));
}

}  // namespace
}  // namespace rodfit
