// The interactive runtime (rodfit/runtime/runtime.h) against the statics solver that `rodfit
// simulate` runs: the same equilibrium after a drag, the same reaction, the reaction as the
// derivative of the equilibrium energy, and the haptic-loop guarantees (a failed step keeps the
// last good state, nothing turns non-finite).
#include <algorithm>
#include <fstream>
#include <sstream>
#include <cmath>
#include <limits>
#include <ostream>
#include <vector>
#include <string>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

Profile Bundled(const std::string& name) {
  return LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + name);
}

// The scene `rodfit simulate` would solve: the profile's rod and held ends, grasped at s.
Scene GraspScene(const Profile& p, double s, const Vec3& position) {
  Scene scene = p.scene;
  scene.cases.front().grasp = Grasp{s, position};
  return scene;
}

// Moves the tool from where it is to `target` in `ticks` equal steps, each followed until the
// grasped point is at the tool.
void Drag(Runtime* rt, const Vec3& target, int ticks) {
  const Vec3 from = rt->ToolPosition();
  for (int k = 1; k <= ticks; ++k) {
    rt->SetToolPosition(from + (target - from) * (static_cast<double>(k) / ticks));
    StepReport r = rt->Step();
    ASSERT_TRUE(r.ok()) << "tick " << k << ": " << ToString(r.status) << " after "
                        << r.iterations << " iterations, residual " << r.residual << " N";
    // A tick moves the grasped point by at most max_tool_move: catch up before the next.
    for (int extra = 0; r.tool_lag > 0.0 && extra < 100; ++extra) {
      r = rt->Step();
      ASSERT_TRUE(r.ok());
    }
    ASSERT_EQ(r.tool_lag, 0.0);
  }
}

struct DragCase {
  const char* profile;
  double s;
  Vec3 target;
};

// Test names and messages by profile (not the struct's bytes).
void PrintTo(const DragCase& c, std::ostream* os) { *os << c.profile << " at s = " << c.s; }
std::string DragCaseName(const ::testing::TestParamInfo<DragCase>& info) {
  std::string name = info.param.profile;
  return name.substr(0, name.find('.'));
}

class RoundTrip : public ::testing::TestWithParam<DragCase> {};

// Profile -> runtime -> the shape `rodfit simulate` finds for the same grasp (SolveCase is the
// path simulate runs), to 1e-10 of the rod's length, and the same force on the tool.
TEST_P(RoundTrip, DragEndsInTheStaticsEquilibrium) {
  const DragCase c = GetParam();
  const Profile p = Bundled(c.profile);
  RuntimeOptions options;
  options.tool_s = c.s;
  Runtime rt(p, options);
  // At most 0.2 mm per tick: a hand moving the tool at 0.2 m/s in a 1 kHz loop.
  Drag(&rt, c.target, static_cast<int>(std::ceil((c.target - rt.ToolPosition()).norm() / 2e-4)));

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
                      DragCase{"bowel_poke.json", 0.06, Vec3(0.06, 0.0, 0.01)}),
    DragCaseName);

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
  Drag(&rt, Vec3(0.15, 0.04, -0.02), 400);
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

// An oriented grasp holds the edge ending at the grasped point as the tool's rigid body: the
// torque on the tool is -dPi*/dphi, phi a small rotation of the tool about the grasped point
// (central differences about each world axis), and the force is still -dPi*/dp.
TEST(Runtime, OrientedGraspTorqueIsMinusTheEnergyRotationGradient) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  options.hold_orientation = true;
  Runtime rt(p, options);
  EXPECT_LT(rt.ToolTorque().norm(), 1e-12);  // taken where the rod lies: no torque yet
  const Vec3 at(0.1, 0.012, 0.015);
  Drag(&rt, at, 30);
  const Eigen::Matrix3d turned =
      Eigen::AngleAxisd(0.3, Vec3(1.0, 1.0, 0.5).normalized()).toRotationMatrix();
  rt.SetToolOrientation(turned);
  StepReport r;
  for (int k = 0; k < 10 && (k == 0 || r.tool_turn_lag > 0.0); ++k) {
    r = rt.Step();
    ASSERT_TRUE(r.ok()) << "tick " << k << ": " << ToString(r.status);
  }
  ASSERT_EQ(r.tool_turn_lag, 0.0);
  EXPECT_LT((rt.ToolOrientation() - turned).norm(), 1e-15);
  const Vec3 torque = rt.ToolTorque();
  const Vec3 force = rt.ToolForce();
  ASSERT_GT(torque.norm(), 0.0);
  // h: as for the force, truncation and round-off of the central difference far below 1e-5.
  const double h = 1e-6;
  Vec3 rotation_gradient, position_gradient;
  for (int a = 0; a < 3; ++a) {
    double energy[2];
    for (int side = 0; side < 2; ++side) {
      rt.SetToolOrientation(Eigen::AngleAxisd(side == 0 ? h : -h, Vec3::Unit(a)) * turned);
      ASSERT_TRUE(rt.Step().ok());
      energy[side] = rt.Energy();
    }
    rotation_gradient[a] = (energy[0] - energy[1]) / (2.0 * h);
    rt.SetToolOrientation(turned);
    for (int side = 0; side < 2; ++side) {
      Vec3 q = at;
      q[a] += side == 0 ? h : -h;
      rt.SetToolPosition(q);
      ASSERT_TRUE(rt.Step().ok());
      energy[side] = rt.Energy();
    }
    position_gradient[a] = (energy[0] - energy[1]) / (2.0 * h);
    rt.SetToolPosition(at);
  }
  EXPECT_LT((torque + rotation_gradient).norm(), 1e-5 * torque.norm())
      << "torque " << torque.transpose() << ", -dPi/dphi " << (-rotation_gradient).transpose();
  EXPECT_LT((force + position_gradient).norm(), 1e-5 * force.norm())
      << "force " << force.transpose() << ", -dPi/dp " << (-position_gradient).transpose();
}

