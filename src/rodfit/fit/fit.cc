// Identification (fit.h): the Ceres problem, its cost per case, the NLopt global start,
// covariance and identifiability.
#include "rodfit/fit/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/SVD>
#include <ceres/ceres.h>
#include <nlopt.hpp>

#include "rodfit/fit/case_cost.h"
#include "rodfit/fit/covariance.h"
#include "rodfit/fit/measurement.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

using namespace fit_internal;

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitOptions& o, Clock::time_point start) : o_(o), start_(start) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress) {
      FitIterationInfo info;
      info.iteration = s.iteration;
      info.cost = s.cost;
      info.relative_decrease = s.cost > 0 ? s.cost_change / s.cost : 0.0;
      info.seconds = std::chrono::duration<double>(Clock::now() - start_).count();
      o_.progress(info);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitOptions& o_;
  Clock::time_point start_;
};

// Every measured reaction names a point the case holds.
void CheckHeldPoints(const FitInput& in, const FitCase& c) {
  std::vector<const ForceMeasurement*> readings;
  for (const auto& meas : c.measurements)
    if (const auto* forces = dynamic_cast<const ForceReadings*>(meas.get()))
      for (const ForceMeasurement& f : forces->readings()) readings.push_back(&f);
  if (readings.empty()) return;
  std::vector<std::string> points = {"clamp"};
  try {
    const RodModel model(in.rod, in.material, in.gravity, c.load_case, in.springs);
    for (const HeldVertex& h : model.held()) points.push_back(h.Label());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("case " + c.load_case.name + ": " + e.what());
  }
  for (const ForceMeasurement* f : readings) {
    if (std::find(points.begin(), points.end(), f->point) == points.end())
      throw std::invalid_argument("case " + c.load_case.name + ": " + f->label +
                                  ": the case holds no " + f->point);
    if (f->moment && f->point != "clamp" && f->point != "end_clamp")
      throw std::invalid_argument("case " + c.load_case.name + ": " + f->label +
                                  ": a moment is measured only at a clamp");
  }
}

// Solves every case once at the start values, in order, so that a case may start from the
// previous one's solution (`start: previous`) as `simulate` solves it; the solutions become
// the evaluators' warm starts. A case that fails here is left cold (its evaluation reports why).
void WarmStartsAtTheStart(const FitInput& in, const std::vector<Fitted>& fitted,
                          const std::vector<double>& logp,
                          const std::vector<std::unique_ptr<CaseEvaluator>>& evals) {
  Scene scene;
  scene.rod = in.rod;
  scene.material = MaterialAt(in, fitted, logp.data());
  scene.gravity = in.gravity;
  scene.springs = in.springs;
  std::optional<CaseSolution> previous;
  for (size_t c = 0; c < in.cases.size(); ++c) {
    std::optional<CaseSolution> solved;
    try {
      auto model = std::make_shared<const RodModel>(scene.rod, scene.material, scene.gravity,
                                                    in.cases[c].load_case, scene.springs);
      solved = SolveModel(model, scene, previous ? &*previous : nullptr, in.statics, nullptr,
                          nullptr);
    } catch (const std::invalid_argument&) {
    }
    if (solved && solved->ok()) evals[c]->SetWarmStart(solved->state);
    previous = std::move(solved);
  }
}

// Log-space search box of a fitted parameter: its bounds, or three decades around the start.
void SearchBox(const Parameter& p, double* lo, double* hi) {
  *lo = p.min ? std::log(*p.min) : std::log(p.value) - 3.0 * std::log(10.0);
  *hi = p.max ? std::log(*p.max) : std::log(p.value) + 3.0 * std::log(10.0);
}

// Residual counts of a fit: all rows, and those that carry noise.
struct ResidualCounts {
  int total = 0;
  // Those that carry noise (Measurement::num_noise_residuals; a surface point, the closest
  // point on the ring, carries 2 of its 3): without this the residual variance would
  // underestimate the noise and the reported std by up to sqrt(3/2) (points) or sqrt(2)
  // (pixels).
  int effective = 0;
};

ResidualCounts CountResiduals(const FitInput& input) {
  ResidualCounts n;
  for (const FitCase& c : input.cases) {
    for (const auto& meas : c.measurements) {
      n.total += meas->num_residuals();
      n.effective += meas->num_noise_residuals();
    }
  }
  return n;
}

