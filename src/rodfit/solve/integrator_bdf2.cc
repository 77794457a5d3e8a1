// BDF2 (integrator.h): second order and L-stable, it damps the unresolved stretch modes: the
// robust choice for driven and stiff rods. Steps of any length: with the step ratio
// w = dt / dt_n-1 (Hairer, Norsett & Wanner I, III.5, variable-step BDF2),
//   v_n+1 = c (d - z),   c = (1 + 2w) / ((1 + w) dt),   z = w^2 / (1 + 2w) d_n-1,
// and the same formula for the rates gives the acceleration c (v_n+1 - v_n - z_v), so that
// M a = f becomes Phi's a/2 |d - y|^2_M with
//   a = c^2,   y = z + (v_n + w^2 / (1 + 2w) (v_n - v_n-1)) / c.
// At w = 1: a = 9 / (4 dt^2), c = 3 / (2 dt), z = d_n-1 / 3, y = d_n-1 / 3 + 2 dt (4 v_n - v_n-1)
// / 9. Variable-step BDF2 is zero-stable for w < 1 + sqrt(2) (Grigorieff 1983): beyond
// kMaxStepRatio the history is dropped and the step is backward Euler's, as the first step is.
//   d_n-1 = q_n - q_n-1.
// Newton starts from an extrapolation of the rates (the step's equations do not depend on where
// it starts): q_n + dt (v_n + w (v_n - v_n-1) / 2), second order in dt as BDF2 (dt (3 v_n -
// v_n-1) / 2 at w = 1), leaves about a third of the residual that q_n + y leaves (3.02
// iterations per step fall to 2.78 on the runtime's dragged bowel); with the rates of one more
// step of the same length, the third-order (Adams–Bashforth) dt (23 v_n - 16 v_n-1 + 5 v_n-2) /
// 12 starts nearer still (2.78 to 2.57). What Newton then adds to the predictor, the correction,
// is smooth in time along a steady motion too (DynamicsOptions::extrapolate_corrections): the
// last two corrections, extrapolated linearly, start it nearer still (on the runtime's dragged
// suture, 100 segments at 1 ms, 2.57 solves per step to 2.28).
#include "rodfit/solve/integrator.h"

#include <algorithm>
#include <utility>

namespace rodfit {
namespace {

// extrapolate_corrections: the last two steps' corrections are extrapolated only when they
// differ by at most this fraction of the last one (a steady motion). After a reversal or a jerk
// of the held points the extrapolation points the wrong way, Newton starts further off, and the
// residual test, whose scale is the elastic forces at the start, ends the step further from its
// solution. Measured on the erratic drags of Dynamics.FastStartAndStopFollowErraticDrags:
// without this guard, more iterations than the plain stepper's and trajectories up to 14x further
// from a tightly converged one; with a bound of 0.5, 1.25x further on the jittered circle; with
// 0.25 (and 0.35), as near as the plain stepper's on all five.
constexpr double kSteadyCorrection = 0.25;

class Bdf2 : public TimeIntegrator {
 public:
  const char* name() const override { return "bdf2"; }
  bool has_sensitivities() const override { return true; }
  bool keeps_history() const override { return true; }
  StepWeights Weights(const DynamicState& s, double dt) const override {
    const int N = static_cast<int>(s.v.size());
    StepWeights w;
    const bool history = s.has_history && s.last_step.size() == N && s.last_v.size() == N &&
                         s.last_dt > 0.0;
    const double ratio = history ? dt / s.last_dt : 0.0;
    w.bdf2 = history && ratio <= kMaxStepRatio;
    w.ratio = w.bdf2 ? ratio : 0.0;
    w.c = w.bdf2 ? (1.0 + 2.0 * ratio) / ((1.0 + ratio) * dt) : 1.0 / dt;
    w.a = w.c * w.c;
    // The third-order start needs the two steps before of this same length.
    w.third_order = w.bdf2 && SameStep(s.last_dt, dt) && s.has_older && s.older_v.size() == N;
    return w;
  }
  void Targets(const DynamicState& s, double dt, const StepWeights& w,
               const DynamicsOptions& options, StepTargets* t) const override {
    const int N = static_cast<int>(s.v.size());
    if (w.bdf2) {
      const double r = w.ratio, beta = r * r / (1.0 + 2.0 * r);
      t->z = beta * s.last_step;
      t->y = t->z + (s.v + beta * (s.v - s.last_v)) / w.c;
    } else {
      t->y = dt * s.v;
      t->z.setZero();
    }
    if (w.third_order) {
      t->y_ab = (dt / 12.0) * (23.0 * s.v - 16.0 * s.last_v + 5.0 * s.older_v);
      t->predictor = t->y_ab;
      if (options.extrapolate_corrections && s.num_corrections >= 2 &&
          s.older_correction.size() == N && s.last_correction.size() == N) {
        const double change = (s.last_correction - s.older_correction).lpNorm<Eigen::Infinity>();
        if (change <= kSteadyCorrection * s.last_correction.lpNorm<Eigen::Infinity>())
          t->predictor += 2.0 * s.last_correction - s.older_correction;
      }
    } else if (w.bdf2) {
      t->predictor = dt * (s.v + (0.5 * w.ratio) * (s.v - s.last_v));
    } else {
      t->predictor = t->y;
    }
  }
  void Finish(const StepWeights& w, const VecX& d, const StepTargets& t, double dt,
              const std::vector<int>& held_rows, DynamicState* s) const override {
    // v_n-1 becomes v_n-2 when this step continued a history of the same step.
    const bool same = w.bdf2 && SameStep(s->last_dt, dt);
    if (same) std::swap(s->older_v, s->last_v);  // v_n-1 is now in last_v, overwritten below
    s->has_older = same;
    // This step's correction, if it started from the third-order predictor (swaps and
    // assignments into vectors of the same size: no allocation).
    if (w.third_order) {
      std::swap(s->older_correction, s->last_correction);
      s->last_correction = d - t.y_ab;
      s->num_corrections = std::min(2, s->num_corrections + 1);
    } else {
      s->num_corrections = 0;
    }
    s->last_v = s->v;
    s->last_step = d;
    s->has_history = true;
    s->last_dt = dt;
    const int N = static_cast<int>(d.size());
    for (int k = 0; k < N; ++k) s->v[k] = w.c * (d[k] - t.z[k]);
    for (int r : held_rows) s->v[r] = 0.0;
  }
};

}  // namespace

const TimeIntegrator& Bdf2Integrator() {
  static const Bdf2 scheme;
  return scheme;
}

}  // namespace rodfit
