// The energy envelope of a moving run (integration.h, kEnergyEnvelopeMargin): the rod's energy
// may not grow beyond its start plus the work done on it. No false alarm where the work is
// large: an undamped rod (implicit midpoint, which does not damp) dragged by a grasp, swung by
// its clamp's turn, shaken by a tip force and moment over time: each run goes to its end inside
// the envelope while the energy it gains is most of its energy scale, so the work is accounted
// (with none accounted, the first would leave the envelope). The runs it stops are in
// tests/cli/energy_envelope_cli_test.cc.
#include <cmath>
#include <cstdio>
#include <functional>

#include <gtest/gtest.h>

#include "rodfit/reference/cantilever_modes.h"
#include "rodfit/solve/integration.h"

namespace rodfit {
namespace {

using reference::Suture;

// A smooth ramp from 0 at t = 0 to 1 at t = T (sin^2), held at 1 after.
double Ramp(double t, double T) {
  if (t >= T) return 1.0;
  const double s = std::sin(0.5 * M_PI * t / T);
  return s * s;
}

class FunctionDrive : public Drive {
 public:
  explicit FunctionDrive(std::function<void(const RodModel&, double, HeldPose*)> pose)
      : pose_(std::move(pose)) {}
  void PoseAt(const RodModel& m, double t, HeldPose* pose) const override {
    Drive::PoseAt(m, t, pose);
    pose_(m, t, pose);
  }

 private:
  std::function<void(const RodModel&, double, HeldPose*)> pose_;
};

struct EnvelopeRun {
  IntegrationStats stats;
  double energy_gain = 0.0;  // [J] E(end) - E(0)
  double energy_scale = 0.0; // [J] the largest kinetic energy plus the largest |Pi - Pi0|
};

EnvelopeRun Simulate(const RodModel& model, const DynamicsOptions& options, const Drive& drive,
             int steps, bool envelope = true) {
  DynamicsStepper stepper(model, options);
  DynamicState s = stepper.AtRest(model.StraightState());
  const double e0 = stepper.KineticEnergy(s) + stepper.PotentialEnergy(s.q);
  const double p0 = stepper.PotentialEnergy(s.q);
  double largest_kinetic = 0.0, largest_potential = 0.0;
  EnvelopeRun run;
  run.stats = Integrate(
      stepper, drive, steps, &s,
      [&](const DynamicState&, const DynamicState& after, const DynamicsStepSummary&) {
        largest_kinetic = std::max(largest_kinetic, stepper.KineticEnergy(after));
        largest_potential =
            std::max(largest_potential, std::abs(stepper.PotentialEnergy(after.q) - p0));
        return true;
      },
      nullptr, nullptr, envelope);
  run.energy_gain = stepper.KineticEnergy(s) + stepper.PotentialEnergy(s.q) - e0;
  run.energy_scale = largest_kinetic + largest_potential;
  return run;
}

DynamicsOptions Midpoint() {
  DynamicsOptions options;
  options.integrator = Integrator::kMidpoint;
  options.time_step = 5e-4;
  return options;
}

// The suture clamped at s = 0 and grasped at its tip; the grasp drawn 3 cm sideways and 1 cm
// up over 0.1 s and held there for 0.05 s. Undamped, the work of the grasp stays in the rod.
TEST(EnergyEnvelope, GraspDragAccountsTheHoldersWork) {
  Suture suture(20);
  const double L = suture.rod.length;
  LoadCase held = suture.load_case;
  held.grasp = Grasp{L, Vec3(L, 0, 0)};
  const RodModel model(suture.rod, suture.material, Vec3(0, 0, -9.81), held);
  ASSERT_EQ(model.held().size(), 1u);
  const FunctionDrive drive([&](const RodModel&, double t, HeldPose* pose) {
    pose->held[0] = Vec3(L, 0.03 * Ramp(t, 0.1), 0.01 * Ramp(t, 0.1));
  });
  const EnvelopeRun run = Simulate(model, Midpoint(), drive, 300);
  ASSERT_TRUE(run.stats.ok) << run.stats.reason;
  std::printf("[measured] grasp drag: energy gained %.3e J of scale %.3e J, largest excess "
              "%.3f of the margin\n",
              run.energy_gain, run.energy_scale, run.stats.energy_excess_ratio);
  // The rod gained energy: the grasp did work worth most of the scale.
  EXPECT_GT(run.energy_gain, 0.5 * run.energy_scale);
  // Inside the envelope with room to spare (measured ~0.01 of the margin).
  EXPECT_LT(run.stats.energy_excess_ratio, 0.5);
  // Without the grasp's work in the account the same gain would leave the envelope.
  EXPECT_GT(run.energy_gain, kEnergyEnvelopeMargin * 3.0 * run.energy_scale);
}

// The clamp turned 0.4 rad about z (and its d1 with it) over 0.1 s: its moment does the work.
TEST(EnergyEnvelope, ClampTurnAccountsTheClampsMomentWork) {
  Suture suture(20);
  const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  const FunctionDrive drive([&](const RodModel&, double t, HeldPose* pose) {
    const double a = 0.4 * Ramp(t, 0.1);
    pose->clamp_tangent = Vec3(std::cos(a), std::sin(a), 0.0);
    pose->clamp_d1 = Vec3::UnitZ();
  });
  const EnvelopeRun run = Simulate(model, Midpoint(), drive, 300);
  ASSERT_TRUE(run.stats.ok) << run.stats.reason;
  std::printf("[measured] clamp turn: energy gained %.3e J of scale %.3e J, largest excess "
              "%.3f of the margin\n",
              run.energy_gain, run.energy_scale, run.stats.energy_excess_ratio);
  EXPECT_GT(run.energy_gain, 0.5 * run.energy_scale);
  EXPECT_LT(run.stats.energy_excess_ratio, 0.5);
}

// A tip force over time (the drive's tip load series) and a tip moment: the loads' work.
TEST(EnergyEnvelope, TipLoadSeriesAccountsTheLoadsWork) {
  Suture suture(20);
  const RodModel model(suture.rod, suture.material, Vec3::Zero(), suture.load_case);
  const FunctionDrive drive([&](const RodModel&, double t, HeldPose* pose) {
    pose->tip_force = Vec3(0.0, 2e-5 * Ramp(t, 0.05), 0.0);
    pose->tip_moment = Vec3(1e-6 * Ramp(t, 0.05), 0.0, 0.0);
  });
  const EnvelopeRun run = Simulate(model, Midpoint(), drive, 300);
  ASSERT_TRUE(run.stats.ok) << run.stats.reason;
  std::printf("[measured] tip loads: energy gained %.3e J of scale %.3e J, largest excess "
              "%.3f of the margin\n",
              run.energy_gain, run.energy_scale, run.stats.energy_excess_ratio);
  EXPECT_GT(run.energy_gain, 0.5 * run.energy_scale);
  EXPECT_LT(run.stats.energy_excess_ratio, 0.5);
}

}  // namespace
}  // namespace rodfit