// The start values' logs, checked against their bounds.
std::vector<double> StartLogValues(const FitInput& input, const std::vector<Fitted>& fitted) {
  std::vector<double> logp;
  for (const Fitted& f : fitted) {
    const Parameter& p = input.parameters[f.input_index];
    if (!(p.value > 0)) throw std::invalid_argument(p.name + ": start value must be > 0");
    if (p.min && p.max && !(*p.min < *p.max))
      throw std::invalid_argument(p.name + ": min must be < max");
    if ((p.min && p.value < *p.min) || (p.max && p.value > *p.max))
      throw std::invalid_argument(p.name + ": start value outside [min, max]");
    logp.push_back(std::log(p.value));
  }
  return logp;
}

// The total cost at log-parameters `lp` (ok false, infinite cost, when a case fails).
double TotalCost(const std::vector<std::unique_ptr<CaseEvaluator>>& evals, const double* lp,
                 bool* ok) {
  double cost = 0.0;
  *ok = true;
  for (const auto& e : evals) {
    if (e->num_residuals() == 0) continue;
    VecX r(e->num_residuals());
    if (!e->Evaluate(lp, r.data(), nullptr, nullptr)) {
      *ok = false;
      return std::numeric_limits<double>::infinity();
    }
    cost += 0.5 * r.squaredNorm();
  }
  return cost;
}

// DIRECT-L: a deterministic derivative-free global search over the log box, from which Ceres
// polishes; `logp` becomes its best point (kept when every evaluation failed).
void GlobalSearch(const FitInput& input, const FitOptions& options,
                  const std::vector<Fitted>& fitted,
                  const std::vector<std::unique_ptr<CaseEvaluator>>& evals,
                  Clock::time_point start, std::vector<double>* logp_out, FitResult* result) {
  std::vector<double>& logp = *logp_out;
  const int m = static_cast<int>(fitted.size());
  // Over the material's logs, the nuisances at their priors' mean (0) meanwhile.
  std::vector<double> full(evals.empty() ? m : evals[0]->num_parameters(), 0.0);
  auto total_cost = [&](const double* lp, bool* ok) {
    std::copy(lp, lp + m, full.begin());
    return TotalCost(evals, full.data(), ok);
  };
  const Clock::time_point global_start = Clock::now();
  // DIRECT-L: a deterministic derivative-free global search over the log box; Ceres polishes.
  nlopt::opt opt(nlopt::GN_DIRECT_L, m);
  std::vector<double> lo(m), hi(m);
  for (int k = 0; k < m; ++k) SearchBox(input.parameters[fitted[k].input_index], &lo[k], &hi[k]);
  opt.set_lower_bounds(lo);
  opt.set_upper_bounds(hi);
  opt.set_maxeval(options.global_evaluations);
  struct Ctx {
    decltype(total_cost)* f;
    int evaluations;
    const FitOptions* options;
    Clock::time_point start;
    double best;
  } ctx{&total_cost, 0, &options, start, std::numeric_limits<double>::infinity()};
  opt.set_min_objective(
      [](const std::vector<double>& x, std::vector<double>&, void* data) {
        Ctx* c = static_cast<Ctx*>(data);
        ++c->evaluations;
        bool ok;
        const double v = (*c->f)(x.data(), &ok);
        if (ok) c->best = std::min(c->best, v);
        if (c->options->progress) {
          FitIterationInfo info;
          info.global = true;
          info.iteration = c->evaluations;
          info.budget = c->options->global_evaluations;
          info.cost = c->best;
          info.seconds = std::chrono::duration<double>(Clock::now() - c->start).count();
          c->options->progress(info);
        }
        return ok ? v : 1e30;  // a failed solve is a very bad point, not an error
      },
      &ctx);
  std::vector<double> x(logp.begin(), logp.begin() + m);
  for (int k = 0; k < m; ++k) x[k] = std::min(hi[k], std::max(lo[k], x[k]));
  double best = 0.0;
  try {
    opt.optimize(x, best);
  } catch (const std::exception&) {
    // maxeval reached is reported as success by NLopt; anything else keeps the best so far.
  }
  result->global_evaluations = ctx.evaluations;
  if (best < 1e30) std::copy(x.begin(), x.end(), logp.begin());
  result->global_seconds = std::chrono::duration<double>(Clock::now() - global_start).count();
}

