// Covariance and identifiability of a fit (covariance.h).
#include "rodfit/fit/covariance.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/LU>
#include <Eigen/SVD>

namespace rodfit {
namespace fit_internal {

Identifiability Identify(const Eigen::MatrixXd& J, const std::vector<std::string>& names,
                         ceres::Problem* problem, double* logp, double covariance_scale,
                         double max_log_std) {
  // Identifiability: columns the residuals do not depend on, directions of J's null space, and
  // parameters whose log is determined only within max_log_std.
  const int m = static_cast<int>(names.size());
  Identifiability out;
  std::vector<bool>& identifiable = out.identifiable;
  std::vector<std::string>& reason = out.reason;
  Eigen::MatrixXd& cov_log = out.cov_log;
  identifiable.assign(m, true);
  reason.assign(m, "");
  cov_log = Eigen::MatrixXd::Constant(m, m, std::numeric_limits<double>::quiet_NaN());
  if (J.size() > 0) {
    const Eigen::VectorXd colnorm = J.colwise().norm();
    const double jmax = std::max(colnorm.maxCoeff(), 1e-300);
    for (int k = 0; k < m; ++k)
      if (colnorm[k] <= 1e-9 * jmax || colnorm[k] == 0.0) {
        identifiable[k] = false;
        reason[k] = "the observations do not depend on it in these cases";
      }
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeFullV);
    const Eigen::VectorXd sv = svd.singularValues();
    for (int i = 0; i < sv.size(); ++i) {
      if (sv[i] > 1e-8 * sv[0]) continue;
      const Eigen::VectorXd v = svd.matrixV().col(i);
      std::vector<int> involved;
      for (int k = 0; k < m; ++k)
        if (std::abs(v[k]) > 0.2 && identifiable[k]) involved.push_back(k);
      for (int k : involved) {
        std::string others;
        for (int o : involved)
          if (o != k) others += (others.empty() ? "" : ", ") + names[o];
        identifiable[k] = false;
        reason[k] = others.empty() ? "the observations do not determine it"
                                   : "not separable from " + others +
                                         ": only a combination is determined by these cases";
      }
    }
    std::vector<int> keep;
    for (int k = 0; k < m; ++k)
      if (identifiable[k]) keep.push_back(k);
    if (!keep.empty()) {
      const int q = static_cast<int>(keep.size());
      Eigen::MatrixXd cov_sub;
      if (q == m) {
        // Full rank: Ceres' covariance of the parameter block.
        ceres::Covariance::Options co;
        co.algorithm_type = ceres::DENSE_SVD;
        co.num_threads = 1;
        ceres::Covariance covariance(co);
        std::vector<std::pair<const double*, const double*>> blocks = {{logp, logp}};
        cov_sub.resize(m, m);
        if (covariance.Compute(blocks, problem) &&
            covariance.GetCovarianceBlock(logp, logp, cov_sub.data())) {
          cov_sub.transposeInPlace();  // row-major from Ceres (symmetric anyway)
        } else {
          cov_sub = (J.transpose() * J).inverse();
        }
      } else {
        Eigen::MatrixXd Js(J.rows(), q);
        for (int i = 0; i < q; ++i) Js.col(i) = J.col(keep[i]);
        cov_sub = (Js.transpose() * Js).inverse();
      }
      cov_sub *= covariance_scale;
      for (int i = 0; i < q; ++i)
        for (int j = 0; j < q; ++j) cov_log(keep[i], keep[j]) = cov_sub(i, j);
      for (int i = 0; i < q; ++i) {
        const int k = keep[i];
        const double s = std::sqrt(std::max(0.0, cov_log(k, k)));
        if (!(s <= max_log_std)) {
          identifiable[k] = false;
          char buf[160];
          std::snprintf(buf, sizeof(buf),
                        "determined only within a factor of %.3g (std of its log %.3g): its "
                        "effect is below the noise",
                        std::exp(s), s);
          reason[k] = buf;
        }
      }
    }
  }
  return out;
}

double ChiSquare95(int dof) {
  // Exact for 1 (the square of the normal's two-sided 95 % point) and 2 (an exponential with
  // mean 2); the cube-root approximation beyond, within 0.5 % from 3 on (2.4 % off at 1).
  if (dof <= 1) return 1.959964 * 1.959964;
  if (dof == 2) return -2.0 * std::log(0.05);
  const double k = static_cast<double>(dof);
  const double c = 1.0 - 2.0 / (9.0 * k) + 1.6449 * std::sqrt(2.0 / (9.0 * k));
  return k * c * c * c;
}

bool WithinConfidenceRegion(const Eigen::MatrixXd& J, const Eigen::VectorXd& d, double variance) {
  return (J * d).squaredNorm() <= ChiSquare95(static_cast<int>(d.size())) * variance;
}

}  // namespace fit_internal
}  // namespace rodfit
