// The interactive runtime (rodfit/runtime/runtime.h) against the statics solver that `rodfit
// simulate` runs: the same equilibrium after a drag, the same reaction, the reaction as the
// derivative of the equilibrium energy, and the haptic-loop guarantees (a failed step keeps the
// last good state, nothing turns non-finite).
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/reactions.h"

namespace rodfit {
namespace {

Profile Bundled(const std::string& name) {
  return LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + name);
}

// The scene `rodfit simulate` would solve: the profile's rod and held ends, grasped at s.
Scene GraspScene(const Profile& p, double s, const Vec3& position) {
  Scene scene = p.scene;
  scene.cases.front().grasp = Grasp{s, position};
  return scene;
}

// Moves the tool from where it is to `target` in `ticks` equal steps, then re-solves there
// until a tick converges with no iteration left to do.
void Drag(Runtime* rt, const Vec3& target, int ticks) {
  const Vec3 from = rt->ToolPosition();
  for (int k = 1; k <= ticks; ++k) {
    rt->SetToolPosition(from + (target - from) * (static_cast<double>(k) / ticks));
    const StepReport r = rt->Step();
    ASSERT_TRUE(r.ok()) << "tick " << k << ": " << ToString(r.status) << " after "
                        << r.iterations << " iterations, residual " << r.residual << " N";
  }
}

struct DragCase {
  const char* profile;
  double s;
  Vec3 target;
};

class RoundTrip : public ::testing::TestWithParam<DragCase> {};

// Profile -> runtime -> the shape `rodfit simulate` finds for the same grasp (SolveCase is the
// path simulate runs), to 1e-10 of the rod's length, and the same force on the tool.
TEST_P(RoundTrip, DragEndsInTheStaticsEquilibrium) {
  const DragCase c = GetParam();
  const Profile p = Bundled(c.profile);
  RuntimeOptions options;
  options.tool_s = c.s;
  Runtime rt(p, options);
  Drag(&rt, c.target, 50);

  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  const CaseSolution ref = SolveCase(GraspScene(p, c.s, c.target), 0, nullptr, statics);
  ASSERT_TRUE(ref.ok()) << ref.summary.reason;
  const double length = p.scene.rod.length;
  const double shape_error = (rt.Shape() - ref.state.x).cwiseAbs().maxCoeff();
  std::printf("%s: max |x_runtime - x_simulate| = %.3e m (%.3e L)\n", c.profile, shape_error,
              shape_error / length);
  // Both solves stop at their gradient tolerance; the shapes then agree to ~1e-12 L.
  EXPECT_LT(shape_error, 1e-10 * length);
  Vec3 grasp_force = Vec3::Zero();
  for (const HeldReaction& r : ref.reactions)
    if (r.point == "grasp") grasp_force = r.force;
  ASSERT_GT(grasp_force.norm(), 0.0);
  EXPECT_LT((rt.ToolForce() - grasp_force).norm(), 1e-7 * grasp_force.norm())
      << rt.ToolForce().transpose() << " vs " << grasp_force.transpose();
  EXPECT_EQ(rt.ToolTorque(), Vec3::Zero());
}

INSTANTIATE_TEST_SUITE_P(
    Bundled, RoundTrip,
    ::testing::Values(DragCase{"bowel_drag.json", 0.1, Vec3(0.1, 0.015, 0.02)},
                      DragCase{"suture.json", 0.2, Vec3(0.17, 0.05, 0.03)},
                      DragCase{"bowel_poke.json", 0.06, Vec3(0.06, 0.0, 0.01)}));

// The force on the tool is -dPi*/dp, Pi* the equilibrium energy as a function of the tool's
// position (the envelope theorem): central differences over each axis.
TEST(Runtime, ToolForceIsMinusTheEnergyGradient) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  Runtime rt(p, options);
  const Vec3 at(0.1, 0.012, 0.015);
  Drag(&rt, at, 30);
  const Vec3 force = rt.ToolForce();
  // h: the force changes by ~1e-6 of itself over h, so the central difference's truncation
  // (~h^2 f'') and round-off (eps Pi / h) are both far below the 1e-5 asked.
  const double h = 1e-6;
  Vec3 gradient;
  for (int a = 0; a < 3; ++a) {
    double energy[2];
    for (int side = 0; side < 2; ++side) {
      Vec3 q = at;
      q[a] += side == 0 ? h : -h;
      rt.SetToolPosition(q);
      ASSERT_TRUE(rt.Step().ok());
      energy[side] = rt.Energy();
    }
    gradient[a] = (energy[0] - energy[1]) / (2.0 * h);
  }
  EXPECT_LT((force + gradient).norm(), 1e-5 * force.norm())
      << "force " << force.transpose() << ", -dPi/dp " << (-gradient).transpose();
}

