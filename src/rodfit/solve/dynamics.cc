#include "rodfit/solve/dynamics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include "rodfit/model/frames.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/deadline.h"
#include "rodfit/solve/integrator.h"
#include "rodfit/solve/linear_solvers.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/rod_problem.h"
#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

bool Integrator::operator==(const Integrator& other) const {
  return std::strcmp(name_, other.name_) == 0;
}

const char* IntegratorName(Integrator integrator) { return integrator.name(); }

bool ParseIntegrator(const std::string& name, Integrator* integrator) {
  const TimeIntegrator* scheme = FindIntegrator(name);
  if (!scheme) return false;
  *integrator = Integrator(scheme->name());  // the registry's storage: lives as long as it
  return true;
}

bool DynamicsOptions::Check(std::string* why) const {
  if (!FindIntegrator(integrator.name())) {
    *why = std::string("unknown integrator ") + integrator.name();
    return false;
  }
  if (!(time_step > 0.0) || !std::isfinite(time_step)) {
    *why = "time_step must be a positive number of seconds";
    return false;
  }
  if (!(stability_safety > 0.0 && stability_safety <= 1.0)) {
    *why = "stability_safety must be in (0, 1]";
    return false;
  }
  if (stability_check_every < 1 || max_newton_iterations < 1) {
    *why = "stability_check_every and max_newton_iterations must be at least 1";
    return false;
  }
  if (max_halvings < 0 || max_halvings > kMaxStepHalvings) {
    *why = "max_halvings must be in [0, " + std::to_string(kMaxStepHalvings) + "]";
    return false;
  }
  if (!(error_tolerance >= 0.0) || !std::isfinite(error_tolerance)) {
    *why = "error_tolerance must be a number of metres >= 0";
    return false;
  }
  if (!(min_time_step > 0.0) || !std::isfinite(min_time_step)) {
    *why = "min_time_step must be a positive number of seconds";
    return false;
  }
  if (!(time_budget >= 0.0) || !std::isfinite(time_budget)) {
    *why = "time_budget must be a number of seconds >= 0";
    return false;
  }
  if (!(residual_tolerance > 0.0) || !(step_tolerance > 0.0)) {
    *why = "tolerances must be positive";
    return false;
  }
  return true;
}

void Drive::PoseAt(const RodModel& model, double /*t*/, HeldPose* pose) const {
  pose->clamp_position = model.clamp_position();
  pose->clamp_tangent = model.clamp_tangent();
  pose->clamp_d1 = model.clamp_d1();
  pose->held.resize(model.held().size());
  for (size_t k = 0; k < model.held().size(); ++k) pose->held[k] = model.held()[k].target;
  if (model.has_end_ghost()) {  // an end clamp, or a symmetric half's crossing edge
    pose->end_tangent = model.end_tangent();
    pose->end_d1 = model.end_twist_held() ? model.end_d1() : Vec3::Zero();
  }
  pose->tip_force.setZero();
  pose->tip_moment.setZero();
  pose->point_force.setZero();
  pose->point_vertex = -1;
}

namespace {

// The pose halfway between two (implicit midpoint): positions and loads averaged, frames the
// normalised mean (the rotation halfway to second order in the step's turn).
void MidPose(const HeldPose& a, const HeldPose& b, HeldPose* m) {
  m->clamp_position = 0.5 * (a.clamp_position + b.clamp_position);
  m->clamp_tangent = (a.clamp_tangent.normalized() + b.clamp_tangent.normalized()).normalized();
  m->clamp_d1 = a.clamp_d1.normalized() + b.clamp_d1.normalized();
  m->held.resize(a.held.size());
  for (size_t k = 0; k < a.held.size(); ++k) m->held[k] = 0.5 * (a.held[k] + b.held[k]);
  m->end_tangent = (a.end_tangent.normalized() + b.end_tangent.normalized()).normalized();
  m->end_d1 = a.end_d1 + b.end_d1;
  m->tip_force = 0.5 * (a.tip_force + b.tip_force);
  m->point_force = 0.5 * (a.point_force + b.point_force);
  m->point_vertex = b.point_vertex;
  m->point_weight = b.point_weight;
  m->tip_moment = 0.5 * (a.tip_moment + b.tip_moment);
}

// d1 made perpendicular to the unit tangent t and unit.
Vec3 Perpendicular(const Vec3& d1, const Vec3& t) {
  return (d1 - d1.dot(t) * t).normalized();
}

}  // namespace

struct DynamicsStepper::Scratch {
  RodFrames frames;  // the explicit steps' and the damping's
  BandedSymmetric hessian, damping;
  RodState damping_state;  // the state `damping` was assembled at (the sensitivities reuse it)
  bool has_damping_state = false;
  BandedCholesky factor;
  std::vector<int> held_rows;  // the held dofs (held_), listed: the Newton loop zeroes their rows
  StepTargets targets;
  std::unique_ptr<StepProblem> problem;  // defined below
  std::unique_ptr<BandedCholeskySolver> solver;
  NewtonMinimizer minimizer;
};