// An oriented grasp's reactions close the force balance: the clamp and the tool (its force on
// both held vertices) carry the weight.
TEST(Runtime, OrientedGraspReactionsCloseTheBalance) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;
  options.tool_s = 0.15;
  options.hold_orientation = true;
  Runtime rt(p, options);
  Drag(&rt, rt.ToolPosition() + Vec3(-0.01, 0.01, 0.005), 100);
  const RodModel& model = rt.model();
  const RodState& s = rt.state();
  Vec3 weight = Vec3::Zero();
  for (int i = 0; i < model.num_vertices(); ++i) weight += model.vertex_weight(i);
  Vec3 clamp = Vec3::Zero();
  for (const HeldReaction& h : HeldReactions(model, s))
    if (h.point == "clamp") clamp = h.force;
  EXPECT_LT((clamp + rt.ToolForce() - weight).norm(), 1e-8 * weight.norm())
      << (clamp + rt.ToolForce()).transpose() << " vs " << weight.transpose();
  EXPECT_GT(rt.ToolTorque().norm(), 0.0);
}

TEST(Runtime, FailedStepKeepsTheLastGoodState) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;
  options.tool_s = 0.2;
  options.max_iterations = 1;  // a tool move needs several Newton iterations
  Runtime rt(p, options);
  const Mat3X good = rt.Shape();
  const Vec3 good_force = rt.ToolForce();
  const Vec3 home = rt.ToolPosition();
  rt.SetToolPosition(home + Vec3(-2e-4, 1e-4, 0.0));
  StepReport r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kNotConverged);
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_EQ(rt.ToolForce(), good_force);
  EXPECT_THAT(r.message, HasSubstr("iteration limit reached after 1 Newton iterations"));
  // A non-finite tool position from a glitching device: refused, state kept, the value named.
  rt.SetToolPosition(Vec3(std::nan(""), 0.0, 0.0));
  r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kToolRefused);
  EXPECT_THAT(r.message, HasSubstr("tool position x = nan is not finite"));
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_TRUE(std::isinf(r.tool_lag));
  // Back where the rod is in equilibrium, the loop carries on.
  rt.SetToolPosition(home);
  r = rt.Step();
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.tool_lag, 0.0);
}

// A quasi-static solve cut short by its iteration cap is not thrown away nor tried again whole:
// the next tick resumes it from where it stopped, and ends in the equilibrium a solve with
// iterations to spare finds for the same move.
TEST(Runtime, SolveCutShortIsResumedByTheNextTick) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;
  options.tool_s = 0.2;
  options.max_iterations = 1;  // the move below needs more (printed)
  Runtime rt(p, options);
  options.max_iterations = 20;
  Runtime reference(p, options);
  const Vec3 target = rt.ToolPosition() + Vec3(-2e-4, 1e-4, 0.0);
  rt.SetToolPosition(target);
  reference.SetToolPosition(target);
  const StepReport done = reference.Step();
  ASSERT_TRUE(done.ok());
  ASSERT_GT(done.iterations, 1);
  StepReport r = rt.Step();
  ASSERT_EQ(r.status, StepStatus::kNotConverged);
  EXPECT_THAT(r.message, HasSubstr("the next tick resumes the solve"));
  int ticks = 1, iterations = r.iterations;
  while (!r.ok() && ticks < 5) {
    r = rt.Step();
    iterations += r.iterations;
    ++ticks;
  }
  ASSERT_TRUE(r.ok()) << r.message;
  std::printf("cut short at 1 iteration a tick: converged at tick %d after %d iterations in all "
              "(uncut: %d)\n", ticks, iterations, done.iterations);
  EXPECT_EQ(r.tool_lag, 0.0);
  // One Newton iteration a tick, resumed: about the iterations of the uncut solve, not a restart
  // per tick.
  EXPECT_LE(iterations, done.iterations + 1);
  EXPECT_LT((rt.Shape() - reference.Shape()).cwiseAbs().maxCoeff(), 1e-9 * p.scene.rod.length);
}

