// Assembly of the rod's potential energy Pi = U - W over the free dofs (DESIGN.md §1): one
// bend–twist stencil per vertex (model/vertex_stencil.h), one stretch term per edge, dead vertex
// loads. Gradients and banded Hessians are assembled from the stencils; frames must be fresh
// (see ApplyStep), which is how the solver keeps them.
#pragma once

#include <array>

#include "rodfit/model/rod.h"
#include "rodfit/model/vertex_stencil.h"
#include "rodfit/solve/banded.h"

namespace rodfit {

/// Half bandwidth of the Hessian in the block ordering of RodModel::VertexDof/TwistDof.
constexpr int kRodBandwidth = 11;

/// Which parts of the energy to include; the load factor scales every external load
/// (load continuation) and `stiffness` can replace the model's (sensitivities use unit ones).
struct EnergyTerms {
  double load_scale = 1.0;
  bool elastic = true;
  bool loads = true;
};

/// Gathers vertex i's stencil q = [x_prev, x_mid, x_next, theta_e, theta_f], its constants and
/// the free-dof index of each entry (-1 for a fixed one: the clamp and the ghost edge).
void GatherVertexStencil(const RodModel& model, const RodState& state, int i, double load_scale,
                         double q[11], VertexStencilConstants* constants,
                         std::array<int, 11>* dof);

double PotentialEnergy(const RodModel& model, const RodState& state,
                       const EnergyTerms& terms = EnergyTerms());

/// Gradient of Pi over the free dofs (size 4n).
void AssembleGradient(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                      VecX* gradient);

/// Gradient and banded Hessian of Pi over the free dofs.
void AssembleHessian(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                     VecX* gradient, BandedSymmetric* hessian);

/// state + alpha * step over the free dofs, with reference frames transported in time to the
/// new tangents and the reference twist carried along (continuous). Returns false, leaving *out
/// unspecified, if an edge would collapse or a tangent would turn by more than ~pi.
bool ApplyStep(const RodModel& model, const RodState& state, const VecX& step, double alpha,
               RodState* out);

/// Largest turn [rad] of any edge tangent under state + step (used to limit Newton steps).
double MaxTangentTurn(const RodModel& model, const RodState& state, const VecX& step);

/// Largest free generalised force [N]: forces, and moments divided by the rod length.
double ScaledGradientNorm(const RodModel& model, const VecX& gradient);

}  // namespace rodfit
