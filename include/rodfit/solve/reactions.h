// Reactions at the held points of an equilibrium (docs/model.md, "Held points"): the force and
// moment the rod exerts on each holder — the clamp at s = 0, an end clamp or end pin, interior
// pins and a grasp — as an instrument's force sensor would read them. At a held vertex the force
// is minus the constraint force, -(dPi/dx_k - Q_k); an end clamp adds its ghost edge's force and
// the moment that holds its frame; the clamp at s = 0 takes whatever the rest leaves (the
// balance of the whole rod, so its accuracy is the solve's).
#pragma once

#include <string>
#include <vector>

#include "rodfit/model/rod.h"

namespace rodfit {

struct HeldReaction {
  std::string point;            ///< "clamp", "end_clamp", "end_pin", "pins[k]", "grasp"
  double s = 0.0;               ///< [m] held arc length
  Vec3 position = Vec3::Zero(); ///< [m] where it is held
  Vec3 force = Vec3::Zero();    ///< [N] exerted by the rod on the holder
  Vec3 moment = Vec3::Zero();   ///< [N m] exerted by the rod on the holder, about `position`
  bool holds_moment = false;    ///< a clamp (the moment is zero for pins and grasps)
};

/// Every held point's reaction: the clamp first, then held vertices by arc length.
std::vector<HeldReaction> HeldReactions(const RodModel& model, const RodState& state);

/// Derivatives of HeldReactions at an equilibrium with respect to m parameters: for each held
/// point (same order) a 6 x m matrix, rows d force (3) and d moment (3). Given dq/dlog p (free
/// dofs x m) and dr (free dofs x m): the derivative of the unconstrained balance residual at
/// fixed q (the unit terms' gradients with hold off), and for each parameter the spring zones
/// whose stiffness it is (their forces change with it; empty for others).
std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> HeldReactionDerivatives(
    const RodModel& model, const RodState& state, const Eigen::MatrixXd& dq,
    const Eigen::MatrixXd& dr, const std::vector<std::vector<int>>& zones_of_parameter);

}  // namespace rodfit
