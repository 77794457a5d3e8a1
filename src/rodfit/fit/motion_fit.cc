// Motion fit (motion_fit.h): the least-squares fit on the rollout's sensitivities, and the
// derivative-free search it replaced; and the fit to observation sequences, whose frames are the
// static observation models (observe) evaluated on the case's trajectory (solve).
#include "rodfit/fit/motion_fit.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <stdexcept>
#include <thread>

#include <ceres/ceres.h>
#include <nlopt.hpp>

#include "rodfit/fit/covariance.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_dynamics.h"

namespace rodfit {
namespace {

using Clock = std::chrono::steady_clock;

// Runs the rest start's search may take (RestStartFromFirstFrames; each a few equilibria, far
// cheaper than one rollout of the recordings).
constexpr int kRestStartRuns = 50;

// The scene at log-parameters `logp` (the material names'), and the fitted rest shape's knots.
struct RestKnots {
  std::vector<double> s;   // [m] the knots, evenly along the rod
  std::vector<double> tau; // [1/m] the scene's rest twist there (not fitted)
  double length = 1.0;     // [m] the unknowns are kappa° L (a turn over the rod's length)
  bool fitted() const { return !s.empty(); }
};

Scene SceneAt(const Scene& scene, const std::vector<std::string>& names, const RestKnots& knots,
              const double* x) {
  Scene s = scene;
  for (size_t k = 0; k < names.size(); ++k) SetMotionParameter(names[k], std::exp(x[k]), &s);
  if (knots.fitted()) {
    const double* y = x + names.size();
    s.rod.rest_curvature_s = knots.s;
    s.rod.rest_curvature_profile.resize(knots.s.size());
    for (size_t j = 0; j < knots.s.size(); ++j)
      s.rod.rest_curvature_profile[j] =
          Vec3(y[2 * j] / knots.length, y[2 * j + 1] / knots.length, knots.tau[j]);
  }
  return s;
}

struct SequencePlan;

// Everything one evaluation of the fit reads, and the rollouts it has spent. The least-squares
// residuals are laid out once (recordings: recording, frame >= 1, marker not driven and seen,
// coordinate; sequences: SequencePlan): their number is the same at every parameter value.
struct Ctx {
  const Scene* scene = nullptr;
  const std::vector<MotionRecordingData>* recordings = nullptr;
  const std::vector<ObservationSequence>* sequences = nullptr;
  const SequencePlan* plan = nullptr;
  const std::vector<std::string>* names = nullptr;  // the material names (log-parameters)
  RestKnots knots;                                    // the rest shape's, when fitted
  int parameters = 0;                                 // names, then 2 per knot (k1, k2)
  // The smoothness prior's rows (after the recordings'): per interior knot and bending
  // component, the second difference of kappa° over its std [1/m].
  int prior_rows = 0;
  double prior_sigma = 1.0;
  const RolloutOptions* options = nullptr;
  const StaticsOptions* statics = nullptr;
  // The grippers' held-frame nuisances (MotionFitOptions::gripper_prior_deg): per recording,
  // kGripperTilts unknowns [rad] from nuisance_first + kGripperTilts * recording (after the
  // material's and the rest shape's, which `directions` differentiate), their prior's rows after
  // the rest shape's. -1: none.
  int nuisance_first = -1;
  double nuisance_sigma = 1.0;  // [rad] the prior's std
  bool nuisances() const { return nuisance_first >= 0; }
  std::vector<ParameterDirection> directions;
  std::vector<std::vector<char>> held;  // per recording, per marker: driven
  // The rest start's problem (RestStartFromFirstFrames): each recording's frame 0 compared (its
  // equilibrium), not its frames >= 1.
  bool first_frames = false;
  double sigma = 1.0;
  int residuals = 0;
  int noise_residuals = 0;  // those that carry noise: the residual variance's count
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
  // The last few points evaluated before the one above, with all it holds: Ceres comes back to
  // points it has evaluated (a line search's first trial after its interpolated one, the
  // accepted point for its Jacobian after a rejected trial, the solution for the covariance),
  // which then cost no second set of rollouts. Measured on the six-recording benchmark: 3 of 15
  // evaluations were such returns.
  struct Evaluation {
    std::vector<double> logp;
    bool ok = false;
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    double mae = 0.0;
    std::string failure;
  };
  static constexpr size_t kRecentEvaluations = 3;
  std::vector<Evaluation> recent;  // oldest first
  // The evaluated point of least cost so far (where the search ends: its covariance is then
  // read without a further set of rollouts).
  Evaluation best;
  // The search's current (last accepted) point, kept by Budget: where Ceres ends after rejected
  // trials, whose covariance would otherwise cost one more set of rollouts when it has left the
  // recent ones and is not the best (a cost that jumps a little between nearby points can
  // make a trial's cost lower than the point Ceres keeps).
  Evaluation accepted;
  // Set when Budget ends the search at the objective's resolution (its rule): the search
  // converged.
  bool resolved = false;
  double run_seconds = 0.0;  // wall time in `forward`
  // Per recording, the adaptive steps of its first rollout, replayed by every later one: the
  // objective and its Jacobian stay smooth in the parameters (a step sequence that changed with
  // them would make the cost jump between a trial and its Jacobian).
  std::vector<StepSchedule> schedules;
  // Per recording, the wall time of its last rollout [s]: the threads take the longest first.
  std::vector<double> recording_seconds;
  StepSchedule* ScheduleOf(size_t recording) {
    if (schedules.size() != recordings->size()) schedules.assign(recordings->size(), StepSchedule());
    StepSchedule& s = schedules[recording];
    if (s.steps.empty()) s.Record(); else s.Replay();
    return &s;
  }
  // "recording NAME: " for a message.
  std::string Named(size_t recording) const {
    const std::string& name = (*recordings)[recording].name;
    return "recording " + (name.empty() ? std::to_string(recording + 1) : name) + ": ";
  }
};

// Per recording, its grippers' tilts: clamp about d1, d2, end about d1, d2 (GripperTiltDerivatives'
// columns), and the step of their central differences [rad] (0.06 degrees: small against the
// prior's degrees, large against the rollout's round-off).
constexpr int kGripperTilts = 4;
constexpr double kGripperTiltStep = 1e-3;

// The rollout options of recording `ri` at unknowns x: the given ones, its grippers' tilts added
// when they are fitted.
RolloutOptions OptionsFor(const Ctx& c, size_t ri, const double* x) {
  RolloutOptions o = *c.options;
  if (!c.nuisances()) return o;
  const double* w = x + c.nuisance_first + kGripperTilts * ri;
  for (int j = 0; j < kGripperTilts; ++j) o.gripper_rotation[j / 2][j % 2] += w[j];
  return o;
}

// The predicted markers' mean absolute coordinate error averaged over the recordings (the score
// the held-out data is judged by), at log-parameters `logp`.
double MeanRolloutError(const std::vector<double>& logp, Ctx* c) {
  const Scene s = SceneAt(*c->scene, *c->names, c->knots, logp.data());
  ++c->evaluations;
  double sum = 0.0;
  for (size_t ri = 0; ri < c->recordings->size(); ++ri) {
    const MotionRecordingData& r = (*c->recordings)[ri];
    try {
      const RolloutResult out = Rollout(s, r.frame_interval, r.frames, *c->options, *c->statics,
                                        c->ScheduleOf(ri));
      if (!out.ok) {  // a run that fails is a very bad point, not an error
        c->last_failure = c->Named(ri) + out.reason;
        return 1e3;
      }
      sum += out.mae_predicted;
    } catch (const std::runtime_error& e) {
      c->last_failure = c->Named(ri) + e.what();
      return 1e3;
    }
  }
  return sum / static_cast<double>(c->recordings->size());
}

// Residuals and their Jacobian at `logp` into the cache (rollouts with sensitivities of every
// recording). False when a rollout or its sensitivities fail there.
bool EvaluateWithSensitivities(const double* logp, Ctx* c) {
  const int m = c->parameters;
  const std::vector<double> point(logp, logp + m);
  if (!c->cached_logp.empty() && c->cached_logp == point) return c->cached_ok;
  // The current point joins the recent ones; a recent one asked for again becomes current.
  Ctx::Evaluation current;
  if (!c->cached_logp.empty()) {
    current.logp = std::move(c->cached_logp);
    current.ok = c->cached_ok;
    current.r = std::move(c->cached_r);
    current.J = std::move(c->cached_J);
    current.mae = c->cached_mae;
    current.failure = c->last_failure;
  }
  const auto again = std::find_if(c->recent.begin(), c->recent.end(),
                                  [&](const Ctx::Evaluation& e) { return e.logp == point; });
  if (again != c->recent.end()) {
    c->cached_logp = std::move(again->logp);
    c->cached_ok = again->ok;
    c->cached_r = std::move(again->r);
    c->cached_J = std::move(again->J);
    c->cached_mae = again->mae;
    c->last_failure = again->failure;
    c->recent.erase(again);
  } else {
    for (const Ctx::Evaluation* kept : {&c->best, &c->accepted})
      if (kept->ok && kept->logp == point) {
        c->cached_logp = kept->logp;
        c->cached_ok = true;
        c->cached_r = kept->r;
        c->cached_J = kept->J;
        c->cached_mae = kept->mae;
        break;
      }
  }
  if (!current.logp.empty()) {
    if (c->recent.size() >= Ctx::kRecentEvaluations) c->recent.erase(c->recent.begin());
    c->recent.push_back(std::move(current));
  }
  if (c->cached_logp == point) return c->cached_ok;
  c->cached_logp = point;
  c->cached_ok = false;
  c->cached_r.setZero(c->residuals);
  c->cached_J.setZero(c->residuals, m);
  const Scene s = SceneAt(*c->scene, *c->names, c->knots, logp);
  ++c->evaluations;
  const auto run_started = Clock::now();
  const bool ran = c->forward(s, c);
  c->run_seconds += std::chrono::duration<double>(Clock::now() - run_started).count();
  if (!ran) return false;
  // A residual that is not finite, or one too large to be squared and summed, is no cost Ceres
  // can compare: said so (an empty reason would leave the message's end blank).
  if (!c->cached_r.allFinite() || !std::isfinite(c->cached_r.squaredNorm())) {
    c->last_failure = "the residuals (model - measured) / sigma overflow (a measurement far too "
                      "large, or a sigma far too small)";
    return false;
  }
  if (!c->cached_J.allFinite()) {
    c->last_failure = "the residuals' derivatives are not finite";
    return false;
  }
  c->cached_ok = true;
  if (!c->best.ok || c->cached_r.squaredNorm() < c->best.r.squaredNorm()) {
    c->best.logp = c->cached_logp;
    c->best.ok = true;
    c->best.r = c->cached_r;
    c->best.J = c->cached_J;
    c->best.mae = c->cached_mae;
  }
  return c->cached_ok;
}

// The frames of a recording whose free markers are compared: 1.. (0 is the start), or the
// rest start's frame 0 alone.
size_t FirstCompared(const Ctx& c) { return c.first_frames ? 0 : 1; }
size_t EndCompared(const Ctx& c, const MotionRecordingData& r) {
  return c.first_frames ? 1 : r.frames.size();
}

// The recordings' residuals' layout: every coordinate of a marker the rollout does not drive,
// in every frame compared that saw it; their number.
int LayOutRecordings(Ctx* c) {
  c->held.clear();
  int rows = 0;
  for (const MotionRecordingData& r : *c->recordings) {
    if (r.frames.size() < 2) throw std::invalid_argument("a recording needs at least 2 frames");
    c->held.push_back(HeldMarkers(*c->options, static_cast<int>(r.frames[0].cols())));
    for (size_t k = FirstCompared(*c); k < EndCompared(*c, r); ++k)
      for (int mk = 0; mk < static_cast<int>(r.frames[k].cols()); ++mk)
        if (!c->held.back()[mk] && r.frames[k].col(mk).allFinite()) rows += 3;
  }
  return rows;
}

// Calls run_one(ri) for every recording ri, in parallel threads (as many as cores, at most one
// per recording). Longest first (by their last rollouts, `seconds`; the first time in order):
// the recordings differ ~3x in cost (a whip's adaptive substeps), and one started last leaves
// the other threads idle at the end (longest-processing-time order, Graham 1969).
template <typename RunOne>
void RunLongestFirst(const std::vector<double>& seconds, const RunOne& run_one) {
  const size_t count = seconds.size();
  const unsigned threads = std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(),
                                                           static_cast<unsigned>(count)));
  if (threads <= 1) {
    for (size_t ri = 0; ri < count; ++ri) run_one(ri);
    return;
  }
  std::vector<size_t> order(count);
  for (size_t ri = 0; ri < count; ++ri) order[ri] = ri;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return seconds[a] > seconds[b]; });
  std::atomic<size_t> next{0};
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t)
    pool.emplace_back([&]() {
      for (size_t k = next++; k < count; k = next++) run_one(order[k]);
    });
  for (std::thread& t : pool) t.join();
}

