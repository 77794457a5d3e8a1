// Dynamics against closed forms: the natural frequencies of a cantilever (Euler–Bernoulli:
// omega_n = (beta_n L)^2 sqrt(B / (rho L^4)), beta_n L = 1.875104, 4.694091, 7.854757, the roots
// of 1 + cos(x) cosh(x) = 0; e.g. Meirovitch, "Fundamentals of Vibrations", table 8.1), the
// energy of the undamped explicit integrator, the midpoint rule's order, the logarithmic
// decrement of a damped mode, and the quasi-static limit (the statics solver).
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "rodfit/reference/cantilever_modes.h"

namespace rodfit {
namespace {

using reference::CantileverModeShape;
using reference::Suture;

// The rod bent into a mode shape of tip deflection ~ `amplitude` [m] (CantileverModeState).
RodState ModeState(const RodModel& model, int mode, double amplitude) {
  RodState q;
  EXPECT_TRUE(reference::CantileverModeState(model, mode, amplitude, &q));
  return q;
}

// The mass-weighted projection of the z displacement on a mode shape.
double Modal(const RodModel& model, const RodState& q, int mode) {
  double p = 0.0;
  for (int i = 1; i <= model.num_edges(); ++i)
    p += model.vertex_mass(i) * q.x(2, i) *
         CantileverModeShape(mode, model.arc_length(i) / model.length());
  return p;
}

struct Oscillation {
  double period = 0.0;           // [s] from downward zero crossings
  std::vector<double> peaks;     // successive maxima of the modal coordinate
  double energy_drift = 0.0;     // max |E - E0| / E0
};

Oscillation FreeOscillation(DynamicsStepper* stepper, DynamicState s, int mode, double duration,
                int energy_every = 1) {
  const RodModel& model = stepper->model();
  const double dt = stepper->options().time_step;
  Oscillation o;
  const double e0 = stepper->KineticEnergy(s) + stepper->PotentialEnergy(s.q);
  double first = -1.0, last = 0.0, p_prev = 0.0, p_prev2 = 0.0;
  int crossings = 0;
  const int steps = static_cast<int>(std::lround(duration / dt));
  Drive still;
  for (int k = 0; k < steps; ++k) {
    const double p = Modal(model, s.q, mode);
    if (k > 0 && p_prev > 0.0 && p <= 0.0) {
      const double tc = s.t - dt * p / (p - p_prev);
      if (first < 0.0) {
        first = tc;
      } else {
        last = tc;
        ++crossings;
      }
    }
    if (k > 1 && p_prev >= p_prev2 && p_prev > p && p_prev > 0.0) {
      // Parabola through the three samples around the maximum.
      const double den = p_prev2 - 2.0 * p_prev + p;
      o.peaks.push_back(p_prev - 0.125 * (p_prev2 - p) * (p_prev2 - p) / den);
    }
    p_prev2 = p_prev;
    p_prev = p;
    const DynamicsStepSummary r = stepper->Step(still, &s);
    EXPECT_TRUE(r.ok) << r.reason;
    if (!r.ok) break;
    if (k % energy_every == 0) {
      const double e = stepper->KineticEnergy(s) + stepper->PotentialEnergy(s.q);
      o.energy_drift = std::max(o.energy_drift, std::abs(e - e0) / e0);
    }
  }
  o.period = crossings > 0 ? (last - first) / crossings : 0.0;
  return o;
}

TEST(Dynamics, CantileverFrequenciesImplicitWithinHalfAPercentAt100Segments) {
  const Suture suture(100);
  const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  for (int mode = 0; mode < 3; ++mode) {
    const double period = 2.0 * M_PI / suture.Omega(mode);
    for (Integrator integrator : {Integrator::kMidpoint, Integrator::kBdf2}) {
      DynamicsOptions options;
      options.integrator = integrator;
      options.time_step = period / 200.0;
      DynamicsStepper stepper(model, options);
      const Oscillation o = FreeOscillation(
          &stepper, stepper.AtRest(ModeState(model, mode, 1e-5)), mode, 4.0 * period, 50);
      EXPECT_NEAR(o.period / period, 1.0, 5e-3)
          << "mode " << mode + 1 << " " << IntegratorName(integrator);
    }
  }
}

TEST(Dynamics, CantileverFrequenciesExplicitWithinHalfAPercentAt100Segments) {
  // The explicit integrator at its stable step: the first mode over 1.2 periods (~8e5 steps)
  // is too long for a unit test, so a stiffer-in-bending, softer-in-stretch rod (EA L^2 / B =
  // 1e4, still far from its stretch modes) keeps the step count small; modes 1 and 2.
  Suture rod(100);
  rod.material.bend_stiffness = 1e-4;
  rod.material.stretch_stiffness = 10.0;
  rod.material.twist_stiffness = 8e-5;
  rod.rod.radius = 1e-3;  // the twist angles' inertia then limits the step no more than bending
  const RodModel model(rod.rod, rod.material, Vec3::Zero(), rod.load_case);
  for (int mode = 0; mode < 2; ++mode) {
    const double period = 2.0 * M_PI / rod.Omega(mode);
    DynamicsOptions options;
    options.integrator = Integrator::kExplicit;
    DynamicsStepper probe(model, options);
    const RodState start = ModeState(model, mode, 1e-5);
    options.time_step = 0.98 * probe.StableTimeStep(start);
    DynamicsStepper stepper(model, options);
    const Oscillation o = FreeOscillation(&stepper, stepper.AtRest(start), mode,
                              (mode == 0 ? 1.3 : 2.2) * period, 1000);
    EXPECT_NEAR(o.period / period, 1.0, 5e-3) << "mode " << mode + 1;
  }
}

TEST(Dynamics, ExplicitEnergyBoundedOver1e5Steps) {
  Suture rod(50);
  const RodModel model(rod.rod, rod.material, Vec3::Zero(), rod.load_case);
  DynamicsOptions options;
  options.integrator = Integrator::kExplicit;
  DynamicsStepper probe(model, options);
  // A large swing (tip 10 % of L) in mode 1.
  const RodState start = ModeState(model, 0, 0.01);
  // The bound is for the linearised rod at the start; the swing changes the tension.
  options.time_step = 0.9 * probe.StableTimeStep(start);
  DynamicsStepper stepper(model, options);
  const Oscillation o = FreeOscillation(&stepper, stepper.AtRest(start), 0,
                            1e5 * options.time_step, 100);
  EXPECT_LT(o.energy_drift, 1e-3);
}

TEST(Dynamics, ExplicitRefusesAStepAboveTheStableStepAndSubstepsWhenAsked) {
  Suture rod(50);
  const RodModel model(rod.rod, rod.material, Vec3::Zero(), rod.load_case);
  DynamicsOptions options;
  options.integrator = Integrator::kExplicit;
  options.time_step = 1e-5;
  DynamicsStepper stepper(model, options);
  const double stable = stepper.StableTimeStep(model.StraightState());
  ASSERT_LT(stable, options.time_step);
  DynamicState s = stepper.AtRest(ModeState(model, 0, 1e-3));
  const DynamicState before = s;
  const DynamicsStepSummary refused = stepper.Step(Drive(), &s);
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.reason.find("stable step"), std::string::npos) << refused.reason;
  EXPECT_EQ(s.t, before.t);
  EXPECT_EQ((s.q.x - before.q.x).norm(), 0.0);
  options.substep = true;
  DynamicsStepper substepping(model, options);
  const DynamicsStepSummary ok = substepping.Step(Drive(), &s);
  ASSERT_TRUE(ok.ok) << ok.reason;
  EXPECT_GE(ok.substeps, static_cast<int>(std::ceil(options.time_step / stable)));
  EXPECT_DOUBLE_EQ(s.t, options.time_step);
}

// The midpoint rule is second order: the error of the tip at a fixed time falls fourfold when
// the step halves. Backward Euler is first order and damps numerically (its amplitude decays
// by ~ exp(-omega^2 dt t / 2)): stated here as a measured decay.
TEST(Dynamics, MidpointAndBdf2AreSecondOrderBackwardEulerFirstOrder) {
  const Suture suture(40);
  const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  const double period = 2.0 * M_PI / suture.Omega(0);
  // The tip at a quarter period (a zero crossing, where the phase error shows) and at half a
  // period (a peak, where the amplitude error shows), stacked.
  auto tips = [&](Integrator integrator, double dt) {
    DynamicsOptions options;
    options.integrator = integrator;
    options.time_step = dt;
    options.step_tolerance = 1e-14;
    DynamicsStepper stepper(model, options);
    // A small amplitude (tip 2e-5 m): the stretch modes, far beyond these steps, where the
    // midpoint rule keeps their amplitudes with a phase that jumps each step, are excited only
    // at second order in it.
    DynamicState s = stepper.AtRest(ModeState(model, 0, 1e-5));
    Eigen::Matrix<double, 6, 1> out;
    const int quarter = static_cast<int>(std::lround(0.25 * period / dt));
    for (int k = 0; k < 2 * quarter; ++k) {
      const DynamicsStepSummary r = stepper.Step(Drive(), &s);
      EXPECT_TRUE(r.ok) << r.reason;
      if (!r.ok) break;
      if (k + 1 == quarter) out.head<3>() = s.q.x.col(model.num_edges());
    }
    out.tail<3>() = s.q.x.col(model.num_edges());
    return out;
  };
  const double h = period / 64.0;
  const auto ref = tips(Integrator::kMidpoint, h / 16.0);
  const double e1 = (tips(Integrator::kMidpoint, h) - ref).norm();
  const double e2 = (tips(Integrator::kMidpoint, h / 2.0) - ref).norm();
  EXPECT_NEAR(std::log2(e1 / e2), 2.0, 0.2) << e1 << " " << e2;
  const double d1 = (tips(Integrator::kBdf2, h) - ref).norm();
  const double d2 = (tips(Integrator::kBdf2, h / 2.0) - ref).norm();
  EXPECT_NEAR(std::log2(d1 / d2), 2.0, 0.25) << d1 << " " << d2;
  const double b1 = (tips(Integrator::kBackwardEuler, h) - ref).norm();
  const double b2 = (tips(Integrator::kBackwardEuler, h / 2.0) - ref).norm();
  EXPECT_NEAR(std::log2(b1 / b2), 1.0, 0.2) << b1 << " " << b2;
}

TEST(Dynamics, BackwardEulerDampsAnUndampedModeNumerically) {
  const Suture suture(40);
  const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  const double omega = suture.Omega(0), period = 2.0 * M_PI / omega;
  DynamicsOptions options;
  options.integrator = Integrator::kBackwardEuler;
  options.time_step = period / 100.0;
  DynamicsStepper stepper(model, options);
  const Oscillation o = FreeOscillation(&stepper, stepper.AtRest(ModeState(model, 0, 1e-4)), 0, 3.0 * period);
  ASSERT_GE(o.peaks.size(), 2u);
  // Backward Euler on x'' = -omega^2 x: |z| = 1 / sqrt(1 + (omega dt)^2) per step, so per period
  // the amplitude falls by (1 + (omega dt)^2)^(-N/2), N = period / dt steps.
  const double expected = std::pow(1.0 + std::pow(omega * options.time_step, 2), -50.0);
  EXPECT_NEAR(o.peaks[1] / o.peaks[0], expected, 0.02 * expected);
}

// Logarithmic decrement delta = ln(x_k / x_k+1) = 2 pi zeta / sqrt(1 - zeta^2) of a damped mode:
// external drag c gives zeta = c / (2 rho omega); bending viscosity eta gives zeta = eta omega /
// (2 B) (Kelvin–Voigt: the damping matrix is eta / B times the bending stiffness matrix).
TEST(Dynamics, LogarithmicDecrementMatchesTheDampingWithinOnePercent) {
  for (int kind = 0; kind < 2; ++kind) {
    Suture suture(100);
    const double omega = suture.Omega(0), period = 2.0 * M_PI / omega;
    const double zeta = 0.02;
    if (kind == 0) {
      suture.material.damping = 2.0 * zeta * suture.rod.linear_density * omega;
    } else {
      suture.material.bend_damping = 2.0 * zeta * suture.material.B1() / omega;
    }
    const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
    DynamicsOptions options;
    options.integrator = Integrator::kMidpoint;
    options.time_step = period / 200.0;
    DynamicsStepper stepper(model, options);
    const Oscillation o =
        FreeOscillation(&stepper, stepper.AtRest(ModeState(model, 0, 1e-5)), 0, 4.2 * period, 1000000);
    ASSERT_GE(o.peaks.size(), 4u);
    const double measured = std::log(o.peaks[0] / o.peaks[3]) / 3.0;
    const double expected = 2.0 * M_PI * zeta / std::sqrt(1.0 - zeta * zeta);
    EXPECT_NEAR(measured / expected, 1.0, 0.01) << (kind == 0 ? "drag" : "bending viscosity");
  }
}

// Moving a pinned end slowly (over many periods of the first mode) with damping, then holding it:
// the rod settles onto the statics solver's equilibrium for the final pin position, under
// gravity, to 1e-6 L.
TEST(Dynamics, SlowDriveReproducesTheStaticsSolver) {
  Suture suture(30);
  const double omega = suture.Omega(0);
  suture.material.damping = 2.0 * 0.7 * suture.rod.linear_density * omega;
  const Vec3 gravity(0, 0, -9.81);
  const Vec3 start_pin(0.19, 0.0, 0.0), end_pin(0.15, 0.03, -0.04);
  LoadCase initial = suture.load_case;
  initial.end_pin = start_pin;
  LoadCase final_case = suture.load_case;
  final_case.end_pin = end_pin;
  const RodModel first(suture.rod, suture.material, gravity, initial);
  const RodModel last(suture.rod, suture.material, gravity, final_case);
  RodState q = first.StraightState();
  ASSERT_TRUE(SolveStatics(first, StaticsOptions(), &q).converged);
  RodState expected = last.StraightState();
  ASSERT_TRUE(SolveStatics(last, StaticsOptions(), &expected).converged);

  // The pin follows a smooth step from start to end over `ramp` seconds.
  struct Ramp : Drive {
    Vec3 a, b;
    double ramp = 0.0;
    void PoseAt(const RodModel& model, double t, HeldPose* pose) const override {
      Drive::PoseAt(model, t, pose);
      const double u = std::min(1.0, t / ramp);
      const double w = u * u * (3.0 - 2.0 * u);
      pose->held[0] = (1.0 - w) * a + w * b;
    }
  } drive;
  drive.a = start_pin;
  drive.b = end_pin;
  drive.ramp = 20.0 * 2.0 * M_PI / omega;
  DynamicsOptions options;
  options.integrator = Integrator::kBackwardEuler;
  options.time_step = 2e-3;
  DynamicsStepper stepper(last, options);
  DynamicState s = stepper.AtRest(q);
  const int steps = static_cast<int>((drive.ramp + 40.0 / omega) / options.time_step);
  for (int k = 0; k < steps; ++k) {
    const DynamicsStepSummary r = stepper.Step(drive, &s);
    ASSERT_TRUE(r.ok) << r.reason << " at t = " << s.t;
  }
  double worst = 0.0;
  for (int i = 0; i <= last.num_edges(); ++i)
    worst = std::max(worst, (s.q.x.col(i) - expected.x.col(i)).norm());
  EXPECT_LT(worst, 1e-6 * suture.rod.length);
}

// A point force of the pose (a tool pushing the rod between two vertices, as the runtime's
// dynamic poke applies it) settles, with damping, in the statics' equilibrium under the same
// dead force at that arc length (LoadCase::point_forces), for BDF2 and the explicit integrator.
TEST(Dynamics, PointForceOfThePoseSettlesInTheStaticsEquilibrium) {
  Suture suture(20);
  const double omega = suture.Omega(0);
  suture.material.damping = 2.0 * 0.7 * suture.rod.linear_density * omega;
  const Vec3 gravity(0, 0, -9.81);
  const double s_point = 0.37 * suture.rod.length;  // between vertices 7 and 8
  const Vec3 force(0.0, 2e-4, 1e-4);                // [N], of the order of the rod's weight
  LoadCase pushed = suture.load_case;
  pushed.point_forces.push_back({s_point, force});
  const RodModel statics_model(suture.rod, suture.material, gravity, pushed);
  RodState expected = statics_model.StraightState();
  ASSERT_TRUE(SolveStatics(statics_model, StaticsOptions(), &expected).converged);
  const RodModel model(suture.rod, suture.material, gravity, suture.load_case);
  struct Push : Drive {
    Vec3 force;
    int vertex = 0;
    double weight = 0.0;
    void PoseAt(const RodModel& m, double t, HeldPose* pose) const override {
      Drive::PoseAt(m, t, pose);
      pose->point_force = force;
      pose->point_vertex = vertex;
      pose->point_weight = weight;
    }
  } push;
  push.force = force;
  const double edge = suture.rod.length / 20;
  push.vertex = static_cast<int>(s_point / edge);
  push.weight = s_point / edge - push.vertex;
  for (const Integrator integrator : {Integrator::kBdf2, Integrator::kExplicit}) {
    SCOPED_TRACE(IntegratorName(integrator));
    DynamicsOptions options;
    options.integrator = integrator;
    options.substep = true;
    options.time_step = 2e-3;
    DynamicsStepper stepper(model, options);
    RodState start = model.StraightState();
    ASSERT_TRUE(SolveStatics(model, StaticsOptions(), &start).converged);
    DynamicState s = stepper.AtRest(start);
    const int steps = static_cast<int>(40.0 / omega / options.time_step);
    for (int k = 0; k < steps; ++k) {
      const DynamicsStepSummary r = stepper.Step(push, &s);
      ASSERT_TRUE(r.ok) << r.reason << " at t = " << s.t;
    }
    double worst = 0.0, moved = 0.0;
    for (int i = 0; i <= model.num_edges(); ++i) {
      worst = std::max(worst, (s.q.x.col(i) - expected.x.col(i)).norm());
      moved = std::max(moved, (start.x.col(i) - expected.x.col(i)).norm());
    }
    EXPECT_GT(moved, 1e-3 * suture.rod.length);  // the force moves the rod visibly
    EXPECT_LT(worst, 1e-6 * suture.rod.length);
  }
}

TEST(Dynamics, RefusesARodWithoutMassAndExplicitWithoutRadius) {
  Suture suture(10);
  suture.rod.linear_density = 0.0;
  const RodModel massless(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  EXPECT_THROW(DynamicsStepper(massless, DynamicsOptions()), std::invalid_argument);
  Suture thin(10);
  thin.rod.radius = 0.0;
  const RodModel no_radius(thin.rod, thin.material, Vec3::Zero(), thin.load_case);
  DynamicsOptions options;
  options.integrator = Integrator::kExplicit;
  EXPECT_THROW(DynamicsStepper(no_radius, options), std::invalid_argument);
  options.integrator = Integrator::kMidpoint;
  EXPECT_NO_THROW(DynamicsStepper(no_radius, options));
}

}  // namespace
}  // namespace rodfit

