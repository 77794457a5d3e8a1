// Banded symmetric storage and Cholesky (see banded.h).
#include "rodfit/solve/banded.h"

#include <algorithm>
#include <cstddef>
#include <cmath>

namespace rodfit {

void BandedSymmetric::Resize(int size, int bandwidth, int block_size) {
  const int p = std::min(bandwidth, std::max(size - 1, 0));
  block_ = std::max(block_size, 1);
  if (size == n_ && p == p_) return;  // keep the storage (and its contents) between assemblies
  n_ = size;
  p_ = p;
  band_.setZero(p_ + 1, n_);
}

double BandedSymmetric::Get(int i, int j) const {
  if (i < j) std::swap(i, j);
  return (i - j <= p_) ? band_(i - j, j) : 0.0;
}

Eigen::VectorXd BandedSymmetric::Multiply(const Eigen::VectorXd& x) const {
  Eigen::VectorXd y;
  MultiplyInto(x, &y);
  return y;
}

// Column j of the band holds A(j..j+p, j): its part below the diagonal adds x_j times it to
// y(j+1..j+p) (an axpy) and, by symmetry, its dot with x(j+1..j+p) to y_j. The dot is summed in
// four independent partial sums, which the compiler keeps in vector registers (one running sum
// is a chain of dependent additions it may not reorder): 3x faster on the rod's band (p = 11),
// where this product is a large part of a step's and of its sensitivities' cost.
void BandedSymmetric::MultiplyInto(const Eigen::VectorXd& x, Eigen::VectorXd* out) const {
  Eigen::VectorXd& y = *out;
  y.setZero(n_);
  const double* xs = x.data();
  double* ys = y.data();
  const int rows = static_cast<int>(band_.rows());
  for (int j = 0; j < n_; ++j) {
    const double* col = band_.data() + static_cast<std::ptrdiff_t>(j) * rows;
    const int len = std::min(n_ - 1 - j, p_);  // entries below the diagonal
    const double xj = xs[j];
    const double* xb = xs + j + 1;
    double* yb = ys + j + 1;
    const double* a = col + 1;
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int k = 0;
    for (; k + 4 <= len; k += 4) {
      yb[k] += a[k] * xj;
      yb[k + 1] += a[k + 1] * xj;
      yb[k + 2] += a[k + 2] * xj;
      yb[k + 3] += a[k + 3] * xj;
      s0 += a[k] * xb[k];
      s1 += a[k + 1] * xb[k + 1];
      s2 += a[k + 2] * xb[k + 2];
      s3 += a[k + 3] * xb[k + 3];
    }
    for (; k < len; ++k) {
      yb[k] += a[k] * xj;
      s0 += a[k] * xb[k];
    }
    ys[j] += col[0] * xj + ((s0 + s1) + (s2 + s3));
  }
}

Eigen::MatrixXd BandedSymmetric::ToDense() const {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n_, n_);
  for (int j = 0; j < n_; ++j)
    for (int i = j; i <= std::min(n_ - 1, j + p_); ++i) A(i, j) = A(j, i) = band_(i - j, j);
  return A;
}

// Right-looking (outer-product) form: once column j of L is known, it updates the columns
// j+1..j+p below their diagonal. In the column-major band each of those updates is a
// contiguous axpy, which the compiler vectorises; the inner-product form would walk rows of the
// band with stride p + 1.
bool BandedCholesky::Factor(const BandedSymmetric& A, double diagonal_shift) {
  n_ = A.size();
  valid_ = false;
  round_off_pivots_ = false;
  block_mode_ = 0;
  const int block = A.block_size();
  if ((block == 3 || block == 4) && A.size() % block == 0 && (A.bandwidth() + 1) % block == 0 &&
      A.bandwidth() >= block - 1)
    return block == 4 ? FactorBlocks<4>(A, diagonal_shift) : FactorBlocks<3>(A, diagonal_shift);
  // Right-looking (outer-product) form: once column j of L is known, it updates the columns
  // j+1..j+p below their diagonal, each a contiguous axpy in the column-major band.
  L_ = A;
  const int n = A.size(), p = A.bandwidth();
  Eigen::MatrixXd& b = L_.band();
  const Eigen::MatrixXd& a = A.band();
  for (int j = 0; j < n; ++j) {
    const double a_jj = a(0, j) + diagonal_shift;
    double d = b(0, j) + diagonal_shift;
    // Relative pivot test: a pivot lost to cancellation means "not positive definite".
    const double floor = kPivotRoundOff * std::abs(a_jj);
    if (!(d >= -floor) || !std::isfinite(d)) return false;
    if (d <= floor) {  // zero to round-off: see kPivotRoundOff
      d = floor;
      round_off_pivots_ = true;
    }
    const double ljj = std::sqrt(d), inv = 1.0 / ljj;
    double* col = &b(0, j);
    col[0] = ljj;
    const int m = std::min(p, n - 1 - j);
    for (int r = 1; r <= m; ++r) col[r] *= inv;
    for (int c = 1; c <= m; ++c) {
      // A(j+c+r, j+c) -= L(j+c+r, j) L(j+c, j) for r = 0..m-c (the shift enters the pivots).
      const double lc = col[c];
      double* target = &b(0, j + c);
      const double* source = col + c;
      for (int r = 0; r <= m - c; ++r) target[r] -= lc * source[r];
    }
  }
  valid_ = true;
  return true;
}

