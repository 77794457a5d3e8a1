// Banded matrices and their factorisations, the O(n) linear algebra of the rod (each energy
// term couples at most three consecutive dof blocks): a symmetric band with Cholesky (the
// potential's Hessian), and a general band with LU and partial pivoting (the tangent of a case
// that carries moments, which have no potential and make it non-symmetric). Symmetric storage
// is the lower band, column major: entry (i, j) with 0 <= i - j <= bandwidth at
// band_(i - j, j).
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
  /// The same into *y (no allocation once y has the size: the dynamics' inner loop).
  void MultiplyInto(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  Eigen::MatrixXd ToDense() const;
  const Eigen::MatrixXd& band() const { return band_; }
  Eigen::MatrixXd& band() { return band_; }

 private:
  int n_ = 0, p_ = 0, block_ = 1;
  Eigen::MatrixXd band_;
};

/// A = L L^T for a banded symmetric A, O(n p^2). Factor() fails (returns false) when A is not
/// positive definite beyond round-off, which the Newton solver uses to detect indefiniteness.
/// A pivot that is zero to round-off (|d| <= kPivotRoundOff |a_jj|) is raised to that floor and
/// the factor flagged (round_off_pivots()): a stiff, fine rod (EA L^2 / EI n ~ 1e15) has soft
/// global modes whose Schur complements are only known to round-off, and treating them as
/// indefinite would shift the whole matrix and stall Newton.
/// When A declares 4 x 4 or 3 x 3 blocks that tile it and its band (BandedSymmetric::Resize), the
/// factor is computed and kept as fixed-size blocks (the same L, several times faster to compute
/// and to solve with); otherwise as a scalar band.
constexpr double kPivotRoundOff = 64 * 2.220446049250313e-16;

class BandedCholesky {
 public:
  bool Factor(const BandedSymmetric& A, double diagonal_shift = 0.0);
  bool valid() const { return valid_; }
  /// True when a pivot was raised from round-off level (see above).
  bool round_off_pivots() const { return round_off_pivots_; }
  int size() const { return n_; }
  /// Solves A x = b in place (b may have several columns).
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;
  Eigen::VectorXd Solve(const Eigen::VectorXd& b) const;
  /// log det(A), useful for detecting the loss of stability along a load path.
  double LogDeterminant() const;

 private:
  template <int kB>
  bool FactorBlocks(const BandedSymmetric& A, double diagonal_shift);
  template <int kB>
  void SolveBlocks(double* x) const;
  template <int kB>
  std::vector<Eigen::Matrix<double, kB, kB>, Eigen::aligned_allocator<Eigen::Matrix<double, kB, kB>>>&
  Blocks();
  template <int kB>
  const std::vector<Eigen::Matrix<double, kB, kB>,
                    Eigen::aligned_allocator<Eigen::Matrix<double, kB, kB>>>&
  Blocks() const {
    return const_cast<BandedCholesky*>(this)->Blocks<kB>();
  }

  int n_ = 0;
  bool valid_ = false;
  bool round_off_pivots_ = false;
  // Scalar mode: L in band storage.
  BandedSymmetric L_;
  // Block mode (the block size, 0: scalar): for block column J, blocks[J * (q + 1) + d] is
  // L(J + d, J) for d = 1..q and the inverse of the diagonal block L(J, J) for d = 0.
  int block_mode_ = 0;
  int block_bandwidth_ = 0;
  std::vector<Eigen::Matrix4d, Eigen::aligned_allocator<Eigen::Matrix4d>> blocks4_;
  std::vector<Eigen::Matrix3d, Eigen::aligned_allocator<Eigen::Matrix3d>> blocks3_;
};

