// Exact sensitivities of the equilibrium to the stiffness parameters (docs/solvers.md,
// "Sensitivities"): at equilibrium g(q, p) = 0, so dq/dp = -H^{-1} dg/dp, with the factorisation
// the statics solver kept. U is linear in each stiffness, so dg/dlog(p) is the gradient of that
// term alone (EnergyTerms::Only). Costs one gradient assembly and one banded back-substitution
// per parameter.
#pragma once

#include <vector>

#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics_workspace.h"

namespace rodfit {

/// From this many segments on (without springs) sensitivities are solved in edge coordinates
/// (edge_solver.h): the vertex factor's condition number ~(2n/pi)^4 costs them ~eps (2n/pi)^4 of
/// relative accuracy, 2e-5 at 1000 segments.
constexpr int kEdgeSensitivitySegments = 1000;

/// The stiffness parameters of the rod model, in EnergyTerms::Only's numbering.
enum class Stiffness { kBend1 = 0, kBend2 = 1, kTwist = 2, kStretch = 3 };

const char* StiffnessName(Stiffness s);

/// dq/dlog(p) for each stiffness in `which`, one column each, in the free-dof ordering
/// (RodModel::VertexDof / TwistDof). Requires a converged, stable solve whose workspace still
/// holds the factorisation (workspace.factor_valid); returns false otherwise.
bool StiffnessSensitivities(const RodModel& model, const RodState& state,
                            const StaticsWorkspace& workspace, const std::vector<Stiffness>& which,
                            Eigen::MatrixXd* dq_dlogp);

/// The general form: one column per energy-term selector (EnergyTerms::Only, OnlySprings),
/// dq/dlog(p) = -H^{-1} grad(term).
bool TermSensitivities(const RodModel& model, const RodState& state,
                       const StaticsWorkspace& workspace, const std::vector<EnergyTerms>& terms,
                       Eigen::MatrixXd* dq_dlogp);

/// The general form of both: dq/dp = -H^{-1} dg/dp for given gradient changes (free dofs x
/// columns, held rows zero), with the solve's kept factor. `keeps_isotropy`: every column keeps
/// an isotropic rod's twist at rest (a bending stiffness scaling B1 and B2 alike, any other
/// stiffness), so that a solve with the twist eliminated may use its positions-only factor; a
/// clamp turned about its tangent does not, and is solved with the whole Hessian then.
bool GradientSensitivities(const RodModel& model, const RodState& state,
                           const StaticsWorkspace& workspace, const Eigen::MatrixXd& dg_dp,
                           bool keeps_isotropy, Eigen::MatrixXd* dq_dp);

/// The derivatives of the free gradient g by turns of a clamp's frame about the world axes at its
/// point (`end`: the end clamp's, else the clamp's at s = 0): free dofs x 3, held rows zero,
/// exact (the ghost edge's stencil differentiated by a Jet; defined in critical_twist.cc, whose
/// nuisance-angle derivatives need it too). `torque` (optional): dPi/d(turn about the clamp's
/// tangent) [N m].
void ClampTurnGradients(const RodModel& model, const RodState& state, bool end,
                        Eigen::MatrixXd* dg_dphi, double* torque = nullptr);

/// Rows of the free-dof sensitivities for vertex positions: d x_i / d log p as a 3(n+1) x m
/// matrix (vertex 0 is clamped: zero rows).
Eigen::MatrixXd VertexSensitivities(const RodModel& model, const Eigen::MatrixXd& dq_dlogp);

}  // namespace rodfit
