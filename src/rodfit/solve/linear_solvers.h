// The linear solves of the Newton minimizer as strategies (newton_minimizer.h, LinearSolver):
//  - BandedCholeskySolver: the rod's symmetric banded Hessian (statics, time steps, ticks), over
//    every free dof or over the positions alone (twist eliminated);
//  - BandedLUSolver: the non-symmetric banded tangent of a balance with moments;
//  - EdgeCoordinateSolver: a fine rod's steps in edge coordinates (edge_solver.h);
//  - DenseCholeskySolver: the section ring's small dense reduced Hessian.
// Each keeps references to storage its owner keeps (the statics' workspace holds the factor
// that sensitivities reuse), so the strategy itself is cheap to make per solve.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "rodfit/model/rod.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/edge_solver.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

/// A = L L^T of a banded symmetric matrix (banded.h). With `positions`, the matrix is the
/// position-only system of a rod whose twist is eliminated (NumPositionDofs), and Solve maps the
/// free-dof layout to it and back (the twist rows of a solution are zero).
class BandedCholeskySolver : public LinearSolver {
 public:
  BandedCholeskySolver(BandedSymmetric* matrix, BandedCholesky* factor, bool positions = false)
      : matrix_(matrix), factor_(factor), positions_(positions) {}
  bool Factor(double shift) override { return factor_->Factor(*matrix_, shift); }
  void Solve(VecX* x) const override;
  double MaxDiagonal() const override;
  /// Bisects the shift down to the smallest that factors, then inverse iteration with it, from
  /// the descent direction -g plus a fixed non-symmetric vector (within a degenerate eigenspace,
  /// an isotropic column buckling alike in every direction about its axis, it converges to the
  /// mode the loads push, so a heavy rod buckles down, not sideways). Its scratch is kept: once
  /// sized it allocates nothing (the runtime's ticks may escape saddles).
  double NegativeCurvature(double shift_ok, double shift_failed, int bisections,
                           const VecX& gradient, VecX* d) override;
  /// Sizes NegativeCurvature's scratch for the matrix's current shape now (a real-time caller
  /// does it at construction; afterwards nothing allocates).
  void ReserveScratch();

 private:
  BandedSymmetric* matrix_;
  BandedCholesky* factor_;
  bool positions_;
  mutable VecX gathered_;  // the position rows (positions_ only)
  // NegativeCurvature's scratch, kept: after a first search it allocates nothing.
  BandedCholesky probe_, best_;
  VecX g_, v_, hv_;
};

/// P A = L U of a general band matrix (banded.h), the shift added on a copy of the diagonal.
class BandedLUSolver : public LinearSolver {
 public:
  BandedLUSolver(BandedMatrix* matrix, BandedLU* factor) : matrix_(matrix), factor_(factor) {}
  bool Factor(double shift) override;
  void Solve(VecX* x) const override { factor_->SolveInPlace(*x); }
  double MaxDiagonal() const override {
    return matrix_->AllFinite() ? matrix_->MaxDiagonal() : std::numeric_limits<double>::quiet_NaN();
  }

 private:
  BandedMatrix* matrix_;
  BandedLU* factor_;
  BandedMatrix shifted_;
};

/// A fine rod's tangent in edge coordinates (edge_solver.h), factored at the state the problem
/// points it to (At). Conservative: positive definite on the held points' constraint space is
/// required; with moments (moment_scale > 0), only non-singular. Its diagonal is never assembled:
/// MaxDiagonal is the rod's stiffest scale, max(EA / l, B / l^3, GJ / l). It cannot look for
/// negative curvature (NegativeCurvature is NaN: a shifted stationary point is reported
/// unstable).
class EdgeCoordinateSolver : public LinearSolver {
 public:
  EdgeCoordinateSolver(EdgeSolver* edge, double stiffest_scale)
      : edge_(edge), scale_(stiffest_scale) {}
  void At(const RodModel* model, const RodState* state, const RodFrames* frames,
          const EnergyTerms* terms, double moment_scale) {
    model_ = model, state_ = state, frames_ = frames, terms_ = terms, moment_scale_ = moment_scale;
  }
  bool Factor(double shift) override;
  void Solve(VecX* x) const override { edge_->SolveInPlace(*x); }
  double MaxDiagonal() const override { return scale_; }
  double NegativeCurvature(double, double, int, const VecX&, VecX*) override {
    return std::numeric_limits<double>::quiet_NaN();
  }

 private:
  EdgeSolver* edge_;
  double scale_;
  const RodModel* model_ = nullptr;
  const RodState* state_ = nullptr;
  const RodFrames* frames_ = nullptr;
  const EnergyTerms* terms_ = nullptr;
  double moment_scale_ = 0.0;
};

/// Sizes `llt`'s storage for n x n matrices, so that factoring one later allocates nothing, by
/// factoring the n x n identity. Not `*llt = Eigen::LLT<Eigen::MatrixXd>(n)`: Eigen's sizing
/// constructor leaves the factorization's status (an enum) uninitialized, and the assignment copies
/// it, which is undefined behaviour (an invalid enum value; the sanitized runtime tests aborted on
/// it in the ring solver).
void ReserveDenseCholesky(int n, Eigen::LLT<Eigen::MatrixXd>* llt);

/// A = L L^T of a small dense symmetric matrix (Eigen's LLT), the shift added on a kept copy:
/// no allocation once sized.
class DenseCholeskySolver : public LinearSolver {
 public:
  /// The matrix the problem assembles into; sized once.
  Eigen::MatrixXd& matrix() { return matrix_; }
  void Resize(int n);
  bool Factor(double shift) override;
  void Solve(VecX* x) const override { llt_.solveInPlace(*x); }
  double MaxDiagonal() const override {
    return matrix_.allFinite() ? matrix_.diagonal().cwiseAbs().maxCoeff()
                               : std::numeric_limits<double>::quiet_NaN();
  }
  const Eigen::LLT<Eigen::MatrixXd>& llt() const { return llt_; }

 private:
  Eigen::MatrixXd matrix_, work_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

}  // namespace rodfit