// The priors' rows after the recordings' (from `row` on): the rest shape's smoothness and the
// held-frame nuisances'.
void AppendPriorRows(Ctx* c, int row) {
  // The rest shape's smoothness prior: (y_j-1 - 2 y_j + y_j+1) / (L sigma) per interior knot
  // and component (y = kappa° L, the unknowns).
  if (c->prior_rows > 0) {
    const int first = static_cast<int>(c->names->size());
    const double w = 1.0 / (c->knots.length * c->prior_sigma);
    const std::vector<double>& y = c->cached_logp;
    for (size_t j = 1; j + 1 < c->knots.s.size(); ++j)
      for (int a = 0; a < 2; ++a, ++row) {
        const int km = first + 2 * static_cast<int>(j - 1) + a, k0 = km + 2, kp = km + 4;
        c->cached_r[row] = w * (y[km] - 2.0 * y[k0] + y[kp]);
        c->cached_J(row, km) = w;
        c->cached_J(row, k0) = -2.0 * w;
        c->cached_J(row, kp) = w;
      }
  }
  // The held-frame nuisances' prior: each tilt over its std.
  if (c->nuisances())
    for (int k = c->nuisance_first; k < c->parameters; ++k, ++row) {
      c->cached_r[row] = c->cached_logp[k] / c->nuisance_sigma;
      c->cached_J(row, k) = 1.0 / c->nuisance_sigma;
    }
}

