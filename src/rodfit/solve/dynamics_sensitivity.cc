// Forward sensitivities of the implicit integrators (dynamics.h, DynamicsStepper::StepSensitivity;
// docs/solvers.md, "Sensitivities in time"). Solve layer: reads the model and the energy
// assembly, nothing above.
//
// The step from q_n solves g(q) = grad Pi(q) + a M (d - y) + c (D + C(q_n)) (d - z) = 0 on the
// free dofs, d = q - q_n (dynamics.cc). Its total derivative with respect to a parameter p, with
// H = K(q_n+1) + a M + c (D + C(q_n)):
//   H dq_n+1 = a M (dq_n + dy) + c (D + C) (dq_n + dz) - c (dC[dq_n]) (d - z) - dg/dp,
// where y and z are the integrator's predictor and damping offsets (linear in v_n and BDF2's
// history, so dy and dz follow from their sensitivities), and dg/dp is:
//  - a stiffness: the gradient of its own term (U is linear in each stiffness). The internal
//    damping matrix is sum eta_k K_unit,k: it does not depend on the stiffnesses;
//  - the external drag c_ext: c D (d - z); an internal viscosity eta_k: c C_k(q_n) (d - z);
//  - the linear density: a M (d - y) and the weights' part of grad Pi (the drag per length and
//    the viscosities do not scale with it).
#include <algorithm>
#include <cmath>

#include "rodfit/solve/banded.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/integrator.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {
namespace {

double LogRatio(double from, double to, double log_factor) {
  return from > 0.0 && to > 0.0 ? std::log(to / from) / log_factor : 0.0;
}

// The internal damping matrix at q with each viscosity scaled by its factor (1, 1, 1: the
// stepper's C; a direction's factors: dC/dlog eta along it). Held rows carry none, as in
// DynamicsStepper::AssembleDamping.
// `rest_curvature` (when given) replaces the model's: the matrix is the Hessian of the energy
// with scaled stiffnesses, which is affine in the rest curvature too.
void DampingMatrix(const RodModel& model, const RodState& q, const std::vector<char>& held,
                   double bend, double twist, double stretch, BandedSymmetric* C,
                   const std::vector<Vec3>* rest_curvature = nullptr) {
  const Material& m = model.material();
  EnergyTerms terms = EnergyTerms::Elastic();
  terms.rest_curvature = rest_curvature;
  terms.bend1 = bend * m.bend_damping / m.B1();
  terms.bend2 = bend * m.bend_damping / m.B2();
  terms.twist = twist * m.twist_damping / m.twist_stiffness;
  terms.stretch = stretch * m.stretch_damping / m.stretch_stiffness;
  terms.springs = 0.0;
  VecX g;
  AssembleHessian(model, q, terms, &g, C);
  for (int k = 0; k < C->size(); ++k)
    if (held[k]) C->At(k, k) = 0.0;
}

// q moved by eps * dq over its free dofs (positions added, twist angles rotated about the
// transported tangents: the chart the sensitivities are expressed in), held values kept.
bool Moved(const RodModel& model, const std::vector<char>& held, const RodState& q, const VecX& dq,
           double eps, RodState* out) {
  const int n = model.num_edges();
  *out = q;
  for (int i = 1; i <= n; ++i)
    for (int r = 0; r < 3; ++r) {
      const int k = RodModel::VertexDof(i) + r;
      if (!held[k]) out->x(r, i) += eps * dq[k];
    }
  for (int j = 0; j < n; ++j)
    if (!held[RodModel::TwistDof(j)]) out->theta[j] += eps * dq[RodModel::TwistDof(j)];
  if (model.has_end_ghost() && !held[RodModel::TwistDof(n)])
    out->end_theta += eps * dq[RodModel::TwistDof(n)];
  out->SyncEdges();
  return UpdateReferenceFrames(model, q, out);
}

// The part of a step's twist increments that a change of the positions adds through the
// transport: d = q_n+1 - q_n counts each twist angle against its reference director transported
// in time from t_n to t_n+1, and moving t_n (or t_n+1) by dt changes that transport by the
// rotation of the small loop it makes, kb . dt / 2 about the tangent with kb = 2 t_n x t_n+1 /
// (1 + t_n . t_n+1) (the same geometry as the reference twist's variation, ZeroTwistVariation).
// `at` is the state whose tangents dq moves (q_n or q_n+1); the twist rows of *out are set, the
// others zero. Neither end ghost's tangent moves with the parameters (both are driven).
void TransportTwist(const RodModel& model, const std::vector<char>& held, const RodState& from,
                    const RodState& to, const RodState& at, const Eigen::MatrixXd& dq,
                    Eigen::MatrixXd* out) {
  const int n = model.num_edges();
  out->setZero(dq.rows(), dq.cols());
  for (int j = 0; j < n; ++j) {
    const int k = RodModel::TwistDof(j);
    if (held[k]) continue;
    const Vec3 ta = from.e.col(j).normalized(), tb = to.e.col(j).normalized();
    const Vec3 half_kb = ta.cross(tb) / (1.0 + ta.dot(tb));
    const double len = at.e.col(j).norm();
    const Vec3 t = at.e.col(j) / len;
    for (int c = 0; c < dq.cols(); ++c) {
      const Vec3 next = dq.block<3, 1>(RodModel::VertexDof(j + 1), c);
      const Vec3 prev = j == 0 ? Vec3(Vec3::Zero()) : Vec3(dq.block<3, 1>(RodModel::VertexDof(j), c));
      const Vec3 de = next - prev;
      (*out)(k, c) = half_kb.dot(de - t.dot(de) * t) / len;
    }
  }
}

// The weights' part of grad Pi (its derivative with respect to the log of the linear density).
void WeightGradient(const RodModel& model, const std::vector<char>& held, VecX* g) {
  g->setZero(model.num_free_dofs());
  for (int i = 1; i <= model.num_edges(); ++i) {
    const Vec3 w = model.vertex_weight(i);
    for (int r = 0; r < 3; ++r) {
      const int k = RodModel::VertexDof(i) + r;
      if (!held[k]) (*g)[k] = -w[r];
    }
  }
}

}  // namespace

