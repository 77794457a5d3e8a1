// Newton steps in edge coordinates (edge_solver.h).
#include "rodfit/solve/edge_solver.h"

#include "rodfit/solve/moment_loads.h"

namespace rodfit {
namespace {

Eigen::Matrix3d Skew(const Vec3& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

constexpr int kEdgeBandwidth = 7;  // two consecutive blocks [e_j, theta_j]

}  // namespace

// The tangent in edge coordinates: its symmetric part (bending, twist, stretch) assembled, then
// factored with the moments' non-symmetric part, then the held points' constraints.
bool EdgeSolver::Factor(const RodModel& model, const RodState& state, const RodFrames& frames,
                        const EnergyTerms& terms, double moment_scale, double shift) {
  valid_ = false;
  positive_definite_ = false;
  if (!Applies(model) || !frames.fresh) return false;
  n_ = model.num_edges();
  ghost_ = model.has_end_ghost();
  ghost_twist_held_ = ghost_ && model.end_twist_held();
  size_ = model.num_free_dofs();
  held_dofs_ = HeldDofs(model);
  held_vertices_.clear();
  for (const HeldVertex& h : model.held()) held_vertices_.push_back(h.vertex);
  VecX theta_gradient;
  AssembleSymmetric(model, state, frames, terms, shift, &theta_gradient);
  if (!FactorTangent(model, frames, terms, moment_scale, theta_gradient)) return false;
  return FactorConstraints();
}

// The symmetric part in a symmetric band (lower storage, kept between calls: a fine rod's band
// is tens of megabytes), shifted by `shift`; *theta_gradient: dPi/dtheta, for the holonomy.
void EdgeSolver::AssembleSymmetric(const RodModel& model, const RodState& state,
                                   const RodFrames& frames, const EnergyTerms& terms, double shift,
                                   VecX* theta_gradient) {
  Ks_.Resize(size_, kEdgeBandwidth, 1);
  Ks_.SetZero();
  auto add = [&](int a, int b, double v) {
    if (a >= b) Ks_.At(a, b) += v;
  };
  const Material& m = model.material();
  VertexStencilConstants c;
  c.B1 = terms.bend1 * m.B1();
  c.B2 = terms.bend2 * m.B2();
  c.GJ = terms.twist * m.twist_stiffness;
  const int nb = NumBendingVertices(model);
  const std::vector<RodFrames::Edge>& fr = frames.edges;
  theta_gradient->setZero(size_);
  for (int i = 0; i < nb; ++i) {
    c.voronoi_length = model.voronoi_length(i);
    c.rest_curvature = model.rest_curvature(i);
    const RodFrames::Edge &e = fr[i], &f = fr[i + 1];
    StencilFrames sf;
    sf.te = e.t, sf.d1e = e.d1, sf.d2e = e.d2, sf.len_e = e.len;
    sf.tf = f.t, sf.d1f = f.d1, sf.d2f = f.d2, sf.len_f = f.len;
    const double theta_e = (i == 0) ? 0.0 : state.theta[i - 1];
    const double theta_f = (i == n_) ? state.end_theta : state.theta[i];
    double g8[8], H8[64];
    VertexHessianFromFrames(c, sf, theta_f - theta_e + state.ref_twist[i], g8, H8);
    // Local (e 0..2, f 3..5, theta_e 6, theta_f 7) to edge-coordinate dofs; the clamp's ghost
    // (e at i = 0) and the end's ghost edge (f at i = n) are fixed.
    int dof[8];
    for (int k = 0; k < 3; ++k) {
      dof[k] = i >= 1 ? 4 * (i - 1) + k : -1;
      dof[3 + k] = i < n_ ? 4 * i + k : -1;
    }
    dof[6] = i >= 1 ? RodModel::TwistDof(i - 1) : -1;
    dof[7] = RodModel::TwistDof(i);
    for (int a = 0; a < 8; ++a) {
      if (dof[a] < 0) continue;
      if (a >= 6) (*theta_gradient)[dof[a]] += g8[a];
      for (int b = 0; b < 8; ++b)
        if (dof[b] >= 0) add(dof[a], dof[b], H8[8 * a + b]);
    }
  }
  const double EA = terms.stretch * m.stretch_stiffness;
  if (EA != 0.0) {
    for (int j = 0; j < n_; ++j) {
      Vec3 g;
      Eigen::Matrix3d Hs;
      StretchGradientHessian(EA, model.rest_edge_length(j), state.e.col(j), &g, &Hs);
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) add(4 * j + r, 4 * j + k, Hs(r, k));
    }
  }
  if (shift != 0.0)
    for (int k = 0; k < 4 * n_ + (ghost_ ? 4 : 0); ++k) Ks_.At(k, k) += shift;
}

// Factors the symmetric part (a conservative case's tangent), and with moments the tangent itself
// (a general copy with the moments' non-symmetric part added).
bool EdgeSolver::FactorTangent(const RodModel& model, const RodFrames& frames,
                               const EnergyTerms& terms, double moment_scale,
                               const VecX& theta_gradient) {
  const std::vector<RodFrames::Edge>& fr = frames.edges;
  // The end ghost's unused vertex dofs and a held ghost twist: identity rows.
  auto identity_row = [](BandedSymmetric* A, int r) {
    const int p = A->bandwidth();
    for (int c = std::max(0, r - p); c <= std::min(A->size() - 1, r + p); ++c)
      A->At(std::max(r, c), std::min(r, c)) = (r == c) ? 1.0 : 0.0;
  };
  symmetric_ = !(moment_scale > 0.0 && model.nonconservative());
  BandedMatrix K;
  if (!symmetric_) K.SetFromSymmetric(Ks_);
  if (!symmetric_) {
    // The moments' load stiffness and the twist holonomy act on each edge's own block (their
    // vertex-coordinate forms are equal and opposite pairs on the edge's two vertices).
    for (const EdgeMoment& em : model.edge_moments()) {
      const int j = em.edge, tw = RodModel::TwistDof(j);
      const EdgeMomentForce q = EdgeMomentLoad(em, frames, terms.load_scale * moment_scale);
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) K.At(4 * j + r, 4 * j + k) -= q.dQe_de(r, k);
        K.At(4 * j + r, tw) -= q.dQe_dtheta[r];
        K.At(tw, 4 * j + r) -= q.dQt_de[r];
      }
    }
    for (int j = 0; j < n_; ++j) {
      const int tw = RodModel::TwistDof(j);
      const RodFrames::Edge& f = fr[j + 1];
      // The holonomy uses the conservative twist gradient (moment_loads.cc): dPi/dtheta_j.
      const Eigen::Matrix3d A = (0.5 * theta_gradient[tw] / (f.len * f.len)) * Skew(f.t);
      for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) K.At(4 * j + r, 4 * j + k) += A(r, k);
    }
  }
  std::vector<int> identity_rows;
  if (ghost_) {
    for (int r = 0; r < 3; ++r) identity_rows.push_back(4 * n_ + r);
    if (ghost_twist_held_) identity_rows.push_back(RodModel::TwistDof(n_));
  }
  if (symmetric_) {
    for (int r : identity_rows) identity_row(&Ks_, r);
    return ldlt_.Factor(Ks_);
  }
  for (int r : identity_rows) K.SetIdentityRow(r);
  BandedSymmetric sym = K.SymmetricPart(1);
  if (!ldlt_.Factor(sym)) return false;
  return lu_.Factor(K);
}

