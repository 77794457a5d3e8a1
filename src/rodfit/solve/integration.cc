// The one integration loop (integration.h).
#include "rodfit/solve/integration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "rodfit/solve/rod_energy.h"

namespace rodfit {
namespace {

// The same boundary and no loads beyond Pi: a step between two such poses has no work done on
// the rod (but for moment loads, which the caller checks). A constant tip force still works on
// a moving tip.
bool StillAndUnloaded(const HeldPose& a, const HeldPose& b) {
  auto unloaded = [](const HeldPose& p) {
    return p.tip_force.squaredNorm() == 0.0 && p.tip_moment.squaredNorm() == 0.0 &&
           (p.point_vertex < 0 || p.point_force.squaredNorm() == 0.0);
  };
  return unloaded(a) && unloaded(b) && a.clamp_position == b.clamp_position &&
         a.clamp_tangent == b.clamp_tangent && a.clamp_d1 == b.clamp_d1 && a.held == b.held &&
         a.end_tangent == b.end_tangent && a.end_d1 == b.end_d1;
}

// The energy envelope (integration.h, kEnergyEnvelopeMargin), accounted step by step. With
// E = T + Pi and g = dPi/dq less the loads beyond Pi on the free dofs (LoadedGradient), the
// work done on the rod in a step is the change of Pi the free dofs' own motion does not explain
// (the held points' motion: the holders' work, each reaction times its displacement, to the
// order of the rule) plus the loads' work beyond Pi:
//   W = dPi - g_mid . dq,   g_mid = (g_before + g_after) / 2 (the trapezoidal rule),
// so the energy not accounted for is E - E0 - W = sum of (dT + g_mid . dq) over the steps: the
// free dofs' kinetic energy against the work of their forces, where damping and a scheme's
// numerical damping can only take energy out. Every held point, clamp frame, end clamp or
// mirror plane counts alike, without their reactions. A step whose boundary does not move and
// that has no loads beyond Pi has W = 0 exactly, with no rule: a rod swinging from a still clamp
// is held to its own energy.
class EnergyEnvelope {
 public:
  EnergyEnvelope(DynamicsStepper& stepper, const Drive& drive, const DynamicState& start)
      : stepper_(stepper), drive_(drive) {
    Evaluate(start, &last_);
    // The floor of a moving boundary's energy scale: the energy of lifting the rod by its own
    // length under standard gravity (whatever the scene's gravity). The trapezoidal work of a
    // boundary that starts moving from rest is resolved only after a few steps, while the run's
    // own scale is still near zero: without a floor, a gripper's start-up on a rod at rest (a
    // recording's pull from frame 0) read as energy from nowhere. A blow-up grows without
    // bound and still leaves it; a rod whose boundary stays still keeps the exact check.
    const RodModel& model = stepper_.model();
    double mass = 0.0;  // [kg]
    for (int i = 0; i <= model.num_edges(); ++i) mass += model.vertex_mass(i);
    moving_floor_ = mass * kStandardGravity * model.length();
    kinetic0_ = last_.kinetic;
    potential0_ = last_.potential;
    largest_kinetic_ = kinetic0_;
  }

  // Accounts the step from `before` (the last step's end) to `after`; false with *why when the
  // rod's energy leaves the envelope. *ratio: the largest excess over the margin so far.
  bool Step(const DynamicState& before, const DynamicState& after, std::string* why,
            double* ratio) {
    Side next;
    Evaluate(after, &next);
    // A step whose boundary and loads stay where they were has no work done on the rod: its
    // change of E is all unexplained, exactly (the rule's error is then not in it).
    double unexplained = next.kinetic + next.potential - last_.kinetic - last_.potential;
    if (stepper_.model().nonconservative() || !StillAndUnloaded(last_.pose, next.pose)) {
      stepper_.Difference(before.q, after.q, &dq_);
      unexplained = next.kinetic - last_.kinetic + 0.5 * (last_.gradient + next.gradient).dot(dq_);
      // The rule's own uncertainty: half the spread between its two rectangle rules. Small for
      // a resolved step; large where a held point jumps in one step (a recording's first frame
      // snapping the held markers), whose work the rule cannot resolve.
      rule_spread_ += 0.5 * std::abs((next.gradient - last_.gradient).dot(dq_));
      boundary_moved_ = true;
    }
    excess_ += unexplained;
    // This step's work: its change of E less what is not accounted for.
    const double step_work =
        (next.kinetic + next.potential) - (last_.kinetic + last_.potential) - unexplained;
    work_variation_ += std::abs(step_work);
    const double gained = (next.kinetic + next.potential) - (kinetic0_ + potential0_);
    const double done = gained - excess_;  // W: the work done on the rod since the start
    largest_kinetic_ = std::max(largest_kinetic_, next.kinetic);
    largest_potential_change_ =
        std::max(largest_potential_change_, std::abs(next.potential - potential0_));
    const double scale = std::max(largest_kinetic_ + largest_potential_change_ + work_variation_,
                                  boundary_moved_ ? moving_floor_ : 0.0);
    const double margin =
        kEnergyEnvelopeMargin * scale + rule_spread_ +
        kEnergyEnvelopeRoundOff * (std::abs(potential0_) + std::abs(next.potential) + kinetic0_ +
                                   next.kinetic + work_variation_);
    last_ = std::move(next);
    const double r = margin > 0.0 ? excess_ / margin : (excess_ > 0.0 ? HUGE_VAL : 0.0);
    *ratio = std::max(*ratio, r);
    if (excess_ <= margin) return true;
    char text[400];
    std::snprintf(text, sizeof(text),
                  "t = %.6g s: the rod's energy grew by %.3g J while %.3g J of work was done on "
                  "it, beyond the energy envelope's margin of %.3g J (%g %% of its energy scale "
                  "%.3g J): not physics but an unstable step or absurd constants (a smaller "
                  "time_step, an implicit integrator?)",
                  after.t, gained, done, margin, 100.0 * kEnergyEnvelopeMargin, scale);
    *why = text;
    return false;
  }

