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

bool GradientSensitivities(const RodModel& model, const RodState& state,
                           const StaticsWorkspace& workspace, const Eigen::MatrixXd& dg_dp,
                           bool keeps_isotropy, Eigen::MatrixXd* dq_dp) {
  const bool lu = workspace.tangent_valid && workspace.tangent.size() == model.num_free_dofs();
  const bool chol = workspace.factor_valid && !workspace.factor_positions &&
                    workspace.hessian.size() == model.num_free_dofs();
  const bool positions = workspace.factor_valid && workspace.factor_positions &&
                         workspace.hessian.size() == NumPositionDofs(model);
  if (!workspace.edge_valid && !lu && !chol && !positions) return false;
  EdgeSolver fine;
  const EdgeSolver* edge = workspace.edge_valid ? &workspace.edge : nullptr;
  if (!edge && model.num_edges() >= kEdgeSensitivitySegments && EdgeSolver::Applies(model)) {
    RodFrames frames;
    ComputeRodFrames(model, state, &frames);
    if (fine.Factor(model, state, frames, EnergyTerms(), lu ? 1.0 : 0.0) &&
        fine.positive_definite())
      edge = &fine;
  }
  *dq_dp = -dg_dp;
  VecX g;
  if (edge) {
    edge->SolveInPlace(*dq_dp);
  } else if (positions) {
    if (keeps_isotropy) {
      VecX column, p;
      for (int k = 0; k < dq_dp->cols(); ++k) {
        GatherPositions(dq_dp->col(k), &p);
        workspace.hessian.SolveInPlace(p);
        ScatterPositions(p, &column);
        ZeroTwistVariation(model, state, column);
        dq_dp->col(k) = column;
      }
    } else {
      BandedSymmetric H;
      BandedCholesky full;
      AssembleHessian(model, state, EnergyTerms(), &g, &H);
      if (!full.Factor(H)) return false;
      full.SolveInPlace(*dq_dp);
    }
  } else if (lu) {
    workspace.tangent.SolveInPlace(*dq_dp);
  } else {
    workspace.hessian.SolveInPlace(*dq_dp);
  }
  return dq_dp->allFinite();
}

bool TermSensitivities(const RodModel& model, const RodState& state,
                       const StaticsWorkspace& workspace, const std::vector<EnergyTerms>& terms,
                       Eigen::MatrixXd* dq_dlogp) {
  Eigen::MatrixXd dg(model.num_free_dofs(), static_cast<int>(terms.size()));
  VecX g;
  bool keeps_isotropy = true;
  for (size_t k = 0; k < terms.size(); ++k) {
    AssembleGradient(model, state, terms[k], &g);
    dg.col(static_cast<int>(k)) = g;
    keeps_isotropy = keeps_isotropy && terms[k].bend1 == terms[k].bend2;
  }
  return GradientSensitivities(model, state, workspace, dg, keeps_isotropy, dq_dlogp);
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