// The recordings' residuals and Jacobian at scene `s` (rollouts with sensitivities), the
// recordings run in parallel threads (each its own rollout, schedule and rows).
bool RecordingsForward(const Scene& s, Ctx* c) {
  const size_t count = c->recordings->size();
  struct Run {
    RolloutResult out;
    std::vector<Eigen::MatrixXd> dp;
    std::vector<Eigen::MatrixXd> d_tilt;  // the held-frame nuisances' columns (when fitted)
    std::string failure;
  };
  std::vector<Run> runs(count);
  // Schedules are chosen (recorded or replayed) before the threads start.
  std::vector<StepSchedule*> schedules(count);
  for (size_t ri = 0; ri < count; ++ri) schedules[ri] = c->ScheduleOf(ri);
  if (c->recording_seconds.size() != count) c->recording_seconds.assign(count, 0.0);
  auto run_one = [&](size_t ri) {
    const MotionRecordingData& rec = (*c->recordings)[ri];
    Run& run = runs[ri];
    const auto started = Clock::now();
    struct Timed {  // the run's wall time, however it ends
      double* seconds;
      Clock::time_point started;
      ~Timed() { *seconds = std::chrono::duration<double>(Clock::now() - started).count(); }
    } timed{&c->recording_seconds[ri], started};
    try {
      const RolloutOptions options = OptionsFor(*c, ri, c->cached_logp.data());
      run.out = RolloutWithSensitivities(s, rec.frame_interval, rec.frames, options,
                                         *c->statics, c->directions, &run.dp, schedules[ri]);
      if (!run.out.ok || run.out.predicted.size() != rec.frames.size()) {
        run.failure = c->Named(ri) + run.out.reason;
        return;
      }
      std::string why;
      if (c->nuisances() &&
          !GripperTiltDerivatives(s, rec, options, *c->statics, kGripperTiltStep, &run.d_tilt,
                                  &why, schedules[ri]))
        run.failure = c->Named(ri) + "the held frames' derivatives: " + why;
    } catch (const std::exception& e) {
      run.failure = c->Named(ri) + e.what();
    }
  };
  RunLongestFirst(c->recording_seconds, run_one);
  int row = 0;
  double mae = 0.0;
  for (size_t ri = 0; ri < count; ++ri) {
    const Run& run = runs[ri];
    if (!run.failure.empty()) {
      c->last_failure = run.failure;
      return false;
    }
    const MotionRecordingData& rec = (*c->recordings)[ri];
    mae += run.out.mae_predicted;
    const int M = static_cast<int>(rec.frames[0].cols());
    for (size_t k = FirstCompared(*c); k < EndCompared(*c, rec); ++k)
      for (int mk = 0; mk < M; ++mk) {
        if (c->held[ri][mk] || !rec.frames[k].col(mk).allFinite()) continue;
        for (int a = 0; a < 3; ++a, ++row) {
          c->cached_r[row] = (run.out.predicted[k](a, mk) - rec.frames[k](a, mk)) / c->sigma;
          c->cached_J.row(row).head(run.dp[k].cols()) = run.dp[k].row(3 * mk + a) / c->sigma;
          if (c->nuisances())
            c->cached_J.row(row).segment<kGripperTilts>(c->nuisance_first + kGripperTilts * ri) =
                run.d_tilt[k].row(3 * mk + a) / c->sigma;
        }
      }
  }
  AppendPriorRows(c, row);
  c->cached_mae = mae / static_cast<double>(count);
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
  Budget(Ctx* ctx, int max_evaluations, bool trusted_sigmas,
         const std::function<void(const FitIterationInfo&)>& progress)
      : ctx_(ctx), max_(max_evaluations), trusted_(trusted_sigmas), progress_(progress) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& it) override {
    if (progress_) {
      FitIterationInfo info;
      info.iteration = it.iteration;
      info.cost = it.cost;
      info.relative_decrease = it.relative_decrease;
      info.seconds = it.cumulative_time_in_seconds;
      info.budget = max_;
      progress_(info);
    }
    if (it.iteration == 0 || it.step_is_successful) {
      // Ceres has just evaluated its new point again for the Jacobian: the cached one.
      KeepAccepted();
    } else if (WithinConfidenceRegion()) {
      ctx_->resolved = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ctx_->evaluations >= max_ ? ceres::SOLVER_TERMINATE_SUCCESSFULLY : ceres::SOLVER_CONTINUE;
  }

 private:
  void KeepAccepted() {
    Ctx::Evaluation& a = ctx_->accepted;
    a.ok = ctx_->cached_ok;
    a.logp = ctx_->cached_logp;
    a.r = ctx_->cached_r;
    a.J = ctx_->cached_J;
    a.mae = ctx_->cached_mae;
  }
  // The objective's resolution: a rejected trial (the last point evaluated) within the current
  // point's 95 % confidence region, d^T J^T J d <= chi2_m(0.95) s^2 with J the current point's
  // Jacobian, s^2 the residual variance (1 with trusted sigmas) and m the unknowns. The data
  // cannot tell such points apart, yet the cost went up: what it measures at that scale is its
  // own noise (a whip amplifies each step's Newton tolerance, and a trial's replayed substep
  // that fails re-adapts the rest of its recording: the cost jumps by ~1e4 between points 1e-9
  // apart where one sigma moves it by ~1e2), not the data. Shrinking the trust region further
  // spends a set of rollouts per trial on that noise: on the six-recording benchmark 6 of 13,
  // which ended at the point the first rejection left. A smooth objective does not reject
  // such a trial (the suture swing's fits run as before).
  bool WithinConfidenceRegion() const {
    const Ctx::Evaluation& a = ctx_->accepted;
    const int m = static_cast<int>(a.logp.size());
    if (!a.ok || m == 0 || ctx_->cached_logp.size() != a.logp.size() || a.J.cols() != m) return false;
    const int dof = ctx_->noise_residuals - m;
    if (dof <= 0) return false;
    Eigen::VectorXd d(m);
    for (int k = 0; k < m; ++k) d[k] = ctx_->cached_logp[k] - a.logp[k];
    const double variance = trusted_ ? 1.0 : a.r.squaredNorm() / static_cast<double>(dof);
    return d.squaredNorm() > 0.0 && fit_internal::WithinConfidenceRegion(a.J, d, variance);
  }

  Ctx* ctx_;
  int max_;
  bool trusted_;
  const std::function<void(const FitIterationInfo&)>& progress_;
};

}  // namespace

namespace {

// The rows a motion sees (InMotionModel).
const MaterialParameterInfo& MotionRow(const std::string& name) {
  const MaterialParameterInfo* row = FindMaterialParameter(name);
  if (!row || !InMotionModel(*row)) {
    std::string allowed;  // so that a typo is answered with the list
    for (const MaterialParameterInfo& p : MaterialParameters())
      if (InMotionModel(p)) allowed += std::string(allowed.empty() ? "" : ", ") + p.name;
    throw std::invalid_argument("a motion fit cannot fit '" + name.substr(0, 60) + "' (it fits " +
                                allowed + ", " + kRestCurvatureParameter + ")");
  }
  return *row;
}

}  // namespace

double EstimateMarkerNoise(const std::vector<MotionRecordingData>& recordings,
                           const RolloutOptions& options) {
  // The fourth difference in time of a coordinate, x_k-2 - 4 x_k-1 + 6 x_k - 4 x_k+1 + x_k+2:
  // 70 sigma^2 of white noise, and of a smooth motion its fourth derivative times dt^4 (a 4 Hz,
  // 6 cm whip at 100 Hz: 0.4 mm against 8 mm for 1 mm of noise). Its median absolute value,
  // robust to the rest, over 0.6745 sqrt(70).
  std::vector<double> d4;
  for (const MotionRecordingData& r : recordings) {
    if (r.frames.empty()) continue;
    const std::vector<char> held = HeldMarkers(options, static_cast<int>(r.frames[0].cols()));
    for (size_t k = 2; k + 2 < r.frames.size(); ++k)
      for (int m = 0; m < static_cast<int>(r.frames[k].cols()); ++m) {
        if (m < static_cast<int>(held.size()) && held[m]) continue;
        bool seen = true;
        for (size_t j = k - 2; j <= k + 2; ++j)
          seen = seen && r.frames[j].cols() > m && r.frames[j].col(m).allFinite();
        if (!seen) continue;
        const Eigen::Vector3d v = r.frames[k - 2].col(m) - 4.0 * r.frames[k - 1].col(m) +
                                  6.0 * r.frames[k].col(m) - 4.0 * r.frames[k + 1].col(m) +
                                  r.frames[k + 2].col(m);
        for (int a = 0; a < 3; ++a) d4.push_back(std::abs(v[a]));
      }
  }
  if (d4.size() < 30) return 0.0;
  std::nth_element(d4.begin(), d4.begin() + d4.size() / 2, d4.end());
  return d4[d4.size() / 2] / (0.6745 * std::sqrt(70.0));
}

// Where the row says: the material, or the rod (linear_density).
void SetMotionParameter(const std::string& name, double value, Scene* scene) {
  AssignMaterialParameter(MotionRow(name).name, value, &scene->material, &scene->rod);
}

double MotionParameter(const std::string& name, const Scene& scene) {
  return EffectiveMaterialParameter(scene.material, MotionRow(name).name, &scene.rod);
}

