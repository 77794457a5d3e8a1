// Stiffness sensitivities of the equilibrium (sensitivity.h).
#include "rodfit/solve/sensitivity.h"

#include "rodfit/model/material_parameters.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

const char* StiffnessName(Stiffness s) {
  // The parameter table numbers the rod's stiffness rows in this enum's order.
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.kind == ParameterKind::kRodStiffness && row.term == static_cast<int>(s)) return row.name;
  return "?";
}

bool TermSensitivities(const RodModel& model, const RodState& state,
                       const StaticsWorkspace& workspace, const std::vector<EnergyTerms>& terms,
                       Eigen::MatrixXd* dq_dlogp) {
  // A conservative case keeps the Cholesky factor of its Hessian; a case with moments the LU
  // factor of its (non-symmetric) tangent. The moments do not depend on the stiffnesses, so
  // dg/dlog p is the unit term's gradient either way.
  const bool lu = workspace.tangent_valid && workspace.tangent.size() == model.num_free_dofs();
  const bool chol = workspace.factor_valid && !workspace.factor_positions &&
                    workspace.hessian.size() == model.num_free_dofs();
  // A solve with its twist eliminated kept the factor of the position-only Hessian. A parameter
  // that breaks what made the twist vanish (B1 alone makes the rod anisotropic) needs the full
  // Hessian: it is then assembled and factored here, once, at the solution (which has zero twist
  // and is an equilibrium of the full problem).
  const bool positions = workspace.factor_valid && workspace.factor_positions &&
                         workspace.hessian.size() == NumPositionDofs(model);
  if (!workspace.edge_valid && !lu && !chol && !positions) return false;
  // A fine rod's sensitivities in edge coordinates: the solve's own edge factor, or one made
  // here at the (stable) solution.
  EdgeSolver fine;
  const EdgeSolver* edge = workspace.edge_valid ? &workspace.edge : nullptr;
  if (!edge && model.num_edges() >= kEdgeSensitivitySegments && EdgeSolver::Applies(model)) {
    RodFrames frames;
    ComputeRodFrames(model, state, &frames);
    if (fine.Factor(model, state, frames, EnergyTerms(), lu ? 1.0 : 0.0) &&
        fine.positive_definite())
      edge = &fine;
  }
  dq_dlogp->resize(model.num_free_dofs(), static_cast<int>(terms.size()));
  VecX g;
  for (size_t k = 0; k < terms.size(); ++k) {
    AssembleGradient(model, state, terms[k], &g);
    dq_dlogp->col(static_cast<int>(k)) = -g;
  }
  if (edge) {
    edge->SolveInPlace(*dq_dlogp);
  } else if (positions) {
    // A term that keeps the rod isotropic (B1 and B2 scaled alike, or neither) has no twist
    // force at zero twist: its derivative keeps the twist zero, so the kept position-only factor
    // and ZeroTwistVariation give it exactly. One that does not needs the full Hessian.
    bool keeps_isotropy = true;
    for (const EnergyTerms& t : terms) keeps_isotropy = keeps_isotropy && t.bend1 == t.bend2;
    if (keeps_isotropy) {
      VecX column, p;
      for (int k = 0; k < dq_dlogp->cols(); ++k) {
        GatherPositions(dq_dlogp->col(k), &p);
        workspace.hessian.SolveInPlace(p);
        ScatterPositions(p, &column);
        ZeroTwistVariation(model, state, column);
        dq_dlogp->col(k) = column;
      }
    } else {
      BandedSymmetric H;
      BandedCholesky full;
      AssembleHessian(model, state, EnergyTerms(), &g, &H);
      if (!full.Factor(H)) return false;
      full.SolveInPlace(*dq_dlogp);
    }
  } else if (lu) {
    workspace.tangent.SolveInPlace(*dq_dlogp);
  } else {
    workspace.hessian.SolveInPlace(*dq_dlogp);
  }
  return dq_dlogp->allFinite();
}

bool StiffnessSensitivities(const RodModel& model, const RodState& state,
                            const StaticsWorkspace& workspace, const std::vector<Stiffness>& which,
                            Eigen::MatrixXd* dq_dlogp) {
  std::vector<EnergyTerms> terms;
  for (Stiffness s : which) terms.push_back(EnergyTerms::Only(static_cast<int>(s)));
  return TermSensitivities(model, state, workspace, terms, dq_dlogp);
}

Eigen::MatrixXd VertexSensitivities(const RodModel& model, const Eigen::MatrixXd& dq_dlogp) {
  const int n = model.num_edges();
  Eigen::MatrixXd dx = Eigen::MatrixXd::Zero(3 * (n + 1), dq_dlogp.cols());
  for (int i = 1; i <= n; ++i) dx.middleRows<3>(3 * i) = dq_dlogp.middleRows<3>(RodModel::VertexDof(i));
  return dx;
}

}  // namespace rodfit