// Block form, left-looking with q = (p + 1) / b - 1 block diagonals (b = 4: blocks [x_i,
// theta_i]; b = 3: the position-only system of a rod whose twist is eliminated):
//   S = A(J,J) - sum_K L(J,K) L(J,K)^T,  L(J,J) = chol(S)  (scalar, same pivot test),
//   L(I,J) = (A(I,J) - sum_K L(I,K) L(J,K)^T) L(J,J)^{-T}  for I = J+1..J+q,
// with K over the block columns both rows reach. Fill-in stays inside the block band.
template <int kB>
bool BandedCholesky::FactorBlocks(const BandedSymmetric& A, double diagonal_shift) {
  using BlockB = Eigen::Matrix<double, kB, kB>;
  const int nb = n_ / kB, q = (A.bandwidth() + 1) / kB - 1, stride = q + 1;
  const Eigen::MatrixXd& a = A.band();
  block_mode_ = kB;
  block_bandwidth_ = q;
  auto& blocks = Blocks<kB>();
  blocks.resize(static_cast<size_t>(nb) * stride);
  // L(I, K) for I > K is blocks[K * stride + (I - K)].
  auto L = [&](int I, int K) -> const BlockB& { return blocks[K * stride + (I - K)]; };
  for (int J = 0; J < nb; ++J) {
    const int j0 = kB * J;
    // Column c of block (I, J) is the contiguous run band(b (I - J) - c .. + b - 1, b J + c); the
    // diagonal block's upper entries fall outside the band and are never read (lower only).
    BlockB S;
    for (int c = 0; c < kB; ++c)
      S.col(c).tail(kB - c) = a.col(j0 + c).head(kB - c);
    for (int K = std::max(0, J - q); K < J; ++K) S.noalias() -= L(J, K) * L(J, K).transpose();
    // Cholesky of the diagonal block (lower triangle of S), then its inverse.
    BlockB Ljj = BlockB::Zero();
    double inv_diag[kB];
    for (int k = 0; k < kB; ++k) {
      double d = S(k, k) + diagonal_shift;
      for (int m = 0; m < k; ++m) d -= Ljj(k, m) * Ljj(k, m);
      const double floor = kPivotRoundOff * std::abs(a(0, j0 + k) + diagonal_shift);
      if (!(d >= -floor) || !std::isfinite(d)) return false;
      if (d <= floor) {  // zero to round-off: see kPivotRoundOff
        d = floor;
        round_off_pivots_ = true;
      }
      const double lkk = std::sqrt(d);
      inv_diag[k] = 1.0 / lkk;
      Ljj(k, k) = lkk;
      for (int r = k + 1; r < kB; ++r) {
        double s = S(r, k);
        for (int m = 0; m < k; ++m) s -= Ljj(r, m) * Ljj(k, m);
        Ljj(r, k) = s * inv_diag[k];
      }
    }
    BlockB inv = BlockB::Zero();  // L(J,J)^{-1} by forward substitution on the identity
    for (int c = 0; c < kB; ++c) {
      inv(c, c) = inv_diag[c];
      for (int r = c + 1; r < kB; ++r) {
        double s = 0.0;
        for (int m = c; m < r; ++m) s -= Ljj(r, m) * inv(m, c);
        inv(r, c) = s * inv_diag[r];
      }
    }
    blocks[J * stride] = inv;
    for (int I = J + 1; I <= std::min(nb - 1, J + q); ++I) {
      const int d = kB * (I - J);
      BlockB B;
      for (int c = 0; c < kB; ++c) B.col(c) = a.col(j0 + c).template segment<kB>(d - c);
      for (int K = std::max(0, I - q); K < J; ++K) B.noalias() -= L(I, K) * L(J, K).transpose();
      // B inv^T with inv lower triangular: column c sums B's columns 0..c only.
      BlockB& LIJ = blocks[J * stride + (I - J)];
      for (int c = 0; c < kB; ++c) {
        LIJ.col(c) = B.col(0) * inv(c, 0);
        for (int k = 1; k <= c; ++k) LIJ.col(c) += B.col(k) * inv(c, k);
      }
    }
  }
  valid_ = true;
  return true;
}

