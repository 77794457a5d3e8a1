// The one integration loop (docs/architecture.md, "Solvers"): a stepper advanced step by step
// from a state, the held points driven, each step's forward sensitivities propagated when asked,
// and an observer called after every step to record what its caller needs (the frames a scene
// writes, the samples a fit compares, the markers a rollout predicts). Simulate, the sequence
// fit and rollout all integrate through it; the runtime's dynamic ticks take the same stepper's
// steps one per tick.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rodfit/model/scene.h"
#include "rodfit/solve/dynamics.h"

namespace rodfit {

/// The stepper's options from a scene's dynamics block (the one conversion; unknown integrator
/// names throw std::invalid_argument).
DynamicsOptions DynamicsOptionsFrom(const DynamicsSpec& spec);

/// What one integration did.
struct IntegrationStats {
  bool ok = false;
  std::string reason;         ///< why it stopped early ("t = ... s: ..."), empty when it ran
  int steps = 0;              ///< steps taken
  int halved_steps = 0;       ///< implicit steps taken in halves (DynamicsOptions::max_halvings)
  int newton_iterations = 0;  ///< implicit: in all
  double seconds = 0.0;       ///< wall time of the steps
};

/// Called after each step with the state before it and after it and the step's summary; returns
/// false to stop the integration there (ok, no reason).
using StepObserver = std::function<bool(const DynamicState& before, const DynamicState& after,
                                        const DynamicsStepSummary& step)>;

/// Forward sensitivities carried through the steps (DynamicsStepper::StepSensitivity).
struct SensitivityCarry {
  const std::vector<ParameterDirection>* directions = nullptr;
  DynamicSensitivity* ds = nullptr;  ///< started by the caller (EquilibriumSensitivity or zero)
};

/// Takes up to `steps` steps of `stepper` from *state (advanced in place), calling `observe`
/// after each and `progress` (when given) with the simulated time. With `sensitivities`, each
/// step's sensitivities are propagated before the observer sees it. A failed step stops it with
/// the time and the reason.
IntegrationStats Integrate(DynamicsStepper& stepper, const Drive& drive, int steps,
                           DynamicState* state, const StepObserver& observe,
                           const SensitivityCarry* sensitivities = nullptr,
                           const std::function<void(double)>& progress = nullptr);

}  // namespace rodfit