namespace rodfit {
namespace {

// The real suture (data/scenes/suture_swing.yaml) released horizontal under gravity: the
// implicit integrators at dt = 1 ms against the explicit one at its stable step (~1.5e-6 s):
// the same motion, vertex by vertex, over the first 0.1 s (the full second is in
// bench_dynamics, too long for a unit test).
TEST(Dynamics, SutureSwingImplicitAtOneMillisecondMatchesExplicit) {
  Suture suture(50);
  suture.material.damping = 1e-5;
  const Vec3 gravity(0, 0, -9.81);
  const RodModel model(suture.rod, suture.material, gravity, suture.load_case);
  const double duration = 0.1;
  auto run = [&](Integrator integrator, double dt) {
    DynamicsOptions options;
    options.integrator = integrator;
    options.time_step = dt;
    DynamicsStepper stepper(model, options);
    DynamicState s = stepper.AtRest(model.StraightState());
    const int steps = static_cast<int>(std::lround(duration / dt));
    for (int k = 0; k < steps; ++k) {
      const DynamicsStepSummary r = stepper.Step(Drive(), &s);
      EXPECT_TRUE(r.ok) << r.reason;
      if (!r.ok) break;
    }
    return s.q.x;
  };
  DynamicsOptions probe_options;
  probe_options.integrator = Integrator::kExplicit;
  DynamicsStepper probe(model, probe_options);
  const double stable = probe.StableTimeStep(model.StraightState());
  const Mat3X reference = run(Integrator::kExplicit, duration / std::ceil(duration / (0.8 * stable)));
  // The tip has fallen ~4 cm by then: the comparison is of a large motion.
  EXPECT_GT(-reference(2, model.num_edges()), 0.02);
  for (Integrator integrator : {Integrator::kBdf2, Integrator::kMidpoint}) {
    const Mat3X x = run(integrator, 1e-3);
    EXPECT_LT((x - reference).colwise().norm().maxCoeff(), 1e-3) << IntegratorName(integrator);
  }
}

// Where BDF2's Newton starts (the third-order extrapolation of the rates when the state carries
// v_n-2, the second-order one without, and the last steps' corrections extrapolated on top) and
// when it stops on its step sizes' contraction (converge_on_rate) change the iterations, not the
// step's solution: the suture's 100 ms fall under gravity agrees to the step's tolerance either
// way, and each further start takes fewer iterations.
TEST(Dynamics, Bdf2StartDoesNotChangeTheTrajectory) {
  Suture suture(50);
  suture.material.damping = 1e-5;
  const RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), suture.load_case);
  enum Start { kSecondOrder, kThirdOrder, kCorrected, kCorrectedOnRate };
  auto run = [&](Start start, int* iterations) {
    DynamicsOptions options;
    options.integrator = Integrator::kBdf2;
    options.time_step = 1e-3;
    options.extrapolate_corrections = start >= kCorrected;
    options.converge_on_rate = start == kCorrectedOnRate;
    DynamicsStepper stepper(model, options);
    DynamicState s = stepper.AtRest(model.StraightState());
    *iterations = 0;
    for (int k = 0; k < 100; ++k) {
      if (start == kSecondOrder) s.has_older = false;
      const DynamicsStepSummary r = stepper.Step(Drive(), &s);
      EXPECT_TRUE(r.ok) << r.reason;
      if (!r.ok) break;
      *iterations += r.newton_iterations;
      if (k >= 2 && start != kSecondOrder) {
        EXPECT_TRUE(s.has_older);
      }
      // The corrections are recorded from the second third-order step on.
      if (k >= 3 && start != kSecondOrder) {
        EXPECT_EQ(s.num_corrections, 2);
      }
    }
    return s.q.x;
  };
  int second = 0, third = 0, corrected = 0, on_rate = 0;
  const Mat3X b = run(kSecondOrder, &second), a = run(kThirdOrder, &third);
  const Mat3X c = run(kCorrected, &corrected), d = run(kCorrectedOnRate, &on_rate);
  EXPECT_GT(-a(2, model.num_edges()), 0.02);  // a large motion
  // The step's convergence test (residual 1e-9 of the forces) leaves ~1e-9 L in the positions.
  for (const Mat3X* x : {&b, &c, &d})
    EXPECT_LT((a - *x).colwise().norm().maxCoeff(), 1e-8 * suture.rod.length);
  std::printf("[measured] suture fall, 100 steps: %d / %d / %d / %d Newton iterations "
              "(second-order start / third-order / corrections extrapolated / and on rate), "
              "largest difference %.1e / %.1e / %.1e L\n",
              second, third, corrected, on_rate,
              (a - b).colwise().norm().maxCoeff() / suture.rod.length,
              (a - c).colwise().norm().maxCoeff() / suture.rod.length,
              (a - d).colwise().norm().maxCoeff() / suture.rod.length);
  EXPECT_LT(third, second);
  EXPECT_LT(corrected, third);
  EXPECT_LE(on_rate, corrected);
}

