// Identification of the rod's stiffness parameters from observations (docs/solvers.md, "The fit"):
// a Ceres problem with one residual block per load case whose Evaluate runs the warm-started static
// solve and returns the weighted residuals with their exact Jacobian (dx/dlog p from the
// implicit-function theorem, solve/sensitivity.h, chained with the observation models'
// closed-form d r / d x). Parameters live in log space with optional bounds; fixed ones stay out
// of the Jacobian; an absent bend_stiffness_2 is tied to bend_stiffness. A robust loss is
// applied per measurement. After the fit: covariance (ceres::Covariance), standard deviations,
// correlations and an identifiability verdict per parameter.
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/measurement.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/scene.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// A load case with its measurements, in residual order (rodfit/fit/measurement.h).
struct FitCase {
  LoadCase load_case;
  MeasurementList measurements;
};

struct FitInput {
  RodSpec rod;
  Material material;  ///< values of every parameter (fitted ones are starts)
  Vec3 gravity = Vec3(0, 0, -9.81);
  /// [deg] each case's gravity direction a nuisance (Scene::gravity_prior_deg); absent: as given.
  std::optional<double> gravity_prior_deg;
  std::vector<SpringZone> springs;  ///< attachment zones (tissue)
  std::optional<SectionSpec> section;  ///< the cross-section model, for surface_points
  /// Every parameter the static fit sees, fitted or not (name, value, fit, min, max).
  std::vector<Parameter> parameters;
  std::vector<FitCase> cases;
  StaticsOptions statics;  ///< solver settings of every forward solve
};

enum class RobustLoss { kNone, kHuber, kCauchy, kSoftL1 };

/// The loss as files spell it: none, huber, cauchy, soft_l1. Inline: the file formats (io's
/// experiment reader and profile writer) spell it without linking the fit.
inline const char* RobustLossName(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone: return "none";
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
    case RobustLoss::kSoftL1: return "soft_l1";
  }
  return "none";
}

struct FitIterationInfo {
  int iteration = 0;
  double cost = 0.0;
  double relative_decrease = 0.0;
  double seconds = 0.0;
  /// The NLopt global search before Levenberg–Marquardt (FitOptions::global): `iteration` counts
  /// its evaluations out of `budget` (so a progress line can estimate the time left) and `cost`
  /// is the best so far.
  bool global = false;
  int budget = 0;
};

struct FitOptions {
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale = 1.0;       ///< [sigmas] where the loss turns robust
  int max_iterations = 100;      ///< Levenberg–Marquardt iterations
  bool trusted_sigmas = false;   ///< covariance not rescaled by the residual variance
  bool global = false;           ///< NLopt global search over the log-bounds first
  int global_evaluations = 300;  ///< forward evaluations the global search may spend
  int num_threads = 2;           ///< cases evaluated in parallel
  /// A parameter whose log has a standard deviation above this is reported as not
  /// identifiable: the data pin it down only within a factor exp(this).
  double max_log_std = 1.0;
  /// For measuring what a skip saves (`rodfit bench --skips`) and its tests only: also compute
  /// the Jacobian columns of the rod stiffnesses that are held fixed, and drop them. The fit's
  /// result is the same; it only costs more.
  bool jacobian_of_fixed_parameters = false;
  /// Called once per iteration (and per evaluation of the global search).
  std::function<void(const FitIterationInfo&)> progress;
  bool Check(std::string* why) const;
};

/// A fitted nuisance of a case, never part of the material: a held frame's rotation vector
/// (`rotation_prior_deg`, R = Exp(phi) R_given), a held point's offset (`position_prior`) or the
/// case's gravity turned (`gravity_prior_deg`, a rotation vector perpendicular to gravity), with
/// its std per world axis (NaN where not determined; 0 along gravity for a gravity turn).
struct NuisanceEstimate {
  int case_index = 0;
  std::string case_name;
  /// "clamp", "end_clamp", "end_pin", "pins[k]", "grasp" or "gravity".
  std::string held;
  std::string quantity = "rotation";  ///< "rotation" or "offset"
  std::string unit = "deg";           ///< of value, std and prior: "deg" or "m"
  double prior = 0.0;
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
  Eigen::Vector3d std = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
};

/// A moving case's fitted run at the times it was observed (a moving fit's report).
struct FittedRun {
  int case_index = 0;            ///< into Scene::cases
  std::vector<double> s;         ///< [m] the vertices' rest arc lengths
  std::vector<double> t;         ///< [s] ascending
  std::vector<Mat3X> x;          ///< per time, the vertices [m]
};

