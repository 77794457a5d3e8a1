// Motion fit (motion_fit.h): the least-squares fit on the rollout's sensitivities, and the
// derivative-free search it replaced. Fit layer: calls the rollout (solve) only.
#include "rodfit/fit/motion_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>

#include <ceres/ceres.h>
#include <nlopt.hpp>

#include "rodfit/fit/covariance.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_dynamics.h"

namespace rodfit {
namespace {

using Clock = std::chrono::steady_clock;

// The scene at log-parameters `logp`.
Scene SceneAt(const Scene& scene, const std::vector<std::string>& names, const double* logp) {
  Scene s = scene;
  for (size_t k = 0; k < names.size(); ++k) SetMotionParameter(names[k], std::exp(logp[k]), &s);
  return s;
}

// Everything one evaluation of the fit reads, and the rollouts it has spent. The least-squares
// residuals are laid out once (recordings: recording, frame >= 1, marker not driven and seen,
// coordinate; sequences: sequence, recorded sample, coordinate): their number is the same at
// every parameter value.
struct Ctx {
  const Scene* scene = nullptr;
  const std::vector<MotionRecordingData>* recordings = nullptr;
  const std::vector<MarkerSequence>* sequences = nullptr;
  const std::vector<std::string>* names = nullptr;
  const RolloutOptions* options = nullptr;
  const StaticsOptions* statics = nullptr;
  std::vector<ParameterDirection> directions;
  std::vector<std::vector<char>> held;  // per recording, per marker: driven
  double sigma = 1.0;
  int residuals = 0;
  // Fills cached_r, cached_J and cached_mae at a scene (false with last_failure set): the
  // recordings' rollouts or the sequences' case runs.
  std::function<bool(const Scene&, struct Ctx*)> forward;
  int evaluations = 0;
  // The last point evaluated with sensitivities: Ceres evaluates an accepted step's point again
  // for its Jacobian, which costs no second set of rollouts.
  std::vector<double> cached_logp;
  bool cached_ok = false;
  Eigen::VectorXd cached_r;
  Eigen::MatrixXd cached_J;  // residuals x parameters, d r / d log p
  double cached_mae = 0.0;   // the mean over recordings of the predicted markers' MAE
  std::string last_failure;
};

// The predicted markers' mean absolute coordinate error averaged over the recordings (the score
// the held-out data is judged by), at log-parameters `logp`.
double MeanRolloutError(const std::vector<double>& logp, Ctx* c) {
  const Scene s = SceneAt(*c->scene, *c->names, logp.data());
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

// Residuals and their Jacobian at `logp` into the cache (rollouts with sensitivities of every
// recording). False when a rollout or its sensitivities fail there.
bool EvaluateWithSensitivities(const double* logp, Ctx* c) {
  const int m = static_cast<int>(c->names->size());
  const std::vector<double> point(logp, logp + m);
  if (!c->cached_logp.empty() && c->cached_logp == point) return c->cached_ok;
  c->cached_logp = point;
  c->cached_ok = false;
  c->cached_r.setZero(c->residuals);
  c->cached_J.setZero(c->residuals, m);
  const Scene s = SceneAt(*c->scene, *c->names, logp);
  ++c->evaluations;
  if (!c->forward(s, c)) return false;
  c->cached_ok = c->cached_r.allFinite() && c->cached_J.allFinite();
  return c->cached_ok;
}

// The recordings' residuals and Jacobian at scene `s` (rollouts with sensitivities).
bool RecordingsForward(const Scene& s, Ctx* c) {
  int row = 0;
  double mae = 0.0;
  for (size_t ri = 0; ri < c->recordings->size(); ++ri) {
    const MotionRecordingData& rec = (*c->recordings)[ri];
    std::vector<Eigen::MatrixXd> dp;
    RolloutResult out;
    try {
      out = RolloutWithSensitivities(s, rec.frame_interval, rec.frames, *c->options, *c->statics,
                                     c->directions, &dp);
    } catch (const std::runtime_error& e) {
      c->last_failure = e.what();
      return false;
    }
    if (!out.ok || out.predicted.size() != rec.frames.size()) {
      c->last_failure = out.reason;
      return false;
    }
    mae += out.mae_predicted;
    const int M = static_cast<int>(rec.frames[0].cols());
    for (size_t k = 1; k < rec.frames.size(); ++k)
      for (int mk = 0; mk < M; ++mk) {
        if (c->held[ri][mk] || !rec.frames[k].col(mk).allFinite()) continue;
        for (int a = 0; a < 3; ++a, ++row) {
          c->cached_r[row] = (out.predicted[k](a, mk) - rec.frames[k](a, mk)) / c->sigma;
          c->cached_J.row(row) = dp[k].row(3 * mk + a) / c->sigma;
        }
      }
  }
  c->cached_mae = mae / static_cast<double>(c->recordings->size());
  return true;
}

// The sequences' residuals and Jacobian at scene `s` (each case's run with sensitivities).
bool SequencesForward(const Scene& s, Ctx* c) {
  int row = 0;
  double sum_abs = 0.0;
  for (const MarkerSequence& seq : *c->sequences) {
    CaseSamples out;
    try {
      out = SampleCaseDynamics(s, seq.case_index, *c->statics, seq.s, seq.t, c->directions);
    } catch (const std::runtime_error& e) {
      c->last_failure = s.cases[seq.case_index].name + ": " + e.what();
      return false;
    }
    if (!out.ok || out.x.size() != seq.t.size()) {
      c->last_failure = s.cases[seq.case_index].name + ": " + out.reason;
      return false;
    }
    for (const MarkerSequence::Sample& sample : seq.samples)
      for (int a = 0; a < 3; ++a, ++row) {
        const double e = out.x[sample.time](a, sample.marker) - sample.position[a];
        sum_abs += std::abs(e);
        c->cached_r[row] = e / seq.sigma;
        c->cached_J.row(row) = out.dx[sample.time].row(3 * sample.marker + a) / seq.sigma;
      }
  }
  c->cached_mae = sum_abs / static_cast<double>(c->residuals);
  return true;
}

// The least-squares cost for Ceres: one parameter block (the log-parameters), the residuals of
// every recording, the Jacobian from the sensitivities (no numeric differentiation).
class MotionCost : public ceres::CostFunction {
 public:
  MotionCost(Ctx* ctx, int parameters) : ctx_(ctx) {
    set_num_residuals(ctx->residuals);
    mutable_parameter_block_sizes()->push_back(parameters);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    if (!EvaluateWithSensitivities(parameters[0], ctx_)) return false;
    Eigen::Map<Eigen::VectorXd>(residuals, ctx_->residuals) = ctx_->cached_r;
    if (jacobians && jacobians[0]) {
      // Ceres' Jacobian blocks are row-major.
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          jacobians[0], ctx_->residuals, ctx_->cached_J.cols()) = ctx_->cached_J;
    }
    return true;
  }

 private:
  Ctx* ctx_;
};

// Stops the search when its rollout budget is spent, keeping its best point (Ceres returns the
// start values after SOLVER_ABORT); the result then says it did not converge.
class Budget : public ceres::IterationCallback {
 public:
  Budget(const Ctx* ctx, int max_evaluations) : ctx_(ctx), max_(max_evaluations) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return ctx_->evaluations >= max_ ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }

