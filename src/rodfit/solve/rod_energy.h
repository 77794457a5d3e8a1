// Assembly of the rod's potential energy Pi = U - W over the free dofs (docs/model.md): one
// bend–twist stencil per bending vertex (model/vertex_stencil.h), one stretch term per edge,
// springs, dead vertex loads. Gradients and banded Hessians are assembled from the stencils;
// frames must be fresh (see ApplyStep), which is how the solver keeps them. Held vertices have
// Dirichlet rows (zero gradient, identity in the Hessian). Moments, which have no potential, are
// added by solve/moment_loads.h.
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
/// Half bandwidth of the position-only Hessian (twist eliminated): blocks [x_i], each term
/// coupling three consecutive vertices.
constexpr int kRodPositionBandwidth = 8;

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
  /// Hold the held vertices (zero their gradient, identity rows in the Hessian). Off only to
  /// read the constraints' reactions from the gradient.
  bool hold = true;
  /// Per bending vertex, the rest curvature to use instead of the model's (null: the model's).
  /// The gradient is affine in it, so the difference of two gradients with the same other terms
  /// is exactly the derivative along the difference of rest curvatures (sensitivities of a
  /// fitted rest shape).
  const std::vector<Vec3>* rest_curvature = nullptr;
  const Vec3& RestCurvature(const RodModel& model, int i) const {
    return rest_curvature ? (*rest_curvature)[i] : model.rest_curvature(i);
  }

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

/// Per-edge frames of a state (ComputeRodFrames): the clamp's ghost edge (index 0), edges
/// 0..n-1 (index j + 1) and, with an end clamp, its ghost edge (index n + 1), each with its unit
/// tangent, length and material directors, the reference director transported by the
/// first-order transport about its reference tangent. `fresh` says the frames are fresh (every
/// tangent within 1e-13 of its reference tangent, as ApplyStep leaves them); only then do the
/// energy and assembly use them, computing each edge once instead of once per vertex and no
/// transport. The solver computes them once per state and passes them to every evaluation at
/// that state.
struct RodFrames {
  struct Edge {
    Vec3 t, d1, d2;
    double len = 0.0;
  };
  std::vector<Edge> edges;
  bool fresh = false;
};
void ComputeRodFrames(const RodModel& model, const RodState& state, RodFrames* frames);
/// The frames of indices first..last only (0: the clamp's ghost, j + 1: edge j, n + 1: the end
/// ghost); `fresh` then speaks for those alone. The others keep what they held.
void ComputeRodFrames(const RodModel& model, const RodState& state, int first, int last,
                      RodFrames* frames);

/// Stretch of one edge, E = EA L0 / 2 (|e| / L0 - 1)^2: its gradient dE/de and (optionally)
/// Hessian with respect to the edge vector e.
void StretchGradientHessian(double EA, double L0, const Vec3& e, Vec3* g, Eigen::Matrix3d* H);

/// A symmetric half's share of its crossing edge's stretch (rod.h, symmetric()), with its first
/// and second derivatives with respect to d, the last vertex's distance to the plane.
double CrossingStretch(const RodModel& model, const RodState& state, double stretch_factor,
                       double* dE_dd, double* d2E_dd2);

/// Number of bending vertices: 0..n-1, and n with an end clamp or a symmetry plane.
inline int NumBendingVertices(const RodModel& model) {
  return model.num_edges() + (model.has_end_ghost() ? 1 : 0);
}

/// The dead loads' part of Pi, -load_scale sum_i f_i . x_i, and of its gradient, -load_scale f_i
/// on x_i's dofs (added to *gradient; with hold, not on held vertices, whose rows the assembly
/// zeroes). Pi is linear in them, so a change of dead loads changes only these parts.
double DeadLoadEnergy(const RodModel& model, const RodState& state, double load_scale);
void AddDeadLoadGradient(const RodModel& model, double load_scale, bool hold, VecX* gradient);

/// Gathers vertex i's stencil q = [x_prev, x_mid, x_next, theta_e, theta_f], its constants and
/// the free-dof index of each entry (-1 for a fixed one: the clamp and its ghost edge). Vertex n
/// (with an end clamp) has the end ghost as its edge f.
void GatherVertexStencil(const RodModel& model, const RodState& state, int i,
                         double q[11], VertexStencilConstants* constants,
                         std::array<int, 11>* dof);

double PotentialEnergy(const RodModel& model, const RodState& state,
                       const EnergyTerms& terms = EnergyTerms());

/// The same for a state whose frames are fresh (reference tangents equal to the edges', as
/// ApplyStep leaves them): the transports are then the identity and the reference twist the
/// stored one, so each edge's frame is computed once and no transport is evaluated. Equal to
/// PotentialEnergy to round-off there, and PotentialEnergy itself for any other state.
double PotentialEnergyFreshFrames(const RodModel& model, const RodState& state,
                                  const EnergyTerms& terms = EnergyTerms(),
                                  const RodFrames* frames = nullptr);

/// Gradient of Pi over the free dofs (size num_free_dofs()).
/// `frames`, if given, must be ComputeRodFrames of `state` (computed here otherwise).
void AssembleGradient(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                      VecX* gradient, const RodFrames* frames = nullptr);

/// The rows of AssembleGradient for the positions of vertices first_vertex..last_vertex and
/// the twists of edges first_vertex - 1..last_vertex, equal to it to the last bit (the same
/// terms summed in the same order), from the stencils, edges and springs that reach them alone:
/// a held point's reaction without the whole rod's gradient. The other rows of *gradient hold
/// partial sums. *frames is scratch (the frames of the edges involved).
void AssembleGradientRows(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                          int first_vertex, int last_vertex, VecX* gradient, RodFrames* frames);