template <int kB>
void BandedCholesky::SolveBlocks(double* x) const {
  using VecB = Eigen::Matrix<double, kB, 1>;
  const auto& blocks = Blocks<kB>();
  const int nb = n_ / kB, q = block_bandwidth_, stride = q + 1;
  // L y = x: y_J = L(J,J)^{-1} (x_J - sum_K L(J,K) y_K).
  for (int J = 0; J < nb; ++J) {
    Eigen::Map<VecB> xJ(x + kB * J);
    VecB s = xJ;
    for (int K = std::max(0, J - q); K < J; ++K)
      s.noalias() -= blocks[K * stride + (J - K)] * Eigen::Map<const VecB>(x + kB * K);
    xJ.noalias() = blocks[J * stride] * s;
  }
  // L^T z = y: z_J = L(J,J)^{-T} (y_J - sum_I L(I,J)^T z_I).
  for (int J = nb - 1; J >= 0; --J) {
    Eigen::Map<VecB> xJ(x + kB * J);
    VecB s = xJ;
    for (int I = J + 1; I <= std::min(nb - 1, J + q); ++I)
      s.noalias() -= blocks[J * stride + (I - J)].transpose() * Eigen::Map<const VecB>(x + kB * I);
    xJ.noalias() = blocks[J * stride].transpose() * s;
  }
}

void BandedCholesky::SolveInPlace(Eigen::Ref<Eigen::MatrixXd> x) const {
  if (block_mode_ == 4) {
    for (int c = 0; c < x.cols(); ++c) SolveBlocks<4>(&x(0, c));
    return;
  }
  if (block_mode_ == 3) {
    for (int c = 0; c < x.cols(); ++c) SolveBlocks<3>(&x(0, c));
    return;
  }
  const int n = L_.size(), p = L_.bandwidth();
  const Eigen::MatrixXd& b = L_.band();
  for (int c = 0; c < x.cols(); ++c) {
    double* v = &x(0, c);
    for (int j = 0; j < n; ++j) {  // L y = x, by columns of L (contiguous)
      const double* col = &b(0, j);
      const double y = v[j] / col[0];
      v[j] = y;
      const int m = std::min(p, n - 1 - j);
      for (int r = 1; r <= m; ++r) v[j + r] -= col[r] * y;
    }
    for (int i = n - 1; i >= 0; --i) {  // L^T z = y: row i of L^T is column i of L
      const double* col = &b(0, i);
      const int m = std::min(p, n - 1 - i);
      double s = v[i];
      for (int r = 1; r <= m; ++r) s -= col[r] * v[i + r];
      v[i] = s / col[0];
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
  if (block_mode_ == 4) {  // the diagonal of L(J,J)^{-1} is 1 / L_jj
    for (int J = 0; J < n_ / 4; ++J)
      for (int k = 0; k < 4; ++k) s -= 2.0 * std::log(blocks4_[J * (block_bandwidth_ + 1)](k, k));
    return s;
  }
  if (block_mode_ == 3) {
    for (int J = 0; J < n_ / 3; ++J)
      for (int k = 0; k < 3; ++k) s -= 2.0 * std::log(blocks3_[J * (block_bandwidth_ + 1)](k, k));
    return s;
  }
  for (int i = 0; i < L_.size(); ++i) s += 2.0 * std::log(L_.band()(0, i));
  return s;
}

void BandedMatrix::Resize(int size, int kl, int ku) {
  n_ = size;
  kl_ = std::min(kl, std::max(size - 1, 0));
  ku_ = std::min(ku, std::max(size - 1, 0));
  band_.setZero(2 * kl_ + ku_ + 1, n_);
}

void BandedMatrix::SetFromSymmetric(const BandedSymmetric& A) {
  Resize(A.size(), A.bandwidth(), A.bandwidth());
  const int p = A.bandwidth();
  for (int j = 0; j < n_; ++j)
    for (int i = j; i <= std::min(n_ - 1, j + p); ++i) {
      const double a = A.At(i, j);
      At(i, j) = a;
      At(j, i) = a;
    }
}

Eigen::VectorXd BandedMatrix::Multiply(const Eigen::VectorXd& x) const {
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n_);
  for (int j = 0; j < n_; ++j)
    for (int i = std::max(0, j - ku_); i <= std::min(n_ - 1, j + kl_); ++i) y[i] += At(i, j) * x[j];
  return y;
}

Eigen::VectorXd BandedMatrix::MultiplyTransposed(const Eigen::VectorXd& x) const {
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n_);
  for (int j = 0; j < n_; ++j)
    for (int i = std::max(0, j - ku_); i <= std::min(n_ - 1, j + kl_); ++i) y[j] += At(i, j) * x[i];
  return y;
}