namespace {
// A direction's rest curvature on the model's bending vertices (false: none).
bool RestCurvatureOnVertices(const RodModel& model, const ParameterDirection& d,
                             std::vector<Vec3>* delta) {
  if (d.rest_curvature_profile.empty()) return false;
  const std::vector<double>& s = model.arc_lengths();
  delta->resize(s.size());
  bool any = false;
  for (size_t i = 0; i < s.size(); ++i) {
    (*delta)[i] = RestCurvatureProfileAt(d.rest_curvature_s, d.rest_curvature_profile, s[i]);
    any = any || (*delta)[i].squaredNorm() > 0.0;
  }
  return any;
}
}  // namespace

void ParameterGradient(const RodModel& model, const RodState& q, const ParameterDirection& d,
                       VecX* g) {
  // A direction that moves no stiffness nor the rest shape (a damping, the density): zero, with
  // no assembly (which would compute the rod's frames only to add nothing).
  if (d.bend1 == 0.0 && d.bend2 == 0.0 && d.twist == 0.0 && d.stretch == 0.0 &&
      d.rest_curvature_profile.empty()) {
    g->setZero(model.num_free_dofs());
    return;
  }
  EnergyTerms terms = EnergyTerms::Only(-1);
  terms.bend1 = d.bend1;
  terms.bend2 = d.bend2;
  terms.twist = d.twist;
  terms.stretch = d.stretch;
  AssembleGradient(model, q, terms, g);
  // U = sum 1/2 B (kappa - kappa°)^2 l: d grad U / d kappa° [delta] is grad U at kappa° = delta
  // less grad U at kappa° = 0, the bend and twist stiffnesses at their values.
  std::vector<Vec3> delta;
  if (!RestCurvatureOnVertices(model, d, &delta)) return;
  const std::vector<Vec3> zero(delta.size(), Vec3::Zero());
  EnergyTerms bend = EnergyTerms::Only(-1);
  bend.bend1 = bend.bend2 = bend.twist = 1.0;
  VecX with, without;
  bend.rest_curvature = &delta;
  AssembleGradient(model, q, bend, &with);
  bend.rest_curvature = &zero;
  AssembleGradient(model, q, bend, &without);
  *g += with - without;
}

namespace {
// The parameter part of dg/dp along a direction (ParameterGradient).
void StiffnessGradient(const RodModel& model, const RodState& q, const ParameterDirection& d, VecX* g) {
  ParameterGradient(model, q, d, g);
}
}  // namespace

