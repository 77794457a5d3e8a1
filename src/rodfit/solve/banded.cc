// Banded symmetric storage and Cholesky (see banded.h).
#include "rodfit/solve/banded.h"

#include <algorithm>
#include <cmath>

namespace rodfit {

void BandedSymmetric::Resize(int size, int bandwidth) {
  n_ = size;
  p_ = std::min(bandwidth, std::max(size - 1, 0));
  band_.setZero(p_ + 1, n_);
}

double BandedSymmetric::Get(int i, int j) const {
  if (i < j) std::swap(i, j);
  return (i - j <= p_) ? band_(i - j, j) : 0.0;
}

Eigen::VectorXd BandedSymmetric::Multiply(const Eigen::VectorXd& x) const {
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n_);
  for (int j = 0; j < n_; ++j) {
    y[j] += band_(0, j) * x[j];
    const int iend = std::min(n_ - 1, j + p_);
    for (int i = j + 1; i <= iend; ++i) {
      const double a = band_(i - j, j);
      y[i] += a * x[j];
      y[j] += a * x[i];
    }
  }
  return y;
}

Eigen::MatrixXd BandedSymmetric::ToDense() const {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n_, n_);
  for (int j = 0; j < n_; ++j)
    for (int i = j; i <= std::min(n_ - 1, j + p_); ++i) A(i, j) = A(j, i) = band_(i - j, j);
  return A;
}

bool BandedCholesky::Factor(const BandedSymmetric& A, double diagonal_shift) {
  L_ = A;
  const int n = A.size(), p = A.bandwidth();
  Eigen::MatrixXd& b = L_.band();
  for (int j = 0; j < n; ++j) {
    double d = b(0, j) + diagonal_shift;
    const int kbeg = std::max(0, j - p);
    for (int k = kbeg; k < j; ++k) d -= b(j - k, k) * b(j - k, k);
    // Relative pivot test: a pivot lost to cancellation means "not positive definite".
    if (!(d > 1e-14 * std::abs(b(0, j) + diagonal_shift)) || !std::isfinite(d)) {
      valid_ = false;
      return false;
    }
    const double ljj = std::sqrt(d);
    b(0, j) = ljj;
    const int iend = std::min(n - 1, j + p);
    for (int i = j + 1; i <= iend; ++i) {
      double s = b(i - j, j);
      for (int k = std::max(kbeg, i - p); k < j; ++k) s -= b(i - k, k) * b(j - k, k);
      b(i - j, j) = s / ljj;
    }
  }
  valid_ = true;
  return true;
}

void BandedCholesky::SolveInPlace(Eigen::Ref<Eigen::MatrixXd> x) const {
  const int n = L_.size(), p = L_.bandwidth();
  const Eigen::MatrixXd& b = L_.band();
  for (int c = 0; c < x.cols(); ++c) {
    for (int i = 0; i < n; ++i) {  // L y = x
      double s = x(i, c);
      for (int k = std::max(0, i - p); k < i; ++k) s -= b(i - k, k) * x(k, c);
      x(i, c) = s / b(0, i);
    }
    for (int i = n - 1; i >= 0; --i) {  // L^T z = y
      double s = x(i, c);
      for (int k = i + 1; k <= std::min(n - 1, i + p); ++k) s -= b(k - i, i) * x(k, c);
      x(i, c) = s / b(0, i);
    }
  }
}

Eigen::VectorXd BandedCholesky::Solve(const Eigen::VectorXd& rhs) const {
  Eigen::VectorXd x = rhs;
  SolveInPlace(x);
  return x;
}

double BandedCholesky::LogDeterminant() const {
  double s = 0.0;
  for (int i = 0; i < L_.size(); ++i) s += 2.0 * std::log(L_.band()(0, i));
  return s;
}

}  // namespace rodfit