namespace {

// The pose's point force on the rows of its two vertices, subtracted from a gradient (vertex
// 0 is the clamp's: no rows; held rows are zeroed by the caller).
void AddPointForce(const HeldPose& pose, VecX* g) {
  if (pose.point_vertex < 0 || pose.point_force.squaredNorm() == 0.0) return;
  for (int k = 0; k < 2; ++k) {
    const int i = pose.point_vertex + k;
    const double w = k == 0 ? 1.0 - pose.point_weight : pose.point_weight;
    if (i >= 1) g->segment<3>(RodModel::VertexDof(i)) -= w * pose.point_force;
  }
}

// The loads beyond Pi, subtracted from a gradient at `state` (frames fresh for it): the
// non-conservative moments and the pose's tip and point loads.
void AddStepLoads(const RodModel& model, const RodState& state, const RodFrames& frames,
                  const HeldPose& pose, VecX* g) {
  const int n = model.num_edges();
  if (model.nonconservative()) AddMomentLoads(model, state, frames, 1.0, g, nullptr);
  if (pose.tip_force.squaredNorm() > 0.0) g->segment<3>(RodModel::VertexDof(n)) -= pose.tip_force;
  AddPointForce(pose, g);
  if (pose.tip_moment.squaredNorm() > 0.0) {
    EdgeMoment em;
    em.edge = n - 1;
    em.moment = pose.tip_moment;
    const EdgeMomentForce f = EdgeMomentLoad(em, frames, 1.0);
    g->segment<3>(RodModel::VertexDof(n)) -= f.Qe;
    if (n >= 2) g->segment<3>(RodModel::VertexDof(n - 1)) += f.Qe;
    (*g)[RodModel::TwistDof(n - 1)] -= f.Qt;
  }
}

// The point force's potential -f . x(s) at a state.
double PointForcePotential(const HeldPose& pose, const RodState& q) {
  if (pose.point_vertex < 0 || pose.point_force.squaredNorm() == 0.0) return 0.0;
  const double w = pose.point_weight;
  return -pose.point_force.dot((1.0 - w) * q.x.col(pose.point_vertex) +
                               w * q.x.col(pose.point_vertex + 1));
}

}  // namespace

// One implicit step as a Newton problem (newton_minimizer.h): its incremental potential
//   Phi(q) = a/2 |d - y|^2_M + c/2 |d - z|^2_C + Pi(q) - f . q,   d = Delta(q_n, q),
// with the weights and targets of the stepper's scheme (integrator.h), the pose's loads and the
// damping matrix C at q_n. Its residual is grad Phi (held rows zero), its matrix
// K + a M + c (drag + C).
class DynamicsStepper::StepProblem : public RodNewtonProblem {
 public:
  explicit StepProblem(DynamicsStepper* stepper)
      : RodNewtonProblem(stepper->model_, stepper->options_.step_tolerance,
                         stepper->model_.length()),
        s_(*stepper) {}
  void Begin(const RodState* q0, const HeldPose* pose, const StepWeights& w,
             const StepTargets* targets) {
    q0_ = q0;
    pose_ = pose;
    a_ = w.a;
    c_ = w.c;
    t_ = targets;
    first_ = true;
    delta_of_ = kCurrent;  // the stepper sets delta to the predictor's
  }
  void SetSolver(LinearSolver* solver) { solver_ = solver; }
  VecX& delta() { return s_.delta_; }
  /// delta = Delta(q_n, current), computed when not known.
  void DeltaOfCurrent() {
    if (delta_of_ != kCurrent) s_.Delta(*q0_, current(), &s_.delta_);
    delta_of_ = kCurrent;
  }

  void Evaluate(bool matrix, VecX* g) override {
    const RodFrames& f = CurrentFrames();
    BandedSymmetric& H = s_.scratch_->hessian;
    if (matrix) {
      AssembleHessian(model_, current(), EnergyTerms(), g, &H, &f);
    } else {
      AssembleGradient(model_, current(), EnergyTerms(), g, &f);
    }
    AddLoads(current(), f, g);
    if (first_) {
      // Relative to the forces the step balances: the case's loads or the elastic forces at the
      // predictor, whichever is larger. At the stretch forces' round-off floor (~eps EA per edge)
      // a residual still hides errors in the soft bending modes (EA L^2 / B ~ 1e7 for a
      // suture), so there convergence is told by the Newton step.
      double elastic = 0.0;
      for (int k = 0; k < g->size(); ++k) elastic = std::max(elastic, weights_[k] * std::abs((*g)[k]));
      force_tol_ = s_.options_.residual_tolerance * std::max(model_.force_scale(), elastic);
      floor_tol_ = ResidualFloor(model_, weights_);
      first_ = false;
    }
    DeltaOfCurrent();
    AddStepForces(g);
    if (!matrix) return;
    const int N = static_cast<int>(g->size());
    for (int k = 0; k < N; ++k) H.At(k, k) += a_ * s_.mass_[k] + c_ * s_.drag_[k];
    if (s_.internal_damping_) H.band() += c_ * s_.scratch_->damping.band();
    // The held rows and columns: the identity (ApplyHeldRows, by the list).
    const int p = H.bandwidth();
    for (int r : s_.scratch_->held_rows)
      for (int col = std::max(0, r - p); col <= std::min(N - 1, r + p); ++col)
        H.At(std::max(r, col), std::min(r, col)) = (r == col) ? 1.0 : 0.0;
  }
  double Energy() override {
    const double e = Phi(current(), CurrentFrames());
    delta_of_ = kCurrent;
    return e;
  }
  double TrialEnergy() override {
    const double e = Phi(trial(), TrialFrames());
    delta_of_ = kTrial;
    return e;
  }
  void TrialResidual(VecX* g) override {
    AssembleGradient(model_, trial(), EnergyTerms(), g, &TrialFrames());
    AddLoads(trial(), TrialFrames(), g);
    if (delta_of_ != kTrial) s_.Delta(*q0_, trial(), &s_.delta_);
    delta_of_ = kTrial;
    AddStepForces(g);
  }
  void AcceptTrial() override {
    RodNewtonProblem::AcceptTrial();
    delta_of_ = delta_of_ == kTrial ? kCurrent : kNone;
  }
  void RestorePrevious() override {
    RodNewtonProblem::RestorePrevious();
    delta_of_ = kNone;
  }
  NewtonTolerances Tolerances() override { return {force_tol_, floor_tol_}; }
  LinearSolver& Solver() override { return *solver_; }