namespace {

// Each parameter's direction in the model's constants, read off the scene scaled by e in it (the
// same at every value: the constants scale with their parameters).
std::vector<ParameterDirection> LogDirections(const Scene& scene,
                                              const std::vector<std::string>& names) {
  std::vector<ParameterDirection> directions;
  for (const std::string& name : names) {
    Scene up = scene;
    SetMotionParameter(name, std::exp(1.0) * MotionParameter(name, scene), &up);
    directions.push_back(ParameterDirection::Between(
        scene.material, scene.rod.linear_density, up.material, up.rod.linear_density, 1.0));
  }
  return directions;
}

// The start values and each parameter's direction (LogDirections); the start point x and the
// log-bounds.
void SetUpParameters(const Scene& scene, const std::vector<std::string>& names,
                     const MotionFitOptions& fit_options, MotionFitResult* result, Ctx* ctx,
                     std::vector<double>* x, std::vector<double>* lo, std::vector<double>* hi) {
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
  ctx->directions = LogDirections(scene, names);
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

// The rest shape's unknowns after the log-parameters: kappa° L of (k1°, k2°) at
// fit_options.rest_curvature_knots knots evenly along the rod, started at the scene's profile
// there (its uniform part stays as given; the rest twist is not fitted), within
// +-max_rest_curvature; their directions (a hat on each knot) and the prior's rows.
void AddRestKnots(const Scene& scene, const MotionFitOptions& fit_options,
                  MotionFitResult* result, Ctx* ctx, std::vector<double>* x,
                  std::vector<double>* lo, std::vector<double>* hi) {
  const int K = fit_options.rest_curvature_knots;
  const double L = scene.rod.length;
  if (!(L > 0.0)) throw std::invalid_argument("rest_curvature: the rod has no length");
  RestKnots& knots = ctx->knots;
  knots.length = L;
  for (int j = 0; j < K; ++j) knots.s.push_back(L * j / (K - 1));
  const double bound = fit_options.max_rest_curvature * L;
  for (int j = 0; j < K; ++j) {
    const Vec3 at = RestCurvatureProfileAt(scene.rod.rest_curvature_s,
                                           scene.rod.rest_curvature_profile, knots.s[j]);
    knots.tau.push_back(at[2]);
    for (int a = 0; a < 2; ++a) {
      char name[48];
      std::snprintf(name, sizeof(name), "rest_curvature.k%d[%d]", a + 1, j);
      if (!(std::abs(at[a] * L) <= bound))
        throw std::invalid_argument(std::string(name) + ": the start value must lie within "
                                    "+-max_rest_curvature");
      result->names.push_back(name);
      result->start.push_back(at[a]);
      x->push_back(at[a] * L);
      lo->push_back(-bound);
      hi->push_back(bound);
      // A hat on the knot: d kappa° / d (kappa° L) = 1 / L there.
      ParameterDirection d;
      d.rest_curvature_s = knots.s;
      d.rest_curvature_profile.assign(K, Vec3::Zero());
      d.rest_curvature_profile[j][a] = 1.0 / L;
      ctx->directions.push_back(d);
    }
  }
  result->rest_curvature_s = knots.s;
  ctx->prior_rows = 2 * (K - 2);
  ctx->prior_sigma = fit_options.rest_curvature_smoothness;
  result->prior_residuals = ctx->prior_rows;
}

// The grippers' held-frame nuisances after the other unknowns (MotionFitOptions::
// gripper_prior_deg): per recording, its clamp's and end's tilts about d1 and d2 [rad], started
// at 0 within +-60 degrees (beyond, the markers' pair no longer tells the gripper at all), and
// their prior's rows. Named in `result` until SplitGripperTilts takes them out.
void AddGripperTilts(const std::vector<MotionRecordingData>& recordings,
                     const RolloutOptions& options, const MotionFitOptions& fit_options,
                     MotionFitResult* result, Ctx* ctx, std::vector<double>* x,
                     std::vector<double>* lo, std::vector<double>* hi) {
  if (fit_options.method != MotionFitMethod::kLevenbergMarquardt)
    throw std::invalid_argument("gripper_prior_deg: the held frames' nuisances are fitted by "
                                "least squares only");
  if (options.held_ends == RolloutOptions::HeldEnds::kPinnedPairs)
    throw std::invalid_argument("gripper_prior_deg: the held frames' nuisances need grippers "
                                "(held ends jaws, grippers or free-roll), not pins");
  for (const MotionRecordingData& r : recordings) {
    const int M = r.frames.empty() ? 0 : static_cast<int>(r.frames[0].cols());
    const std::vector<char> held = HeldMarkers(options, M);
    if (M < 5 || !held[1] || !held[M - 2] || !held[M - 1])
      throw std::invalid_argument("gripper_prior_deg: the grippers need markers 0, 1, n-2 and "
                                  "n-1 held (and a marker between them)");
  }
  ctx->nuisance_first = static_cast<int>(x->size());
  ctx->nuisance_sigma = fit_options.gripper_prior_deg * M_PI / 180.0;
  const char* tilt[kGripperTilts] = {"clamp.d1", "clamp.d2", "end.d1", "end.d2"};
  for (size_t r = 0; r < recordings.size(); ++r)
    for (int j = 0; j < kGripperTilts; ++j) {
      result->names.push_back("gripper_tilt[" + std::to_string(r) + "]." + tilt[j]);
      result->start.push_back(0.0);
      x->push_back(0.0);
      lo->push_back(-M_PI / 3.0);
      hi->push_back(M_PI / 3.0);
    }
  result->gripper_prior_residuals = kGripperTilts * static_cast<int>(recordings.size());
}

// The nuisances out of the result's per-name vectors into gripper_rotation_deg and
// gripper_rotation_std_deg (their covariance marginalised: the names' block of it).
void SplitGripperTilts(const Ctx& ctx, size_t recordings, MotionFitResult* result) {
  if (!ctx.nuisances()) return;
  const int first = ctx.nuisance_first;
  const double deg = 180.0 / M_PI;
  auto at = [&](const std::vector<double>& v, int k) {
    return k < static_cast<int>(v.size()) ? v[k] : std::numeric_limits<double>::quiet_NaN();
  };
  for (size_t r = 0; r < recordings; ++r) {
    std::array<Vec3, 2> value{Vec3::Zero(), Vec3::Zero()}, sd{Vec3::Zero(), Vec3::Zero()};
    for (int j = 0; j < kGripperTilts; ++j) {
      const int k = first + kGripperTilts * static_cast<int>(r) + j;
      value[j / 2][j % 2] = deg * at(result->values, k);
      sd[j / 2][j % 2] = deg * at(result->std, k);
    }
    result->gripper_rotation_deg.push_back(value);
    result->gripper_rotation_std_deg.push_back(sd);
  }
  auto cut = [first](auto* v) {
    if (static_cast<int>(v->size()) > first) v->resize(first);
  };
  cut(&result->names);
  cut(&result->start);
  cut(&result->values);
  cut(&result->std);
  cut(&result->identifiable);
  cut(&result->reason);
  cut(&result->at_bound);
  if (result->covariance_log.rows() > first)
    result->covariance_log = Eigen::MatrixXd(result->covariance_log.topLeftCorner(first, first));
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
  ctx->accepted = Ctx::Evaluation();
  ctx->resolved = false;
  Budget budget(ctx, fit_options.max_evaluations, fit_options.trusted_sigmas, fit_options.progress);
  so.callbacks.push_back(&budget);
  ceres::Solver::Summary summary;
  // Ceres' times count from its own start; the fit's began with the first run, just above.
  const double before = ctx->run_seconds;
  ceres::Solve(so, &problem, &summary);
  result->iterations = static_cast<int>(summary.iterations.size()) - 1;
  for (const ceres::IterationSummary& it : summary.iterations) {
    result->cost_per_iteration.push_back(it.cost);
    result->seconds_per_iteration.push_back(before + it.cumulative_time_in_seconds);
  }
  result->converged = summary.IsSolutionUsable() && (summary.termination_type == ceres::CONVERGENCE ||
                                                      ctx->resolved);
  if (ctx->resolved)
    result->message = "converged: a trial step within the parameters' 95 % confidence region raised "
                       "the cost (the objective's resolution)";
  else if (summary.termination_type == ceres::USER_SUCCESS)
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
  const int logs = static_cast<int>(ctx->names->size());  // then the rest shape's kappa° L
  // then the grippers' tilts [rad]
  const int knots_end = ctx->nuisances() ? ctx->nuisance_first : m;
  for (int k = 0; k < m; ++k) {
    result->values[k] = k < logs ? std::exp(x[k]) : k < knots_end ? x[k] / ctx->knots.length : x[k];
    result->at_bound[k] = std::abs(x[k] - lo[k]) < 1e-6 || std::abs(x[k] - hi[k]) < 1e-6;
  }
  result->std.assign(m, std::numeric_limits<double>::quiet_NaN());
  result->identifiable.assign(m, false);
  result->reason.assign(m, "no Jacobian at the solution (the rollout fails there)");
  result->covariance_log = Eigen::MatrixXd::Constant(m, m, std::numeric_limits<double>::quiet_NaN());
  result->residuals = ctx->residuals;
  result->noise_residuals = ctx->noise_residuals;
  if (EvaluateWithSensitivities(x.data(), ctx)) {
    if (fit_options.method == MotionFitMethod::kLevenbergMarquardt) result->error_fitted = ctx->cached_mae;
    result->residual_variance =
        ctx->cached_r.squaredNorm() / static_cast<double>(ctx->noise_residuals - m);
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
    for (int k = 0; k < m; ++k) {
      if (!verdict.identifiable[k]) continue;
      const double s = std::sqrt(verdict.cov_log(k, k));
      // The delta method for a log-parameter; a rest curvature's unknown is kappa° L.
      result->std[k] = k < logs ? result->values[k] * s : k < knots_end ? s / ctx->knots.length : s;
    }
    for (int k = logs; k < knots_end; ++k)
      if (!verdict.identifiable[k] && verdict.reason[k].rfind("determined only within", 0) == 0) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "determined only within %.3g 1/m (a turn of %.3g rad over the rod): its "
                      "effect is below the noise",
                      std::sqrt(verdict.cov_log(k, k)) / ctx->knots.length,
                      std::sqrt(verdict.cov_log(k, k)));
        result->reason[k] = text;
      }
  } else if (fit_options.method == MotionFitMethod::kLevenbergMarquardt) {
    result->converged = false;
    result->message = "the rollout fails at the fitted values: " + ctx->last_failure;
  }
  result->evaluations = ctx->evaluations;
}