ParameterDirection ParameterDirection::Between(const Material& a, double density_a,
                                               const Material& b, double density_b,
                                               double log_factor) {
  ParameterDirection d;
  d.bend1 = LogRatio(a.B1(), b.B1(), log_factor);
  d.bend2 = LogRatio(a.B2(), b.B2(), log_factor);
  d.twist = LogRatio(a.twist_stiffness, b.twist_stiffness, log_factor);
  d.stretch = LogRatio(a.stretch_stiffness, b.stretch_stiffness, log_factor);
  d.drag = LogRatio(a.damping, b.damping, log_factor);
  d.bend_damping = LogRatio(a.bend_damping, b.bend_damping, log_factor);
  d.twist_damping = LogRatio(a.twist_damping, b.twist_damping, log_factor);
  d.stretch_damping = LogRatio(a.stretch_damping, b.stretch_damping, log_factor);
  d.density = LogRatio(density_a, density_b, log_factor);
  return d;
}

bool EquilibriumSensitivity(const RodModel& model, const RodState& q,
                            const std::vector<ParameterDirection>& directions, Eigen::MatrixXd* dq,
                            std::string* why) {
  if (model.nonconservative()) {
    *why = "sensitivities need a case without moment loads";
    return false;
  }
  const std::vector<char>& held = HeldDofs(model);
  BandedSymmetric H;
  BandedCholesky factor;
  VecX g;
  AssembleHessian(model, q, EnergyTerms(), &g, &H);
  ApplyHeldRows(held, nullptr, &H);
  if (!factor.Factor(H)) {
    *why = "the start's equilibrium is not stable (its Hessian is not positive definite)";
    return false;
  }
  const int N = model.num_free_dofs();
  dq->setZero(N, static_cast<int>(directions.size()));
  VecX weights;
  WeightGradient(model, held, &weights);
  for (size_t k = 0; k < directions.size(); ++k) {
    StiffnessGradient(model, q, directions[k], &g);
    g += directions[k].density * weights;
    for (int r = 0; r < N; ++r) (*dq)(r, static_cast<int>(k)) = held[r] ? 0.0 : -g[r];
  }
  factor.SolveInPlace(*dq);
  if (!dq->allFinite()) {
    *why = "non-finite sensitivities of the start";
    return false;
  }
  return true;
}

bool DynamicsStepper::StepSensitivity(const Drive& drive, const DynamicState& before,
                                      const DynamicState& after,
                                      const std::vector<ParameterDirection>& directions,
                                      DynamicSensitivity* ds, std::string* why) {
  // A halved step: through each of its substeps, in order.
  if (!substeps_.empty() && substeps_.front().first.t == before.t && substeps_end_ == after.t) {
    for (size_t k = 0; k < substeps_.size(); ++k) {
      const DynamicState& end = k + 1 < substeps_.size() ? substeps_[k + 1].first : after;
      if (!OneStepSensitivity(drive, substeps_[k].second, substeps_[k].first, end, directions, ds, why))
        return false;
    }
    return true;
  }
  return OneStepSensitivity(drive, options_.time_step, before, after, directions, ds, why);
}

namespace {

// One implicit step's sensitivity problem, shared by the stages of
// DynamicsStepper::OneStepSensitivity: what the step was (its states, weights and targets), the
// stepper's per-dof constants, and the matrices assembled once for all the directions.
struct StepSensitivityProblem {
  StepSensitivityProblem(const RodModel& m, const std::vector<char>& h, const VecX& mass_per_dof,
                         const VecX& drag_per_dof, bool internal, const DynamicState& from,
                         const DynamicState& to)
      : model(m), held(h), mass(mass_per_dof), drag(drag_per_dof), internal_damping(internal),
        before(from), after(to) {
    bend_twist.bend1 = bend_twist.bend2 = bend_twist.twist = 1.0;
  }
  int size() const { return model.num_free_dofs(); }
  // A v = (a M + c (D + C)) v: how the step's residual weighs its increment d.
  VecX ApplyA(const VecX& v) const {
    VecX out = a * mass.cwiseProduct(v) + c * drag.cwiseProduct(v);
    if (internal_damping) out += c * C.Multiply(v);
    return out;
  }

