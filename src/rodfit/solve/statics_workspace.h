// The statics solver's workspace (include/rodfit/solve/statics.h declares it): the banded factor
// at the last solution and what a warm start needs to reuse it. Internal: it names the banded and
// edge-coordinate factorisations, which are not part of the installed API.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "rodfit/model/rod.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/edge_solver.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// Scratch kept between solves; after a converged, stable solve `hessian` holds the Cholesky
/// factor of the (unshifted) Hessian at the solution when `factor_valid` is true, or, for a case
/// with moments, `tangent` the LU factor of its tangent when `tangent_valid` is true.
struct StaticsWorkspace {
  BandedCholesky hessian;
  bool factor_valid = false;
  /// `hessian` is the factor of the position-only Hessian (StaticsOptions::eliminate_twist):
  /// its size is NumPositionDofs, and sensitivities factor the full Hessian themselves.
  bool factor_positions = false;
  BandedLU tangent;
  bool tangent_valid = false;
  /// A fine rod's factor in edge coordinates (StaticsOptions::edge_solver_segments): when valid,
  /// sensitivities solve with it instead of `hessian` or `tangent`.
  EdgeSolver edge;
  bool edge_valid = false;
  /// The state and model (RodModel::hessian_digest) the kept factor belongs to. A solve that
  /// starts from exactly this state on a model with the same digest (a warm start after a
  /// change of dead loads only) takes its first Newton step with the kept factor, which is the
  /// exact Hessian there, instead of assembling and factoring it again.
  RodState factor_state;
  uint64_t factor_digest = 0;
  /// Pi and its gradient at factor_state without the dead loads: with them, the re-solve's
  /// first iteration needs no assembly at all (Pi is linear in the dead loads).
  double factor_unloaded_energy = 0.0;
  VecX factor_unloaded_gradient;
  /// Unit edge tangents (3 x edges) of the state `hessian` was last factored at, converged or
  /// not: chord steps carry that factor to the current edge directions.
  Eigen::Matrix3Xd factor_tangents;
  /// Scratch: the band the Hessian is assembled into (its storage kept between solves).
  BandedSymmetric scratch_hessian;
};

}  // namespace rodfit
