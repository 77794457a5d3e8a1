// Tests of the cross-section ring (model/cross_section.h, solve/ring.h; tissue paper §4
// eqs. 10–11): the closed-form gradient and Hessian of the ring energy against central
// differences and Jet autodiff (first order, and nested Jets for the Hessian) at rest and deformed states; the
// solve's invariants (zero force, balanced load, fixed mass centre, mirror symmetry, linear
// response to small forces); the exact sensitivities against finite differences of the solve;
// and the linear closed form of a thin ring held up by a point and loaded by a uniform body
// force (Roark's case of a ring supported at its base under its own weight).
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>

#include <ceres/jet.h>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/model/cross_section.h"
#include "rodfit/solve/ring.h"

namespace rodfit {
namespace {

constexpr double kPi = 3.14159265358979323846;

SectionSpec Spec(int nodes, double radius = 0.01) {
  SectionSpec s;
  s.radius = radius;
  s.nodes = nodes;
  return s;
}

Eigen::VectorXd Packed(const Eigen::Matrix2Xd& m) {
  return Eigen::Map<const Eigen::VectorXd>(m.data(), m.size());
}

std::string Show(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  std::ostringstream os;
  os << "analytic:\n" << a << "\nreference:\n" << b;
  return os.str();
}

// Inward force of magnitude f aimed at node k of an N-gon: along the line through node k and the
// centre, so the loading is mirror symmetric about that line.
Eigen::Vector2d AimedAt(int k, int N, double f) {
  const double a = 2.0 * kPi * k / N;
  return -f * Eigen::Vector2d(std::cos(a), std::sin(a));
}

// ---------------------------------------------------------------------------------------------
// Derivatives of the ring energy.

// Displacements of an 8-node ring of radius R from rest: none, a smooth oval plus random noise,
// and a strong dent (the equilibrium under a large push).
std::vector<Eigen::VectorXd> TestStates(const RingGeometry& g, const RingStiffness& k) {
  std::vector<Eigen::VectorXd> states;
  states.push_back(Eigen::VectorXd::Zero(2 * g.n));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Eigen::VectorXd x = Packed(g.rest);
  for (int i = 0; i < g.n; ++i) {
    x[2 * i] *= 1.15;
    x[2 * i + 1] *= 0.9;
    x[2 * i] += 0.05 * g.radius * U(rng);
    x[2 * i + 1] += 0.05 * g.radius * U(rng);
  }
  states.push_back(x - Packed(g.rest));
  SectionSpec spec = Spec(g.n, g.radius);
  const RingResult dented =
      SolveRing(spec, k, AimedAt(2, g.n, 3.0 * k.bend / (g.radius * g.radius)));
  EXPECT_TRUE(dented.summary.converged) << dented.summary.BriefReport();
  states.push_back(Packed(dented.displacement()));
  return states;
}

TEST(RingEnergy, GradientAndHessianAgainstCentralDifferencesAndJets) {
  constexpr int kN = 8, kDof = 2 * kN;
  using J = ceres::Jet<double, kDof>;
  using JJ = ceres::Jet<J, kDof>;
  const RingGeometry g = MakeRingGeometry(Spec(kN));
  // kb / R^2 = 20 N against ks = 3 N: both terms matter.
  const RingStiffness k{2e-3, 3.0};
  for (const Eigen::VectorXd& x : TestStates(g, k)) {
    Eigen::VectorXd grad;
    Eigen::MatrixXd hess;
    const double e = RingElasticEnergy(g, k, x, &grad, &hess);
    EXPECT_NEAR(e, RingElasticEnergy<double>(g, k, x.data()), 1e-15 * (1.0 + std::abs(e)));
    EXPECT_LT((hess - hess.transpose()).cwiseAbs().maxCoeff(), 1e-9 * hess.cwiseAbs().maxCoeff());

    // First-order Jets of the templated energy.
    std::vector<J> xj(kDof);
    for (int i = 0; i < kDof; ++i) xj[i] = J(x[i], i);
    const J ej = RingElasticEnergy<J>(g, k, xj.data());
    const double gscale = std::max(grad.cwiseAbs().maxCoeff(), k.bend / (g.radius * g.radius) * 1e-3);
    EXPECT_LT((grad - ej.v).cwiseAbs().maxCoeff(), 1e-10 * gscale)
        << Show(grad.transpose(), ej.v.transpose());

    // Nested Jets: the exact Hessian of the templated energy.
    std::vector<JJ> xjj(kDof);
    for (int i = 0; i < kDof; ++i) {
      xjj[i] = JJ(J(x[i], i), i);
    }
    const JJ ejj = RingElasticEnergy<JJ>(g, k, xjj.data());
    Eigen::MatrixXd hess_jet(kDof, kDof);
    for (int i = 0; i < kDof; ++i) hess_jet.row(i) = ejj.v[i].v.transpose();
    const double hscale = hess.cwiseAbs().maxCoeff();
    EXPECT_LT((hess - hess_jet).cwiseAbs().maxCoeff(), 1e-9 * hscale) << Show(hess, hess_jet);

    // Central differences: energy -> gradient, gradient -> Hessian. Step 1e-6 R: truncation
    // (step^2) and round-off (eps / step) both near 1e-10 relative.
    const double step = 1e-6 * g.radius;
    Eigen::VectorXd grad_fd(kDof);
    Eigen::MatrixXd hess_fd(kDof, kDof);
    for (int i = 0; i < kDof; ++i) {
      Eigen::VectorXd xp = x, xm = x, gp, gm;
      xp[i] += step;
      xm[i] -= step;
      grad_fd[i] = (RingElasticEnergy(g, k, xp) - RingElasticEnergy(g, k, xm)) / (2.0 * step);
      RingElasticEnergy(g, k, xp, &gp);
      RingElasticEnergy(g, k, xm, &gm);
      hess_fd.col(i) = (gp - gm) / (2.0 * step);
    }
    EXPECT_LT((grad - grad_fd).cwiseAbs().maxCoeff(), 1e-6 * gscale)
        << Show(grad.transpose(), grad_fd.transpose());
    EXPECT_LT((hess - hess_fd).cwiseAbs().maxCoeff(), 1e-6 * hscale) << Show(hess, hess_fd);
  }
}

TEST(RingEnergy, RestIsStressFreeAndRigidMotionsCostNothing) {
  const RingGeometry g = MakeRingGeometry(Spec(12));
  const RingStiffness k{1e-3, 5.0};
  Eigen::VectorXd grad;
  Eigen::MatrixXd hess;
  const double force_scale = k.stretch + k.bend / (g.radius * g.radius);
  // Only the bending term's last-bit rounding (kappa - kappa° ~ eps kappa°) is left.
  EXPECT_LT(RingElasticEnergy(g, k, Eigen::VectorXd::Zero(2 * g.n), &grad, &hess),
            1e-28 * force_scale * g.radius);
  EXPECT_LT(grad.cwiseAbs().maxCoeff(), 1e-15 * force_scale);
  // A finite rigid motion of the rest ring has zero energy; the Hessian at rest has exactly the
  // three rigid modes in its null space (the rest ring is stable under any elastic deformation).
  const double a = 0.7;
  Eigen::VectorXd u(2 * g.n);
  for (int i = 0; i < g.n; ++i) {
    const Eigen::Vector2d p = g.rest.col(i);
    u.segment<2>(2 * i) = Eigen::Rotation2Dd(a) * p + Eigen::Vector2d(0.3, -0.2) * g.radius - p;
  }
  EXPECT_NEAR(RingElasticEnergy(g, k, u), 0.0, 1e-12 * force_scale * g.radius);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(hess);
  const Eigen::VectorXd ev = eig.eigenvalues();
  const double top = ev.maxCoeff();
  for (int i = 0; i < 3; ++i) EXPECT_LT(std::abs(ev[i]), 1e-10 * top) << ev.transpose();
  EXPECT_GT(ev[3], 1e-8 * top) << ev.transpose();
}

// ---------------------------------------------------------------------------------------------
// The solve.

TEST(SolveRing, ZeroForceLeavesTheRingAtRest) {
  const SectionSpec spec = Spec(16);
  const RingStiffness k{1e-4, 2.0};
  const RingResult r = SolveRing(spec, k, Eigen::Vector2d::Zero());
  EXPECT_TRUE(r.summary.converged);
  EXPECT_EQ(r.summary.reason, RingTermination::kZeroLoad);
  EXPECT_EQ(r.contact_node, -1);
  EXPECT_EQ((r.nodes - r.rest).cwiseAbs().maxCoeff(), 0.0);
  // Also from a warm start: the unloaded ring is at rest.
  const RingResult dented = SolveRing(spec, k, AimedAt(0, 16, 0.1));
  ASSERT_TRUE(dented.summary.converged);
  const RingResult back = SolveRing(spec, k, Eigen::Vector2d::Zero(), {}, &dented.nodes);
  EXPECT_TRUE(back.summary.converged);
  // Back at rest up to the round-off of the rest polygon's coordinates (~eps R).
  EXPECT_LT((back.nodes - back.rest).cwiseAbs().maxCoeff(), 1e-14 * spec.radius);
}

TEST(SolveRing, WarmStartReachesTheSameEquilibriumFaster) {
  const SectionSpec spec = Spec(16);
  const RingStiffness k{1e-4, 2.0};
  const RingResult cold = SolveRing(spec, k, AimedAt(3, 16, 3.0));
  const RingResult near = SolveRing(spec, k, AimedAt(3, 16, 3.3));
  const RingResult warm = SolveRing(spec, k, AimedAt(3, 16, 3.0), {}, &near.nodes);
  ASSERT_TRUE(cold.summary.converged && warm.summary.converged);
  EXPECT_LT((cold.nodes - warm.nodes).cwiseAbs().maxCoeff(), 1e-12 * spec.radius);
  EXPECT_LT(warm.summary.iterations, cold.summary.iterations);
}

// One RingSolver re-solving into one result (the runtime's mesh): each solve from rest is the
// fresh SolveRing's exactly (nothing of the last solve leaks into the next), and each
// warm-started from the last result (a zero force among them) reaches the same equilibrium.
TEST(SolveRing, ReusedSolverMatchesFreshSolves) {
  const SectionSpec spec = Spec(24);
  const RingStiffness k{1e-4, 2.0};
  RingSolveOptions options;
  options.compute_sensitivities = false;
  RingSolver solver(spec, k, options);
  RingResult cold, warm;
  bool have_warm = false;
  for (int step = 0; step <= 12; ++step) {
    const double a = 0.3 * step;
    const Eigen::Vector2d F = (step == 6 ? 0.0 : 0.5 + 0.2 * step) *
                              Eigen::Vector2d(std::cos(a), std::sin(a));
    const RingResult fresh = SolveRing(spec, k, F, options);
    solver.Solve(F, nullptr, &cold);
    solver.Solve(F, have_warm ? &warm.nodes : nullptr, &warm);
    have_warm = true;
    ASSERT_TRUE(fresh.summary.converged && cold.summary.converged && warm.summary.converged)
        << "step " << step;
    EXPECT_EQ(cold.nodes, fresh.nodes) << "step " << step;
    EXPECT_EQ(cold.summary.iterations, fresh.summary.iterations);
    EXPECT_EQ(cold.contact_node, fresh.contact_node);
    EXPECT_EQ(cold.d_nodes_d_log_bend.size(), 0);
    // The same gradient test (1e-10 |F|) from another start: the nodes agree to about 1e-11 of
    // the dent (measured at most 1.4e-11 of it); 1e-9 leaves a factor of 70 for round-off.
    const double dent = (fresh.nodes - fresh.rest).cwiseAbs().maxCoeff();
    EXPECT_LE((warm.nodes - fresh.nodes).cwiseAbs().maxCoeff(), 1e-9 * dent) << "step " << step;
  }
}

// The runtime's poke: the bowel's section (data/profiles/bowel_poke.json: r 12 mm, 32 nodes,
// kb 2.2e-5 N m^2, ks 5 N) under a push rising from zero and falling back, each solve
// warm-started from the last. Near zero force the Newton step's promised decrease falls below
// the energy's round-off while the gradient is still 1e3 x its tolerance: the Armijo test alone
// then took only steps of 2^-20 and less, and 35 of 1300 such solves ran to max_iterations.
TEST(SolveRing, WarmSolvesConvergeThroughTinyForces) {
  SectionSpec spec = Spec(32, 0.012);
  spec.h_factor = 0.5;
  spec.stop_factor = 0.01;
  const RingStiffness k{2.1963071633622573e-05, 5.0};
  RingSolveOptions options;
  options.compute_sensitivities = false;
  RingSolver solver(spec, k, options);
  RingResult ring;
  bool warm = false;
  int most = 0;
  for (int tick = 1; tick <= 1300; ++tick) {
    const double push = 0.015 * (1.0 - std::cos(2.0 * kPi * tick / 1000.0));
    const Eigen::Vector2d F = push * Eigen::Vector2d(0.28, -0.96);
    solver.Solve(F, warm ? &ring.nodes : nullptr, &ring);
    ASSERT_TRUE(ring.summary.converged) << "tick " << tick << ": " << ring.summary.BriefReport();
    warm = true;
    most = std::max(most, ring.summary.iterations);
  }
  std::printf("most Newton iterations of a warm solve: %d\n", most);  // measured: 3
  EXPECT_LE(most, 8);
}

TEST(SolveRing, ContactNodeIsWhereTheForcePushesIn) {
  const RingGeometry g = MakeRingGeometry(Spec(16));
  EXPECT_EQ(ContactNode(g, AimedAt(5, 16, 1.0)), 5);
  EXPECT_EQ(ContactNode(g, AimedAt(0, 16, 1.0)), 0);
  // A force between nodes 3 and 4, closer to 3.
  const double a = 2.0 * kPi * 3.3 / 16;
  EXPECT_EQ(ContactNode(g, -Eigen::Vector2d(std::cos(a), std::sin(a))), 3);
}

TEST(SolveRing, LoadIsBalancedAndTheMassCentreStays) {
  const SectionSpec spec = Spec(24);
  const RingGeometry g = MakeRingGeometry(spec);
  const RingStiffness k{1e-4, 2.0};
  // Aimed at a node, and at an angle to every node's normal (then the rotation pin carries a
  // moment).
  for (const Eigen::Vector2d& F : {AimedAt(5, 24, 0.5), Eigen::Vector2d(0.3, -0.4)}) {
    const RingLoad load = MakeRingLoad(g, F);
    Eigen::Vector2d net = Eigen::Vector2d::Zero();
    for (int i = 0; i < g.n; ++i) net += load.nodal.segment<2>(2 * i);
    EXPECT_LT(net.norm(), 1e-15 * F.norm());
    const RingResult r = SolveRing(spec, k, F);
    ASSERT_TRUE(r.summary.converged) << r.summary.BriefReport();
    EXPECT_TRUE(r.summary.stable);
    const Eigen::VectorXd u = Packed(r.displacement());
    EXPECT_LT((RingCentre(g, r.nodes) - RingCentre(g, g.rest)).norm(), 1e-14 * spec.radius);
    // Equilibrium: the elastic forces balance the load up to the rotation pin, i.e. the full
    // gradient of Pi has no net force, and its moment is the pin's.
    Eigen::VectorXd grad;
    RingElasticEnergy(g, k, u, &grad);
    grad -= load.nodal;
    Eigen::Vector2d net_g = Eigen::Vector2d::Zero();
    for (int i = 0; i < g.n; ++i) net_g += grad.segment<2>(2 * i);
    EXPECT_LT(net_g.norm(), 1e-9 * F.norm());
    // The deformation is a real dent at the contact node.
    const Eigen::Vector2d n_c = g.rest.col(r.contact_node).normalized();
    EXPECT_LT(r.displacement().col(r.contact_node).dot(n_c), -1e-3 * spec.radius);
  }
  EXPECT_NEAR(SolveRing(spec, k, AimedAt(5, 24, 0.5)).pin_moment, 0.0, 1e-12 * 0.5 * spec.radius);
  EXPECT_GT(std::abs(SolveRing(spec, k, Eigen::Vector2d(0.3, -0.4)).pin_moment),
            1e-3 * 0.5 * spec.radius);
}

TEST(SolveRing, MirrorSymmetricAboutTheForceLine) {
  // N = 20, force aimed at node 3 and large enough to be well nonlinear (F R^2 / kb = 2).
  const int N = 20, c = 3;
  const SectionSpec spec = Spec(N);
  const RingStiffness k{1e-4, 5.0};
  const double f = 2.0 * k.bend / (spec.radius * spec.radius);
  const RingResult r = SolveRing(spec, k, AimedAt(c, N, f));
  ASSERT_TRUE(r.summary.converged) << r.summary.BriefReport();
  EXPECT_EQ(r.contact_node, c);
  const Eigen::Vector2d n = r.rest.col(c).normalized();
  const Eigen::Matrix2d mirror = 2.0 * n * n.transpose() - Eigen::Matrix2d::Identity();
  double worst = 0.0;
  for (int j = 0; j < N; ++j) {
    const int a = (c + j) % N, b = ((c - j) % N + N) % N;
    worst = std::max(worst, (mirror * r.nodes.col(a) - r.nodes.col(b)).norm());
  }
  EXPECT_LT(worst, 1e-12 * spec.radius);
  const double dent = -r.displacement().col(c).dot(n);
  EXPECT_GT(dent, 0.05 * spec.radius);  // really nonlinear
}

TEST(SolveRing, ResponseIsLinearInSmallForces) {
  const SectionSpec spec = Spec(32);
  const RingStiffness k{1e-4, 10.0};
  const double unit = k.bend / (spec.radius * spec.radius);  // force that dents by ~R
  // Relative nonlinearity |u(2F) - 2 u(F)| / |2 u(F)| of a force F R^2 / kb = eps is O(eps):
  // check it is below 2 eps (the ring's quadratic terms are O(1)) and that it scales like eps,
  // so it is the physics and not solver noise.
  auto nonlinearity = [&](const Eigen::Vector2d& F) {
    const RingResult r1 = SolveRing(spec, k, F), r2 = SolveRing(spec, k, 2.0 * F);
    EXPECT_TRUE(r1.summary.converged && r2.summary.converged);
    const Eigen::Matrix2Xd u1 = r1.displacement(), u2 = r2.displacement();
    return (u2 - 2.0 * u1).cwiseAbs().maxCoeff() / (2.0 * u1.cwiseAbs().maxCoeff());
  };
  for (const Eigen::Vector2d& dir : {Eigen::Vector2d(AimedAt(7, 32, 1.0)),
                                     Eigen::Vector2d(0.6, -0.8)}) {
    const double eps = 1e-4;
    const double small = nonlinearity(eps * unit * dir), larger = nonlinearity(10 * eps * unit * dir);
    EXPECT_LT(small, 2.0 * eps);
    EXPECT_NEAR(larger / small, 10.0, 1.0);
  }
}

TEST(SolveRing, LargePushConvergesToAStableDent) {
  const SectionSpec spec = Spec(32);
  const RingStiffness k{1e-4, 10.0};
  const double f = 8.0 * k.bend / (spec.radius * spec.radius);
  const RingResult r = SolveRing(spec, k, AimedAt(0, 32, f));
  EXPECT_TRUE(r.summary.IsUsable()) << r.summary.BriefReport();
  EXPECT_TRUE(r.summary.stable);
  EXPECT_LT(r.summary.iterations, 30);
  // A deep dent, yet the ring does not pass through its own centre.
  EXPECT_GT(r.nodes(0, 0), -0.9 * spec.radius);
  EXPECT_LT(r.nodes(0, 0), 0.7 * spec.radius);
}

TEST(SolveRing, SensitivitiesMatchFiniteDifferencesOfTheSolve) {
  const SectionSpec spec = Spec(16);
  const RingStiffness k{1e-4, 3.0};
  const Eigen::Vector2d F(-0.7, 0.45);  // not aimed at a node: pin and all terms active
  RingSolveOptions tight;
  tight.gradient_tolerance = 1e-14;
  const RingResult r = SolveRing(spec, k, F, tight);
  ASSERT_TRUE(r.summary.converged && r.summary.stable) << r.summary.BriefReport();
  ASSERT_EQ(r.d_nodes_d_log_bend.size(), 32);
  const double h = 1e-5;  // in log stiffness; central differences: error ~ h^2 = 1e-10
  auto solve = [&](const RingStiffness& kk, const Eigen::Vector2d& FF) {
    const RingResult s = SolveRing(spec, kk, FF, tight);
    EXPECT_TRUE(s.summary.converged);
    EXPECT_EQ(s.contact_node, r.contact_node);
    return Packed(s.displacement());
  };
  const Eigen::VectorXd db =
      (solve({k.bend * std::exp(h), k.stretch}, F) - solve({k.bend * std::exp(-h), k.stretch}, F)) / (2 * h);
  const Eigen::VectorXd ds =
      (solve({k.bend, k.stretch * std::exp(h)}, F) - solve({k.bend, k.stretch * std::exp(-h)}, F)) / (2 * h);
  EXPECT_LT((db - r.d_nodes_d_log_bend).cwiseAbs().maxCoeff(), 1e-6 * db.cwiseAbs().maxCoeff())
      << Show(r.d_nodes_d_log_bend.transpose(), db.transpose());
  EXPECT_LT((ds - r.d_nodes_d_log_stretch).cwiseAbs().maxCoeff(), 1e-6 * ds.cwiseAbs().maxCoeff())
      << Show(r.d_nodes_d_log_stretch.transpose(), ds.transpose());
  for (int c = 0; c < 2; ++c) {
    const double hf = 1e-5 * F.norm();
    Eigen::Vector2d e = Eigen::Vector2d::Zero();
    e[c] = hf;
    const Eigen::VectorXd dF = (solve(k, F + e) - solve(k, F - e)) / (2 * hf);
    EXPECT_LT((dF - r.d_nodes_d_force.col(c)).cwiseAbs().maxCoeff(), 1e-6 * dF.cwiseAbs().maxCoeff())
        << Show(r.d_nodes_d_force.col(c).transpose(), dF.transpose());
  }
  // A stiffer ring dents less: the log-bend sensitivity opposes the displacement at the contact.
  EXPECT_LT(r.d_nodes_d_log_bend.segment<2>(2 * r.contact_node).dot(r.displacement().col(r.contact_node)), 0.0);
}

// Closed form for our loading, by linear theory of the thin inextensible ring (derived here;
// it is Roark's "ring supported at the base and loaded by its own weight", Roark's Formulas for
// Stress and Strain, thin-ring table, with the weight w 2 pi R = P: Delta D_V = -0.4674 w R^4/EI,
// Delta D_H = +0.4292 w R^4/EI). Radial displacement w(theta) = sum_n a_n cos(n theta) with the
// tangential one from inextensibility; the uniform body force acts only on the rigid mode n = 1,
// the point load P at theta = 0 gives a_n = -P R^3 / (pi EI (n^2 - 1)^2) for n >= 2. Summing,
//   along the load line:  Delta D = -(pi/8 - 1/pi) P R^3 / EI       (-0.074389)
//   across it:            Delta D = +(1/pi - 1/4)  P R^3 / EI       (+0.068310)
// and the stretch stiffness adds the breathing mode a_0 = -P R / (2 pi EA) (Delta D = -P R /
// (pi EA)); the other modes' stretch corrections are O(EI / (EA R^2)) = 1e-7 here.
TEST(SolveRing, MatchesThinRingClosedFormUnderPointLoadAndBodyForce) {
  const double R = 1.0, EI = 1.0, EA = 1e7;
  const double P = 1e-4 * EI / (R * R);  // linear regime: nonlinearity ~1e-4
  const double along = -(kPi / 8 - 1 / kPi) * P * R * R * R / EI - P * R / (kPi * EA);
  const double across = (1 / kPi - 0.25) * P * R * R * R / EI - P * R / (kPi * EA);
  std::vector<double> err;
  for (int N : {32, 64, 128}) {
    const RingResult r = SolveRing(Spec(N, R), {EI, EA}, AimedAt(0, N, P));
    ASSERT_TRUE(r.summary.converged) << r.summary.BriefReport();
    const double d_along = (r.nodes.col(0) - r.nodes.col(N / 2)).norm() - 2 * R;
    const double d_across = (r.nodes.col(N / 4) - r.nodes.col(3 * N / 4)).norm() - 2 * R;
    err.push_back(std::max(std::abs(d_along / along - 1), std::abs(d_across / across - 1)));
  }
  // Second-order convergence in N (the point load sits on a node) and within 0.1% at N = 128
  // (discretisation ~3e-4, nonlinearity ~1e-4).
  EXPECT_LT(err[2], 1e-3);
  EXPECT_GT(err[0] / err[1], 3.0);
  EXPECT_GT(err[1] / err[2], 3.0);
}

TEST(SolveRing, RejectsInvalidInput) {
  EXPECT_THROW(SolveRing(Spec(6), {1e-4, 1.0}, Eigen::Vector2d(1, 0)), std::invalid_argument);
  EXPECT_THROW(SolveRing(Spec(16, 0.0), {1e-4, 1.0}, Eigen::Vector2d(1, 0)), std::invalid_argument);
  EXPECT_THROW(SolveRing(Spec(16), {0.0, 1.0}, Eigen::Vector2d(1, 0)), std::invalid_argument);
  EXPECT_THROW(SolveRing(Spec(16), {1e-4, -1.0}, Eigen::Vector2d(1, 0)), std::invalid_argument);
  std::string why;
  SectionSpec s = Spec(16);
  s.h_factor = 0.0;
  EXPECT_FALSE(s.Check(&why));
  EXPECT_NE(why.find("h_factor"), std::string::npos);
}

TEST(Section, WorldMappingAndProjection) {
  SectionPlacement p;
  p.centre = Eigen::Vector3d(1, 2, 3);
  p.d1 = Eigen::Vector3d(0, 0, 1);
  p.d2 = Eigen::Vector3d(0, -1, 0);
  const Eigen::Vector2d F = ProjectToSection(Eigen::Vector3d(5, 2, -3), p);
  EXPECT_EQ(F, Eigen::Vector2d(-3, -2));  // the normal component (along x) is dropped
  Eigen::Matrix2Xd pts(2, 2);
  pts << 1, 0, 0, 2;
  const Eigen::Matrix3Xd w = SectionToWorld(pts, p);
  EXPECT_EQ(Eigen::Vector3d(w.col(0)), Eigen::Vector3d(1, 2, 4));
  EXPECT_EQ(Eigen::Vector3d(w.col(1)), Eigen::Vector3d(1, 0, 3));
}

}  // namespace
}  // namespace rodfit
