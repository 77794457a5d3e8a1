// The time integrators as small classes (docs/architecture.md, "Integrators"). An implicit
// scheme states one step as the incremental potential the one Newton minimizer descends,
//   Phi(q) = a/2 |d - y|^2_M + c/2 |d - z|^2_C + Pi(q) - f . q,   d = q - q_n,
// by its inertia and damping weights a, c and targets y, z (free-dof increments), says where
// Newton starts (its predictor), and turns the converged increment into the new rates and its
// history. The stepper (dynamics.h) owns the loop, the pose of the held points, the assembly and
// the retraction; a scheme owns nothing but its formulas.
//
// Adding a scheme is one new file (integrator_NAME.cc, a class deriving from TimeIntegrator and
// a factory function) plus one line in the registry's table (integrator.cc).
#pragma once

#include <string>
#include <vector>

#include "rodfit/model/rod.h"
#include "rodfit/solve/dynamics.h"

namespace rodfit {

/// The largest ratio of a step to the step before that variable-step BDF2 takes: it is
/// zero-stable below 1 + sqrt(2) (Grigorieff 1983); the adaptive stepper grows steps by at most
/// this factor, and a larger jump restarts the history (backward Euler).
inline constexpr double kMaxStepRatio = 2.0;

/// One step's weights and the state of its history (set by TimeIntegrator::Weights).
struct StepWeights {
  double a = 0.0;  ///< [1/s^2] the inertia's weight
  double c = 0.0;  ///< [1/s] the damping's weight
  /// The unknown is the midpoint q_n+1/2: the held points take the pose halfway through the
  /// step, and the state at its end is carried on by the same increment (implicit midpoint).
  bool midpoint = false;
  /// BDF2 with the step before (its formulas, not backward Euler's), at the step ratio
  /// dt / dt_n-1 (variable-step BDF2; at most kMaxStepRatio).
  bool bdf2 = false;
  double ratio = 0.0;
  /// The predictor is BDF2's third-order extrapolation of the rates (y_ab holds it).
  bool third_order = false;
};

/// The vectors of one step (the stepper's scratch, at the free dofs' size).
struct StepTargets {
  VecX y;          ///< the inertia's target increment
  VecX z;          ///< the damping's target increment
  VecX predictor;  ///< where Newton starts: q_n + predictor
  VecX y_ab;       ///< BDF2: the third-order predictor without the extrapolated corrections
};

class TimeIntegrator {
 public:
  virtual ~TimeIntegrator() = default;
  virtual const char* name() const = 0;
  /// False for an explicit scheme (its step is not a minimization: DynamicsStepper steps it).
  virtual bool implicit() const { return true; }
  /// Forward sensitivities through its steps are implemented (DynamicsStepper::StepSensitivity).
  virtual bool has_sensitivities() const { return false; }
  /// It keeps a history of the last step (DynamicState::last_step, last_v), whose derivatives
  /// the sensitivities then carry.
  virtual bool keeps_history() const { return false; }
  /// The step's weights from the state at its start and the step's length [s].
  virtual StepWeights Weights(const DynamicState& s, double dt) const = 0;
  /// The targets y, z and the predictor of the step (vectors sized on entry).
  virtual void Targets(const DynamicState& s, double dt, const StepWeights& w,
                       const DynamicsOptions& options, StepTargets* t) const = 0;
  /// The rates and history after the step, from its converged increment d (held rows of the
  /// rates zero). For a midpoint scheme the stepper has advanced the state itself.
  virtual void Finish(const StepWeights& w, const VecX& d, const StepTargets& t, double dt,
                      const std::vector<int>& held_rows, DynamicState* s) const = 0;
};

/// The registered scheme of a name (a static instance), or null for an unknown name.
const TimeIntegrator* FindIntegrator(const std::string& name);
/// The registered schemes' names, in the registry's order.
std::vector<std::string> IntegratorNames();

// Factories of the registered schemes (each in its own file).
const TimeIntegrator& BackwardEulerIntegrator();
const TimeIntegrator& MidpointIntegrator();
const TimeIntegrator& Bdf2Integrator();
const TimeIntegrator& StormerVerletIntegrator();

}  // namespace rodfit
