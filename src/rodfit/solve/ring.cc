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

RingSolver::RingSolver(const SectionSpec& spec, const RingStiffness& stiffness,
                       const RingSolveOptions& options)
    : stiffness_(stiffness), options_(options) {
  std::string why;
  Require(stiffness.Check(&why), why);
  Require(options.Check(&why), why);
  g_ = MakeRingGeometry(spec);
  const int m = 2 * g_.n;
  // Orthonormal basis Z of the constraints' null space: the last m - 3 columns of Q in C^T = QR.
  const Eigen::MatrixXd Ct = RingConstraints(g_).transpose();
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Ct);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(m, m);
  Z_ = Q.rightCols(m - 3);
  // The reflections themselves (Eigen keeps v_k's entries below the k-th in column k of the
  // factor, with an implicit 1 at k).
  reflectors_.setZero(m, 3);
  for (int k = 0; k < 3; ++k) {
    reflectors_(k, k) = 1.0;
    reflectors_.col(k).tail(m - k - 1) = qr.matrixQR().col(k).tail(m - k - 1);
    tau_[k] = qr.hCoeffs()[k];
  }
  // Every buffer at its size.
  MakeRingLoad(g_, Vec2::Zero(), &load_);
  u_.setZero(m);
  grad_.setZero(m);
  grad_try_.setZero(m);
  u_try_.setZero(m);
  du_.setZero(m);
  full_.setZero(m);
  gr_.setZero(m - 3);
  p_.setZero(m - 3);
  hess_.setZero(m, m);
  work_.setZero(m, m);
  hr_.setZero(m - 3, m - 3);
  llt_ = Eigen::LLT<Eigen::MatrixXd>(m - 3);
}

void RingSolver::ToReduced(const Eigen::VectorXd& x, Eigen::VectorXd* reduced) {
  // Q^T x = H_2 H_1 H_0 x; Z^T x is its tail.
  full_ = x;
  for (int k = 0; k < 3; ++k)
    full_ -= (tau_[k] * reflectors_.col(k).dot(full_)) * reflectors_.col(k);
  *reduced = full_.tail(full_.size() - 3);
}

void RingSolver::FromReduced(const Eigen::VectorXd& reduced, Eigen::VectorXd* x) {
  // Q [0; y] = H_0 H_1 H_2 [0; y].
  const int m = static_cast<int>(full_.size());
  x->head<3>().setZero();
  x->tail(m - 3) = reduced;
  for (int k = 2; k >= 0; --k)
    *x -= (tau_[k] * reflectors_.col(k).dot(*x)) * reflectors_.col(k);
}

void RingSolver::ReducedHessian(const Eigen::MatrixXd& hessian, Eigen::MatrixXd* reduced) {
  // Q^T H Q = H_2 H_1 H_0 H H_0 H_1 H_2, one symmetric reflection at a time:
  // H_k M H_k = M - v z^T - z v^T with w = M v, z = tau w - tau^2 (v.w) / 2 v.
  work_ = hessian;
  for (int k = 0; k < 3; ++k) {
    const auto v = reflectors_.col(k);
    full_.noalias() = work_ * v;
    full_ = tau_[k] * full_ - (0.5 * tau_[k] * tau_[k] * v.dot(full_)) * v;
    work_.noalias() -= v * full_.transpose();
    work_.noalias() -= full_ * v.transpose();
  }
  const int r = static_cast<int>(work_.rows()) - 3;
  *reduced = work_.bottomRightCorner(r, r);
}

double RingSolver::Potential(const Eigen::VectorXd& u, Eigen::VectorXd* grad,
                             Eigen::MatrixXd* hess, double* scale) {
  const double elastic = RingElasticEnergy(g_, stiffness_, u, grad, hess);
  const double work = load_.nodal.dot(u);
  if (grad) *grad -= load_.nodal;
  if (scale) *scale = std::abs(elastic) + std::abs(work);
  return elastic - work;
}

