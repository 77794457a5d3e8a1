// Hand-derived Hessian of the vertex bend–twist stencil (vertex_stencil.h) at fresh frames.
//
// It is the symmetric part of the Jacobian of the closed-form gradient VertexGradientEdges with
// the linearised transport, which is the true Hessian at fresh frames (the two differ only by
// an antisymmetric holonomy term). The derivation works in the tangent variables
// (te, tf, theta_e, theta_f) and maps to the edges at the end. First-order variations at fresh
// frames, for dte, dtf perpendicular to te, tf:
//   d(d_k,e) = -te (d_k,e . dte) + (twist rotation by d theta_e)   (transport to first order)
//   d kb     = dKb/dte dte + dKb/dtf dtf,  dKb/dte = -(2 [tf]x + kb tf^T) / chi,
//                                          dKb/dtf =  (2 [te]x - kb te^T) / chi
//   d m      = kb . (dte + dtf) / 2                                 (reference twist)
// Every bending measure is K = kb . D for a vector D = D_e + D_f carried by the frames of e and f
// (K1: D = d1e + d1f, K2: D = d2e + d2f). Its gradient is
//   dK = [ue, uf, kb.n_e, kb.n_f],  ue = (2 tf x D - K tf) / chi,  uf = (2 D x te - K te) / chi,
// with n = dD/dtheta, and the Jacobian of that gradient is written out in AddKbJacobian. The
// energy E(K1, K2, Delta) then has the Jacobian
//   B1/(4l) dK1 dK1^T + B2/(4l) dK2 dK2^T + GJ/l dDelta dDelta^T       (Gauss–Newton part)
//   + a1/2 J(dK1) + a2/2 J(dK2) + a3 J(dDelta)                         (curvature part).
// The test (tests/model/vertex_stencil_test.cc) checks it entry by entry against the Jet
// Jacobian of the closed-form gradient and against the energy's true Hessian.
#include "rodfit/model/vertex_stencil.h"

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;
using Mat2 = Eigen::Matrix2d;
using Vec3d = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// The stencil's frames: tangent-plane bases E = [d1e d2e], F = [d1f d2f] (the material
/// directors, orthonormal and perpendicular to te, tf) and the projections every term needs.
struct ReducedGeometry {
  Vec3d te, tf, kb, d1e, d2e, d1f, d2f;
  double ic;             // 1 / chi
  Vec2 kbE, kbF;         // E^T kb, F^T kb
  Vec2 tfE, teF;         // E^T tf, F^T te
  Mat2 C;                // E^T F
  Vec2 ToE(const Vec3d& v) const { return Vec2(d1e.dot(v), d2e.dot(v)); }
  Vec2 ToF(const Vec3d& v) const { return Vec2(d1f.dot(v), d2f.dot(v)); }
};

/// Gradient of K = kb . D in the reduced variables r = [E^T dte, F^T dtf, theta_e, theta_f]
/// for D = D_e + D_f turning with the frames of e and f (n_e, n_f = dD/dtheta) or fixed
/// (n = 0): [(2 E^T(tf x D) - K E^T tf) / chi, (2 F^T(D x te) - K F^T te) / chi, kb.n_e,
/// kb.n_f]. The tangential parts te . dK/dte = tf . dK/dtf are K / chi.
Vec6 KbGradient(const ReducedGeometry& g, const Vec3d& D, const Vec3d& n_e, const Vec3d& n_f,
                double* K) {
  *K = g.kb.dot(D);
  Vec6 dK;
  dK << (2.0 * g.ToE(g.tf.cross(D)) - *K * g.tfE) * g.ic,
      (2.0 * g.ToF(D.cross(g.te)) - *K * g.teF) * g.ic, g.kb.dot(n_e), g.kb.dot(n_f);
  return dK;
}