// A tool that jumps far ahead (a lost tracking frame) is followed at max_tool_move per tick:
// every tick converges, and the lag closes.
TEST(Runtime, FarJumpIsFollowedOverSeveralTicks) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  Runtime rt(p, options);
  const Vec3 target = rt.ToolPosition() + Vec3(0.0, 0.01, 0.005);
  rt.SetToolPosition(target);
  const double max_move = options.max_tool_move * rt.model().min_rest_edge_length();
  double lag = (target - rt.ToolPosition()).norm();
  int ticks = 0;
  while (lag > 0.0 && ticks < 1000) {
    const StepReport r = rt.Step();
    ASSERT_TRUE(r.ok()) << "tick " << ticks;
    EXPECT_NEAR(r.tool_lag, std::max(0.0, lag - max_move), 1e-12);
    lag = r.tool_lag;
    ++ticks;
  }
  EXPECT_EQ(lag, 0.0);
  EXPECT_EQ(ticks, static_cast<int>(std::ceil(0.0111803398875 / max_move - 1e-9)));
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

// The dynamic step keeps the budget too: past it the tick gives up with the last good state
// (rates and time included). The tick after a lost one has no budget and catches up: it takes
// the step the lost tick would have (the same as a runtime without a budget), and the budget
// holds again for the tick after it.
TEST(Runtime, DynamicTimeBudgetReturnsTheLastGoodState) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  options.mode = RuntimeMode::kDynamic;
  options.time_budget = 1e-12;  // below any Newton iteration's cost
  Runtime rt(p, options);
  const Mat3X before = rt.Shape();
  const Vec3 force = rt.ToolForce();
  const Vec3 moved = rt.ToolPosition() + Vec3(0.0, 1e-3, 0.0);
  rt.SetToolPosition(moved);
  StepReport r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kTimeBudget);
  EXPECT_EQ(rt.Shape(), before);
  EXPECT_EQ(rt.ToolForce(), force);
  EXPECT_EQ(rt.KineticEnergy(), 0.0);

  options.time_budget = 0.0;
  Runtime unlimited(p, options);
  unlimited.SetToolPosition(moved);
  const StepReport first = unlimited.Step();
  EXPECT_EQ(first.status, StepStatus::kConverged);
  EXPECT_GT(first.iterations, 1);  // so a budget checked before the second iteration could bite

  r = rt.Step();  // catching up
  EXPECT_EQ(r.status, StepStatus::kConverged);
  EXPECT_LT((rt.Shape() - unlimited.Shape()).cwiseAbs().maxCoeff(), 1e-12 * p.scene.rod.length);
  EXPECT_GT(rt.KineticEnergy(), 0.0);
  const Mat3X caught_up = rt.Shape();
  rt.SetToolPosition(moved + Vec3(0.0, 1e-3, 0.0));
  r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kTimeBudget);
  EXPECT_EQ(rt.Shape(), caught_up);
}

