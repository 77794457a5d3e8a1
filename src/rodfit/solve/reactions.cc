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

std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> HeldReactionDerivatives(
    const RodModel& model, const RodState& state, const Eigen::MatrixXd& dq,
    const Eigen::MatrixXd& dr, const std::vector<std::vector<int>>& zones_of_parameter) {
  const int n = model.num_edges(), m = static_cast<int>(dq.cols());
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  // d r / d log p along the equilibrium: dr + K dq, K the unconstrained tangent (its held rows
  // are the constraint forces' derivatives).
  VecX r;
  BandedMatrix K;
  BandedSymmetric H;
  AssembleBalance(model, state, frames, 1.0, &r, &K, &H, /*hold=*/false);
  Eigen::MatrixXd dr_total = dr;
  for (int c = 0; c < m; ++c) dr_total.col(c) += K.Multiply(dq.col(c));
  // Vertex displacements dx_i / d log p (x_0 is clamped).
  auto dx = [&](int i, int c) -> Vec3 {
    return i == 0 ? Vec3::Zero() : Vec3(dq.block<3, 1>(RodModel::VertexDof(i), c));
  };
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> out;
  Eigen::Matrix<double, 6, Eigen::Dynamic> clamp = Eigen::MatrixXd::Zero(6, m);
  out.push_back(clamp);
  const Vec3 x0 = state.x.col(0);
  for (const HeldVertex& h : model.held()) {
    Eigen::Matrix<double, 6, Eigen::Dynamic> d = Eigen::MatrixXd::Zero(6, m);
    const Vec3 position = state.x.col(h.vertex);
    for (int c = 0; c < m; ++c) {
      Vec3 on_rod = dr_total.block<3, 1>(RodModel::VertexDof(h.vertex), c);
      Vec3 couple = Vec3::Zero();
      if (h.kind == HeldVertex::Kind::kEndClamp) {
        const Vec3 r_ghost = dr_total.block<3, 1>(RodModel::VertexDof(n + 1), c);
        on_rod += r_ghost;
        couple = (model.end_ghost_length() * state.end_t).cross(r_ghost) +
                 dr_total(RodModel::TwistDof(n), c) * state.end_t;
      }
      d.block<3, 1>(0, c) = -on_rod;
      d.block<3, 1>(3, c) = -couple;
      // The clamp's share (its balance; held positions do not move).
      out[0].block<3, 1>(0, c) += on_rod;
      out[0].block<3, 1>(3, c) += (position - x0).cross(on_rod) + couple;
    }
    out.push_back(d);
  }
  // The rest of the clamp's balance: external forces at moving vertices, springs, moments.
  for (int c = 0; c < m; ++c) {
    Vec3 dforce = Vec3::Zero(), dmoment = Vec3::Zero();
    for (int i = 0; i <= n; ++i) {
      const Vec3 xi = state.x.col(i), dxi = dx(i, c);
      Vec3 f = model.vertex_forces().col(i), df = Vec3::Zero();
      for (int z = 0; z < model.num_spring_zones(); ++z) {
        const double k = model.zone_stiffness(z) * model.zone_cell_length(z, i);
        f -= k * (xi - model.spring_anchor(i));
        df -= k * dxi;
        for (int zc : zones_of_parameter[c])
          if (zc == z) df -= k * (xi - model.spring_anchor(i));  // d/dlog K of the spring force
      }
      dforce += df;
      dmoment += dxi.cross(f) + (xi - x0).cross(df);
    }
    for (const EdgeMoment& em : model.edge_moments()) {
      if (!em.follower) continue;
      // A follower turns with its edge: w = t x dt + t dtheta, dt = P de / l.
      const int j = em.edge;
      const RodFrames::Edge& f = frames.edges[j + 1];
      const Vec3 de = dx(j + 1, c) - dx(j, c);
      const Vec3 dt = (de - f.t * f.t.dot(de)) / f.len;
      const Vec3 w = f.t.cross(dt) + dq(RodModel::TwistDof(j), c) * f.t;
      dmoment += w.cross(WorldMoment(em, frames));
    }
    out[0].block<3, 1>(0, c) += dforce;
    out[0].block<3, 1>(3, c) += dmoment;
  }
  return out;
}

}  // namespace rodfit