/// Adds sym(J(dK)), the symmetric part of the Jacobian of KbGradient, for K = kb . D with
/// dK = KbGradient(D), to the blocks of *J that VertexHessianFromFrames reads: the 2 x 2
/// diagonal blocks whole and the blocks above them (the blocks below are their transposes).
/// Every term is linear in the data (D, D_e, D_f, n_e, n_f, and dK, K with them), so one call
/// adds any linear combination of bending measures, the coefficients folded into the data.
/// DeE = E^T D_e, DfF = F^T D_f, kbDe = kb . D_e, kbDf = kb . D_f.
void AddKbJacobian(const ReducedGeometry& g, const Vec3d& D, const Vec2& DeE, const Vec2& DfF,
                   double kbDe, double kbDf, const Vec3d& n_e, const Vec3d& n_f,
                   const Vec6& dK, double K, Mat6* J) {
  const double ic = g.ic;
  const Vec2 weE = dK.segment<2>(0), wfF = dK.segment<2>(2);
  // (te, te): sym(kb D_e^T) - (tf w_e^T + w_e tf^T) / chi; likewise (tf, tf).
  const Mat2 kbDe_outer = g.kbE * DeE.transpose(), kbDf_outer = g.kbF * DfF.transpose();
  J->block<2, 2>(0, 0) += 0.5 * (kbDe_outer + kbDe_outer.transpose()) -
                          ic * (g.tfE * weE.transpose() + weE * g.tfE.transpose());
  J->block<2, 2>(2, 2) += 0.5 * (kbDf_outer + kbDf_outer.transpose()) -
                          ic * (g.teF * wfF.transpose() + wfF * g.teF.transpose());
  // (te, tf): -(2 [D]x + tf w_f^T + K I + w_e te^T) / chi (already symmetric with (tf, te)).
  const Vec3d Dx1 = D.cross(g.d1f), Dx2 = D.cross(g.d2f);
  Mat2 X;
  X << g.d1e.dot(Dx1), g.d1e.dot(Dx2), g.d2e.dot(Dx1), g.d2e.dot(Dx2);
  const Mat2 ef = -ic * (2.0 * X + g.tfE * wfF.transpose() + K * g.C + weE * g.teF.transpose());
  J->block<2, 2>(0, 2) += ef;
  // (t, theta): (2 tf x n - (kb.n) tf) / chi and (2 n x te - (kb.n) te) / chi.
  for (int t = 0; t < 2; ++t) {
    const Vec3d& n = (t == 0) ? n_e : n_f;
    const double kn = dK[4 + t];
    const Vec2 e_col = ic * (2.0 * g.ToE(g.tf.cross(n)) - kn * g.tfE);
    const Vec2 f_col = ic * (2.0 * g.ToF(n.cross(g.te)) - kn * g.teF);
    J->block<2, 1>(0, 4 + t) += e_col;
    J->block<2, 1>(2, 4 + t) += f_col;
  }
  // (theta, theta): d n_e / d theta_e = -D_e for both bending directions.
  (*J)(4, 4) -= kbDe;
  (*J)(5, 5) -= kbDf;
}

/// Adds coef * sym(J(dDelta)), dDelta = [kb/2, kb/2, -1, 1] (d m = kb . (dte + dtf) / 2):
/// (te, te) -(kb tf^T + tf kb^T) / 4 chi, (tf, tf) -(kb te^T + te kb^T) / 4 chi,
/// (te, tf) ([te]x + [tf]x) / 2 chi - (kb te^T + tf kb^T) / 4 chi (the blocks AddKbJacobian
/// adds to).
void AddTwistCurvature(const ReducedGeometry& g, double coef, Mat6* J) {
  const double c4 = 0.25 * coef * g.ic;
  J->block<2, 2>(0, 0) -= c4 * (g.kbE * g.tfE.transpose() + g.tfE * g.kbE.transpose());
  J->block<2, 2>(2, 2) -= c4 * (g.kbF * g.teF.transpose() + g.teF * g.kbF.transpose());
  // E^T ([te]x + [tf]x) F from the frames: d1 x t = -d2, d2 x t = d1, t x d1 = d2, t x d2 = -d1.
  const Mat2& C = g.C;
  Mat2 S;
  S << C(0, 1) - C(1, 0), -C(0, 0) - C(1, 1), C(0, 0) + C(1, 1), C(0, 1) - C(1, 0);
  const Mat2 ef = 2.0 * c4 * S - c4 * (g.kbE * g.teF.transpose() + g.tfE * g.kbF.transpose());
  J->block<2, 2>(0, 2) += ef;
}

}  // namespace

