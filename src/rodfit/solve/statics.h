// Quasi-static equilibrium of a RodModel: Newton on the free dofs with a banded Cholesky
// factorisation (O(n) per iteration), Armijo line search on the potential energy, a diagonal
// shift when the Hessian is indefinite, load continuation when a full-load step fails, and a
// hard iteration cap (DESIGN.md §2). The factorisation at the solution is kept in the workspace
// for sensitivities dx/dp = -H^{-1} dg/dp.
#pragma once

#include <string>

#include "rodfit/model/rod.h"
#include "rodfit/solve/banded.h"

namespace rodfit {

struct StaticsOptions {
  int max_iterations = 300;            ///< Newton iterations in all, over every load step
  /// Converged when the largest free generalised force is below this times the case's
  /// force scale (moments divided by the rod length). Relative, dimensionless.
  double gradient_tolerance = 1e-9;
  /// Also converged when the Newton step (the distance to the solution once Newton converges
  /// quadratically) is below this times the edge length on positions and this in radians on
  /// twist, and the gradient is below 1e-5 of the force scale. Stiff stretch (EA L^2 / EI >> 1)
  /// puts a round-off floor of ~ eps EA |x| / l on the gradient that the first test cannot pass.
  double step_tolerance = 1e-9;
  int max_line_search_steps = 30;      ///< halvings before a step counts as failed
  double armijo = 1e-4;                ///< sufficient-decrease constant
  int max_load_steps = 64;             ///< load increments before giving up on continuation
  double max_rotation_per_step = 0.5;  ///< [rad] cap on any tangent's turn in one Newton step
  /// Between Newton steps, take chord steps with the last factor (carried to the current edge
  /// directions, see statics.cc) while they converge fast; the Hessian is always assembled and
  /// factored at the solution, so the result and the kept factor do not depend on this.
  bool chord_steps = true;
  bool Check(std::string* why) const;
};

struct StaticsSummary {
  bool converged = false;
  int iterations = 0;            ///< Newton iterations (chord steps included)
  int chord_steps = 0;           ///< of which chord steps (StaticsOptions::chord_steps)
  /// False when the equilibrium found is not a minimum (the Hessian there is indefinite, e.g. a
  /// column loaded past its buckling load and kept perfectly straight). Such a state is an
  /// equilibrium, but an experiment would not show it.
  bool stable = true;
  int load_steps = 1;            ///< load increments used (1 = solved at full load directly)
  double gradient_norm = 0.0;    ///< [N] largest free generalised force at exit (moments / L)
  double energy = 0.0;           ///< [J] potential energy at exit
  std::string reason;            ///< why the solver stopped
  bool IsUsable() const { return converged; }
  std::string BriefReport() const;
};

/// Scratch kept between solves; after a converged solve `hessian` holds the Cholesky factor of
/// the (unshifted) Hessian at the solution when `factor_valid` is true (a stable equilibrium).
struct StaticsWorkspace {
  BandedCholesky hessian;
  bool factor_valid = false;
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
};

/// Solves for equilibrium starting from *state (a warm start, or model.StraightState()).
/// On failure *state is left at the last accepted iterate and the summary says why.
StaticsSummary SolveStatics(const RodModel& model, const StaticsOptions& options,
                            RodState* state, StaticsWorkspace* workspace = nullptr);

}  // namespace rodfit
