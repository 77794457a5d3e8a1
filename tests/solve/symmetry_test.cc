// Mirror symmetry (LoadCase::symmetry): a case that is its own mirror image is solved as the half
// from the clamp to the plane. The half's equilibrium mirrored must be the whole rod's: the same
// centre-line (to 1e-8 L) and the same reactions, from a cold start and in warm re-solves, in
// 3-D (clamps tilted out of the plane of gravity, an anisotropic section) as in a plane. And a
// case that is not symmetric is refused with the reason (the YAML key: tests/io/symmetry_yaml_test.cc).
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/case_solve.h"

namespace rodfit {
namespace {

// A wire 1.5 m long held by two clamps 1 m apart, mirror images in the plane x = 0.5 m, under
// gravity -z (in the plane). `tilt` turns the clamps' tangents out of the x-z plane (a 3-D,
// twisted equilibrium).
Scene Bridge(int segments, bool tilt, bool anisotropic) {
  Scene s;
  s.rod.length = 1.5;
  s.rod.segments = segments;
  s.rod.radius = 1e-3;
  s.rod.linear_density = 0.05;
  s.material.bend_stiffness = 1e-3;
  if (anisotropic) s.material.bend_stiffness_2 = 2.5e-3;
  s.material.twist_stiffness = 8e-4;
  s.material.stretch_stiffness = 1e5;
  s.gravity = Vec3(0, 0, -9.81);
  LoadCase c;
  c.name = "bridge";
  c.clamp.tangent = tilt ? Vec3(1, 0.5, 0.3) : Vec3(1, 0, 0);
  c.clamp.normal = Vec3(0, 0, 1);
  EndClamp ec;
  ec.position = Vec3(1.0, 0, 0);
  ec.tangent = tilt ? Vec3(1, -0.5, -0.3) : Vec3(1, 0, 0);  // -mirror(clamp tangent)
  ec.normal = c.clamp.normal;  // the mirror image of d1 = the clamp's normal across x
  // The clamp's d1 is the normal's part across the tangent: mirror it for the end clamp.
  const Vec3 d3 = c.clamp.tangent.normalized();
  Vec3 d1 = (c.clamp.normal - c.clamp.normal.dot(d3) * d3).normalized();
  d1.x() = -d1.x();
  ec.normal = d1;
  c.end_clamp = ec;
  s.cases.push_back(c);
  return s;
}

Scene WithSymmetry(Scene s) {
  s.cases[0].symmetry = SymmetryPlane{Vec3(0.5, 0, 0), Vec3(1, 0, 0)};
  return s;
}

double MaxDistance(const Mat3X& a, const Mat3X& b) {
  EXPECT_EQ(a.cols(), b.cols());
  if (a.cols() != b.cols()) return INFINITY;
  return (a - b).colwise().norm().maxCoeff();
}

struct SymmetryCase {
  int segments;
  bool tilt, anisotropic;
};

class HalfEqualsWhole : public ::testing::TestWithParam<SymmetryCase> {};

// Cold: each from the straight rod, by its own continuation (the whole rod's end clamp moved in,
// the half's plane moved in). Warm: both re-solved after a 1 % change of gravity from their own
// equilibria, as a sweep or a fit does. Both ways the half, mirrored, is an equilibrium of the
// whole rod's own model and the whole rod's first half one of the half's.
//
// An anisotropic section (B2 = 2.5 B1) between tilted clamps is bistable: two stable symmetric
// equilibria, the section turned differently along the rod. The two continuations are different
// loading paths (the whole rod's end clamp turns in from the straight rod's end, the half's plane
// only moves), and there each reaches another one. For it the cold comparison is replaced by the
// cross-check of both equilibria in both models.
TEST_P(HalfEqualsWhole, ShapeAndReactions) {
  const SymmetryCase p = GetParam();
  const Scene whole_scene = Bridge(p.segments, p.tilt, p.anisotropic);
  const Scene half_scene = WithSymmetry(whole_scene);
  const CaseSolution whole = SolveCase(whole_scene, 0, nullptr);
  const CaseSolution cold_half = SolveCase(half_scene, 0, nullptr);
  ASSERT_TRUE(whole.ok()) << whole.summary.reason;
  ASSERT_TRUE(cold_half.ok()) << cold_half.summary.reason;
  ASSERT_TRUE(cold_half.model->symmetric());
  EXPECT_EQ(cold_half.model->num_edges(), (p.segments - 1) / 2);
  EXPECT_TRUE(cold_half.summary.stable);
  const double L = whole_scene.rod.length;
  const RodModel& half_model = *cold_half.model;
  const RodModel& whole_model = *whole.model;

  // The cold half, mirrored, is an equilibrium of the whole rod (Newton does not move it).
  RodState mirrored = MirroredState(half_model, cold_half.state, whole_model);
  const RodState mirrored_before = mirrored;
  const StaticsSummary as_whole = SolveStatics(whole_model, StaticsOptions(), &mirrored);
  ASSERT_TRUE(as_whole.converged) << as_whole.reason;
  EXPECT_TRUE(as_whole.stable);
  EXPECT_LE(MaxDistance(mirrored.x, mirrored_before.x) / L, 1e-8);
  // The whole rod's first half, as a start of the half, converges to the whole rod.
  const RodState from_whole = HalfState(half_model, whole_model, whole.state);
  const CaseSolution half =
      SolveCase(half_scene, 0, nullptr, StaticsOptions(), nullptr, &from_whole);
  ASSERT_TRUE(half.ok()) << half.summary.reason;
  const double shape_error = MaxDistance(whole.shape, half.shape) / L;
  const double cold_error = MaxDistance(whole.shape, cold_half.shape) / L;
  std::printf("[measured] %d segments%s%s: |half - whole| = %.2e L (same branch), %.2e L (both "
              "cold)\n", p.segments, p.tilt ? ", 3-D" : "", p.anisotropic ? ", anisotropic" : "",
              shape_error, cold_error);
  EXPECT_LE(shape_error, 1e-8);
  if (!p.anisotropic) {
    EXPECT_LE(cold_error, 1e-8);
  }
  // The rod sags (it is not the trivial straight line) and leaves the x-z plane when tilted.
  EXPECT_LT(half.shape.row(2).minCoeff(), -0.1 * L);
  if (p.tilt) {
    EXPECT_GT(half.shape.row(1).cwiseAbs().maxCoeff(), 0.01 * L);
  }
  // The clamps' reactions: each carries half the weight, the end clamp's force the mirror image
  // of the clamp's, and the half's equal the whole rod's.
  ASSERT_EQ(whole.reactions.size(), 2u);
  ASSERT_EQ(half.reactions.size(), 2u);
  const double weight = whole_scene.rod.linear_density * L * 9.81;
  // A reaction sums the balance of every vertex beyond it, each converged to the gradient
  // tolerance (relative to the load scale, here the weight): its error is at most n times that.
  const double force_tol = StaticsOptions().gradient_tolerance * p.segments * weight;
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(half.reactions[k].point, whole.reactions[k].point);
    EXPECT_LE((half.reactions[k].force - whole.reactions[k].force).norm(), force_tol) << k;
    EXPECT_LE((half.reactions[k].moment - whole.reactions[k].moment).norm(), force_tol * L)
        << k;
    EXPECT_NEAR(half.reactions[k].force.z(), -0.5 * weight, force_tol) << k;
  }
  Vec3 mirrored_force = half.reactions[0].force;
  mirrored_force.x() = -mirrored_force.x();
  EXPECT_LE((half.reactions[1].force - mirrored_force).norm(), force_tol);