// The failure of an evaluation at the fit's last values, told apart as bad data or a solver
// limit: they call for different fixes. The first case that failed, in case order, whatever
// thread ran it.
std::string EvaluationFailure(const std::vector<std::unique_ptr<CaseEvaluator>>& evals,
                              int iterations) {
  std::string why;
  bool data = false;
  for (const auto& e : evals) {
    bool is_data = false;
    const std::string failure = e->last_failure(&is_data);
    if (why.empty() && !failure.empty()) why = failure, data = is_data;
  }
  const std::string at = iterations <= 0 ? "start" : "fitted";
  if (data) return "bad data: " + why + " at the " + at + " values";
  return "the forward solve fails at the " + at + " values" +
         (why.empty() ? std::string() : " (" + why + ")") +
         ": a solver limit, not bad data (start nearer, or raise solver.max_iterations)";
}

// The weighted Jacobian (log space, after the loss) at the problem's values; empty, with the
// failure in result->message, when an evaluation fails there.
Eigen::MatrixXd JacobianAtSolution(ceres::Problem* problem,
                                   const std::vector<std::unique_ptr<CaseEvaluator>>& evals,
                                   FitResult* result) {
  double cost = 0.0;
  ceres::CRSMatrix crs;
  std::vector<double> res;
  ceres::Problem::EvaluateOptions eo;
  Eigen::MatrixXd J;
  if (!problem->Evaluate(eo, &cost, &res, nullptr, &crs)) {
    result->success = false;
    result->message = EvaluationFailure(evals, result->iterations);
    return J;
  }
  J.setZero(crs.num_rows, crs.num_cols);
  for (int i = 0; i < crs.num_rows; ++i)
    for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) J(i, crs.cols[k]) = crs.values[k];
  return J;
}

// Every parameter of the model, fitted or not, into result->parameters.
void ReportParameters(const FitInput& input, const std::vector<Fitted>& fitted,
                      const std::vector<double>& logp, const Identifiability& id,
                      FitResult* result) {
  const int m = static_cast<int>(fitted.size());
  const std::vector<bool>& identifiable = id.identifiable;
  const std::vector<std::string>& reason = id.reason;
  const Eigen::MatrixXd& cov_log = id.cov_log;
  const Material final_material = MaterialAt(input, fitted, logp.data());
  for (size_t k = 0; k < input.parameters.size(); ++k) {
    const Parameter& p = input.parameters[k];
    Parameter e;
    e.name = p.name;
    e.value = p.value;
    e.start = p.value;
    e.fit = p.fit;
    e.min = p.min;
    e.max = p.max;
    for (int f = 0; f < m; ++f) {
      if (fitted[f].input_index != static_cast<int>(k)) continue;
      e.value = std::exp(logp[f]);
      e.identifiable = identifiable[f];
      e.reason = reason[f];
      if (identifiable[f]) e.std = e.value * std::sqrt(cov_log(f, f));  // delta method
      e.at_bound = (p.min && std::abs(logp[f] - std::log(*p.min)) < 1e-6) ||
                   (p.max && std::abs(logp[f] - std::log(*p.max)) < 1e-6);
      result->fitted_names.push_back(p.name);
    }
    // A tied row held in the fit reports the value it follows (B2 = B1 when isotropic).
    const MaterialParameterInfo* row = FindMaterialParameter(p.name);
    if (row && row->tied_to && !p.fit && !MaterialParameterValue(input.material, p.name))
      e.value = EffectiveMaterialParameter(final_material, p.name);
    result->parameters.push_back(e);
  }
}

