// Assembly of the rod's potential energy Pi = U - W over the free dofs (DESIGN.md §1): one
// bend–twist stencil per vertex (model/vertex_stencil.h), one stretch term per edge, dead vertex
// loads. Gradients and banded Hessians are assembled from the stencils; frames must be fresh
// (see ApplyStep), which is how the solver keeps them.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "rodfit/model/rod.h"
#include "rodfit/model/vertex_stencil.h"
#include "rodfit/solve/banded.h"

namespace rodfit {

/// Half bandwidth of the Hessian in the block ordering of RodModel::VertexDof/TwistDof.
constexpr int kRodBandwidth = 11;

/// Which parts of the energy to include. The load factor scales every external load (load
/// continuation); the stiffness factors scale the model's B1, B2, GJ, EA. U is linear in each
/// stiffness, so the gradient with one factor 1, the others 0 and no loads is dg/dlog(p) of that
/// stiffness (sensitivities).
struct EnergyTerms {
  double load_scale = 1.0;
  bool loads = true;
  double bend1 = 1.0, bend2 = 1.0, twist = 1.0, stretch = 1.0, springs = 1.0;
  /// With springs on: only the zones whose parameter is this name ("" = spring_stiffness);
  /// null = every zone.
  const std::string* spring_parameter = nullptr;
  /// Hold the grasped vertex (zero its gradient, identity rows in the Hessian). Off only to read
  /// the constraint's reaction from the gradient.
  bool fix_grasp = true;

  bool AnyBendTwist() const { return bend1 != 0.0 || bend2 != 0.0 || twist != 0.0; }
  /// Only the springs of zones with parameter `name` ("" = spring_stiffness), no loads.
  static EnergyTerms OnlySprings(const std::string* name) {
    EnergyTerms t = Only(-1);
    t.springs = 1.0;
    t.spring_parameter = name;
    return t;
  }
  /// Only the elastic energy (no loads).
  static EnergyTerms Elastic() {
    EnergyTerms t;
    t.loads = false;
    return t;
  }
  /// Only the stiffness named by `which` (0 = B1, 1 = B2, 2 = GJ, 3 = EA), no loads.
  static EnergyTerms Only(int which) {
    EnergyTerms t;
    t.loads = false;
    t.bend1 = which == 0, t.bend2 = which == 1, t.twist = which == 2, t.stretch = which == 3;
    t.springs = 0.0;
    return t;
  }
};

/// Per-edge frames of a state (ComputeRodFrames): the ghost edge (index 0, the clamp frame) and
/// edges 0..n-1 (index j + 1), each with its unit tangent, length and material directors, the
/// reference director transported by the first-order transport about its reference tangent.
/// `fresh` says the frames are fresh (every tangent within 1e-13 of its reference tangent, as
/// ApplyStep leaves them); only then do the energy and assembly use them, computing each edge
/// once instead of once per vertex and no transport. The solver computes them once per state
/// and passes them to every evaluation at that state.
struct RodFrames {
  struct Edge {
    Vec3 t, d1, d2;
    double len = 0.0;
  };
  std::vector<Edge> edges;
  bool fresh = false;
};
void ComputeRodFrames(const RodModel& model, const RodState& state, RodFrames* frames);

/// The dead loads' part of Pi, -load_scale sum_i f_i . x_i, and of its gradient, -load_scale f_i
/// on x_i's dofs (added to *gradient; with hold_grasp, not on the held vertex, whose rows the
/// assembly zeroes). Pi is linear in them, so a change of dead loads changes only these parts.
double DeadLoadEnergy(const RodModel& model, const RodState& state, double load_scale);
void AddDeadLoadGradient(const RodModel& model, double load_scale, bool hold_grasp,
                         VecX* gradient);

/// Gathers vertex i's stencil q = [x_prev, x_mid, x_next, theta_e, theta_f], its constants and
/// the free-dof index of each entry (-1 for a fixed one: the clamp and the ghost edge).
void GatherVertexStencil(const RodModel& model, const RodState& state, int i, double load_scale,
                         double q[11], VertexStencilConstants* constants,
                         std::array<int, 11>* dof);

double PotentialEnergy(const RodModel& model, const RodState& state,
                       const EnergyTerms& terms = EnergyTerms());

/// The same for a state whose frames are fresh (reference tangents equal to the edges', as
/// ApplyStep leaves them): the transports are then the identity and the reference twist the
/// stored one, so each edge's frame is computed once and no transport is evaluated. Equal to
/// PotentialEnergy to round-off there, and PotentialEnergy itself for any other state. The
/// assembly takes the same shortcut; the solver uses both.
double PotentialEnergyFreshFrames(const RodModel& model, const RodState& state,
                                  const EnergyTerms& terms = EnergyTerms(),
                                  const RodFrames* frames = nullptr);

/// Gradient of Pi over the free dofs (size 4n).
/// `frames`, if given, must be ComputeRodFrames of `state` (computed here otherwise).
void AssembleGradient(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                      VecX* gradient, const RodFrames* frames = nullptr);

/// Gradient and banded Hessian of Pi over the free dofs.
void AssembleHessian(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                     VecX* gradient, BandedSymmetric* hessian,
                     const RodFrames* frames = nullptr);

/// state + alpha * step over the free dofs, with reference frames transported in time to the
/// new tangents and the reference twist carried along (continuous). Returns false, leaving *out
/// unspecified, if an edge would collapse or a tangent would turn by more than ~pi.
bool ApplyStep(const RodModel& model, const RodState& state, const VecX& step, double alpha,
               RodState* out);

/// Largest turn [rad] of any edge tangent under state + step (used to limit Newton steps).
double MaxTangentTurn(const RodModel& model, const RodState& state, const VecX& step);

/// The force [N] the rod exerts on the instrument at the grasped vertex: minus the constraint
/// force that holds it, -dPi/dx_k at equilibrium (zero without a grasp).
Vec3 GraspReaction(const RodModel& model, const RodState& state);

/// Largest free generalised force [N]: forces, and moments divided by the rod length.
double ScaledGradientNorm(const RodModel& model, const VecX& gradient);

}  // namespace rodfit