 private:
  enum DeltaOf { kNone, kCurrent, kTrial };
  // The step's loads beyond Pi (AddStepLoads).
  void AddLoads(const RodState& state, const RodFrames& frames, VecX* g) const {
    AddStepLoads(model_, state, frames, *pose_, g);
  }
  // grad Phi = grad Pi - f + a M (d - y) + c C (d - z), delta holding d; held rows zeroed. Into
  // kept scratch: a step allocates nothing once the stepper has taken one.
  void AddStepForces(VecX* g) const {
    const int N = static_cast<int>(g->size());
    const VecX& d = s_.delta_;
    const VecX& y = t_->y;
    const VecX& z = t_->z;
    if (s_.internal_damping_) {
      s_.delta0_ = d - z;
      s_.scratch_->damping.MultiplyInto(s_.delta0_, &s_.cd_);
      for (int k = 0; k < N; ++k) (*g)[k] += c_ * s_.cd_[k];
    }
    for (int k = 0; k < N; ++k)
      (*g)[k] += a_ * s_.mass_[k] * (d[k] - y[k]) + c_ * s_.drag_[k] * (d[k] - z[k]);
    for (int r : s_.scratch_->held_rows) (*g)[r] = 0.0;
  }
  // Phi at a state with fresh frames; leaves delta = Delta(q_n, state).
  double Phi(const RodState& state, const RodFrames& frames) const {
    const int n = model_.num_edges();
    const int N = static_cast<int>(s_.delta_.size());
    s_.Delta(*q0_, state, &s_.delta_);
    double e = PotentialEnergyFreshFrames(model_, state, EnergyTerms(), &frames);
    e -= pose_->tip_force.dot(state.x.col(n));
    e += PointForcePotential(*pose_, state);
    const VecX& d = s_.delta_;
    s_.delta0_ = d - t_->z;
    double inertia = 0.0, damp = 0.0;
    for (int k = 0; k < N; ++k) {
      if (s_.held_[k]) continue;
      const double r = d[k] - t_->y[k];
      inertia += s_.mass_[k] * r * r;
      damp += s_.drag_[k] * s_.delta0_[k] * s_.delta0_[k];
    }
    if (s_.internal_damping_) {
      s_.scratch_->damping.MultiplyInto(s_.delta0_, &s_.cd_);
      damp += s_.delta0_.dot(s_.cd_);
    }
    return e + 0.5 * a_ * inertia + 0.5 * c_ * damp;
  }

  DynamicsStepper& s_;
  const RodState* q0_ = nullptr;
  const HeldPose* pose_ = nullptr;
  const StepTargets* t_ = nullptr;
  double a_ = 0.0, c_ = 0.0;
  double force_tol_ = 0.0, floor_tol_ = 0.0;
  bool first_ = true;
  DeltaOf delta_of_ = kNone;
  LinearSolver* solver_ = nullptr;
};

DynamicsStepper::DynamicsStepper(const RodModel& model, const DynamicsOptions& options)
    : model_(model), options_(options), scratch_(std::make_unique<Scratch>()) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  scheme_ = FindIntegrator(options_.integrator.name());
  const RodSpec& rod = model.rod();
  if (!(rod.linear_density > 0.0))
    throw std::invalid_argument("dynamics needs rod.linear_density > 0 (the rod has no mass)");
  const Material& m = model.material();
  for (double c : {m.damping, m.bend_damping, m.twist_damping, m.stretch_damping}) {
    if (!(c >= 0.0) || !std::isfinite(c))
      throw std::invalid_argument("damping parameters must be finite and >= 0");
  }
  const int n = model.num_edges();
  const int dofs = model.num_free_dofs();
  // Rotational inertia per length of a solid round section about its axis: rho A r^2 / 2.
  const double spin_inertia = 0.5 * rod.linear_density * rod.radius * rod.radius;
  if (!scheme_->implicit() && !(spin_inertia > 0.0)) {
    throw std::invalid_argument(
        "the explicit integrator needs rod.radius > 0 (the twist angles' inertia); use an "
        "implicit integrator, which treats a rod without it as spinning quasi-statically");
  }
  mass_.setOnes(dofs);
  drag_.setZero(dofs);
  for (int i = 1; i <= n; ++i) {
    const double cell = model.vertex_mass(i) / rod.linear_density;  // [m]
    mass_.segment<3>(RodModel::VertexDof(i)).setConstant(model.vertex_mass(i));
    drag_.segment<3>(RodModel::VertexDof(i)).setConstant(m.damping * cell);
  }
  for (int j = 0; j < n; ++j) mass_[RodModel::TwistDof(j)] = spin_inertia * model.rest_edge_length(j);
  if (model.has_end_ghost()) {
    // The end clamp's ghost edge: its twist is the end's turn about its tangent, with half the
    // last edge's spin inertia (the ghost carries no material of its own).
    mass_[RodModel::TwistDof(n)] = 0.5 * spin_inertia * model.end_ghost_length();
  }
  internal_damping_ = m.bend_damping > 0.0 || m.twist_damping > 0.0 || m.stretch_damping > 0.0;
  held_ = HeldDofs(model);
  for (int k = 0; k < static_cast<int>(held_.size()); ++k)
    if (held_[k]) scratch_->held_rows.push_back(k);
  weights_ = GradientNormWeights(model);
  Drive().PoseAt(model, 0.0, &pose_);
  pose_mid_ = pose_;
  scratch_->damping.Resize(dofs, kRodBandwidth, 4);
  scratch_->damping.SetZero();
  // Every scratch vector, state and frame list at its size now: a step then allocates nothing,
  // whichever of its paths (line search, shifted factor, failure) it takes; the runtime's
  // haptic ticks rely on it.
  for (VecX* v : {&g_, &step_, &delta_, &delta0_, &force_, &cv_, &cd_})
    v->setZero(dofs);
  StepTargets& t = scratch_->targets;
  for (VecX* v : {&t.y, &t.z, &t.predictor, &t.y_ab}) v->setZero(dofs);
  trial_ = model.StraightState();
  ComputeRodFrames(model, trial_, &scratch_->frames);
  scratch_->hessian.Resize(dofs, kRodBandwidth, 4);
  scratch_->problem = std::make_unique<StepProblem>(this);
  scratch_->problem->Presize();
  scratch_->solver =
      std::make_unique<BandedCholeskySolver>(&scratch_->hessian, &scratch_->factor);
  scratch_->problem->SetSolver(scratch_->solver.get());
  scratch_->minimizer.Reserve(dofs);
}

