// Störmer–Verlet (leapfrog; the centred difference in time, the suture paper's explicit scheme):
// one gradient per step, stable below 2 / omega_max (DynamicsStepper::StableTimeStep). It is not
// a minimization: DynamicsStepper steps it itself (kick, drift, kick); this class registers it.
#include "rodfit/solve/integrator.h"

namespace rodfit {
namespace {

class StormerVerlet : public TimeIntegrator {
 public:
  const char* name() const override { return "explicit"; }
  bool implicit() const override { return false; }
  StepWeights Weights(const DynamicState&, double) const override { return StepWeights(); }
  void Targets(const DynamicState&, double, const StepWeights&, const DynamicsOptions&,
               StepTargets*) const override {}
  void Finish(const StepWeights&, const VecX&, const StepTargets&, double,
              const std::vector<int>&, DynamicState*) const override {}
};

}  // namespace

const TimeIntegrator& StormerVerletIntegrator() {
  static const StormerVerlet scheme;
  return scheme;
}

}  // namespace rodfit
