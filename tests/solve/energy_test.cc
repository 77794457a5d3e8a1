// Derivative and invariance tests of the assembled rod energy (solve/rod_energy.h): gradient and
// banded Hessian against central differences of Pi at random bent and twisted states (all terms:
// bend, twist, stretch, gravity, tip force and moment, point forces), zero gradient in the rest
// state, a stress-free rest shape for intrinsic curvature with the contract's sign, and
// invariance under rigid motions.
#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "rodfit/solve/statics_workspace.h"
#include "test_util.h"

namespace rodfit {
namespace {

using testing::Cantilever;
using testing::ModelOf;

// A loaded, anisotropic, naturally curved rod with every load type.
Scene LoadedScene(int n) {
  Scene s = Cantilever(n, 0.3);
  s.material.bend_stiffness_2 = 1.7;
  s.material.stretch_stiffness = 1e3;  // soft enough that stretch shows in the differences
  s.rod.rest_curvature = Vec3(0.4, -0.7, 0.3);
  s.gravity = Vec3(0.5, -1.0, -9.81);
  s.cases[0].clamp.tangent = Vec3(1, 0.3, 0.2);
  s.cases[0].clamp.normal = Vec3(0, 0.2, 1);
  s.cases[0].tip_force = Vec3(0.3, -0.8, -1.1);
  s.cases[0].tip_moment = Vec3(0.2, -0.5, 0.4);
  s.cases[0].point_forces.push_back({0.37, Vec3(0.2, 0.5, 0.1)});
  return s;
}

// A random bent and twisted state with fresh frames, reached by retracted random steps.
RodState RandomState(const RodModel& model, std::mt19937* rng, double amplitude) {
  std::normal_distribution<double> N(0.0, 1.0);
  RodState state = model.StraightState();
  for (int k = 0; k < 4; ++k) {
    VecX step(model.num_free_dofs());
    for (int i = 0; i < step.size(); ++i)
      step[i] = amplitude * N(*rng) * ((i % 4 == 3) ? 1.0 : model.rest_edge_length(0));
    // A random step can compress an edge to nothing; halve it until every edge keeps at least
    // half its rest length (a degenerate edge makes central differences meaningless).
    auto shortest = [&](const RodState& r) {
      double m = 1e300;
      for (int j = 0; j < model.num_edges(); ++j)
        m = std::min(m, (r.x.col(j + 1) - r.x.col(j)).norm() / model.rest_edge_length(j));
      return m;
    };
    RodState next;
    double alpha = 1.0;
    while (!ApplyStep(model, state, step, alpha, &next) || shortest(next) < 0.5) alpha *= 0.5;
    state = next;
  }
  return state;
}

// Displaces the free dofs without refreshing the frames: Pi of the result is the energy
// function whose derivatives the solver assembles (frames anchored at `state`).
RodState Displaced(const RodState& state, const VecX& d) {
  RodState out = state;
  for (int i = 1; i < out.x.cols(); ++i) out.x.col(i) += d.segment<3>(RodModel::VertexDof(i));
  for (int j = 0; j < out.theta.size(); ++j) out.theta[j] += d[RodModel::TwistDof(j)];
  out.SyncEdges();
  return out;
}

double StepFor(const RodModel& model, int k) {
  return (k % 4 == 3) ? 1e-5 : 1e-5 * model.rest_edge_length(0);
}

// The solver's line search evaluates Pi with each edge's frame computed once and no transport
// (fresh frames); at a fresh state that is the full energy to round-off, for every term.
TEST(RodEnergy, FreshFramePathEqualsTheFullEnergyAtFreshStates) {
  for (double amplitude : {1e-4, 0.05, 0.3}) {
    const Scene s = LoadedScene(12);
    const RodModel model = ModelOf(s);
    std::mt19937 rng(11);
    const RodState state = RandomState(model, &rng, amplitude);
    for (const EnergyTerms& terms : {EnergyTerms(), EnergyTerms::Elastic(), EnergyTerms::Only(0),
                                     EnergyTerms::Only(2), EnergyTerms::Only(3)}) {
      const double full = PotentialEnergy(model, state, terms);
      const double fresh = PotentialEnergyFreshFrames(model, state, terms);
      EXPECT_NEAR(fresh, full, 1e-12 * (std::abs(full) + 1e-6)) << "amplitude " << amplitude;
    }
    // Not a shortcut that ignores the twist: a twisted state changes both alike.
    RodState twisted = state;
    twisted.theta[5] += 0.3;
    EXPECT_NEAR(PotentialEnergyFreshFrames(model, twisted), PotentialEnergy(model, twisted),
                1e-12 * std::abs(PotentialEnergy(model, twisted)));
    EXPECT_GT(std::abs(PotentialEnergy(model, twisted) - PotentialEnergy(model, state)), 1e-6);
  }
}

// The runtime reads a held point's reaction from AssembleGradientRows: the rows it promises equal
// AssembleGradient's to the last bit, at every window, with springs, a free end and an end
// clamp (whose ghost stencil reaches the last vertex), held rows off as the reaction needs.
TEST(RodEnergy, GradientRowsEqualTheWholeGradient) {
  for (const bool end_clamp : {false, true}) {
    Scene s = LoadedScene(12);
    s.springs.push_back({0.2, 0.7, ""});
    s.material.spring_stiffness = 40.0;
    if (end_clamp) {
      s.cases[0].tip_moment = Vec3::Zero();
      s.cases[0].tip_force = Vec3::Zero();
      s.cases[0].end_clamp = EndClamp{Vec3(0.9, 0.2, -0.1), Vec3(1, 0, 0.2), Vec3(0, 0, 1)};
    }
    const RodModel model = ModelOf(s);
    std::mt19937 rng(5);
    const RodState state = RandomState(model, &rng, 0.05);
    EnergyTerms terms;
    terms.hold = false;
    VecX whole, rows;
    AssembleGradient(model, state, terms, &whole);
    RodFrames frames;
    const int n = model.num_edges();
    for (int first = 1; first <= n; ++first) {
      for (int last = first; last <= std::min(n, first + 2); ++last) {
        AssembleGradientRows(model, state, terms, first, last, &rows, &frames);
        for (int v = first; v <= last; ++v)
          for (int k = 0; k < 3; ++k)
            EXPECT_EQ(rows[RodModel::VertexDof(v) + k], whole[RodModel::VertexDof(v) + k])
                << "vertex " << v << " of rows " << first << ".." << last;
        for (int j = std::max(first - 1, 0); j <= std::min(last, n - 1 + (end_clamp ? 1 : 0)); ++j)
          EXPECT_EQ(rows[RodModel::TwistDof(j)], whole[RodModel::TwistDof(j)])
              << "twist " << j << " of rows " << first << ".." << last;
      }
    }
  }
}

TEST(RodEnergy, GradientAndHessianMatchCentralDifferences) {
  for (double amplitude : {1e-4, 0.05, 0.3}) {  // nearly straight to strongly bent
    const Scene s = LoadedScene(12);
    const RodModel model = ModelOf(s);
    std::mt19937 rng(7);
    const RodState state = RandomState(model, &rng, amplitude);
    VecX g;
    BandedSymmetric H;
    AssembleHessian(model, state, EnergyTerms(), &g, &H);
    VecX g_only;
    AssembleGradient(model, state, EnergyTerms(), &g_only);
    EXPECT_LT((g - g_only).cwiseAbs().maxCoeff(), 1e-12 * g.cwiseAbs().maxCoeff());

    const int nd = model.num_free_dofs();
    VecX g_fd(nd);
    Eigen::MatrixXd H_fd(nd, nd);
    for (int a = 0; a < nd; ++a) {
      VecX da = VecX::Zero(nd);
      da[a] = StepFor(model, a);
      g_fd[a] = (PotentialEnergy(model, Displaced(state, da)) -
                 PotentialEnergy(model, Displaced(state, -da))) / (2 * da[a]);
      // Hessian column by central differences of the energy's second differences.
      for (int b = 0; b < nd; ++b) {
        VecX db = VecX::Zero(nd);
        db[b] = 30 * StepFor(model, b);
        VecX da2 = 30 * da;
        auto E = [&](const VecX& d) { return PotentialEnergy(model, Displaced(state, d)); };
        H_fd(a, b) = (E(da2 + db) - E(da2 - db) - E(-da2 + db) + E(-da2 - db)) /
                     (4 * da2[a] * db[b]);
      }
    }
    const double gscale = g.cwiseAbs().maxCoeff();
    EXPECT_LT((g - g_fd).cwiseAbs().maxCoeff(), 1e-6 * gscale)
        << "amplitude " << amplitude << "\nassembled " << g.transpose() << "\ncentral "
        << g_fd.transpose();
    const Eigen::MatrixXd Hd = H.ToDense();
    const double hscale = Hd.cwiseAbs().maxCoeff();
    Eigen::Index r, c;
    (Hd - H_fd).cwiseAbs().maxCoeff(&r, &c);
    EXPECT_LT((Hd - H_fd).cwiseAbs().maxCoeff(), 2e-5 * hscale)
        << "amplitude " << amplitude << " at (" << r << ", " << c << "): " << Hd(r, c) << " vs "
        << H_fd(r, c);
  }
}

TEST(RodEnergy, ZeroGradientInTheRestState) {
  Scene s = Cantilever(20);
  const RodModel model = ModelOf(s);
  const RodState state = model.StraightState();
  VecX g;
  AssembleGradient(model, state, EnergyTerms(), &g);
  // Zero up to the round-off of the stiff stretch term, eps EA |x| / l = 4.4e-9 N here.
  EXPECT_LT(g.cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT(std::abs(PotentialEnergy(model, state)), 1e-20);
}

TEST(RodEnergy, IntrinsicCurvatureGivesAStressFreeRestShape) {
  // Unloaded, a rod with rest curvature (k1°, k2°, tau°) settles with exactly those material
  // curvatures and no elastic energy; [0, k, 0] bends it towards the clamp's normal (d1).
  Scene s = Cantilever(40);
  s.rod.rest_curvature = Vec3(0.3, 2.0, 0.8);
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  const StaticsSummary summary = SolveStatics(model, StaticsOptions(), &state);
  ASSERT_TRUE(summary.converged) << summary.BriefReport();
  EXPECT_LT(std::abs(PotentialEnergy(model, state)), 1e-18);

  Scene planar = Cantilever(40);
  planar.rod.rest_curvature = Vec3(0, 2.0, 0);
  const RodModel pm = ModelOf(planar);
  RodState ps = pm.StraightState();
  ASSERT_TRUE(SolveStatics(pm, StaticsOptions(), &ps).converged);
  const Vec3 tip = ps.vertex(40);
  EXPECT_GT(tip.z(), 0.2);              // towards the normal +z
  EXPECT_LT(std::abs(tip.y()), 1e-9);   // in the tangent-normal plane
  // An arc of curvature 2: tip at (sin 2 / 2, (1 - cos 2) / 2) up to O(1/N^2).
  EXPECT_NEAR(tip.x(), std::sin(2.0) / 2.0, 2e-3);
  EXPECT_NEAR(tip.z(), (1 - std::cos(2.0)) / 2.0, 2e-3);
}

TEST(RodEnergy, InvariantUnderRigidMotion) {
  const Scene s = LoadedScene(15);
  const RodModel model = ModelOf(s);
  std::mt19937 rng(3);
  const RodState state = RandomState(model, &rng, 0.2);

  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.9, Vec3(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
  const Vec3 p(0.4, -1.2, 2.5);
  Scene moved = s;
  moved.gravity = R * s.gravity;
  LoadCase& c = moved.cases[0];
  c.clamp.position = R * c.clamp.position + p;
  c.clamp.tangent = R * c.clamp.tangent;
  c.clamp.normal = R * c.clamp.normal;
  c.tip_force = R * c.tip_force;
  c.tip_moment = R * c.tip_moment;
  c.point_forces[0].force = R * c.point_forces[0].force;
  const RodModel moved_model = ModelOf(moved);
  RodState moved_state = state;
  moved_state.x = (R * state.x).colwise() + p;
  moved_state.e = R * state.e;
  moved_state.clamp_t = R * state.clamp_t;
  moved_state.clamp_d1 = R * state.clamp_d1;
  moved_state.ref_u = R * state.ref_u;
  moved_state.ref_t = R * state.ref_t;

  // Elastic energy is invariant; the loads' work changes by the constant -F.p only.
  const EnergyTerms elastic = EnergyTerms::Elastic();
  EXPECT_NEAR(PotentialEnergy(moved_model, moved_state, elastic),
              PotentialEnergy(model, state, elastic), 1e-12);
  VecX g, gm;
  AssembleGradient(model, state, EnergyTerms(), &g);
  AssembleGradient(moved_model, moved_state, EnergyTerms(), &gm);
  for (int i = 1; i <= model.num_edges(); ++i) {
    const int k = RodModel::VertexDof(i);
    EXPECT_LT((gm.segment<3>(k) - R * g.segment<3>(k)).norm(), 1e-10);
  }
  for (int j = 0; j < model.num_edges(); ++j)
    EXPECT_NEAR(gm[RodModel::TwistDof(j)], g[RodModel::TwistDof(j)], 1e-10);

  // And the equilibrium moves with it.
  RodState a = model.StraightState(), b = moved_model.StraightState();
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &a).converged);
  ASSERT_TRUE(SolveStatics(moved_model, StaticsOptions(), &b).converged);
  EXPECT_LT((((R * a.x).colwise() + p) - b.x).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Statics, WarmStartFromTheSolutionReturnsAtOnce) {
  const Scene s = LoadedScene(30);
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  StaticsWorkspace ws;
  StaticsSummary first = SolveStatics(model, StaticsOptions(), &state, &ws);
  ASSERT_TRUE(first.converged) << first.BriefReport();
  // The scene carries a tip moment: the kept factor is the LU of its non-symmetric tangent.
  EXPECT_TRUE(ws.tangent_valid);
  const RodState solved = state;
  StaticsSummary again = SolveStatics(model, StaticsOptions(), &state, &ws);
  ASSERT_TRUE(again.converged);
  EXPECT_LE(again.iterations, 1);
  EXPECT_LT((state.x - solved.x).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Statics, IterationCapIsReportedNotHidden) {
  const Scene s = LoadedScene(30);
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  StaticsOptions options;
  options.max_iterations = 1;
  const StaticsSummary summary = SolveStatics(model, options, &state);
  EXPECT_FALSE(summary.converged);
  EXPECT_FALSE(summary.IsUsable());
  EXPECT_NE(summary.reason.find("iteration"), std::string::npos) << summary.reason;
}

TEST(Statics, OptionsAreChecked) {
  StaticsOptions o;
  std::string why;
  EXPECT_TRUE(o.Check(&why));
  o.gradient_tolerance = -1;
  EXPECT_FALSE(o.Check(&why));
  EXPECT_NE(why.find("gradient_tolerance"), std::string::npos);
}

}  // namespace
}  // namespace rodfit