 private:
  const Ctx* ctx_;
  int max_;
};

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

bool MotionFitOptions::Check(std::string* why) const {
  if (max_evaluations < 1) {
    *why = "max_evaluations must be at least 1";
    return false;
  }
  if (!(range > 1.0) || !std::isfinite(range)) {
    *why = "range must be a finite factor > 1";
    return false;
  }
  if (!(marker_sigma >= 0.0) || !std::isfinite(marker_sigma)) {
    *why = "marker_sigma must be a finite length >= 0";
    return false;
  }
  if (!(max_log_std > 0.0)) {
    *why = "max_log_std must be > 0";
    return false;
  }
  return true;
}

// linear_density is the rod's (RodSpec), not a row of the material table: the one name the
// motion fit adds to SetMaterialParameter's.
void SetMotionParameter(const std::string& name, double value, Scene* scene) {
  if (name == "linear_density") {
    scene->rod.linear_density = value;
  } else {
    SetMaterialParameter(name, value, &scene->material);
  }
}

double MotionParameter(const std::string& name, const Scene& scene) {
  return name == "linear_density" ? scene.rod.linear_density
                                  : MaterialParameter(name, scene.material);
}

namespace {

// The start values and each parameter's direction in the model's constants, read off the scene
// scaled by e in it (the same at every value: the constants scale with their parameters); the
// start point x and the log-bounds.
void SetUpParameters(const Scene& scene, const std::vector<std::string>& names,
                     const MotionFitOptions& fit_options, MotionFitResult* result, Ctx* ctx,
                     std::vector<double>* x, std::vector<double>* lo, std::vector<double>* hi) {
  if (names.empty()) throw std::invalid_argument("no parameters to fit");
  std::string why;
  if (!fit_options.Check(&why)) throw std::invalid_argument(why);
  const size_t m = names.size();
  if ((!fit_options.lower.empty() && fit_options.lower.size() != m) ||
      (!fit_options.upper.empty() && fit_options.upper.size() != m))
    throw std::invalid_argument("bounds must be given per fitted parameter");
  result->names = names;
  for (const std::string& name : names) {
    const double v = MotionParameter(name, scene);
    if (!(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument(name + ": a fitted parameter needs a start value > 0 (fitted in "
                                         "log space)");
    result->start.push_back(v);
  }
  for (const std::string& name : names) {
    Scene up = scene;
    SetMotionParameter(name, std::exp(1.0) * MotionParameter(name, scene), &up);
    ctx->directions.push_back(ParameterDirection::Between(
        scene.material, scene.rod.linear_density, up.material, up.rod.linear_density, 1.0));
  }
  x->resize(m);
  lo->resize(m);
  hi->resize(m);
  for (size_t k = 0; k < m; ++k) {
    (*x)[k] = std::log(result->start[k]);
    const double lower = fit_options.lower.empty() ? NAN : fit_options.lower[k];
    const double upper = fit_options.upper.empty() ? NAN : fit_options.upper[k];
    (*lo)[k] = std::isfinite(lower) ? std::log(lower) : (*x)[k] - std::log(fit_options.range);
    (*hi)[k] = std::isfinite(upper) ? std::log(upper) : (*x)[k] + std::log(fit_options.range);
    if (!((*lo)[k] <= (*x)[k] && (*x)[k] <= (*hi)[k] && (*lo)[k] < (*hi)[k]))
      throw std::invalid_argument(names[k] + ": the start value must lie within its bounds");
  }
}

// Levenberg–Marquardt from x within [lo, hi]. False (with the result filled as a failed fit)
// when the forward map fails at the start.
bool SearchLeastSquares(Ctx* ctx, std::vector<double>* x_io, const std::vector<double>& lo,
                        const std::vector<double>& hi, const MotionFitOptions& fit_options,
                        MotionFitResult* result) {
  std::vector<double>& x = *x_io;
  const int m = static_cast<int>(x.size());
  result->method = "levenberg_marquardt";
  if (!EvaluateWithSensitivities(x.data(), ctx)) {
    // Nothing to search from: said so, the start values returned as they are.
    result->values = result->start;
    result->at_bound.assign(m, false);
    result->message = "the rollout fails at the start values: " + ctx->last_failure;
    result->std.assign(m, std::numeric_limits<double>::quiet_NaN());
    result->identifiable.assign(m, false);
    result->reason.assign(m, "not fitted");
    result->evaluations = ctx->evaluations;
    return false;
  }
  result->error_start = ctx->cached_mae;
  result->initial_cost = 0.5 * ctx->cached_r.squaredNorm();
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  problem.AddResidualBlock(new MotionCost(ctx, m), nullptr, x.data());
  for (int k = 0; k < m; ++k) {
    problem.SetParameterLowerBound(x.data(), k, lo[k]);
    problem.SetParameterUpperBound(x.data(), k, hi[k]);
  }
  ceres::Solver::Options so;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = fit_options.max_evaluations;
  // With the residuals in sigmas the cost is ~N/2: a relative change of 1e-8 is ~1e-5 of one
  // unit of chi^2, far below what the data can tell; tighter, a parameter the data do not
  // determine keeps the search creeping along its flat direction.
  so.function_tolerance = 1e-8;
  so.parameter_tolerance = 1e-8;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  Budget budget(ctx, fit_options.max_evaluations);
  so.callbacks.push_back(&budget);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  result->iterations = static_cast<int>(summary.iterations.size()) - 1;
  result->converged = summary.IsSolutionUsable() && summary.termination_type == ceres::CONVERGENCE;
  if (summary.termination_type == ceres::USER_SUCCESS)
    result->message = "stopped at max_evaluations (" + std::to_string(fit_options.max_evaluations) +
                      " rollouts) before converging";
  else
    result->message = summary.message;
  if (!summary.IsSolutionUsable()) result->message = "no usable solution: " + summary.message;
  return true;
}

// The values at x, and the covariance and identifiability there from its Jacobian.
void Uncertainty(Ctx* ctx, std::vector<double>* x_io, const std::vector<double>& lo,
                 const std::vector<double>& hi, const MotionFitOptions& fit_options,
                 MotionFitResult* result) {
  std::vector<double>& x = *x_io;
  const int m = static_cast<int>(x.size());
  result->values.resize(m);
  result->at_bound.resize(m);
  for (int k = 0; k < m; ++k) {
    result->values[k] = std::exp(x[k]);
    result->at_bound[k] = std::abs(x[k] - lo[k]) < 1e-6 || std::abs(x[k] - hi[k]) < 1e-6;
  }
  result->std.assign(m, std::numeric_limits<double>::quiet_NaN());
  result->identifiable.assign(m, false);
  result->reason.assign(m, "no Jacobian at the solution (the rollout fails there)");
  result->covariance_log = Eigen::MatrixXd::Constant(m, m, std::numeric_limits<double>::quiet_NaN());
  result->residuals = ctx->residuals;
  if (EvaluateWithSensitivities(x.data(), ctx)) {
    if (fit_options.method == MotionFitMethod::kLevenbergMarquardt) result->error_fitted = ctx->cached_mae;
    result->residual_variance = ctx->cached_r.squaredNorm() / static_cast<double>(ctx->residuals - m);
    result->final_cost = 0.5 * ctx->cached_r.squaredNorm();
    // The static fit's verdict (covariance.h): its full-rank covariance is Ceres' over a problem
    // at the solution, whose Jacobian is the cached one (no further rollout).
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem at_solution(po);
    at_solution.AddResidualBlock(new MotionCost(ctx, m), nullptr, x.data());
    const fit_internal::Identifiability verdict = fit_internal::Identify(
        ctx->cached_J, result->names, &at_solution, x.data(),
        fit_options.trusted_sigmas ? 1.0 : result->residual_variance, fit_options.max_log_std);
    result->identifiable = verdict.identifiable;
    result->reason = verdict.reason;
    result->covariance_log = verdict.cov_log;
    for (int k = 0; k < m; ++k)
      if (verdict.identifiable[k])
        result->std[k] = result->values[k] * std::sqrt(verdict.cov_log(k, k));  // delta method
  } else if (fit_options.method == MotionFitMethod::kLevenbergMarquardt) {
    result->converged = false;
    result->message = "the rollout fails at the fitted values: " + ctx->last_failure;
  }
  result->evaluations = ctx->evaluations;
}

}  // namespace

MotionFitResult FitMotion(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                          const std::vector<std::string>& names, const RolloutOptions& options,
                          const StaticsOptions& statics, const MotionFitOptions& fit_options) {
  const auto started = Clock::now();
  if (recordings.empty()) throw std::invalid_argument("no recordings");
  MotionFitResult result;
  Ctx ctx;
  std::vector<double> x, lo, hi;
  SetUpParameters(scene, names, fit_options, &result, &ctx, &x, &lo, &hi);
  const int m = static_cast<int>(names.size());
  if (fit_options.method == MotionFitMethod::kLevenbergMarquardt && scene.dynamics &&
      scene.dynamics->integrator != "bdf2" && scene.dynamics->integrator != "backward_euler")
    throw std::invalid_argument("the least-squares motion fit differentiates the bdf2 and "
                                "backward_euler steps, not " + scene.dynamics->integrator +
                                " (set dynamics.integrator, or use the derivative-free search)");
  ctx.scene = &scene;
  ctx.recordings = &recordings;
  ctx.names = &names;
  ctx.options = &options;
  ctx.statics = &statics;
  ctx.forward = RecordingsForward;
  ctx.sigma = fit_options.marker_sigma > 0.0 ? fit_options.marker_sigma : 1.0;
  // The residuals' layout: every coordinate of a marker the rollout does not drive, in every
  // frame after the first that saw it.
  for (const MotionRecordingData& r : recordings) {
    if (r.frames.size() < 2) throw std::invalid_argument("a recording needs at least 2 frames");
    ctx.held.push_back(HeldMarkers(options, static_cast<int>(r.frames[0].cols())));
    for (size_t k = 1; k < r.frames.size(); ++k)
      for (int mk = 0; mk < static_cast<int>(r.frames[k].cols()); ++mk)
        if (!ctx.held.back()[mk] && r.frames[k].col(mk).allFinite()) ctx.residuals += 3;
  }
  if (ctx.residuals <= m)
    throw std::invalid_argument("the recordings have " + std::to_string(ctx.residuals) +
                                " predicted marker coordinates: too few for " +
                                std::to_string(m) + " parameters");

  if (fit_options.method == MotionFitMethod::kBobyqa) {
    result.method = "bobyqa";
    result.error_start = MeanRolloutError(x, &ctx);
    nlopt::opt opt(nlopt::LN_BOBYQA, m);
    opt.set_lower_bounds(lo);
    opt.set_upper_bounds(hi);
    opt.set_maxeval(fit_options.max_evaluations);
    opt.set_xtol_abs(1e-3);  // 0.1 % in each parameter
    opt.set_initial_step(std::vector<double>(m, 0.5));
    opt.set_min_objective(
        [](const std::vector<double>& p, std::vector<double>&, void* data) {
          return MeanRolloutError(p, static_cast<Ctx*>(data));
        },
        &ctx);
    double best = result.error_start;
    nlopt::result status = nlopt::FAILURE;
    try {
      status = opt.optimize(x, best);
    } catch (const nlopt::roundoff_limited&) {
      // The search stopped at round-off: x is its best point.
      status = nlopt::ROUNDOFF_LIMITED;
    }
    result.error_fitted = best;
    result.converged = status == nlopt::XTOL_REACHED || status == nlopt::FTOL_REACHED ||
                       status == nlopt::ROUNDOFF_LIMITED;
    result.message = status == nlopt::MAXEVAL_REACHED
                         ? "stopped at max_evaluations (" +
                               std::to_string(fit_options.max_evaluations) + " rollouts)"
                         : "BOBYQA status " + std::to_string(static_cast<int>(status));
    result.iterations = ctx.evaluations;
  } else if (!SearchLeastSquares(&ctx, &x, lo, hi, fit_options, &result)) {
    result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
    return result;
  }
  Uncertainty(&ctx, &x, lo, hi, fit_options, &result);
  result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return result;
}

namespace {

// The sequences' shared checks: a moving scene with a differentiable integrator, cases and
// samples that exist, times within the run.
void CheckSequences(const Scene& scene, const std::vector<MarkerSequence>& sequences) {
  if (!scene.dynamics) throw std::invalid_argument("marker sequences need a dynamics: block");
  if (sequences.empty()) throw std::invalid_argument("no marker sequences");
  for (const MarkerSequence& seq : sequences) {
    if (seq.case_index < 0 || seq.case_index >= static_cast<int>(scene.cases.size()))
      throw std::invalid_argument("a marker sequence names no case of the scene");
    if (!(seq.sigma > 0.0)) throw std::invalid_argument("a marker sequence needs a sigma > 0");
    for (const MarkerSequence::Sample& sample : seq.samples)
      if (sample.time < 0 || sample.time >= static_cast<int>(seq.t.size()) || sample.marker < 0 ||
          sample.marker >= static_cast<int>(seq.s.size()) || !sample.position.allFinite())
        throw std::invalid_argument("a marker sequence's sample has no time, marker or position");
  }
}

}  // namespace

MotionFitResult FitSequences(const Scene& scene, const std::vector<MarkerSequence>& sequences,
                             const std::vector<std::string>& names, const StaticsOptions& statics,
                             const MotionFitOptions& fit_options) {
  const auto started = Clock::now();
  CheckSequences(scene, sequences);
  if (fit_options.method != MotionFitMethod::kLevenbergMarquardt)
    throw std::invalid_argument("marker sequences are fitted by least squares only");
  if (scene.dynamics->integrator != "bdf2" && scene.dynamics->integrator != "backward_euler")
    throw std::invalid_argument("the motion fit differentiates the bdf2 and backward_euler steps, "
                                "not " + scene.dynamics->integrator + " (set dynamics.integrator)");
  MotionFitResult result;
  Ctx ctx;
  std::vector<double> x, lo, hi;
  SetUpParameters(scene, names, fit_options, &result, &ctx, &x, &lo, &hi);
  ctx.scene = &scene;
  ctx.sequences = &sequences;
  ctx.names = &names;
  ctx.statics = &statics;
  ctx.forward = SequencesForward;
  for (const MarkerSequence& seq : sequences) ctx.residuals += 3 * static_cast<int>(seq.samples.size());
  const int m = static_cast<int>(names.size());
  if (ctx.residuals <= m)
    throw std::invalid_argument("the sequences have " + std::to_string(ctx.residuals) +
                                " recorded marker coordinates: too few for " + std::to_string(m) +
                                " parameters");
  if (SearchLeastSquares(&ctx, &x, lo, hi, fit_options, &result))
    Uncertainty(&ctx, &x, lo, hi, fit_options, &result);
  result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
  return result;
}

SequenceResiduals EvaluateSequences(const Scene& scene, const std::vector<MarkerSequence>& sequences,
                                    const StaticsOptions& statics) {
  CheckSequences(scene, sequences);
  SequenceResiduals out;
  for (const MarkerSequence& seq : sequences) {
    out.error.emplace_back(seq.samples.size(), Eigen::Vector3d::Constant(NAN));
    CaseSamples run;
    try {
      run = SampleCaseDynamics(scene, seq.case_index, statics, seq.s, seq.t, {});
    } catch (const std::runtime_error& e) {
      run.reason = e.what();
    }
    if (!run.ok && out.reason.empty()) out.reason = scene.cases[seq.case_index].name + ": " + run.reason;
    for (size_t k = 0; k < seq.samples.size(); ++k) {
      const MarkerSequence::Sample& sample = seq.samples[k];
      if (sample.time < static_cast<int>(run.x.size()))
        out.error.back()[k] = run.x[sample.time].col(sample.marker) - sample.position;
    }
  }
  out.ok = out.reason.empty();
  return out;
}

MotionFitResult FitToRecordings(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                                const std::vector<std::string>& names, const RolloutOptions& options,
                                const StaticsOptions& statics, int max_evaluations, double range) {
  MotionFitOptions fit_options;
  fit_options.max_evaluations = max_evaluations;
  fit_options.range = range;
  return FitMotion(scene, recordings, names, options, statics, fit_options);
}

}  // namespace rodfit