/// A = L D L^T of a symmetric band matrix without pivoting (scalar band), for symmetric
/// indefinite matrices whose inertia is wanted: by Sylvester's law the signs of D are those of
/// A's eigenvalues. Factor() fails on a zero or non-finite pivot (an unpivoted LDL^T can break
/// down where a pivoted one would not; the solver then shifts the diagonal).
template <>
inline std::vector<Eigen::Matrix4d, Eigen::aligned_allocator<Eigen::Matrix4d>>&
BandedCholesky::Blocks<4>() {
  return blocks4_;
}
template <>
inline std::vector<Eigen::Matrix3d, Eigen::aligned_allocator<Eigen::Matrix3d>>&
BandedCholesky::Blocks<3>() {
  return blocks3_;
}

class BandedLDLT {
 public:
  bool Factor(const BandedSymmetric& A, double diagonal_shift = 0.0);
  int negative_pivots() const { return negative_; }
  int size() const { return n_; }
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;

 private:
  int n_ = 0, p_ = 0, negative_ = 0;
  Eigen::MatrixXd band_;  // L below the diagonal (unit diagonal implied), D on the diagonal
};

/// A general (non-symmetric) band matrix with kl sub- and ku super-diagonals, stored by
/// diagonals in column-major LAPACK band form with kl extra rows for the LU's fill-in:
/// entry (i, j), -ku <= i - j <= kl, at band_(kl + ku + i - j, j).
class BandedMatrix {
 public:
  BandedMatrix() = default;
  /// Sets the shape and zeroes every entry.
  void Resize(int size, int kl, int ku);
  int size() const { return n_; }
  int lower() const { return kl_; }
  int upper() const { return ku_; }
  double& At(int i, int j) { return band_(kl_ + ku_ + i - j, j); }
  double At(int i, int j) const { return band_(kl_ + ku_ + i - j, j); }
  bool InBand(int i, int j) const { return i - j <= kl_ && j - i <= ku_; }
  /// Copies a symmetric band (both triangles).
  void SetFromSymmetric(const BandedSymmetric& A);
  /// y = A x.
  Eigen::VectorXd Multiply(const Eigen::VectorXd& x) const;
  /// The same into *y (no allocation once y has the size: the dynamics' inner loop).
  void MultiplyInto(const Eigen::VectorXd& x, Eigen::VectorXd* y) const;
  /// y = A^T x.
  Eigen::VectorXd MultiplyTransposed(const Eigen::VectorXd& x) const;
  /// The symmetric part (A + A^T) / 2 as a symmetric band (block size `block_size`).
  BandedSymmetric SymmetricPart(int block_size = 1) const;
  Eigen::MatrixXd ToDense() const;
  /// Zeroes row and column i and puts 1 on the diagonal (a Dirichlet condition).
  void SetIdentityRow(int i);
  bool AllFinite() const { return band_.allFinite(); }
  /// Largest |A(i, i)|.
  double MaxDiagonal() const { return band_.row(kl_ + ku_).cwiseAbs().maxCoeff(); }

 private:
  friend class BandedLU;
  int n_ = 0, kl_ = 0, ku_ = 0;
  Eigen::MatrixXd band_;
};

/// P A = L U of a general band matrix with partial pivoting (LAPACK dgbtf2's algorithm), O(n kl
/// (kl + ku)). Factor() fails for a (numerically) singular matrix.
class BandedLU {
 public:
  bool Factor(const BandedMatrix& A);
  bool valid() const { return valid_; }
  int size() const { return n_; }
  /// Solves A x = b in place (b may have several columns).
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;
  Eigen::VectorXd Solve(const Eigen::VectorXd& b) const;
  /// Solves A^T x = b in place.
  void SolveTransposedInPlace(Eigen::Ref<Eigen::MatrixXd> b) const;
  /// Sign of det(A): +1, -1 (0 when not factored).
  int DeterminantSign() const;

 private:
  int n_ = 0, kl_ = 0, ku_ = 0;
  bool valid_ = false;
  Eigen::MatrixXd lu_;
  std::vector<int> pivots_;
};

}  // namespace rodfit