DynamicsStepper::~DynamicsStepper() = default;

DynamicState DynamicsStepper::AtRest(const RodState& q) const {
  DynamicState s;
  s.q = q;
  s.v.setZero(model_.num_free_dofs());
  s.t = 0.0;
  return s;
}

double DynamicsStepper::KineticEnergy(const DynamicState& s) const {
  double k = 0.0;
  for (int i = 0; i < s.v.size(); ++i)
    if (!held_[i]) k += 0.5 * mass_[i] * s.v[i] * s.v[i];
  return k;
}

double DynamicsStepper::PotentialEnergy(const RodState& q) const {
  return rodfit::PotentialEnergy(model_, q);
}

void DynamicsStepper::Delta(const RodState& a, const RodState& b, VecX* d) const {
  const int n = model_.num_edges();
  d->setZero(model_.num_free_dofs());
  for (int i = 1; i <= n; ++i) d->segment<3>(RodModel::VertexDof(i)) = b.x.col(i) - a.x.col(i);
  // Each twist increment is the material frame's turn about the tangent against its transport
  // straight from a's tangent to b's. b's reference directors came from a's through the
  // predictor and every Newton iterate, and a chain of transports differs from the direct one by
  // the loop's holonomy: without this term the step's result would depend on the Newton path,
  // and its sensitivities (StepSensitivity) would not be those of a function of q_n.
  for (int j = 0; j < n; ++j) {
    const Vec3 ta = a.ref_t.col(j), tb = b.ref_t.col(j);
    const Vec3 u = ParallelTransport<double, double>(ta, tb, Vec3(a.ref_u.col(j)));
    (*d)[RodModel::TwistDof(j)] =
        b.theta[j] - a.theta[j] + SignedAngle<double>(u, Vec3(b.ref_u.col(j)), tb);
  }
  if (model_.has_end_ghost()) (*d)[RodModel::TwistDof(n)] = b.end_theta - a.end_theta;
  for (int r : scratch_->held_rows) (*d)[r] = 0.0;
}

bool DynamicsStepper::Advance(const RodState& q, const VecX& dx, const HeldPose& pose,
                              RodState* out) const {
  const int n = model_.num_edges();
  *out = q;
  out->x.col(0) = pose.clamp_position;
  out->clamp_t = pose.clamp_tangent.normalized();
  out->clamp_d1 = Perpendicular(pose.clamp_d1, out->clamp_t);
  for (int i = 1; i <= n; ++i) {
    const int h = model_.held_at_vertex(i);
    out->x.col(i) = h >= 0 ? pose.held[h] : Vec3(q.x.col(i) + dx.segment<3>(RodModel::VertexDof(i)));
  }
  for (int j = 0; j < n; ++j) out->theta[j] = q.theta[j] + dx[RodModel::TwistDof(j)];
  out->SyncEdges();
  if (model_.has_end_ghost()) {
    // The ghost's reference director is transported in time to the new end tangent; its twist
    // angle follows the rate (a free end) or keeps the held d1.
    const Vec3 t_new = pose.end_tangent.normalized();
    Vec3 u = ParallelTransport<double, double>(q.end_t, t_new, q.end_u);
    u = (u - u.dot(t_new) * t_new).normalized();
    out->end_t = t_new;
    out->end_u = u;
    out->end_theta = model_.end_twist_held()
                         ? SignedAngle<double>(u, Perpendicular(pose.end_d1, t_new), t_new)
                         : q.end_theta + dx[RodModel::TwistDof(n)];
  }
  return UpdateReferenceFrames(model_, q, out);
}