// A budget beyond what the steady clock's 64-bit nanoseconds hold (1e308 s, infinity: both
// accepted, as >= 0) is no limit: each tick, quasi-static and dynamic, is the tick without a
// budget. Before, the budget was converted to nanoseconds unchecked — undefined behaviour, which
// the sanitized C API corpus aborted on (a signed overflow in the deadline's arithmetic) and
// which in the release build put the deadline in the past (a quasi-static tick ran out of time
// after its first Newton iteration).
TEST(Runtime, HugeTimeBudgetIsNoLimit) {
  const Profile p = Bundled("bowel_drag.json");
  for (const RuntimeMode mode : {RuntimeMode::kQuasiStatic, RuntimeMode::kDynamic}) {
    RuntimeOptions options;
    options.tool_s = 0.1;
    options.mode = mode;
    Runtime unlimited(p, options);
    const Vec3 moved = unlimited.ToolPosition() + Vec3(0.0, 1e-3, 0.0);
    unlimited.SetToolPosition(moved);
    const StepReport reference = unlimited.Step();
    ASSERT_EQ(reference.status, StepStatus::kConverged);
    ASSERT_GT(reference.iterations, 1);  // so a deadline already past would bite
    for (const double budget : {1e308, std::numeric_limits<double>::infinity(), 2e9}) {
      options.time_budget = budget;
      Runtime rt(p, options);
      rt.SetToolPosition(moved);
      const StepReport r = rt.Step();
      EXPECT_EQ(r.status, StepStatus::kConverged) << "budget " << budget;
      EXPECT_EQ(r.iterations, reference.iterations) << "budget " << budget;
      EXPECT_EQ(rt.Shape(), unlimited.Shape()) << "budget " << budget;
    }
  }
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

// The loop's mesh (into a kept buffer, the ring warm-started from the last tick's dent) is the
// mesh built afresh (the ring solved from rest) to the ring's tolerance, tick after tick, as the
// push rises, turns and falls back to zero.
TEST(Runtime, MeshIntoBufferIsTheFreshMesh) {
  const Profile p = Bundled("bowel_poke.json");
  RuntimeOptions options;
  options.tool = ToolKind::kPoke;
  options.tool_s = 0.075;
  Runtime rt(p, options);
  TubeMesh mesh;
  rt.Mesh(&mesh);
  EXPECT_EQ(mesh.vertices, rt.Mesh().vertices);  // no dent: the same sweep
  double deepest = 0.0;
  for (int k = 1; k <= 40; ++k) {
    const double phase = 2.0 * M_PI * k / 40.0;
    rt.SetToolForce(0.03 * (1.0 - std::cos(phase)) *
                    Vec3(0.0, -std::cos(0.5 * phase), -std::sin(0.5 * phase)));
    ASSERT_TRUE(rt.Step().ok()) << "tick " << k;
    rt.Mesh(&mesh);
    const TubeMesh fresh = rt.Mesh();
    ASSERT_EQ(mesh.triangles, fresh.triangles);
    const TubeMesh swept = BuildTube(rt.model(), rt.state(), p.scene.section->radius,
                                     options.mesh_ring_vertices);
    const double dent = (fresh.vertices - swept.vertices).cwiseAbs().maxCoeff();
    deepest = std::max(deepest, dent);
    // Both rings meet the same gradient test (1e-10 |F|) from different starts: their nodes,
    // and so the propagated moves, agree to about 1e-10 of the dent (measured at most 2e-10 of
    // it); 1e-8 leaves a factor of 50 for round-off elsewhere.
    EXPECT_LE((mesh.vertices - fresh.vertices).cwiseAbs().maxCoeff(), 1e-8 * dent + 1e-15)
        << "tick " << k;
  }
  EXPECT_GT(deepest, 1e-3 * p.scene.section->radius);  // a real dent was compared
}

// A closed tool path, one turn per second at 1 kHz, in the tool's y-z plane.
Vec3 Circle(const Vec3& centre, double radius, int tick, int ticks_per_turn) {
  const double phase = 2.0 * M_PI * tick / ticks_per_turn;
  return centre + radius * Vec3(0.0, std::sin(phase), 1.0 - std::cos(phase));
}

// Quasi-static ticks: the equilibrium energy is a function of the tool's position, so every
// turn of a closed path ends at the same energy — no drift over 10^4 ticks.
TEST(Runtime, QuasiStaticClosedPathReturnsToItsEnergy) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  Runtime rt(p, options);
  const Vec3 centre = rt.ToolPosition();
  const double e_start = rt.Energy();
  const int ticks_per_turn = 1000;
  double worst = 0.0;
  for (int turn = 1; turn <= 10; ++turn) {
    for (int k = 1; k <= ticks_per_turn; ++k) {
      rt.SetToolPosition(Circle(centre, 0.01, k, ticks_per_turn));
      ASSERT_TRUE(rt.Step().ok()) << "turn " << turn << " tick " << k;
    }
    worst = std::max(worst, std::abs(rt.Energy() - e_start));
  }
  std::printf("bowel quasi-static: |E(turn) - E(0)| <= %.3e J of %.3e J over 10^4 ticks\n", worst,
              std::abs(e_start));
  // Each turn ends at the start's equilibrium, solved to the gradient tolerance: the energy
  // error is second order in the state's, far below 1e-10 of the energy.
  EXPECT_LT(worst, 1e-10 * std::abs(e_start));
}

// Dynamic ticks: the tool does work on the rod along the path, but the energy at the end of each
// turn must not grow from turn to turn (BDF2 and the damping only take energy out; a growing
// energy would be the integrator going unstable), over 10^5 ticks.
TEST(Runtime, DynamicClosedPathDoesNotGainEnergy) {
  const Profile p = Bundled("bowel_drag.json");
  RuntimeOptions options;
  options.tool_s = 0.1;
  options.mode = RuntimeMode::kDynamic;
  Runtime rt(p, options);
  const Vec3 centre = rt.ToolPosition();
  const int ticks_per_turn = 1000;
  std::vector<double> energy;  // at the end of each turn, the tool back at its start
  for (int turn = 1; turn <= 100; ++turn) {
    for (int k = 1; k <= ticks_per_turn; ++k) {
      rt.SetToolPosition(Circle(centre, 0.01, k, ticks_per_turn));
      ASSERT_TRUE(rt.Step().ok()) << "turn " << turn << " tick " << k;
    }
    energy.push_back(rt.Energy() + rt.KineticEnergy());
  }
  const double first = *std::max_element(energy.begin(), energy.begin() + 5);
  const double last = *std::max_element(energy.end() - 5, energy.end());
  std::printf("bowel dynamic: energy at a turn's end %.6e J (turns 1-5, max), %.6e J (turns "
              "96-100, max)\n", first, last);
  EXPECT_LE(last, first + 1e-6 * std::abs(first));
  EXPECT_TRUE(rt.Shape().allFinite());
}