  const RodModel& model;
  const std::vector<char>& held;
  const VecX& mass;  // [kg] lumped, per free dof
  const VecX& drag;  // [N s/m] external drag coefficient, per free dof
  bool internal_damping;
  const DynamicState& before;
  const DynamicState& after;
  double a = 0.0, c = 0.0;  // the step's inertia [1/s^2] and damping [1/s] weights
  VecX y, z;                // its inertia and damping targets
  VecX d;                   // its increment q_n+1 - q_n
  VecX w;                   // the damping's displacement d - z
  EnergyTerms bend_twist = EnergyTerms::Only(-1);  // the bending and twist terms alone
  // K's bending and twist part at q_n+1 (the passes need it on its own), the lagged internal
  // damping matrix C(q_n), and the factor of the Newton matrix at the solution.
  BandedSymmetric K_bend_twist, C;
  BandedCholesky factor;
  // Scratch of the central differences, kept between the directions and passes (no allocation
  // per use).
  mutable RodState qp, qm;
  mutable VecX gp, gm;
  mutable BandedSymmetric Cp, Cm;
};

// The Newton matrix at the solution, K(q_n+1) + a M + c (D + C(q_n)), assembled and factored:
// K as its bending and twist part plus the rest (stretch, springs) — one assembly of the bending
// stencils rather than two. C(q_n) is assembled unless `has_damping` (p->C holds it already).
bool FactorStepMatrix(StepSensitivityProblem* p, bool has_damping, std::string* why) {
  const int N = p->size();
  BandedSymmetric H;
  VecX g;
  EnergyTerms others;  // everything else in the step's energy
  others.bend1 = others.bend2 = others.twist = 0.0;
  RodFrames after_frames;
  ComputeRodFrames(p->model, p->after.q, &after_frames);
  AssembleHessian(p->model, p->after.q, p->bend_twist, &g, &p->K_bend_twist, &after_frames);
  AssembleHessian(p->model, p->after.q, others, &g, &H, &after_frames);
  H.band() += p->K_bend_twist.band();
  for (int k = 0; k < N; ++k) H.At(k, k) += p->a * p->mass[k] + p->c * p->drag[k];
  if (p->internal_damping) {
    if (!has_damping) DampingMatrix(p->model, p->before.q, p->held, 1.0, 1.0, 1.0, &p->C);
    H.band() += p->c * p->C.band();
  }
  ApplyHeldRows(p->held, nullptr, &H);
  if (!p->factor.Factor(H)) {
    *why = "the step's Newton matrix is not positive definite at its solution";
    return false;
  }
  return true;
}

// *col -= c dC[dq] w, the lagged damping matrix moved with the state along dq: a central
// difference of its assembly, the state moved by ~1e-6 L (truncation ~1e-12, round-off ~1e-10,
// relative). False when a moved state folds an edge back.
bool SubtractDampingStateDerivative(const StepSensitivityProblem& p, const VecX& dq, VecX* col,
                                    std::string* why) {
  const int N = p.size();
  const double L = p.model.length();
  double scale = 0.0;
  for (int r = 0; r < N; ++r) {
    if (p.held[r]) continue;
    scale = std::max(scale, r % 4 == 3 ? std::abs(dq[r]) : std::abs(dq[r]) / L);
  }
  if (scale == 0.0) return true;
  const double eps = 1e-6 / scale;
  if (!Moved(p.model, p.held, p.before.q, dq, eps, &p.qp) ||
      !Moved(p.model, p.held, p.before.q, dq, -eps, &p.qm)) {
    *why = "the damping's derivative: a perturbed state folds an edge back";
    return false;
  }
  DampingMatrix(p.model, p.qp, p.held, 1.0, 1.0, 1.0, &p.Cp);
  DampingMatrix(p.model, p.qm, p.held, 1.0, 1.0, 1.0, &p.Cm);
  *col -= (p.c / (2.0 * eps)) * (p.Cp.Multiply(p.w) - p.Cm.Multiply(p.w));
  return true;
}

// *col -= dg/dp along `dir` (the file's header): its stiffnesses' and rest curvature's gradient,
// the drag's and viscosities' damping forces, the density's inertia and weights.
void SubtractParameterPart(const StepSensitivityProblem& p, const ParameterDirection& dir,
                           const VecX& weights, VecX* col) {
  VecX tmp;
  StiffnessGradient(p.model, p.after.q, dir, &tmp);
  *col -= tmp;
  if (dir.drag != 0.0) *col -= dir.drag * p.c * p.drag.cwiseProduct(p.w);
  BandedSymmetric Cp, Cm;
  if (p.internal_damping &&
      (dir.bend_damping != 0.0 || dir.twist_damping != 0.0 || dir.stretch_damping != 0.0)) {
    DampingMatrix(p.model, p.before.q, p.held, dir.bend_damping, dir.twist_damping,
                  dir.stretch_damping, &Cp);
    *col -= p.c * Cp.Multiply(p.w);
  }
  // The internal damping's matrix is a Hessian of the energy (DampingMatrix): affine in the
  // rest curvature, its derivative the difference of the matrices with the direction's and none.
  std::vector<Vec3> rest_delta;
  if (p.internal_damping && RestCurvatureOnVertices(p.model, dir, &rest_delta)) {
    const std::vector<Vec3> rest_zero(rest_delta.size(), Vec3::Zero());
    DampingMatrix(p.model, p.before.q, p.held, 1.0, 1.0, 1.0, &Cp, &rest_delta);
    DampingMatrix(p.model, p.before.q, p.held, 1.0, 1.0, 1.0, &Cm, &rest_zero);
    *col -= p.c * (Cp.Multiply(p.w) - Cm.Multiply(p.w));
  }
  if (dir.density != 0.0) {
    *col -= dir.density * (p.a * p.mass.cwiseProduct(p.d - p.y) + weights);
  }
}

// The bending and twist Hessians of the assembly are exact at zero twist moment but drop the
// second derivative of the reference twist (relative error ~1e-3 in a rod that twists as it
// moves): their exact product with v less the assembled one, a central difference of their
// gradient with the state moved by 1e-6 L. False when a moved state folds an edge back.
bool MissingHessianProduct(const StepSensitivityProblem& p, const VecX& v, VecX* out) {
  const int N = p.size();
  const double L = p.model.length();
  *out = -p.K_bend_twist.Multiply(v);
  double scale = 0.0;
  for (int r = 0; r < N; ++r)
    if (!p.held[r]) scale = std::max(scale, r % 4 == 3 ? std::abs(v[r]) : std::abs(v[r]) / L);
  if (scale == 0.0) return true;
  const double eps = 1e-6 / scale;
  if (!Moved(p.model, p.held, p.after.q, v, eps, &p.qp) ||
      !Moved(p.model, p.held, p.after.q, v, -eps, &p.qm))
    return false;
  AssembleGradient(p.model, p.qp, p.bend_twist, &p.gp);
  AssembleGradient(p.model, p.qm, p.bend_twist, &p.gm);
  *out += (p.gp - p.gm) / (2.0 * eps);
  for (int r = 0; r < N; ++r)
    if (p.held[r]) (*out)[r] = 0.0;
  return true;
}

// H dq_n+1 = rhs - E dq_n+1, solved by iterating from E = 0: two parts of the step's Jacobian
// are not in H, both small against it, so each pass gains a factor ~1e-3 or better:
//  - the end state's tangents move the transport too (TransportTwist): A P dq_n+1;
//  - the assembled bending and twist Hessians' missing part (MissingHessianProduct).
// *next: the solution, one column per direction.
bool SolveWithMissingTerms(const StepSensitivityProblem& p, const Eigen::MatrixXd& rhs,
                           Eigen::MatrixXd* next_out, std::string* why) {
  const int N = p.size();
  const int m = static_cast<int>(rhs.cols());
  Eigen::MatrixXd& next = *next_out;
  next = rhs;
  p.factor.SolveInPlace(next);
  std::vector<double> last_change(m, 0.0);  // per column, the previous pass's relative change
  std::vector<char> settled(m, 0);          // per column: no further pass changes it
  int open = m;
  VecX extra;
  Eigen::MatrixXd twist_from_end;
  for (int pass = 0; pass < 30 && open > 0; ++pass) {
    TransportTwist(p.model, p.held, p.before.q, p.after.q, p.after.q, next, &twist_from_end);
    Eigen::MatrixXd again = rhs;
    for (int k = 0; k < m; ++k) {
      if (settled[k]) continue;
      if (!MissingHessianProduct(p, next.col(k), &extra)) {
        *why = "the step's sensitivities: a perturbed state folds an edge back";
        return false;
      }
      again.col(k) -= p.ApplyA(twist_from_end.col(k)) + extra;
    }
    for (int r = 0; r < N; ++r)
      if (p.held[r]) again.row(r).setZero();
    p.factor.SolveInPlace(again);
    // A column has settled when the error left in it is below 1e-9 of it: by its change in this
    // pass when that is below 1e-9, or by the change times theta / (1 - theta), theta the
    // passes' contraction measured as this change over the last (the stopping rule of the
    // simplified Newton iteration, Hairer & Wanner II, IV.8): the passes contract by 1e-3 or
    // better, so a column usually settles in two passes rather than three. The central
    // differences' round-off (~1e-10 relative; ~1e-9 in a rod curved at rest, which twists as
    // it bends) bounds how far they settle: a change below 1e-7 of it that no longer shrinks
    // is that floor. A settled column is passed on as it is.
    for (int k = 0; k < m; ++k) {
      if (settled[k]) {
        again.col(k) = next.col(k);
        continue;
      }
      const double change = (again.col(k) - next.col(k)).cwiseAbs().maxCoeff() /
                            std::max(next.col(k).cwiseAbs().maxCoeff(), 1e-300);
      const double theta = pass > 0 && last_change[k] > 0.0 ? change / last_change[k] : 1.0;
      const bool estimated = theta < 0.5 && theta / (1.0 - theta) * change <= 1e-9;
      const bool floor = pass > 0 && change <= 1e-7 && change >= 0.1 * last_change[k];
      if (change <= 1e-9 || estimated || floor) settled[k] = 1, --open;
      last_change[k] = change;
    }
    next = again;
  }
  if (open > 0 || !next.allFinite()) {
    *why = "the step's sensitivities did not settle (the rod turns or twists too far in one step)";
    return false;
  }
  return true;
}

// The sensitivities after a step, from the solved dq_n+1 (`next`): the rates and BDF2's history
// follow the step's increment d (dynamics.cc: v = c (d - z)), the increment's derivative the
// change of dq plus the twist its transport gains from the start's and the end's tangents; held
// rows are zero.
void AdvanceSensitivities(const std::vector<char>& held, bool keeps_history, double c,
                          const Eigen::MatrixXd& next, const Eigen::MatrixXd& twist_from_start,
                          const Eigen::MatrixXd& twist_from_end, const Eigen::MatrixXd& dz_all,
                          DynamicSensitivity* ds) {
  Eigen::MatrixXd dd = next - ds->dq + twist_from_start + twist_from_end;
  Eigen::MatrixXd dv_new = c * (dd - dz_all);
  for (int r = 0; r < dd.rows(); ++r)
    if (held[r]) dd.row(r).setZero(), dv_new.row(r).setZero();
  if (keeps_history) {
    ds->dlast_v = ds->dv;
    ds->dlast_step = dd;
  }
  ds->dv = dv_new;
  ds->dq = next;
}

}  // namespace

