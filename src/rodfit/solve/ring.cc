// The ring's constrained Newton solve (ring.h).
#include "rodfit/solve/ring.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/QR>

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;

void Require(bool ok, const std::string& why) {
  if (!ok) throw std::invalid_argument(why);
}

}  // namespace

bool RingSolveOptions::Check(std::string* why) const {
  std::string w;
  if (max_iterations < 1) w = "max_iterations must be at least 1";
  else if (max_line_search_steps < 1) w = "max_line_search_steps must be at least 1";
  else if (!(gradient_tolerance >= 0.0)) w = "gradient_tolerance must be non-negative";
  else if (!(step_tolerance >= 0.0)) w = "step_tolerance must be non-negative";
  if (why) *why = w;
  return w.empty();
}

RingResult SolveRing(const SectionSpec& spec, const RingStiffness& stiffness,
                     const Vec2& force_in_plane, const RingSolveOptions& options,
                     const Eigen::Matrix2Xd* warm_start) {
  std::string why;
  Require(stiffness.Check(&why), why);
  Require(options.Check(&why), why);
  Require(force_in_plane.allFinite(), "section force must be finite");
  const RingGeometry g = MakeRingGeometry(spec);
  const int n = g.n, m = 2 * n;
  const RingLoad load = MakeRingLoad(g, force_in_plane);

  RingResult result;
  result.rest = g.rest;
  result.nodes = g.rest;
  result.contact_node = load.contact_node;
  result.force = force_in_plane;
  const Eigen::Map<const Eigen::VectorXd> x_rest(g.rest.data(), m);
  // The unknowns are the displacements u = x - x° (see RingElasticEnergy on precision).

  // Orthonormal basis Z of the constraints' null space: the last m - 3 columns of Q in C^T = QR.
  const Eigen::MatrixXd Ct = RingConstraints(g).transpose();
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Ct);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(m, m);
  const Eigen::MatrixXd Z = Q.rightCols(m - 3);

  const double force_norm = force_in_plane.norm();
  RingSummary& summary = result.summary;
  auto sensitivities = [&](const Eigen::LLT<Eigen::MatrixXd>& llt, const Eigen::VectorXd& u) {
    if (!options.compute_sensitivities) return;
    Eigen::VectorXd gb, gs;
    RingElasticEnergy(g, RingStiffness{stiffness.bend, 0.0}, u, &gb);
    RingElasticEnergy(g, RingStiffness{0.0, stiffness.stretch}, u, &gs);
    // U is linear in each stiffness: d grad / d log kb = grad of the bending part.
    result.d_nodes_d_log_bend = -Z * llt.solve(Z.transpose() * gb);
    result.d_nodes_d_log_stretch = -Z * llt.solve(Z.transpose() * gs);
    if (load.contact_node >= 0) {
      // grad Pi = grad U - f(F): d u / d F = Z Hr^-1 Z^T d f / d F.
      result.d_nodes_d_force = Z * llt.solve(Z.transpose() * load.d_nodal_d_force);
    }
  };

  Eigen::VectorXd u = Eigen::VectorXd::Zero(m);
  if (warm_start) {
    Require(warm_start->cols() == n, "warm start must have one column per section node");
    const Eigen::Map<const Eigen::VectorXd> ws(warm_start->data(), m);
    u = Z * (Z.transpose() * (ws - x_rest));
  }

  auto potential = [&](const Eigen::VectorXd& uu, Eigen::VectorXd* grad, Eigen::MatrixXd* hess,
                       double* scale) {
    const double elastic = RingElasticEnergy(g, stiffness, uu, grad, hess);
    const double work = load.nodal.dot(uu);
    if (grad) *grad -= load.nodal;
    if (scale) *scale = std::abs(elastic) + std::abs(work);
    return elastic - work;
  };

  // F = 0: the rest ring is the solution (U >= 0 vanishes only on rigid motions, which the
  // constraints remove), whatever the warm start.
  if (force_norm == 0.0) {
    summary.converged = true;
    summary.reason = RingTermination::kZeroLoad;
    summary.stable = true;
    Eigen::MatrixXd H;
    RingElasticEnergy(g, stiffness, u, nullptr, &H);
    const Eigen::LLT<Eigen::MatrixXd> llt(Z.transpose() * H * Z);
    summary.stable = llt.info() == Eigen::Success;
    if (summary.stable) sensitivities(llt, u);
    return result;
  }

  Eigen::VectorXd grad;
  Eigen::MatrixXd hess;
  double scale = 0.0;
  double pi = potential(u, &grad, &hess, &scale);
  for (int it = 0;; ++it) {
    if (!std::isfinite(pi) || !grad.allFinite()) {
      summary.reason = RingTermination::kNotFinite;
      break;
    }
    const Eigen::VectorXd gr = Z.transpose() * grad;
    summary.gradient_norm = gr.lpNorm<Eigen::Infinity>();
    if (summary.gradient_norm <= options.gradient_tolerance * force_norm) {
      summary.converged = true;
      summary.reason = RingTermination::kGradientTolerance;
      break;
    }
    if (it >= options.max_iterations) {
      summary.reason = RingTermination::kMaxIterations;
      break;
    }
    // Newton direction on the reduced Hessian, shifted until positive definite.
    Eigen::MatrixXd Hr = Z.transpose() * hess * Z;
    Eigen::LLT<Eigen::MatrixXd> llt(Hr);
    if (llt.info() != Eigen::Success) {
      ++summary.hessian_shifts;
      const double diag = Hr.diagonal().cwiseAbs().maxCoeff();
      double mu = 1e-8 * diag;
      for (int s = 0; s < 60 && llt.info() != Eigen::Success; ++s, mu *= 10.0) {
        llt.compute(Hr + mu * Eigen::MatrixXd::Identity(m - 3, m - 3));
      }
      if (llt.info() != Eigen::Success) {
        summary.reason = RingTermination::kNotFinite;
        break;
      }
    }
    const Eigen::VectorXd p = -llt.solve(gr);
    const Eigen::VectorXd du = Z * p;
    const double slope = gr.dot(p);
    // Converged once the Newton step is negligible: relative to the displacement, or promising
    // less than Pi's round-off (the decrement -g.p is twice the promised decrease). The gradient
    // alone cannot tell: its round-off floor (cancellation in the turning angle, eps ks |u| / L_k
    // in the stretch) can exceed gradient_tolerance |F|. The tiny step is taken, not discarded.
    const bool tiny_step = du.lpNorm<Eigen::Infinity>() <= options.step_tolerance * u.lpNorm<Eigen::Infinity>();
    const bool round_off = -slope <= 16.0 * std::numeric_limits<double>::epsilon() * scale;
    if (tiny_step || round_off) {
      u += du;
      pi = potential(u, &grad, &hess, &scale);
      ++summary.iterations;
      summary.converged = true;
      summary.reason = tiny_step ? RingTermination::kStepTolerance : RingTermination::kRoundOff;
      summary.gradient_norm = (Z.transpose() * grad).lpNorm<Eigen::Infinity>();
      break;
    }
    // Armijo backtracking; Pi's round-off (a few ulps of its terms) is tolerated so that the last
    // steps near convergence, whose decrease is below round-off, are not rejected as uphill.
    const double noise = 64.0 * std::numeric_limits<double>::epsilon() * scale;
    double alpha = 1.0;
    bool accepted = false;
    Eigen::VectorXd u_try;
    double pi_try = 0.0;
    for (int ls = 0; ls < options.max_line_search_steps; ++ls, alpha *= 0.5) {
      u_try = u + alpha * du;
      pi_try = potential(u_try, nullptr, nullptr, nullptr);
      if (std::isfinite(pi_try) && pi_try <= pi + 1e-4 * alpha * slope + noise) {
        accepted = true;
        break;
      }
    }
    ++summary.iterations;
    if (!accepted) {
      summary.reason = RingTermination::kLineSearchFailed;
      break;
    }
    u = u_try;
    pi = potential(u, &grad, &hess, &scale);
  }

  summary.energy = pi;
  result.nodes = g.rest + Eigen::Map<const Eigen::Matrix2Xd>(u.data(), 2, n);
  const Vec2 centre = RingCentre(g, result.nodes);
  if (load.contact_node >= 0) {
    const Vec2 r = result.nodes.col(load.contact_node) - centre;
    result.pin_moment = r.x() * force_in_plane.y() - r.y() * force_in_plane.x();
  }
  if (std::isfinite(pi) && hess.allFinite()) {
    const Eigen::LLT<Eigen::MatrixXd> llt(Z.transpose() * hess * Z);
    summary.stable = llt.info() == Eigen::Success;
    if (summary.converged && summary.stable) sensitivities(llt, u);
  }
  return result;
}

}  // namespace rodfit
