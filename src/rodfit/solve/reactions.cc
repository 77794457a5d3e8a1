// Reactions at held points (reactions.h).
#include "rodfit/solve/reactions.h"

#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

std::vector<HeldReaction> HeldReactions(const RodModel& model, const RodState& state) {
  const int n = model.num_edges();
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  // The unconstrained balance residual r = dPi/dq - Q: at a held dof, the force the holder
  // applies to the rod.
  EnergyTerms terms;
  terms.hold = false;
  VecX r;
  AssembleGradient(model, state, terms, &r, &frames);
  AddMomentLoads(model, state, frames, 1.0, &r, nullptr);

  std::vector<HeldReaction> out;
  HeldReaction clamp;
  clamp.point = "clamp";
  clamp.s = 0.0;
  clamp.position = state.x.col(0);
  clamp.holds_moment = true;
  out.push_back(clamp);
  // Force and moment (about x_0) the holders other than the clamp apply to the rod.
  Vec3 held_force = Vec3::Zero(), held_moment = Vec3::Zero();
  for (const HeldVertex& h : model.held()) {
    HeldReaction q;
    q.point = h.Label();
    q.s = h.s;
    q.position = state.x.col(h.vertex);
    Vec3 on_rod = r.segment<3>(RodModel::VertexDof(h.vertex));
    Vec3 couple = Vec3::Zero();
    if (h.kind == HeldVertex::Kind::kEndClamp) {
      // The clamp body holds vertex n and the ghost edge: its translation moves both, its
      // rotation turns the ghost (x_n fixed) and its frame.
      const Vec3 r_ghost = r.segment<3>(RodModel::VertexDof(n + 1));
      const double r_twist = r[RodModel::TwistDof(n)];
      const Vec3 e_ghost = model.end_ghost_length() * state.end_t;
      on_rod += r_ghost;
      couple = e_ghost.cross(r_ghost) + r_twist * state.end_t;
      q.holds_moment = true;
    }
    q.force = -on_rod;
    q.moment = -couple;
    held_force += on_rod;
    held_moment += (q.position - state.x.col(0)).cross(on_rod) + couple;
    out.push_back(q);
  }
  // The clamp at s = 0 balances everything else: external forces (all vertices, the clamped
  // one's share included), springs, moments and the other holders.
  Vec3 force = held_force, moment = held_moment;
  const Vec3 x0 = state.x.col(0);
  for (int i = 0; i <= n; ++i) {
    Vec3 f = model.vertex_forces().col(i);
    for (int z = 0; z < model.num_spring_zones(); ++z)
      f -= model.zone_stiffness(z) * model.zone_cell_length(z, i) *
           (state.x.col(i) - model.spring_anchor(i));
    force += f;
    moment += (state.x.col(i) - x0).cross(f);
  }
  for (const EdgeMoment& em : model.edge_moments()) moment += WorldMoment(em, frames);
  // The clamp applies -force and -moment to the rod; the rod applies the opposite to it.
  out[0].force = force;
  out[0].moment = moment;
  return out;
}

}  // namespace rodfit