void DynamicsStepper::Forces(const RodState& q, const HeldPose& pose, VecX* g) {
  LoadedGradient(q, pose, &scratch_->frames, g);
}

void DynamicsStepper::LoadedGradient(const RodState& q, const HeldPose& pose, RodFrames* frames,
                                     VecX* g) const {
  ComputeRodFrames(model_, q, frames);
  AssembleGradient(model_, q, EnergyTerms(), g, frames);
  AddStepLoads(model_, q, *frames, pose, g);
  for (int k = 0; k < g->size(); ++k)
    if (held_[k]) (*g)[k] = 0.0;
}

void DynamicsStepper::AssembleDamping(const RodState& q) {
  if (!internal_damping_) return;
  const Material& m = model_.material();
  EnergyTerms terms = EnergyTerms::Elastic();
  // U is linear in each stiffness: the Hessian with factors eta / k is sum eta K_unit.
  terms.bend1 = m.bend_damping / m.B1();
  terms.bend2 = m.bend_damping / m.B2();
  terms.twist = m.twist_damping / m.twist_stiffness;
  terms.stretch = m.stretch_damping / m.stretch_stiffness;
  terms.springs = 0.0;
  ComputeRodFrames(model_, q, &scratch_->frames);
  AssembleHessian(model_, q, terms, &cv_, &scratch_->damping, &scratch_->frames);
  // Held rows carry no damping (their dofs do not move freely).
  for (int k = 0; k < scratch_->damping.size(); ++k)
    if (held_[k]) scratch_->damping.At(k, k) = 0.0;
  scratch_->damping_state = q;
  scratch_->has_damping_state = true;
}

bool DynamicsStepper::DampingAt(const RodState& q, BandedSymmetric* C) const {
  if (!internal_damping_ || !scratch_->has_damping_state) return false;
  const RodState& a = scratch_->damping_state;
  // Every field the assembly reads, compared exactly (a copy of the state is equal).
  const bool same = a.x == q.x && a.e == q.e && a.theta == q.theta && a.ref_u == q.ref_u &&
                    a.ref_t == q.ref_t && a.ref_twist == q.ref_twist && a.clamp_t == q.clamp_t &&
                    a.clamp_d1 == q.clamp_d1 && a.end_t == q.end_t && a.end_u == q.end_u &&
                    a.end_theta == q.end_theta && a.plane_point == q.plane_point;
  if (!same) return false;
  *C = scratch_->damping;
  return true;
}

double DynamicsStepper::StableTimeStep(const RodState& q) {
  ComputeRodFrames(model_, q, &scratch_->frames);
  AssembleHessian(model_, q, EnergyTerms(), &g_, &scratch_->hessian, &scratch_->frames);
  AssembleDamping(q);
  const int N = model_.num_free_dofs();
  const int p = scratch_->hessian.bandwidth();
  // Gershgorin bounds of the mass-scaled stiffness and damping: every eigenvalue of
  // M^-1/2 K M^-1/2 lies below the largest absolute row sum.
  double lambda_k = 0.0, lambda_c = 0.0;
  for (int r = 0; r < N; ++r) {
    if (held_[r]) continue;
    double sk = 0.0, sc = drag_[r] / mass_[r];
    for (int c = std::max(0, r - p); c <= std::min(N - 1, r + p); ++c) {
      if (held_[c]) continue;
      const double scale = 1.0 / std::sqrt(mass_[r] * mass_[c]);
      sk += std::abs(scratch_->hessian.Get(r, c)) * scale;
      if (internal_damping_) sc += std::abs(scratch_->damping.Get(r, c)) * scale;
    }
    lambda_k = std::max(lambda_k, sk);
    lambda_c = std::max(lambda_c, sc);
  }
  if (!(lambda_k > 0.0) || !std::isfinite(lambda_k)) return 0.0;
  // Leapfrog with damping lagged by half a step is stable for a mode (omega, c) when
  // omega^2 dt^2 + 2 c dt < 4; with the bounds for both: the positive root in dt.
  const double dt = (-lambda_c + std::sqrt(lambda_c * lambda_c + 4.0 * lambda_k)) / lambda_k;
  return options_.stability_safety * dt;
}

