// The ring's constrained Newton solve (ring.h).
#include "rodfit/solve/ring.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include "rodfit/model/check.h"
#include "rodfit/solve/linear_solvers.h"
#include "rodfit/solve/newton_minimizer.h"

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;

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

// The ring's statics as a Newton problem (newton_minimizer.h), on the constrained coordinates
// y (u = u_0 + Z y; the constraints C u = 0 are kept exactly): its merit is Pi, its residual
// Z^T grad Pi, its matrix Z^T H Z (dense: the ring has few nodes), its step du = Z p.
class RingSolver::Problem : public NewtonProblem {
 public:
  explicit Problem(RingSolver* s) : s_(*s) {
    const int m = 2 * s->g_.n;
    ones_ = VecX::Ones(m - 3);
    solver_.Resize(m - 3);
    for (VecX* v : {&u_trial_, &u_previous_, &du_, &grad_trial_}) v->setZero(m);
  }
  /// Starts from the displacements u (the solver's u_).
  void Begin() {
    energy_valid_ = false;
    hess_at_current_ = false;
  }
  bool hessian_at_current() const { return hess_at_current_; }
  const Eigen::MatrixXd& reduced_hessian() { return solver_.matrix(); }
  int NumDofs() const override { return static_cast<int>(ones_.size()); }
  void Evaluate(bool matrix, VecX* g) override {
    energy_ = s_.Potential(s_.u_, &s_.grad_, matrix ? &s_.hess_ : nullptr, &scale_);
    energy_valid_ = true;
    hess_at_current_ = matrix;
    s_.ToReduced(s_.grad_, g);
    if (matrix) s_.ReducedHessian(s_.hess_, &solver_.matrix());
  }
  double Energy() override {
    if (!energy_valid_) energy_ = s_.Potential(s_.u_, nullptr, nullptr, &scale_);
    energy_valid_ = true;
    return energy_;
  }
  bool Retract(const VecX& p, double alpha) override {
    s_.FromReduced(p, &du_);  // O(N): three reflections
    u_trial_ = s_.u_ + alpha * du_;
    trial_energy_valid_ = false;
    return true;
  }
  double TrialEnergy() override {
    trial_energy_ = s_.Potential(u_trial_, nullptr, nullptr, &trial_scale_);
    trial_energy_valid_ = true;
    return trial_energy_;
  }
  void TrialResidual(VecX* g) override {
    s_.Potential(u_trial_, &grad_trial_, nullptr, nullptr);
    s_.ToReduced(grad_trial_, g);
  }
  void AcceptTrial() override {
    u_previous_.swap(s_.u_);
    s_.u_.swap(u_trial_);
    energy_valid_ = trial_energy_valid_;
    energy_ = trial_energy_;
    if (trial_energy_valid_) scale_ = trial_scale_;
    hess_at_current_ = false;
  }
  void RestorePrevious() override {
    u_previous_.swap(s_.u_);
    energy_valid_ = false;
    hess_at_current_ = false;
  }
  StepCaps Caps(const VecX&) override {
    // No turn to cap: the ring's energy is exact at any displacement.
    return {1.0, std::numeric_limits<double>::infinity()};
  }
  RelativeStep Measure(const VecX& p) override {
    s_.FromReduced(p, &du_);
    // Relative to the displacement: the gradient's round-off floor (eps ks |u| / L_k from the
    // stretch, more from cancellation in a fine ring's turning angles) can exceed its tolerance.
    const double u = s_.u_.lpNorm<Eigen::Infinity>();
    const double d = du_.lpNorm<Eigen::Infinity>();
    return {u > 0.0 ? d / (s_.options_.step_tolerance * u)
                    : (d > 0.0 ? std::numeric_limits<double>::infinity() : 0.0),
            0.0};
  }
  const VecX& NormWeights() override { return ones_; }
  // Pi's round-off: a few ulps of its terms (|U| and |f . u|, which cancel).
  double EnergyNoise(double) override {
    return 64.0 * std::numeric_limits<double>::epsilon() * scale_;
  }
  NewtonTolerances Tolerances() override { return {s_.options_.gradient_tolerance * force_, 0.0}; }
  // The ring's first shift: a small fraction of its reduced Hessian's diagonal (its bending and
  // stretch are of one order on a section's scale, unlike a thread's).
  double ShiftBase() override { return 1e-8 * solver_.MaxDiagonal(); }
  LinearSolver& Solver() override { return solver_; }
  void SetForce(double force_norm) { force_ = force_norm; }

