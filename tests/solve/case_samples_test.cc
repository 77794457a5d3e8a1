// Points of a case's trajectory at given arc lengths and times (case_dynamics.h,
// SampleCaseDynamics): on a step and on a vertex they are the trajectory's own vertices; between
// steps and vertices the linear interpolation; and their sensitivities (the initial
// equilibrium's, then through every BDF2 step) equal central differences of the run itself; and
// the held points' reactions along the trajectory (MovingReactions): on a written frame those of
// reactions.csv, with the tip load series in the clamp's balance, and their derivatives equal
// central differences.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/case_dynamics.h"

namespace rodfit {
namespace {

// A cantilever sagging under its weight at rest, its clamp then lifted by 1 cm in 50 ms.
Scene Lifted() {
  Scene s;
  s.rod.length = 0.2;
  s.rod.segments = 8;
  s.rod.radius = 1.25e-4;
  s.rod.linear_density = 5.6e-5;
  s.material.bend_stiffness = 2.0e-6;  // B2 tied to it (isotropic)
  s.material.twist_stiffness = 1.6e-6;
  s.material.stretch_stiffness = 245.0;
  s.material.damping = 1.0e-4;
  s.material.bend_damping = 1.0e-9;
  DynamicsSpec d;
  d.time_step = 2.0e-3;
  d.duration = 0.06;
  d.integrator = "bdf2";
  s.dynamics = d;
  LoadCase c;
  c.name = "lifted";
  DrivenPoint lift;
  lift.point = "clamp";
  lift.path.t = {0.0, 0.05};
  lift.path.a = {Vec3::Zero(), Vec3(0.0, 0.0, 0.01)};
  c.drives = {lift};
  s.cases = {c};
  return s;
}

TEST(CaseSamples, OnStepsAndVerticesTheTrajectoryItself) {
  Scene s = Lifted();
  s.dynamics->output_every = 5;
  const CaseTrajectory traj = SimulateCaseDynamics(s, 0, StaticsOptions());
  ASSERT_TRUE(traj.ok) << traj.reason;
  // Vertex 4 (s = 0.1) and the tip at the written frames 0, 10 ms, 20 ms.
  const CaseSamples at = SampleCaseDynamics(s, 0, StaticsOptions(), {0.1, 0.2}, {0.0, 0.01, 0.02}, {});
  ASSERT_TRUE(at.ok) << at.reason;
  ASSERT_EQ(at.x.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT((at.x[k].col(0) - traj.frames[k].x.col(4)).norm(), 1e-15) << k;
    EXPECT_LT((at.x[k].col(1) - traj.frames[k].x.col(8)).norm(), 1e-15) << k;
  }
  // Half-way between vertices 4 and 5 and between two steps: the mean of the four.
  const CaseSamples mid = SampleCaseDynamics(s, 0, StaticsOptions(), {0.1125}, {0.011}, {});
  const CaseSamples ends = SampleCaseDynamics(s, 0, StaticsOptions(), {0.1, 0.125}, {0.01, 0.012}, {});
  const Eigen::Vector3d mean =
      0.25 * (ends.x[0].col(0) + ends.x[0].col(1) + ends.x[1].col(0) + ends.x[1].col(1));
  EXPECT_LT((mid.x[0].col(0) - mean).norm(), 1e-15);
  EXPECT_THROW(SampleCaseDynamics(s, 0, StaticsOptions(), {0.1}, {0.07}, {}), std::invalid_argument);
  EXPECT_THROW(SampleCaseDynamics(s, 0, StaticsOptions(), {0.3}, {0.01}, {}), std::invalid_argument);
}

TEST(CaseSamples, SensitivitiesEqualCentralDifferences) {
  const Scene base = Lifted();
  const std::vector<double> s = {0.07, 0.2}, t = {0.0, 0.013, 0.06};
  struct Knob {
    const char* name;
    void (*scale)(Scene*, double);
  };
  const std::vector<Knob> knobs = {
      {"bend_stiffness",
       [](Scene* sc, double f) { sc->material.bend_stiffness *= f; }},
      {"damping", [](Scene* sc, double f) { sc->material.damping *= f; }},
      {"bend_damping", [](Scene* sc, double f) { sc->material.bend_damping *= f; }},
      {"linear_density", [](Scene* sc, double f) { sc->rod.linear_density *= f; }},
  };
  std::vector<ParameterDirection> directions;
  for (const Knob& k : knobs) {
    Scene up = base;
    k.scale(&up, std::exp(1.0));
    directions.push_back(ParameterDirection::Between(base.material, base.rod.linear_density,
                                                     up.material, up.rod.linear_density, 1.0));
  }
  // The start's equilibrium converged far below its default tolerances, so that central
  // differences measure the derivative rather than the solver's stopping point.
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  statics.step_tolerance = 1e-13;
  const CaseSamples exact = SampleCaseDynamics(base, 0, statics, s, t, directions);
  ASSERT_TRUE(exact.ok) << exact.reason;
  ASSERT_EQ(exact.dx.size(), t.size());
  const double h = 1e-3;  // in log p, as tests/solve/rollout_sensitivity_test.cc
  std::vector<double> largest(knobs.size(), 0.0);
  for (size_t j = 0; j < knobs.size(); ++j)
    for (const Eigen::MatrixXd& d : exact.dx) largest[j] = std::max(largest[j], d.col(j).norm());
  for (size_t j = 0; j < knobs.size(); ++j) {
    Scene plus = base, minus = base;
    knobs[j].scale(&plus, std::exp(h));
    knobs[j].scale(&minus, std::exp(-h));
    const CaseSamples p = SampleCaseDynamics(plus, 0, statics, s, t, {});
    const CaseSamples m = SampleCaseDynamics(minus, 0, statics, s, t, {});
    ASSERT_TRUE(p.ok && m.ok);
    for (size_t k = 0; k < t.size(); ++k) {
      Eigen::VectorXd fd(3 * s.size());
      for (size_t q = 0; q < s.size(); ++q)
        fd.segment<3>(3 * q) = (p.x[k].col(q) - m.x[k].col(q)) / (2.0 * h);
      const Eigen::VectorXd d = exact.dx[k].col(j);
      // The damping terms do not move the initial equilibrium: both are 0 at t = 0 (each
      // relative to the largest derivative of the run, as the rollout's test).
      EXPECT_LT((d - fd).norm(), 1e-5 * largest[j] + 1e-12) << knobs[j].name << " at t = " << t[k];
    }
  }
}

// The lifted cantilever with its tip pinned 15 cm from the clamp (the rod hangs between them),
// pushed along y by a tip load that grows over the run: the clamp's balance and a held vertex.
Scene PinnedAndPushed() {
  Scene s = Lifted();
  s.cases[0].end_pin = Vec3(0.15, 0.0, 0.0);
  s.gravity = Vec3(0.0, 0.0, -9.81);
  // A stretchy cable (EA 0.5 N: it stretches ~1e-4 under its weight), so that the stretch
  // stiffness moves the reactions by more than the round-off of a stiff rod's axial force.
  s.material.stretch_stiffness = 0.5;
  return s;
}

TEST(CaseSamples, ReactionsOnTheWrittenFramesAreReactionsCsvs) {
  Scene s = PinnedAndPushed();
  s.dynamics->output_every = 5;
  const CaseTrajectory traj = SimulateCaseDynamics(s, 0, StaticsOptions());
  ASSERT_TRUE(traj.ok) << traj.reason;
  const CaseSamples at =
      SampleCaseDynamics(s, 0, StaticsOptions(), {0.1}, {0.0, 0.01, 0.02, 0.06}, {}, true);
  ASSERT_TRUE(at.ok) << at.reason;
  ASSERT_EQ(at.reactions.size(), 4u);
  const std::vector<int> frame = {0, 1, 2, 6};
  for (int k = 0; k < 4; ++k) {
    const std::vector<HeldReaction>& want = traj.frames[frame[k]].reactions;
    ASSERT_EQ(at.reactions[k].size(), want.size());
    ASSERT_EQ(want.size(), 2u);  // the clamp and the end pin
    for (size_t p = 0; p < want.size(); ++p) {
      EXPECT_EQ(at.reactions[k][p].point, want[p].point);
      EXPECT_LT((at.reactions[k][p].force - want[p].force).norm(), 1e-12 * want[p].force.norm() + 1e-15)
          << k << " " << want[p].point;
      EXPECT_LT((at.reactions[k][p].moment - want[p].moment).norm(), 1e-12 * want[0].moment.norm() + 1e-15)
          << k << " " << want[p].point;
    }
  }
  // Half-way between two steps: the mean of the steps' reactions.
  const CaseSamples mid = SampleCaseDynamics(s, 0, StaticsOptions(), {0.1}, {0.011}, {}, true);
  const CaseSamples ends = SampleCaseDynamics(s, 0, StaticsOptions(), {0.1}, {0.01, 0.012}, {}, true);
  for (size_t p = 0; p < 2; ++p)
    EXPECT_LT((mid.reactions[0][p].force -
               0.5 * (ends.reactions[0][p].force + ends.reactions[1][p].force)).norm(),
              1e-15 + 1e-14 * ends.reactions[0][p].force.norm());
}

TEST(CaseSamples, TheClampCarriesTheTipLoadSeries) {
  // A weightless rod in its equilibrium under a tip force at t = 0 and at rest: its clamp holds
  // exactly that force (the rod passes it on), and its moment about the clamp.
  Scene s = Lifted();
  s.gravity = Vec3::Zero();
  s.cases[0].drives.clear();
  s.material.damping = 0.0;
  s.material.bend_damping = 0.0;
  const Vec3 push(0.0, 2.0e-4, -1.0e-4);
  s.cases[0].tip_load.t = {0.0, 1.0};
  s.cases[0].tip_load.a = {push, push};
  s.cases[0].initial.equilibrium = true;
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  const CaseTrajectory traj = SimulateCaseDynamics(s, 0, statics);
  ASSERT_TRUE(traj.ok) << traj.reason;
  const HeldReaction& clamp = traj.frames[0].reactions[0];
  const Vec3 tip = traj.frames[0].x.col(traj.frames[0].x.cols() - 1);
  EXPECT_LT((clamp.force - push).norm(), 1e-9 * push.norm());
  EXPECT_LT((clamp.moment - tip.cross(push)).norm(), 1e-9 * tip.norm() * push.norm());
  // Still at rest after the steps: the equilibrium holds (no inertia in the balance).
  const HeldReaction& later = traj.frames.back().reactions[0];
  EXPECT_LT((later.force - push).norm(), 1e-6 * push.norm());
}

TEST(CaseSamples, ReactionSensitivitiesEqualCentralDifferences) {
  const Scene base = PinnedAndPushed();
  const std::vector<double> t = {0.0, 0.013, 0.04, 0.06};
  struct Knob {
    const char* name;
    void (*scale)(Scene*, double);
  };
  const std::vector<Knob> knobs = {
      {"bend_stiffness", [](Scene* sc, double f) { sc->material.bend_stiffness *= f; }},
      {"stretch_stiffness", [](Scene* sc, double f) { sc->material.stretch_stiffness *= f; }},
      {"damping", [](Scene* sc, double f) { sc->material.damping *= f; }},
      {"bend_damping", [](Scene* sc, double f) { sc->material.bend_damping *= f; }},
      {"linear_density", [](Scene* sc, double f) { sc->rod.linear_density *= f; }},
  };
  std::vector<ParameterDirection> directions;
  for (const Knob& k : knobs) {
    Scene up = base;
    k.scale(&up, std::exp(1.0));
    directions.push_back(ParameterDirection::Between(base.material, base.rod.linear_density,
                                                     up.material, up.rod.linear_density, 1.0));
  }
  StaticsOptions statics;
  statics.gradient_tolerance = 1e-12;
  statics.step_tolerance = 1e-13;
  const CaseSamples exact = SampleCaseDynamics(base, 0, statics, {0.1}, t, directions, true);
  ASSERT_TRUE(exact.ok) << exact.reason;
  ASSERT_EQ(exact.d_reactions.size(), t.size());
  // As the positions' test: h = 1e-3 in log p, each error relative to the largest derivative of
  // the run (per point, force and moment apart).
  const double h = 1e-3;
  for (size_t j = 0; j < knobs.size(); ++j) {
    Scene plus = base, minus = base;
    knobs[j].scale(&plus, std::exp(h));
    knobs[j].scale(&minus, std::exp(-h));
    const CaseSamples p = SampleCaseDynamics(plus, 0, statics, {0.1}, t, {}, true);
    const CaseSamples m = SampleCaseDynamics(minus, 0, statics, {0.1}, t, {}, true);
    ASSERT_TRUE(p.ok && m.ok);
    // Per point, force and moment apart, relative to the largest derivative of the run.
    for (size_t q = 0; q < 2; ++q)
      for (int part = 0; part < 2; ++part) {
        double largest = 0.0;
        for (size_t k = 0; k < t.size(); ++k)
          largest = std::max(largest, exact.d_reactions[k][q].block<3, 1>(3 * part, j).norm());
        for (size_t k = 0; k < t.size(); ++k) {
          const Vec3 fd = part == 0 ? Vec3((p.reactions[k][q].force - m.reactions[k][q].force) / (2.0 * h))
                                    : Vec3((p.reactions[k][q].moment - m.reactions[k][q].moment) / (2.0 * h));
          const Vec3 d = exact.d_reactions[k][q].block<3, 1>(3 * part, j);
          EXPECT_LT((d - fd).norm(), 1e-5 * largest + 1e-13)
              << knobs[j].name << " point " << q << (part ? " moment" : " force") << " at t = " << t[k]
              << ": " << d.transpose() << " vs " << fd.transpose();
        }
      }
  }
}

}  // namespace
}  // namespace rodfit