// The free markers' mean distance [m] from the frame-0 equilibria in the rest start's cached
// residuals (3 rows a marker, the prior's rows after them).
double FirstFramesMisfit(const Ctx& c) {
  const int markers = (c.residuals - c.prior_rows) / 3;
  double sum = 0.0;
  for (int k = 0; k < markers; ++k) sum += c.cached_r.segment<3>(3 * k).norm();
  return markers > 0 ? c.sigma * sum / markers : 0.0;
}

// The rest knots y (kappa° L) fitted at fixed material logs p to every recording's frame-0 free
// markers, each predicted by the equilibrium the rollout starts from (its held markers at frame
// 0), with the motion fit's smoothness prior, by the least squares above from *y. The recordings
// start at rest, so their first frames show the rest shape bent by gravity and the held ends. At
// one configuration the rest curvature and the stiffness trade off (kappa° = kappa - M / B): the
// fit is the rest shape consistent with the stiffness p, and with `derivative` its change with p
// (dy/dp = -J_y^+ J_p of the frame-0 residuals at the fit, the prior's rows in J_y). Each run is
// every recording's equilibrium with its sensitivities and one frame after it (the rollout's
// start), far cheaper than a rollout of the recordings.
struct FirstFramesFit {
  bool ok = false;
  std::string message;
  int runs = 0;
  double misfit_before = std::numeric_limits<double>::quiet_NaN();  // [m] FirstFramesMisfit
  double misfit_after = std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixXd dy_dp;  // knots' unknowns x material logs
};

FirstFramesFit RestToFirstFrames(const Ctx& ctx, const std::vector<double>& p,
                                 std::vector<double>* y, const std::vector<double>& ylo,
                                 const std::vector<double>& yhi,
                                 const MotionFitOptions& fit_options, bool derivative) {
  FirstFramesFit out;
  const size_t logs = ctx.names->size();
  std::vector<MotionRecordingData> firsts = *ctx.recordings;
  for (MotionRecordingData& r : firsts) r.frames.resize(2);  // the start and its velocity
  const RestKnots scene_rest;  // the material at p; the knots are the unknowns below
  const Scene material = SceneAt(*ctx.scene, *ctx.names, scene_rest, p.data());
  const std::vector<std::string> no_names;
  Ctx sub;
  sub.scene = &material;
  sub.recordings = &firsts;
  sub.names = &no_names;
  sub.knots = ctx.knots;
  sub.parameters = static_cast<int>(y->size());
  sub.prior_rows = ctx.prior_rows;
  sub.prior_sigma = ctx.prior_sigma;
  sub.options = ctx.options;
  sub.statics = ctx.statics;
  sub.directions.assign(ctx.directions.begin() + static_cast<long>(logs), ctx.directions.end());
  sub.sigma = ctx.sigma;
  sub.first_frames = true;
  sub.forward = RecordingsForward;
  const int data_rows = LayOutRecordings(&sub);
  if (data_rows == 0) {
    out.message = "no free marker is seen in a first frame";
    return out;
  }
  sub.residuals = data_rows + sub.prior_rows;
  sub.noise_residuals = sub.residuals;
  MotionFitOptions options = fit_options;
  options.progress = nullptr;
  options.max_evaluations = kRestStartRuns;
  MotionFitResult search;
  search.start.assign(y->size(), 0.0);
  if (EvaluateWithSensitivities(y->data(), &sub)) out.misfit_before = FirstFramesMisfit(sub);
  if (!SearchLeastSquares(&sub, y, ylo, yhi, options, &search)) {
    out.runs = sub.evaluations;
    out.message = search.message;
    return out;
  }
  if (EvaluateWithSensitivities(y->data(), &sub)) out.misfit_after = FirstFramesMisfit(sub);
  out.runs = sub.evaluations;
  out.message = search.message;
  if (derivative) {
    // The frame-0 residuals' Jacobian in the material too, at (p, y).
    Ctx all = sub;
    all.names = ctx.names;
    all.parameters = static_cast<int>(logs + y->size());
    all.directions = ctx.directions;
    all.cached_logp.clear();
    all.recent.clear();
    all.best = Ctx::Evaluation();
    all.evaluations = 0;
    all.scene = ctx.scene;
    std::vector<double> x = p;
    x.insert(x.end(), y->begin(), y->end());
    const bool ran = EvaluateWithSensitivities(x.data(), &all);
    out.runs += all.evaluations;
    if (!ran) {
      out.message = all.last_failure;
      return out;
    }
    const Eigen::MatrixXd Jy = all.cached_J.rightCols(static_cast<long>(y->size()));
    out.dy_dp = -Jy.colPivHouseholderQr().solve(all.cached_J.leftCols(static_cast<long>(logs)));
  }
  out.ok = true;
  return out;
}

// The search before the joint one (variable projection, Golub & Pereyra): the material logs
// alone, the rest knots slaved to them by RestToFirstFrames (each evaluation fits them to the
// first frames at its material, warm-started from the last), the Jacobian the total one,
// J_p + J_y dy/dp. From a straight start 3x too stiff the joint search trades the rest shape
// against the stiffness into another minimum (docs/performance.md, "bench_rest_shape"); along
// the first frames' valley the stiffness is found first, then the joint search refines all from
// there. x's knots become those slaved to its material at the end. Its rollouts count in
// ctx->evaluations.
void SearchWithSlavedRest(Ctx* ctx, std::vector<double>* x, const std::vector<double>& lo,
                          const std::vector<double>& hi, const MotionFitOptions& fit_options,
                          MotionFitResult* result) {
  const size_t logs = ctx->names->size();
  const size_t unknowns = x->size() - logs;
  std::vector<double> p(x->begin(), x->begin() + static_cast<long>(logs));
  std::vector<double> y(x->begin() + static_cast<long>(logs), x->end());
  const std::vector<double> plo(lo.begin(), lo.begin() + static_cast<long>(logs));
  const std::vector<double> phi(hi.begin(), hi.begin() + static_cast<long>(logs));
  const std::vector<double> ylo(lo.begin() + static_cast<long>(logs), lo.end());
  const std::vector<double> yhi(hi.begin() + static_cast<long>(logs), hi.end());
  // The start: the rest shape of the first frames at the start's material.
  const FirstFramesFit first = RestToFirstFrames(*ctx, p, &y, ylo, yhi, fit_options, false);
  result->rest_start_runs += first.runs;
  result->rest_start_misfit_before = first.misfit_before;
  if (!first.ok) {
    result->rest_start_message = "the scene's rest shape kept (its first frames: " +
                                 first.message + ")";
    return;
  }
  result->rest_start_misfit_after = first.misfit_after;
  std::copy(y.begin(), y.end(), x->begin() + static_cast<long>(logs));
  for (size_t k = logs; k < x->size(); ++k) result->start[k] = (*x)[k] / ctx->knots.length;
  if (logs == 0) {
    result->rest_start_message = "the first frames' rest shape: " + first.message;
    return;
  }
  Ctx full = *ctx;  // the joint problem's rollouts, with their own step schedules
  Ctx outer = *ctx;
  outer.knots = RestKnots();  // the knots are not outer's unknowns: `forward` sets them
  outer.parameters = static_cast<int>(logs);
  outer.prior_rows = 0;       // full's rows (its prior's among them) are outer's
  outer.directions.resize(logs);
  std::string inner_failure;
  outer.forward = [&](const Scene&, Ctx* o) {
    const FirstFramesFit f = RestToFirstFrames(*ctx, o->cached_logp, &y, ylo, yhi, fit_options, true);
    result->rest_start_runs += f.runs;
    if (!f.ok) {
      o->last_failure = "the rest shape from the first frames: " + f.message;
      return false;
    }
    full.cached_logp = o->cached_logp;
    full.cached_logp.insert(full.cached_logp.end(), y.begin(), y.end());
    full.cached_r.setZero(full.residuals);
    full.cached_J.setZero(full.residuals, full.parameters);
    const Scene s = SceneAt(*full.scene, *full.names, full.knots, full.cached_logp.data());
    if (!RecordingsForward(s, &full)) {
      o->last_failure = full.last_failure;
      return false;
    }
    o->cached_r = full.cached_r;
    o->cached_J = full.cached_J.leftCols(static_cast<long>(logs)) +
                  full.cached_J.rightCols(static_cast<long>(unknowns)) * f.dy_dp;
    o->cached_mae = full.cached_mae;
    return true;
  };
  MotionFitResult search;
  search.start.assign(logs, 0.0);
  const bool searched = SearchLeastSquares(&outer, &p, plo, phi, fit_options, &search);
  ctx->evaluations += outer.evaluations;
  ctx->run_seconds += outer.run_seconds;
  if (!searched) {
    result->rest_start_message = "the first frames' rest shape (the search with it slaved "
                                 "failed: " + search.message + ")";
    return;
  }
  // The knots slaved to the material found (the last evaluation may have been a rejected trial).
  const FirstFramesFit last = RestToFirstFrames(*ctx, p, &y, ylo, yhi, fit_options, false);
  result->rest_start_runs += last.runs;
  if (!last.ok) {
    result->rest_start_message = "the first frames' rest shape (at the slaved search's material "
                                 "it failed: " + last.message + ")";
    return;
  }
  std::copy(p.begin(), p.end(), x->begin());
  std::copy(y.begin(), y.end(), x->begin() + static_cast<long>(logs));
  result->rest_start_message = "the first frames' rest shape, then the material with it slaved: " +
                               std::to_string(outer.evaluations) + " rollouts, " +
                               std::to_string(search.iterations) + " iterations (" +
                               search.message + ")";
}

}  // namespace