 private:
  RingSolver& s_;
  VecX ones_, u_trial_, u_previous_, du_, grad_trial_;
  DenseCholeskySolver solver_;
  double energy_ = 0.0, trial_energy_ = 0.0, scale_ = 0.0, trial_scale_ = 0.0, force_ = 0.0;
  bool energy_valid_ = false, trial_energy_valid_ = false, hess_at_current_ = false;
};

RingSolver::~RingSolver() = default;

RingSolver::RingSolver(const SectionSpec& spec, const RingStiffness& stiffness,
                       const RingSolveOptions& options)
    : stiffness_(stiffness), options_(options) {
  std::string why;
  RODFIT_CHECK_ARG(stiffness.Check(&why), why);
  RODFIT_CHECK_ARG(options.Check(&why), why);
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
  ReserveDenseCholesky(m - 3, &llt_);
  problem_ = std::make_unique<Problem>(this);
  minimizer_ = std::make_unique<NewtonMinimizer>();
  NewtonOptions& o = minimizer_->options();
  o.max_iterations = options.max_iterations;
  o.max_line_search_steps = options.max_line_search_steps;
  // The tiny final step is taken, not discarded; a step promising less than Pi's round-off also
  // ends the solve.
  o.converge_after_small_step = true;
  o.converge_on_decrement = true;
  minimizer_->Reserve(m - 3);
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
  // RODFIT_CHECK_ARG builds its message only on failure: nothing allocated on a good solve.
  RODFIT_CHECK_ARG(force_in_plane.allFinite(), "section force must be finite");
  const RingGeometry& g = g_;
  const int n = g.n, m = 2 * n;
  MakeRingLoad(g, force_in_plane, &load_);
  const Eigen::Map<const Eigen::VectorXd> x_rest(g.rest.data(), m);
  // The unknowns are the displacements u = x - x° (see RingElasticEnergy on precision).
  Eigen::VectorXd& u = u_;
  u.setZero();
  if (warm_start) {  // read before *result is written: it may be the last result's nodes
    RODFIT_CHECK_ARG(warm_start->cols() == n, "warm start must have one column per section node");
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

  problem_->Begin();
  problem_->SetForce(force_norm);
  const NewtonSummary nr = minimizer_->Minimize(problem_.get());
  summary.iterations = nr.iterations;
  summary.hessian_shifts = nr.shifted_factors;
  summary.converged = nr.converged();
  switch (nr.termination) {
    case Termination::kConverged: summary.reason = RingTermination::kGradientTolerance; break;
    case Termination::kSmallStep:
    case Termination::kContraction:
    case Termination::kRoundOff: summary.reason = RingTermination::kStepTolerance; break;
    case Termination::kIterationCap: summary.reason = RingTermination::kMaxIterations; break;
    case Termination::kLineSearchFailed: summary.reason = RingTermination::kLineSearchFailed; break;
    default: summary.reason = RingTermination::kNotFinite; break;
  }
  // Pi, its gradient and Hessian at the result (the last evaluation's when it was there).
  double scale = 0.0;
  double pi = 0.0;
  if (problem_->hessian_at_current()) {
    pi = Potential(u, nullptr, nullptr, &scale);
  } else {
    pi = Potential(u, &grad_, &hess_, &scale);
  }
  ToReduced(grad_, &gr_);
  summary.gradient_norm = gr_.lpNorm<Eigen::Infinity>();
  summary.energy = pi;
  r.nodes = g.rest + Eigen::Map<const Eigen::Matrix2Xd>(u.data(), 2, n);
  const Vec2 centre = RingCentre(g, r.nodes);
  if (load_.contact_node >= 0) {
    const Vec2 arm = r.nodes.col(load_.contact_node) - centre;
    r.pin_moment = arm.x() * force_in_plane.y() - arm.y() * force_in_plane.x();
  }
  if (std::isfinite(pi) && hess_.allFinite()) {
    // The reduced Hessian at the result: the last evaluation's when it was there.
    if (problem_->hessian_at_current()) {
      hr_ = problem_->reduced_hessian();  // same size: a copy, no allocation
    } else {
      ReducedHessian(hess_, &hr_);
    }
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
