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
  /// With the energy envelope: the largest (E - E0 - W) over the envelope's margin of any step
  /// (above 1 the run stopped there).
  double energy_excess_ratio = 0.0;
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

/// The energy envelope of a moving run (docs/solvers.md, "Energy envelope"): the rod's kinetic
/// plus potential energy E = T + Pi (elastic, springs, gravity and the case's dead loads) may not
/// grow beyond its start E0 plus the work W done on it since — by the held points' and clamps'
/// motion and by the loads beyond Pi (a tip load series, a point force, moment loads) — by more
/// than this fraction of the run's energy scale (the largest T, the largest |Pi - Pi0| and the
/// summed |W| of the steps so far) plus round-off (kEnergyEnvelopeRoundOff of the energies'
/// magnitudes). W of a step is the change of Pi its free dofs' motion does not explain, by the
/// trapezoidal rule over the forces at the step's ends, plus the loads' work: the held points'
/// reactions times their displacements, without evaluating the reactions. Damping and the
/// schemes' numerical damping only take energy out (their dissipation is >= 0), so the bound
/// holds for any damping without accounting it. Energy the rod gains beyond it is not physics:
/// an unstable step (an explicit step above its bound), a blow-up of absurd constants.
inline constexpr double kEnergyEnvelopeMargin = 0.05;
inline constexpr double kEnergyEnvelopeRoundOff = 1e-9;

/// Takes up to `steps` steps of `stepper` from *state (advanced in place), calling `observe`
/// after each and `progress` (when given) with the simulated time. With `sensitivities`, each
/// step's sensitivities are propagated before the observer sees it. A failed step stops it with
/// the time and the reason. With `energy_envelope`, a step that leaves the energy envelope
/// (kEnergyEnvelopeMargin) stops it after the observer has seen it, with the time and the
/// energies.
IntegrationStats Integrate(DynamicsStepper& stepper, const Drive& drive, int steps,
                           DynamicState* state, const StepObserver& observe,
                           const SensitivityCarry* sensitivities = nullptr,
                           const std::function<void(double)>& progress = nullptr,
                           bool energy_envelope = false);

}  // namespace rodfit