// The runtime's fast start and stop (extrapolate_corrections, converge_on_rate) on paths that
// are anything but steady: the suture grasped at its tip is dragged round a circle and reversed
// dead, held still and jerked by a tenth of an edge; sped up and slowed down; pulled along a
// line with jerks every 10 ms; round the circle with a device's jitter (where the corrections
// are never steady); reversed three times. Every step converges, in no more iterations than the
// plain stepper's, and the trajectory is as near a tightly converged one (residual 1e-12) as the
// plain stepper's: where the extrapolated corrections would point the wrong way they are not
// used (without that guard the first path ended 14x further off).
TEST(Dynamics, FastStartAndStopFollowErraticDrags) {
  Suture suture(40);
  suture.material.damping = 1e-5;
  const double L = suture.rod.length, l = L / 40;
  LoadCase held = suture.load_case;
  held.grasp = Grasp{L, Vec3(L, 0, 0)};
  const RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), held);
  int grasp_index = -1;
  for (size_t k = 0; k < model.held().size(); ++k)
    if (model.held()[k].kind == HeldVertex::Kind::kGrasp) grasp_index = static_cast<int>(k);
  ASSERT_GE(grasp_index, 0);
  const double w = 2.0 * 3.141592653589793 * 5.0, r = 0.01;  // a 1 cm circle at 5 turns/s
  auto circle = [&](double u) {
    return Vec3(L - r + r * std::cos(w * u), r * std::sin(w * u), 0.0);
  };
  // A haptic device's jitter: +-5 um per coordinate in the plane of the drag, new every step.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> uniform(-5e-6, 5e-6);
  std::vector<Vec3> jitter(101);
  for (Vec3& j : jitter) j = Vec3(uniform(random), uniform(random), 0.0);
  // Time [s] -> the grasp's position.
  const std::vector<std::pair<const char*, std::function<Vec3(double)>>> paths = {
      {"reversed, stopped, jerked",
       [&](double t) {
         Vec3 p = circle(t < 0.04 ? t : t < 0.06 ? 0.08 - t : 0.04);
         if (t >= 0.07) p.y() += 0.1 * l;
         return p;
       }},
      {"sped up, slowed down",
       [&](double t) {
         return circle(t < 0.03 ? t : t < 0.06 ? 0.03 + 2 * (t - 0.03) : 0.09 + 0.5 * (t - 0.06));
       }},
      {"line with jerks",
       [&](double t) {
         return Vec3(L, 0.2 * t, (static_cast<int>(t / 0.01) % 2 ? 0.05 : -0.05) * l);
       }},
      {"circle with +-5 um jitter",
       [&](double t) {
         const size_t k = static_cast<size_t>(std::lround(t / 1e-3));
         return Vec3(circle(t) + jitter[std::min(k, jitter.size() - 1)]);
       }},
      {"reversed three times",
       [&](double t) {
         return circle(t > 0.07 ? 0.09 - t : t > 0.045 ? t - 0.05 : t > 0.02 ? 0.04 - t : t);
       }},
  };
  class PathDrive : public Drive {
   public:
    PathDrive(int index, std::function<Vec3(double)> path)
        : index_(index), path_(std::move(path)) {}
    void PoseAt(const RodModel& m, double t, HeldPose* pose) const override {
      Drive::PoseAt(m, t, pose);
      pose->held[index_] = path_(t);
    }

   private:
    int index_;
    std::function<Vec3(double)> path_;
  };
  enum Kind { kPlain, kFast, kTight };
  for (const auto& [name, path] : paths) {
    const PathDrive drive(grasp_index, path);
    auto run = [&](Kind kind, std::vector<Mat3X>* shapes, int* iterations) {
      DynamicsOptions options;
      options.integrator = Integrator::kBdf2;
      options.time_step = 1e-3;
      options.extrapolate_corrections = options.converge_on_rate = kind == kFast;
      if (kind == kTight) {
        options.residual_tolerance = 1e-12;
        options.step_tolerance = 1e-14;
      }
      DynamicsStepper stepper(model, options);
      DynamicState s = stepper.AtRest(model.StraightState());
      *iterations = 0;
      for (int k = 0; k < 100; ++k) {
        const DynamicsStepSummary result = stepper.Step(drive, &s);
        ASSERT_TRUE(result.ok) << name << ", step " << k << ": " << result.reason;
        *iterations += result.newton_iterations;
        shapes->push_back(s.q.x);
      }
    };
    std::vector<Mat3X> plain, fast, tight;
    int plain_iterations = 0, fast_iterations = 0, tight_iterations = 0;
    run(kPlain, &plain, &plain_iterations);
    run(kFast, &fast, &fast_iterations);
    run(kTight, &tight, &tight_iterations);
    ASSERT_EQ(plain.size(), 100u);
    ASSERT_EQ(fast.size(), 100u);
    ASSERT_EQ(tight.size(), 100u);
    double plain_off = 0.0, fast_off = 0.0;
    for (size_t k = 0; k < plain.size(); ++k) {
      plain_off = std::max(plain_off, (plain[k] - tight[k]).colwise().norm().maxCoeff());
      fast_off = std::max(fast_off, (fast[k] - tight[k]).colwise().norm().maxCoeff());
    }
    std::printf("[measured] %-26s 100 steps: %d / %d Newton iterations (plain / fast), largest "
                "distance to the tight trajectory %.2e / %.2e L\n",
                name, plain_iterations, fast_iterations, plain_off / L, fast_off / L);
    EXPECT_LE(fast_iterations, plain_iterations) << name;
    // Measured within 1 % of each other on every path.
    EXPECT_LT(fast_off, 1.1 * plain_off + 1e-10 * L) << name;
    // The tip moved: a real drag, not a rod at rest.
    double travel = 0.0;
    for (const Mat3X& x : plain) travel = std::max(travel, (x.col(40) - Vec3(L, 0, 0)).norm());
    EXPECT_GT(travel, 0.005) << name;
  }
}

