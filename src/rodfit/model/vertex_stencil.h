// Bend–twist energy of one vertex of the discrete elastic rod (docs/model.md; Bergou et al.
// 2008, tissue paper eqs. 6–7), on the stencil q = [x_prev (3), x_mid (3), x_next (3), theta_e,
// theta_f] of edges e = x_mid - x_prev and f = x_next - x_mid.
//
//   kb  = 2 te x tf / (1 + te.tf)                        curvature binormal, |kb| = 2 tan(phi/2)
//   k1  = kb.(d1e + d1f) / (2 l),  k2 = kb.(d2e + d2f) / (2 l),  tau = (theta_f - theta_e + m) / l
//   E   = l/2 [B1 (k1 - k1°)^2 + B2 (k2 - k2°)^2 + GJ (tau - tau°)^2]
//
// Reference directors are transported in time from (t_old, u_old) of each edge, and m is the
// reference twist (angle from the spatial transport of u_e to u_f about tf), kept continuous.
// Moments on the rod are not part of the stencil: a moment fixed in space has no potential in
// 3-D, so it enters the equilibrium as a generalised force on its edge (solve/moment_loads.h).
//
// VertexEnergy is the energy itself. VertexGradient is its gradient in closed form, valid where
// the reference frames are fresh (t = t_old), which is where the solver evaluates it; its Jet
// Jacobian differs from the true Hessian only by an antisymmetric holonomy term, so the Hessian
// is the symmetric part of that Jacobian. Tests check both against the energy.
#pragma once

#include <cmath>

#include <Eigen/Core>

#include "rodfit/model/frames.h"

namespace rodfit {

/// Constants of one vertex stencil: stiffness, rest curvature and the last transported frames.
struct VertexStencilConstants {
  double voronoi_length = 1.0;        ///< rest Voronoi length l [m]
  double B1 = 0, B2 = 0, GJ = 0;      ///< [N m^2]
  Eigen::Vector3d rest_curvature = Eigen::Vector3d::Zero();  ///< k1°, k2°, tau° [1/m]
  Eigen::Vector3d t_old_e, u_old_e, t_old_f, u_old_f;        ///< transport anchors of e, f
  double ref_twist_old = 0.0;         ///< reference twist at the anchors [rad]
};

/// Geometry of the stencil: tangents, material frames, curvature binormal, reference twist.
/// Built from the edges e, f and the twist angles. With `Linearized`, the transports and the
/// reference twist are replaced by their first-order expansions about the anchors
/// (u = u_old - t_old (u_old . (t - t_old)), m = m_old + kb_old . (dte + dtf) / 2): exact in
/// value and first derivative where the frames are fresh (t = t_old), which is all a Jet
/// carries, at a fraction of the cost. The solver's Hessian uses that; everything else uses the
/// full transport.
template <typename T, bool Linearized = false>
struct VertexGeometry {
  Vec3T<T> te, tf, d1e, d2e, d1f, d2f, kb;
  T len_e, len_f, chi, ref_twist;

  VertexGeometry(const VertexStencilConstants& c, const Vec3T<T>& e, const Vec3T<T>& f,
                 const T& theta_e, const T& theta_f) {
    using std::cos;
    using std::sin;
    using std::sqrt;
    len_e = sqrt(e.squaredNorm());  // edges never shrink to zero: stretch energy prevents it
    len_f = sqrt(f.squaredNorm());
    te = e / len_e;
    tf = f / len_f;
    Vec3T<T> ue, uf;
    if (Linearized) {
      ue = CastVec<T>(c.u_old_e) - CastVec<T>(c.t_old_e) * (te - CastVec<T>(c.t_old_e)).dot(CastVec<T>(c.u_old_e));
      uf = CastVec<T>(c.u_old_f) - CastVec<T>(c.t_old_f) * (tf - CastVec<T>(c.t_old_f)).dot(CastVec<T>(c.u_old_f));
    } else {
      ue = ParallelTransport<T, double>(CastVec<T>(c.t_old_e), te, c.u_old_e);
      uf = ParallelTransport<T, double>(CastVec<T>(c.t_old_f), tf, c.u_old_f);
    }
    const Vec3T<T> ve = te.cross(ue), vf = tf.cross(uf);
    const T ce = cos(theta_e), se = sin(theta_e), cf = cos(theta_f), sf = sin(theta_f);
    d1e = ce * ue + se * ve;
    d2e = -se * ue + ce * ve;
    d1f = cf * uf + sf * vf;
    d2f = -sf * uf + cf * vf;
    chi = Cst<T>(1.0) + te.dot(tf);
    kb = Cst<T>(2.0) * te.cross(tf) / chi;
    if (Linearized) {
      const Eigen::Vector3d kb_old =
          2.0 * c.t_old_e.cross(c.t_old_f) / (1.0 + c.t_old_e.dot(c.t_old_f));
      ref_twist = Cst<T>(c.ref_twist_old) +
                  Cst<T>(0.5) * (te - CastVec<T>(c.t_old_e) + tf - CastVec<T>(c.t_old_f))
                                    .dot(CastVec<T>(kb_old));
    } else {
      // Reference twist: the spatial transport of u_e onto tf, then the angle to u_f about tf.
      const Vec3T<T> ue_on_f = ParallelTransport<T, T>(te, tf, ue);
      const T raw = SignedAngle<T>(ue_on_f, uf, tf);
      ref_twist = UnwrapNear(raw, ScalarPart(raw), c.ref_twist_old);
    }
  }