// Constraints: C de = sum_{j<k} de_j = 0 for each held vertex k. Their Schur complement (with
// the symmetric part's, for the inertia), and whether the factors are usable.
bool EdgeSolver::FactorConstraints() {
  const int m3 = 3 * static_cast<int>(held_vertices_.size());
  Eigen::MatrixXd Ct = Eigen::MatrixXd::Zero(size_, m3);
  for (size_t h = 0; h < held_vertices_.size(); ++h)
    for (int r = 0; r < 3; ++r)
      for (int j = 0; j < held_vertices_[h]; ++j) Ct(4 * j + r, 3 * h + r) = 1.0;
  int negative_schur = 0;
  if (m3 > 0) {
    // The symmetric part's Schur complement, for the inertia.
    Eigen::MatrixXd Ys = Ct;
    ldlt_.SolveInPlace(Ys);
    const Eigen::MatrixXd Ss = Ct.transpose() * Ys;
    if (!Ss.allFinite()) return false;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (Ss + Ss.transpose()));
    for (int k = 0; k < m3; ++k) negative_schur += eig.eigenvalues()[k] < 0.0;
    Y_ = symmetric_ ? Ys : Ct;
    if (!symmetric_) lu_.SolveInPlace(Y_);
    const Eigen::MatrixXd S = Ct.transpose() * Y_;
    schur_.compute(S);
    if (!S.allFinite() || !(std::abs(schur_.determinant()) > 0)) return false;
  } else {
    Y_.resize(size_, 0);
  }
  positive_definite_ = ldlt_.negative_pivots() == negative_schur;
  valid_ = Y_.allFinite();
  return valid_;
}