  // Warm re-solves after gravity changes by 1 %.
  Scene whole_heavier = whole_scene, half_heavier = half_scene;
  whole_heavier.gravity *= 1.01;
  half_heavier.gravity *= 1.01;
  const CaseSolution whole2 = SolveCase(whole_heavier, 0, nullptr, StaticsOptions(), nullptr,
                                        &whole.state);
  const CaseSolution half2 = SolveCase(half_heavier, 0, nullptr, StaticsOptions(), nullptr,
                                       &half.state);
  ASSERT_TRUE(whole2.ok()) << whole2.summary.reason;
  ASSERT_TRUE(half2.ok()) << half2.summary.reason;
  const double warm_error = MaxDistance(whole2.shape, half2.shape) / L;
  std::printf("[measured] %d segments: |half - whole| = %.2e L (warm), iterations %d / %d\n",
              p.segments, warm_error, half2.summary.iterations, whole2.summary.iterations);
  EXPECT_LE(warm_error, 1e-8);
  EXPECT_GT(MaxDistance(half.shape, half2.shape), 1e-4 * L);  // the re-solve moved the rod
}

INSTANTIATE_TEST_SUITE_P(Bridges, HalfEqualsWhole,
                         ::testing::Values(SymmetryCase{21, false, false},
                                           SymmetryCase{101, false, false},
                                           SymmetryCase{101, true, false},
                                           SymmetryCase{101, true, true},
                                           SymmetryCase{301, true, true},
                                           SymmetryCase{1001, true, false}));

// The plane's position may be given by any point of it and its normal either way round.
TEST(Symmetry, AnyPointOfThePlaneAndEitherNormal) {
  Scene a = WithSymmetry(Bridge(41, true, false));
  Scene b = a;
  b.cases[0].symmetry = SymmetryPlane{Vec3(0.5, 3.0, -2.0), Vec3(-2, 0, 0)};
  const CaseSolution sa = SolveCase(a, 0, nullptr), sb = SolveCase(b, 0, nullptr);
  ASSERT_TRUE(sa.ok() && sb.ok());
  EXPECT_LE(MaxDistance(sa.shape, sb.shape), 1e-12 * a.rod.length);
}

// What a symmetric case must be, each refused with its reason (RodModel and the YAML reader share
// SymmetryProblem).
TEST(Symmetry, RefusesCasesThatAreNotTheirOwnMirrorImage) {
  const Scene good = WithSymmetry(Bridge(21, true, false));
  ASSERT_EQ(SymmetryProblem(good.rod, good.gravity, good.cases[0], false), "");
  auto problem = [&](Scene s, bool springs = false) {
    return SymmetryProblem(s.rod, s.gravity, s.cases[0], springs);
  };
  Scene s = good;
  s.rod.segments = 20;
  EXPECT_EQ(problem(s), "symmetry needs an odd number of segments (an edge crossing the plane at "
                        "the rod's middle), got 20: use 19 or 21");
  s = good;
  s.cases[0].end_clamp->position.y() += 1e-3;
  EXPECT_EQ(problem(s), "symmetry: the end_clamp's position is not the mirror image of the clamp's");
  s = good;
  s.cases[0].end_clamp->tangent = Vec3(1, 0.5, 0.3);
  EXPECT_EQ(problem(s),
            "symmetry: the end_clamp's tangent is not the mirror image of the clamp's (reversed)");
  s = good;
  s.cases[0].end_clamp->normal = Vec3(0, 1, 0);
  EXPECT_EQ(problem(s), "symmetry: the end_clamp's normal is not the mirror image of the clamp's");
  s = good;
  s.gravity = Vec3(1, 0, -9.81);
  EXPECT_EQ(problem(s), "symmetry: gravity crosses the plane (it must lie in it)");
  s = good;
  s.cases[0].tip_force = Vec3(0, 0, -1);
  EXPECT_NE(problem(s).find("under gravity only"), std::string::npos);
  s = good;
  s.cases[0].end_clamp.reset();
  s.cases[0].end_pin = Vec3(1, 0, 0);
  EXPECT_EQ(problem(s),
            "symmetry: the rod's end must be held by an end_clamp, the mirror image of the clamp");
  EXPECT_EQ(problem(good, true), "symmetry: not with springs");
  s = good;
  s.rod.rest_curvature = Vec3(0, 1, 0);
  EXPECT_EQ(problem(s),
            "symmetry: not with rest_curvature (a curved rod's mirror image is another rod)");
  s = good;
  s.cases[0].symmetry->point = Vec3(0, 0, 0);  // through the clamp
  EXPECT_EQ(problem(s), "symmetry: the clamp lies on the plane");
  s = good;
  s.cases[0].symmetry->normal = Vec3::Zero();
  EXPECT_EQ(problem(s), "symmetry: point and normal must be finite, the normal not zero");
  // The model refuses the same case with the same words.
  s = good;
  s.rod.segments = 20;
  try {
    RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
    ADD_FAILURE() << "an even segment count was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), problem(s));
  }
}


// ---------------------------------------------------------------------------------------------
// Symmetry in time (solve/case_dynamics.h): a moving case that stays its own mirror image is
// integrated on the half; the written trajectory (the half and its mirror image) and the held
// points' reactions must be the whole rod's, integrated as a whole: the same centre-line to 1e-8 L
// (the two Newton iterations stop at their tolerance on different unknowns), and the same
// reactions to 1e-4 of the rod's weight. The reactions are the stiff terms' forces: an axial
// difference of 1e-8 L over an edge carries EA 1e-8 L / l ~ 2e-2 N here, so the reactions agree
// far better than the positions alone would bound (measured: 4e-7 N with BDF2 and backward
// Euler, 1e-5 N with the midpoint rule, whose undamped stretch waves carry the differences).

// The bridge released from its equilibrium with a mirror-symmetric velocity (a swing out of its
// plane and a bounce), or with both clamps driven along mirror-image paths.
Scene MovingBridge(bool tilt, bool driven, const std::string& integrator) {
  Scene s = Bridge(21, tilt, /*anisotropic=*/true);
  DynamicsSpec d;
  d.time_step = 2e-3;
  d.duration = 0.1;
  d.integrator = integrator;
  d.output_every = 5;
  s.dynamics = d;
  LoadCase& c = s.cases[0];
  if (driven) {
    // The clamp rises 5 cm and moves 10 cm inward over 0.1 s, turning about z; the end clamp
    // does the mirror image (x -> 1 - x, tangent reversed and mirrored, normal mirrored).
    DrivenPoint a{"clamp", {}}, b{"end_clamp", {}};
    for (int k = 0; k <= 10; ++k) {
      const double t = 0.01 * k, u = t / 0.1;
      const Vec3 p(0.1 * u, 0.0, 0.05 * u);
      const Vec3 tangent =
          Vec3(std::cos(0.3 * u), std::sin(0.3 * u), 0.0) + c.clamp.tangent - Vec3(1, 0, 0);
      const Vec3 normal = c.clamp.normal;
      auto mirror = [](Vec3 v) {
        v.x() = -v.x();
        return v;
      };
      a.path.t.push_back(t);
      a.path.a.push_back(p);
      a.path.b.push_back(tangent);
      a.path.c.push_back(normal);
      b.path.t.push_back(t);
      b.path.a.push_back(Vec3(1.0 - p.x(), p.y(), p.z()));
      b.path.b.push_back(-mirror(tangent));
      b.path.c.push_back(mirror(normal));
    }
    c.drives = {a, b};
  } else {
    c.initial.velocity_s = {0.0, 0.375, 0.75, 1.125, 1.5};
    c.initial.velocity.resize(3, 5);
    // v(s) mirrored about the middle: y and z even in s - 0.75, x odd.
    c.initial.velocity << 0.0, 0.2, 0.0, -0.2, 0.0,  //
        0.0, 0.5, 0.8, 0.5, 0.0,                     //
        0.0, -0.3, 0.4, -0.3, 0.0;
  }
  return s;
}

TEST(SymmetryInTime, HalfTrajectoryAndReactionsEqualTheWholeRods) {
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-11;
  for (const std::string integrator : {"bdf2", "backward_euler", "midpoint"}) {
    for (bool tilt : {false, true}) {
      for (bool driven : {false, true}) {
        SCOPED_TRACE(integrator + (tilt ? ", tilted" : ", planar") +
                     (driven ? ", driven" : ", released"));
        const Scene whole_scene = MovingBridge(tilt, driven, integrator);
        const CaseTrajectory whole = SimulateCaseDynamics(whole_scene, 0, statics);
        const CaseTrajectory half = SimulateCaseDynamics(WithSymmetry(whole_scene), 0, statics);
        ASSERT_TRUE(whole.ok) << whole.reason;
        ASSERT_TRUE(half.ok) << half.reason;
        ASSERT_EQ(whole.frames.size(), half.frames.size());
        ASSERT_EQ(whole.s.size(), half.s.size());  // the whole rod is written
        double dx = 0.0, df = 0.0, motion = 0.0;
        for (size_t k = 0; k < whole.frames.size(); ++k) {
          const TrajectoryFrame& a = whole.frames[k];
          const TrajectoryFrame& b = half.frames[k];
          dx = std::max(dx, MaxDistance(a.x, b.x));
          motion = std::max(motion, MaxDistance(a.x, whole.frames[0].x));
          ASSERT_EQ(a.reactions.size(), b.reactions.size());
          for (size_t h = 0; h < a.reactions.size(); ++h) {
            EXPECT_EQ(a.reactions[h].point, b.reactions[h].point);
            df = std::max({df, (a.reactions[h].force - b.reactions[h].force).norm(),
                           (a.reactions[h].moment - b.reactions[h].moment).norm()});
          }
        }
        const double weight = 1.5 * 0.05 * 9.81;
        std::printf("[measured] %s %s %s: half vs whole %.2e L, reactions %.2e N (weight %.3f N), "
                    "motion %.3f m\n", integrator.c_str(), tilt ? "tilted" : "planar",
                    driven ? "driven" : "released", dx / 1.5, df, weight, motion);
        EXPECT_GT(motion, 1e-3);  // it moves
        EXPECT_LT(dx, 1e-8 * 1.5);
        EXPECT_LT(df, 1e-4 * weight);
      }
    }
  }
}

TEST(SymmetryInTime, DrivesThatBreakTheMirrorAreRefusedWithTheReason) {
  Scene s = WithSymmetry(MovingBridge(/*tilt=*/true, /*driven=*/true, "bdf2"));
  auto message = [](const Scene& scene) {
    try {
      SimulateCaseDynamics(scene, 0, StaticsOptions());
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  Scene moved = s;
  moved.cases[0].drives[1].path.a[4].z() += 1e-3;  // the end clamp off the mirror at sample 4
  EXPECT_NE(message(moved).find("not the clamp's mirror image (sample 4)"), std::string::npos)
      << message(moved);
  Scene alone = s;
  alone.cases[0].drives.pop_back();  // the clamp alone
  EXPECT_NE(message(alone).find("drive both the clamp and the end clamp"), std::string::npos)
      << message(alone);
  Scene loaded = s;
  loaded.cases[0].tip_load = loaded.cases[0].drives[0].path;
  EXPECT_NE(message(loaded).find("tip load series"), std::string::npos) << message(loaded);
}

}  // namespace
}  // namespace rodfit
