// Implicit midpoint (integrator.h): second order, no numerical damping of a linear oscillator
// (unresolved stiff modes keep their energy). The unknown is the midpoint q_m = q_n + d:
//   y = dt v_n / 2, z = 0, a = 4 / dt^2, c = 2 / dt;  q_n+1 = 2 q_m - q_n (the midpoint carried on
// by the same increment, which the stepper does), v_n+1 = 2 v_m - v_n with v_m = 2 d / dt.
#include "rodfit/solve/integrator.h"

namespace rodfit {
namespace {

class Midpoint : public TimeIntegrator {
 public:
  const char* name() const override { return "midpoint"; }
  StepWeights Weights(const DynamicState&, double dt) const override {
    StepWeights w;
    w.a = 4.0 / (dt * dt);
    w.c = 2.0 / dt;
    w.midpoint = true;
    return w;
  }
  void Targets(const DynamicState& s, double dt, const StepWeights&, const DynamicsOptions&,
               StepTargets* t) const override {
    t->y = (0.5 * dt) * s.v;
    t->z.setZero();
    t->predictor = t->y;
  }
  void Finish(const StepWeights&, const VecX& d, const StepTargets&, double dt,
              const std::vector<int>& held_rows, DynamicState* s) const override {
    const int N = static_cast<int>(d.size());
    for (int k = 0; k < N; ++k) s->v[k] = 4.0 * d[k] / dt - s->v[k];
    for (int r : held_rows) s->v[r] = 0.0;
  }
};

}  // namespace

const TimeIntegrator& MidpointIntegrator() {
  static const Midpoint scheme;
  return scheme;
}

}  // namespace rodfit
