// Energy, gradient and banded Hessian assembly of the rod (rod_energy.h). The vertex Hessian is
// the symmetric part of the Jacobian of the closed-form stencil gradient, derived by hand (see
// model/vertex_stencil.h for why that is exact); stretch is differentiated by hand too.
#include "rodfit/solve/rod_energy.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>


#include "rodfit/model/frames.h"

namespace rodfit {

double CrossingStretch(const RodModel& model, const RodState& state, double stretch_factor,
                       double* dE_dd, double* d2E_dd2) {
  // Half the stretch of the edge that crosses a symmetric case's plane: its length is twice the
  // distance d of the half's last vertex to the plane.
  const double EA = stretch_factor * model.material().stretch_stiffness;
  const double lc = model.crossing_length();
  const double d = (state.plane_point - state.x.col(model.num_edges())).dot(state.end_t);
  const double strain = 2.0 * d / lc - 1.0;
  if (dE_dd) *dE_dd = EA * strain;
  if (d2E_dd2) *d2E_dd2 = 2.0 * EA / lc;
  return 0.25 * EA * lc * strain * strain;
}

void StretchGradientHessian(double EA, double L0, const Vec3& e, Vec3* g, Eigen::Matrix3d* H) {
  const double len = e.norm();
  const Vec3 t = e / len;
  const double strain = len / L0 - 1.0;
  *g = EA * strain * t;  // dE/dxb; dE/dxa = -g
  if (H)
    *H = (EA / L0) * t * t.transpose() +
         (EA * strain / len) * (Eigen::Matrix3d::Identity() - t * t.transpose());
}

namespace {

// A symmetric half's crossing edge (f of vertex n) keeps its direction, the plane's normal, and
// the bending energy reads edge directions only, so no dof moves it: its rows and columns of the
// stencil's edge-variable gradient and Hessian are dropped (otherwise x_n would carry -dE/df).
// Its twist (local 7) stays. (An end clamp's ghost keeps them: its far vertex is a held dof
// whose gradient is the clamp's reaction, and x_n is held.)
void DropGhostEdge(double g8[8], double H8[64]) {
  for (int a = 3; a < 6; ++a) {
    g8[a] = 0.0;
    if (!H8) continue;
    for (int b = 0; b < 8; ++b) H8[8 * a + b] = H8[8 * b + a] = 0.0;
  }
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
  if (base >= 0) {  // every stencil from vertex 2 on: all its dofs are free (no tests per entry)
    double* g = gradient->data() + base;
    for (int a = 0; a < 12; ++a) g[a] += g_local[a];  // local 3 (not in the stencil) adds 0
    return;
  }
  for (int a = 0; a < 12; ++a)
    if (base + a >= 0 && a != 3) (*gradient)[base + a] += g_local[a];
}

void AddStencilHessian(int i, const double g8[8], const double H8[64], VecX* gradient,
                       BandedSymmetric* H) {
  AddStencilGradient(i, g8, gradient);
  // H_local = A^T H8 A with d/dx_prev = -d/de, d/dx_mid = d/de - d/df, d/dx_next = d/df, added
  // column by column straight into the lower band (a local 12 x 12 matrix first cost 3 % of a
  // dynamic tick). In the band a column is contiguous from its diagonal: col(a)[r - a] is the
  // entry (r, a) of the stencil's local dofs. theta_e (local 7) lies between x_mid and x_next,
  // theta_f (local 11) after everything; local 3 is not in the stencil.
  auto h = [H8](int r, int c) { return H8[8 * r + c]; };  // e rows/cols 0..2, f 3..5, theta 6, 7
  const int base = 4 * (i - 2);
  auto col = [&](int a) { return base + a >= 0 ? &H->At(base + a, base + a) : nullptr; };
  for (int c = 0; c < 3; ++c) {
    if (double* x = col(c)) {  // x_prev
      for (int r = c; r < 3; ++r) x[r - c] += h(r, c);                           // Hee
      for (int r = 0; r < 3; ++r) x[4 + r - c] += h(3 + r, c) - h(r, c);         // Hfe - Hee
      x[7 - c] -= h(6, c);                                                       // -he_e
      for (int r = 0; r < 3; ++r) x[8 + r - c] -= h(3 + r, c);                   // -Hfe
      x[11 - c] -= h(7, c);                                                      // -hf_e
    }
  }
  for (int c = 0; c < 3; ++c) {
    if (double* x = col(4 + c)) {  // x_mid
      for (int r = c; r < 3; ++r)  // Hee - Hfe - Hfe^T + Hff
        x[r - c] += h(r, c) - h(3 + r, c) - h(3 + c, r) + h(3 + r, 3 + c);
      x[3 - c] += h(6, c) - h(6, 3 + c);                                         // he_e - he_f
      for (int r = 0; r < 3; ++r) x[4 + r - c] += h(3 + r, c) - h(3 + r, 3 + c); // Hfe - Hff
      x[7 - c] += h(7, c) - h(7, 3 + c);                                         // hf_e - hf_f
    }
  }
  if (double* x = col(7)) {  // theta_e
    x[0] += h(6, 6);
    for (int r = 0; r < 3; ++r) x[1 + r] += h(6, 3 + r);                         // he_f^T
    x[4] += h(7, 6);
  }
  for (int c = 0; c < 3; ++c) {
    double* x = col(8 + c);  // x_next
    for (int r = c; r < 3; ++r) x[r - c] += h(3 + r, 3 + c);                     // Hff
    x[3 - c] += h(7, 3 + c);                                                     // hf_f
  }
  *col(11) += h(7, 7);
}

// The twist-eliminated stencil (AssemblePositionHessian): vertex i's gradient g8 and Hessian H8
// in (e, f, theta_e, theta_f), restricted to the motions (de, df) along which the twist stays
// zero: d theta_e = 0, d theta_f = -d m = -kb . (de / |e| + df / |f|) / 2 (the reference twist's
// first variation; kb is perpendicular to both tangents). Any split of the twist change between
// theta_e and theta_f gives the same result: turning both frames alike leaves an isotropic
// bending energy unchanged. A ghost edge's tangent is fixed (ghost_e: the clamp's, ghost_f: the
// end's), so its part of d m is zero. With r that row, the restricted Hessian is
//   H6 = H8[x, x] + H8[x, 7] r^T + r H8[7, x] + H8[7, 7] r r^T;
// the curvature term dE/dtheta_f d^2 theta_f is zero since dE/dtheta vanishes at zero twist for
// an isotropic rod. It is added to the position band at the dofs of x_prev, x_mid, x_next:
// nine consecutive position dofs from 3 (i - 2).
void AddPositionStencilHessian(int i, const double H8[64], const Vec3& kb, double len_e,
                               double len_f, bool ghost_e, bool ghost_f, BandedSymmetric* H) {
  using Mat3 = Eigen::Matrix3d;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  const Eigen::Map<const Eigen::Matrix<double, 8, 8, Eigen::RowMajor>> h(H8);
  Vec6 r;
  r.head<3>() = ghost_e ? Vec3::Zero() : Vec3(-0.5 / len_e * kb);
  r.tail<3>() = ghost_f ? Vec3::Zero() : Vec3(-0.5 / len_f * kb);
  const Vec6 h7 = h.block<6, 1>(0, 7);
  const Mat6 H6 = h.block<6, 6>(0, 0) + h7 * r.transpose() + r * h7.transpose() +
                  h(7, 7) * r * r.transpose();
  const Mat3 Hee = H6.block<3, 3>(0, 0), Hfe = H6.block<3, 3>(3, 0), Hff = H6.block<3, 3>(3, 3);
  // A^T H6 A with d/dx_prev = -d/de, d/dx_mid = d/de - d/df, d/dx_next = d/df (lower triangle).
  Eigen::Matrix<double, 9, 9> L;
  L.block<3, 3>(0, 0) = Hee;
  L.block<3, 3>(3, 0) = Hfe - Hee;
  L.block<3, 3>(3, 3) = Hee - Hfe - Hfe.transpose() + Hff;
  L.block<3, 3>(6, 0) = -Hfe;
  L.block<3, 3>(6, 3) = Hfe - Hff;
  L.block<3, 3>(6, 6) = Hff;
  const int base = 3 * (i - 2);
  for (int a = 0; a < 9; ++a) {
    if (base + a < 0) continue;
    double* column = &H->At(base + a, base + a);
    const double* local = &L(a, a);
    for (int row = 0; row < 9 - a; ++row) column[row] += local[row];
  }
}

}  // namespace

void ComputeRodFrames(const RodModel& model, const RodState& state, RodFrames* frames) {
  ComputeRodFrames(model, state, 0, model.num_edges() + (model.has_end_ghost() ? 1 : 0), frames);
}

void ComputeRodFrames(const RodModel& model, const RodState& state, int first, int last,
                      RodFrames* frames) {
  const int n = model.num_edges();
  const bool ghost = model.has_end_ghost();
  frames->edges.resize(n + 1 + (ghost ? 1 : 0));
  first = std::max(first, 0);
  last = std::min(last, static_cast<int>(frames->edges.size()) - 1);
  frames->fresh = true;
  if (first == 0) {
    RodFrames::Edge& clamp = frames->edges[0];
    clamp.t = state.clamp_t;
    clamp.d1 = state.clamp_d1;
    clamp.d2 = clamp.t.cross(clamp.d1);
    clamp.len = model.rest_edge_length(0);
  }
  for (int j = std::max(first - 1, 0); j < std::min(last, n); ++j) {
    RodFrames::Edge& f = frames->edges[j + 1];
    const Vec3 e = state.e.col(j);
    f.len = std::sqrt(e.squaredNorm());
    f.t = e * (1.0 / f.len);  // one division (e / len is three)
    const Vec3 t_old = state.ref_t.col(j), u_old = state.ref_u.col(j);
    frames->fresh = frames->fresh && (f.t - t_old).cwiseAbs().maxCoeff() <= 1e-13;
    // The transport linearised about the reference tangent, as in VertexGeometry<double, true>:
    // the identity where frames are fresh.
    const Vec3 u = u_old - t_old * (f.t - t_old).dot(u_old);
    const Vec3 v = f.t.cross(u);
    double c, sn;
    SinCos(state.theta[j], &c, &sn);
    f.d1 = c * u + sn * v;
    f.d2 = -sn * u + c * v;
  }
  // The end clamp's ghost edge: its frame is the state's, turned by end_theta.
  if (ghost && last == n + 1) {
    RodFrames::Edge& g = frames->edges[n + 1];
    g.t = state.end_t;
    g.len = model.end_ghost_length();
    const Vec3 v = g.t.cross(state.end_u);
    double c, sn;
    SinCos(state.end_theta, &c, &sn);
    g.d1 = c * state.end_u + sn * v;
    g.d2 = -sn * state.end_u + c * v;
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
    kb = (2.0 / chi) * te.cross(tf);
  }
};

// Energy of the springs, the stretch and the dead loads (everything but bend and twist).
double NonBendingEnergy(const RodModel& model, const RodState& state, const EnergyTerms& terms) {
  const int n = model.num_edges();
  double energy = 0.0;
  if (terms.stretch != 0.0) {
    const double EA = terms.stretch * model.material().stretch_stiffness;
    for (int j = 0; j < n; ++j) {
      double qs[6] = {0.0, 0.0, 0.0, state.e(0, j), state.e(1, j), state.e(2, j)};
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
  if (model.symmetric() && terms.stretch != 0.0) {
    double g;
    energy += CrossingStretch(model, state, terms.stretch, &g, nullptr);
  }
  if (terms.loads) energy += DeadLoadEnergy(model, state, terms.load_scale);
  return energy;
}

// Stiffness and rest curvature of every vertex stencil under `terms`; the Voronoi length and
// transport anchors are set per vertex.
VertexStencilConstants StencilStiffness(const RodModel& model, const EnergyTerms& terms) {
  VertexStencilConstants c;
  const Material& m = model.material();
  c.B1 = terms.bend1 * m.B1();
  c.B2 = terms.bend2 * m.B2();
  c.GJ = terms.twist * m.twist_stiffness;
  return c;
}

}  // namespace

double DeadLoadEnergy(const RodModel& model, const RodState& state, double load_scale) {
  double energy = 0.0;
  for (int i = 1; i <= model.num_edges(); ++i)
    energy -= load_scale * model.vertex_forces().col(i).dot(state.x.col(i));
  return energy;
}

void AddDeadLoadGradient(const RodModel& model, double load_scale, bool hold, VecX* gradient) {
  for (int i = 1; i <= model.num_edges(); ++i) {
    if (hold && model.held_at_vertex(i) >= 0) continue;
    gradient->segment<3>(RodModel::VertexDof(i)) -= load_scale * model.vertex_forces().col(i);
  }
}

void GatherVertexStencil(const RodModel& model, const RodState& state, int i, double q[11],
                         VertexStencilConstants* c, std::array<int, 11>* dof) {
  const Material& m = model.material();
  const int n = model.num_edges();
  c->voronoi_length = model.voronoi_length(i);
  c->B1 = m.B1();
  c->B2 = m.B2();
  c->GJ = m.twist_stiffness;
  c->rest_curvature = model.rest_curvature(i);
  c->ref_twist_old = state.ref_twist[i];
  Vec3 x_prev, x_next;
  if (i == 0) {  // ghost edge behind the clamp carrying the clamp frame
    x_prev = state.x.col(0) - model.rest_edge_length(0) * state.clamp_t;
    c->t_old_e = state.clamp_t;
    c->u_old_e = state.clamp_d1;
    q[9] = 0.0;
  } else {
    x_prev = state.x.col(i - 1);
    c->t_old_e = state.ref_t.col(i - 1);
    c->u_old_e = state.ref_u.col(i - 1);
    q[9] = state.theta[i - 1];
  }
  if (i == n) {  // the end clamp's ghost edge after vertex n
    x_next = state.x.col(n) + model.end_ghost_length() * state.end_t;
    c->t_old_f = state.end_t;
    c->u_old_f = state.end_u;
    q[10] = state.end_theta;
  } else {
    x_next = state.x.col(i + 1);
    c->t_old_f = state.ref_t.col(i);
    c->u_old_f = state.ref_u.col(i);
    q[10] = state.theta[i];
  }
  for (int k = 0; k < 3; ++k) {
    q[k] = x_prev[k];
    q[3 + k] = state.x(k, i);
    q[6 + k] = x_next[k];
  }
  if (dof) {
    // Dofs beyond the end (the ghost's far vertex and twist) exist only with an end clamp, whose
    // block of dofs follows the last edge's.
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
  const int nb = NumBendingVertices(model);
  double energy = 0.0;
  double q[11];
  VertexStencilConstants c;
  if (terms.AnyBendTwist()) {
    for (int i = 0; i < nb; ++i) {
      GatherVertexStencil(model, state, i, q, &c, nullptr);
      c.B1 *= terms.bend1, c.B2 *= terms.bend2, c.GJ *= terms.twist;
      c.rest_curvature = terms.RestCurvature(model, i);
      energy += VertexEnergy<double>(c, q);
    }
  }
  return energy + NonBendingEnergy(model, state, terms);
}

double PotentialEnergyFreshFrames(const RodModel& model, const RodState& state,
                                  const EnergyTerms& terms, const RodFrames* frames) {
  const int n = model.num_edges(), nb = NumBendingVertices(model);
  double energy = 0.0;
  VertexStencilConstants c = StencilStiffness(model, terms);
  if (terms.AnyBendTwist()) {
    RodFrames local;
    if (!frames) ComputeRodFrames(model, state, &local);
    const RodFrames& rf = frames ? *frames : local;
    if (!rf.fresh) return PotentialEnergy(model, state, terms);
    const std::vector<RodFrames::Edge>& fr = rf.edges;
    for (int i = 0; i < nb; ++i) {
      const FreshStencilGeometry g(fr[i], fr[i + 1]);
      c.voronoi_length = model.voronoi_length(i);
      c.rest_curvature = terms.RestCurvature(model, i);
      const double theta_e = (i == 0) ? 0.0 : state.theta[i - 1];
      const double theta_f = (i == n) ? state.end_theta : state.theta[i];
      energy += StencilEnergy<double>(c, g.te, g.tf, g.kb, g.d1e + g.d1f, g.d2e + g.d2f,
                                      theta_f - theta_e + state.ref_twist[i]);
    }
  }
  return energy + NonBendingEnergy(model, state, terms);
}

namespace {

// kPositions: the Hessian over the positions only, the twist eliminated
// (AssemblePositionHessian); the gradient keeps the free-dof layout with its twist rows zeroed.
// Rows of vertices first_vertex..last_vertex (AssembleGradientRows): only the terms that reach
// them are summed, in the same order as for the whole rod. The whole rod by default.
// Vertex i's stencil into the gradient and the Hessian: bending and twist (from the frames when
// fresh, else from its gathered dofs q), and edge i's stretch (stiffness EA) when `stretch`
// (every edge is the f of exactly one vertex). kPositions: the Hessian over the positions, the
// twist eliminated.
template <bool kPositions>
void AddVertexHessian(const RodModel& model, const RodState& state, int i,
                      const VertexStencilConstants& c, const double* q, const RodFrames& rf,
                      bool bend_twist, bool stretch, double EA, double dtheta, VecX* gradient,
                      BandedSymmetric* H) {
  const int n = model.num_edges();
  const bool fresh = rf.fresh;
  const std::vector<RodFrames::Edge>& fr = rf.edges;
  double g8[8], H8[64];
  if (bend_twist && fresh) {
    const RodFrames::Edge &e = fr[i], &f = fr[i + 1];
    StencilFrames sf;
    sf.te = e.t, sf.d1e = e.d1, sf.d2e = e.d2, sf.len_e = e.len;
    sf.tf = f.t, sf.d1f = f.d1, sf.d2f = f.d2, sf.len_f = f.len;
    VertexHessianFromFrames(c, sf, dtheta, g8, H8);
  } else if (bend_twist) {
    VertexHessianEdges(c, q, g8, H8);
  } else {
    std::fill(g8, g8 + 8, 0.0);
    std::fill(H8, H8 + 64, 0.0);
  }
  if (stretch) {
    Vec3 gs;
    Eigen::Matrix3d Hs;
    StretchGradientHessian(EA, model.rest_edge_length(i), state.e.col(i), &gs, &Hs);
    for (int r = 0; r < 3; ++r) {
      g8[3 + r] += gs[r];
      for (int k = 0; k < 3; ++k) H8[8 * (3 + r) + 3 + k] += Hs(r, k);
    }
  }
  if (i == n && model.symmetric()) DropGhostEdge(g8, H8);
  if (kPositions) {
    // kb and the edge lengths of the stencil, from its frames or its edges.
    Vec3 te, tf;
    double len_e, len_f;
    if (fresh) {
      te = fr[i].t, tf = fr[i + 1].t, len_e = fr[i].len, len_f = fr[i + 1].len;
    } else {
      const Vec3 e(q[3] - q[0], q[4] - q[1], q[5] - q[2]), f(q[6] - q[3], q[7] - q[4], q[8] - q[5]);
      len_e = e.norm(), len_f = f.norm();
      te = e / len_e, tf = f / len_f;
    }
    const Vec3 kb = 2.0 * te.cross(tf) / (1.0 + te.dot(tf));
    AddStencilGradient(i, g8, gradient);
    AddPositionStencilHessian(i, H8, kb, len_e, len_f, i == 0, i == n, H);
  } else {
    AddStencilHessian(i, g8, H8, gradient, H);
  }
}

// The terms after the stencils: the springs, a symmetric half's crossing stretch, the dead
// loads and the held rows (rows of vertices first_vertex..last_vertex, as Assemble).
template <bool kHessian, bool kPositions>
void AddPointTerms(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                   int first_vertex, int last_vertex, VecX* gradient, BandedSymmetric* H) {
  const int n = model.num_edges();
  // Row of free dof k in the Hessian being assembled.
  auto row = [](int k) { return kPositions ? PositionDof(k) : k; };
  if (terms.springs != 0.0) {
    for (int z = 0; z < model.num_spring_zones(); ++z) {
      if (terms.spring_parameter && model.spring_zone(z).parameter != *terms.spring_parameter)
        continue;
      const double K = terms.springs * model.zone_stiffness(z);
      for (int i = std::max(1, first_vertex); i <= std::min(n, last_vertex); ++i) {
        const double k = K * model.zone_cell_length(z, i);
        if (k == 0.0) continue;
        const int d = RodModel::VertexDof(i);
        gradient->segment<3>(d) += k * (state.x.col(i) - model.spring_anchor(i));
        if (kHessian)
          for (int r = 0; r < 3; ++r) H->At(row(d + r), row(d + r)) += k;
      }
    }
  }
  if (model.symmetric() && terms.stretch != 0.0 && last_vertex >= n) {
    // The crossing edge's half stretch, a function of d = (c - x_n) . normal.
    double dE, d2E;
    CrossingStretch(model, state, terms.stretch, &dE, &d2E);
    const Vec3 nrm = state.end_t;  // the plane's normal as the state has it
    const int d = RodModel::VertexDof(n);
    gradient->segment<3>(d) -= dE * nrm;
    if (kHessian)
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k <= r; ++k) H->At(row(d + r), row(d + k)) += d2E * nrm[r] * nrm[k];
  }
  if (terms.loads) AddDeadLoadGradient(model, terms.load_scale, /*hold=*/false, gradient);
  if (terms.hold) {
    // Dirichlet rows: held vertices do not move; their gradient is the constraint force.
    if (kPositions) {
      ApplyHeldRows(HeldDofs(model), gradient, nullptr);
      if (kHessian) ApplyHeldRows(HeldPositionDofs(model), nullptr, H);
    } else {
      ApplyHeldRows(HeldDofs(model), gradient, kHessian ? H : nullptr);
    }
  }
  if (kPositions)
    for (int j = 0; j < model.num_free_dofs() / 4; ++j) (*gradient)[4 * j + 3] = 0.0;
}

template <bool kHessian, bool kPositions = false>
void Assemble(const RodModel& model, const RodState& state, const EnergyTerms& terms,
              VecX* gradient, BandedSymmetric* H, const RodFrames* frames, int first_vertex = 0,
              int last_vertex = std::numeric_limits<int>::max()) {
  const int n = model.num_edges(), nb = NumBendingVertices(model);
  // Stencils first - 1..last + 1 and edges first - 1..last reach those vertices.
  const int first_stencil = std::max(first_vertex - 1, 0);
  const int end_stencil = last_vertex >= nb ? nb : std::min(nb, last_vertex + 2);
  const int first_edge = first_stencil, end_edge = last_vertex >= n ? n : last_vertex + 1;
  gradient->setZero(model.num_free_dofs());
  if (kHessian) {
    if (kPositions) {
      H->Resize(NumPositionDofs(model), kRodPositionBandwidth, 3);  // blocks [x_i]
    } else {
      H->Resize(model.num_free_dofs(), kRodBandwidth, 4);  // blocks [x_i, theta_{i-1}]
    }
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
  const bool bend_twist = terms.AnyBendTwist();
  for (int i = first_stencil; i < end_stencil; ++i) {
    if (fresh) {
      c = stiffness;
      c.voronoi_length = model.voronoi_length(i);
      c.rest_curvature = terms.RestCurvature(model, i);
    } else {
      GatherVertexStencil(model, state, i, q, &c, &dof);
      c.B1 *= terms.bend1, c.B2 *= terms.bend2, c.GJ *= terms.twist;
      c.rest_curvature = terms.RestCurvature(model, i);
    }
    const double theta_e = (i == 0) ? 0.0 : state.theta[i - 1];
    const double theta_f = (i == n) ? state.end_theta : state.theta[i];
    const double dtheta = theta_f - theta_e + state.ref_twist[i];
    // The stretch of edge i is added to vertex i's stencil (every edge is the f of exactly one
    // vertex); vertex n's f is the end ghost, which does not stretch.
    const bool stretch = EA != 0.0 && i < n;
    if (kHessian) {
      if (!bend_twist && !stretch) continue;
      AddVertexHessian<kPositions>(model, state, i, c, q, rf, bend_twist, stretch, EA, dtheta,
                                   gradient, H);
      continue;
    }
    if (!bend_twist) continue;
    if (fresh) {
      double g8[8];
      StencilGradient<double>(c, FreshStencilGeometry(fr[i], fr[i + 1]), dtheta, g8);
      if (i == n && model.symmetric()) DropGhostEdge(g8, nullptr);
      AddStencilGradient(i, g8, gradient);
    } else {
      double g[11];
      VertexGradient<double>(c, q, g);
      if (i == n && model.symmetric()) {
        // The crossing edge (dofs 6..8 here) neither moves nor stretches with x_n: undo the -g_f the
        // stencil's x_mid row carries for it.
        for (int k = 0; k < 3; ++k) g[3 + k] += g[6 + k], g[6 + k] = 0.0;
      }
      for (int a = 0; a < 11; ++a)
        if (dof[a] >= 0) (*gradient)[dof[a]] += g[a];
    }
  }
  if (!kHessian && EA != 0.0) {
    Vec3 g;
    for (int j = first_edge; j < end_edge; ++j) {
      StretchGradientHessian(EA, model.rest_edge_length(j), state.e.col(j), &g, nullptr);
      if (j >= 1) gradient->segment<3>(RodModel::VertexDof(j)) -= g;
      gradient->segment<3>(RodModel::VertexDof(j + 1)) += g;
    }
  }
  AddPointTerms<kHessian, kPositions>(model, state, terms, first_vertex, last_vertex, gradient,
                                      H);
}

}  // namespace

const std::vector<char>& HeldDofs(const RodModel& model) { return model.held_dofs(); }

// The held rows of the position-only system (AssemblePositionHessian).
std::vector<char> HeldPositionDofs(const RodModel& model) {
  const std::vector<char>& held = HeldDofs(model);
  std::vector<char> out(NumPositionDofs(model), 0);
  for (int k = 0; k < static_cast<int>(held.size()); ++k)
    if (k % 4 != 3 && held[k]) out[PositionDof(k)] = 1;
  return out;
}

bool TwistCanBeEliminated(const RodModel& model) {
  const Material& m = model.material();
  return m.B1() == m.B2() && !model.curved_at_rest() &&
         model.edge_moments().empty() && !(model.has_end_ghost() && model.end_twist_held());
}

void SetZeroTwist(const RodModel& model, RodState* state) {
  const int n = model.num_edges();
  double previous = 0.0;  // the clamp's ghost edge carries the clamp frame untwisted
  for (int j = 0; j < n; ++j) {
    state->theta[j] = previous - state->ref_twist[j];
    previous = state->theta[j];
  }
  if (model.has_end_ghost()) state->end_theta = previous - state->ref_twist[n];
}

void ZeroTwistVariation(const RodModel& model, const RodState& state, Eigen::Ref<VecX> dq) {
  const int n = model.num_edges();
  auto position = [&](int i) -> Vec3 {
    return i == 0 ? Vec3(Vec3::Zero()) : Vec3(dq.segment<3>(RodModel::VertexDof(i)));
  };
  // dt of edge j (-1: the clamp's ghost, n: the end's; both fixed).
  auto tangent_change = [&](int j, Vec3* t) -> Vec3 {
    if (j < 0) {
      *t = state.clamp_t;
      return Vec3::Zero();
    }
    if (j >= n) {
      *t = state.end_t;
      return Vec3::Zero();
    }
    const double len = state.e.col(j).norm();
    *t = state.e.col(j) / len;
    const Vec3 de = position(j + 1) - position(j);
    return (de - t->dot(de) * *t) / len;
  };
  double previous = 0.0;  // the clamp's ghost twist is held
  const int nb = NumBendingVertices(model);
  for (int i = 0; i < nb; ++i) {
    Vec3 te, tf;
    const Vec3 dte = tangent_change(i - 1, &te), dtf = tangent_change(i, &tf);
    const Vec3 kb = 2.0 * te.cross(tf) / (1.0 + te.dot(tf));
    const double dm = 0.5 * kb.dot(dte + dtf);
    previous -= dm;
    dq[RodModel::TwistDof(i)] = previous;
  }
}

void GatherPositions(const VecX& free, VecX* positions) {
  const int blocks = static_cast<int>(free.size()) / 4;
  positions->resize(3 * blocks);
  for (int j = 0; j < blocks; ++j) positions->segment<3>(3 * j) = free.segment<3>(4 * j);
}

void ScatterPositions(const VecX& positions, VecX* free) {
  const int blocks = static_cast<int>(positions.size()) / 3;
  free->resize(4 * blocks);
  for (int j = 0; j < blocks; ++j) {
    free->segment<3>(4 * j) = positions.segment<3>(3 * j);
    (*free)[4 * j + 3] = 0.0;
  }
}

void AssemblePositionHessian(const RodModel& model, const RodState& state,
                             const EnergyTerms& terms, VecX* gradient, BandedSymmetric* hessian,
                             const RodFrames* frames) {
  Assemble<true, true>(model, state, terms, gradient, hessian, frames);
}

void ApplyHeldRows(const std::vector<char>& held, VecX* gradient, BandedSymmetric* H) {
  const int size = static_cast<int>(held.size());
  for (int r = 0; r < size; ++r) {
    if (!held[r]) continue;
    if (gradient) (*gradient)[r] = 0.0;
    if (!H) continue;
    const int p = H->bandwidth();
    for (int c = std::max(0, r - p); c <= std::min(size - 1, r + p); ++c)
      H->At(std::max(r, c), std::min(r, c)) = (r == c) ? 1.0 : 0.0;
  }
}

void AssembleGradient(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                      VecX* gradient, const RodFrames* frames) {
  Assemble<false>(model, state, terms, gradient, nullptr, frames);
}

void AssembleHessian(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                     VecX* gradient, BandedSymmetric* hessian, const RodFrames* frames) {
  Assemble<true>(model, state, terms, gradient, hessian, frames);
}

void AssembleGradientRows(const RodModel& model, const RodState& state, const EnergyTerms& terms,
                          int first_vertex, int last_vertex, VecX* gradient, RodFrames* frames) {
  // Frames of the edges the stencils first - 1..last + 1 read (frames index: edge j is j + 1).
  ComputeRodFrames(model, state, std::max(first_vertex - 1, 0), last_vertex + 2, frames);
  Assemble<false>(model, state, terms, gradient, nullptr, frames, first_vertex, last_vertex);
}

bool UpdateReferenceFrames(const RodModel& model, const RodState& prev, RodState* out) {
  const int n = model.num_edges();
  const Eigen::Index prev_twists = prev.ref_twist.size();  // before the resize (prev may be *out)
  for (int j = 0; j < n; ++j) {
    const Vec3 e = out->e.col(j);
    const double len = e.norm();
    if (!(len > 1e-9 * model.rest_edge_length(j))) return false;
    // Reciprocals: a vector divided by a scalar is three divisions, the slowest arithmetic of
    // the frame updates, which run three times per Newton iteration of a dynamic tick.
    const Vec3 t = e * (1.0 / len);
    const Vec3 t_old = prev.ref_t.col(j);
    if (t.dot(t_old) < -0.99) return false;  // transport is singular at a full reversal
    Vec3 u = ParallelTransport<double, double>(t_old, t, Vec3(prev.ref_u.col(j)));
    u -= u.dot(t) * t;  // remove round-off drift
    u *= 1.0 / u.norm();
    out->ref_u.col(j) = u;
    out->ref_t.col(j) = t;
  }
  if (out->ref_twist.size() != n + 1) out->ref_twist.conservativeResize(n + 1);
  const int nb = NumBendingVertices(model);
  for (int i = 0; i < nb; ++i) {
    const Vec3 te = (i == 0) ? out->clamp_t : Vec3(out->ref_t.col(i - 1));
    const Vec3 ue = (i == 0) ? out->clamp_d1 : Vec3(out->ref_u.col(i - 1));
    const Vec3 tf = (i == n) ? out->end_t : Vec3(out->ref_t.col(i));
    const Vec3 uf = (i == n) ? out->end_u : Vec3(out->ref_u.col(i));
    if (te.dot(tf) < -0.99) return false;  // a fold back on itself: kb blows up
    const Vec3 p = ParallelTransport<double, double>(te, tf, ue);
    const double raw = SignedAngle<double>(p, uf, tf);
    const double old = i < prev_twists ? prev.ref_twist[i] : 0.0;
    out->ref_twist[i] = UnwrapNear(raw, raw, old);
  }
  return true;
}

bool ApplyStep(const RodModel& model, const RodState& state, const VecX& step, double alpha,
               RodState* out) {
  const int n = model.num_edges();
  *out = state;
  // Edge-wise retraction: each edge turns to the direction of e + de and changes its length only
  // by the linear part t.de. It agrees with x + alpha step to first order (so Newton keeps its
  // quadratic convergence), but a large rotation no longer stretches the edges by O(|de|^2),
  // which against a stiff EA (EA L^2 / EI ~ 1e6 for a suture) would force tiny steps.
  Vec3 prev_step = Vec3::Zero();
  for (int j = 0; j < n; ++j) {
    const Vec3 next_step = alpha * step.segment<3>(RodModel::VertexDof(j + 1));
    const Vec3 e = state.e.col(j);
    const Vec3 de = next_step - prev_step;
    const double len = e.norm();
    const double new_len = len + e.dot(de) / len;
    const Vec3 dir = e + de;
    const double dir_norm = dir.norm();
    if (!(new_len > 1e-6 * model.rest_edge_length(j)) || !(dir_norm > 0)) return false;
    out->e.col(j) = (new_len / dir_norm) * dir;
    prev_step = next_step;
  }
  // Held vertices must not move: the retraction's (second-order) closure error is taken up by
  // the edges since the previous held vertex (or the clamp), each by its compliance: turning is
  // cheap (bending, B / l^3) and stretching dear (EA / l), so the correction c_j = -C_j w with
  // C_j = P_j + r_j t_j t_j^T, r_j = B / (EA l_j^2), sum_j c_j = -gap, mostly turns the edges. A
  // correction spread evenly would change their lengths, and against a stiff EA that costs more
  // energy than the step gains. The rod beyond the held vertex shifts with it.
  // A symmetric half's last vertex is free, but its distance to the plane is the crossing edge's
  // stretch (stiffness 2 EA / l_c): its normal coordinate is closed the same way onto the linear
  // step's, or the retraction's second-order shortening would all go into that stiff edge. The
  // crossing edge is one more compliance in that closure (its half stretch, l_c / 2 EA), so the
  // shortening left to stretch is shared as an even tension, which the half then balances.
  const bool close_plane = model.symmetric();
  if (!model.held().empty() || close_plane) {
    const Material& m = model.material();
    const double B = std::min(m.B1(), m.B2()), EA = m.stretch_stiffness;
    // Moves edges from..to-1 so that their sum changes by -(sum_j C_j) w, each by its
    // compliance C_j: w closes `gap` at a held vertex. At a symmetric half's plane only the normal
    // component is closed, with w along the normal as the mirrored whole rod has it (its
    // compliance is block diagonal in normal and plane), the crossing edge taking its share.
    auto compliance = [&](int j, Vec3* t, double* r) {
      *t = out->e.col(j).normalized();
      const double lj = model.rest_edge_length(j);
      *r = std::min(1.0, B / (EA * lj * lj));
    };
    auto close = [&](int from, int to, const Vec3& gap, const Vec3* plane_normal,
                     double crossing_compliance) {
      Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
      Vec3 t;
      double r;
      for (int j = from; j < to; ++j) {
        compliance(j, &t, &r);
        sum += Eigen::Matrix3d::Identity() - (1.0 - r) * t * t.transpose();
      }
      Vec3 w;
      if (plane_normal) {
        const Vec3& nrm = *plane_normal;
        w = (nrm.dot(gap) / (nrm.dot(sum * nrm) + crossing_compliance)) * nrm;
      } else {
        w = sum.ldlt().solve(gap);
      }
      for (int j = from; j < to; ++j) {
        compliance(j, &t, &r);
        out->e.col(j) -= w - (1.0 - r) * t * t.dot(w);
      }
    };
    int from = 0;
    for (const HeldVertex& h : model.held()) {
      Vec3 pos = state.x.col(from);
      for (int j = from; j < h.vertex; ++j) pos += out->e.col(j);
      close(from, h.vertex, pos - state.x.col(h.vertex), nullptr, 0.0);
      from = h.vertex;
    }
    if (close_plane && from < n) {
      Vec3 pos = state.x.col(from);
      for (int j = from; j < n; ++j) pos += out->e.col(j);
      const Vec3 linear = state.x.col(n) + alpha * step.segment<3>(RodModel::VertexDof(n));
      const Vec3& normal = state.end_t;
      // The half of the crossing edge: half its r = B / (EA l_c^2), as in the whole rod.
      const double lc = model.crossing_length();
      close(from, n, pos - linear, &normal, 0.5 * std::min(1.0, B / (EA * lc * lc)));
    }
  }
  out->SyncVertices();
  for (const HeldVertex& h : model.held()) out->x.col(h.vertex) = state.x.col(h.vertex);
  for (int j = 0; j < n; ++j) out->theta[j] += alpha * step[RodModel::TwistDof(j)];
  if (model.has_end_ghost() && !model.end_twist_held())
    out->end_theta += alpha * step[RodModel::TwistDof(n)];
  return UpdateReferenceFrames(model, state, out);
}

Vec3 GraspReaction(const RodModel& model, const RodState& state) {
  if (model.grasp_vertex() < 1) return Vec3::Zero();
  EnergyTerms terms;
  terms.hold = false;
  VecX g;
  AssembleGradient(model, state, terms, &g);
  return -g.segment<3>(RodModel::VertexDof(model.grasp_vertex()));
}

double MaxTangentTurn(const RodModel& model, const RodState& state, const VecX& step) {
  const int n = model.num_edges();
  double lowest_cos = 1.0;  // the largest turn has the smallest cosine: one acos at the end
  for (int j = 0; j < n; ++j) {
    const Vec3 e0 = state.e.col(j);
    Vec3 e1 = e0 + step.segment<3>(RodModel::VertexDof(j + 1));
    if (j >= 1) e1 -= step.segment<3>(RodModel::VertexDof(j));
    // The cosine with one division (normalized() divides each vector by its norm).
    const double norms = std::sqrt(e0.squaredNorm()) * std::sqrt(e1.squaredNorm());
    if (std::isnan(norms)) return M_PI;
    lowest_cos = std::min(lowest_cos, norms > 0.0 ? e0.dot(e1) / norms : 0.0);
  }
  if (!std::isfinite(lowest_cos)) return M_PI;
  return std::acos(std::max(-1.0, std::min(1.0, lowest_cos)));
}

StepTurnStrain MaxTurnAndStrainChange(const RodModel& model, const RodState& state,
                                      const VecX& step) {
  const int n = model.num_edges();
  double lowest_cos = 1.0;  // the largest turn has the smallest cosine: one acos at the end
  double strain = 0.0;
  for (int j = 0; j < n; ++j) {
    const Vec3 e0 = state.e.col(j);
    Vec3 de = step.segment<3>(RodModel::VertexDof(j + 1));
    if (j >= 1) de -= step.segment<3>(RodModel::VertexDof(j));
    const Vec3 e1 = e0 + de;
    const double n0 = std::sqrt(e0.squaredNorm());
    const double norms = n0 * std::sqrt(e1.squaredNorm());
    if (std::isnan(norms)) return {M_PI, std::numeric_limits<double>::infinity()};
    lowest_cos = std::min(lowest_cos, norms > 0.0 ? e0.dot(e1) / norms : 0.0);
    strain = std::max(strain, std::abs(e0.dot(de)) / (n0 * model.rest_edge_length(j)));
  }
  StepTurnStrain r;
  r.turn = std::isfinite(lowest_cos) ? std::acos(std::max(-1.0, std::min(1.0, lowest_cos))) : M_PI;
  r.strain = std::isfinite(strain) ? strain : std::numeric_limits<double>::infinity();
  return r;
}

VecX GradientNormWeights(const RodModel& model) {
  const int n = model.num_edges();
  VecX w = VecX::Zero(model.num_free_dofs());
  const double L = model.length();
  for (int i = 1; i <= n; ++i) {
    const double cell =
        0.5 * (model.rest_edge_length(i - 1) + (i < n ? model.rest_edge_length(i) : 0.0));
    w.segment<3>(RodModel::VertexDof(i)).setConstant(L / cell);
  }
  for (int j = 0; j < n; ++j) w[RodModel::TwistDof(j)] = 1.0 / model.rest_edge_length(j);
  if (model.has_end_ghost()) w[RodModel::TwistDof(n)] = 1.0 / model.end_ghost_length();
  const std::vector<char>& held = HeldDofs(model);
  for (int k = 0; k < w.size(); ++k)
    if (held[k]) w[k] = 0.0;
  return w;
}

double ScaledGradientNorm(const RodModel& model, const VecX& g) {
  const VecX w = GradientNormWeights(model);
  double worst = 0.0, probe = 0.0;
  for (int k = 0; k < g.size(); ++k) {
    const double v = w[k] * std::abs(g[k]);
    worst = std::max(worst, v);
    probe += v * 0.0;  // NaN for a NaN or infinite entry anywhere (std::max drops a NaN)
  }
  return probe == 0.0 ? worst : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace rodfit