// The bowel poked in dynamic mode, damped: external drag at 0.7 of the critical damping of the
// tissue springs' mode (omega = sqrt(k / rho), 26 rad/s), so that every vertex mode decays at
// least as fast as exp(-c t / (2 rho)), 18 /s (the drag is proportional to the mass), and a
// twist viscosity that damps the slowest twist mode (wave number pi / 2L, spin inertia
// rho r^2 / 2) at the same rate. The drag does not reach the edges' spin: without the twist
// viscosity a twist oscillation excited by the push keeps the shape ringing at ~2e-6 L
// (measured over 3 s).
Profile DampedPokeProfile() {
  Profile p = Bundled("bowel_poke.json");
  const double rho = p.scene.rod.linear_density;
  const double omega = std::sqrt(p.scene.material.spring_stiffness / rho);
  p.scene.material.damping = 2.0 * 0.7 * rho * omega;
  const double r = p.scene.rod.radius, L = p.scene.rod.length;
  const double k = M_PI / (2.0 * L);
  p.scene.material.twist_damping = 2.0 * (0.5 * rho * r * r) * 0.7 * omega / (k * k);
  return p;
}

RuntimeOptions DynamicPoke() {
  RuntimeOptions options;
  options.tool = ToolKind::kPoke;
  options.tool_s = 0.075;
  options.mode = RuntimeMode::kDynamic;
  return options;
}

// A push with a component along each axis (out of the sag's plane too) [N].
const Vec3 kPush(0.005, -0.03, -0.01);

// Held long enough (2 s, 36 decay times of the slowest mode), a damped dynamic poke settles in
// the quasi-static poke's equilibrium under the same force: the same centre-line, poked point,
// force on the tool, energy and dented mesh (the ring solved from the same section force).
TEST(Runtime, DynamicPokeSettlesInTheQuasiStaticPoke) {
  const Profile p = DampedPokeProfile();
  RuntimeOptions options = DynamicPoke();
  Runtime dynamic(p, options);
  options.mode = RuntimeMode::kQuasiStatic;
  Runtime quasi(p, options);
  quasi.SetToolForce(kPush);
  ASSERT_TRUE(quasi.Step().ok());
  dynamic.SetToolForce(kPush);
  const double L = p.scene.rod.length;
  for (int k = 1; k <= 2000; ++k) {
    const StepReport r = dynamic.Step();
    ASSERT_TRUE(r.ok()) << "tick " << k << ": " << ToString(r.status);
  }
  const double moved = (dynamic.Shape() - Runtime(p, options).Shape()).cwiseAbs().maxCoeff();
  const double shape_error = (dynamic.Shape() - quasi.Shape()).cwiseAbs().maxCoeff();
  const double tool_error = (dynamic.ToolPosition() - quasi.ToolPosition()).norm();
  TubeMesh dynamic_mesh, quasi_mesh;
  dynamic.Mesh(&dynamic_mesh);
  quasi.Mesh(&quasi_mesh);
  const double mesh_error = (dynamic_mesh.vertices - quasi_mesh.vertices).cwiseAbs().maxCoeff();
  std::printf("dynamic poke settled: shape %.3e L, poked point %.3e L, mesh %.3e L (moved %.3e L); "
              "energy %.6e vs %.6e J\n", shape_error / L, tool_error / L, mesh_error / L, moved / L,
              dynamic.Energy(), quasi.Energy());
  EXPECT_GT(moved, 1e-3 * L);  // the push moves the rod visibly
  // The transient has decayed by exp(-36) of the ~1e-2 L move; both states then sit at their
  // solvers' tolerances, where the shapes agree to round-off (measured 1.4e-14 L; the ring of
  // the dent, solved from the same section force, to 2e-14 L). 1e-10 L as in the round trip.
  EXPECT_LT(shape_error, 1e-10 * L);
  EXPECT_LT(tool_error, 1e-10 * L);
  EXPECT_LT(mesh_error, 1e-10 * L);
  EXPECT_EQ(dynamic.ToolForce(), -kPush);
  EXPECT_EQ(dynamic.ToolForce(), quasi.ToolForce());
  EXPECT_NEAR(dynamic.Energy(), quasi.Energy(), 1e-10 * std::abs(quasi.Energy()));
}