// Shapes, poked sections and RMS per observation at the fitted parameters, and every
// measurement's residual. Without the robust loss, so that the reported misfit is in
// measurement units; from each case's last state, the equilibrium the fit followed rather than
// one a cold start might find instead.
void ReportCases(const FitInput& input, const std::vector<Fitted>& fitted,
                 const std::vector<double>& logp,
                 const std::vector<std::unique_ptr<CaseEvaluator>>& evals, FitResult* result) {
  for (size_t c = 0; c < evals.size(); ++c) {
    Mat3X shape;
    CaseEvaluator plain(input, static_cast<int>(c), fitted, nullptr);
    if (const std::optional<RodState> warm = evals[c]->WarmState()) plain.SetWarmStart(*warm);
    VecX rr(std::max(1, plain.num_residuals()));
    RodState state;
    if (!plain.Evaluate(logp.data(), rr.data(), nullptr, &shape, &state)) continue;
    result->shapes.push_back(shape);
    const FitCase& fc = input.cases[c];
    // The poked section at the fit, for the report's measured-versus-fitted section plot.
    Eigen::Matrix3Xd rest_ring, ring, tube;
    std::vector<Eigen::Vector3i> triangles;
    if (fc.load_case.poke && input.section) {
      try {
        const Material material = MaterialAt(input, fitted, logp.data());
        const RodModel model(input.rod, material, input.gravity, fc.load_case, input.springs);
        const PokeResult poke =
            SolvePoke(model, state, *input.section,
                      RingStiffness{material.ring_bend_stiffness, material.ring_stretch_stiffness});
        if (poke.ring.summary.converged) {
          rest_ring = poke.rest_world;
          ring = poke.deformed_world;
          // The dented tube, for the report's 3-D view.
          TubeMesh mesh = PokedTube(model, state, *input.section, poke);
          tube = std::move(mesh.vertices);
          triangles = std::move(mesh.triangles);
        }
      } catch (const std::invalid_argument&) {
        // No section to show; the residuals above already count this case.
      }
    }
    result->rest_sections.push_back(rest_ring);
    result->sections.push_back(ring);
    result->tube_vertices.push_back(std::move(tube));
    result->tube_triangles.push_back(std::move(triangles));
    // Every measurement's misfit in its unit, from the case's weighted residuals.
    int offset = 0;
    for (const auto& meas : fc.measurements) {
      ObservationFit of;
      of.case_index = static_cast<int>(c);
      of.case_name = fc.load_case.name;
      of.label = meas->label();
      of.type = meas->type();
      of.unit = meas->unit();
      of.num_measurements = meas->num_measurements();
      meas->Summarise(shape, rr.data() + offset, &of, &result->measurement_residuals);
      result->observations.push_back(of);
      offset += meas->num_residuals();
    }
  }
}

}  // namespace

bool FitOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(loss_scale > 0)) return fail("loss_scale must be > 0");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (global_evaluations < 1) return fail("global_evaluations must be >= 1");
  if (num_threads < 1) return fail("num_threads must be >= 1");
  if (!(max_log_std > 0)) return fail("max_log_std must be > 0");
  return true;
}

VarianceBand ResidualVarianceBand(int dof) {
  // Wilson–Hilferty: (chi2 / dof)^(1/3) is nearly normal with mean 1 - 2/(9 dof) and variance
  // 2/(9 dof). z = 3.0902 is the normal's 99.9 % quantile.
  const double nu = std::max(1, dof), z = 3.090232306167813;
  const double mean = 1.0 - 2.0 / (9.0 * nu), sd = std::sqrt(2.0 / (9.0 * nu));
  const double low = std::max(0.0, mean - z * sd), high = mean + z * sd;
  return {low * low * low, high * high * high};
}

ResidualCheck CheckResiduals(const FitResult& result, const FitOptions& options) {
  ResidualCheck c;
  c.band = ResidualVarianceBand(result.residual_dof);
  const double v = result.residual_variance;
  c.above = v > c.band.high;
  // Under a robust loss the cost understates the squared residuals: only too large counts.
  c.below = options.trusted_sigmas && options.loss == RobustLoss::kNone && v < c.band.low;
  c.gross = options.trusted_sigmas ? c.above : v > kGrossResidualVariance;
  return c;
}