bool GripperTiltDerivatives(const Scene& scene, const MotionRecordingData& recording,
                            const RolloutOptions& options, const StaticsOptions& statics,
                            double step, std::vector<Eigen::MatrixXd>* d_predicted,
                            std::string* why, StepSchedule* schedule) {
  // The engine's sensitivities move the parameters, not a driven clamp's frame: central
  // differences of the whole rollout, one pair per tilt, each on the same steps (the schedule).
  d_predicted->clear();
  const size_t frames = recording.frames.size();
  const int M = frames ? static_cast<int>(recording.frames[0].cols()) : 0;
  std::vector<Eigen::MatrixXd> d(frames, Eigen::MatrixXd::Zero(3 * M, kGripperTilts));
  for (int j = 0; j < kGripperTilts; ++j)
    for (const double sign : {1.0, -1.0}) {
      RolloutOptions o = options;
      o.gripper_rotation[j / 2][j % 2] += sign * step;
      if (schedule) schedule->Replay();
      const RolloutResult r =
          Rollout(scene, recording.frame_interval, recording.frames, o, statics, schedule);
      if (!r.ok || r.predicted.size() != frames) {
        *why = r.reason.empty() ? "the rollout stopped early" : r.reason;
        return false;
      }
      for (size_t k = 0; k < frames; ++k)
        d[k].col(j) += sign / (2.0 * step) *
                       Eigen::Map<const Eigen::VectorXd>(r.predicted[k].data(), 3 * M);
    }
  *d_predicted = std::move(d);
  return true;
}

namespace {

// The material parameters among `names` (log-parameters, in their order); *rest: whether
// "rest_curvature" (the rest shape's knots) is among them. Throws std::invalid_argument for a
// name given twice.
std::vector<std::string> MaterialNames(const std::vector<std::string>& names, bool* rest) {
  std::vector<std::string> material_names;
  for (const std::string& name : names) {
    if (name == kRestCurvatureParameter) {
      if (*rest) throw std::invalid_argument("rest_curvature is named twice");
      *rest = true;
    } else {
      if (std::find(material_names.begin(), material_names.end(), name) != material_names.end())
        throw std::invalid_argument("'" + name.substr(0, 60) + "' is named twice");
      material_names.push_back(name);
    }
  }
  return material_names;
}

// The derivative-free search (MotionFitMethod::kBobyqa): BOBYQA on the predicted markers' mean
// absolute error from x, within [lo, hi]; x left at its best point.
void SearchBobyqa(Ctx* ctx, std::vector<double>* x, const std::vector<double>& lo,
                  const std::vector<double>& hi, const MotionFitOptions& fit_options,
                  MotionFitResult* result) {
  const int m = ctx->parameters;
  result->method = "bobyqa";
  result->error_start = MeanRolloutError(*x, ctx);
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
      ctx);
  double best = result->error_start;
  nlopt::result status = nlopt::FAILURE;
  try {
    status = opt.optimize(*x, best);
  } catch (const nlopt::roundoff_limited&) {
    // The search stopped at round-off: x is its best point.
    status = nlopt::ROUNDOFF_LIMITED;
  }
  result->error_fitted = best;
  result->converged = status == nlopt::XTOL_REACHED || status == nlopt::FTOL_REACHED ||
                      status == nlopt::ROUNDOFF_LIMITED;
  result->message = status == nlopt::MAXEVAL_REACHED
                        ? "stopped at max_evaluations (" +
                              std::to_string(fit_options.max_evaluations) + " rollouts)"
                        : "BOBYQA status " + std::to_string(static_cast<int>(status));
  result->iterations = ctx->evaluations;
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
  bool rest = false;
  const std::vector<std::string> material_names = MaterialNames(names, &rest);
  // The grippers' tilts alone (a calibration of the held frames at given parameters) are a fit too.
  const bool tilts = fit_options.gripper_prior_deg > 0.0;
  if (material_names.empty() && !rest && !tilts) throw std::invalid_argument("no parameters to fit");
  SetUpParameters(scene, material_names, fit_options, &result, &ctx, &x, &lo, &hi);
  if (rest) AddRestKnots(scene, fit_options, &result, &ctx, &x, &lo, &hi);
  // The rest start from the first frames searches the material and knots alone (its unknowns
  // end with the knots): not combined with the tilts.
  if (tilts && rest && fit_options.rest_start_from_first_frames)
    throw std::invalid_argument("gripper_prior_deg: the grippers' tilts are not fitted with "
                                "rest_start_from_first_frames");
  if (tilts) AddGripperTilts(recordings, options, fit_options, &result, &ctx, &x, &lo, &hi);
  ctx.parameters = static_cast<int>(x.size());
  const int m = ctx.parameters;
  if (fit_options.method == MotionFitMethod::kLevenbergMarquardt && scene.dynamics &&
      scene.dynamics->integrator != "bdf2" && scene.dynamics->integrator != "backward_euler")
    throw std::invalid_argument("the least-squares motion fit differentiates the bdf2 and "
                                "backward_euler steps, not " + scene.dynamics->integrator +
                                " (set dynamics.integrator, or use the derivative-free search)");
  ctx.scene = &scene;
  ctx.recordings = &recordings;
  ctx.names = &material_names;
  ctx.options = &options;
  ctx.statics = &statics;
  ctx.forward = RecordingsForward;
  // The markers' noise: as stated, or estimated from the recordings (EstimateMarkerNoise), so
  // that the residuals are in sigmas, the rest shape's prior is weighed against them and the
  // residual variance says whether the model explains the recordings.
  result.marker_sigma = fit_options.marker_sigma;
  if (!(result.marker_sigma > 0.0)) {
    result.marker_sigma = EstimateMarkerNoise(recordings, options);
    result.marker_sigma_estimated = result.marker_sigma > 0.0;
  }
  ctx.sigma = result.marker_sigma > 0.0 ? result.marker_sigma : 1.0;
  const int data_rows = LayOutRecordings(&ctx);
  ctx.residuals = data_rows;
  // The priors' rows (the rest shape's, the grippers' tilts'): rows that carry their noise too.
  ctx.residuals += ctx.prior_rows + result.gripper_prior_residuals;
  ctx.noise_residuals = ctx.residuals;
  if (data_rows <= m)
    throw std::invalid_argument("the recordings have " + std::to_string(data_rows) +
                                " predicted marker coordinates: too few for " +
                                std::to_string(m) + " parameters");

  if (rest && fit_options.rest_start_from_first_frames)
    SearchWithSlavedRest(&ctx, &x, lo, hi, fit_options, &result);

  if (fit_options.method == MotionFitMethod::kBobyqa) {
    SearchBobyqa(&ctx, &x, lo, hi, fit_options, &result);
  } else if (!SearchLeastSquares(&ctx, &x, lo, hi, fit_options, &result)) {
    SplitGripperTilts(ctx, recordings.size(), &result);
    result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
    return result;
  }
  Uncertainty(&ctx, &x, lo, hi, fit_options, &result);
  SplitGripperTilts(ctx, recordings.size(), &result);
  result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
  result.run_seconds = ctx.run_seconds;
  return result;
}