// The stages: the step's weights and targets (as StepImplicit took them), its Newton matrix at
// the solution (FactorStepMatrix), per direction the right-hand side (what the state before
// carries, the lagged damping's derivative, the parameter's own part), the solve with the
// Jacobian's missing terms (SolveWithMissingTerms), and the rates and history that follow.
bool DynamicsStepper::OneStepSensitivity(const Drive& drive, double dt, const DynamicState& before,
                                         const DynamicState& after,
                                         const std::vector<ParameterDirection>& directions,
                                         DynamicSensitivity* ds, std::string* why) {
  const int N = model_.num_free_dofs();
  const int m = static_cast<int>(directions.size());
  if (!scheme_->has_sensitivities()) {
    *why = std::string("sensitivities in time are not implemented for the ") + scheme_->name() +
           " integrator (backward_euler and bdf2 have them)";
    return false;
  }
  drive.PoseAt(model_, after.t, &pose_);
  if (model_.nonconservative() || pose_.tip_moment.squaredNorm() > 0.0) {
    *why = "sensitivities in time need a case without moment loads";
    return false;
  }
  if (ds->dq.rows() != N || ds->dq.cols() != m) {
    *why = "the sensitivities do not match the model (start them with EquilibriumSensitivity)";
    return false;
  }
  if (ds->dv.rows() != N || ds->dv.cols() != m) ds->dv.setZero(N, m);
  // The weights and targets StepImplicit used (its scheme's; BDF2's first step is backward
  // Euler's). y and z are linear in the rates and the history, so their derivatives are the
  // same targets of the derivatives (DerivativeTargets below).
  const StepWeights sw = scheme_->Weights(before, dt);
  const bool bdf2 = sw.bdf2;
  if (bdf2 && (ds->dlast_step.rows() != N || ds->dlast_step.cols() != m ||
               ds->dlast_v.rows() != N || ds->dlast_v.cols() != m)) {
    *why = "the sensitivities lack the BDF2 history the state has (follow every step)";
    return false;
  }
  StepSensitivityProblem p(model_, held_, mass_, drag_, internal_damping_, before, after);
  p.a = sw.a;
  p.c = sw.c;
  StepTargets targets;
  for (VecX* v : {&targets.y, &targets.z, &targets.predictor, &targets.y_ab}) v->setZero(N);
  DynamicsOptions plain = options_;
  plain.extrapolate_corrections = false;
  scheme_->Targets(before, dt, sw, plain, &targets);
  p.y = targets.y;
  p.z = targets.z;
  // The targets of a column of derivatives (rates, last step, last rates).
  DynamicState derivative;
  derivative.has_history = before.has_history;
  derivative.last_dt = before.last_dt;
  derivative.has_older = false;
  StepTargets d_targets = targets;
  auto DerivativeTargets = [&](const VecX& dv, int k, VecX* dy, VecX* dz) {
    derivative.v = dv;
    derivative.last_step = bdf2 ? VecX(ds->dlast_step.col(k)) : VecX::Zero(N);
    derivative.last_v = bdf2 ? VecX(ds->dlast_v.col(k)) : VecX::Zero(N);
    derivative.older_v = VecX::Zero(N);
    StepWeights dw = sw;
    dw.third_order = false;
    scheme_->Targets(derivative, dt, dw, plain, &d_targets);
    *dy = d_targets.y;
    *dz = d_targets.z;
  };
  Delta(before.q, after.q, &p.d);
  p.w = p.d - p.z;
  // C(q_n): the stepper's own when it was made at this step's start (the last substep's).
  const bool has_damping = DampingAt(before.q, &p.C);
  if (!FactorStepMatrix(&p, has_damping, why)) return false;

  const double a = p.a, c = p.c;
  VecX weights;
  WeightGradient(model_, held_, &weights);
  // The increment's twist rows gained from moving the start's tangents.
  Eigen::MatrixXd twist_from_start;
  TransportTwist(model_, held_, before.q, after.q, before.q, ds->dq, &twist_from_start);
  Eigen::MatrixXd rhs(N, m);
  Eigen::MatrixXd dz_all = Eigen::MatrixXd::Zero(N, m);  // the damping targets' derivatives
  VecX dy, dz, col;
  for (int k = 0; k < m; ++k) {
    const VecX dq = ds->dq.col(k);
    const VecX dv = ds->dv.col(k);
    DerivativeTargets(dv, k, &dy, &dz);
    dz_all.col(k) = dz;
    // Inertia and damping carried from the state before.
    col = a * mass_.cwiseProduct(dq + dy) + c * drag_.cwiseProduct(dq + dz) -
          p.ApplyA(twist_from_start.col(k));
    if (internal_damping_) {
      col += c * p.C.Multiply(dq + dz);
      if (!SubtractDampingStateDerivative(p, dq, &col, why)) return false;
    }
    SubtractParameterPart(p, directions[k], weights, &col);
    for (int r = 0; r < N; ++r)
      if (held_[r]) col[r] = 0.0;
    rhs.col(k) = col;
  }
  Eigen::MatrixXd next;
  if (!SolveWithMissingTerms(p, rhs, &next, why)) return false;
  Eigen::MatrixXd twist_from_end;
  TransportTwist(model_, held_, before.q, after.q, after.q, next, &twist_from_end);
  AdvanceSensitivities(held_, scheme_->keeps_history(), c, next, twist_from_start,
                       twist_from_end, dz_all, ds);
  return true;
}

}  // namespace rodfit