// The implicit step's derivative check: backward Euler's state is the stationary point of its
// incremental potential, i.e. on every free dof
//   m_k (v1_k - v0_k) / dt + d_k v1_k + dPi/dq_k (q1) = 0,
// d_k the drag coefficient (c times the vertex's length; none on the twists). dPi/dq_k is taken
// here by central differences of the energy along each dof (ApplyStep, the solver's own dof
// update), independent of the closed-form gradient and Hessian Newton used. A 3-D motion: an
// anisotropic suture bent into its first mode, pulled sideways at the tip under gravity, every
// dof moving with its own initial rate.
TEST(Dynamics, BackwardEulerStepIsStationaryAgainstAFiniteDifferenceGradient) {
  Suture su(12);
  su.material.bend_stiffness_2 = 1.5 * su.material.bend_stiffness;
  su.material.damping = 0.05;  // [N s/m^2]
  su.load_case.tip_force = Vec3(0.0, 2e-5, 0.0);
  const RodModel model(su.rod, su.material, Vec3(0, 0, -9.81), su.load_case);
  DynamicsOptions options;
  options.integrator = Integrator::kBackwardEuler;
  options.time_step = 1e-3;
  // Newton to round-off, so that what is left is the check's own error (the default tolerance,
  // relative to the rod's weight, would leave twist residuals near the tiny twist moments).
  options.residual_tolerance = 1e-14;
  DynamicsStepper stepper(model, options);
  DynamicState s = stepper.AtRest(ModeState(model, 0, 0.02));
  const std::vector<char>& held = HeldDofs(model);
  const int N = model.num_free_dofs();
  for (int k = 0; k < N; ++k) {
    if (held[k]) continue;
    const bool twist = k % 4 == 3;
    // Rates of a few cm/s and rad/s, different on every dof.
    s.v[k] = (twist ? 0.5 : 0.03) * std::sin(1.7 * k + 0.3);
  }
  const VecX v0 = s.v;
  const DynamicsStepSummary r = stepper.Step(Drive(), &s);
  ASSERT_TRUE(r.ok) << r.reason;
  const double dt = options.time_step;
  const VecX& m = stepper.mass();
  double worst_force = 0.0, scale_force = 0.0, worst_moment = 0.0, scale_moment = 0.0;
  for (int k = 0; k < N; ++k) {
    if (held[k]) continue;
    const bool twist = k % 4 == 3;
    // Steps where the differences' truncation and round-off (eps Pi / h) are both far below the
    // terms: the twist moments are ~1e-12 N m (the spin inertia is tiny), the forces ~1e-5 N.
    const double h = twist ? 1e-4 : 1e-9;  // [rad], [m]
    VecX e = VecX::Zero(N);
    e[k] = 1.0;
    RodState plus, minus;
    ASSERT_TRUE(ApplyStep(model, s.q, e, h, &plus));
    ASSERT_TRUE(ApplyStep(model, s.q, e, -h, &minus));
    const double gradient =
        (stepper.PotentialEnergy(plus) - stepper.PotentialEnergy(minus)) / (2.0 * h);
    const double drag = twist ? 0.0 : su.material.damping * m[k] / su.rod.linear_density;
    const double inertia = m[k] * (s.v[k] - v0[k]) / dt;
    const double residual = inertia + drag * s.v[k] + gradient;
    const double size = std::max({std::abs(inertia), std::abs(drag * s.v[k]), std::abs(gradient)});
    if (twist) {
      worst_moment = std::max(worst_moment, std::abs(residual));
      scale_moment = std::max(scale_moment, size);
    } else {
      worst_force = std::max(worst_force, std::abs(residual));
      scale_force = std::max(scale_force, size);
    }
  }
  // The terms are of the size of the inertia forces (~1e-5 N, ~1e-10 N m); the balance holds to
  // the finite differences' error.
  EXPECT_GT(scale_force, 1e-7);
  EXPECT_GT(scale_moment, 0.0);
  EXPECT_LT(worst_force, 1e-5 * scale_force);
  EXPECT_LT(worst_moment, 1e-5 * scale_moment);
}

}  // namespace
}  // namespace rodfit
