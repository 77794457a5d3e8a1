// The statics of the cross-section ring (docs/model.md, "Cross-section"; tissue paper §4
// eqs. 10–11): the constrained Newton solve of the ring's energy (model/cross_section.h) under an
// in-plane force, with its stiffness and force sensitivities.
#pragma once

#include <string>

#include <Eigen/Core>

#include "rodfit/model/cross_section.h"

namespace rodfit {

struct RingSolveOptions {
  int max_iterations = 50;            ///< Newton iterations before giving up
  int max_line_search_steps = 40;     ///< step halvings per iteration
  /// Converged when the constrained gradient's infinity norm is below this times |F| [-].
  double gradient_tolerance = 1e-10;
  /// ... or when the Newton step changes no displacement by more than this times the largest
  /// displacement (the step is then taken) [-]: the gradient's round-off floor (about eps ks |u|
  /// / L_k from the stretch, more from cancellation in the turning angle of a fine ring) can
  /// exceed gradient_tolerance |F|. A step promising less than Pi's round-off also ends the solve.
  double step_tolerance = 1e-10;
  bool compute_sensitivities = true;  ///< fill the d_nodes_d_* fields of RingResult
  bool Check(std::string* why) const;
};

/// Statics of the ring under the in-plane force F (section coordinates [N]): Newton on the
/// constrained coordinates with a dense Cholesky (N is small), a diagonal shift when the
/// reduced Hessian is indefinite, Armijo backtracking on Pi and an iteration cap. `warm_start`
/// (node positions, 2 x N, section coordinates) is projected onto the constraints first. Throws
/// std::invalid_argument for an invalid spec, stiffness or options.
RingResult SolveRing(const SectionSpec& spec, const RingStiffness& stiffness,
                     const Eigen::Vector2d& force_in_plane, const RingSolveOptions& options = {},
                     const Eigen::Matrix2Xd* warm_start = nullptr);

}  // namespace rodfit