bool EvaluateForwardMap(const FitInput& input, const std::vector<double>& log_values,
                        Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian) {
  const std::vector<Fitted> fitted = FittedParameters(input);
  const size_t columns = fitted.size() + NuisanceColumns(Nuisances(input, 0));
  if (log_values.size() != columns) throw std::invalid_argument("log_values size");
  int total = 0;
  std::vector<std::unique_ptr<CaseEvaluator>> evals;
  for (size_t c = 0; c < input.cases.size(); ++c) {
    evals.push_back(std::make_unique<CaseEvaluator>(input, static_cast<int>(c), fitted, nullptr));
    total += evals.back()->num_residuals();
  }
  const int m = static_cast<int>(columns);
  residuals->resize(total);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(total, m);
  int row = 0;
  for (auto& e : evals) {
    if (!e->Evaluate(log_values.data(), residuals->data() + row,
                     jacobian ? J.data() + row * m : nullptr, nullptr))
      return false;
    row += e->num_residuals();
  }
  if (jacobian) *jacobian = J;
  return true;
}

namespace {

// The fit's problem over x (the material's logs with their bounds, then the nuisances): every
// case's rows and the nuisances' prior rows. With `material_only`, over the material's logs
// alone, the nuisances held where x has them.
struct ProblemMaker {
  const FitInput& input;
  const std::vector<Fitted>& fitted;
  const std::vector<Nuisance>& nuisances;
  const std::vector<const CaseEvaluator*>& observed;
  int num_threads;
  int m, M;  // the material's columns, all columns
  std::unique_ptr<ceres::Problem> operator()(std::vector<double>* x, bool material_only) const {
    ceres::Problem::Options problem_options;
    problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    auto problem = std::make_unique<ceres::Problem>(problem_options);
    problem->AddParameterBlock(x->data(), material_only ? m : M);
    for (int k = 0; k < m; ++k) {
      const Parameter& p = input.parameters[fitted[k].input_index];
      if (p.min) problem->SetParameterLowerBound(x->data(), k, std::log(*p.min));
      if (p.max) problem->SetParameterUpperBound(x->data(), k, std::log(*p.max));
    }
    if (material_only) {
      problem->AddResidualBlock(
          new MaterialOnlyCost(std::make_unique<AllCasesCost>(observed, num_threads), m,
                               std::vector<double>(x->begin() + m, x->end())),
          nullptr, x->data());
      return problem;
    }
    problem->AddResidualBlock(new AllCasesCost(observed, num_threads), nullptr, x->data());
    for (const Nuisance& n : nuisances)
      problem->AddResidualBlock(new NuisancePriorCost(n, M), nullptr, x->data());
    return problem;
  }
};

// One path of the fit from x: its problem, where it ended and its iterations' costs.
struct FitPath {
  std::vector<double> x;
  std::unique_ptr<ceres::Problem> problem;
  ceres::Solver::Summary summary;
  double initial_cost = 0.0;
  std::vector<double> costs, seconds;
  bool usable() const { return summary.IsSolutionUsable() && std::isfinite(summary.final_cost); }
};

// The fit from x, all columns together; `staged`: the material's alone first, the nuisances
// held, then all together from there (one cost history, times since `start`).
FitPath RunPath(const ceres::Solver::Options& so, const ProblemMaker& make_problem,
                Clock::time_point start, std::vector<double> x, bool staged) {
  FitPath path;
  path.x = std::move(x);
  if (staged) {
    const std::unique_ptr<ceres::Problem> material = make_problem(&path.x, true);
    ceres::Solver::Summary first;
    const double at = std::chrono::duration<double>(Clock::now() - start).count();
    ceres::Solve(so, material.get(), &first);
    path.initial_cost = first.initial_cost;
    for (const ceres::IterationSummary& it : first.iterations) {
      path.costs.push_back(it.cost);
      path.seconds.push_back(at + it.cumulative_time_in_seconds);
    }
  }
  path.problem = make_problem(&path.x, false);
  const double at = std::chrono::duration<double>(Clock::now() - start).count();
  ceres::Solve(so, path.problem.get(), &path.summary);
  if (!staged) path.initial_cost = path.summary.initial_cost;
  for (const ceres::IterationSummary& it : path.summary.iterations) {
    if (staged && &it == &path.summary.iterations.front()) continue;  // the stage's end
    path.costs.push_back(it.cost);
    path.seconds.push_back(at + it.cumulative_time_in_seconds);
  }
  return path;
}

// The fit's Ceres options (the cases run in parallel inside AllCasesCost, in a fixed order).
ceres::Solver::Options SolverOptions(const FitOptions& options) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = 1;
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-10;
  so.gradient_tolerance = 1e-14;
  so.logging_type = ceres::SILENT;
  return so;
}

