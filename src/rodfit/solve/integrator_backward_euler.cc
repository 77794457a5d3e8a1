// Backward Euler (integrator.h): first order, L-stable, numerically damped.
//   y = dt v_n, z = 0, a = 1 / dt^2, c = 1 / dt;  v_n+1 = d / dt.
#include "rodfit/solve/integrator.h"

namespace rodfit {
namespace {

class BackwardEuler : public TimeIntegrator {
 public:
  const char* name() const override { return "backward_euler"; }
  bool has_sensitivities() const override { return true; }
  StepWeights Weights(const DynamicState&, double dt) const override {
    StepWeights w;
    w.a = 1.0 / (dt * dt);
    w.c = 1.0 / dt;
    return w;
  }
  void Targets(const DynamicState& s, double dt, const StepWeights&, const DynamicsOptions&,
               StepTargets* t) const override {
    t->y = dt * s.v;
    t->z.setZero();
    t->predictor = t->y;
  }
  void Finish(const StepWeights& w, const VecX& d, const StepTargets& t, double,
              const std::vector<int>& held_rows, DynamicState* s) const override {
    const int N = static_cast<int>(d.size());
    for (int k = 0; k < N; ++k) s->v[k] = w.c * (d[k] - t.z[k]);
    for (int r : held_rows) s->v[r] = 0.0;
  }
};

}  // namespace

const TimeIntegrator& BackwardEulerIntegrator() {
  static const BackwardEuler scheme;
  return scheme;
}

}  // namespace rodfit
