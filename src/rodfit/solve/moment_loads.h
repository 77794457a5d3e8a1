// Moments on the rod as generalised forces (docs/model.md, "Moments"). A moment M on the rigid
// rotation of edge j does the virtual work M . dphi with dphi = t x dt + t dtheta_j (the
// material frame turns with its tangent by parallel transport, and about it by its twist
// angle), so it adds Q_e = (M x t) / |e| to the end vertex x_{j+1}, -Q_e to x_j and Q_theta =
// M . t to theta_j. A moment fixed in space (dead) or turning with the edge (follower) is not
// the gradient of any potential in 3-D (Ziegler; Argyris): the balance g(q) - Q(q) = 0 is
// solved with the load stiffness -dQ/dq, which is not symmetric. In the plane, a dead moment
// about the plane's normal gives the planar potential M * (end rotation) exactly.
#pragma once

#include "rodfit/model/rod.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

/// Adds -load_scale Q to *residual (the gradient of Pi: the balance is residual = 0) and, when
/// given, -load_scale dQ/dq to the tangent *J (sized num_free_dofs, bandwidths >= 11).
/// `frames` must be ComputeRodFrames of `state` (fresh).
void AddMomentLoads(const RodModel& model, const RodState& state, const RodFrames& frames,
                    double load_scale, VecX* residual, BandedMatrix* J);

/// One edge moment's generalised force on its edge (Q_e on x_{j+1}, -Q_e on x_j, Q_theta on
/// theta_j) at `scale` times its value, and its derivatives with respect to the edge vector and
/// the twist angle.
struct EdgeMomentForce {
  Vec3 Qe, dQe_dtheta, dQt_de;
  double Qt = 0.0;
  Eigen::Matrix3d dQe_de;
};
EdgeMomentForce EdgeMomentLoad(const EdgeMoment& em, const RodFrames& frames, double scale);

/// The world moment of an EdgeMoment in `state` (the follower's components turned to world).
Vec3 WorldMoment(const EdgeMoment& em, const RodFrames& frames);

/// The balance r = grad Pi - Q (held rows zeroed) and, when J is given, its tangent dr/dq along
/// the solver's retraction: the Hessian of Pi, the holonomy of the twist angles' reference
/// directors (antisymmetric, proportional to the twist gradient, see moment_loads.cc), minus
/// dQ/dq; held rows and columns identity. `H` is scratch for the symmetric assembly.
/// With hold = false the held rows are left as they are (the constraint forces and their
/// derivatives, for reactions).
/// `moment_scale` scales the moments on top of load_scale (moment continuation).
void AssembleBalance(const RodModel& model, const RodState& state, const RodFrames& frames,
                     double load_scale, VecX* residual, BandedMatrix* J, BandedSymmetric* H,
                     bool hold = true, double moment_scale = 1.0);

}  // namespace rodfit