DynamicsStepSummary DynamicsStepper::Step(const Drive& drive, DynamicState* s) {
  if (s->v.size() != model_.num_free_dofs()) s->v.setZero(model_.num_free_dofs());
  if (scheme_->implicit()) {
    substeps_.clear();  // keeps its capacity: no allocation in a step that is not halved
    if (options_.time_budget > 0.0)
      deadline_ = DeadlineAfter(options_.time_budget);
    if (options_.error_tolerance > 0.0) return StepAdaptive(drive, s);
    DynamicsStepSummary summary = StepImplicit(drive, options_.time_step, s);
    if (summary.ok || summary.out_of_time || options_.max_halvings == 0) return summary;
    // Newton did not converge: the same interval in halves, each halved again as it needs.
    const DynamicState start = *s;
    const double t_end = s->t + options_.time_step;
    DynamicsStepSummary halved;
    halved.newton_iterations = summary.newton_iterations;
    halved.substeps = 0;
    if (!StepHalving(drive, 0.5 * options_.time_step, 1, s, &halved) ||
        !StepHalving(drive, 0.5 * options_.time_step, 1, s, &halved)) {
      *s = start;
      substeps_.clear();
      force_valid_ = false;
      halved.ok = false;
      if (!halved.out_of_time)
        halved.reason += " (in a step halved " + std::to_string(options_.max_halvings) + " times)";
      return halved;
    }
    s->t = t_end;
    substeps_end_ = t_end;
    halved.ok = true;
    return halved;
  }
  // Explicit: the stable step at the current shape, re-evaluated every few steps.
  const double dt = options_.time_step;
  if (stable_dt_ == 0.0 || steps_since_check_ >= options_.stability_check_every) {
    stable_dt_ = StableTimeStep(s->q);
    steps_since_check_ = 0;
  }
  ++steps_since_check_;
  DynamicsStepSummary summary;
  int substeps = 1;
  if (dt > stable_dt_) {
    if (!options_.substep || !(stable_dt_ > 0.0)) {
      char text[320];
      std::snprintf(text, sizeof(text),
                    "time_step %.4g s is above the explicit integrator's stable step %.4g s at "
                    "t = %.6g s (use a smaller time_step, substep: true, or an implicit "
                    "integrator)",
                    dt, stable_dt_, s->t);
      summary.reason = text;
      return summary;
    }
    substeps = static_cast<int>(std::ceil(dt / stable_dt_));
    if (substeps > 10000000) {
      summary.reason = "the explicit integrator would need more than 1e7 substeps per step";
      return summary;
    }
  }
  const DynamicState before = *s;
  const double h = dt / substeps;
  const double t0 = s->t;
  for (int k = 0; k < substeps; ++k) {
    DynamicsStepSummary one = StepExplicit(drive, h, s);
    if (!one.ok) {
      *s = before;
      force_valid_ = false;
      return one;
    }
    s->t = t0 + (k + 1) * h;
  }
  s->t = t0 + dt;
  summary.ok = true;
  summary.substeps = substeps;
  return summary;
}

DynamicsStepSummary DynamicsStepper::StepExplicit(const Drive& drive, double dt, DynamicState* s) {
  DynamicsStepSummary summary;
  const int N = model_.num_free_dofs();
  // Velocity Verlet (kick, drift, kick), with the damping force of the velocity half a step
  // before: one force evaluation per step (the end's force is the next step's start).
  if (!force_valid_ || force_time_ != s->t) {
    drive.PoseAt(model_, s->t, &pose_);
    Forces(s->q, pose_, &force_);
    force_valid_ = true;
  }
  AssembleDamping(s->q);
  auto damping_force = [&](const VecX& v, VecX* out) {
    *out = drag_.cwiseProduct(v);
    if (internal_damping_) *out += scratch_->damping.Multiply(v);
  };
  damping_force(s->v, &cv_);
  step_.resize(N);
  for (int k = 0; k < N; ++k)
    step_[k] = held_[k] ? 0.0 : s->v[k] - 0.5 * dt * (force_[k] + cv_[k]) / mass_[k];
  drive.PoseAt(model_, s->t + dt, &pose_);
  delta_ = dt * step_;
  if (!Advance(s->q, delta_, pose_, &trial_)) {
    summary.reason = "an edge collapsed or folded back (the explicit step blew up)";
    return summary;
  }
  Forces(trial_, pose_, &force_);
  if (!force_.allFinite()) {
    summary.reason = "non-finite forces (the explicit step blew up)";
    force_valid_ = false;
    return summary;
  }
  damping_force(step_, &cv_);
  for (int k = 0; k < N; ++k)
    s->v[k] = held_[k] ? 0.0 : step_[k] - 0.5 * dt * (force_[k] + cv_[k]) / mass_[k];
  std::swap(s->q, trial_);
  force_time_ = s->t + dt;
  summary.ok = true;
  return summary;
}

namespace {
// Adaptive stepping's controller (StepAdaptive): the next substep is the last times
// kStepSafety (error / tolerance)^(-1/3) (BDF2's local error grows as dt^3), within
// [kMinStepChange, kMaxStepRatio] of it; a failed substep is retried at kFailedStepShrink of it.
constexpr double kStepSafety = 0.9;
constexpr double kMinStepChange = 0.2;
constexpr double kFailedStepShrink = 0.25;
}  // namespace