  VertexGeometry(const VertexStencilConstants& c, const T* q)
      : VertexGeometry(c, Vec3T<T>(q[3] - q[0], q[4] - q[1], q[5] - q[2]),
                       Vec3T<T>(q[6] - q[3], q[7] - q[4], q[8] - q[5]), q[9], q[10]) {}

  static double ScalarPart(double v) { return v; }
  template <typename J>
  static double ScalarPart(const J& v) { return ScalarPart(v.a); }
};

/// Material curvatures and torsion (k1, k2, tau) [1/m] of the stencil at q.
template <typename T>
Vec3T<T> VertexCurvatures(const VertexStencilConstants& c, const T* q) {
  const VertexGeometry<T> g(c, q);
  const T inv2l = Cst<T>(0.5 / c.voronoi_length);
  return Vec3T<T>(g.kb.dot(g.d1e + g.d1f) * inv2l, g.kb.dot(g.d2e + g.d2f) * inv2l,
                  (q[10] - q[9] + g.ref_twist) * Cst<T>(1.0 / c.voronoi_length));
}

/// Energy of the stencil [J] from its geometry: tangents, curvature binormal kb, the summed
/// directors D1 = d1e + d1f, D2 = d2e + d2f and the twist difference dtheta (including the
/// reference twist). The one formula behind VertexEnergy and the solver's fresh-frame path.
template <typename T>
T StencilEnergy(const VertexStencilConstants& c, const Vec3T<T>& /*te*/, const Vec3T<T>& /*tf*/,
                const Vec3T<T>& kb, const Vec3T<T>& D1, const Vec3T<T>& D2, const T& dtheta) {
  const double l = c.voronoi_length;
  const T k1 = kb.dot(D1) / Cst<T>(2.0 * l) - Cst<T>(c.rest_curvature[0]);
  const T k2 = kb.dot(D2) / Cst<T>(2.0 * l) - Cst<T>(c.rest_curvature[1]);
  const T tw = dtheta / Cst<T>(l) - Cst<T>(c.rest_curvature[2]);
  return Cst<T>(0.5 * l) * (Cst<T>(c.B1) * k1 * k1 + Cst<T>(c.B2) * k2 * k2 + Cst<T>(c.GJ) * tw * tw);
}

/// Energy of the stencil [J] (bend and twist).
template <typename T>
T VertexEnergy(const VertexStencilConstants& c, const T* q) {
  const VertexGeometry<T> g(c, q);
  return StencilEnergy<T>(c, g.te, g.tf, g.kb, g.d1e + g.d1f, g.d2e + g.d2f,
                          q[10] - q[9] + g.ref_twist);
}

/// A stencil's two edges where the frames are fresh (reference tangents equal to the edges'):
/// unit tangents, material directors and lengths. The solver computes them once per edge.
struct StencilFrames {
  Eigen::Vector3d te, tf, d1e, d2e, d1f, d2f;
  double len_e = 1.0, len_f = 1.0;
};

/// Closed-form gradient of VertexEnergy with respect to (e, f, theta_e, theta_f), exact where
/// the frames are fresh: out = [dE/de (3), dE/df (3), dE/dtheta_e, dE/dtheta_f].
/// The formula itself, from a geometry g with the members of VertexGeometry (te, tf, kb, chi,
/// d1e, d2e, d1f, d2f, len_e, len_f) and the twist difference dtheta (with the reference twist).
template <typename T, typename Geometry>
void StencilGradient(const VertexStencilConstants& c, const Geometry& g, const T& dtheta,
                     T* out) {
  const double l = c.voronoi_length;
  const Vec3T<T> D1 = g.d1e + g.d1f, D2 = g.d2e + g.d2f;
  const T kbD1 = g.kb.dot(D1), kbD2 = g.kb.dot(D2);
  // Moments conjugate to l*k1, l*k2 and l*tau.
  const T a1 = Cst<T>(c.B1) * (kbD1 / Cst<T>(2.0 * l) - Cst<T>(c.rest_curvature[0]));
  const T a2 = Cst<T>(c.B2) * (kbD2 / Cst<T>(2.0 * l) - Cst<T>(c.rest_curvature[1]));
  const T a3 = Cst<T>(c.GJ) * (dtheta / Cst<T>(l) - Cst<T>(c.rest_curvature[2]));
  const T inv_chi = Cst<T>(1.0) / g.chi;
  // d(kb.V)/dte = (2/chi) tf x V - (kb.V/chi) tf for a fixed V; the frame terms of D1, D2 vanish
  // because kb is perpendicular to both tangents. d m / dte = kb / 2 (likewise for tf).
  Vec3T<T> g_te = (a1 * (g.tf.cross(D1) * Cst<T>(2.0) - kbD1 * g.tf) +
                   a2 * (g.tf.cross(D2) * Cst<T>(2.0) - kbD2 * g.tf)) * (Cst<T>(0.5) * inv_chi) +
                  a3 * Cst<T>(0.5) * g.kb;
  Vec3T<T> g_tf = (a1 * (D1.cross(g.te) * Cst<T>(2.0) - kbD1 * g.te) +
                   a2 * (D2.cross(g.te) * Cst<T>(2.0) - kbD2 * g.te)) * (Cst<T>(0.5) * inv_chi) +
                  a3 * Cst<T>(0.5) * g.kb;
  T g_th_e = Cst<T>(0.5) * (a1 * g.kb.dot(g.d2e) - a2 * g.kb.dot(g.d1e)) - a3;
  T g_th_f = Cst<T>(0.5) * (a1 * g.kb.dot(g.d2f) - a2 * g.kb.dot(g.d1f)) + a3;
  // Tangent gradients to edge gradients: d te = (I - te te^T) de / |e|.
  const Vec3T<T> g_e = (g_te - g.te * g.te.dot(g_te)) / g.len_e;
  const Vec3T<T> g_f = (g_tf - g.tf * g.tf.dot(g_tf)) / g.len_f;
  for (int k = 0; k < 3; ++k) {
    out[k] = g_e[k];
    out[3 + k] = g_f[k];
  }
  out[6] = g_th_e;
  out[7] = g_th_f;
}

template <typename T, bool Linearized = false>
void VertexGradientEdges(const VertexStencilConstants& c, const Vec3T<T>& e, const Vec3T<T>& f,
                         const T& theta_e, const T& theta_f, T* out) {
  const VertexGeometry<T, Linearized> g(c, e, f, theta_e, theta_f);
  StencilGradient<T>(c, g, theta_f - theta_e + g.ref_twist, out);
}

/// The same gradient with respect to the stencil q (11 entries).
template <typename T>
void VertexGradient(const VertexStencilConstants& c, const T* q, T* grad) {
  const Vec3T<T> e(q[3] - q[0], q[4] - q[1], q[5] - q[2]);
  const Vec3T<T> f(q[6] - q[3], q[7] - q[4], q[8] - q[5]);
  T ge[8];
  VertexGradientEdges<T>(c, e, f, q[9], q[10], ge);
  for (int k = 0; k < 3; ++k) {
    grad[k] = -ge[k];
    grad[3 + k] = ge[k] - ge[3 + k];
    grad[6 + k] = ge[3 + k];
  }
  grad[9] = ge[6];
  grad[10] = ge[7];
}

/// Gradient g8 and Hessian H8 (row major 8x8) of VertexEnergy in the edge variables
/// (e, f, theta_e, theta_f) at fresh frames: H8 is the symmetric part of the Jacobian of the
/// linearised closed-form gradient, derived by hand (about 10x cheaper than its Jet Jacobian,
/// which the tests compare it with). q is the stencil (11 entries). Defined in vertex_stencil.cc.
void VertexHessianEdges(const VertexStencilConstants& c, const double* q, double* g8,
                        double* H8);
/// The same from the stencil's fresh frames and its twist difference
/// dtheta = theta_f - theta_e + reference twist; reads only the stiffness, rest curvature and
/// Voronoi length of c.
void VertexHessianFromFrames(const VertexStencilConstants& c, const StencilFrames& frames,
                             double dtheta, double* g8, double* H8);
/// Stretch energy of one edge, E = EA L0 / 2 (|e| / L0 - 1)^2 (per-edge stretch, docs/model.md),
/// with its gradient and Hessian with respect to q = [x_a (3), x_b (3)].
template <typename T>
T StretchEnergy(double EA, double rest_length, const T* q) {
  using std::sqrt;
  const Vec3T<T> e(q[3] - q[0], q[4] - q[1], q[5] - q[2]);
  const T strain = sqrt(e.squaredNorm()) / Cst<T>(rest_length) - Cst<T>(1.0);
  return Cst<T>(0.5 * EA * rest_length) * strain * strain;
}

}  // namespace rodfit
