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
  VecX g;
  if (positions_) {
    GatherPositions(gradient, &g);
  } else {
    g = gradient;
  }
  double lo = std::max(shift_failed, 0.0), hi = shift_ok;
  BandedCholesky probe, best;
  for (int k = 0; k < bisections && hi > 1.0001 * lo; ++k) {
    const double mid = lo > 0.0 ? std::sqrt(lo * hi) : 0.5 * hi;
    if (probe.Factor(H, mid)) {
      hi = mid;
    } else {
      lo = mid;
    }
  }
  if (!best.Factor(H, hi)) return 0.0;
  VecX v = VecX::Ones(H.size());
  for (int k = 0; k < v.size(); k += 3) v[k] = -0.5;
  const double gmax = g.cwiseAbs().maxCoeff();
  if (gmax > 0) v = 1e-3 * v - g / gmax;
  double rq = 0.0;
  for (int it = 0; it < 40; ++it) {
    best.SolveInPlace(v);
    const double scale = v.cwiseAbs().maxCoeff();
    if (!(scale > 0) || !std::isfinite(scale)) return 0.0;
    v /= scale;
    const double q = v.dot(H.Multiply(v)) / v.squaredNorm();
    if (it > 3 && std::abs(q - rq) <= 1e-6 * std::abs(q)) {
      rq = q;
      break;
    }
    rq = q;
  }
  if (positions_) {
    d->setZero(gradient.size());
    ScatterPositions(v, d);
  } else {
    *d = v;
  }
  return rq;
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

void DenseCholeskySolver::Resize(int n) {
  if (matrix_.rows() == n) return;
  matrix_.setZero(n, n);
  work_.setZero(n, n);
  llt_ = Eigen::LLT<Eigen::MatrixXd>(n);
}

bool DenseCholeskySolver::Factor(double shift) {
  if (!matrix_.allFinite()) return false;
  work_ = matrix_;
  if (shift != 0.0) work_.diagonal().array() += shift;
  llt_.compute(work_);
  return llt_.info() == Eigen::Success;
}

}  // namespace rodfit