double DynamicsStepper::LocalError(const DynamicState& before, const DynamicState& after,
                                   double dt) {
  // Milne's device: the converged positions against an explicit prediction of the same order,
  //   x_p = x_n + dt v_n + dt^2 / 2 a_n,  a_n = (v_n - v_n-1) / dt_n-1,
  // whose error is C_p dt^3 x(3) with C_p = 1/6 + 1/(4w) (w = dt / dt_n-1; the rates' backward
  // difference is first order), against BDF2's C dt^3 x(3) with C = (1 + w)^2 / (6 w (1 + 2w))
  // (2/9 at w = 1; Hairer, Norsett & Wanner I, III.5): the error is C / (C + C_p) of their
  // distance. Without history (a first step, backward Euler) both are first order with
  // constants 1/2: half the distance to x_n + dt v_n.
  // The rod is stiff (its stretch and twist modes are far faster than its motion), and there the
  // explicit prediction is no estimate: BDF2 damps those modes, the prediction extrapolates them,
  // and their difference would shrink the step until it resolves them. The difference is
  // filtered as Hairer & Wanner II, IV.8 filter RADAU5's, e <- (a M + K)^-1 a M e with the
  // step's Newton matrix: the identity on the modes the step resolves (omega^2 << a), a / omega^2
  // on those it does not.
  const int n = model_.num_edges();
  const int N = model_.num_free_dofs();
  const bool history = before.has_history && before.last_v.size() == N && before.last_dt > 0.0;
  double factor = 0.5;
  double reach = 0.0;  // dt^2 / 2 / dt_n-1
  if (history) {
    const double w = dt / before.last_dt;
    const double C = (1.0 + w) * (1.0 + w) / (6.0 * w * (1.0 + 2.0 * w));
    const double Cp = 1.0 / 6.0 + 1.0 / (4.0 * w);
    factor = C / (C + Cp);
    reach = 0.5 * dt * dt / before.last_dt;
  }
  VecX& e = step_;  // scratch
  e.setZero(N);
  for (int i = 1; i <= n; ++i) {
    if (model_.held_at_vertex(i) >= 0) continue;
    const int k = RodModel::VertexDof(i);
    Vec3 predicted = before.q.x.col(i) + dt * before.v.segment<3>(k);
    if (history) predicted += reach * (before.v.segment<3>(k) - before.last_v.segment<3>(k));
    e.segment<3>(k) = after.q.x.col(i) - predicted;
  }
  const double a = scheme_->Weights(before, dt).a;
  for (int k = 0; k < N; ++k) e[k] *= a * mass_[k];
  for (int r : scratch_->held_rows) e[r] = 0.0;
  if (scratch_->factor.valid() && scratch_->factor.size() == N) {
    scratch_->factor.SolveInPlace(e);
  } else {
    for (int k = 0; k < N; ++k) e[k] /= a * mass_[k];
  }
  double worst = 0.0;
  for (int i = 1; i <= n; ++i)
    if (model_.held_at_vertex(i) < 0) worst = std::max(worst, e.segment<3>(RodModel::VertexDof(i)).norm());
  return factor * worst;
}

// One function, though long: the controller's loop (choose the substep, take it, judge it,
// retry or accept) shares the step length, the schedule and the summary between its stages.
DynamicsStepSummary DynamicsStepper::StepAdaptive(const Drive& drive, DynamicState* s) {
  const double dt = options_.time_step;
  const double t_end = s->t + dt;
  const DynamicState start = *s;
  substeps_.clear();
  DynamicsStepSummary summary;
  summary.substeps = 0;
  double h = adaptive_step_ > 0.0 ? std::min(adaptive_step_, dt) : dt;
  std::string last_failure;
  DynamicState before;
  const bool replay = schedule_ && schedule_->mode == StepSchedule::Mode::kReplay;
  while (t_end - s->t > 1e-12 * dt) {
    const double left = t_end - s->t;
    double step;
    bool replayed = false;
    if (replay && !schedule_->departed && schedule_->next < schedule_->steps.size()) {
      step = std::min(schedule_->steps[schedule_->next], left);
      replayed = true;
    } else {
      // Equal substeps through what is left of the interval: its end is an output time.
      const double count = std::ceil(left / h - 1e-9);
      step = left / std::max(count, 1.0);
    }
    if (step < options_.min_time_step) {
      const double t_failed = s->t;
      *s = start;
      substeps_.clear();
      force_valid_ = false;
      if (options_.failure_reasons)
        summary.reason = "the adaptive step fell below min_time_step (" +
                         std::to_string(options_.min_time_step) + " s) at t = " +
                         std::to_string(t_failed) + " s: " + last_failure;
      return summary;
    }
    before = *s;
    const DynamicsStepSummary one = StepImplicit(drive, step, s);
    summary.newton_iterations += one.newton_iterations;
    summary.residual = one.residual;
    summary.termination = one.termination;
    if (one.out_of_time) {
      *s = start;
      substeps_.clear();
      summary.out_of_time = true;
      summary.reason = one.reason;
      return summary;
    }
    double error = 0.0;
    if (one.ok) error = LocalError(before, *s, step) / options_.error_tolerance;
    // A replayed substep is taken as it was (a fit's objective stays smooth in the parameters),
    // unless it fails outright.
    const bool accept = one.ok && (replayed || error <= 1.0);
    if (!accept) {
      *s = before;
      ++summary.rejected;
      if (replayed) schedule_->departed = true;
      last_failure = one.ok ? "local error above error_tolerance" : one.reason;
      h = one.ok ? step * std::max(kMinStepChange, kStepSafety * std::cbrt(1.0 / error))
                 : step * kFailedStepShrink;
      continue;
    }
    substeps_.emplace_back(before, step);
    ++summary.substeps;
    if (replayed) {
      ++schedule_->next;
    } else if (schedule_ && schedule_->mode == StepSchedule::Mode::kRecord) {
      schedule_->steps.push_back(step);
    }
    const double change = error > 0.0 ? kStepSafety * std::cbrt(1.0 / error) : kMaxStepRatio;
    h = step * std::clamp(change, kMinStepChange, kMaxStepRatio);
  }
  s->t = t_end;
  substeps_end_ = t_end;
  adaptive_step_ = h;
  force_valid_ = false;
  summary.ok = true;
  return summary;
}

