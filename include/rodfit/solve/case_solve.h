// One case, solved: the single path by which `rodfit simulate`, `rodfit synth` and the fit turn
// a scene's load case into an equilibrium (docs/solvers.md). It builds the rod model the case
// needs, makes its start state (straight, the previous case's solution, or a given centre-line),
// moves held points to their targets by continuation, solves, and returns the state with its
// summary, the reactions at the held points and, for a poked case, the cross-section.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rodfit/model/rod.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

struct CaseSolution {
  std::shared_ptr<const RodModel> model;  ///< the case's model (a half rod for a symmetric case)
  RodState state;
  StaticsSummary summary;
  std::vector<HeldReaction> reactions;
  std::optional<PokeResult> poke;  ///< the poked cross-section (a case with a poke)
  /// The full centre-line: state.x, or for a symmetric case the half and its mirror image.
  Mat3X shape;
  std::vector<double> shape_s;     ///< [m] arc length of each column of `shape`
  double seconds = 0.0;            ///< wall time of the solve
  bool ok() const { return summary.converged; }
};

/// Solves `scene.cases[index]`. `previous` is the solution of the case before it in a sweep (for
/// `start: previous`; null for the first case); `workspace` may carry a kept factor from an
/// earlier solve of this case (the fit's warm starts) together with `warm`, its state.
/// Throws std::invalid_argument (the model's message) for a case that is not a valid rod.
CaseSolution SolveCase(const Scene& scene, int index, const CaseSolution* previous,
                       const StaticsOptions& options = StaticsOptions(),
                       StaticsWorkspace* workspace = nullptr, const RodState* warm = nullptr);

/// The same for a model already built (the fit's parameter changes): start from `warm` when
/// given, else from the case's start.
CaseSolution SolveModel(std::shared_ptr<const RodModel> model, const Scene& scene,
                        const CaseSolution* previous, const StaticsOptions& options,
                        StaticsWorkspace* workspace, const RodState* warm);

/// The whole rod of a symmetric case (RodModel::symmetric()): the half state `h` of model `half`
/// and its mirror image, as a state of `full`, the case's model without the symmetry.
RodState MirroredState(const RodModel& half, const RodState& h, const RodModel& full);

/// The first half of a whole rod's state `whole` (model `full`) as a state of its symmetric half.
RodState HalfState(const RodModel& half, const RodModel& full, const RodState& whole);

/// The state a case starts from (before continuation): see StartShape.
RodState StartState(const RodModel& model, const CaseSolution* previous);

}  // namespace rodfit
