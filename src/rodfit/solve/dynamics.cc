#include "rodfit/solve/dynamics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>

#include "rodfit/model/frames.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {

const char* IntegratorName(Integrator integrator) {
  switch (integrator) {
    case Integrator::kExplicit: return "explicit";
    case Integrator::kBackwardEuler: return "backward_euler";
    case Integrator::kMidpoint: return "midpoint";
    case Integrator::kBdf2: return "bdf2";
  }
  return "?";
}

bool ParseIntegrator(const std::string& name, Integrator* integrator) {
  for (Integrator k : {Integrator::kExplicit, Integrator::kBackwardEuler, Integrator::kMidpoint,
                       Integrator::kBdf2}) {
    if (name == IntegratorName(k)) {
      *integrator = k;
      return true;
    }
  }
  return false;
}

bool DynamicsOptions::Check(std::string* why) const {
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

// extrapolate_corrections: the last two steps' corrections are extrapolated only when they
// differ by at most this fraction of the last one (a steady motion).
constexpr double kSteadyCorrection = 0.25;

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
  RodFrames frames, trial_frames;
  BandedSymmetric hessian, damping;
  BandedCholesky factor;
  std::vector<int> held_rows;  // the held dofs (held_), listed: the Newton loop zeroes their rows
};

DynamicsStepper::DynamicsStepper(const RodModel& model, const DynamicsOptions& options)
    : model_(model), options_(options), scratch_(std::make_unique<Scratch>()) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
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
  if (options_.integrator == Integrator::kExplicit && !(spin_inertia > 0.0)) {
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
  for (VecX* v : {&g_, &g_trial_, &step_, &delta_, &delta0_, &force_, &cv_, &cd_, &y_, &z_,
                  &y_pred_, &y_ab_})
    v->setZero(dofs);
  prev_ = model.StraightState();
  trial_ = prev_;
  ComputeRodFrames(model, prev_, &scratch_->frames);
  scratch_->trial_frames = scratch_->frames;
  scratch_->hessian.Resize(dofs, kRodBandwidth, 4);
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

// The point force's potential -f . x(s) at a state.
double PointForcePotential(const HeldPose& pose, const RodState& q) {
  if (pose.point_vertex < 0 || pose.point_force.squaredNorm() == 0.0) return 0.0;
  const double w = pose.point_weight;
  return -pose.point_force.dot((1.0 - w) * q.x.col(pose.point_vertex) +
                               w * q.x.col(pose.point_vertex + 1));
}

}  // namespace

