// Quasi-static equilibrium of a RodModel (docs/solvers.md): Newton on the free dofs with a
// banded Cholesky factorisation (O(n) per iteration), Armijo line search on the potential
// energy, a diagonal shift when the Hessian is indefinite, an escape from saddles along their
// negative curvature, load continuation when a full-load step fails, continuation of held
// points from where the start state has them, and a hard cap on every loop. A case that carries
// moments has no potential: its balance is solved with the non-symmetric tangent (banded LU) and
// a line search on the residual. The factorisation at the solution is kept in the workspace for
// sensitivities dx/dp = -K^{-1} dg/dp.
#pragma once

#include <memory>
#include <string>

#include "rodfit/model/rod.h"

namespace rodfit {

/// From this many segments on, the continuation of held points (StaticsOptions::
/// edge_solver_segments) runs in edge coordinates.
inline constexpr int kEdgeContinuationSegments = 5000;

struct StaticsOptions {
  int max_iterations = 300;            ///< Newton iterations in all, over every load step
  /// Converged when ScaledGradientNorm (the largest free generalised force per length, times L)
  /// is below this times the case's load scale (RodModel::force_scale). Relative.
  double gradient_tolerance = 1e-9;
  /// Also converged when an unshifted Newton step (the distance to the solution once Newton
  /// converges quadratically) is below this times the rod length on positions and this in
  /// radians on twist, or below 1e3 times that where the gradient is at its round-off floor: a
  /// stiff stretch (EA L^2 / EI >> 1) leaves a floor of ~eps EA on each force that the first test
  /// may not pass, while the state is as exact as doubles allow.
  double step_tolerance = 1e-9;
  int max_load_steps = 64;             ///< load increments before giving up on continuation
  /// Continuation of held points and clamp frames from the start state to their targets: the
  /// largest move per step, as a fraction of the rod length and in radians, and the cap on steps.
  double continuation_move = 0.1;
  double continuation_turn = 0.3;
  int max_continuation_steps = 2000;
  /// Leave a saddle (a converged state with a negative curvature direction, such as a straight
  /// column past its buckling load) along that direction. Off: report it as unstable.
  bool escape_saddles = true;
  /// Between Newton steps, take chord steps with the last factor (carried to the current edge
  /// directions, see statics.cc) while they converge fast; the Hessian is always assembled and
  /// factored at the solution, so the result and the kept factor do not depend on this.
  bool chord_steps = true;
  /// From this many segments on (and without springs), Newton steps are solved in edge
  /// coordinates (edge_solver.h): the vertex-coordinate bending operator's condition number,
  /// ~(2n/pi)^4, is 1e17 at 2e4 segments, where the vertex factor's steps lose the soft modes.
  /// Below it the vertex factor's steps, inexact in their last digits, still converge (and keep
  /// the kept factor and chord steps of warm re-solves); sensitivities, which need every digit,
  /// switch to edge coordinates from kEdgeSensitivitySegments (sensitivity.h).
  int edge_solver_segments = 20000;
  /// Drop the twist angles from Newton's unknowns when nothing can twist the rod
  /// (TwistCanBeEliminated: isotropic bending, no rest curvature or twist, no moments, no end
  /// frame held about its tangent): the equilibrium then has zero twist, and the system over the
  /// positions alone is exact and smaller (docs/solvers.md, "Twist elimination"). Off: the twist
  /// is solved for like any scene's (for comparisons; `rodfit bench --skips`).
  bool eliminate_twist = true;
  bool Check(std::string* why) const;
};

struct StaticsSummary {
  bool converged = false;
  int iterations = 0;            ///< Newton iterations (chord steps included)
  int chord_steps = 0;           ///< of which chord steps (StaticsOptions::chord_steps)
  /// False when the equilibrium found is not a minimum: the Hessian (for a case with moments,
  /// the symmetric part of the tangent) has a negative direction, e.g. a column loaded past its
  /// buckling load and held straight. Such a state is an equilibrium, but an experiment would not
  /// show it.
  bool stable = true;
  bool nonconservative = false;  ///< the case carries moments (non-symmetric tangent)
  int load_steps = 1;            ///< load increments used (1 = solved at full load directly)
  int continuation_steps = 0;    ///< steps that moved held points / clamps to their targets
  int saddle_escapes = 0;        ///< steps taken along a negative curvature
  bool twist_eliminated = false; ///< Newton's last system was over the positions only
  double gradient_norm = 0.0;    ///< [N] ScaledGradientNorm at exit
  double energy = 0.0;           ///< [J] potential energy at exit (conservative part)
  std::string reason;            ///< why the solver stopped
  std::string reason_detail;     ///< how a converged solve ended, when not by its tolerance
  bool IsUsable() const { return converged; }
  std::string BriefReport() const;
};

/// Scratch kept between solves: the factor at the last solution, for warm starts and
/// sensitivities. Its layout is internal (src/rodfit/solve/statics_workspace.h); a caller that
/// re-solves one case many times (after a change of its dead loads, or of a parameter) keeps one
/// from NewStaticsWorkspace() and passes it to every solve.
struct StaticsWorkspace;

/// An empty workspace (no kept factor).
std::shared_ptr<StaticsWorkspace> NewStaticsWorkspace();


/// Solves for equilibrium starting from *state (a warm start, model.StraightState(), or a start
/// shape). Held points, the clamp and an end clamp's frame are moved from where *state has them
/// to the model's targets by continuation. On failure *state is left at the last accepted
/// iterate and the summary says why.
StaticsSummary SolveStatics(const RodModel& model, const StaticsOptions& options,
                            RodState* state, StaticsWorkspace* workspace = nullptr);

/// The residual of the balance at a state (the gradient of Pi minus the moments' generalised
/// forces), with held rows zeroed: zero at equilibrium.
void BalanceResidual(const RodModel& model, const RodState& state, VecX* residual);

}  // namespace rodfit