/// Gradient and banded Hessian of Pi over the free dofs.
void AssembleHessian(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                     VecX* gradient, BandedSymmetric* hessian,
                     const RodFrames* frames = nullptr);

/// Twist elimination (docs/solvers.md, "Twist elimination"). When nothing can twist the rod,
/// its equilibrium has zero material twist at every vertex, and the twist angles follow from
/// the positions (SetZeroTwist): isotropic bending (B1 == B2), no rest curvature or rest twist,
/// no moment loads, and no end frame held about its tangent (an end clamp without a normal, an
/// end pin or a free end). The statics solver then carries the positions only.
bool TwistCanBeEliminated(const RodModel& model);

/// Sets every twist angle (and a free end ghost's) so that the material twist
/// theta_f - theta_e + reference twist is zero at every vertex, from the clamp on.
void SetZeroTwist(const RodModel& model, RodState* state);

/// The first-order change of the zero-twist angles (SetZeroTwist) under a change of the
/// positions: given dq's position rows (free-dof layout), fills its twist rows. At fresh frames
/// the reference twist at vertex i changes by kb_i . (dt_e + dt_f) / 2 with dt = (I - t t^T) de /
/// |e| (the clamp's and an end ghost's tangents fixed), and each twist angle follows it from the
/// clamp on. Exact derivatives of a twist-eliminated equilibrium (sensitivities) are then the
/// position-only solve and this.
void ZeroTwistVariation(const RodModel& model, const RodState& state, Eigen::Ref<VecX> dq);

/// The position-only system of a rod whose twist is eliminated: the free dofs without the twist
/// angles, 3 per block of RodModel::VertexDof (block j = x_{j+1}; an end ghost's vertex last).
inline int NumPositionDofs(const RodModel& model) { return 3 * (model.num_free_dofs() / 4); }
/// The position-only index of free dof k (k not a twist dof).
inline int PositionDof(int k) { return 3 * (k / 4) + k % 4; }
/// The position rows of a free-dof vector, and back (twist rows zero).
void GatherPositions(const VecX& free, VecX* positions);
void ScatterPositions(const VecX& positions, VecX* free);

/// Gradient of Pi over the free dofs with its twist rows zeroed, and the Hessian of the
/// twist-eliminated energy over the positions (NumPositionDofs, 3 x 3 blocks): each vertex
/// stencil's Hessian restricted to the motions that keep its twist zero (the twist angles
/// follow the reference twist), which is exact where the twist is zero and the rod isotropic
/// (the stencil's twist gradient vanishes there). `state` must have zero twist (SetZeroTwist).
void AssemblePositionHessian(const RodModel& model, const RodState& state,
                             const EnergyTerms& terms, VecX* gradient, BandedSymmetric* hessian,
                             const RodFrames* frames = nullptr);

/// Whether free dof k is held (a held vertex's coordinate, an end ghost's vertex, or a held
/// ghost twist): such dofs have Dirichlet rows.
const std::vector<char>& HeldDofs(const RodModel& model);

/// HeldDofs for the position-only system (NumPositionDofs).
std::vector<char> HeldPositionDofs(const RodModel& model);

/// Dirichlet rows and columns for the held dofs: zero gradient, identity diagonal (either may be
/// null).
void ApplyHeldRows(const std::vector<char>& held, VecX* gradient, BandedSymmetric* H);

/// state + alpha * step over the free dofs, with reference frames transported in time to the
/// new tangents and the reference twist carried along (continuous). Edges are retracted one by
/// one (see rod_energy.cc); held vertices stay where they are. Returns false, leaving *out
/// unspecified, if an edge would collapse or a tangent would turn by more than ~pi.
bool ApplyStep(const RodModel& model, const RodState& state, const VecX& step, double alpha,
               RodState* out);

/// Re-transports the reference frames of `next` (whose e and x are set) from those of `prev`
/// and recomputes the reference twists, kept continuous. False at a full reversal of a tangent.
bool UpdateReferenceFrames(const RodModel& model, const RodState& prev, RodState* next);

/// Largest turn [rad] of any edge tangent under state + step (used to limit Newton steps).
double MaxTangentTurn(const RodModel& model, const RodState& state, const VecX& step);

/// The largest turn [rad] of any edge tangent under state + step (MaxTangentTurn) and the largest
/// change of any edge's strain, |t . de| / l0 (the retraction changes lengths by the linear part
/// only), in one pass over the edges.
struct StepTurnStrain {
  double turn = 0.0;
  double strain = 0.0;
};
StepTurnStrain MaxTurnAndStrainChange(const RodModel& model, const RodState& state,
                                      const VecX& step);

/// The force [N] the rod exerts on the instrument at the grasped vertex: minus the constraint
/// force that holds it, -dPi/dx_k at equilibrium (zero without a grasp).
Vec3 GraspReaction(const RodModel& model, const RodState& state);

/// The convergence measure [N]: the largest free generalised force per length of the rod it
/// acts on, times L: forces over their vertex's Voronoi cell and moments over their edge, so
/// that the measure of a given load does not shrink as the segments grow finer.
double ScaledGradientNorm(const RodModel& model, const VecX& gradient);

/// Weights w_k with ScaledGradientNorm = max_k w_k |g_k| (zero on held dofs' rows).
VecX GradientNormWeights(const RodModel& model);

}  // namespace rodfit
