// Generalised forces and load stiffness of edge moments (moment_loads.h).
//
// With e the edge, l = |e|, t = e / l and P = I - t t^T (dt = P de / l):
//   dead:     Q_e = [M]x e / l^2,         dQ_e/de = [M]x (I - 2 t t^T) / l^2,
//             Q_theta = M . t,            dQ_theta/de = (P M)^T / l,   dQ/dtheta = 0;
//   follower: M = m1 d1 + m2 d2 + m3 d3 turns with the frame (dd_k = w x d_k, w = t x dt +
//             t dtheta), so Q_e = (m2 d1 - m1 d2) / l, Q_theta = m3 and
//             dQ_e = -(t Q_e^T + Q_e t^T) de / l + (m1 d1 + m2 d2) dtheta / l.
#include "rodfit/solve/moment_loads.h"

namespace rodfit {
namespace {

Eigen::Matrix3d Skew(const Vec3& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

}  // namespace

Vec3 WorldMoment(const EdgeMoment& em, const RodFrames& frames) {
  if (!em.follower) return em.moment;
  const RodFrames::Edge& f = frames.edges[em.edge + 1];
  return em.moment[0] * f.d1 + em.moment[1] * f.d2 + em.moment[2] * f.t;
}

void AssembleBalance(const RodModel& model, const RodState& state, const RodFrames& frames,
                     double load_scale, VecX* g, BandedMatrix* J, BandedSymmetric* H, bool hold,
                     double moment_scale) {
  EnergyTerms terms;
  terms.load_scale = load_scale;
  terms.hold = false;  // held rows are applied after the moments
  if (J) {
    AssembleHessian(model, state, terms, g, H, &frames);
    J->SetFromSymmetric(*H);
    // Holonomy: the twist angle theta_j is measured from a reference director transported in
    // time to the current tangent. Where the gradient is taken at the next state, that director
    // has been transported along another path than the one the Hessian differentiates, and the
    // two differ by a turn about t of half the swept solid angle, 1/2 t . (dt_1 x dt_2). So the
    // tangent carries, on each edge's own block, 1/2 (dPi/dtheta_j) [t_j]x / l_j^2: zero at a
    // conservative equilibrium (where dPi/dtheta = 0), not where a moment's twist part balances.
    const int n = model.num_edges();
    for (int j = 0; j < n; ++j) {
      const double m = (*g)[RodModel::TwistDof(j)];
      if (m == 0.0) continue;
      const RodFrames::Edge& f = frames.edges[j + 1];
      const Eigen::Matrix3d A = (0.5 * m / (f.len * f.len)) * Skew(f.t);
      const int rows[2] = {RodModel::VertexDof(j + 1), j >= 1 ? RodModel::VertexDof(j) : -1};
      const double sign[2] = {1.0, -1.0};
      for (int a = 0; a < 2; ++a)
        for (int b = 0; b < 2; ++b) {
          if (rows[a] < 0 || rows[b] < 0) continue;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) J->At(rows[a] + r, rows[b] + c) += sign[a] * sign[b] * A(r, c);
        }
    }
  } else {
    AssembleGradient(model, state, terms, g, &frames);
  }
  AddMomentLoads(model, state, frames, load_scale * moment_scale, g, J);
  if (!hold) return;
  const std::vector<char>& held = HeldDofs(model);
  for (int k = 0; k < g->size(); ++k) {
    if (!held[k]) continue;
    (*g)[k] = 0.0;
    if (J) J->SetIdentityRow(k);
  }
}

EdgeMomentForce EdgeMomentLoad(const EdgeMoment& em, const RodFrames& frames, double scale) {
  EdgeMomentForce q;
  const RodFrames::Edge& f = frames.edges[em.edge + 1];
  const double l = f.len;
  const Vec3& t = f.t;
  const Vec3 M = scale * WorldMoment(em, frames);
  q.Qe = M.cross(t) / l;
  q.Qt = M.dot(t);
  q.dQe_dtheta.setZero();
  if (!em.follower) {
    q.dQe_de = Skew(M) * (Eigen::Matrix3d::Identity() - 2.0 * t * t.transpose()) / (l * l);
    q.dQt_de = (M - t * t.dot(M)) / l;
  } else {
    const Vec3 m = scale * em.moment;
    q.dQe_de = -(t * q.Qe.transpose() + q.Qe * t.transpose()) / l;
    q.dQt_de.setZero();
    q.dQe_dtheta = (m[0] * f.d1 + m[1] * f.d2) / l;
  }
  return q;
}

void AddMomentLoads(const RodModel& model, const RodState& state, const RodFrames& frames,
                    double load_scale, VecX* residual, BandedMatrix* J) {
  (void)state;
  if (load_scale == 0.0) return;
  for (const EdgeMoment& em : model.edge_moments()) {
    const int j = em.edge;
    const EdgeMomentForce q = EdgeMomentLoad(em, frames, load_scale);
    const int end = RodModel::VertexDof(j + 1);
    const int start = j >= 1 ? RodModel::VertexDof(j) : -1;  // x_0 is clamped
    const int twist = RodModel::TwistDof(j);
    residual->segment<3>(end) -= q.Qe;
    if (start >= 0) residual->segment<3>(start) += q.Qe;
    (*residual)[twist] -= q.Qt;
    if (!J) continue;
    // J -= dQ/dq with e = x_{j+1} - x_j: signs +1 for x_{j+1}, -1 for x_j.
    const int rows[2] = {end, start};
    const double sign[2] = {1.0, -1.0};
    for (int a = 0; a < 2; ++a) {
      if (rows[a] < 0) continue;
      for (int b = 0; b < 2; ++b) {
        if (rows[b] < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c)
            J->At(rows[a] + r, rows[b] + c) -= sign[a] * sign[b] * q.dQe_de(r, c);
      }
      for (int r = 0; r < 3; ++r) J->At(rows[a] + r, twist) -= sign[a] * q.dQe_dtheta[r];
      for (int c = 0; c < 3; ++c) J->At(twist, rows[a] + c) -= sign[a] * q.dQt_de[c];
    }
  }
}

}  // namespace rodfit
