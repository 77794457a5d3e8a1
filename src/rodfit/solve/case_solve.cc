// One case, solved (case_solve.h).
#include "rodfit/solve/case_solve.h"

#include <chrono>
#include <stdexcept>

#include "rodfit/model/frames.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

RodState MirroredState(const RodModel& half, const RodState& h, const RodModel& full) {
  // Vertices: the half's, then the mirror images in reverse. Material frames: the mirror image of
  // an edge traversed backwards has d3' = -mirror(d3), d1' = mirror(d1); the crossing edge's is
  // the half's ghost frame.
  const int m = half.num_edges(), N = full.num_edges();
  const Vec3& nrm = half.symmetry_normal();
  auto reflect = [&](const Vec3& v) { return Vec3(v - 2.0 * v.dot(nrm) * nrm); };
  RodState w;
  w.x.resize(3, N + 1);
  for (int i = 0; i <= m; ++i) w.x.col(i) = h.x.col(i);
  for (int k = 0; k <= m; ++k) w.x.col(m + 1 + k) = half.Mirror(h.x.col(m - k));
  w.SyncEdges();
  full.InitialiseFrames(&w);
  // The clamp's frame is the half's, which a moving case turns away from the model's target;
  // the reference twists are recomputed against it below.
  w.clamp_t = h.clamp_t;
  w.clamp_d1 = h.clamp_d1;
  std::vector<Vec3> d1(N);
  for (int j = 0; j < m; ++j) d1[j] = half.MaterialFrame(h, j).d1;
  const Vec3 ghost_d1 = std::cos(h.end_theta) * h.end_u + std::sin(h.end_theta) * h.end_t.cross(h.end_u);
  d1[m] = ghost_d1;
  for (int j = 0; j < m; ++j) d1[N - 1 - j] = reflect(d1[j]);
  for (int j = 0; j < N; ++j) {
    const Vec3 t = w.ref_t.col(j), u = w.ref_u.col(j);
    const Vec3 dj = (d1[j] - d1[j].dot(t) * t).normalized();
    w.theta[j] = SignedAngle<double>(u, dj, t);
  }
  // The end clamp's ghost: the mirror image of the clamp's frame (d3 reversed), its twist the
  // mirror of the clamp's ghost twist (zero).
  w.end_t = -reflect(w.clamp_t);
  const Vec3 end_d1 = reflect(w.clamp_d1);
  w.end_u = (end_d1 - end_d1.dot(w.end_t) * w.end_t).normalized();
  w.end_theta = 0.0;
  UpdateReferenceFrames(full, w, &w);
  return w;
}

RodState HalfState(const RodModel& half, const RodModel& full, const RodState& whole) {
  // The first half's vertices, twist angles and frames; the crossing edge's frame as the half's
  // ghost; the plane half a crossing edge beyond the last vertex.
  const int m = half.num_edges();
  RodState h;
  h.x = whole.x.leftCols(m + 1);
  h.e = whole.e.leftCols(m);
  h.theta = whole.theta.head(m);
  h.ref_u = whole.ref_u.leftCols(m);
  h.ref_t = whole.ref_t.leftCols(m);
  h.ref_twist = whole.ref_twist.head(m + 1);
  h.clamp_t = whole.clamp_t;
  h.clamp_d1 = whole.clamp_d1;
  const EdgeFrame crossing = full.MaterialFrame(whole, m);
  h.end_t = crossing.d3;
  h.end_u = crossing.d1;
  h.end_theta = 0.0;
  h.plane_point = h.x.col(m) + 0.5 * half.crossing_length() * h.end_t;
  UpdateReferenceFrames(half, h, &h);
  return h;
}

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
      if (pm.arc_lengths() == model.arc_lengths() && pm.has_end_ghost() == model.has_end_ghost() &&
          pm.symmetric() == model.symmetric())
        return previous->state;
      return model.StateFromCentreline(previous->shape_s, previous->shape);
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
  // The half's plane is moved from where the start has it like any held end. A fine half (its
  // plane has no edge-coordinate form, statics.h kEdgeContinuationSegments), or one whose
  // continuation fails, is reached through the whole rod's continuation (its end clamp moved):
  // the half started from the whole rod's first half converges at once.
  const bool through_whole =
      model->symmetric() && !warm && model->full_segments() >= kEdgeContinuationSegments;
  out.state = warm ? *warm : StartState(*model, previous);
  if (!through_whole) out.summary = SolveStatics(*model, options, &out.state, workspace);
  if (model->symmetric() && !warm && !out.summary.converged) {
    LoadCase full_case = model->load_case();
    full_case.symmetry.reset();
    const RodModel full(scene.rod, scene.material, scene.gravity, full_case, scene.springs);
    RodState whole = StartState(full, previous);
    const StaticsSummary first = SolveStatics(full, options, &whole);
    if (first.converged) {
      const int tried = out.summary.iterations;
      out.state = HalfState(*model, full, whole);
      out.summary = SolveStatics(*model, options, &out.state, workspace);
      out.summary.iterations += first.iterations + tried;
      out.summary.continuation_steps += first.continuation_steps;
    }
  }
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
  if (model->symmetric() && out.summary.converged) {
    // The whole rod, the half and its mirror image, as a state of the full case's own model:
    // its shape, and its reactions (the clamp's and the end clamp's) from the full model's
    // balance.
    LoadCase full_case = model->load_case();
    full_case.symmetry.reset();
    const RodModel full(scene.rod, scene.material, scene.gravity, full_case, scene.springs);
    const RodState whole = MirroredState(*model, out.state, full);
    out.shape = whole.x;
    out.shape_s = full.arc_lengths();
    out.reactions = HeldReactions(full, whole);
  }
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