struct FitResult {
  bool success = false;          ///< converged to a usable estimate
  std::string message;           ///< termination, or why the fit failed
  int iterations = 0;
  int global_evaluations = 0;
  double initial_cost = 0.0;     ///< 1/2 sum of squared weighted residuals (after the loss)
  double final_cost = 0.0;
  int num_residuals = 0;
  /// 2 cost / (N - m), the chi-square per degree of freedom: about 1 when the model explains the
  /// data and the sigmas are right. Computed with trusted sigmas too (it then does not scale
  /// the covariance, but still says whether the model fits; see ResidualVarianceBand).
  double residual_variance = 1.0;
  int residual_dof = 1;          ///< N - m (at least 1): the degrees of freedom of that ratio
  double seconds = 0.0;          ///< wall time of the whole fit
  double global_seconds = 0.0;   ///< wall time of the NLopt global search (0 without)
  /// Ceres' cost at the start ([0]) and after each iteration, and the wall time since the fit
  /// began [s] at each: the report's convergence plot.
  std::vector<double> cost_per_iteration, seconds_per_iteration;
  /// Summed over all case evaluations (threads add up): forward solves, sensitivities and the
  /// observation models; the rest of `seconds` is Ceres and the covariance.
  double solve_seconds = 0.0, jacobian_seconds = 0.0, observation_seconds = 0.0;
  int forward_solves = 0;
  /// Every parameter of the input with its estimate: value, start, std, identifiable, reason,
  /// at_bound (a parameter not fitted: its value).
  std::vector<Parameter> parameters;
  std::vector<std::string> fitted_names;
  /// The cases' fitted nuisances, case by case (none without rotation priors).
  std::vector<NuisanceEstimate> nuisances;
  Eigen::MatrixXd correlation;   ///< among fitted parameters (in log space)
  std::vector<ObservationFit> observations;
  /// Force and moment readings and surface points, one entry each (centre-line observations
  /// are evaluated again from `shapes`).
  std::vector<MeasurementResidual> measurement_residuals;
  std::vector<Mat3X> shapes;     ///< fitted centre-lines, one per case
  /// Per entry of `shapes`: the poked cross-section's ring nodes at rest and deformed at the
  /// fitted parameters [m], world (empty for a case without a poke or without a section).
  std::vector<Eigen::Matrix3Xd> rest_sections, sections;
  /// Per entry of `shapes`: the tube surface with the poke's dent at the fitted parameters
  /// (solve/poke.h, PokedTube; vertices [m] and triangles), empty without a poke or a section.
  std::vector<Eigen::Matrix3Xd> tube_vertices;
  std::vector<std::vector<Eigen::Vector3i>> tube_triangles;
  /// A moving fit: per case with observation sequences, the fitted run at the recorded times.
  std::vector<FittedRun> trajectories;
};

/// The range a residual variance (chi-square / dof) of a correct model with correct sigmas lies
/// in with probability 99.8 %: the 0.1 % and 99.9 % quantiles of chi-square(dof) / dof, from
/// the Wilson–Hilferty cube-root normal approximation (within 1 % of the exact quantiles for
/// dof >= 30, 7 % at dof = 10; the lower end is clamped at 0). Outside it, either the model does
/// not explain the data or the stated sigmas are wrong.
struct VarianceBand {
  double low = 0.0, high = 0.0;
};
VarianceBand ResidualVarianceBand(int dof);

/// Whether a fit's residuals are what its stated sigmas predict (docs/cli.md, "fit"). `above`:
/// the residual variance lies above its band; with untrusted sigmas the std are scaled by it,
/// but a model error (a clamp pose, the rod length, a camera's calibration) is not noise and is
/// not covered. `below` (trusted sigmas without a robust loss only): the data scatter less than
/// the sigmas say, so the std are too large. `gross`: the result is not to be used as it stands:
/// above the band with trusted sigmas, or above kGrossResidualVariance without them.
struct ResidualCheck {
  VarianceBand band;
  bool above = false, below = false, gross = false;
};
/// The residual variance above which an untrusted-sigma fit is not used: sigmas ten times too
/// small, or a model far from the data.
inline constexpr double kGrossResidualVariance = 100.0;
ResidualCheck CheckResiduals(const FitResult& result, const FitOptions& options);

/// Runs the identification. Throws std::invalid_argument for an ill-posed request (nothing to
/// fit, a fitted parameter the model does not use, min >= max, a start outside its bounds).
/// The ring's `ring_bend_stiffness` / `ring_stretch_stiffness` are fitted from `surface_points`
/// only (fitting one without any surface points is an error); surface points move with the
/// section's placement on the rod as well, whose sensitivity is not modelled, so fitting a rod
/// parameter together with cases that have surface points is an error too.
FitResult Fit(const FitInput& input, const FitOptions& options);

/// The forward map for tests and benchmarks: weighted residuals of every case stacked, and
/// optionally their Jacobian with respect to the log of the fitted parameters followed by the
/// cases' nuisance rotation vectors [rad] (3 per held frame with a rotation prior, case by case,
/// clamp before end clamp; their priors' rows are not included). False when a case's solve
/// fails.
bool EvaluateForwardMap(const FitInput& input, const std::vector<double>& log_values,
                        Eigen::VectorXd* residuals, Eigen::MatrixXd* jacobian);

}  // namespace rodfit