// Settled under a dynamic poke, the rod is in balance with the poke as a dead load: the balance
// residual of the statics model with the same force at tool_s vanishes at the dynamic state (the
// real check: the clamp's reading is the balance of everything else, HeldReactions), the clamp
// then reads what `rodfit simulate` reads for the poked case, and the clamp and the tool carry
// the weight and the springs' pull.
TEST(Runtime, SettledDynamicPokeBalancesTheHeldEnds) {
  const Profile p = DampedPokeProfile();
  const RuntimeOptions options = DynamicPoke();
  Runtime rt(p, options);
  rt.SetToolForce(kPush);
  for (int k = 1; k <= 2000; ++k) ASSERT_TRUE(rt.Step().ok()) << "tick " << k;
  Scene poked = p.scene;
  poked.cases.front().poke = Poke{options.tool_s, kPush};
  const RodModel model(poked.rod, poked.material, poked.gravity, poked.cases.front(),
                       poked.springs);
  ASSERT_EQ(model.arc_lengths(), rt.model().arc_lengths());
  const RodState& s = rt.state();
  VecX residual;
  BalanceResidual(model, s, &residual);
  const double worst = residual.lpNorm<Eigen::Infinity>();
  std::printf("settled dynamic poke: balance residual %.3e N (load scale %.3e N)\n", worst,
              model.force_scale());
  // The dynamic steps converge to 1e-9 of the load scale; the settled state's residual is that
  // step's (measured 2e-12 of it).
  EXPECT_LT(worst, 1e-9 * model.force_scale());

  Vec3 clamp = Vec3::Zero();
  for (const HeldReaction& r : HeldReactions(model, s))
    if (r.point == "clamp") clamp = r.force;
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  const CaseSolution ref = SolveCase(poked, 0, nullptr, statics);
  ASSERT_TRUE(ref.ok()) << ref.summary.reason;
  Vec3 ref_clamp = Vec3::Zero();
  for (const HeldReaction& r : ref.reactions)
    if (r.point == "clamp") ref_clamp = r.force;
  EXPECT_LT((clamp - ref_clamp).norm(), 1e-8 * ref_clamp.norm())
      << clamp.transpose() << " vs " << ref_clamp.transpose();

  Vec3 weight = Vec3::Zero(), springs = Vec3::Zero();
  for (int i = 0; i < model.num_vertices(); ++i) {
    weight += model.vertex_weight(i);
    for (int z = 0; z < model.num_spring_zones(); ++z)
      springs -= model.zone_stiffness(z) * model.zone_cell_length(z, i) *
                 (s.x.col(i) - model.spring_anchor(i));
  }
  EXPECT_EQ(rt.ToolForce(), -kPush);
  EXPECT_LT((clamp + rt.ToolForce() - weight - springs).norm(), 1e-10 * model.force_scale())
      << (clamp + rt.ToolForce()).transpose() << " vs " << (weight + springs).transpose();
}

// A poke force cycling between 0 and 4 |kPush| (period 0.5 s, 40 cycles): the rod never holds
// more energy than the tool's work put in, E(t) - E(0) <= W(t) = sum f_n+1 . (x_n+1 - x_n), x the
// poked point and E kinetic plus the rod's own potential, at every tick. Undamped, BDF2's own
// dissipation is all that takes energy out, and the energy at the cycles' ends (the force back at
// zero) must not grow; damped, it settles in the periodic response.
TEST(Runtime, DynamicCyclicPokeGainsNoEnergy) {
  for (const bool damped : {false, true}) {
    SCOPED_TRACE(damped ? "damped" : "undamped");
    const Profile p = damped ? DampedPokeProfile() : Bundled("bowel_poke.json");
    Runtime rt(p, DynamicPoke());
    const int ticks_per_cycle = 500, cycles = 40;
    // The rod's own energy: Energy() counts the tool's work potential -f . x.
    auto rod_energy = [&](const Vec3& f) {
      return rt.Energy() + f.dot(rt.ToolPosition()) + rt.KineticEnergy();
    };
    const double e0 = rod_energy(Vec3::Zero());
    Vec3 x = rt.ToolPosition();
    double work = 0.0, least_dissipated = 0.0;
    std::vector<double> cycle_end;
    for (int c = 0; c < cycles; ++c) {
      for (int k = 1; k <= ticks_per_cycle; ++k) {
        const Vec3 f = 2.0 * (1.0 - std::cos(2.0 * M_PI * k / ticks_per_cycle)) * kPush;
        rt.SetToolForce(f);
        ASSERT_TRUE(rt.Step().ok()) << "cycle " << c << " tick " << k;
        work += f.dot(rt.ToolPosition() - x);
        x = rt.ToolPosition();
        least_dissipated = std::min(least_dissipated, work - (rod_energy(f) - e0));
      }
      cycle_end.push_back(rod_energy(Vec3::Zero()) - e0);
    }
    const double first = *std::max_element(cycle_end.begin(), cycle_end.begin() + 10);
    const double last = *std::max_element(cycle_end.end() - 10, cycle_end.end());
    std::printf("%s cyclic poke: work %.3e J, dissipated %.3e J (least over the ticks %.3e J); "
                "energy at a cycle's end %.6e J (cycles 1-10, max), %.6e J (31-40, max)\n",
                damped ? "damped" : "undamped", work, work - cycle_end.back(), least_dissipated,
                first, last);
    // The sums' round-off: 1e-12 of the energies summed (one tick can dissipate a negative
    // amount, -6e-10 J measured undamped, BDF2 not being energy-stable step by step; the sum
    // never has).
    EXPECT_GE(least_dissipated, -1e-12 * (std::abs(e0) + work));
    EXPECT_LE(last, first);
    if (damped) {  // the periodic response: the last cycles end at the same energy
      EXPECT_LT(std::abs(cycle_end.back() - cycle_end[cycles - 2]), 1e-9 * cycle_end.back());
    }
    EXPECT_TRUE(rt.Shape().allFinite());
  }
}