 private:
  struct Side {
    double kinetic = 0.0, potential = 0.0;  // [J]
    VecX gradient;                          // LoadedGradient [N, N m]
    HeldPose pose;
  };

  void Evaluate(const DynamicState& s, Side* side) {
    side->pose.held.assign(stepper_.model().held().size(), Vec3::Zero());
    drive_.PoseAt(stepper_.model(), s.t, &side->pose);
    stepper_.LoadedGradient(s.q, side->pose, &frames_, &side->gradient);
    side->kinetic = stepper_.KineticEnergy(s);
    side->potential = stepper_.PotentialEnergy(s.q);
  }

  DynamicsStepper& stepper_;
  const Drive& drive_;
  Side last_;
  RodFrames frames_;
  VecX dq_;
  double kinetic0_ = 0.0, potential0_ = 0.0;
  double excess_ = 0.0;          // [J] E - E0 - W
  double work_variation_ = 0.0;  // [J] the sum of |W| of every step
  double rule_spread_ = 0.0;     // [J] the trapezoidal rule's uncertainty summed over the steps
  double largest_kinetic_ = 0.0, largest_potential_change_ = 0.0;
  double moving_floor_ = 0.0;  // [J] m g0 L, the scale's floor once the boundary has moved
  bool boundary_moved_ = false;
  static constexpr double kStandardGravity = 9.80665;  // [m/s^2], g0
};

}  // namespace

DynamicsOptions DynamicsOptionsFrom(const DynamicsSpec& spec) {
  DynamicsOptions options;
  options.time_step = spec.time_step;
  options.substep = spec.substep;
  options.max_halvings = spec.max_halvings;
  options.error_tolerance = spec.error_tolerance;
  options.min_time_step = spec.min_time_step;
  if (!ParseIntegrator(spec.integrator, &options.integrator))
    throw std::invalid_argument("unknown integrator " + spec.integrator);
  return options;
}

IntegrationStats Integrate(DynamicsStepper& stepper, const Drive& drive, int steps,
                           DynamicState* state, const StepObserver& observe,
                           const SensitivityCarry* sensitivities,
                           const std::function<void(double)>& progress, bool energy_envelope) {
  IntegrationStats stats;
  DynamicState& s = *state;
  DynamicState before;
  std::optional<EnergyEnvelope> envelope;
  if (energy_envelope) envelope.emplace(stepper, drive, s);
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < steps; ++k) {
    before = s;
    const DynamicsStepSummary r = stepper.Step(drive, &s);
    if (!r.ok) {
      stats.reason = "t = " + std::to_string(s.t) + " s: " + r.reason;
      break;
    }
    ++stats.steps;
    if (r.substeps > 1) ++stats.halved_steps;
    stats.newton_iterations += r.newton_iterations;
    if (sensitivities) {
      std::string why;
      if (!stepper.StepSensitivity(drive, before, s, *sensitivities->directions,
                                   sensitivities->ds, &why)) {
        stats.reason = "t = " + std::to_string(s.t) + " s: " + why;
        break;
      }
    }
    if (progress) progress(s.t);
    if (!observe(before, s, r)) break;
    std::string why;
    if (envelope && !envelope->Step(before, s, &why, &stats.energy_excess_ratio)) {
      stats.reason = why;
      break;
    }
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats.ok = stats.reason.empty();
  return stats;
}

}  // namespace rodfit
