// Warm starts that reuse the kept factorisation (statics.h, RodModel::hessian_digest): the
// digest separates what changes the Hessian from dead loads, and a re-solve that takes its first
// step with the kept factor ends at the same equilibrium, with the same factor and the same
// sensitivities, as one that assembles everything again.
#include <cmath>

#include <gtest/gtest.h>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

namespace rodfit {
namespace {

using testing::ModelOf;

Scene Heavy() { return testing::HeavyCantilever(); }

TEST(HessianDigest, DeadLoadsKeepItEverythingTheHessianReadsChangesIt) {
  const Scene base = Heavy();
  const uint64_t d0 = ModelOf(base).hessian_digest();
  // Dead loads: the Hessian is the same.
  Scene s = base;
  s.cases[0].tip_force *= 1.01;
  EXPECT_EQ(ModelOf(s).hessian_digest(), d0);
  s = base;
  s.gravity *= 0.5;
  EXPECT_EQ(ModelOf(s).hessian_digest(), d0);
  s = base;
  s.cases[0].point_forces.push_back({0.3, Vec3(0.1, 0.2, 0.3)});
  EXPECT_EQ(ModelOf(s).hessian_digest(), d0);
  // And they give the same assembled Hessian.
  {
    const RodModel a = ModelOf(base), b = ModelOf(s);
    const RodState x = a.StraightState();
    VecX ga, gb;
    BandedSymmetric Ha, Hb;
    AssembleHessian(a, x, EnergyTerms(), &ga, &Ha);
    AssembleHessian(b, x, EnergyTerms(), &gb, &Hb);
    EXPECT_EQ(Ha.band(), Hb.band());
  }
  // Anything the Hessian reads: a new digest.
  auto differs = [&](const Scene& changed, const char* what) {
    EXPECT_NE(ModelOf(changed).hessian_digest(), d0) << what;
  };
  s = base, s.material.bend_stiffness *= 1.01, differs(s, "B1");
  s = base, s.material.bend_stiffness_2 = 1.41, differs(s, "B2");
  s = base, s.material.twist_stiffness *= 1.01, differs(s, "GJ");
  s = base, s.material.stretch_stiffness *= 1.01, differs(s, "EA");
  s = base, s.rod.rest_curvature = Vec3(0.1, 0, 0), differs(s, "rest curvature");
  s = base, s.rod.length = 1.1, differs(s, "length");
  s = base, s.cases[0].tip_moment = Vec3(0, 0.1, 0), differs(s, "tip moment");
  s = base, s.cases[0].clamp.normal = Vec3(0, 1, 0), differs(s, "clamp frame");
  s = base, s.cases[0].clamp.position = Vec3(0, 0, 0.1), differs(s, "clamp position");
  s = base, s.cases[0].grasp = Grasp{0.5, Vec3(0.4, 0.1, 0.2)}, differs(s, "grasp");
  Scene springs = base;
  springs.springs.push_back({0.2, 0.8, ""});
  springs.material.spring_stiffness = 10.0;
  auto with_springs = [](const Scene& sc) {
    return RodModel(sc.rod, sc.material, sc.gravity, sc.cases[0], sc.springs).hessian_digest();
  };
  const uint64_t ds = with_springs(springs);
  EXPECT_NE(ds, d0);
  s = springs, s.material.spring_stiffness = 11.0;
  EXPECT_NE(with_springs(s), ds) << "spring stiffness";
  s = springs, s.cases[0].cuts.push_back({0.4, 0.5});
  EXPECT_NE(with_springs(s), ds) << "cut";
  s = springs, s.cases[0].tip_force *= 2.0;
  EXPECT_EQ(with_springs(s), ds) << "tip force with springs";
}

TEST(WarmStart, ReusingTheKeptFactorGivesTheSameEquilibriumAndSensitivities) {
  Scene s = Heavy();
  const RodModel model = ModelOf(s);
  RodState base = model.StraightState();
  StaticsWorkspace ws;
  ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &base, &ws).converged);
  s.cases[0].tip_force *= 1.01;
  const RodModel changed = ModelOf(s);
  ASSERT_EQ(changed.hessian_digest(), model.hessian_digest());

  // Newton steps only, so that both solves take the same steps (chord_test.cc covers chords).
  StaticsOptions newton;
  newton.chord_steps = false;
  RodState reused = base;  // ws holds the factor at base: the first step reuses it
  const StaticsSummary a = SolveStatics(changed, newton, &reused, &ws);
  RodState fresh = base;
  StaticsWorkspace fresh_ws;  // no factor: everything assembled
  const StaticsSummary b = SolveStatics(changed, newton, &fresh, &fresh_ws);
  ASSERT_TRUE(a.converged) << a.BriefReport();
  ASSERT_TRUE(b.converged) << b.BriefReport();
  EXPECT_TRUE(a.stable);
  // The first step is the same Newton step, so the iterates agree to round-off.
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_LT((reused.x - fresh.x).cwiseAbs().maxCoeff(), 1e-12 * s.rod.length);
  EXPECT_LT((reused.theta - fresh.theta).cwiseAbs().maxCoeff(), 1e-10);
  // The kept factor is the one at the new equilibrium: the sensitivities agree.
  Eigen::MatrixXd da, db;
  const std::vector<Stiffness> all = {Stiffness::kBend1, Stiffness::kBend2, Stiffness::kTwist,
                                      Stiffness::kStretch};
  ASSERT_TRUE(StiffnessSensitivities(changed, reused, ws, all, &da));
  ASSERT_TRUE(StiffnessSensitivities(changed, fresh, fresh_ws, all, &db));
  EXPECT_LT((da - db).cwiseAbs().maxCoeff(), 1e-8 * db.cwiseAbs().maxCoeff());
}

TEST(WarmStart, AFactorFromAnotherStateOrModelIsNotTakenForTheHessian) {
  // Newton steps only: the kept factor may serve as a chord basis (chord_test.cc), but it must
  // never stand in for the Hessian of another model or state, so these solves take exactly the
  // steps of a solve with a fresh workspace.
  StaticsOptions newton;
  newton.chord_steps = false;
  Scene s = Heavy();
  const RodModel model = ModelOf(s);
  RodState base = model.StraightState();
  StaticsWorkspace ws;
  ASSERT_TRUE(SolveStatics(model, newton, &base, &ws).converged);
  // A stiffer model from the same state: the kept factor is not its Hessian.
  s.material.bend_stiffness *= 2.0;
  const RodModel stiffer = ModelOf(s);
  RodState a = base, b = base;
  StaticsWorkspace kept_ws = ws, fresh_ws;
  ASSERT_TRUE(SolveStatics(stiffer, newton, &a, &kept_ws).converged);
  ASSERT_TRUE(SolveStatics(stiffer, newton, &b, &fresh_ws).converged);
  EXPECT_EQ(a.x, b.x);
  // The same model from a perturbed state: not reused either.
  RodState c = base, d = base;
  c.x.col(5) += Vec3(1e-4, 0, 0);
  d.x.col(5) += Vec3(1e-4, 0, 0);
  c.SyncEdges();
  d.SyncEdges();
  StaticsWorkspace ws2 = ws, fresh2;
  ASSERT_TRUE(SolveStatics(model, newton, &c, &ws2).converged);
  ASSERT_TRUE(SolveStatics(model, newton, &d, &fresh2).converged);
  EXPECT_EQ(c.x, d.x);
}

}  // namespace
}  // namespace rodfit
