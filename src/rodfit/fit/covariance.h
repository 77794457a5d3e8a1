// Covariance and identifiability of a fit at its solution (docs/solvers.md, "Covariance and
// identifiability"), internal to fit/.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <ceres/ceres.h>

namespace rodfit {
namespace fit_internal {

struct Identifiability {
  std::vector<bool> identifiable;  ///< per fitted parameter
  std::vector<std::string> reason; ///< why not, per fitted parameter (empty when identifiable)
  /// Covariance of the log-parameters (scaled); NaN rows and columns for the unidentifiable.
  Eigen::MatrixXd cov_log;
};

/// From the weighted Jacobian J (log space, after the loss) at the solution `logp` of
/// `problem`: a parameter is unidentifiable when the residuals do not depend on it, when it
/// lies in a direction of J's null space (with the parameters it cannot be told from), or when
/// the std of its log exceeds max_log_std. The covariance of the identifiable ones is
/// (J^T J)^-1 (Ceres' when all are), times `covariance_scale` (the residual variance, or 1 for
/// trusted sigmas). An empty J (the evaluation failed) leaves all identifiable with a NaN
/// covariance.
Identifiability Identify(const Eigen::MatrixXd& J, const std::vector<std::string>& names,
                         ceres::Problem* problem, double* logp, double covariance_scale,
                         double max_log_std);

/// The 95 % quantile of the chi-square distribution with `dof` >= 1 degrees of freedom: exact
/// for 1 and 2, Wilson & Hilferty 1931's cube-root approximation beyond (within 0.5 % of the
/// tables).
double ChiSquare95(int dof);

/// Whether a step d of the parameters lies within the 95 % confidence region of a point whose
/// weighted Jacobian is J (residuals x parameters): d^T J^T J d <= ChiSquare95(m) * variance, with
/// `variance` the residual variance (1 for trusted sigmas) and m the parameters.
bool WithinConfidenceRegion(const Eigen::MatrixXd& J, const Eigen::VectorXd& d, double variance);

}  // namespace fit_internal
}  // namespace rodfit
