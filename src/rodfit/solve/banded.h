// Symmetric banded matrix and its Cholesky factorisation, the O(n) linear algebra of the rod
// (each energy term couples at most three consecutive dof blocks). Storage is the lower band,
// column major: entry (i, j) with 0 <= i - j <= bandwidth at band_(i - j, j).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/StdVector>

namespace rodfit {

class BandedSymmetric {
 public:
  BandedSymmetric() = default;
  BandedSymmetric(int size, int bandwidth, int block_size = 1) {
    Resize(size, bandwidth, block_size);
  }
  /// Sets the shape; the entries are zeroed only when it changes (call SetZero to clear).
  /// block_size b > 1 declares a block-banded matrix: b x b blocks, nonzero only within
  /// (bandwidth + 1) / b - 1 block diagonals, so the entries of the band beyond those blocks
  /// are structural zeros (the rod: blocks [x_i, theta_i], each term coupling at most three
  /// consecutive blocks). Cholesky then works on fixed-size blocks, which is several times
  /// faster than the scalar band; its factor is the same.
  void Resize(int size, int bandwidth, int block_size = 1);
  void SetZero() { band_.setZero(); }

  int size() const { return n_; }
  int bandwidth() const { return p_; }
  int block_size() const { return block_; }
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
  int n_ = 0, p_ = 0, block_ = 1;
  Eigen::MatrixXd band_;
};

/// A = L L^T for a banded symmetric A, O(n p^2). Factor() fails (returns false) when A is not
/// numerically positive definite, which the Newton solver uses to detect indefiniteness.
/// When A declares 4 x 4 blocks that tile it and its band (BandedSymmetric::Resize), the factor
/// is computed and kept as fixed-size blocks (the same L, several times faster to compute and
/// to solve with); otherwise as a scalar band.
class BandedCholesky {
 public:
  bool Factor(const BandedSymmetric& A, double diagonal_shift = 0.0);
  bool valid() const { return valid_; }
  int size() const { return n_; }
  /// Solves A x = b in place (b may have several columns).
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;
  Eigen::VectorXd Solve(const Eigen::VectorXd& b) const;
  /// log det(A), useful for detecting the loss of stability along a load path.
  double LogDeterminant() const;

 private:
  using Block = Eigen::Matrix4d;
  bool FactorBlocks4(const BandedSymmetric& A, double diagonal_shift);
  void SolveBlocks4(double* x) const;

  int n_ = 0;
  bool valid_ = false;
  // Scalar mode: L in band storage.
  BandedSymmetric L_;
  // Block mode: for block column J, blocks_[J * (q + 1) + d] is
  // L(J + d, J) for d = 1..q and the inverse of the diagonal block L(J, J) for d = 0.
  bool block_mode_ = false;
  int block_bandwidth_ = 0;
  std::vector<Block, Eigen::aligned_allocator<Block>> blocks_;
};

}  // namespace rodfit