void VertexHessianEdges(const VertexStencilConstants& c, const double* q, double* g8,
                        double* H8) {
  const VertexGeometry<double, true> geo(c, Vec3d(q[3] - q[0], q[4] - q[1], q[5] - q[2]),
                                         Vec3d(q[6] - q[3], q[7] - q[4], q[8] - q[5]), q[9],
                                         q[10]);
  StencilFrames fr;
  fr.te = geo.te, fr.tf = geo.tf;
  fr.d1e = geo.d1e, fr.d2e = geo.d2e, fr.d1f = geo.d1f, fr.d2f = geo.d2f;
  fr.len_e = geo.len_e, fr.len_f = geo.len_f;
  VertexHessianFromFrames(c, fr, q[10] - q[9] + geo.ref_twist, g8, H8);
}

void VertexHessianFromFrames(const VertexStencilConstants& c, const StencilFrames& fr,
                             double delta, double* g8, double* H8) {
  const double inv_l = 1.0 / c.voronoi_length;  // reciprocals: divisions are slow
  ReducedGeometry g;
  g.te = fr.te, g.tf = fr.tf;
  g.d1e = fr.d1e, g.d2e = fr.d2e, g.d1f = fr.d1f, g.d2f = fr.d2f;
  const double chi = 1.0 + g.te.dot(g.tf);
  g.ic = 1.0 / chi;
  g.kb = (2.0 * g.ic) * g.te.cross(g.tf);
  g.kbE = g.ToE(g.kb), g.kbF = g.ToF(g.kb);
  g.tfE = g.ToE(g.tf), g.teF = g.ToF(g.te);
  g.C << g.d1e.dot(g.d1f), g.d1e.dot(g.d2f), g.d2e.dot(g.d1f), g.d2e.dot(g.d2f);

  const double K1 = g.kbE[0] + g.kbF[0], K2 = g.kbE[1] + g.kbF[1];
  const double a1 = c.B1 * (K1 * (0.5 * inv_l) - c.rest_curvature[0]);
  const double a2 = c.B2 * (K2 * (0.5 * inv_l) - c.rest_curvature[1]);
  const double a3 = c.GJ * (delta * inv_l - c.rest_curvature[2]);

  // Gradients of K1 = kb.(d1e + d1f) (n = d2) and K2 = kb.(d2e + d2f) (n = -d1), and of the
  // twist difference Delta: dDelta = [kb/2, kb/2, -1, 1].
  double K1c, K2c;
  const Vec6 dK1 = KbGradient(g, g.d1e + g.d1f, g.d2e, g.d2f, &K1c);
  const Vec6 dK2 = KbGradient(g, g.d2e + g.d2f, -g.d1e, -g.d1f, &K2c);
  Vec6 dDelta;
  dDelta << 0.5 * g.kbE, 0.5 * g.kbF, -1.0, 1.0;
  const Vec6 grad = 0.5 * a1 * dK1 + 0.5 * a2 * dK2 + a3 * dDelta;
  // Tangential components of the tangent gradients (te . g_te, tf . g_tf): projected away from
  // the edge gradient, but they enter its derivative through d P_e.
  const double g_te_t = (0.5 * a1 * K1c + 0.5 * a2 * K2c) * g.ic;
  const double g_tf_t = g_te_t;
  // Curvature part of the Jacobian, a1/2 J(dK1) + a2/2 J(dK2) in one call (linear in the data),
  // and a3 J(dDelta).
  const double c1 = 0.5 * a1, c2 = 0.5 * a2;
  const Vec3d D = c1 * (g.d1e + g.d1f) + c2 * (g.d2e + g.d2f);
  const Vec2 Dside(c1, c2);  // E^T D_e = F^T D_f: the frames' own components
  const Vec6 dK = c1 * dK1 + c2 * dK2;
  const double K = c1 * K1c + c2 * K2c;
  const double twist_coef = a3;
  // J is symmetric and read only in its 2 x 2 diagonal blocks and the blocks above them: those
  // are summed (the Gauss–Newton part here, entry by entry), the blocks below are left zero.
  const double w1 = c.B1 * (0.25 * inv_l), w2 = c.B2 * (0.25 * inv_l), w3 = c.GJ * inv_l;
  Mat6 J = Mat6::Zero();
  for (int col = 0; col < 6; ++col)
    for (int row = 0; row <= (col | 1); ++row)
      J(row, col) =
          w1 * dK1[row] * dK1[col] + w2 * dK2[row] * dK2[col] + w3 * dDelta[row] * dDelta[col];

  AddKbJacobian(g, D, Dside, Dside, c1 * g.kbE[0] + c2 * g.kbE[1], c1 * g.kbF[0] + c2 * g.kbF[1],
                c1 * g.d2e - c2 * g.d1e, c1 * g.d2f - c2 * g.d1f, dK, K, &J);
  AddTwistCurvature(g, twist_coef, &J);

  // Reduced to edge variables: dte = E (E^T de) / |e|, and g_e = P_e g_te / |e| = E g_eE / |e|,
  //   d g_e / de = [E (J_ee - (te.g_te) I) E^T - te p_e^T - p_e te^T] / |e|^2,  p_e = E g_eE,
  // the cross blocks carrying E / |e| and F / |f|.
  const double ie = 1.0 / fr.len_e, jf = 1.0 / fr.len_f;
  Eigen::Matrix<double, 3, 2> E, F;
  E << g.d1e, g.d2e;
  F << g.d1f, g.d2f;
  const Vec3d pe = E * grad.segment<2>(0), pf = F * grad.segment<2>(2);
  const Mat2 Jee = J.block<2, 2>(0, 0) - g_te_t * Mat2::Identity();
  const Mat2 Jff = J.block<2, 2>(2, 2) - g_tf_t * Mat2::Identity();
  Eigen::Map<Eigen::Matrix<double, 8, 8, Eigen::RowMajor>> H(H8);
  H.block<3, 3>(0, 0) = (E * Jee * E.transpose() - g.te * pe.transpose() - pe * g.te.transpose()) *
                        (ie * ie);
  H.block<3, 3>(3, 3) = (F * Jff * F.transpose() - g.tf * pf.transpose() - pf * g.tf.transpose()) *
                        (jf * jf);
  H.block<3, 3>(0, 3) = (E * J.block<2, 2>(0, 2) * F.transpose()) * (ie * jf);
  H.block<3, 3>(3, 0) = H.block<3, 3>(0, 3).transpose();
  H.block<3, 2>(0, 6) = (E * J.block<2, 2>(0, 4)) * ie;
  H.block<3, 2>(3, 6) = (F * J.block<2, 2>(2, 4)) * jf;
  H.block<2, 6>(6, 0) = H.block<6, 2>(0, 6).transpose();
  H.block<2, 2>(6, 6) = J.block<2, 2>(4, 4);

  const Vec3d ge = pe * ie, gf = pf * jf;
  for (int k = 0; k < 3; ++k) {
    g8[k] = ge[k];
    g8[3 + k] = gf[k];
  }
  g8[6] = grad[4];
  g8[7] = grad[5];
}

}  // namespace rodfit