// A dynamic poke's step that does not converge keeps the last good state, and the force on the
// tool stays the last good step's; an absurd or non-finite force is refused, the state kept the
// same way; the loop carries on once the force is one the step can follow.
TEST(Runtime, FailedDynamicPokeStepKeepsTheLastGoodState) {
  const Profile p = DampedPokeProfile();
  Runtime rt(p, DynamicPoke());
  rt.SetToolForce(kPush);
  for (int k = 0; k < 10; ++k) ASSERT_TRUE(rt.Step().ok());
  const Mat3X good = rt.Shape();
  const double good_time = rt.time(), good_kinetic = rt.KineticEnergy();
  ASSERT_GT(good_kinetic, 0.0);  // in motion
  // An absurd push (10^4 N on a bowel weighing 0.66 N, above max_strain EA = 4 N): refused.
  rt.SetToolForce(Vec3(0.0, -1e4, 0.0));
  StepReport r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kToolRefused);
  EXPECT_THAT(r.message, HasSubstr("poke force |f| = 10000 N is out of range"));
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_EQ(rt.ToolForce(), -kPush);
  EXPECT_EQ(rt.time(), good_time);
  EXPECT_EQ(rt.KineticEnergy(), good_kinetic);
  // A non-finite force from a glitching device: refused, state kept.
  rt.SetToolForce(Vec3(0.0, std::nan(""), 0.0));
  r = rt.Step();
  EXPECT_EQ(r.status, StepStatus::kToolRefused);
  EXPECT_THAT(r.message, HasSubstr("poke force y = nan is not finite"));
  EXPECT_EQ(rt.Shape(), good);
  EXPECT_EQ(rt.ToolForce(), -kPush);
  // The push again: the loop carries on from the kept state.
  rt.SetToolForce(kPush);
  r = rt.Step();
  EXPECT_TRUE(r.ok()) << ToString(r.status);
  EXPECT_GT(rt.time(), good_time);
  EXPECT_TRUE(rt.Shape().allFinite());

  // A step that cannot converge (5 Newton iterations for a push of 3 N from rest, which takes
  // 6): the last good state kept, and the next ticks apply a quarter of the change, then half
  // of what is left, then all of it (each converged in 4 iterations, measured), never the
  // failed step again.
  RuntimeOptions options = DynamicPoke();
  options.dynamic_newton_iterations = 5;
  Runtime capped(p, options);
  const Mat3X rest = capped.Shape();
  const Vec3 hard(0.0, -3.0, 0.0);
  capped.SetToolForce(hard);
  r = capped.Step();
  EXPECT_EQ(r.status, StepStatus::kNotConverged);
  EXPECT_THAT(r.message, HasSubstr("iteration limit reached after 5 Newton iterations"));
  EXPECT_THAT(r.message, HasSubstr("the next tick applies a quarter of the change of force"));
  EXPECT_EQ(capped.Shape(), rest);
  EXPECT_EQ(capped.ToolForce(), Vec3::Zero());
  for (const double part : {0.25, 0.625, 1.0}) {
    r = capped.Step();
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_NEAR((capped.ToolForce() + part * hard).norm(), 0.0, 1e-15) << part;
  }
}

TEST(Runtime, InvalidOptionsAreRefused) {
  const Profile p = Bundled("suture.json");
  RuntimeOptions options;  // tool_s missing
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
  options.tool_s = 0.5;  // beyond L = 0.2
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
  options.tool_s = 0.1;
  options.hold_orientation = true;  // a quasi-static grasp's only
  options.mode = RuntimeMode::kDynamic;
  EXPECT_THROW(Runtime(p, options), std::invalid_argument);
}

