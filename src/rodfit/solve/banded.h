// Symmetric banded matrix and its Cholesky factorisation, the O(n) linear algebra of the rod
// (each energy term couples at most three consecutive dof blocks). Storage is the lower band,
// column major: entry (i, j) with 0 <= i - j <= bandwidth at band_(i - j, j).
#pragma once

#include <Eigen/Core>

namespace rodfit {

class BandedSymmetric {
 public:
  BandedSymmetric() = default;
  BandedSymmetric(int size, int bandwidth) { Resize(size, bandwidth); }
  void Resize(int size, int bandwidth);
  void SetZero() { band_.setZero(); }

  int size() const { return n_; }
  int bandwidth() const { return p_; }
  /// Lower-band entry (i >= j, i - j <= bandwidth).
  double& At(int i, int j) { return band_(i - j, j); }
  double At(int i, int j) const { return band_(i - j, j); }
  /// Symmetric read of any entry (zero outside the band).
  double Get(int i, int j) const;
  /// y = A x.
  Eigen::VectorXd Multiply(const Eigen::VectorXd& x) const;
  Eigen::MatrixXd ToDense() const;
  const Eigen::MatrixXd& band() const { return band_; }
  Eigen::MatrixXd& band() { return band_; }

 private:
  int n_ = 0, p_ = 0;
  Eigen::MatrixXd band_;
};

/// A = L L^T for a banded symmetric A, O(n p^2). Factor() fails (returns false) when A is not
/// numerically positive definite, which the Newton solver uses to detect indefiniteness.
class BandedCholesky {
 public:
  bool Factor(const BandedSymmetric& A, double diagonal_shift = 0.0);
  bool valid() const { return valid_; }
  int size() const { return L_.size(); }
  /// Solves A x = b in place (b may have several columns).
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;
  Eigen::VectorXd Solve(const Eigen::VectorXd& b) const;
  /// log det(A), useful for detecting the loss of stability along a load path.
  double LogDeterminant() const;

 private:
  BandedSymmetric L_;
  bool valid_ = false;
};

}  // namespace rodfit
