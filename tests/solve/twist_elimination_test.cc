// Twist elimination (statics.h, StaticsOptions::eliminate_twist; docs/solvers.md): a scene in
// which nothing can twist the rod is solved over the positions only, with the twist angles
// following them at zero twist. The answer must be the full solve's (to 1e-10 L), the
// position-only Hessian must be the exact second derivative of the eliminated energy, the
// sensitivities and reactions must not change, and a scene that can twist keeps its twist.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"
#include "rodfit/solve/statics_workspace.h"
#include "test_util.h"

namespace rodfit {
namespace {

using testing::Cantilever;

// The largest vertex distance / L between two states.
double MaxDistance(const RodState& a, const RodState& b, double L) {
  return (a.x - b.x).colwise().norm().maxCoeff() / L;
}

struct Solved {
  RodState state;
  StaticsSummary summary;
  std::shared_ptr<StaticsWorkspace> ws = NewStaticsWorkspace();
};

Solved Solve(const Scene& s, bool eliminate) {
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
  StaticsOptions o;
  o.eliminate_twist = eliminate;
  Solved out;
  out.state = model.StraightState();
  out.summary = SolveStatics(model, o, &out.state, out.ws.get());
  return out;
}

// The planar heavy cantilever: isotropic, sagging under its own weight.
Scene HeavyPlanar(int segments) {
  Scene s = Cantilever(segments, /*density=*/2.0);
  s.gravity = Vec3(0, 0, -9.81);
  return s;
}

// An isotropic 3-D case: a tilted clamp with a tip force out of every plane of the rod.
Scene TipForce3D(int segments) {
  Scene s = Cantilever(segments, /*density=*/0.5);
  s.gravity = Vec3(0, 0, -9.81);
  s.cases[0].clamp.tangent = Vec3(std::cos(0.4), 0, std::sin(0.4));
  s.cases[0].tip_force = Vec3(0.5, 2.0, -1.5);
  return s;
}

// The same answer with and without: positions to 1e-10 L (both solves converge to 1e-9 of the
// load scale; Newton's last step makes the state exact far below that), the twist angles alike.
void ExpectSameAnswer(const Scene& s, const char* what) {
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
  ASSERT_TRUE(TwistCanBeEliminated(model)) << what;
  const Solved with = Solve(s, true), without = Solve(s, false);
  ASSERT_TRUE(with.summary.converged) << what << ": " << with.summary.BriefReport();
  ASSERT_TRUE(without.summary.converged) << what << ": " << without.summary.BriefReport();
  EXPECT_TRUE(with.summary.twist_eliminated) << what;
  EXPECT_FALSE(without.summary.twist_eliminated) << what;
  EXPECT_LE(MaxDistance(with.state, without.state, s.rod.length), 1e-10) << what;
  // The full solve finds zero twist by itself: the material frames agree. (The twist angles
  // themselves need not: they are measured from reference frames transported in time, which
  // depend on the iterates each solve went through.)
  double frame_difference = 0.0;
  for (int j = 0; j < model.num_edges(); ++j)
    frame_difference = std::max(frame_difference, (model.MaterialFrame(with.state, j).d1 -
                                                   model.MaterialFrame(without.state, j).d1)
                                                      .norm());
  EXPECT_LE(frame_difference, 1e-8) << what;
  EXPECT_EQ(with.summary.stable, without.summary.stable) << what;
}

TEST(TwistElimination, PlanarHeavyCantileverSameAnswer) {
  for (int n : {20, 100, 400}) ExpectSameAnswer(HeavyPlanar(n), "planar heavy cantilever");
}

TEST(TwistElimination, ThreeDimensionalTipForceSameAnswer) {
  for (int n : {30, 150}) ExpectSameAnswer(TipForce3D(n), "3-D tip force");
}

TEST(TwistElimination, HeldPointsSameAnswer) {
  // An end clamp holding only the tangent (free to turn about it) and a pin: held rows in the
  // position-only system, continuation of held points.
  Scene s = TipForce3D(60);
  s.cases[0].tip_force = Vec3::Zero();  // the end clamp takes the end
  EndClamp end;
  end.position = Vec3(0.6, 0.3, 0.2);
  end.tangent = Vec3(0.2, 1.0, 0.0);
  s.cases[0].end_clamp = end;
  ExpectSameAnswer(s, "end clamp without normal");
  Scene p = HeavyPlanar(60);
  Pin pin;
  pin.s = 0.5;
  pin.position = Vec3(0.45, 0.1, -0.1);
  p.cases[0].pins.push_back(pin);
  ExpectSameAnswer(p, "pin");
}

TEST(TwistElimination, ScenesThatCanTwistKeepTheTwist) {
  struct Variant {
    const char* what;
    void (*apply)(Scene*);
  };
  const Variant variants[] = {
      {"tip moment", [](Scene* s) { s->cases[0].tip_moment = Vec3(0.0, 0.3, 0.2); }},
      {"anisotropic bending", [](Scene* s) { s->material.bend_stiffness_2 = 1.4; }},
      {"rest twist", [](Scene* s) { s->rod.rest_curvature = Vec3(0, 0, 0.5); }},
      {"rest curvature", [](Scene* s) { s->rod.rest_curvature = Vec3(0, 1.0, 0); }},
      {"end clamp with normal",
       [](Scene* s) {
         EndClamp end;
         end.position = Vec3(0.6, 0.3, 0.2);
         end.tangent = Vec3(0.2, 1.0, 0.0);
         end.normal = Vec3(0, 0, 1);
         s->cases[0].end_clamp = end;
         s->cases[0].tip_force = Vec3::Zero();
       }},
  };
  for (const Variant& v : variants) {
    Scene s = TipForce3D(40);
    v.apply(&s);
    const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
    EXPECT_FALSE(TwistCanBeEliminated(model)) << v.what;
    const Solved solved = Solve(s, true);
    ASSERT_TRUE(solved.summary.converged) << v.what << ": " << solved.summary.BriefReport();
    EXPECT_FALSE(solved.summary.twist_eliminated) << v.what;
    EXPECT_FALSE(solved.ws->factor_positions) << v.what;
  }
}

// The position-only Hessian is the derivative of the position gradient along zero-twist
// motions: at an equilibrium (where the retraction's own curvature meets a zero gradient),
// H d against central differences of the gradient along d, the twist following the positions.
TEST(TwistElimination, PositionHessianIsTheEliminatedEnergysSecondDerivative) {
  const Scene s = TipForce3D(12);
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
  Solved solved = Solve(s, true);
  ASSERT_TRUE(solved.summary.converged);
  const RodState& x = solved.state;
  VecX g;
  BandedSymmetric H;
  AssemblePositionHessian(model, x, EnergyTerms(), &g, &H);
  ASSERT_EQ(H.size(), NumPositionDofs(model));
  VecX d = VecX::Zero(model.num_free_dofs());
  for (int i = 1; i <= model.num_edges(); ++i)
    d.segment<3>(RodModel::VertexDof(i)) =
        Vec3(std::sin(1.3 * i), std::cos(0.7 * i), std::sin(0.4 * i + 1.0)) * 1e-2;
  VecX dp;
  GatherPositions(d, &dp);
  const VecX Hd = H.Multiply(dp);
  const double h = 1e-5;
  auto gradient_at = [&](double a) {
    RodState moved;
    EXPECT_TRUE(ApplyStep(model, x, d, a, &moved));
    SetZeroTwist(model, &moved);
    VecX gf, gp;
    AssembleGradient(model, moved, EnergyTerms(), &gf);
    GatherPositions(gf, &gp);
    return gp;
  };
  const VecX fd = (gradient_at(h) - gradient_at(-h)) / (2 * h);
  // Central differences with h = 1e-5 on a stiff stretch (EA / B = 1e6): truncation ~h^2 of
  // the third derivative, round-off ~eps |g_stretch| / h; 1e-5 of the largest entry covers both.
  const double scale = Hd.cwiseAbs().maxCoeff();
  EXPECT_LE((Hd - fd).cwiseAbs().maxCoeff(), 1e-5 * scale)
      << "H d:\n" << Hd.transpose() << "\ncentral differences:\n" << fd.transpose();
}

// Sensitivities from an eliminated solve (which keeps only the position-only factor) equal the
// full solve's, B1 and B2 apart included (each alone breaks the isotropy), and so do the
// reactions at the held points.
TEST(TwistElimination, SensitivitiesAndReactionsUnchanged) {
  Scene s = TipForce3D(40);
  s.cases[0].tip_force = Vec3::Zero();
  EndClamp end;
  end.position = Vec3(0.6, 0.3, 0.2);
  end.tangent = Vec3(0.2, 1.0, 0.0);
  s.cases[0].end_clamp = end;
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
  const Solved with = Solve(s, true), without = Solve(s, false);
  ASSERT_TRUE(with.summary.converged && without.summary.converged);
  ASSERT_TRUE(with.ws->factor_positions);
  const std::vector<Stiffness> which = {Stiffness::kBend1, Stiffness::kBend2, Stiffness::kTwist,
                                        Stiffness::kStretch};
  Eigen::MatrixXd dq_with, dq_without;
  ASSERT_TRUE(StiffnessSensitivities(model, with.state, *with.ws, which, &dq_with));
  ASSERT_TRUE(StiffnessSensitivities(model, without.state, *without.ws, which, &dq_without));
  const Eigen::MatrixXd dx_with = VertexSensitivities(model, dq_with);
  const Eigen::MatrixXd dx_without = VertexSensitivities(model, dq_without);
  // dx/dlog B1 is of the order of the deflection (~L): 1e-8 L is far below any use of it and
  // above the difference the two solutions' 1e-10 L makes through the Hessian's conditioning.
  EXPECT_LE((dx_with - dx_without).cwiseAbs().maxCoeff(), 1e-8 * s.rod.length)
      << dx_with.topRows(12) << "\n\n" << dx_without.topRows(12);
  EXPECT_GT(dx_with.col(0).cwiseAbs().maxCoeff(), 1e-3);  // B1 does move the rod
  const std::vector<HeldReaction> r_with = HeldReactions(model, with.state);
  const std::vector<HeldReaction> r_without = HeldReactions(model, without.state);
  ASSERT_EQ(r_with.size(), r_without.size());
  // Each solve leaves every free generalised force below gradient_tolerance x the load scale,
  // and a clamp's reaction balances the whole rod, so it sums up to n of them: that is as far as
  // two converged solves' reactions can be apart.
  const double F = model.num_edges() * StaticsOptions().gradient_tolerance * model.force_scale();
  for (size_t k = 0; k < r_with.size(); ++k) {
    EXPECT_LE((r_with[k].force - r_without[k].force).norm(), F) << r_with[k].point;
    EXPECT_LE((r_with[k].moment - r_without[k].moment).norm(), F * s.rod.length)
        << r_with[k].point;
  }
}

// Parameters that keep the rod isotropic (B1 and B2 together, GJ, EA) are derived with the kept
// position-only factor and the twist angles' zero-twist variation (no full Hessian): every row,
// the twist rows included, equals the full solve's.
TEST(TwistElimination, IsotropicSensitivitiesFromThePositionFactor) {
  for (bool held : {false, true}) {
    Scene s = TipForce3D(40);
    if (held) {
      s.cases[0].tip_force = Vec3::Zero();
      EndClamp end;
      end.position = Vec3(0.6, 0.3, 0.2);
      end.tangent = Vec3(0.2, 1.0, 0.0);
      s.cases[0].end_clamp = end;
    }
    const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
    const Solved with = Solve(s, true), without = Solve(s, false);
    ASSERT_TRUE(with.summary.converged && without.summary.converged);
    ASSERT_TRUE(with.ws->factor_positions);
    EnergyTerms bend = EnergyTerms::Only(-1);
    bend.bend1 = bend.bend2 = 1.0;
    const std::vector<EnergyTerms> terms = {bend, EnergyTerms::Only(2), EnergyTerms::Only(3)};
    Eigen::MatrixXd dq_with, dq_without;
    ASSERT_TRUE(TermSensitivities(model, with.state, *with.ws, terms, &dq_with));
    ASSERT_TRUE(TermSensitivities(model, without.state, *without.ws, terms, &dq_without));
    // Positions in L, twist angles in radians: 1e-8, as above.
    EXPECT_LE((dq_with - dq_without).cwiseAbs().maxCoeff(), 1e-8)
        << (held ? "end clamp" : "free end") << "\n"
        << dq_with.topRows(8) << "\n\n" << dq_without.topRows(8);
    EXPECT_GT(dq_with.col(0).cwiseAbs().maxCoeff(), 1e-3);
    // GJ moves nothing when nothing twists.
    EXPECT_LE(dq_with.col(1).cwiseAbs().maxCoeff(), 1e-12);
  }
}

// A warm re-solve after a change of dead loads reuses the kept position-only factor and lands
// where a cold eliminated solve does.
TEST(TwistElimination, WarmStartFromPositionFactor) {
  Scene s = HeavyPlanar(80);
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0], s.springs);
  Solved first = Solve(s, true);
  ASSERT_TRUE(first.summary.converged);
  Scene pushed = s;
  pushed.cases[0].tip_force = Vec3(0, 0.3, -0.2);
  const RodModel model2(pushed.rod, pushed.material, pushed.gravity, pushed.cases[0]);
  ASSERT_EQ(model2.hessian_digest(), model.hessian_digest());
  RodState warm = first.state;
  const StaticsSummary again = SolveStatics(model2, StaticsOptions(), &warm, first.ws.get());
  ASSERT_TRUE(again.converged) << again.BriefReport();
  const Solved cold = Solve(pushed, true);
  ASSERT_TRUE(cold.summary.converged);
  EXPECT_LE(MaxDistance(warm, cold.state, 1.0), 1e-10);
}

}  // namespace
}  // namespace rodfit