// The rod's natural shape carried by the profile (rod.rest_shape) into the runtime's model: a
// weightless suture whose rest shape is a helix (curvature 30 1/m, torsion 10 1/m, one turn over
// its 0.2 m: out of every plane), its knots the intrinsic curvature of 401 points of the helix
// (RestCurvatureOfCentreline, as `rod.rest_shape: FILE` reads a centre-line). Held at the clamp
// only and grasped at its tip where the rest shape puts it, the runtime's rod is the helix, with
// no force on the tool; dragged 1 cm away and back, it returns to it (the rest shape is the
// energy's minimum, not only the start). The discrete rod's curvature (tan form, DESIGN's
// (pi/N)^2 / 3 for a circle) gives a shape error falling as 1/N^2: measured 1.08e-3 L at 50
// segments and 2.7e-4 L at 100 (a ratio of 4.0); allowed 1.5e-3 L and 4e-4 L, and a ratio
// above 3.5.
TEST(Runtime, ProfileRestShapeIsTheWeightlessEquilibrium) {
  const double a = 0.03, b = 0.01, c = std::hypot(a, b), length = 0.2;
  auto helix = [&](double s) {
    const double t = s / c;
    return Vec3(a * std::sin(t), a * (1.0 - std::cos(t)), b * t);
  };
  const Vec3 tangent0(a / c, 0.0, b / c), normal0(0.0, 1.0, 0.0);  // r'(0), and d1 across it
  const int points = 401;
  std::vector<double> s(points);
  Mat3X curve(3, points);
  for (int k = 0; k < points; ++k) {
    s[k] = length * k / (points - 1);
    curve.col(k) = helix(s[k]);
  }
  std::vector<double> knots;
  std::vector<Vec3> profile;
  RestCurvatureOfCentreline(s, curve, normal0, length, &knots, &profile);

  nlohmann::json doc = nlohmann::json::parse(ReadFile(std::string(RODFIT_SOURCE_DIR) +
                                                      "/data/profiles/suture.json"));
  doc["gravity"] = {0.0, 0.0, 0.0};
  doc["held"]["clamp"] = {{"position", {0.0, 0.0, 0.0}},
                          {"tangent", {tangent0.x(), tangent0.y(), tangent0.z()}},
                          {"normal", {normal0.x(), normal0.y(), normal0.z()}}};
  nlohmann::json rest = {{"s_m", knots}};
  for (const char* key : {"k1_per_m", "k2_per_m", "tau_per_m"}) rest[key] = nlohmann::json::array();
  for (const Vec3& k : profile) {
    rest["k1_per_m"].push_back(k[0]);
    rest["k2_per_m"].push_back(k[1]);
    rest["tau_per_m"].push_back(k[2]);
  }
  doc["rod"]["rest_shape"] = rest;

  std::vector<double> errors;
  for (int segments : {50, 100}) {
    doc["rod"]["segments"] = segments;
    const Profile p = ParseProfile(doc.dump(), "helix.json");
    ASSERT_EQ(p.scene.rod.rest_curvature_s.size(), knots.size());
    const double allowed = (segments == 50 ? 1.5e-3 : 4e-4) * length;
    for (RuntimeMode mode : {RuntimeMode::kQuasiStatic, RuntimeMode::kDynamic}) {
      SCOPED_TRACE(std::string(mode == RuntimeMode::kQuasiStatic ? "quasi-static" : "dynamic") +
                   ", " + std::to_string(segments) + " segments");
      RuntimeOptions options;
      options.tool_s = length;
      options.mode = mode;
      Runtime rt(p, options);
      auto error = [&] {
        const Mat3X& x = rt.Shape();
        double worst = 0.0;
        for (int i = 0; i < x.cols(); ++i)
          worst = std::max(worst, (x.col(i) - helix(length * i / (x.cols() - 1))).norm());
        return worst;
      };
      const double at_start = error();
      std::printf("helix, %d segments: max |x - r(s)| = %.3e m (%.3e L), tool force %.3e N\n",
                  segments, at_start, at_start / length, rt.ToolForce().norm());
      EXPECT_LT(at_start, allowed);
      EXPECT_LT(rt.ToolForce().norm(), 1e-9);
      if (mode == RuntimeMode::kDynamic) {
        // Steps at rest stay at rest: the rest shape is in balance with no load.
        for (int k = 0; k < 50; ++k) ASSERT_TRUE(rt.Step().ok());
        EXPECT_LT(std::abs(error() - at_start), 1e-6 * length);
        continue;
      }
      errors.push_back(at_start);
      const Vec3 home = rt.ToolPosition();
      Drag(&rt, home + Vec3(0.0, 0.01, -0.005), 60);
      EXPECT_GT(error(), 2e-3);  // the drag did bend it
      Drag(&rt, home, 60);
      EXPECT_LT(std::abs(error() - at_start), 1e-6 * length);
    }
  }
  ASSERT_EQ(errors.size(), 2u);
  std::printf("error ratio 50 / 100 segments: %.2f\n", errors[0] / errors[1]);
  EXPECT_GT(errors[0] / errors[1], 3.5);  // second order
}

}  // namespace
}  // namespace rodfit