// One function, though long: the Newton loop of one implicit step, its mass, damping and
// elastic terms assembled into one band, shares that band, the predictor and the line search
// state between its stages.
bool DynamicsStepper::StepHalving(const Drive& drive, double dt, int depth, DynamicState* s,
                                  DynamicsStepSummary* summary) {
  const DynamicState before = *s;
  const DynamicsStepSummary one = StepImplicit(drive, dt, s);
  summary->newton_iterations += one.newton_iterations;
  summary->residual = one.residual;
  if (one.ok) {
    substeps_.emplace_back(before, dt);
    ++summary->substeps;
    return true;
  }
  if (depth >= options_.max_halvings || one.out_of_time) {
    summary->termination = one.termination;
    summary->reason = one.reason;
    summary->out_of_time = one.out_of_time;
    return false;
  }
  return StepHalving(drive, 0.5 * dt, depth + 1, s, summary) &&
         StepHalving(drive, 0.5 * dt, depth + 1, s, summary);
}

DynamicsStepSummary DynamicsStepper::StepImplicit(const Drive& drive, double dt, DynamicState* s) {
  DynamicsStepSummary summary;
  const int n = model_.num_edges();
  const int N = model_.num_free_dofs();
  StepTargets& t = scratch_->targets;
  const StepWeights w = scheme_->Weights(*s, dt);
  scheme_->Targets(*s, dt, w, options_, &t);
  drive.PoseAt(model_, s->t + dt, &pose_);
  const HeldPose* pose = &pose_;
  if (w.midpoint) {
    drive.PoseAt(model_, s->t, &pose_mid_);
    HeldPose start = pose_mid_;
    MidPose(start, pose_, &pose_mid_);
    pose = &pose_mid_;
  }
  AssembleDamping(s->q);
  const RodState& q0 = s->q;
  StepProblem& problem = *scratch_->problem;
  if (!Advance(q0, t.predictor, *pose, &problem.current())) {  // the predictor
    summary.termination = Termination::kRetractionFailed;
    if (options_.failure_reasons)
      summary.reason = "the predictor folds an edge back: time_step too large for this motion";
    return summary;
  }
  problem.CurrentChanged();
  // Delta(q0, q) of the predictor without Delta's transports: Advance transported q's reference
  // directors straight from q0's, so the holonomy term of its twist increments is zero (to
  // round-off). It saves one of the three Deltas of a tick, 1 % of its instructions.
  {
    const RodState& q = problem.current();
    delta_.setZero(N);
    for (int i = 1; i <= n; ++i) delta_.segment<3>(RodModel::VertexDof(i)) = q.x.col(i) - q0.x.col(i);
    for (int j = 0; j < n; ++j) delta_[RodModel::TwistDof(j)] = q.theta[j] - q0.theta[j];
    if (model_.has_end_ghost()) delta_[RodModel::TwistDof(n)] = q.end_theta - q0.end_theta;
    for (int r : scratch_->held_rows) delta_[r] = 0.0;
  }
  problem.Begin(&q0, pose, w, &t);
  const bool has_moments = model_.nonconservative() || pose->tip_moment.squaredNorm() > 0.0;
  NewtonOptions& o = scratch_->minimizer.options();
  o.max_iterations = options_.max_newton_iterations;
  // A step with moments has no potential: the capped step is taken (its tangent here lacks the
  // moments' load stiffness, so the residual is no merit either).
  o.merit = has_moments ? Merit::kNone : Merit::kEnergy;
  // After the first Newton step the matrix a M + c C + K changes little within a step (the mass
  // term dominates it at a step that resolves the motion): later iterations reuse its factor
  // while the residual falls fast, and refactor otherwise; whole steps are checked by the
  // residual at the next iteration instead of the energy (two evaluations of Phi per iteration,
  // 8 % of a step of the runtime's dragged bowel).
  o.chords = ChordPolicy::kWhileContracting;
  o.verify_steps_by_residual = true;
  o.converge_after_small_step = true;
  o.converge_on_rate = options_.converge_on_rate;
  o.time_budget = 0.0;
  if (options_.time_budget > 0.0) {
    const double left = std::chrono::duration<double>(deadline_ - std::chrono::steady_clock::now()).count();
    o.time_budget = std::max(left, 1e-12);
  }
  const NewtonSummary r = scratch_->minimizer.Minimize(&problem);
  summary.newton_iterations = r.iterations;
  summary.residual = r.residual_norm;
  summary.termination = r.termination;
  if (!r.converged()) {
    summary.out_of_time = r.termination == Termination::kTimeBudget;
    if (summary.out_of_time) {
      summary.reason = "time budget";  // short: no allocation in a haptic loop's tick
    } else if (options_.failure_reasons) {
      summary.reason = r.termination == Termination::kIterationCap
                           ? "the implicit step did not converge in " +
                                 std::to_string(options_.max_newton_iterations) +
                                 " Newton iterations (reduce time_step)"
                           : std::string("the implicit step failed: ") + r.message();
    }
    return summary;
  }
  problem.DeltaOfCurrent();
  if (w.midpoint) {
    // q_{n+1} = 2 q_m - q_n (the midpoint's state carried on by the same increment).
    if (!Advance(problem.current(), delta_, pose_, &trial_)) {
      summary.termination = Termination::kRetractionFailed;
      if (options_.failure_reasons)
        summary.reason = "the midpoint's extrapolation folds an edge back (reduce time_step)";
      return summary;
    }
    scheme_->Finish(w, delta_, t, dt, scratch_->held_rows, s);
    std::swap(s->q, trial_);
  } else {
    scheme_->Finish(w, delta_, t, dt, scratch_->held_rows, s);
    std::swap(s->q, problem.current());  // the problem's current takes q_n (no copy)
    problem.CurrentChanged();
  }
  s->t += dt;
  force_valid_ = false;
  summary.ok = true;
  return summary;
}

}  // namespace rodfit
