// The one integration loop (integration.h).
#include "rodfit/solve/integration.h"

#include <chrono>
#include <stdexcept>

namespace rodfit {

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
                           const std::function<void(double)>& progress) {
  IntegrationStats stats;
  DynamicState& s = *state;
  DynamicState before;
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
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats.ok = stats.reason.empty();
  return stats;
}

}  // namespace rodfit
