// Derivative tests of the vertex bend–twist stencil (model/vertex_stencil.h): the closed-form
// gradient against central differences of the energy, and the Hessian the solver uses (the
// symmetric part of the Jet Jacobian of that gradient) against full second-order autodiff of the
// energy and against central differences, on random states from nearly straight to strongly
// bent and twisted.
#include <algorithm>
#include <cmath>
#include <random>

#include <ceres/jet.h>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/model/vertex_stencil.h"

namespace rodfit {
namespace {

using Jet11 = ceres::Jet<double, 11>;
using Mat11 = Eigen::Matrix<double, 11, 11>;
using Vec11 = Eigen::Matrix<double, 11, 1>;

struct Stencil {
  VertexStencilConstants c;
  Vec11 q;
};

Eigen::Vector3d RandomUnitPerp(const Eigen::Vector3d& t, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Vector3d u(n(*rng), n(*rng), n(*rng));
  u -= u.dot(t) * t;
  return u.normalized();
}

// A stencil with fresh frames (t_old = current tangents): `bend` [rad] is the turning angle,
// `twist` the twist difference, edge lengths near `len`.
Stencil MakeStencil(std::mt19937* rng, double bend, double twist) {
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Stencil s;
  const double len = 0.01;
  Eigen::Vector3d te = Eigen::Vector3d(U(*rng), U(*rng), U(*rng)).normalized();
  Eigen::Vector3d axis = RandomUnitPerp(te, rng);
  Eigen::Vector3d tf = Eigen::AngleAxisd(bend, axis) * te;
  Eigen::Vector3d xm(U(*rng), U(*rng), U(*rng));
  Eigen::Vector3d xp = xm - len * (1 + 0.1 * U(*rng)) * te;
  Eigen::Vector3d xn = xm + len * (1 + 0.1 * U(*rng)) * tf;
  s.q << xp, xm, xn, U(*rng), U(*rng) + twist;
  s.c.voronoi_length = len;
  s.c.B1 = 1.3e-6;
  s.c.B2 = 0.7e-6;
  s.c.GJ = 0.9e-6;
  s.c.rest_curvature = Eigen::Vector3d(3.0 * U(*rng), 3.0 * U(*rng), 2.0 * U(*rng));
  s.c.t_old_e = te;
  s.c.t_old_f = tf;
  s.c.u_old_e = RandomUnitPerp(te, rng);
  s.c.u_old_f = RandomUnitPerp(tf, rng);
  s.c.ref_twist_old = 0.0;
  // Make the stored reference twist the continuous value at this state.
  VertexGeometry<double> g(s.c, s.q.data());
  s.c.ref_twist_old = g.ref_twist;
  return s;
}

double Energy(const Stencil& s, const Vec11& q) { return VertexEnergy<double>(s.c, q.data()); }

Vec11 Gradient(const Stencil& s) {
  Vec11 g;
  VertexGradient<double>(s.c, s.q.data(), g.data());
  return g;
}

// The reference for the hand-derived VertexHessianEdges: the symmetric part of the Jet Jacobian
// of the closed-form gradient with the linearised transport, in the edge variables.
void JetHessianEdges(const VertexStencilConstants& c, const double* q, double* g8, double* H8) {
  using Jet8 = ceres::Jet<double, 8>;
  const Vec3T<Jet8> e(Jet8(q[3] - q[0], 0), Jet8(q[4] - q[1], 1), Jet8(q[5] - q[2], 2));
  const Vec3T<Jet8> f(Jet8(q[6] - q[3], 3), Jet8(q[7] - q[4], 4), Jet8(q[8] - q[5], 5));
  Jet8 out[8];
  VertexGradientEdges<Jet8, true>(c, e, f, Jet8(q[9], 6), Jet8(q[10], 7), out);
  for (int a = 0; a < 8; ++a) {
    g8[a] = out[a].a;
    for (int b = 0; b < 8; ++b) H8[8 * a + b] = 0.5 * (out[a].v[b] + out[b].v[a]);
  }
}

// The Hessian the solver assembles: VertexHessianEdges in the edge variables (hand-derived
// symmetric part of the closed-form gradient's Jacobian), mapped to the stencil by
// e = x_mid - x_prev, f = x_next - x_mid. Also checks it against the Jet Jacobian to round-off.
Mat11 SolverHessian(const Stencil& s) {
  double g8[8], H8[64], g8_jet[8], H8_jet[64];
  VertexHessianEdges(s.c, s.q.data(), g8, H8);
  JetHessianEdges(s.c, s.q.data(), g8_jet, H8_jet);
  double hmax = 0.0, gmax = 0.0;
  for (int a = 0; a < 64; ++a) hmax = std::max(hmax, std::abs(H8_jet[a]));
  for (int a = 0; a < 8; ++a) gmax = std::max(gmax, std::abs(g8_jet[a]));
  for (int a = 0; a < 8; ++a) EXPECT_NEAR(g8[a], g8_jet[a], 1e-12 * gmax) << "g8[" << a << "]";
  for (int a = 0; a < 64; ++a)
    EXPECT_NEAR(H8[a], H8_jet[a], 1e-11 * hmax) << "H8(" << a / 8 << ", " << a % 8 << ")";
  Eigen::Matrix<double, 8, 11> A = Eigen::Matrix<double, 8, 11>::Zero();
  for (int k = 0; k < 3; ++k) {
    A(k, k) = -1, A(k, 3 + k) = 1;
    A(3 + k, 3 + k) = -1, A(3 + k, 6 + k) = 1;
  }
  A(6, 9) = A(7, 10) = 1;
  const Eigen::Map<const Eigen::Matrix<double, 8, 8, Eigen::RowMajor>> H(H8);
  const Eigen::Map<const Eigen::Matrix<double, 8, 1>> g(g8);
  // Its gradient part must equal the closed-form gradient too.
  EXPECT_LT((A.transpose() * g - Gradient(s)).cwiseAbs().maxCoeff(),
            1e-12 * (1 + Gradient(s).cwiseAbs().maxCoeff()));
  return A.transpose() * H * A;
}

Vec11 AutodiffGradient(const Stencil& s) {
  Jet11 q[11];
  for (int a = 0; a < 11; ++a) q[a] = Jet11(s.q[a], a);
  return VertexEnergy<Jet11>(s.c, q).v;
}

Vec11 AutodiffGradientAt(const Stencil& s, const Vec11& qv) {
  Jet11 q[11];
  for (int a = 0; a < 11; ++a) q[a] = Jet11(qv[a], a);
  return VertexEnergy<Jet11>(s.c, q).v;
}

// The true Hessian of the energy (frames anchored at the base state), by central differences
// of its exact autodiff gradient (nested Jets do not pass through Eigen's reductions).
Mat11 AutodiffHessian(const Stencil& s) {
  Mat11 H;
  for (int b = 0; b < 11; ++b) {
    const double h = b < 9 ? 1e-6 : 1e-4;
    Vec11 qp = s.q, qm = s.q;
    qp[b] += h;
    qm[b] -= h;
    H.col(b) = (AutodiffGradientAt(s, qp) - AutodiffGradientAt(s, qm)) / (2 * h);
  }
  return H;
}

// Steps: 1e-7 m on positions (edge 1e-2 m), 1e-5 rad on angles: central-difference truncation
// ~1e-10 relative, round-off ~1e-9 relative.
double Step(int a) { return a < 9 ? 1e-7 : 1e-5; }

Vec11 CentralGradient(const Stencil& s) {
  Vec11 g;
  for (int a = 0; a < 11; ++a) {
    Vec11 qp = s.q, qm = s.q;
    qp[a] += Step(a);
    qm[a] -= Step(a);
    g[a] = (Energy(s, qp) - Energy(s, qm)) / (2 * Step(a));
  }
  return g;
}

Mat11 CentralHessian(const Stencil& s) {
  Mat11 H;
  for (int a = 0; a < 11; ++a)
    for (int b = 0; b < 11; ++b) {
      const double ha = Step(a) * 30, hb = Step(b) * 30;
      auto E = [&](double da, double db) {
        Vec11 q = s.q;
        q[a] += da;
        q[b] += db;
        return Energy(s, q);
      };
      H(a, b) = (E(ha, hb) - E(ha, -hb) - E(-ha, hb) + E(-ha, -hb)) / (4 * ha * hb);
    }
  return H;
}

struct Regime {
  const char* name;
  double bend, twist;
};

class VertexStencilDerivatives : public ::testing::TestWithParam<Regime> {};

TEST_P(VertexStencilDerivatives, GradientAndHessianMatchEnergy) {
  const Regime r = GetParam();
  std::mt19937 rng(1234);
  for (int trial = 0; trial < 10; ++trial) {
    const Stencil s = MakeStencil(&rng, r.bend, r.twist);
    const Vec11 g = Gradient(s);
    const Vec11 g_ad = AutodiffGradient(s);
    const Vec11 g_fd = CentralGradient(s);
    const double gscale = g_ad.cwiseAbs().maxCoeff() + 1e-12;
    EXPECT_LT((g - g_ad).cwiseAbs().maxCoeff(), 1e-9 * gscale)
        << r.name << "\nclosed form\n" << g.transpose() << "\nautodiff\n" << g_ad.transpose();
    EXPECT_LT((g - g_fd).cwiseAbs().maxCoeff(), 1e-6 * gscale)
        << r.name << "\nclosed form\n" << g.transpose() << "\ncentral\n" << g_fd.transpose();

    const Mat11 H = SolverHessian(s);
    const Mat11 H_ad = AutodiffHessian(s);
    const double hscale = H_ad.cwiseAbs().maxCoeff();
    EXPECT_LT((H - H_ad).cwiseAbs().maxCoeff(), 1e-6 * hscale)
        << r.name << "\nsolver\n" << H << "\nautodiff\n" << H_ad;
    const Mat11 H_fd = CentralHessian(s);
    EXPECT_LT((H - H_fd).cwiseAbs().maxCoeff(), 1e-4 * hscale)
        << r.name << "\nsolver\n" << H << "\ncentral\n" << H_fd;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Regimes, VertexStencilDerivatives,
    ::testing::Values(Regime{"straight", 0.0, 0.0}, Regime{"nearly_straight", 1e-4, 1e-4},
                      Regime{"bent", 0.6, 0.3}, Regime{"strongly_bent_twisted", 2.4, 2.0},
                      Regime{"twisted_straight", 0.0, 1.2}),
    [](const ::testing::TestParamInfo<Regime>& info) { return std::string(info.param.name); });

TEST(VertexStencil, CurvatureSignConvention) {
  // A rod turning from d3 = x towards d1 = z is a rotation about -y... with d1 = z, d2 = d3 x d1
  // = x cross z = -y: the rotation axis te x tf = x cross z = -y = d2, so k2 > 0 and k1 = 0
  // (docs/model.md, "Conventions": rest curvature [0, k, 0], k > 0 bends towards the clamp normal
  // d1).
  VertexStencilConstants c;
  c.voronoi_length = 0.1;
  c.t_old_e = Eigen::Vector3d::UnitX();
  c.u_old_e = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d tf = Eigen::Vector3d(1, 0, 0.1).normalized();
  c.t_old_f = tf;
  c.u_old_f = (Eigen::Vector3d::UnitZ() - tf.z() * tf).normalized();
  const double q[11] = {-0.1, 0, 0, 0, 0, 0, tf.x() * 0.1, 0, tf.z() * 0.1, 0, 0};
  const Eigen::Vector3d k = VertexCurvatures<double>(c, q);
  EXPECT_NEAR(k[0], 0.0, 1e-12);
  EXPECT_GT(k[1], 0.0);
  EXPECT_NEAR(k[1], 2 * std::tan(std::atan(0.1) / 2) / 0.1, 1e-9);
  EXPECT_NEAR(k[2], 0.0, 1e-12);
}

}  // namespace
}  // namespace rodfit