void RingSolver::Sensitivities(const Eigen::VectorXd& u, RingResult* result) {
  // Allocates: a fit's solve, not the runtime's.
  if (!options_.compute_sensitivities) return;
  const Eigen::MatrixXd& Z = Z_;
  Eigen::VectorXd gb, gs;
  RingElasticEnergy(g_, RingStiffness{stiffness_.bend, 0.0}, u, &gb);
  RingElasticEnergy(g_, RingStiffness{0.0, stiffness_.stretch}, u, &gs);
  // U is linear in each stiffness: d grad / d log kb = grad of the bending part.
  result->d_nodes_d_log_bend = -Z * llt_.solve(Z.transpose() * gb);
  result->d_nodes_d_log_stretch = -Z * llt_.solve(Z.transpose() * gs);
  if (load_.contact_node >= 0) {
    // grad Pi = grad U - f(F): d u / d F = Z Hr^-1 Z^T d f / d F.
    result->d_nodes_d_force = Z * llt_.solve(Z.transpose() * load_.d_nodal_d_force);
  }
}

// One function, though long: the constrained Newton loop shares its factor and line search
// state; the sensitivities reuse the last factor.
void RingSolver::Solve(const Vec2& force_in_plane, const Eigen::Matrix2Xd* warm_start,
                       RingResult* result) {
  // (No Require here: its message would be built, and allocated, on every solve.)
  if (!force_in_plane.allFinite()) throw std::invalid_argument("section force must be finite");
  const RingGeometry& g = g_;
  const int n = g.n, m = 2 * n;
  MakeRingLoad(g, force_in_plane, &load_);
  const Eigen::Map<const Eigen::VectorXd> x_rest(g.rest.data(), m);
  // The unknowns are the displacements u = x - x° (see RingElasticEnergy on precision).
  Eigen::VectorXd& u = u_;
  u.setZero();
  if (warm_start) {  // read before *result is written: it may be the last result's nodes
    if (warm_start->cols() != n)
      throw std::invalid_argument("warm start must have one column per section node");
    // Its projection onto the constraints: u = Z Z^T (x_warm - x°).
    u_try_ = Eigen::Map<const Eigen::VectorXd>(warm_start->data(), m) - x_rest;
    ToReduced(u_try_, &gr_);
    FromReduced(gr_, &u);
  }

  RingResult& r = *result;
  r.rest = g.rest;  // the result's storage is kept once sized
  r.nodes = g.rest;
  r.contact_node = load_.contact_node;
  r.force = force_in_plane;
  r.pin_moment = 0.0;
  r.summary = RingSummary();
  if (!options_.compute_sensitivities) {
    r.d_nodes_d_log_bend.resize(0);
    r.d_nodes_d_log_stretch.resize(0);
    r.d_nodes_d_force.resize(0, 2);
  }
  const double force_norm = force_in_plane.norm();
  RingSummary& summary = r.summary;

  // F = 0: the rest ring is the solution (U >= 0 vanishes only on rigid motions, which the
  // constraints remove), whatever the warm start.
  if (force_norm == 0.0) {
    u.setZero();
    summary.converged = true;
    summary.reason = RingTermination::kZeroLoad;
    RingElasticEnergy(g, stiffness_, u, nullptr, &hess_);
    ReducedHessian(hess_, &hr_);
    llt_.compute(hr_);
    summary.stable = llt_.info() == Eigen::Success;
    if (summary.stable) Sensitivities(u, result);
    return;
  }

  double scale = 0.0;
  double pi = Potential(u, &grad_, &hess_, &scale);
  for (int it = 0;; ++it) {
    if (!std::isfinite(pi) || !grad_.allFinite()) {
      summary.reason = RingTermination::kNotFinite;
      break;
    }
    ToReduced(grad_, &gr_);
    summary.gradient_norm = gr_.lpNorm<Eigen::Infinity>();
    if (summary.gradient_norm <= options_.gradient_tolerance * force_norm) {
      summary.converged = true;
      summary.reason = RingTermination::kGradientTolerance;
      break;
    }
    if (it >= options_.max_iterations) {
      summary.reason = RingTermination::kMaxIterations;
      break;
    }
    // Newton direction on the reduced Hessian, shifted until positive definite.
    ReducedHessian(hess_, &hr_);
    llt_.compute(hr_);
    const bool shifted = llt_.info() != Eigen::Success;
    if (shifted) {
      ++summary.hessian_shifts;
      const double diag = hr_.diagonal().cwiseAbs().maxCoeff();
      double mu = 1e-8 * diag;
      for (int s = 0; s < 60 && llt_.info() != Eigen::Success; ++s, mu *= 10.0) {
        hr_.diagonal().array() += mu - (s == 0 ? 0.0 : mu / 10.0);
        llt_.compute(hr_);
      }
      if (llt_.info() != Eigen::Success) {
        summary.reason = RingTermination::kNotFinite;
        break;
      }
    }
    p_ = llt_.solve(gr_);
    p_ = -p_;
    FromReduced(p_, &du_);
    const double slope = gr_.dot(p_);
    // Converged once the Newton step is negligible: relative to the displacement, or promising
    // less than Pi's round-off (the decrement -g.p is twice the promised decrease). The gradient
    // alone cannot tell: its round-off floor (cancellation in the turning angle, eps ks |u| / L_k
    // in the stretch) can exceed gradient_tolerance |F|. The tiny step is taken, not discarded.
    const bool tiny_step =
        du_.lpNorm<Eigen::Infinity>() <= options_.step_tolerance * u.lpNorm<Eigen::Infinity>();
    const bool round_off = -slope <= 16.0 * std::numeric_limits<double>::epsilon() * scale;
    if (tiny_step || round_off) {
      u += du_;
      pi = Potential(u, &grad_, &hess_, &scale);
      ++summary.iterations;
      summary.converged = true;
      summary.reason = tiny_step ? RingTermination::kStepTolerance : RingTermination::kRoundOff;
      ToReduced(grad_, &gr_);
      summary.gradient_norm = gr_.lpNorm<Eigen::Infinity>();
      break;
    }
    // Armijo backtracking; Pi's round-off (a few ulps of its terms) is tolerated so that the last
    // steps near convergence, whose decrease is below round-off, are not rejected as uphill.
    const double noise = 64.0 * std::numeric_limits<double>::epsilon() * scale;
    double alpha = 1.0;
    bool accepted = false;
    if (!shifted && -slope <= 1e3 * noise) {
      // A decrease the energy barely resolves: Pi is a sum of terms far larger than the step's
      // change (|U| and |f.u| cancel), so its actual round-off exceeds `noise`, and Armijo
      // accepted only steps of 2^-17 and smaller there and ran to max_iterations with the
      // gradient 1e3 x its tolerance (35 of 1300 warm solves of a runtime poke's ring). The
      // full, unshifted Newton step is judged by the gradient instead, and taken if it lowers it.
      u_try_ = u + du_;
      Potential(u_try_, &grad_try_, nullptr, nullptr);
      ToReduced(grad_try_, &p_);  // p_ is free until the next iteration's solve
      if (grad_try_.allFinite() && p_.lpNorm<Eigen::Infinity>() < summary.gradient_norm)
        accepted = true;
    }
    for (int ls = 0; ls < options_.max_line_search_steps && !accepted; ++ls, alpha *= 0.5) {
      u_try_ = u + alpha * du_;
      const double pi_try = Potential(u_try_, nullptr, nullptr, nullptr);
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
    u.swap(u_try_);
    pi = Potential(u, &grad_, &hess_, &scale);
  }

  summary.energy = pi;
  r.nodes = g.rest + Eigen::Map<const Eigen::Matrix2Xd>(u.data(), 2, n);
  const Vec2 centre = RingCentre(g, r.nodes);
  if (load_.contact_node >= 0) {
    const Vec2 arm = r.nodes.col(load_.contact_node) - centre;
    r.pin_moment = arm.x() * force_in_plane.y() - arm.y() * force_in_plane.x();
  }
  if (std::isfinite(pi) && hess_.allFinite()) {
    ReducedHessian(hess_, &hr_);
    llt_.compute(hr_);
    summary.stable = llt_.info() == Eigen::Success;
    if (summary.converged && summary.stable) Sensitivities(u, result);
  }
}

RingResult SolveRing(const SectionSpec& spec, const RingStiffness& stiffness,
                     const Vec2& force_in_plane, const RingSolveOptions& options,
                     const Eigen::Matrix2Xd* warm_start) {
  RingSolver solver(spec, stiffness, options);
  RingResult result;
  solver.Solve(force_in_plane, warm_start, &result);
  return result;
}

}  // namespace rodfit
