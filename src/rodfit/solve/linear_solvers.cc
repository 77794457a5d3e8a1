// The minimizer's linear solve strategies (linear_solvers.h).
#include "rodfit/solve/linear_solvers.h"

#include <algorithm>
#include <cmath>

namespace rodfit {

void BandedCholeskySolver::Solve(VecX* x) const {
  if (!positions_) {
    factor_->SolveInPlace(*x);
    return;
  }
  GatherPositions(*x, &gathered_);
  factor_->SolveInPlace(gathered_);
  ScatterPositions(gathered_, x);
}

double BandedCholeskySolver::MaxDiagonal() const {
  const double d = matrix_->band().row(0).cwiseAbs().maxCoeff();
  // A non-finite entry anywhere makes a pivot non-finite (every entry of the band's blocks enters
  // one), so a failed factor of a finite diagonal may still be a NaN elsewhere: look.
  if (!std::isfinite(d) || !((matrix_->band().array() * 0.0).sum() == 0.0))
    return std::numeric_limits<double>::quiet_NaN();
  return d;
}

double BandedCholeskySolver::NegativeCurvature(double shift_ok, double shift_failed,
                                               int bisections, const VecX& gradient, VecX* d) {
  const BandedSymmetric& H = *matrix_;
  if (positions_) {
    GatherPositions(gradient, &g_);
  } else {
    g_ = gradient;  // same size after the first search: no allocation
  }
  double lo = std::max(shift_failed, 0.0), hi = shift_ok;
  for (int k = 0; k < bisections && hi > 1.0001 * lo; ++k) {
    const double mid = lo > 0.0 ? std::sqrt(lo * hi) : 0.5 * hi;
    if (probe_.Factor(H, mid)) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  if (!best_.Factor(H, hi)) return 0.0;
  v_.resize(H.size());
  v_.setOnes();
  for (int k = 0; k < v_.size(); k += 3) v_[k] = -0.5;
  const double gmax = g_.cwiseAbs().maxCoeff();
  if (gmax > 0) v_ = 1e-3 * v_ - g_ / gmax;
  double rq = 0.0;
  for (int it = 0; it < 40; ++it) {
    best_.SolveInPlace(v_);
    const double scale = v_.cwiseAbs().maxCoeff();
    if (!(scale > 0) || !std::isfinite(scale)) return 0.0;
    v_ /= scale;
    H.MultiplyInto(v_, &hv_);
    const double q = v_.dot(hv_) / v_.squaredNorm();
    if (it > 3 && std::abs(q - rq) <= 1e-6 * std::abs(q)) {
      rq = q;
      break;
    }
    rq = q;
  }
  if (positions_) {
    d->resize(gradient.size());
    d->setZero();
    ScatterPositions(v_, d);
  } else {
    *d = v_;
  }
  return rq;
}

void BandedCholeskySolver::ReserveScratch() {
  const BandedSymmetric& H = *matrix_;
  // A shift far above the diagonal factors any matrix: it sizes the factors' blocks.
  const double big = 1e3 * (H.band().row(0).cwiseAbs().maxCoeff() + 1.0);
  probe_.Factor(H, big);
  best_.Factor(H, big);
  const int n = H.size();  // the position rows alone when positions_: the matrix is theirs
  g_.setZero(n);
  v_.setZero(n);
  hv_.setZero(n);
}

bool BandedLUSolver::Factor(double shift) {
  if (shift == 0.0) return factor_->Factor(*matrix_);
  shifted_ = *matrix_;
  for (int r = 0; r < shifted_.size(); ++r) shifted_.At(r, r) += shift;
  return factor_->Factor(shifted_);
}

bool EdgeCoordinateSolver::Factor(double shift) {
  const bool ok = edge_->Factor(*model_, *state_, *frames_, *terms_, moment_scale_, shift);
  return moment_scale_ > 0.0 ? ok : ok && edge_->positive_definite();
}

void ReserveDenseCholesky(int n, Eigen::LLT<Eigen::MatrixXd>* llt) {
  llt->compute(Eigen::MatrixXd::Identity(n, n));
}

void DenseCholeskySolver::Resize(int n) {
  if (matrix_.rows() == n) return;
  matrix_.setZero(n, n);
  work_.setZero(n, n);
  ReserveDenseCholesky(n, &llt_);
}

bool DenseCholeskySolver::Factor(double shift) {
  // Non-finite entries are caught on the factor's diagonal (O(n), not O(n^2) before factoring):
  // LLT reads the lower triangle, and a NaN or infinity at (i, j) makes L(i, i) NaN or the pivot
  // negative, since L(i, i)^2 = A(i, i) - sum_k L(i, k)^2 with L(i, j) carrying it.
  if (shift == 0.0) {
    llt_.compute(matrix_);  // LLT keeps its own copy: none needed here
  } else {
    work_ = matrix_;
    work_.diagonal().array() += shift;
    llt_.compute(work_);
  }
  return llt_.info() == Eigen::Success && llt_.matrixLLT().diagonal().allFinite();
}

}  // namespace rodfit
