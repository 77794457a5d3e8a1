// Identifiability and covariance from a weighted Jacobian (identifiability.h).
#include "rodfit/fit/identifiability.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/Dense>
#include <Eigen/SVD>

namespace rodfit {

IdentifiabilityReport AssessIdentifiability(
    const Eigen::MatrixXd& J, const std::vector<std::string>& names, double covariance_scale,
    double max_log_std, const std::function<bool(Eigen::MatrixXd*)>& full_covariance) {
  const int m = static_cast<int>(names.size());
  IdentifiabilityReport out;
  out.identifiable.assign(m, true);
  out.reason.assign(m, std::string());
  out.cov_log = Eigen::MatrixXd::Constant(m, m, std::numeric_limits<double>::quiet_NaN());
  std::vector<bool>& identifiable = out.identifiable;
  std::vector<std::string>& reason = out.reason;
  if (J.size() == 0) return out;
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
  if (keep.empty()) return out;
  const int q = static_cast<int>(keep.size());
  Eigen::MatrixXd cov_sub;
  if (q == m) {
    if (!full_covariance || !full_covariance(&cov_sub)) cov_sub = (J.transpose() * J).inverse();
  } else {
    Eigen::MatrixXd Js(J.rows(), q);
    for (int i = 0; i < q; ++i) Js.col(i) = J.col(keep[i]);
    cov_sub = (Js.transpose() * Js).inverse();
  }
  cov_sub *= covariance_scale;
  for (int i = 0; i < q; ++i)
    for (int j = 0; j < q; ++j) out.cov_log(keep[i], keep[j]) = cov_sub(i, j);
  for (int i = 0; i < q; ++i) {
    const int k = keep[i];
    const double s = std::sqrt(std::max(0.0, out.cov_log(k, k)));
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
  return out;
}

}  // namespace rodfit