// The final cost, and whether the fit converged, with its message.
void ReportTermination(const ceres::Solver::Summary& summary, FitResult* result) {
  result->final_cost = summary.final_cost;
  result->message = summary.message;
  result->success = summary.IsSolutionUsable() && summary.termination_type == ceres::CONVERGENCE;
  if (!summary.IsSolutionUsable() || !std::isfinite(summary.final_cost)) {
    result->success = false;
    result->message = "no usable solution: " + summary.message;
  } else if (summary.termination_type == ceres::NO_CONVERGENCE) {
    result->message = "did not converge within max_iterations: " + summary.message;
  }
}

// The names of the fit's columns: the material's parameters, then each nuisance's components.
std::vector<std::string> ColumnNames(const FitInput& input, const std::vector<Fitted>& fitted,
                                     const std::vector<Nuisance>& nuisances) {
  std::vector<std::string> names;
  for (const Fitted& f : fitted) names.push_back(f.name);
  for (const Nuisance& n : nuisances)
    for (int k = 0; k < n.size(); ++k)
      names.push_back("case " + input.cases[n.case_index].load_case.name + " " + n.Name() +
                      (n.kind == Nuisance::Kind::kPosition ? " offset " : " rotation ") +
                      (n.kind == Nuisance::Kind::kGravity ? (k == 0 ? "b1" : "b2")
                                                          : std::string(1, "xyz"[k])));
  return names;
}

// The nuisances: values and std per world axis, [deg] or [m] (the std from the whole covariance
// cov_log, NaN where the fit could not separate them). Gravity's two angles about b1, b2 are
// reported as the rotation vector B (a, b) with the covariance B C B^T (0 along gravity).
void ReportNuisances(const FitInput& input, const std::vector<Nuisance>& nuisances,
                     const std::vector<double>& logp, const Eigen::MatrixXd& cov_log,
                     FitResult* out) {
  FitResult& result = *out;
  for (const Nuisance& n : nuisances) {
    NuisanceEstimate e;
    e.case_index = n.case_index;
    e.case_name = input.cases[n.case_index].load_case.name;
    e.held = n.Name();
    const bool offset = n.kind == Nuisance::Kind::kPosition;
    const double scale = offset ? 1.0 : 180.0 / M_PI;
    e.quantity = offset ? "offset" : "rotation";
    e.unit = offset ? "m" : "deg";
    e.prior = n.sigma * scale;
    Eigen::MatrixXd B = Eigen::MatrixXd::Identity(3, 3);
    if (n.kind == Nuisance::Kind::kGravity) B = GravityTiltBasis(input.gravity);
    const Eigen::VectorXd v =
        B * Eigen::Map<const Eigen::VectorXd>(logp.data() + n.first_column, n.size());
    const Eigen::MatrixXd C =
        B * cov_log.block(n.first_column, n.first_column, n.size(), n.size()) * B.transpose();
    for (int i = 0; i < 3; ++i) {
      e.value[i] = v[i] * scale;
      e.std[i] = std::sqrt(std::max(0.0, C(i, i))) * scale;
      if (std::isnan(C(i, i))) e.std[i] = std::numeric_limits<double>::quiet_NaN();
    }
    result.nuisances.push_back(e);
  }
}

// A case's time spent, added to the fit's.
void AddTiming(const CaseEvaluator::Timing& t, FitResult* result) {
  result->solve_seconds += t.solve;
  result->jacobian_seconds += t.jacobian;
  result->observation_seconds += t.observation;
  result->forward_solves += t.solves;
}

}  // namespace

