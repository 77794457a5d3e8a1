// Tissue terms: springs tying the rod to its rest position, cuts, and a grasp with its
// reaction force. Published references and physics checks, and derivatives.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

namespace rodfit {
namespace {

RodModel Model(const Scene& s, const std::vector<SpringZone>& zones, int k = 0) {
  return RodModel(s.rod, s.material, s.gravity, s.cases[k], zones);
}

StaticsSummary Solve(const RodModel& m, RodState* state, StaticsWorkspace* ws = nullptr) {
  StaticsOptions o;
  o.gradient_tolerance = 1e-11;
  return SolveStatics(m, o, state, ws);
}

// Hetenyi, "Beams on Elastic Foundation" (1946), infinite beam under a point load P on a
// Winkler foundation of modulus k: w(x) = P beta / (2k) exp(-beta x)(cos beta x + sin beta x),
// beta = (k / 4 EI)^(1/4) (docs/model.md, "Validation"). A long rod (L = 30 / beta each side of the
// load) approximates the infinite beam; the peak deflection must be within 2 %.
TEST(Springs, WinklerFoundationPointLoad) {
  const double EI = 1.0, k = 1e4, P = 1.0;
  const double beta = std::pow(k / (4 * EI), 0.25);
  Scene s = testing::Cantilever(600);
  s.rod.length = 6.0;  // load at 3 = 21 / beta from both ends
  s.material.spring_stiffness = k;
  s.material.stretch_stiffness = 1e8;
  s.cases[0].point_forces.push_back({3.0, Vec3(0, 0, -P)});
  const RodModel model = Model(s, {{0.0, 6.0, ""}});
  RodState state = model.StraightState();
  const StaticsSummary summary = Solve(model, &state);
  ASSERT_TRUE(summary.converged) << summary.BriefReport();
  const double peak = -state.vertex(300).z();
  const double expected = P * beta / (2 * k);
  EXPECT_NEAR(peak, expected, 0.02 * expected);
  // And the decay: at x = pi / (2 beta) the closed form gives exp(-pi/2) of the peak.
  const int i = 300 + static_cast<int>(std::lround(M_PI / (2 * beta) / 0.01));
  const double x = (i - 300) * 0.01;
  const double w_x = expected * std::exp(-beta * x) * (std::cos(beta * x) + std::sin(beta * x));
  EXPECT_NEAR(-state.vertex(i).z(), w_x, 0.02 * expected);
}

// The tissue paper's scenario: a uniform rod under gravity fixed at one end, without and with
// springs. With springs, far from the clamp the weight per length is carried by the springs
// alone: the sag tends to rho g / K.
TEST(Springs, GravitySagTendsToWeightOverK) {
  Scene s = testing::Cantilever(200, 0.5);  // rho = 0.5 kg/m, EI = 1, L = 1
  s.gravity = Vec3(0, 0, -9.81);
  s.material.spring_stiffness = 2e5;       // beta = (K / 4EI)^(1/4) = 15 / m: 1/beta << L
  const RodModel free_rod = Model(s, {});
  RodState a = free_rod.StraightState();
  ASSERT_TRUE(Solve(free_rod, &a).converged);
  const RodModel tied = Model(s, {{0.0, 1.0, ""}});
  RodState b = tied.StraightState();
  ASSERT_TRUE(Solve(tied, &b).converged);
  const double sag_far = -b.vertex(150).z();
  const double expected = 0.5 * 9.81 / 2e5;
  EXPECT_NEAR(sag_far, expected, 1e-3 * expected);
  // Without springs the same rod hangs far lower (a cantilever under its weight).
  EXPECT_GT(-a.vertex(200).z(), 100 * expected);
}

TEST(Springs, CutRemovesTheSprings) {
  Scene s = testing::Cantilever(100, 0.5);
  s.gravity = Vec3(0, 0, -9.81);
  s.material.spring_stiffness = 2e5;
  s.cases[0].cuts.push_back({0.5, 1.0});  // the distal half is cut free
  const RodModel model = Model(s, {{0.0, 1.0, ""}});
  EXPECT_EQ(model.zone_cell_length(0, 80), 0.0);
  EXPECT_NEAR(model.zone_cell_length(0, 20), 0.01, 1e-15);
  EXPECT_NEAR(model.zone_cell_length(0, 50), 0.005, 1e-15);  // half its cell is cut
  RodState state = model.StraightState();
  ASSERT_TRUE(Solve(model, &state).converged);
  // The free half hangs from the tied one: its tip sags far more than rho g / K.
  EXPECT_GT(-state.vertex(100).z(), 20 * 0.5 * 9.81 / 2e5);
}

TEST(Springs, BadZonesAreRejected) {
  Scene s = testing::Cantilever(10);
  s.material.spring_stiffness = 1.0;
  EXPECT_THROW(Model(s, {{0.0, 0.6, ""}, {0.5, 1.0, ""}}), std::invalid_argument);  // overlap
  EXPECT_THROW(Model(s, {{0.5, 1.2, ""}}), std::invalid_argument);  // beyond L
  EXPECT_THROW(Model(s, {{0.0, 1.0, "mesentery"}}), std::invalid_argument);  // no value
  s.cases[0].cuts.push_back({-0.1, 0.2});
  EXPECT_THROW(Model(s, {{0.0, 1.0, ""}}), std::invalid_argument);  // cut outside the rod
}

// A scene with every tissue term: two zones (one with its own parameter), a cut, a grasp.
Scene TissueScene() {
  Scene s = testing::Cantilever(16, 0.3);
  s.gravity = Vec3(0.4, 0.2, -9.81);
  s.material.stretch_stiffness = 500;
  s.material.spring_stiffness = 40;
  s.material.spring_parameters["mesentery"] = 90;
  s.cases[0].cuts.push_back({0.3, 0.4});
  s.cases[0].grasp = Grasp{0.75, Vec3(0.6, 0.25, 0.2)};
  s.cases[0].tip_force = Vec3(0.1, 0.0, 0.3);
  return s;
}
const std::vector<SpringZone> kZones = {{0.0, 0.5, ""}, {0.5, 1.0, "mesentery"}};

TEST(Springs, GradientAndHessianMatchCentralDifferences) {
  const Scene s = TissueScene();
  Scene free_scene = s;
  free_scene.cases[0].grasp.reset();  // all dofs free for the difference test
  const RodModel model = Model(free_scene, kZones);
  RodState state = model.StraightState();
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0, 1);
  VecX step(model.num_free_dofs());
  for (int i = 0; i < step.size(); ++i) step[i] = 0.3 * N(rng) * (i % 4 == 3 ? 1.0 : 1.0 / 16);
  RodState bent;
  double alpha = 1.0;  // halve a random step that would fold an edge
  while (!ApplyStep(model, state, step, alpha, &bent)) alpha *= 0.5;
  VecX g;
  BandedSymmetric H;
  AssembleHessian(model, bent, EnergyTerms(), &g, &H);
  for (int a = 0; a < model.num_free_dofs(); ++a) {
    const double h = 1e-6;
    auto displaced = [&](double d) {
      RodState r = bent;
      if (a % 4 == 3) r.theta[a / 4] += d;
      else r.x(a % 4, a / 4 + 1) += d;
      r.SyncEdges();
      return r;
    };
    const double fd = (PotentialEnergy(model, displaced(h)) - PotentialEnergy(model, displaced(-h))) / (2 * h);
    EXPECT_NEAR(g[a], fd, 1e-6 * (1 + std::abs(fd))) << "dof " << a;
  }
  // The springs' Hessian contribution is K l I on each vertex block.
  VecX g0;
  BandedSymmetric Hs;
  AssembleHessian(model, bent, EnergyTerms::OnlySprings(nullptr), &g0, &Hs);
  for (int i = 1; i <= 16; ++i) {
    double k = 0;
    for (int z = 0; z < 2; ++z) k += model.zone_stiffness(z) * model.zone_cell_length(z, i);
    const int d = RodModel::VertexDof(i);
    EXPECT_NEAR(Hs.Get(d, d), k, 1e-12 * (1 + k));
    EXPECT_NEAR(Hs.Get(d, d + 1), 0.0, 1e-15);
    EXPECT_LT((g0.segment<3>(d) - k * (bent.vertex(i) - model.spring_anchor(i))).norm(), 1e-12);
  }
}

TEST(Grasp, HoldsTheVertexAndReactionIsTheEnvelopeDerivative) {
  const Scene s = TissueScene();
  const RodModel model = Model(s, kZones);
  RodState state = model.StraightState();
  const StaticsSummary summary = Solve(model, &state);
  ASSERT_TRUE(summary.converged) << summary.BriefReport();
  const int k = model.grasp_vertex();
  EXPECT_EQ(k, 12);
  EXPECT_LT((state.vertex(k) - s.cases[0].grasp->position).norm(), 1e-14);
  const Vec3 reaction = GraspReaction(model, state);
  // Envelope theorem: d Pi*(p) / dp is the force the instrument applies, so the tissue pulls
  // on the instrument with -d Pi* / dp. Central differences over re-solved equilibria.
  for (int c = 0; c < 3; ++c) {
    const double h = 1e-5;
    double pi[2];
    for (int side = 0; side < 2; ++side) {
      Scene moved = s;
      moved.cases[0].grasp->position[c] += side == 0 ? h : -h;
      const RodModel m = Model(moved, kZones);
      RodState st = state;
      st.x.col(k) = moved.cases[0].grasp->position;
      for (int i = k + 1; i <= 16; ++i) st.x.col(i) += moved.cases[0].grasp->position - state.vertex(k);
      RodState fresh = m.StraightState();
      ASSERT_TRUE(Solve(m, &fresh).converged);
      pi[side] = PotentialEnergy(m, fresh);
    }
    const double dpi = (pi[0] - pi[1]) / (2 * h);
    EXPECT_NEAR(reaction[c], -dpi, 1e-5 * (1 + reaction.norm())) << "component " << c;
  }
}

TEST(Grasp, ReactionClosesTheForceBalance) {
  // The rod as a whole is in equilibrium: the clamp's force (the elastic forces summed over the
  // free vertices, by translation invariance of the elastic energy), the grasp's force on the
  // rod (-GraspReaction), the dead loads and the spring forces add up to zero.
  const Scene s = TissueScene();
  const RodModel model = Model(s, kZones);
  RodState state = model.StraightState();
  ASSERT_TRUE(Solve(model, &state).converged);
  Vec3 loads = Vec3::Zero(), springs = Vec3::Zero();
  for (int i = 1; i <= 16; ++i) {
    loads += model.vertex_forces().col(i);
    for (int z = 0; z < 2; ++z)
      springs -= model.zone_stiffness(z) * model.zone_cell_length(z, i) *
                 (state.vertex(i) - model.spring_anchor(i));
  }
  EnergyTerms elastic = EnergyTerms::Elastic();
  elastic.springs = 0.0;
  elastic.hold = false;
  VecX g;
  AssembleGradient(model, state, elastic, &g);
  Vec3 clamp_on_rod = Vec3::Zero();
  for (int i = 1; i <= 16; ++i) clamp_on_rod -= g.segment<3>(RodModel::VertexDof(i));
  const Vec3 grasp_on_rod = -GraspReaction(model, state);
  EXPECT_GT(grasp_on_rod.norm(), 0.1 * loads.norm());  // the grasp carries a real share
  EXPECT_LT((clamp_on_rod + grasp_on_rod + loads + springs).norm(), 1e-8 * (1 + loads.norm()));
}

TEST(Springs, SensitivityToEachZoneMatchesTheForwardMap) {
  Scene s = TissueScene();
  s.cases[0].grasp.reset();
  const RodModel model = Model(s, kZones);
  RodState state = model.StraightState();
  StaticsWorkspace ws;
  ASSERT_TRUE(Solve(model, &state, &ws).converged);
  const std::string plain, named = "mesentery";
  Eigen::MatrixXd dq;
  ASSERT_TRUE(TermSensitivities(model, state, ws,
                                {EnergyTerms::OnlySprings(&plain), EnergyTerms::OnlySprings(&named)},
                                &dq));
  const Eigen::MatrixXd dx = VertexSensitivities(model, dq);
  for (int col = 0; col < 2; ++col) {
    const double h = 1e-4;
    Mat3X x[2];
    for (int side = 0; side < 2; ++side) {
      Scene p = s;
      const double f = std::exp(side == 0 ? h : -h);
      if (col == 0) p.material.spring_stiffness *= f;
      else p.material.spring_parameters["mesentery"] *= f;
      const RodModel m = Model(p, kZones);
      RodState st = m.StraightState();
      ASSERT_TRUE(Solve(m, &st).converged);
      x[side] = st.x;
    }
    const Mat3X fd = (x[0] - x[1]) / (2 * h);
    const Eigen::Map<const VecX> f(fd.data(), fd.size());
    EXPECT_LT((dx.col(col) - f).cwiseAbs().maxCoeff(), 1e-5 * f.cwiseAbs().maxCoeff()) << col;
  }
}

}  // namespace
}  // namespace rodfit