BandedSymmetric BandedMatrix::SymmetricPart(int block_size) const {
  const int p = std::max(kl_, ku_);
  BandedSymmetric S(n_, p, block_size);
  S.SetZero();
  for (int j = 0; j < n_; ++j)
    for (int i = j; i <= std::min(n_ - 1, j + p); ++i) {
      const double a = InBand(i, j) ? At(i, j) : 0.0, b = InBand(j, i) ? At(j, i) : 0.0;
      S.At(i, j) = 0.5 * (a + b);
    }
  return S;
}

Eigen::MatrixXd BandedMatrix::ToDense() const {
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n_, n_);
  for (int j = 0; j < n_; ++j)
    for (int i = std::max(0, j - ku_); i <= std::min(n_ - 1, j + kl_); ++i) A(i, j) = At(i, j);
  return A;
}

void BandedMatrix::SetIdentityRow(int i) {
  for (int j = std::max(0, i - kl_); j <= std::min(n_ - 1, i + ku_); ++j) At(i, j) = 0.0;
  for (int r = std::max(0, i - ku_); r <= std::min(n_ - 1, i + kl_); ++r) At(r, i) = 0.0;
  At(i, i) = 1.0;
}

// Unblocked band LU with partial pivoting, as LAPACK's dgbtf2: column j's pivot is searched
// among rows j..j+kl; the row swap may extend U by kl diagonals, which the storage keeps room for.
bool BandedLU::Factor(const BandedMatrix& A) {
  n_ = A.n_, kl_ = A.kl_, ku_ = A.ku_;
  lu_ = A.band_;
  pivots_.assign(n_, 0);
  valid_ = false;
  const int kv = ku_ + kl_;  // row of the diagonal in the band storage
  double scale = 0.0;
  for (int j = 0; j < n_; ++j) scale = std::max(scale, lu_.col(j).cwiseAbs().maxCoeff());
  if (!std::isfinite(scale) || scale == 0.0) return false;
  auto a = [&](int i, int j) -> double& { return lu_(kv + i - j, j); };
  int ju = 0;  // last column touched by U so far
  for (int j = 0; j < n_; ++j) {
    const int km = std::min(kl_, n_ - 1 - j);
    int jp = 0;
    double best = -1.0;
    for (int r = 0; r <= km; ++r) {
      const double v = std::abs(a(j + r, j));
      if (v > best) best = v, jp = r;
    }
    pivots_[j] = j + jp;
    // A zero pivot is singular. (A pivot small against the whole matrix is not: the rod's rows
    // span EA / l to GJ / l, ten orders of magnitude on a stiff, fine rod.)
    if (!(best > 1e-300 * scale) || !std::isfinite(best)) return false;
    ju = std::max(ju, std::min(j + ku_ + jp, n_ - 1));
    if (jp != 0)
      for (int c = j; c <= ju; ++c) std::swap(a(j, c), a(j + jp, c));
    const double inv = 1.0 / a(j, j);
    for (int r = 1; r <= km; ++r) a(j + r, j) *= inv;
    for (int c = j + 1; c <= ju; ++c) {
      const double u = a(j, c);
      if (u == 0.0) continue;
      for (int r = 1; r <= km; ++r) a(j + r, c) -= a(j + r, j) * u;
    }
  }
  valid_ = true;
  return true;
}

