// Points of a case's trajectory at given arc lengths and times (case_dynamics.h,
// SampleCaseDynamics): on a step and on a vertex they are the trajectory's own vertices; between
// steps and vertices the linear interpolation; and their sensitivities (the initial
// equilibrium's, then through every BDF2 step) equal central differences of the run itself.
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

}  // namespace
}  // namespace rodfit
