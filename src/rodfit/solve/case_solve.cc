// One case, solved (case_solve.h).
#include "rodfit/solve/case_solve.h"

#include <chrono>
#include <stdexcept>

namespace rodfit {

RodState StartState(const RodModel& model, const CaseSolution* previous) {
  const StartShape& start = model.load_case().start;
  switch (start.kind) {
    case StartShape::Kind::kStraight:
      return model.StraightState();
    case StartShape::Kind::kPoints:
      return model.StateFromCentreline(start.s, start.points);
    case StartShape::Kind::kPrevious: {
      if (!previous || !previous->ok()) return model.StraightState();
      const RodModel& pm = *previous->model;
      // The same vertices: the previous equilibrium itself, twist included (a sweep follows one
      // branch); SolveStatics moves its held points and clamp to this case's by continuation.
      if (pm.arc_lengths() == model.arc_lengths() && pm.has_end_clamp() == model.has_end_clamp())
        return previous->state;
      return model.StateFromCentreline(pm.arc_lengths(), previous->state.x);
    }
  }
  return model.StraightState();
}

CaseSolution SolveModel(std::shared_ptr<const RodModel> model, const Scene& scene,
                        const CaseSolution* previous, const StaticsOptions& options,
                        StaticsWorkspace* workspace, const RodState* warm) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseSolution out;
  out.model = model;
  out.state = warm ? *warm : StartState(*model, previous);
  out.summary = SolveStatics(*model, options, &out.state, workspace);
  if (out.summary.converged) {
    out.reactions = HeldReactions(*model, out.state);
    const LoadCase& c = model->load_case();
    if (c.poke && scene.section) {
      out.poke = SolvePoke(*model, out.state, *scene.section,
                           {scene.material.ring_bend_stiffness,
                            scene.material.ring_stretch_stiffness});
    }
  }
  out.shape = out.state.x;
  out.shape_s = model->arc_lengths();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

CaseSolution SolveCase(const Scene& scene, int index, const CaseSolution* previous,
                       const StaticsOptions& options, StaticsWorkspace* workspace,
                       const RodState* warm) {
  const LoadCase& c = scene.cases.at(index);
  auto model = std::make_shared<const RodModel>(scene.rod, scene.material, scene.gravity, c,
                                                scene.springs);
  return SolveModel(std::move(model), scene, previous, options, workspace, warm);
}

}  // namespace rodfit