void EdgeSolver::Solve(double* e) const {
  Eigen::Map<VecX> v(e, size_);
  if (symmetric_) {
    ldlt_.SolveInPlace(v);
  } else {
    lu_.SolveInPlace(v);
  }
}

void EdgeSolver::ToEdge(const double* x, double* e) const {
  // (A^-T x)_j = sum over vertices i > j of x_i (vertex i's dofs at VertexDof(i) = 4 (i - 1)).
  double acc[3] = {0, 0, 0};
  for (int j = n_ - 1; j >= 0; --j) {
    for (int r = 0; r < 3; ++r) {
      acc[r] += x[4 * j + r];  // vertex j + 1
      e[4 * j + r] = acc[r];
    }
    e[4 * j + 3] = x[4 * j + 3];
  }
  for (int k = 4 * n_; k < size_; ++k) e[k] = x[k];
}

void EdgeSolver::ToVertex(const double* e, double* x) const {
  double acc[3] = {0, 0, 0};
  for (int j = 0; j < n_; ++j) {
    for (int r = 0; r < 3; ++r) {
      acc[r] += e[4 * j + r];
      x[4 * j + r] = acc[r];  // vertex j + 1
    }
    x[4 * j + 3] = e[4 * j + 3];
  }
  for (int k = 4 * n_; k < size_; ++k) x[k] = e[k];
}

void EdgeSolver::SolveInPlace(Eigen::Ref<Eigen::MatrixXd> rhs) const {
  VecX e(size_), x(size_);
  for (int col = 0; col < rhs.cols(); ++col) {
    VecX b = rhs.col(col);
    for (int k = 0; k < size_; ++k)
      if (held_dofs_[k]) b[k] = 0.0;
    ToEdge(b.data(), e.data());
    Solve(e.data());
    if (Y_.cols() > 0) {
      // lambda = S^-1 C z, de = z - Y lambda.
      VecX Cz = VecX::Zero(Y_.cols());
      for (size_t h = 0; h < held_vertices_.size(); ++h)
        for (int r = 0; r < 3; ++r)
          for (int j = 0; j < held_vertices_[h]; ++j) Cz[3 * h + r] += e[4 * j + r];
      const VecX lambda = schur_.solve(Cz);
      e -= Y_ * lambda;
    }
    ToVertex(e.data(), x.data());
    for (int k = 0; k < size_; ++k)
      if (held_dofs_[k]) x[k] = 0.0;
    rhs.col(col) = x;
  }
}

}  // namespace rodfit
