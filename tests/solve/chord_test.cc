// Chord steps (StaticsOptions::chord_steps, statics.cc ChordStep): Newton steps between which
// the solver reuses the last factor, carried to the current edge directions. They must change
// how fast a solve gets there, never where it ends: the same equilibrium as Newton alone, the
// same stability verdict, and a kept factor that is the Hessian's own at the solution.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"
#include "test_util.h"

namespace rodfit {
namespace {

using testing::ModelOf;

// The heavy cantilever; EA L^2 / EI = 1e6, the stiff-stretch regime where unrotated chords
// fail. (Chord steps belong to the potential's symmetric path: a case with moments is solved
// with its non-symmetric tangent instead.)
Scene Heavy() { return testing::HeavyCantilever(); }

StaticsOptions WithChords(bool on) {
  StaticsOptions o;
  o.chord_steps = on;
  return o;
}

// The largest difference of the material directors d1 between two states. (The twist angles
// themselves are not comparable: they are measured from reference frames transported along the
// iterates, so two paths to one equilibrium hold different reference frames and angles.)
double MaterialFrameGap(const RodModel& model, const RodState& a, const RodState& b) {
  RodFrames fa, fb;
  ComputeRodFrames(model, a, &fa);
  ComputeRodFrames(model, b, &fb);
  double gap = 0.0;
  for (size_t j = 0; j < fa.edges.size(); ++j)
    gap = std::max(gap, (fa.edges[j].d1 - fb.edges[j].d1).cwiseAbs().maxCoeff());
  return gap;
}

struct Change {
  const char* what;
  void (*apply)(Scene*);
};

// Warm re-solves after each change, from the old equilibrium and its workspace, with and without
// chord steps. Both end at the same equilibrium (within what the gradient tolerance resolves:
// 1e-9 of the force scale, ~20 N here, over a compliance L^3 / 3 EI = 0.3 m/N, ~1e-8 m).
TEST(ChordSteps, WarmResolvesEndWhereNewtonEnds) {
  const Change changes[] = {
      {"tip force +1%", [](Scene* s) { s->cases[0].tip_force *= 1.01; }},
      {"tip force +10%", [](Scene* s) { s->cases[0].tip_force *= 1.1; }},
      {"tip force x3", [](Scene* s) { s->cases[0].tip_force *= 3.0; }},
      {"gravity +1%", [](Scene* s) { s->gravity *= 1.01; }},
      {"gravity +5%", [](Scene* s) { s->gravity *= 1.05; }},
      {"B1 +1%", [](Scene* s) { s->material.bend_stiffness *= 1.01; }},
      {"B1 +30%", [](Scene* s) { s->material.bend_stiffness *= 1.3; }},
      {"GJ +10%", [](Scene* s) { s->material.twist_stiffness *= 1.1; }},
      {"EA +1%", [](Scene* s) { s->material.stretch_stiffness *= 1.01; }},
  };
  const Scene base_scene = Heavy();
  const RodModel base_model = ModelOf(base_scene);
  RodState base = base_model.StraightState();
  StaticsWorkspace base_ws;
  ASSERT_TRUE(SolveStatics(base_model, WithChords(true), &base, &base_ws).converged);
  const double L = base_scene.rod.length;
  int solves_with_chords = 0;
  for (const Change& c : changes) {
    SCOPED_TRACE(c.what);
    Scene s = base_scene;
    c.apply(&s);
    const RodModel model = ModelOf(s);
    RodState with = base, without = base;
    StaticsWorkspace ws_with = base_ws, ws_without = base_ws;
    const StaticsSummary a = SolveStatics(model, WithChords(true), &with, &ws_with);
    const StaticsSummary b = SolveStatics(model, WithChords(false), &without, &ws_without);
    ASSERT_TRUE(a.converged) << a.BriefReport();
    ASSERT_TRUE(b.converged) << b.BriefReport();
    EXPECT_EQ(a.stable, b.stable);
    EXPECT_EQ(b.chord_steps, 0);
    solves_with_chords += (a.chord_steps > 0);
    EXPECT_LT((with.x - without.x).cwiseAbs().maxCoeff(), 1e-7 * L);
    EXPECT_LT(MaterialFrameGap(model, with, without), 1e-6);
    // The kept factor is the Hessian's at the solution: the sensitivities agree with those of
    // a factor assembled there from scratch (a fresh workspace converges at once).
    RodState again = with;
    StaticsWorkspace fresh_ws;
    const StaticsSummary f = SolveStatics(model, WithChords(false), &again, &fresh_ws);
    ASSERT_TRUE(f.converged);
    ASSERT_EQ(f.iterations, 0);
    Eigen::MatrixXd kept, fresh;
    const std::vector<Stiffness> all = {Stiffness::kBend1, Stiffness::kBend2, Stiffness::kTwist,
                                        Stiffness::kStretch};
    ASSERT_TRUE(StiffnessSensitivities(model, with, ws_with, all, &kept));
    ASSERT_TRUE(StiffnessSensitivities(model, again, fresh_ws, all, &fresh));
    EXPECT_LT((kept - fresh).cwiseAbs().maxCoeff(), 1e-9 * fresh.cwiseAbs().maxCoeff());
  }
  EXPECT_GE(solves_with_chords, 3);  // the comparison means something only if chords were taken
}

// The case chord steps are for: a haptic loop re-solving a suture after 1 % load changes. The
// first step reuses the kept factor (the exact Newton step); then one chord step reaches the
// tolerance where Newton would have assembled and factored a Hessian, and the Hessian is
// assembled once, at the solution. Over 40 re-solves in a row, each from the last, the state
// does not drift from Newton's.
TEST(ChordSteps, HapticLoopOnASutureTakesOneChordPerResolveAndDoesNotDrift) {
  Scene s = testing::BenchmarkSuture(100);
  const RodModel a = ModelOf(s);
  s.cases[0].tip_force *= 1.01;
  const RodModel b = ModelOf(s);
  RodState with = a.StraightState(), without = with;
  StaticsWorkspace ws_with, ws_without;
  ASSERT_TRUE(SolveStatics(a, WithChords(true), &with, &ws_with).converged);
  ASSERT_TRUE(SolveStatics(a, WithChords(false), &without, &ws_without).converged);
  for (int k = 0; k < 40; ++k) {
    SCOPED_TRACE(k);
    const RodModel& m = (k % 2 == 0) ? b : a;
    const StaticsSummary x = SolveStatics(m, WithChords(true), &with, &ws_with);
    const StaticsSummary y = SolveStatics(m, WithChords(false), &without, &ws_without);
    ASSERT_TRUE(x.converged) << x.BriefReport();
    ASSERT_TRUE(y.converged) << y.BriefReport();
    EXPECT_EQ(x.iterations, 2) << x.BriefReport();
    EXPECT_EQ(x.chord_steps, 1) << x.BriefReport();
    EXPECT_EQ(y.iterations, 2) << y.BriefReport();
  }
  // The tolerance resolves positions to about 1e-9 of the force scale (~1e-4 N) times the
  // compliance L^3 / 3 EI ~ 3e3 m/N, ~3e-7 m; the two runs agree far better than that.
  EXPECT_LT((with.x - without.x).cwiseAbs().maxCoeff(), 1e-7 * s.rod.length);
  EXPECT_LT(MaterialFrameGap(a, with, without), 1e-8);
}

// A fixed grasp adds Dirichlet rows that the edge-wise carrying of the factor does not respect:
// such solves keep to Newton.
TEST(ChordSteps, AFixedGraspKeepsToNewton) {
  Scene s = Heavy();
  s.cases[0].grasp = Grasp{0.6, Vec3(0.5, 0.1, 0.3)};
  const RodModel model = ModelOf(s);
  RodState state = model.StraightState();
  StaticsWorkspace ws;
  const StaticsSummary first = SolveStatics(model, WithChords(true), &state, &ws);
  ASSERT_TRUE(first.converged) << first.BriefReport();
  s.cases[0].tip_force *= 1.01;
  const StaticsSummary again = SolveStatics(ModelOf(s), WithChords(true), &state, &ws);
  ASSERT_TRUE(again.converged) << again.BriefReport();
  EXPECT_EQ(first.chord_steps, 0);
  EXPECT_EQ(again.chord_steps, 0);
}

}  // namespace
}  // namespace rodfit