namespace {

// Where each frame of the sequences is evaluated. Each case with sequences is run once per
// evaluation, at every vertex (so that any observation model can be evaluated on the shape) and
// at the union of its sequences' frame times; frame f of sequence q reads time `time` of run
// `run` and writes its residuals from row `row`.
struct SequencePlan {
  struct Run {
    int case_index = 0;
    std::vector<double> s;  // [m] the case's vertex arc lengths
    std::vector<double> t;  // [s] ascending, distinct
    bool reactions = false; // a reaction sequence reads the run's held points
  };
  struct FrameAt {
    int run = 0, time = 0, row = 0;
    int point = -1;  // a reading's: its index among the run's HeldReactions
  };
  std::vector<Run> runs;
  std::vector<std::vector<FrameAt>> frames;  // per sequence, per frame
  int residuals = 0, noise_residuals = 0;
};

// A frame's rows, those that carry noise, and its samples (Measurement::num_samples).
int FrameRows(const ObservationSequence::Frame& f) { return f.measurement->num_residuals(); }
int FrameNoiseRows(const ObservationSequence::Frame& f) {
  return f.measurement->num_noise_residuals();
}
int FrameSamples(const ObservationSequence::Frame& f) { return f.measurement->num_samples(); }

// Whether two frames' measurements are of one type, point and sigma.
bool SameEntry(const Measurement& a, const Measurement& b) {
  if (a.type() != b.type() || a.num_samples() < 1 || b.num_samples() < 1 ||
      a.sample_sigma(0) != b.sample_sigma(0))
    return false;
  const auto* ra = dynamic_cast<const ForceReadings*>(&a);
  const auto* rb = dynamic_cast<const ForceReadings*>(&b);
  if ((ra == nullptr) != (rb == nullptr)) return false;
  if (!ra) return true;
  const ForceMeasurement& fa = ra->readings().front();
  const ForceMeasurement& fb = rb->readings().front();
  return fa.point == fb.point && fa.moment.has_value() == fb.moment.has_value() &&
         (!fa.moment || fa.sigma_moment == fb.sigma_moment);
}

// The point a reaction sequence reads (its readings' one point), or "" for another sequence.
std::string ReadPoint(const Measurement& m) {
  const auto* readings = dynamic_cast<const ForceReadings*>(&m);
  return readings ? readings->readings().front().point : std::string();
}

// The held points of case `index` as the sequences' runs see them (the whole rod, the held
// points where their paths start): HeldReaction::point of each, in HeldReactions' order.
std::vector<std::string> CaseHeldPoints(const Scene& scene, int index) {
  LoadCase whole = CaseAtStart(scene.cases.at(index));
  whole.symmetry.reset();
  const RodModel model(scene.rod, scene.material, scene.gravity, whole, scene.springs);
  std::vector<std::string> points = {"clamp"};
  for (const HeldVertex& h : model.held()) points.push_back(h.Label());
  return points;
}

// The sequences' checks (a moving scene, cases and frames that exist, times within the run,
// one observation type and sigma per sequence, sample numbers that number the samples) and
// their layout.
SequencePlan PlanSequences(const Scene& scene, const std::vector<ObservationSequence>& sequences) {
  if (!scene.dynamics) throw std::invalid_argument("observation sequences need a dynamics: block");
  if (sequences.empty()) throw std::invalid_argument("no observation sequences");
  const double duration = scene.dynamics->duration;
  SequencePlan plan;
  std::vector<int> run_of(scene.cases.size(), -1);
  for (const ObservationSequence& seq : sequences) {
    if (seq.case_index < 0 || seq.case_index >= static_cast<int>(scene.cases.size()))
      throw std::invalid_argument("an observation sequence names no case of the scene");
    if (seq.frames.empty()) throw std::invalid_argument("an observation sequence has no frames");
    int& run = run_of[seq.case_index];
    if (run < 0) {
      run = static_cast<int>(plan.runs.size());
      plan.runs.push_back({seq.case_index, CaseVertexArcLengths(scene, seq.case_index), {}});
    }
    for (const ObservationSequence::Frame& frame : seq.frames)
      if (!frame.measurement)
        throw std::invalid_argument("a frame of an observation sequence must hold a measurement");
    const Measurement& first = *seq.frames.front().measurement;
    const bool numbered = !seq.frames.front().sample.empty();
    std::vector<char> numbered_once(seq.num_samples() > 0 ? seq.num_samples() : 0, 0);
    const std::string first_point = ReadPoint(first);
    if (first.needs_state() || first.needs_section())
      throw std::invalid_argument("a " + first.type() + " sequence: its measurement needs more "
                                  "of the rod than a moving case's vertices and reactions");
    if (first.needs_reactions()) {
      plan.runs[run].reactions = true;
      const std::vector<std::string> points = CaseHeldPoints(scene, seq.case_index);
      if (std::find(points.begin(), points.end(), first_point) == points.end())
        throw std::invalid_argument("a reaction sequence's case holds no '" + first_point + "'");
    }
    for (size_t f = 0; f < seq.frames.size(); ++f) {
      const ObservationSequence::Frame& frame = seq.frames[f];
      const Measurement& meas = *frame.measurement;
      if (first.needs_reactions()) {
        const auto* readings = dynamic_cast<const ForceReadings*>(&meas);
        if (!readings || readings->readings().size() != 1 || !SameEntry(first, meas))
          throw std::invalid_argument("the readings of a reaction sequence differ in point or sigma");
        const ForceMeasurement& reading = readings->readings().front();
        if (!(reading.sigma > 0.0) || (reading.moment && !(reading.sigma_moment > 0.0)))
          throw std::invalid_argument("a reading's sigma (and sigma_moment) must be > 0");
        if (reading.moment && reading.point != "clamp" && reading.point != "end_clamp")
          throw std::invalid_argument("a moment is read only at a clamp, not at " + reading.point);
      } else {
        if (meas.needs_reactions())
          throw std::invalid_argument("the frames of an observation sequence differ in type");
        if (meas.num_vertices() != static_cast<int>(plan.runs[run].s.size()))
          throw std::invalid_argument("a frame's observation is not on the case's " +
                                      std::to_string(plan.runs[run].s.size()) + " vertices");
        if (!SameEntry(first, meas))
          throw std::invalid_argument("the frames of an observation sequence differ in type or sigma");
      }
      if (!(frame.t >= 0.0 && frame.t <= duration * (1.0 + 1e-12)) ||
          (f > 0 && !(frame.t >= seq.frames[f - 1].t)))
        throw std::invalid_argument("frame times must ascend within [0, dynamics.duration]");
      if (numbered != !frame.sample.empty() ||
          (numbered && static_cast<int>(frame.sample.size()) != FrameSamples(frame)))
        throw std::invalid_argument("a frame's sample numbers must be given per measurement, in "
                                    "every frame or in none");
      for (const int k : frame.sample) {
        if (k < 0 || k >= static_cast<int>(numbered_once.size()) || numbered_once[k])
          throw std::invalid_argument("a frame's sample numbers must number the sequence's "
                                      "samples 0.. once each");
        numbered_once[k] = 1;
      }
      plan.runs[run].t.push_back(frame.t);
    }
  }
  for (SequencePlan::Run& run : plan.runs) {
    std::sort(run.t.begin(), run.t.end());
    run.t.erase(std::unique(run.t.begin(), run.t.end()), run.t.end());
  }
  for (const ObservationSequence& seq : sequences) {
    plan.frames.emplace_back();
    const int run = run_of[seq.case_index];
    const std::vector<double>& times = plan.runs[run].t;
    int point = -1;
    if (seq.is_reaction()) {
      const std::vector<std::string> points = CaseHeldPoints(scene, seq.case_index);
      point = static_cast<int>(std::find(points.begin(), points.end(),
                                         ReadPoint(*seq.frames[0].measurement)) -
                               points.begin());
    }
    for (const ObservationSequence::Frame& frame : seq.frames) {
      const int time = static_cast<int>(std::lower_bound(times.begin(), times.end(), frame.t) -
                                        times.begin());
      plan.frames.back().push_back({run, time, plan.residuals, point});
      plan.residuals += FrameRows(frame);
      plan.noise_residuals += FrameNoiseRows(frame);
    }
  }
  return plan;
}

// The sequences' residuals, and with directions their Jacobian d r / d log p, at scene `s`: each
// planned run once, then every frame's observation on the vertices at its time, its vertex
// Jacobian chained with the vertices' sensitivities. The rows of a run or frame that fails stay
// NaN; false with the first failure in *why.
bool SequencesAt(const Scene& s, const SequencePlan& plan,
                 const std::vector<ObservationSequence>& sequences, const StaticsOptions& statics,
                 const std::vector<ParameterDirection>& directions, Eigen::VectorXd* r,
                 Eigen::MatrixXd* J, std::string* why,
                 std::vector<CaseSamples>* samples = nullptr) {
  r->setConstant(plan.residuals, std::numeric_limits<double>::quiet_NaN());
  if (J) J->setConstant(plan.residuals, directions.size(), std::numeric_limits<double>::quiet_NaN());
  bool ok = true;
  auto fail = [&](const std::string& reason) {
    if (ok) *why = reason;
    ok = false;
  };
  std::vector<CaseSamples> runs(plan.runs.size());
  for (size_t k = 0; k < plan.runs.size(); ++k) {
    const SequencePlan::Run& run = plan.runs[k];
    const std::string& name = s.cases[run.case_index].name;
    try {
      runs[k] = SampleCaseDynamics(s, run.case_index, statics, run.s, run.t, directions,
                                   run.reactions);
    } catch (const std::runtime_error& e) {
      fail(name + ": " + e.what());
      continue;
    }
    if (!runs[k].ok) fail(name + ": " + runs[k].reason);
  }
  const int m = static_cast<int>(directions.size());
  std::vector<double> rf, jf;
  for (size_t q = 0; q < sequences.size(); ++q)
    for (size_t f = 0; f < sequences[q].frames.size(); ++f) {
      const SequencePlan::FrameAt& at = plan.frames[q][f];
      const CaseSamples& run = runs[at.run];
      if (at.time >= static_cast<int>(run.x.size())) continue;  // the run stopped before it
      const ObservationSequence::Frame& frame = sequences[q].frames[f];
      const Measurement& meas = *frame.measurement;
      // The case's whole rod at the frame's time: its vertices and, for a reading, its held
      // points' reactions, with their derivatives.
      SolvedCase solved;
      solved.x = &run.x[at.time];
      solved.num_parameters = m;
      if (J) solved.d_x = &run.dx[at.time];
      if (meas.needs_reactions()) {
        solved.reactions = &run.reactions[at.time];
        if (J) solved.d_reactions = &run.d_reactions[at.time];
      }
      const int rows = meas.num_residuals();
      rf.assign(rows, 0.0);
      jf.assign(J ? static_cast<size_t>(rows) * m : 0, 0.0);
      std::string reason;
      if (!meas.Evaluate(solved, rf.data(), J ? jf.data() : nullptr, &reason)) {
        char when[48];
        std::snprintf(when, sizeof(when), " at t = %.9g s", frame.t);
        fail(s.cases[sequences[q].case_index].name + ": " + meas.type() + when +
             ": the rod cannot be observed (a point at or behind the camera)");
        continue;
      }
      using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
      r->segment(at.row, rows) = Eigen::Map<const VecX>(rf.data(), rows);
      if (J) J->middleRows(at.row, rows) = Eigen::Map<const RowMajor>(jf.data(), rows, m);
    }
  if (samples) *samples = std::move(runs);
  return ok;
}

// The sequences' residuals and Jacobian at scene `s` into the cache, and the mean absolute
// residual component in the entries' units.
bool SequencesForward(const Scene& s, Ctx* c) {
  if (!SequencesAt(s, *c->plan, *c->sequences, *c->statics, c->directions, &c->cached_r,
                   &c->cached_J, &c->last_failure))
    return false;
  double sum_abs = 0.0;
  for (size_t q = 0; q < c->sequences->size(); ++q)
    for (size_t f = 0; f < (*c->sequences)[q].frames.size(); ++f) {
      const Measurement& meas = *(*c->sequences)[q].frames[f].measurement;
      for (int k = 0, row = c->plan->frames[q][f].row; k < meas.num_samples(); ++k) {
        const int dim = meas.sample_rows(k);
        sum_abs += meas.sample_sigma(k) * c->cached_r.segment(row, dim).lpNorm<1>();
        row += dim;
      }
    }
  c->cached_mae = sum_abs / static_cast<double>(c->residuals);
  return true;
}

void CheckIntegrator(const Scene& scene) {
  if (scene.dynamics->integrator != "bdf2" && scene.dynamics->integrator != "backward_euler")
    throw std::invalid_argument("the motion fit differentiates the bdf2 and backward_euler steps, "
                                "not " + scene.dynamics->integrator + " (set dynamics.integrator)");
}

}  // namespace