void BandedLU::SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const {
  const int kv = ku_ + kl_;
  auto a = [&](int i, int j) { return lu_(kv + i - j, j); };
  for (int col = 0; col < b.cols(); ++col) {
    double* x = &b(0, col);
    for (int j = 0; j < n_; ++j) {  // L y = P b
      const int p = pivots_[j];
      if (p != j) std::swap(x[j], x[p]);
      const int km = std::min(kl_, n_ - 1 - j);
      for (int r = 1; r <= km; ++r) x[j + r] -= a(j + r, j) * x[j];
    }
    for (int j = n_ - 1; j >= 0; --j) {  // U x = y (U has kl + ku super-diagonals)
      x[j] /= a(j, j);
      for (int i = std::max(0, j - kv); i < j; ++i) x[i] -= a(i, j) * x[j];
    }
  }
}

Eigen::VectorXd BandedLU::Solve(const Eigen::VectorXd& rhs) const {
  Eigen::VectorXd x = rhs;
  SolveInPlace(x);
  return x;
}

void BandedLU::SolveTransposedInPlace(Eigen::Ref<Eigen::MatrixXd> b) const {
  // A^T = U^T L^T P: solve U^T z = b, L^T w = z, x = P^T w.
  const int kv = ku_ + kl_;
  auto a = [&](int i, int j) { return lu_(kv + i - j, j); };
  for (int col = 0; col < b.cols(); ++col) {
    double* x = &b(0, col);
    for (int j = 0; j < n_; ++j) {
      double s = x[j];
      for (int i = std::max(0, j - kv); i < j; ++i) s -= a(i, j) * x[i];
      x[j] = s / a(j, j);
    }
    for (int j = n_ - 1; j >= 0; --j) {
      const int km = std::min(kl_, n_ - 1 - j);
      double s = x[j];
      for (int r = 1; r <= km; ++r) s -= a(j + r, j) * x[j + r];
      x[j] = s;
      const int p = pivots_[j];
      if (p != j) std::swap(x[j], x[p]);
    }
  }
}

int BandedLU::DeterminantSign() const {
  if (!valid_) return 0;
  int sign = 1;
  const int kv = ku_ + kl_;
  for (int j = 0; j < n_; ++j) {
    if (pivots_[j] != j) sign = -sign;
    if (lu_(kv, j) < 0) sign = -sign;
  }
  return sign;
}

bool BandedLDLT::Factor(const BandedSymmetric& A, double diagonal_shift) {
  n_ = A.size();
  p_ = A.bandwidth();
  band_ = A.band();
  negative_ = 0;
  for (int j = 0; j < n_; ++j) band_(0, j) += diagonal_shift;
  double scale = 0.0;
  for (int j = 0; j < n_; ++j) scale = std::max(scale, std::abs(band_(0, j)));
  // Right-looking: column j's pivot d and multipliers l = a / d update the trailing columns.
  std::vector<double> w(p_ + 1);
  for (int j = 0; j < n_; ++j) {
    const double d = band_(0, j);
    if (!std::isfinite(d) || std::abs(d) <= 1e-300 * std::max(scale, 1e-300)) return false;
    if (d < 0) ++negative_;
    const int m = std::min(p_, n_ - 1 - j);
    for (int r = 1; r <= m; ++r) {
      w[r] = band_(r, j);        // a(j + r, j)
      band_(r, j) = w[r] / d;    // l(j + r, j)
    }
    for (int c = 1; c <= m; ++c) {
      double* target = &band_(0, j + c);
      for (int r = c; r <= m; ++r) target[r - c] -= band_(r, j) * w[c];  // l_r d l_c
    }
  }
  return true;
}

void BandedLDLT::SolveInPlace(Eigen::Ref<Eigen::MatrixXd> b) const {
  for (int col = 0; col < b.cols(); ++col) {
    double* x = &b(0, col);
    for (int j = 0; j < n_; ++j) {  // L y = b
      const int m = std::min(p_, n_ - 1 - j);
      for (int r = 1; r <= m; ++r) x[j + r] -= band_(r, j) * x[j];
    }
    for (int j = 0; j < n_; ++j) x[j] /= band_(0, j);  // D
    for (int j = n_ - 1; j >= 0; --j) {  // L^T z = y
      const int m = std::min(p_, n_ - 1 - j);
      double s = x[j];
      for (int r = 1; r <= m; ++r) s -= band_(r, j) * x[j + r];
      x[j] = s;
    }
  }
}

}  // namespace rodfit