FitResult Fit(const FitInput& input, const FitOptions& options) {
  const Clock::time_point start = Clock::now();
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("fit options: " + why);
  const std::vector<Fitted> fitted = FittedParameters(input);
  if (fitted.empty()) throw std::invalid_argument("parameters: nothing to fit (no `fit: true`)");
  const int m = static_cast<int>(fitted.size());
  // The parameter vector: the material's logs, then every case's nuisances (their priors'
  // residuals are rows of the fit like any measurement's: counted in N and in the chi-square).
  const std::vector<Nuisance> nuisances = Nuisances(input, m);
  const int M = m + NuisanceColumns(nuisances);
  std::vector<double> logp = StartLogValues(input, fitted);
  logp.resize(M, 0.0);
  ResidualCounts counts = CountResiduals(input);
  for (const FitCase& c : input.cases) CheckHeldPoints(input, c);
  if (counts.total == 0) throw std::invalid_argument("cases: no observations to fit");
  counts.total += NuisanceColumns(nuisances);
  counts.effective += NuisanceColumns(nuisances);
  if (counts.total <= M)
    throw std::invalid_argument("cases: fewer residuals than fitted parameters");

  const std::unique_ptr<ceres::LossFunction> loss = MakeLoss(options.loss, options.loss_scale);
  std::vector<std::unique_ptr<CaseEvaluator>> evals;
  for (size_t c = 0; c < input.cases.size(); ++c) {
    evals.push_back(
        std::make_unique<CaseEvaluator>(input, static_cast<int>(c), fitted, loss.get()));
    evals.back()->ComputeFixedColumns(options.jacobian_of_fixed_parameters);
  }
  WarmStartsAtTheStart(input, fitted, logp, evals);

  FitResult result;
  if (options.global) GlobalSearch(input, options, fitted, evals, start, &logp, &result);

  std::vector<const CaseEvaluator*> observed;
  for (auto& e : evals)
    if (e->num_residuals() > 0) observed.push_back(e.get());
  const ProblemMaker make_problem{input, fitted, nuisances, observed, options.num_threads, m, M};
  ceres::Solver::Options so = SolverOptions(options);
  ProgressCallback callback(options, start);
  so.callbacks.push_back(&callback);
  // With nuisances, two paths, and the one that ends lower: all together from the start, and the
  // material first with every nuisance at its prior's mean (0; the global search's order), then
  // all together from there. Neither order is right for every experiment: from a start 3x too
  // soft, the joint path can let a nuisance hold the rod up (a gravity tilted 50 degrees under
  // a 2 degree prior) and stay in that minimum; with clamps 20 degrees off, the material-first
  // path drives a stiffness to its bound to absorb the clamps' error and stays there.
  FitPath chosen = RunPath(so, make_problem, start, logp, false);
  if (M > m) {
    FitPath staged = RunPath(so, make_problem, start, logp, true);
    if (staged.usable() && (!chosen.usable() || staged.summary.final_cost < chosen.summary.final_cost))
      chosen = std::move(staged);
  }
  logp.swap(chosen.x);  // the buffer the chosen problem's parameter block is (swap keeps it)
  ceres::Problem& problem = *chosen.problem;
  const ceres::Solver::Summary& summary = chosen.summary;
  result.iterations = static_cast<int>(chosen.costs.size()) - 1;
  result.cost_per_iteration = chosen.costs;
  result.seconds_per_iteration = chosen.seconds;
  result.initial_cost = chosen.initial_cost;
  result.num_residuals = counts.total;
  ReportTermination(summary, &result);

  const Eigen::MatrixXd J = JacobianAtSolution(&problem, evals, &result);
  const int dof = std::max(1, counts.effective - M);
  result.residual_dof = dof;
  result.residual_variance = 2.0 * result.final_cost / dof;
  // Trusted sigmas leave the covariance as the sigmas state it; the variance is still reported,
  // so that a model that does not explain the data is not passed silently.
  const double covariance_scale = options.trusted_sigmas ? 1.0 : result.residual_variance;
  const Identifiability id = Identify(J, ColumnNames(input, fitted, nuisances), &problem,
                                     logp.data(), covariance_scale, options.max_log_std);
  const Eigen::MatrixXd& cov_log = id.cov_log;
  result.correlation.setZero(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j)
      result.correlation(i, j) = cov_log(i, j) / std::sqrt(cov_log(i, i) * cov_log(j, j));

  ReportParameters(input, fitted, logp, id, &result);
  ReportNuisances(input, nuisances, logp, cov_log, &result);
  ReportCases(input, fitted, logp, evals, &result);
  for (const auto& e : evals) AddTiming(e->timing(), &result);
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace rodfit