int ObservationSequence::num_samples() const {
  int n = 0;
  for (const Frame& frame : frames)
    if (frame.measurement) n += FrameSamples(frame);
  return n;
}

std::vector<double> CaseVertexArcLengths(const Scene& scene, int index) {
  // As SampleCaseDynamics builds it: the whole rod, the held points where their paths start.
  LoadCase whole = CaseAtStart(scene.cases.at(index));
  whole.symmetry.reset();
  return RodModel(scene.rod, scene.material, scene.gravity, whole, scene.springs).arc_lengths();
}

SequenceEvaluation EvaluateSequenceResiduals(const Scene& scene,
                                             const std::vector<ObservationSequence>& sequences,
                                             const std::vector<std::string>& names,
                                             const StaticsOptions& statics) {
  const SequencePlan plan = PlanSequences(scene, sequences);
  const std::vector<ParameterDirection> directions = LogDirections(scene, names);
  if (!directions.empty()) CheckIntegrator(scene);
  SequenceEvaluation out;
  out.noise_residuals = plan.noise_residuals;
  out.ok = SequencesAt(scene, plan, sequences, statics, directions, &out.residuals,
                       directions.empty() ? nullptr : &out.jacobian, &out.reason);
  return out;
}

MotionFitResult FitSequences(const Scene& scene, const std::vector<ObservationSequence>& sequences,
                             const std::vector<std::string>& names, const StaticsOptions& statics,
                             const MotionFitOptions& fit_options) {
  const auto started = Clock::now();
  const SequencePlan plan = PlanSequences(scene, sequences);
  if (fit_options.method != MotionFitMethod::kLevenbergMarquardt)
    throw std::invalid_argument("observation sequences are fitted by least squares only");
  CheckIntegrator(scene);
  MotionFitResult result;
  Ctx ctx;
  std::vector<double> x, lo, hi;
  if (names.empty()) throw std::invalid_argument("no parameters to fit");
  if (std::find(names.begin(), names.end(), kRestCurvatureParameter) != names.end())
    throw std::invalid_argument("rest_curvature is fitted to marker recordings (rollout --fit), "
                                "not to observation sequences");
  SetUpParameters(scene, names, fit_options, &result, &ctx, &x, &lo, &hi);
  ctx.parameters = static_cast<int>(x.size());
  ctx.scene = &scene;
  ctx.sequences = &sequences;
  ctx.plan = &plan;
  ctx.names = &names;
  ctx.statics = &statics;
  ctx.forward = SequencesForward;
  ctx.residuals = plan.residuals;
  ctx.noise_residuals = plan.noise_residuals;
  const int m = static_cast<int>(names.size());
  if (ctx.noise_residuals <= m)
    throw std::invalid_argument("the sequences have " + std::to_string(ctx.noise_residuals) +
                                " recorded residuals that carry noise: too few for " +
                                std::to_string(m) + " parameters");
  if (SearchLeastSquares(&ctx, &x, lo, hi, fit_options, &result))
    Uncertainty(&ctx, &x, lo, hi, fit_options, &result);
  result.seconds = std::chrono::duration<double>(Clock::now() - started).count();
  result.run_seconds = ctx.run_seconds;
  return result;
}

SequenceResiduals EvaluateSequences(const Scene& scene,
                                    const std::vector<ObservationSequence>& sequences,
                                    const StaticsOptions& statics) {
  const SequencePlan plan = PlanSequences(scene, sequences);
  SequenceEvaluation at;
  std::vector<CaseSamples> runs;
  at.ok = SequencesAt(scene, plan, sequences, statics, {}, &at.residuals, nullptr, &at.reason,
                      &runs);
  SequenceResiduals out;
  out.ok = at.ok;
  out.reason = at.reason;
  for (size_t k = 0; k < plan.runs.size() && k < runs.size(); ++k) {
    FittedRun trajectory;
    trajectory.case_index = plan.runs[k].case_index;
    trajectory.s = plan.runs[k].s;
    // A run that stopped early has fewer states than times: the times it reached.
    trajectory.x = runs[k].x;
    trajectory.t.assign(plan.runs[k].t.begin(),
                        plan.runs[k].t.begin() + std::min(plan.runs[k].t.size(), runs[k].x.size()));
    trajectory.x.resize(trajectory.t.size());
    out.trajectories.push_back(std::move(trajectory));
  }
  int row = 0;
  for (const ObservationSequence& seq : sequences) {
    out.error.emplace_back(seq.num_samples(), Eigen::Vector3d::Constant(NAN));
    int next = 0;  // the sample of a measurement when the frames give no numbers
    for (const ObservationSequence::Frame& frame : seq.frames) {
      const Measurement& meas = *frame.measurement;
      for (int k = 0, k_row = row; k < meas.num_samples(); ++k, ++next) {
        const int dim = meas.sample_rows(k);
        Eigen::Vector3d e = Eigen::Vector3d::Zero();
        e.head(dim) = meas.sample_sigma(k) * at.residuals.segment(k_row, dim);
        out.error.back()[frame.sample.empty() ? next : frame.sample[k]] = e;
        k_row += dim;
      }
      row += FrameRows(frame);
    }
  }
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
