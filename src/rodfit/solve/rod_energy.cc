// Energy, gradient and banded Hessian assembly of the rod (rod_energy.h). The vertex Hessian is
// the symmetric part of the Jacobian of the closed-form stencil gradient, derived by hand (see
// model/vertex_stencil.h for why that is exact); stretch is differentiated by hand too.
#include "rodfit/solve/rod_energy.h"

#include <algorithm>
#include <cmath>
#include <vector>


#include "rodfit/model/frames.h"

namespace rodfit {
namespace {


void StretchGradientHessian(double EA, double L0, const Vec3& xa, const Vec3& xb, Vec3* g,
                            Eigen::Matrix3d* H) {
  const Vec3 e = xb - xa;
  const double len = e.norm();
  const Vec3 t = e / len;
  const double strain = len / L0 - 1.0;
  *g = EA * strain * t;  // dE/dxb; dE/dxa = -g
  if (H)
    *H = (EA / L0) * t * t.transpose() +
         (EA * strain / len) * (Eigen::Matrix3d::Identity() - t * t.transpose());
}

// Adds vertex i's stencil gradient and Hessian, given in the edge variables (e, f, theta_e,
// theta_f), to the free dofs. With e = x_i - x_{i-1} and f = x_{i+1} - x_i the stencil covers
// the dof blocks i-2, i-1, i = [x_{i-1}, theta_{i-2}, x_i, theta_{i-1}, x_{i+1}, theta_i]: twelve
// consecutive dofs from 4 (i - 2), local x_prev 0..2, x_mid 4..6, theta_e 7, x_next 8..10,
// theta_f 11 (local 3 is not in the stencil). Dofs below zero are the clamp and the ghost edge.
void AddStencilGradient(int i, const double g8[8], VecX* gradient) {
  const int base = 4 * (i - 2);
  const double g_local[12] = {-g8[0],        -g8[1],        -g8[2],        0.0,
                              g8[0] - g8[3], g8[1] - g8[4], g8[2] - g8[5], g8[6],
                              g8[3],         g8[4],         g8[5],         g8[7]};
  for (int a = 0; a < 12; ++a)
    if (base + a >= 0 && a != 3) (*gradient)[base + a] += g_local[a];
}

void AddStencilHessian(int i, const double g8[8], const double H8[64], VecX* gradient,
                       BandedSymmetric* H) {
  AddStencilGradient(i, g8, gradient);
  using Mat3 = Eigen::Matrix3d;
  const Eigen::Map<const Eigen::Matrix<double, 8, 8, Eigen::RowMajor>> h(H8);
  const Mat3 Hee = h.block<3, 3>(0, 0), Hfe = h.block<3, 3>(3, 0), Hff = h.block<3, 3>(3, 3);
  // H_local = A^T H8 A with d/dx_prev = -d/de, d/dx_mid = d/de - d/df, d/dx_next = d/df.
  Eigen::Matrix<double, 12, 12> L;  // lower triangle filled below; local 3 is not used
  L.row(3).setZero();
  L.block<3, 3>(0, 0) = Hee;
  L.block<3, 3>(4, 0) = Hfe - Hee;
  L.block<3, 3>(4, 4) = Hee - Hfe - Hfe.transpose() + Hff;
  L.block<3, 3>(8, 0) = -Hfe;
  L.block<3, 3>(8, 4) = Hfe - Hff;
  L.block<3, 3>(8, 8) = Hff;
  // theta_e (local 7) lies between x_mid and x_next, theta_f (local 11) after everything.
  const Eigen::RowVector3d he_e = h.block<1, 3>(6, 0), he_f = h.block<1, 3>(6, 3);
  const Eigen::RowVector3d hf_e = h.block<1, 3>(7, 0), hf_f = h.block<1, 3>(7, 3);
  L.block<1, 3>(7, 0) = -he_e;
  L.block<1, 3>(7, 4) = he_e - he_f;
  L.block<3, 1>(8, 7) = he_f.transpose();
  L.block<1, 3>(11, 0) = -hf_e;
  L.block<1, 3>(11, 4) = hf_e - hf_f;
  L.block<1, 3>(11, 8) = hf_f;
  L(7, 7) = h(6, 6);
  L(11, 7) = h(7, 6);
  L(11, 11) = h(7, 7);
  // L now holds the lower triangle (and full diagonal blocks); add it to the lower band.
  const int base = 4 * (i - 2);
  for (int a = 0; a < 12; ++a) {
    if (base + a < 0 || a == 3) continue;
    // The band column is contiguous in the row, like the column of L.
    double* column = &H->At(base + a, base + a);
    const double* local = &L(a, a);
    for (int r = 0; r < 12 - a; ++r) column[r] += local[r];
  }
}

}  // namespace

void ComputeRodFrames(const RodModel& model, const RodState& state, RodFrames* frames) {
  const int n = model.num_edges();
  frames->edges.resize(n + 1);
  frames->fresh = true;
  RodFrames::Edge& ghost = frames->edges[0];
  ghost.t = model.clamp_tangent();
  ghost.d1 = model.clamp_d1();
  ghost.d2 = ghost.t.cross(ghost.d1);
  ghost.len = model.rest_edge_length(0);
  for (int j = 0; j < n; ++j) {
    RodFrames::Edge& f = frames->edges[j + 1];
    const Vec3 e = state.x.col(j + 1) - state.x.col(j);
    f.len = std::sqrt(e.squaredNorm());
    f.t = e / f.len;
    const Vec3 t_old = state.ref_t.col(j), u_old = state.ref_u.col(j);
    frames->fresh = frames->fresh && (f.t - t_old).cwiseAbs().maxCoeff() <= 1e-13;
    // The transport linearised about the reference tangent, as in VertexGeometry<double, true>:
    // the identity where frames are fresh.
    const Vec3 u = u_old - t_old * (f.t - t_old).dot(u_old);
    const Vec3 v = f.t.cross(u);
    const double c = std::cos(state.theta[j]), sn = std::sin(state.theta[j]);
    f.d1 = c * u + sn * v;
    f.d2 = -sn * u + c * v;
  }
}

namespace {

// Geometry of vertex i's stencil from the edge frames, in the form StencilGradient reads.
struct FreshStencilGeometry {
  Vec3 te, tf, kb, d1e, d2e, d1f, d2f;
  double chi, len_e, len_f;
  FreshStencilGeometry(const RodFrames::Edge& e, const RodFrames::Edge& f)
      : te(e.t), tf(f.t), d1e(e.d1), d2e(e.d2), d1f(f.d1), d2f(f.d2), len_e(e.len), len_f(f.len) {
    chi = 1.0 + te.dot(tf);
    kb = 2.0 * te.cross(tf) / chi;
  }
};

// Energy of the springs, the stretch and the dead loads (everything but bend and twist).
double NonBendingEnergy(const RodModel& model, const RodState& state, const EnergyTerms& terms) {
  const int n = model.num_edges();
  double energy = 0.0;
  if (terms.stretch != 0.0) {
    const double EA = terms.stretch * model.material().stretch_stiffness;
    for (int j = 0; j < n; ++j) {
      double qs[6];
      for (int k = 0; k < 3; ++k) {
        qs[k] = state.x(k, j);
        qs[3 + k] = state.x(k, j + 1);
      }
      energy += StretchEnergy<double>(EA, model.rest_edge_length(j), qs);
    }
  }
  if (terms.springs != 0.0) {
    for (int z = 0; z < model.num_spring_zones(); ++z) {
      if (terms.spring_parameter && model.spring_zone(z).parameter != *terms.spring_parameter)
        continue;
      const double K = terms.springs * model.zone_stiffness(z);
      for (int i = 1; i <= n; ++i)
        energy += 0.5 * K * model.zone_cell_length(z, i) *
                  (state.x.col(i) - model.spring_anchor(i)).squaredNorm();
    }
  }
  if (terms.loads) energy += DeadLoadEnergy(model, state, terms.load_scale);
  return energy;
}

// Stiffness, rest curvature and moment of every vertex stencil under `terms`; the Voronoi
// length and transport anchors are set per vertex.
VertexStencilConstants StencilStiffness(const RodModel& model, const EnergyTerms& terms) {
  VertexStencilConstants c;
  const Material& m = model.material();
  c.B1 = terms.bend1 * m.B1();
  c.B2 = terms.bend2 * m.B2();
  c.GJ = terms.twist * m.twist_stiffness;
  c.rest_curvature = model.rod().rest_curvature;
  c.moment = (terms.loads ? terms.load_scale : 0.0) * model.load_case().tip_moment;
  return c;
}

}  // namespace

double DeadLoadEnergy(const RodModel& model, const RodState& state, double load_scale) {
  double energy = 0.0;
  for (int i = 1; i <= model.num_edges(); ++i)
    energy -= load_scale * model.vertex_forces().col(i).dot(state.x.col(i));
  return energy;
}

void AddDeadLoadGradient(const RodModel& model, double load_scale, bool hold_grasp,
                         VecX* gradient) {
  for (int i = 1; i <= model.num_edges(); ++i) {
    if (hold_grasp && i == model.grasp_vertex()) continue;
    gradient->segment<3>(RodModel::VertexDof(i)) -= load_scale * model.vertex_forces().col(i);
  }
}

void GatherVertexStencil(const RodModel& model, const RodState& state, int i, double load_scale,
                         double q[11], VertexStencilConstants* c, std::array<int, 11>* dof) {
  const Material& m = model.material();
  c->voronoi_length = model.voronoi_length(i);
  c->B1 = m.B1();
  c->B2 = m.B2();
  c->GJ = m.twist_stiffness;
  c->rest_curvature = model.rod().rest_curvature;
  c->moment = load_scale * model.load_case().tip_moment;
  c->ref_twist_old = state.ref_twist[i];
  Vec3 x_prev;
  if (i == 0) {  // ghost edge behind the clamp carrying the clamp frame
    x_prev = state.x.col(0) - model.rest_edge_length(0) * model.clamp_tangent();
    c->t_old_e = model.clamp_tangent();
    c->u_old_e = model.clamp_d1();
    q[9] = 0.0;
  } else {
    x_prev = state.x.col(i - 1);
    c->t_old_e = state.ref_t.col(i - 1);
    c->u_old_e = state.ref_u.col(i - 1);
    q[9] = state.theta[i - 1];
  }
  c->t_old_f = state.ref_t.col(i);
  c->u_old_f = state.ref_u.col(i);
  q[10] = state.theta[i];
  for (int k = 0; k < 3; ++k) {
    q[k] = x_prev[k];
    q[3 + k] = state.x(k, i);
    q[6 + k] = state.x(k, i + 1);
  }
  if (dof) {
    for (int k = 0; k < 3; ++k) {
      (*dof)[k] = (i - 1 >= 1) ? RodModel::VertexDof(i - 1) + k : -1;
      (*dof)[3 + k] = (i >= 1) ? RodModel::VertexDof(i) + k : -1;
      (*dof)[6 + k] = RodModel::VertexDof(i + 1) + k;
    }
    (*dof)[9] = (i >= 1) ? RodModel::TwistDof(i - 1) : -1;
    (*dof)[10] = RodModel::TwistDof(i);
  }
}

double PotentialEnergy(const RodModel& model, const RodState& state, const EnergyTerms& terms) {
  const int n = model.num_edges();
  double energy = 0.0;
  double q[11];
  VertexStencilConstants c;
  for (int i = 0; i < n; ++i) {
    GatherVertexStencil(model, state, i, terms.loads ? terms.load_scale : 0.0, q, &c, nullptr);
    c.B1 *= terms.bend1, c.B2 *= terms.bend2, c.GJ *= terms.twist;
    if (!terms.AnyBendTwist() && c.moment.squaredNorm() == 0.0) continue;
    energy += VertexEnergy<double>(c, q);
  }
  return energy + NonBendingEnergy(model, state, terms);
}

double PotentialEnergyFreshFrames(const RodModel& model, const RodState& state,
                                  const EnergyTerms& terms, const RodFrames* frames) {
  const int n = model.num_edges();
  double energy = 0.0;
  VertexStencilConstants c = StencilStiffness(model, terms);
  if (terms.AnyBendTwist() || c.moment.squaredNorm() != 0.0) {
    RodFrames local;
    if (!frames) ComputeRodFrames(model, state, &local);
    const RodFrames& rf = frames ? *frames : local;
    if (!rf.fresh) return PotentialEnergy(model, state, terms);
    const std::vector<RodFrames::Edge>& fr = rf.edges;
    for (int i = 0; i < n; ++i) {
      const FreshStencilGeometry g(fr[i], fr[i + 1]);
      c.voronoi_length = model.voronoi_length(i);
      const double theta_e = (i == 0) ? 0.0 : state.theta[i - 1];
      energy += StencilEnergy<double>(c, g.te, g.tf, g.kb, g.d1e + g.d1f, g.d2e + g.d2f,
                                      state.theta[i] - theta_e + state.ref_twist[i]);
    }
  }
  return energy + NonBendingEnergy(model, state, terms);
}

namespace {

template <bool kHessian>
void Assemble(const RodModel& model, const RodState& state, const EnergyTerms& terms,
              VecX* gradient, BandedSymmetric* H, const RodFrames* frames) {
  const int n = model.num_edges();
  gradient->setZero(model.num_free_dofs());
  if (kHessian) {
    H->Resize(model.num_free_dofs(), kRodBandwidth, 4);  // blocks [x_i, theta_{i-1}]
    H->SetZero();
  }
  double q[11];
  std::array<int, 11> dof;
  VertexStencilConstants c;
  const double EA = terms.stretch * model.material().stretch_stiffness;
  RodFrames local;
  if (!frames) ComputeRodFrames(model, state, &local);
  const RodFrames& rf = frames ? *frames : local;
  const bool fresh = rf.fresh;
  const std::vector<RodFrames::Edge>& fr = rf.edges;
  const VertexStencilConstants stiffness = StencilStiffness(model, terms);
  const bool bend_twist = terms.AnyBendTwist() || stiffness.moment.squaredNorm() != 0.0;
  for (int i = 0; i < n; ++i) {
    if (fresh) {
      c = stiffness;
      c.voronoi_length = model.voronoi_length(i);
    } else {
      GatherVertexStencil(model, state, i, terms.loads ? terms.load_scale : 0.0, q, &c, &dof);
      c.B1 *= terms.bend1, c.B2 *= terms.bend2, c.GJ *= terms.twist;
    }
    const double theta_e = (i == 0) ? 0.0 : state.theta[i - 1];
    const double dtheta = state.theta[i] - theta_e + state.ref_twist[i];
    if (kHessian) {
      // Vertex i's stencil in the edge variables, with the stretch of its edge f = edge i
      // added (every edge is the f of exactly one vertex), scattered once.
      if (!bend_twist && EA == 0.0) continue;
      double g8[8], H8[64];
      if (bend_twist && fresh) {
        const RodFrames::Edge &e = fr[i], &f = fr[i + 1];
        StencilFrames frames;
        frames.te = e.t, frames.d1e = e.d1, frames.d2e = e.d2, frames.len_e = e.len;
        frames.tf = f.t, frames.d1f = f.d1, frames.d2f = f.d2, frames.len_f = f.len;
        VertexHessianFromFrames(c, frames, dtheta, g8, H8);
      } else if (bend_twist) {
        VertexHessianEdges(c, q, g8, H8);
      } else {
        std::fill(g8, g8 + 8, 0.0);
        std::fill(H8, H8 + 64, 0.0);
      }
      if (EA != 0.0) {
        Vec3 gs;
        Eigen::Matrix3d Hs;
        StretchGradientHessian(EA, model.rest_edge_length(i), state.x.col(i), state.x.col(i + 1),
                               &gs, &Hs);
        for (int r = 0; r < 3; ++r) {
          g8[3 + r] += gs[r];
          for (int k = 0; k < 3; ++k) H8[8 * (3 + r) + 3 + k] += Hs(r, k);
        }
      }
      AddStencilHessian(i, g8, H8, gradient, H);
      continue;
    }
    if (!bend_twist) continue;
    if (fresh) {
      double g8[8];
      StencilGradient<double>(c, FreshStencilGeometry(fr[i], fr[i + 1]), dtheta, g8);
      AddStencilGradient(i, g8, gradient);
    } else {
      double g[11];
      VertexGradient<double>(c, q, g);
      for (int a = 0; a < 11; ++a)
        if (dof[a] >= 0) (*gradient)[dof[a]] += g[a];
    }
  }
  if (!kHessian && EA != 0.0) {
    Vec3 g;
    for (int j = 0; j < n; ++j) {
      StretchGradientHessian(EA, model.rest_edge_length(j), state.x.col(j), state.x.col(j + 1),
                             &g, nullptr);
      if (j >= 1) gradient->segment<3>(RodModel::VertexDof(j)) -= g;
      gradient->segment<3>(RodModel::VertexDof(j + 1)) += g;
    }
  }
  if (terms.springs != 0.0) {
    for (int z = 0; z < model.num_spring_zones(); ++z) {
      if (terms.spring_parameter && model.spring_zone(z).parameter != *terms.spring_parameter)
        continue;
      const double K = terms.springs * model.zone_stiffness(z);
      for (int i = 1; i <= n; ++i) {
        const double k = K * model.zone_cell_length(z, i);
        if (k == 0.0) continue;
        const int d = RodModel::VertexDof(i);
        gradient->segment<3>(d) += k * (state.x.col(i) - model.spring_anchor(i));
        if (kHessian)
          for (int r = 0; r < 3; ++r) H->At(d + r, d + r) += k;
      }
    }
  }
  if (terms.loads) AddDeadLoadGradient(model, terms.load_scale, /*hold_grasp=*/false, gradient);
  if (terms.fix_grasp && model.grasp_vertex() >= 1) {
    // Dirichlet rows: the grasped vertex does not move; its gradient is the constraint force.
    const int d = RodModel::VertexDof(model.grasp_vertex());
    gradient->segment<3>(d).setZero();
    if (kHessian) {
      const int p = H->bandwidth();
      for (int r = d; r < d + 3; ++r)
        for (int c = std::max(0, r - p); c <= std::min(H->size() - 1, r + p); ++c)
          H->At(std::max(r, c), std::min(r, c)) = (r == c) ? 1.0 : 0.0;
    }
  }
}

}  // namespace

void AssembleGradient(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                      VecX* gradient, const RodFrames* frames) {
  Assemble<false>(model, state, terms, gradient, nullptr, frames);
}

void AssembleHessian(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                     VecX* gradient, BandedSymmetric* hessian, const RodFrames* frames) {
  Assemble<true>(model, state, terms, gradient, hessian, frames);
}

bool ApplyStep(const RodModel& model, const RodState& state, const VecX& step, double alpha,
               RodState* out) {
  const int n = model.num_edges();
  *out = state;
  // Edge-wise retraction: each edge turns to the direction of e + de and changes its length only
  // by the linear part t.de, then the vertices are summed from the clamp. It agrees with
  // x + alpha step to first order (so Newton keeps its quadratic convergence), but a large
  // rotation no longer stretches the edges by O(|de|^2), which against a stiff EA
  // (EA L^2 / EI ~ 1e6 for a suture) would force tiny steps.
  Vec3 prev_step = Vec3::Zero();
  for (int j = 0; j < n; ++j) {
    const Vec3 next_step = alpha * step.segment<3>(RodModel::VertexDof(j + 1));
    const Vec3 e = state.x.col(j + 1) - state.x.col(j);
    const Vec3 de = next_step - prev_step;
    const double len = e.norm();
    const double new_len = len + e.dot(de) / len;
    const Vec3 dir = e + de;
    if (!(new_len > 1e-6 * model.rest_edge_length(j)) || !(dir.norm() > 0)) return false;
    out->x.col(j + 1) = out->x.col(j) + new_len * dir.normalized();
    prev_step = next_step;
  }
  if (const int k = model.grasp_vertex(); k >= 1) {
    // The grasped vertex must not move: spread the retraction's (second-order) closure error
    // over the vertices between the clamp and the grasp, and shift the rest with it.
    const Vec3 gap = out->x.col(k) - state.x.col(k);
    for (int i = 1; i <= n; ++i) out->x.col(i) -= gap * std::min(1.0, double(i) / k);
  }
  for (int j = 0; j < n; ++j) out->theta[j] += alpha * step[RodModel::TwistDof(j)];
  for (int j = 0; j < n; ++j) {
    const Vec3 e = out->x.col(j + 1) - out->x.col(j);
    const double len = e.norm();
    if (!(len > 1e-9 * model.rest_edge_length(j))) return false;
    const Vec3 t = e / len;
    const Vec3 t_old = state.ref_t.col(j);
    if (t.dot(t_old) < -0.99) return false;  // transport is singular at a full reversal
    Vec3 u = ParallelTransport<double, double>(t_old, t, Vec3(state.ref_u.col(j)));
    u = (u - u.dot(t) * t).normalized();  // remove round-off drift
    out->ref_u.col(j) = u;
    out->ref_t.col(j) = t;
  }
  for (int i = 0; i < n; ++i) {
    const Vec3 te = (i == 0) ? model.clamp_tangent() : Vec3(out->ref_t.col(i - 1));
    const Vec3 ue = (i == 0) ? model.clamp_d1() : Vec3(out->ref_u.col(i - 1));
    const Vec3 tf = out->ref_t.col(i), uf = out->ref_u.col(i);
    if (te.dot(tf) < -0.99) return false;  // a fold back on itself: kb blows up
    const Vec3 p = ParallelTransport<double, double>(te, tf, ue);
    const double raw = SignedAngle<double>(p, uf, tf);
    out->ref_twist[i] = UnwrapNear(raw, raw, state.ref_twist[i]);
  }
  return true;
}

Vec3 GraspReaction(const RodModel& model, const RodState& state) {
  if (model.grasp_vertex() < 1) return Vec3::Zero();
  EnergyTerms terms;
  terms.fix_grasp = false;
  VecX g;
  AssembleGradient(model, state, terms, &g);
  return -g.segment<3>(RodModel::VertexDof(model.grasp_vertex()));
}

double MaxTangentTurn(const RodModel& model, const RodState& state, const VecX& step) {
  const int n = model.num_edges();
  double lowest_cos = 1.0;  // the largest turn has the smallest cosine: one acos at the end
  for (int j = 0; j < n; ++j) {
    Vec3 e0 = state.x.col(j + 1) - state.x.col(j);
    Vec3 e1 = e0 + step.segment<3>(RodModel::VertexDof(j + 1));
    if (j >= 1) e1 -= step.segment<3>(RodModel::VertexDof(j));
    lowest_cos = std::min(lowest_cos, e0.normalized().dot(e1.normalized()));
  }
  return std::acos(std::max(-1.0, std::min(1.0, lowest_cos)));
}

double ScaledGradientNorm(const RodModel& model, const VecX& g) {
  double worst = 0.0;
  for (int k = 0; k < g.size(); ++k) {
    const bool twist = (k % 4) == 3;
    worst = std::max(worst, std::abs(g[k]) / (twist ? model.length() : 1.0));
  }
  return worst;
}

}  // namespace rodfit