void DynamicsStepper::Forces(const RodState& q, const HeldPose& pose, VecX* g) {
  const int n = model_.num_edges();
  ComputeRodFrames(model_, q, &scratch_->frames);
  AssembleGradient(model_, q, EnergyTerms(), g, &scratch_->frames);
  if (model_.nonconservative()) AddMomentLoads(model_, q, scratch_->frames, 1.0, g, nullptr);
  if (pose.tip_force.squaredNorm() > 0.0) g->segment<3>(RodModel::VertexDof(n)) -= pose.tip_force;
  AddPointForce(pose, g);
  if (pose.tip_moment.squaredNorm() > 0.0) {
    EdgeMoment em;
    em.edge = n - 1;
    em.moment = pose.tip_moment;
    const EdgeMomentForce f = EdgeMomentLoad(em, scratch_->frames, 1.0);
    g->segment<3>(RodModel::VertexDof(n)) -= f.Qe;
    if (n >= 2) g->segment<3>(RodModel::VertexDof(n - 1)) += f.Qe;
    (*g)[RodModel::TwistDof(n - 1)] -= f.Qt;
  }
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
  if (options_.integrator != Integrator::kExplicit) {
    substeps_.clear();  // keeps its capacity: no allocation in a step that is not halved
    if (options_.time_budget > 0.0)
      deadline_ = std::chrono::steady_clock::now() +
                  std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                      std::chrono::duration<double>(options_.time_budget));
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
  const bool midpoint = options_.integrator == Integrator::kMidpoint;
  // BDF2 needs the step before, of the same length (its first step, and the first after a
  // change of step, is backward Euler's).
  const bool bdf2 = options_.integrator == Integrator::kBdf2 && s->has_history &&
                    s->last_step.size() == N && s->last_v.size() == N &&
                    SameStep(s->last_dt, dt);
  // Phi(q) = a/2 |d - y|_M^2 + c/2 |d - z|_C^2 + Pi(q) - f . q, d = q - q_n (see dynamics.h):
  // backward Euler y = dt v_n; midpoint (the unknown is the midpoint) y = dt v_n / 2; BDF2
  // y = d_n-1 / 3 + 2 dt (4 v_n - v_n-1) / 9 and z = d_n-1 / 3, d_n-1 = q_n - q_n-1.
  const double a = midpoint ? 4.0 / (dt * dt) : bdf2 ? 9.0 / (4.0 * dt * dt) : 1.0 / (dt * dt);
  const double c = midpoint ? 2.0 / dt : bdf2 ? 1.5 / dt : 1.0 / dt;
  if (bdf2) {
    y_ = s->last_step / 3.0 + (2.0 * dt / 9.0) * (4.0 * s->v - s->last_v);
    z_ = s->last_step / 3.0;
  } else {
    y_ = (midpoint ? 0.5 * dt : dt) * s->v;
    z_.setZero(N);
  }
  drive.PoseAt(model_, s->t + dt, &pose_);
  const HeldPose* pose = &pose_;
  if (midpoint) {
    drive.PoseAt(model_, s->t, &pose_mid_);
    HeldPose start = pose_mid_;
    MidPose(start, pose_, &pose_mid_);
    pose = &pose_mid_;
  }
  AssembleDamping(s->q);
  const BandedSymmetric& C = scratch_->damping;
  const RodState& q0 = s->q;
  // The first Newton iterate: BDF2's q_n + y is where the rod would coast, its elastic forces
  // unbalanced; the rates' extrapolation q_n + dt (3 v_n - v_n-1) / 2 (second order in dt, as
  // BDF2) starts nearer the step's solution, and the first Newton step from it leaves about a
  // third of the residual that one from q_n + y leaves (3.02 iterations per step fall to 2.78
  // on the runtime's dragged bowel). With the rates of one more step, the third-order
  // (Adams–Bashforth) extrapolation dt (23 v_n - 16 v_n-1 + 5 v_n-2) / 12 starts nearer still
  // (2.78 to 2.57). The step's equations do not depend on where Newton starts.
  // What Newton then adds to the predictor, the correction, is smooth in time along a steady
  // motion too (extrapolate_corrections): the last two steps' corrections, extrapolated
  // linearly, start it nearer still. On the runtime's dragged suture (100 segments, 1 ms) the
  // first residual falls 30-fold where they are used, and after two solves it is below the
  // tolerance where it was 1-10 times over in half the steps (2.57 solves per step to 2.28).
  const bool third_order = bdf2 && s->has_older && s->older_v.size() == N;
  if (third_order) {
    y_ab_ = (dt / 12.0) * (23.0 * s->v - 16.0 * s->last_v + 5.0 * s->older_v);
    y_pred_ = y_ab_;
    // Only while the corrections are steady: after a reversal or a jerk of the held points the
    // extrapolation points the wrong way, Newton starts further off, and the residual test,
    // whose scale is the elastic forces at the start, ends the step further from its solution.
    // Measured on the erratic drags of Dynamics.FastStartAndStopFollowErraticDrags: without this
    // guard, more iterations than the plain stepper's and trajectories up to 14x further from a
    // tightly converged one; with a bound of 0.5, 1.25x further on the jittered circle; with
    // 0.25 (and 0.35), as near as the plain stepper's on all five. (Taking that scale without
    // the corrections, g - H c, cured the jitter at 0.5 but cost a banded product, 4 % of a
    // tick, as much as the bound of 0.25 costs in solves.)
    if (options_.extrapolate_corrections && s->num_corrections >= 2 &&
        s->older_correction.size() == N && s->last_correction.size() == N) {
      const double change = (s->last_correction - s->older_correction).lpNorm<Eigen::Infinity>();
      if (change <= kSteadyCorrection * s->last_correction.lpNorm<Eigen::Infinity>())
        y_pred_ += 2.0 * s->last_correction - s->older_correction;
    }
  } else if (bdf2) {
    y_pred_ = dt * (1.5 * s->v - 0.5 * s->last_v);
  } else {
    y_pred_ = y_;
  }
  if (!Advance(q0, y_pred_, *pose, &prev_)) {  // the predictor
    if (options_.failure_reasons)
      summary.reason = "the predictor folds an edge back: time_step too large for this motion";
    return summary;
  }
  RodState& q = prev_;
  // Delta(q0, q) of the predictor without Delta's transports: Advance transported q's reference
  // directors straight from q0's, so the holonomy term of its twist increments is zero (to
  // round-off). It saves one of the three Deltas of a tick, 1 % of its instructions.
  delta_.setZero(N);
  for (int i = 1; i <= n; ++i) delta_.segment<3>(RodModel::VertexDof(i)) = q.x.col(i) - q0.x.col(i);
  for (int j = 0; j < n; ++j) delta_[RodModel::TwistDof(j)] = q.theta[j] - q0.theta[j];
  if (model_.has_end_ghost()) delta_[RodModel::TwistDof(n)] = q.end_theta - q0.end_theta;
  for (int r : scratch_->held_rows) delta_[r] = 0.0;
  const bool has_moments = model_.nonconservative() || pose->tip_moment.squaredNorm() > 0.0;
  const double L = model_.length();
  auto phi = [&](const RodState& state, const RodFrames& frames, double* value) {
    Delta(q0, state, &delta_);
    double e = PotentialEnergyFreshFrames(model_, state, EnergyTerms(), &frames);
    e -= pose->tip_force.dot(state.x.col(n));
    e += PointForcePotential(*pose, state);
    VecX& r = cv_;
    r = delta_ - y_;
    delta0_ = delta_ - z_;
    double inertia = 0.0, damp = 0.0;
    for (int k = 0; k < N; ++k) {
      if (held_[k]) continue;
      inertia += mass_[k] * r[k] * r[k];
      damp += drag_[k] * delta0_[k] * delta0_[k];
    }
    if (internal_damping_) {
      C.MultiplyInto(delta0_, &cd_);
      damp += delta0_.dot(cd_);
    }
    *value = e + 0.5 * a * inertia + 0.5 * c * damp;
    return std::isfinite(*value);
  };
  // The step's loads beyond Pi: the non-conservative moments and the pose's tip loads.
  auto AddLoads = [&](const RodState& state, const RodFrames& frames, VecX* g) {
    if (model_.nonconservative()) AddMomentLoads(model_, state, frames, 1.0, g, nullptr);
    if (pose->tip_force.squaredNorm() > 0.0) g->segment<3>(RodModel::VertexDof(n)) -= pose->tip_force;
    AddPointForce(*pose, g);
    if (pose->tip_moment.squaredNorm() > 0.0) {
      EdgeMoment em;
      em.edge = n - 1;
      em.moment = pose->tip_moment;
      const EdgeMomentForce f = EdgeMomentLoad(em, frames, 1.0);
      g->segment<3>(RodModel::VertexDof(n)) -= f.Qe;
      if (n >= 2) g->segment<3>(RodModel::VertexDof(n - 1)) += f.Qe;
      (*g)[RodModel::TwistDof(n - 1)] -= f.Qt;
    }
  };
  // The inertia and damping forces of the step at `state`, added to *g: grad Phi = grad Pi - f
  // + a M (d - y) + c C (d - z); then the held rows are zeroed, and the result's largest
  // weighted entry (weights_: the scaled residual) is returned.
  auto AddStepForces = [&](const RodState& state, VecX* g, bool delta_known) {
    if (!delta_known) Delta(q0, state, &delta_);  // else delta_ holds Delta(q0, state)
    // Into kept scratch: a step allocates nothing once the stepper has taken one (the runtime's
    // haptic loop relies on it).
    if (internal_damping_) {
      delta0_ = delta_ - z_;
      C.MultiplyInto(delta0_, &cd_);
      for (int k = 0; k < N; ++k) (*g)[k] += c * cd_[k];
    }
    for (int k = 0; k < N; ++k)
      (*g)[k] += a * mass_[k] * (delta_[k] - y_[k]) + c * drag_[k] * (delta_[k] - z_[k]);
    for (int r : scratch_->held_rows) (*g)[r] = 0.0;
    // A NaN entry makes the norm NaN (std::max would drop it), which the caller rejects: a
    // hostile damping of 1e308 overflows c drag to inf, and inf 0 is NaN. Dropped, the NaN rows
    // left the twist rows' tiny residual, and the step "converged" without an iteration.
    double norm = 0.0;
    bool nan = false;
    for (int k = 0; k < N; ++k) {
      const double v = weights_[k] * std::abs((*g)[k]);
      nan = nan || std::isnan(v);
      norm = std::max(norm, v);
    }
    return nan ? std::numeric_limits<double>::quiet_NaN() : norm;
  };
  double force_tol = -1.0, floor_tol = 0.0;
  // Phi at q, evaluated only when a line search needs it (energy_known).
  double energy = 0.0;
  bool energy_known = false;
  ComputeRodFrames(model_, q, &scratch_->frames);
  // The frames of q and delta_ = Delta(q0, q) are computed once per state: each accepted
  // line-search trial leaves them for the next iteration.
  bool frames_current = true, delta_current = true;
  // A whole, unshifted step is taken without the line search's energy test (an evaluation of
  // Phi at the step's start and one per iteration: 8 % of a step of the runtime's dragged bowel)
  // and checked by the residual at the next iteration instead: if the residual did not fall, the step is undone (the state before it is
  // kept in trial_) and the iteration repeated with the line search, which the rest of the step
  // then keeps (line_search).
  bool unchecked = false, line_search = has_moments;
  double unchecked_from = 0.0;  // the residual before the unchecked step
  bool converged = false;
  // After the first Newton step the matrix a M + c C + K changes little within a step (the mass
  // term dominates it at a step that resolves the motion): later iterations reuse its factor
  // (chord steps, a gradient and a back-substitution each) while the residual falls at least
  // fourfold per iteration, and refactor otherwise.
  bool chord = false;
  bool unchecked_chord = false;  // the unchecked step was a chord step
  double previous_gnorm = std::numeric_limits<double>::infinity();
  // The sizes of the last full step (positions [m], twists [rad]) for converge_on_rate; < 0:
  // none.
  double last_dx = -1.0, last_dth = -1.0;
  constexpr double kTiny = std::numeric_limits<double>::min();
  for (int it = 0; it < options_.max_newton_iterations && !converged; ++it) {
    if (it > 0 && options_.time_budget > 0.0 && std::chrono::steady_clock::now() > deadline_) {
      summary.out_of_time = true;
      summary.reason = "time budget";  // short: no allocation in a haptic loop's tick
      return summary;
    }
    if (!frames_current) ComputeRodFrames(model_, q, &scratch_->frames);
    frames_current = true;
    if (chord) {
      AssembleGradient(model_, q, EnergyTerms(), &g_, &scratch_->frames);
    } else {
      AssembleHessian(model_, q, EnergyTerms(), &g_, &scratch_->hessian, &scratch_->frames);
    }
    AddLoads(q, scratch_->frames, &g_);
    if (force_tol < 0.0) {
      // Relative to the forces the step balances: the case's loads or the elastic forces at
      // the predictor, whichever is larger.
      double elastic = 0.0;
      for (int k = 0; k < N; ++k) elastic = std::max(elastic, weights_[k] * std::abs(g_[k]));
      force_tol = options_.residual_tolerance * std::max(model_.force_scale(), elastic);
      // The stretch forces' round-off, ~eps EA per edge (as in the statics): a residual at this
      // floor still hides errors in the soft bending modes (EA L^2 / B ~ 1e7 for a suture), so
      // there convergence is told by the Newton step.
      const double max_weight = weights_.size() ? weights_.maxCoeff() : 1.0;
      floor_tol = 64.0 * std::numeric_limits<double>::epsilon() *
                  model_.material().stretch_stiffness * max_weight;
    }
    const double gnorm = AddStepForces(q, &g_, delta_current);  // held rows zeroed
    delta_current = true;
    if (!chord) {
      BandedSymmetric& H = scratch_->hessian;
      for (int k = 0; k < N; ++k) H.At(k, k) += a * mass_[k] + c * drag_[k];
      if (internal_damping_) H.band() += c * C.band();
      // The held rows and columns: the identity (ApplyHeldRows, by the list).
      const int p = H.bandwidth();
      for (int r : scratch_->held_rows)
        for (int col = std::max(0, r - p); col <= std::min(N - 1, r + p); ++col)
          H.At(std::max(r, col), std::min(r, col)) = (r == col) ? 1.0 : 0.0;
    }
    summary.residual = gnorm;
    if (!std::isfinite(gnorm)) {
      if (options_.failure_reasons) summary.reason = "non-finite residual in the implicit step";
      return summary;
    }
    if (gnorm <= force_tol) {
      converged = true;
      break;
    }
    if (unchecked && !(gnorm < unchecked_from) && gnorm > floor_tol) {
      // The whole step raised the residual (above its round-off floor, where a rise is noise):
      // back to the state before it, and this iteration again with the Hessian there.
      std::swap(q, trial_);
      unchecked = false;
      last_dx = -1.0;  // the step undone measured nothing
      // A chord step on an older factor may fail where a Newton step would not: only a Newton
      // step's failure calls for the line search.
      line_search = line_search || !unchecked_chord;
      frames_current = delta_current = energy_known = false;
      chord = false;
      previous_gnorm = std::numeric_limits<double>::infinity();
      --it;
      continue;
    }
    unchecked = false;
    if (chord && gnorm > 0.25 * previous_gnorm) {
      // The old factor no longer converges fast: this iteration again with the Hessian.
      chord = false;
      previous_gnorm = std::numeric_limits<double>::infinity();
      --it;
      continue;
    }
    previous_gnorm = gnorm;
    bool shifted = false;
    if (!chord && !scratch_->factor.Factor(scratch_->hessian)) {
      // Phi is not convex here (compressed edges whose geometric stiffness outweighs a M at this
      // step): a diagonal shift, grown tenfold until the factor exists, gives a descent
      // direction for the line search, as in the statics.
      double max_diagonal = 0.0;
      for (int k = 0; k < N; ++k) max_diagonal = std::max(max_diagonal, std::abs(scratch_->hessian.At(k, k)));
      double shift = 1e-10 * max_diagonal;
      while (!scratch_->factor.Factor(scratch_->hessian, shift) && shift < 1e3 * max_diagonal) shift *= 10.0;
      if (!scratch_->factor.valid()) {
        if (options_.failure_reasons)
          summary.reason = "the step's Newton matrix cannot be made positive definite";
        return summary;
      }
      shifted = true;
    }
    step_ = -g_;
    scratch_->factor.SolveInPlace(step_);
    ++summary.newton_iterations;
    double alpha = 1.0;
    const double turn = MaxTangentTurn(model_, q, step_);
    if (turn > 0.5) alpha = 0.5 / turn;
    bool accepted = false;
    if (!line_search && !shifted && alpha == 1.0 && ApplyStep(model_, q, step_, 1.0, &trial_)) {
      std::swap(q, trial_);  // trial_ keeps the state before the step for its check
      unchecked = true;
      unchecked_chord = chord;
      unchecked_from = gnorm;
      accepted = true;
      frames_current = delta_current = energy_known = false;
    }
    if (!accepted && !has_moments && !energy_known) {
      if (!frames_current) ComputeRodFrames(model_, q, &scratch_->frames);
      frames_current = true;
      if (!phi(q, scratch_->frames, &energy)) {
        if (options_.failure_reasons) summary.reason = "non-finite energy in the implicit step";
        return summary;
      }
      energy_known = delta_current = true;
    }
    const double slope = g_.dot(step_);
    for (int ls = 0; ls < 30 && !accepted; ++ls, alpha *= 0.5) {
      if (!ApplyStep(model_, q, step_, alpha, &trial_)) continue;
      if (has_moments) {  // no potential: the full (capped) step
        accepted = true;
        frames_current = delta_current = false;
        break;
      }
      ComputeRodFrames(model_, trial_, &scratch_->trial_frames);
      double e_trial = 0.0;
      const double noise = 1e-13 * (std::abs(energy) + model_.force_scale() * L);
      if (!phi(trial_, scratch_->trial_frames, &e_trial)) continue;
      if (e_trial <= energy + 1e-4 * alpha * slope + noise) {
        energy = e_trial;
        accepted = true;
        // phi has left delta_ = Delta(q0, trial_), and trial_frames are trial_'s.
        std::swap(scratch_->frames, scratch_->trial_frames);
        break;
      }
      // Near the solution Phi stops being a faithful merit of the step's equations: its
      // decrease along the full step (about slope / 2) falls below the round-off of its sum,
      // and over a long step the twist rows' increment against q_n (a transport from q_n's
      // tangents straight to the trial's) differs at second order in the tangents' turn from
      // the increments the gradient sums, so Phi can rise along a Newton step that lowers the
      // residual. The energy test then rejects the convergent step and backtracking crawls
      // (|g| falling 0.1-0.4 % per iteration, measured on a cable driven at 10 ms steps). For a
      // small unshifted correction the residual is the merit: the full step is taken when it
      // lowers the weighted residual.
      if (ls == 0 && !shifted && (turn <= 1e-3 || -slope <= 1e3 * noise)) {
        AssembleGradient(model_, trial_, EnergyTerms(), &g_trial_, &scratch_->trial_frames);
        AddLoads(trial_, scratch_->trial_frames, &g_trial_);
        // phi left Delta(q0, trial_); held rows zeroed.
        if (AddStepForces(trial_, &g_trial_, /*delta_known=*/true) < gnorm) {
          energy = e_trial;
          accepted = true;
          std::swap(scratch_->frames, scratch_->trial_frames);
          break;
        }
      }
    }
    if (!accepted) {
      if (options_.failure_reasons) summary.reason = "the implicit step's line search failed";
      return summary;
    }
    if (!unchecked) std::swap(q, trial_);
    chord = alpha == 1.0 && !shifted;
    // A full Newton step that moves nothing by more than the step tolerance (or by 1e3 times
    // that with the residual at its round-off floor): converged.
    if (alpha == 1.0 && !shifted) {
      // Blocks [x_i, theta_i] of four dofs (RodModel::VertexDof, TwistDof); held rows' steps
      // are zero (their rows of the matrix are the identity's, their residuals zero).
      double dx = 0.0, dth = 0.0;
      for (int k = 0; k < N; k += 4) {
        dx = std::max({dx, std::abs(step_[k]), std::abs(step_[k + 1]), std::abs(step_[k + 2])});
        dth = std::max(dth, std::abs(step_[k + 3]));
      }
      const double tol = options_.step_tolerance * (gnorm <= std::max(force_tol, floor_tol) ? 1e3 : 1.0);
      if (dx <= tol * L && dth <= tol) converged = true;
      if (options_.converge_on_rate && last_dx >= 0.0) {
        // Newton and chord iterates converge linearly at least: the error left after this
        // step is about its size times the contraction of the step sizes.
        const double rate =
            std::max(dx / std::max(last_dx, kTiny), dth / std::max(last_dth, kTiny));
        if (rate < 1.0 && dx * rate <= tol * L && dth * rate <= tol) converged = true;
      }
      last_dx = dx;
      last_dth = dth;
    } else {
      last_dx = -1.0;  // a damped or shifted step measures no contraction
    }
  }
  if (!converged) {
    if (options_.failure_reasons)
      summary.reason = "the implicit step did not converge in " +
                       std::to_string(options_.max_newton_iterations) +
                       " Newton iterations (reduce time_step)";
    return summary;
  }
  if (!delta_current) Delta(q0, q, &delta_);
  if (midpoint) {
    // q_{n+1} = 2 q_m - q_n (the midpoint's state carried on by the same increment), v_{n+1} =
    // 2 v_m - v_n with v_m = 2 d / dt.
    if (!Advance(q, delta_, pose_, &trial_)) {
      if (options_.failure_reasons)
        summary.reason = "the midpoint's extrapolation folds an edge back (reduce time_step)";
      return summary;
    }
    for (int k = 0; k < N; ++k) s->v[k] = held_[k] ? 0.0 : 4.0 * delta_[k] / dt - s->v[k];
    std::swap(s->q, trial_);
  } else {
    // Backward Euler v = d / dt; BDF2 v = 3 (d - d_n-1 / 3) / (2 dt) = c (d - z).
    if (options_.integrator == Integrator::kBdf2) {
      // v_n-1 becomes v_n-2 when this step continued a history of the same step.
      if (bdf2) std::swap(s->older_v, s->last_v);  // v_n-1 is now in last_v, overwritten below
      s->has_older = bdf2;
      // This step's correction, if it started from the third-order predictor (swaps and
      // assignments into vectors of the same size: no allocation).
      if (third_order) {
        std::swap(s->older_correction, s->last_correction);
        s->last_correction = delta_ - y_ab_;
        s->num_corrections = std::min(2, s->num_corrections + 1);
      } else {
        s->num_corrections = 0;
      }
      s->last_v = s->v;
      s->last_step = delta_;
      s->has_history = true;
      s->last_dt = dt;
    }
    for (int k = 0; k < N; ++k) s->v[k] = c * (delta_[k] - z_[k]);
    for (int r : scratch_->held_rows) s->v[r] = 0.0;
    std::swap(s->q, q);  // q, the stepper's scratch, takes q_n (no copy)
  }
  s->t += dt;
  force_valid_ = false;
  summary.ok = true;
  return summary;
}

}  // namespace rodfit