// The reactions close the balance: tool, clamp, weight and springs.
TEST(Runtime, ReactionsCloseTheForceBalance) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;
  options.tool_s = 0.2;
  Runtime rt(p, options);
  Drag(&rt, Vec3(0.15, 0.04, -0.02), 40);
  const RodModel& model = rt.model();
  Vec3 weight = Vec3::Zero();
  for (int i = 0; i < model.num_vertices(); ++i) weight += model.vertex_weight(i);
  Vec3 clamp = Vec3::Zero(), tool = Vec3::Zero();
  for (const HeldReaction& r : HeldReactions(model, rt.state())) {
    if (r.point == "clamp") clamp = r.force;
    if (r.point == "grasp") tool = r.force;
  }
  EXPECT_LT((tool - rt.ToolForce()).norm(), 1e-9 * tool.norm());
  // The holders carry the weight: what the rod exerts on them sums to its weight.
  EXPECT_LT((clamp + tool - weight).norm(), 1e-8 * weight.norm())
      << (clamp + tool).transpose() << " vs " << weight.transpose();
}

TEST(Runtime, FailedStepKeepsTheLastGoodState) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;
  options.tool_s = 0.2;
  options.max_iterations = 4;
  Runtime rt(p, options);
  Drag(&rt, Vec3(0.18, 0.03, 0.0), 200);
  const Mat3X good = rt.Shape();
  const Vec3 good_force = rt.ToolForce();
  // A jump across the room in one tick: Newton cannot get there in three iterations.
  rt.SetToolPosition(Vec3(-0.5, 2.0, 1.0));
  StepReport r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kNotConverged);
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_EQ(rt.ToolForce(), good_force);
  // A non-finite tool position from a glitching device: refused, state kept.
  rt.SetToolPosition(Vec3(std::nan(""), 0.0, 0.0));
  r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kNotConverged);
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_TRUE(rt.Shape().allFinite());
  // Back on the path, the loop carries on.
  rt.SetToolPosition(Vec3(0.181, 0.03, 0.0));
  EXPECT_TRUE(rt.Step().ok());
}

TEST(Runtime, TimeBudgetReturnsTheLastGoodState) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  options.time_budget = 1e-12;  // below any Newton iteration's cost
  Runtime rt(p, options);
  const Mat3X before = rt.Shape();
  rt.SetToolPosition(rt.ToolPosition() + Vec3(0.0, 0.01, 0.0));
  const StepReport r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kTimeBudget);
  EXPECT_EQ(rt.Shape(), before);
}

// A poke: the force on the tool is the tissue pushing back, and the mesh carries the dent.
TEST(Runtime, PokeDentsTheMesh) {
  const Profile p = Bundled("bowel_poke.json");
  ASSERT_TRUE(p.scene.section.has_value());
  RuntimeOptions options;
  options.tool = ToolKind::kPoke;
  options.tool_s = 0.075;
  Runtime rt(p, options);
  const TubeMesh before = rt.Mesh();
  const Vec3 push(0.0, -0.03, 0.0);
  rt.SetToolForce(push);
  ASSERT_TRUE(rt.Step().ok());
  EXPECT_EQ(rt.ToolForce(), -push);
  const TubeMesh after = rt.Mesh();
  ASSERT_EQ(after.num_vertices(), before.num_vertices());
  // The dent: the mesh moves more than the centre-line does near the tool.
  const TubeMesh swept = BuildTube(rt.model(), rt.state(), p.scene.section->radius,
                                   options.mesh_ring_vertices);
  EXPECT_GT((after.vertices - swept.vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE(after.vertices.allFinite());
}

// Dynamic ticks: a closed tool path leaves no energy behind (BDF2 and the damping only take
// energy out), and the rod comes back to rest where it started.
TEST(Runtime, DynamicClosedPathDoesNotGainEnergy) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  options.mode = RuntimeMode::kDynamic;
  Runtime rt(p, options);
  const Vec3 centre = rt.ToolPosition();
  const double e_start = rt.Energy() + rt.KineticEnergy();
  const int ticks_per_turn = 1000;  // 1 s per turn at 1 kHz
  for (int k = 1; k <= 10 * ticks_per_turn; ++k) {
    const double phase = 2.0 * M_PI * k / ticks_per_turn;
    rt.SetToolPosition(centre + 0.01 * Vec3(0.0, std::sin(phase), 1.0 - std::cos(phase)));
    ASSERT_TRUE(rt.Step().ok()) << "tick " << k;
  }
  for (int k = 0; k < 2000; ++k) ASSERT_TRUE(rt.Step().ok());  // the tool at rest, back home
  const double e_end = rt.Energy() + rt.KineticEnergy();
  std::printf("bowel dynamic: energy %.6e J at start, %.6e J after 10 turns and 2 s of rest\n",
              e_start, e_end);
  EXPECT_LE(e_end, e_start + 1e-6 * std::abs(e_start));
  EXPECT_TRUE(rt.Shape().allFinite());
}

TEST(Runtime, InvalidOptionsAreRefused) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;  // tool_s missing
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
  options.tool_s = 0.5;  // beyond L = 0.2
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
  options.tool_s = 0.1;
  options.tool = ToolKind::kPoke;
  options.mode = RuntimeMode::kDynamic;
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
