// Newton steps of a fine rod in edge coordinates (docs/solvers.md, "Fine rods"). In vertex
// coordinates the bending stiffness is a fourth-order difference operator: its condition number
// grows as (2n/pi)^4, 1e15 at 10^4 segments and 1e19 at 10^5, beyond double precision, so the
// banded Cholesky's step loses the soft (global) modes. In edge coordinates (e_j = x_{j+1} - x_j)
// every term is local (bending couples two consecutive edges, stretch one, moments one) and the
// operator is of second order: condition ~n^2. Held vertices become linear constraints
// sum_{j<k} de_j = 0, solved by a Schur complement on their multipliers (3 per held point);
// dead loads are linear and leave the Hessian alone. Springs tie every vertex to the ground, a
// dense matrix in edge coordinates; they also bound the vertex-coordinate condition number, so
// scenes with springs keep the vertex-coordinate factor.
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "rodfit/model/rod.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

class EdgeSolver {
 public:
  /// Whether a model can use it: no springs (nor a symmetric half's crossing edge, whose stretch
  /// ties its last vertex to the plane).
  static bool Applies(const RodModel& model) {
    return !model.has_springs() && !model.symmetric();
  }

  /// Factors the tangent at a state with fresh frames, plus `shift` on its diagonal: the Hessian
  /// of Pi under `terms` (hold and springs ignored) and, when `moment_scale` > 0 and the model
  /// carries moments, their load stiffness and the twist holonomy (the balance's tangent,
  /// moment_loads.h). False when it is singular (or an unpivoted LDL^T breaks down).
  bool Factor(const RodModel& model, const RodState& state, const RodFrames& frames,
              const EnergyTerms& terms, double moment_scale, double shift = 0.0);
  bool valid() const { return valid_; }
  /// Whether the (symmetric part of the) tangent is positive definite on the displacements the
  /// held points allow: by the inertia of the KKT matrix (Haynsworth), when the tangent K has as
  /// many negative eigenvalues as the constraints' Schur complement C K^-1 C^T.
  bool positive_definite() const { return positive_definite_; }

  /// Solves K dx = rhs in vertex coordinates (RodModel::VertexDof / TwistDof layout) with the held
  /// dofs' rows of K replaced by identity rows and rhs zero there, as the Dirichlet assembly
  /// has it: dx is zero on held dofs. Columns are solved one by one.
  void SolveInPlace(Eigen::Ref<Eigen::MatrixXd> rhs) const;

 private:
  void ToEdge(const double* x, double* e) const;   // suffix sums (A^-T)
  void ToVertex(const double* e, double* x) const; // prefix sums (A^-1)

  void Solve(double* e) const;  // K^-1 in edge coordinates
  // Factor's steps: the symmetric part assembled into Ks_ (with dPi/dtheta for the holonomy),
  // the factors, and the held points' constraints' Schur complement.
  void AssembleSymmetric(const RodModel& model, const RodState& state, const RodFrames& frames,
                         const EnergyTerms& terms, double shift, VecX* theta_gradient);
  bool FactorTangent(const RodModel& model, const RodFrames& frames, const EnergyTerms& terms,
                     double moment_scale, const VecX& theta_gradient);
  bool FactorConstraints();

  bool valid_ = false, positive_definite_ = false, symmetric_ = true;
  int n_ = 0, size_ = 0;
  std::vector<int> held_vertices_;
  std::vector<char> held_dofs_;
  bool ghost_ = false, ghost_twist_held_ = false;
  BandedSymmetric Ks_;                // the tangent's symmetric part (assembly scratch)
  BandedLDLT ldlt_;                   // the symmetric part: solves (conservative) and inertia
  BandedLU lu_;                       // the tangent itself, with moments
  Eigen::MatrixXd Y_;                 // K^-1 C^T
  Eigen::PartialPivLU<Eigen::MatrixXd> schur_;  // C K^-1 C^T
};

}  // namespace rodfit
