#include "rodfit/fit/motion_fit.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <nlopt.hpp>

#include "rodfit/model/material_parameters.h"

namespace rodfit {
namespace {

struct Ctx {
  const Scene* scene;
  const std::vector<MotionRecordingData>* recordings;
  const std::vector<std::string>* names;
  const RolloutOptions* options;
  const StaticsOptions* statics;
  int evaluations;
};

// The objective: the predicted markers' mean absolute coordinate error, averaged over the
// recordings (the score the held-out data is judged by), at log-parameters `logp`.
double MeanRolloutError(const std::vector<double>& logp, Ctx* c) {
  Scene s = *c->scene;
  for (size_t k = 0; k < logp.size(); ++k)
    SetMaterialParameter((*c->names)[k], std::exp(logp[k]), &s.material);
  ++c->evaluations;
  double sum = 0.0;
  for (const MotionRecordingData& r : *c->recordings) {
    try {
      const RolloutResult out = Rollout(s, r.frame_interval, r.frames, *c->options, *c->statics);
      if (!out.ok) return 1e3;  // a run that fails is a very bad point, not an error
      sum += out.mae_predicted;
    } catch (const std::runtime_error&) {
      return 1e3;
    }
  }
  return sum / static_cast<double>(c->recordings->size());
}

}  // namespace

namespace {

// The rows a motion sees: the rod's stiffnesses and its damping (springs and the ring are not
// part of a moving thread's model).
const MaterialParameterInfo& MotionRow(const std::string& name) {
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  if (!row || (row->kind != ParameterKind::kRodStiffness && row->kind != ParameterKind::kDamping))
    throw std::invalid_argument("a motion fit cannot fit '" + name.substr(0, 60) + "'");
  return *row;
}

}  // namespace

void SetMaterialParameter(const std::string& name, double value, Material* m) {
  AssignMaterialParameter(MotionRow(name).name, value, m);
}

double MaterialParameter(const std::string& name, const Material& m) {
  return EffectiveMaterialParameter(m, MotionRow(name).name);
}

MotionFitResult FitToRecordings(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                                const std::vector<std::string>& names, const RolloutOptions& options,
                                const StaticsOptions& statics, int max_evaluations, double range) {
  if (names.empty()) throw std::invalid_argument("no parameters to fit");
  if (recordings.empty()) throw std::invalid_argument("no recordings");
  MotionFitResult result;
  result.names = names;
  const int m = static_cast<int>(names.size());
  for (const std::string& name : names) {
    const double v = MaterialParameter(name, scene.material);
    if (!(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument(name + ": a fitted parameter needs a start value > 0 (fitted in "
                                         "log space)");
    result.start.push_back(v);
  }
  Ctx ctx{&scene, &recordings, &names, &options, &statics, 0};
  std::vector<double> x(m), lo(m), hi(m);
  for (int k = 0; k < m; ++k) {
    x[k] = std::log(result.start[k]);
    lo[k] = x[k] - std::log(range);
    hi[k] = x[k] + std::log(range);
  }
  result.error_start = MeanRolloutError(x, &ctx);
  nlopt::opt opt(nlopt::LN_BOBYQA, m);
  opt.set_lower_bounds(lo);
  opt.set_upper_bounds(hi);
  opt.set_maxeval(max_evaluations);
  opt.set_xtol_abs(1e-3);  // 0.1 % in each parameter
  opt.set_initial_step(std::vector<double>(m, 0.5));
  opt.set_min_objective(
      [](const std::vector<double>& p, std::vector<double>&, void* data) {
        return MeanRolloutError(p, static_cast<Ctx*>(data));
      },
      &ctx);
  double best = result.error_start;
  try {
    opt.optimize(x, best);
  } catch (const nlopt::roundoff_limited&) {
    // The search stopped at round-off: x is its best point.
  }
  result.values.resize(m);
  for (int k = 0; k < m; ++k) result.values[k] = std::exp(x[k]);
  result.error_fitted = best;
  result.evaluations = ctx.evaluations;
  return result;
}

}  // namespace rodfit
