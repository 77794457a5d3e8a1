// The identifiability verdict and covariance of a least-squares fit in log-parameter space
// (docs/solvers.md, "Covariance"), from its weighted Jacobian at the solution.
// Fit layer: shared by the static fit (fit.cc) and the motion fit (motion_fit.cc), so that both
// call a parameter identifiable by the same rules.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace rodfit {

struct IdentifiabilityReport {
  std::vector<bool> identifiable;   ///< per column of J
  std::vector<std::string> reason;  ///< why not (empty when identifiable)
  /// Covariance of the log-parameters (scaled), NaN in the rows and columns of the parameters
  /// not identifiable.
  Eigen::MatrixXd cov_log;
};

/// A column the residuals do not depend on (norm below 1e-9 of the largest), the parameters of
/// a direction of J's (numerical, 1e-8) null space, and a parameter whose log has a standard
/// deviation above max_log_std are not identifiable. The covariance of the others is
/// (J_s^T J_s)^-1 times covariance_scale; with all of them identifiable `full_covariance`, when
/// given and successful, supplies (J^T J)^-1 instead (the static fit's Ceres covariance).
/// An empty J (no Jacobian at the solution) leaves every parameter identifiable and cov_log NaN.
IdentifiabilityReport AssessIdentifiability(
    const Eigen::MatrixXd& J, const std::vector<std::string>& names, double covariance_scale,
    double max_log_std, const std::function<bool(Eigen::MatrixXd*)>& full_covariance = nullptr);

}  // namespace rodfit
