// Dynamics of the discrete rod (docs/solvers.md, "Dynamics"): the same energy as the statics,
// with lumped vertex masses m_i (linear density times the vertex's cell), the rotational inertia
// of each edge about its axis (linear density r^2 / 2 times its length, a solid round section),
// external viscous drag -c l_i v_i on the vertices, and Kelvin-Voigt internal damping of the
// bending, twist and stretch rates. The generalised coordinates are those of the statics
// (vertices and twist angles against reference frames transported in time), so their rates are
// the vertex velocities and the edges' spin about their axes.
//
// Internal damping: the viscous force of a term is -(eta / k) K_k v, with K_k the term's stiffness
// matrix (its Hessian with unit stiffness, scaled by eta) at the start of the step: the
// linearisation of the dissipation 1/2 eta (d strain / dt)^2 about the current shape. It is the
// "Rayleigh stiffness damping" of a simulator with one coefficient per deformation mode.
//
// Integrators:
//  - kExplicit: Störmer–Verlet (leapfrog; the centred difference in time), one gradient per step.
//    Its step is bounded by 2 / omega_max; StableTimeStep() bounds omega_max from above by
//    Gershgorin's theorem on M^-1/2 K M^-1/2 (and the damping), so a step below it is stable for
//    the linearised rod. The bound is re-evaluated as the shape changes; a step above it is
//    refused with the limit, or substepped when asked.
//  - kBackwardEuler (first order, numerically damped), kMidpoint (implicit midpoint, second
//    order, no numerical damping of a linear oscillator, so unresolved stiff modes keep their
//    energy) and kBdf2 (second order and L-stable: it damps the unresolved stretch modes, the
//    robust choice for driven and stiff rods): each step minimises an incremental potential
//    Phi(q) = a/2 |d - y|^2_M + c/2 |d - z|^2_C + Pi(q) - f . q, d = q - q_n, by Newton on
//    the banded Hessian (the statics' plus a M + c C), from the predictor q_n + y.
//
// Driven points: the clamp, an end clamp and the held points (pins, grasp, end pin) follow a
// HeldPose given per time by a Drive. Dirichlet rows keep them where the pose puts them.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "rodfit/model/rod.h"
#include "rodfit/solve/termination.h"

namespace rodfit {

/// Two step lengths [s] that are the same step, within round-off (BDF2's history applies).
inline bool SameStep(double a, double b) {
  return std::abs(a - b) <= 1e-9 * std::max(std::abs(a), std::abs(b));
}

/// A scheme in time, by its registered name (the schemes are classes in a registry,
/// src/rodfit/solve/integrator.h: "explicit" (Störmer–Verlet), "backward_euler", "midpoint",
/// "bdf2"). The constants below name the bundled ones; any registered name works.
class Integrator {
 public:
  constexpr explicit Integrator(const char* name) : name_(name) {}
  const char* name() const { return name_; }
  bool operator==(const Integrator& other) const;
  bool operator!=(const Integrator& other) const { return !(*this == other); }
  static const Integrator kExplicit, kBackwardEuler, kMidpoint, kBdf2;

 private:
  const char* name_;
};
inline constexpr Integrator Integrator::kExplicit{"explicit"};
inline constexpr Integrator Integrator::kBackwardEuler{"backward_euler"};
inline constexpr Integrator Integrator::kMidpoint{"midpoint"};
inline constexpr Integrator Integrator::kBdf2{"bdf2"};
/// Its name.
const char* IntegratorName(Integrator integrator);
/// Looks a name up in the registry; false for an unknown one.
bool ParseIntegrator(const std::string& name, Integrator* integrator);

struct DynamicsOptions {
  double time_step = kDefaultTimeStep;  ///< [s]
  /// The scheme (scene.h, kDefaultIntegrator: the scene YAML's default too).
  Integrator integrator = Integrator(kDefaultIntegrator);
  /// Explicit only: with a time_step above the stable step, take as many equal substeps as the
  /// stable step needs instead of refusing.
  bool substep = false;
  /// Explicit only: the fraction of the stability bound 2 / omega_max used (the bound is for the
  /// linearised rod at the shape where it was evaluated).
  double stability_safety = 0.9;
  /// Explicit only: re-evaluate the stable step every this many steps (and whenever the
  /// energy grows by more than the work done on the rod could explain).
  int stability_check_every = 50;
  /// Implicit: Newton iterations per step before the step counts as failed.
  int max_newton_iterations = 50;
  /// Implicit: a step whose Newton iterations do not converge is retried as two half steps,
  /// each of which may be halved again, down to time_step / 2^max_halvings (a driven rod
  /// whose held points jump far in one step leaves Newton's basin); 0: the step fails. A
  /// halved step's sensitivities follow its substeps (StepSensitivity). The scene YAML's
  /// default too (scene.h).
  int max_halvings = kDefaultMaxHalvings;
  /// Implicit: adaptive steps (docs/solvers.md, "Adaptive steps"). Each time_step is covered by
  /// substeps of variable-step BDF2 (or of the scheme chosen) whose local error estimate —
  /// Milne's device: the converged positions against an explicit second-order prediction — stays
  /// within this many metres at every vertex; a substep whose Newton fails or whose predictor
  /// folds an edge is retried at a quarter of its length, and steps grow by at most
  /// kMaxStepRatio per substep. Every time_step still ends exactly on its time (the outputs).
  /// 0: fixed steps (a failed step halved, max_halvings).
  double error_tolerance = 0.0;
  /// Implicit, adaptive: the shortest substep [s]; a substep that would need less fails the
  /// step with the time and the reason.
  double min_time_step = 1e-7;
  /// Implicit: the wall time [s] one Step() may take (0: no limit). Newton checks it before
  /// each iteration after the first; a step past it fails with
  /// DynamicsStepSummary::out_of_time, *s unchanged and not halved (the runtime's haptic loop
  /// gives up such a tick rather than miss its deadline).
  double time_budget = 0.0;
  /// Implicit: a failed step says why in DynamicsStepSummary::reason. Its text is built on the
  /// heap; the runtime's ticks, which must not allocate, turn it off and read ok and
  /// out_of_time.
  bool failure_reasons = true;
  /// Implicit: a full step that follows another full step of the same Newton solve also ends
  /// it when its size times their contraction (its size over the last's), the estimate of the
  /// error left after it, is within step_tolerance: the Newton convergence test of CVODE and
  /// IDA. The residual after that step is then not evaluated. Off by default: the stepper's
  /// sensitivities difference converged states and want every step's residual checked; the
  /// runtime's ticks turn it on (one gradient fewer per tick).
  bool converge_on_rate = false;
  /// Implicit, BDF2: Newton starts from the third-order predictor plus the last two steps'
  /// corrections (DynamicState::last_correction, older_correction) extrapolated linearly, while
  /// they are steady, which along a steady motion (a dragged rod) starts it much nearer the
  /// step's solution. Off by default (it pays along a steady motion only); the runtime's ticks
  /// turn it on.
  bool extrapolate_corrections = false;
  /// Implicit: converged when the scaled residual (ScaledGradientNorm) is below this times the
  /// larger of the case's load scale and its inertial forces, or when a Newton step moves no
  /// vertex by more than step_tolerance L (and no twist angle by more than that in radians).
  double residual_tolerance = 1e-9;
  double step_tolerance = 1e-11;
  bool Check(std::string* why) const;
};

/// Where the held boundary is at one time: the clamp at s = 0 (position, d3, d1), each held
/// point of RodModel::held() (in order), the end clamp's frame, and extra dead loads at the tip.
struct HeldPose {
  Vec3 clamp_position = Vec3::Zero();
  Vec3 clamp_tangent = Vec3::UnitX();
  Vec3 clamp_d1 = Vec3::UnitZ();
  std::vector<Vec3> held;                 ///< [m] per RodModel::held()
  Vec3 end_tangent = Vec3::UnitX();       ///< end clamp only
  Vec3 end_d1 = Vec3::UnitZ();            ///< end clamp with a held normal only
  Vec3 tip_force = Vec3::Zero();          ///< [N] added to the case's (dead, at s = L)
  Vec3 tip_moment = Vec3::Zero();         ///< [N m] added at s = L (dead, world components)
  /// A dead force [N] at a point between vertices point_vertex and point_vertex + 1, shared
  /// (1 - point_weight, point_weight): a tool pushing the rod (the runtime's poke). None when
  /// point_vertex < 0.
  Vec3 point_force = Vec3::Zero();
  int point_vertex = -1;
  double point_weight = 0.0;
};

/// The pose of the held boundary over time. The default holds the model's own targets.
class Drive {
 public:
  virtual ~Drive() = default;
  /// Fills *pose for time t [s] (pose->held has RodModel::held().size() entries on entry).
  virtual void PoseAt(const RodModel& model, double t, HeldPose* pose) const;
};

/// Positions, twist angles and their rates.
struct DynamicState {
  RodState q;
  VecX v;          ///< rates of the free dofs (held dofs: 0) [m/s, rad/s]
  double t = 0.0;  ///< [s]
  /// BDF2's history: the last step's increment q_n - q_n-1 and the rates v_n-1 (set by a BDF2
  /// step; a state without it starts with a backward Euler step).
  VecX last_step, last_v;
  bool has_history = false;
  double last_dt = 0.0;  ///< [s] the step of that history (BDF2 uses it only at the same step)
  /// The rates v_n-2 of the BDF2 step before that one, at the same step: only where Newton
  /// starts (a third-order extrapolation of the rates); the step's equations do not read it.
  VecX older_v;
  bool has_older = false;
  /// BDF2's Newton corrections, the converged increment minus the third-order predictor's, of
  /// the last step (last_correction) and the one before (older_correction): num_corrections of
  /// them are valid, from consecutive steps of the same length. Only where Newton starts
  /// (DynamicsOptions::extrapolate_corrections); the step's equations do not read them.
  VecX last_correction, older_correction;
  int num_corrections = 0;
};

/// A direction in the log of the constants the dynamics read (sensitivities): how much the log of
/// each moves per unit change of the log of one fitted parameter. bend_stiffness with B2 tied
/// moves both bend1 and bend2; a damping parameter moves one of the damping constants.
struct ParameterDirection {
  double bend1 = 0.0, bend2 = 0.0, twist = 0.0, stretch = 0.0;  ///< B1, B2, GJ, EA
  double drag = 0.0;                                            ///< external damping c
  double bend_damping = 0.0, twist_damping = 0.0, stretch_damping = 0.0;
  double density = 0.0;  ///< linear density (the masses, spin inertias and weights)
  /// The rest curvature's derivative (a fitted rest shape; docs/solvers.md, "Sensitivities in
  /// time"): a profile as RodSpec::rest_curvature_s / rest_curvature_profile [1/m per unit of the
  /// parameter], placed on the bending vertices by RestCurvatureProfileAt. Empty: none.
  std::vector<double> rest_curvature_s;
  std::vector<Vec3> rest_curvature_profile;
  /// The direction from one set of constants to another that differ by the factor exp(log_factor)
  /// in one parameter: each constant's log change over log_factor (0 where a constant is 0 in
  /// both). Reads the Material, so the parameter's name is resolved where the name table is.
  static ParameterDirection Between(const Material& a, double density_a, const Material& b,
                                    double density_b, double log_factor);
};

/// Forward sensitivities of a trajectory: the derivatives with respect to the log of each
/// parameter (one column each) of the state's free dofs (positions [m]; twist angles [rad], as
/// rotations about the tangent beyond its transport, which is how ApplyStep moves them), the
/// rates and BDF2's history.
struct DynamicSensitivity {
  Eigen::MatrixXd dq, dv, dlast_step, dlast_v;  ///< num_free_dofs x parameters
};

/// The substeps of adaptive stepping, recorded and replayed: a fit's objective stays smooth in
/// the parameters when the trials and Jacobians of one iteration take the steps its base
/// trajectory took (DynamicsStepper::SetSchedule).
struct StepSchedule {
  enum class Mode { kRecord, kReplay };
  Mode mode = Mode::kRecord;
  std::vector<double> steps;  ///< [s] every accepted substep, in order
  size_t next = 0;            ///< replay: the next substep to take
  bool departed = false;      ///< replay: a substep failed and the stepper adapted instead
  void Record() { mode = Mode::kRecord, steps.clear(), next = 0, departed = false; }
  void Replay() { mode = Mode::kReplay, next = 0, departed = false; }
};

struct DynamicsStepSummary {
  bool ok = false;
  int newton_iterations = 0;  ///< implicit: Newton iterations in this step
  int substeps = 1;           ///< substeps taken (explicit with substep; implicit halved)
  int rejected = 0;           ///< adaptive: substeps retried (error above tolerance or failed)
  /// Implicit: how the (last) Newton solve of the step ended (termination.h); kConverged for an
  /// explicit step.
  Termination termination = Termination::kConverged;
  double residual = 0.0;      ///< implicit: scaled residual at exit [N]
  std::string reason;         ///< why a step failed
  bool out_of_time = false;   ///< failed because DynamicsOptions::time_budget ran out
};

/// The sensitivities of an equilibrium q of the model (the start of a trajectory) along each
/// direction: dq = -K^-1 dg/dp with K the full Hessian at q (stiffnesses and the weights; the
/// damping constants do not move an equilibrium), one column per direction into *dq.
/// False with the reason for a case with moment loads or an unstable equilibrium.
/// The derivative along `direction` of the gradient of the rod's elastic energy at q (free dofs,
/// held rows zeroed; no loads): the stiffness factors' terms (U is linear in each stiffness) and
/// the rest curvature's (the gradient is affine in it: the difference of the gradients with the
/// direction's rest curvature and with none, the bending stiffnesses at their values). Exact, up
/// to round-off.
void ParameterGradient(const RodModel& model, const RodState& q,
                       const ParameterDirection& direction, VecX* g);

bool EquilibriumSensitivity(const RodModel& model, const RodState& q,
                            const std::vector<ParameterDirection>& directions, Eigen::MatrixXd* dq,
                            std::string* why);

class TimeIntegrator;  // a scheme of the registry (src/rodfit/solve/integrator.h)
struct RodFrames;      // an assembly's frames (src/rodfit/solve/rod_energy.h)
class BandedSymmetric;  // a band matrix (src/rodfit/solve/banded.h)

/// Integrates a RodModel in time. The stepper owns its scratch (band matrices, factor, states),
/// kept between steps. The held points' reactions at a step's end are those of
/// solve/reactions.h at the state (the held vertices' own inertia is the driver's).
class DynamicsStepper {
 public:
  /// Throws std::invalid_argument when the rod cannot move (no linear density) or the explicit
  /// integrator lacks a rotational inertia (radius 0).
  DynamicsStepper(const RodModel& model, const DynamicsOptions& options);
  ~DynamicsStepper();

  const RodModel& model() const { return model_; }
  const DynamicsOptions& options() const { return options_; }
  /// Sets DynamicsOptions::time_budget [s] (>= 0) and max_newton_iterations (>= 1) for the
  /// steps from now on (the runtime sizes its buffers by a first step without its tick's limits).
  void SetNewtonLimits(int max_newton_iterations, double time_budget) {
    options_.max_newton_iterations = std::max(max_newton_iterations, 1);
    options_.time_budget = std::max(time_budget, 0.0);
  }

  /// Adaptive steps: record into or replay from `schedule` (null: neither). The stepper keeps
  /// the pointer.
  void SetSchedule(StepSchedule* schedule) { schedule_ = schedule; }

  /// The state at rest in the initial shape `q` (velocities zero, t = 0).
  DynamicState AtRest(const RodState& q) const;

  /// One step of options().time_step from s->t. On failure *s is unchanged and the summary says
  /// why (explicit: the step is above the stable step; implicit: Newton did not converge, in
  /// the smallest substep when max_halvings allows halving).
  DynamicsStepSummary Step(const Drive& drive, DynamicState* s);

  /// Forward sensitivities through the step just taken from `before` to `after` (docs/solvers.md,
  /// "Sensitivities in time"; through each substep when the step was halved): the step's
  /// stationarity g(q_n+1; q_n, v_n, history, p) = 0 is
  /// differentiated, dq_n+1/dp = -H^-1 (dg/dp + dg/dq_n dq_n/dp + dg/d(history) d(history)/dp),
  /// with H = K(q_n+1) + a M + c C(q_n) the Newton matrix at the solution (assembled and
  /// factored here: the step's own factor may be a chord iteration's older one). Backward Euler
  /// and BDF2 only. Central differences of the assembly (relative accuracy ~1e-9) stand in
  /// where the assembly has no exact derivative: the lagged damping matrix C(q_n) along dq_n
  /// (a third derivative of the energy), and the bending and twist Hessians' missing second
  /// derivative of the reference twist. On failure (midpoint or explicit integrator, moment
  /// loads, an indefinite H, corrections that do not settle) returns false with the reason; *ds
  /// is then unusable.
  bool StepSensitivity(const Drive& drive, const DynamicState& before, const DynamicState& after,
                       const std::vector<ParameterDirection>& directions, DynamicSensitivity* ds,
                       std::string* why);

  /// The explicit integrator's stable step [s] at a state: stability_safety times the bound
  /// 2 / (omega_max) of the linearised, lagged-damped leapfrog, omega_max from Gershgorin.
  double StableTimeStep(const RodState& q);

  /// Kinetic energy 1/2 v^T M v [J] and the potential energy Pi of the model's own loads [J].
  double KineticEnergy(const DynamicState& s) const;
  double PotentialEnergy(const RodState& q) const;

  /// The gradient of Pi at q less the loads beyond it (moment loads, the pose's tip and point
  /// loads), held rows zero: minus the forces the steps integrate, without damping or inertia.
  /// Into `frames` (the caller's scratch): the stepper's own state is untouched.
  void LoadedGradient(const RodState& q, const HeldPose& pose, RodFrames* frames, VecX* g) const;
  /// The free-dof difference b - a as the steps take it (the twists' increments with the
  /// reference frames' transport; held dofs 0).
  void Difference(const RodState& a, const RodState& b, VecX* d) const { Delta(a, b, d); }

  /// Lumped mass of each free dof [kg or kg m^2] (held dofs: their mass, unused).
  const VecX& mass() const { return mass_; }

 private:
  DynamicsStepSummary StepExplicit(const Drive& drive, double dt, DynamicState* s);
  DynamicsStepSummary StepImplicit(const Drive& drive, double dt, DynamicState* s);
  /// Covers dt from s->t by one implicit step, or by halves of it down to `depth` halvings;
  /// each substep's start and step are appended to substeps_. On failure *s is partly advanced.
  bool StepHalving(const Drive& drive, double dt, int depth, DynamicState* s,
                   DynamicsStepSummary* summary);
  /// Covers time_step from s->t by adaptive substeps (DynamicsOptions::error_tolerance).
  DynamicsStepSummary StepAdaptive(const Drive& drive, DynamicState* s);
  /// The local error estimate [m] of the substep from `before` to `after` of length dt (the
  /// largest over the vertices).
  double LocalError(const DynamicState& before, const DynamicState& after, double dt);
  bool OneStepSensitivity(const Drive& drive, double dt, const DynamicState& before,
                          const DynamicState& after, const std::vector<ParameterDirection>& directions,
                          DynamicSensitivity* ds, std::string* why);
  /// Gradient of Pi at q plus the pose's extra tip loads' (held rows zeroed).
  void Forces(const RodState& q, const HeldPose& pose, VecX* g);
  /// The damping matrix C (external drag and internal viscosities) at q into the scratch band `damping`.
  void AssembleDamping(const RodState& q);
  /// The internal damping matrix the last AssembleDamping made, when it was made at a state
  /// equal to q (the last substep's start): a sensitivity step's C(q_n) without a second
  /// assembly. False otherwise.
  bool DampingAt(const RodState& q, BandedSymmetric* C) const;
  /// Free-dof difference b - a (held dofs 0).
  void Delta(const RodState& a, const RodState& b, VecX* d) const;
  /// *out = q with free vertices moved by `dx` (dof vector), the boundary at `pose`.
  bool Advance(const RodState& q, const VecX& dx, const HeldPose& pose, RodState* out) const;

  const RodModel& model_;
  DynamicsOptions options_;
  const TimeIntegrator* scheme_ = nullptr;  // the registry's (integrator.h)
  VecX mass_, drag_;  // per free dof: lumped mass, external drag coefficient [N s/m]
  bool internal_damping_ = false;
  std::vector<char> held_;
  VecX weights_;  // ScaledGradientNorm weights
  // Scratch.
  HeldPose pose_, pose_mid_;
  RodState trial_;
  VecX g_, step_, delta_, delta0_, force_, cv_, cd_;
  // The frames, the band matrices and their factor, the step's problem and the minimizer:
  // internal types (dynamics.cc).
  struct Scratch;
  class StepProblem;
  std::unique_ptr<Scratch> scratch_;
  bool force_valid_ = false;  // explicit: force_ holds -grad at s->q (cached between steps)
  double force_time_ = -1.0;
  // When the Step() in progress runs out of DynamicsOptions::time_budget.
  std::chrono::steady_clock::time_point deadline_;
  double stable_dt_ = 0.0;
  int steps_since_check_ = 0;
  // The last implicit step's substeps when it was halved (empty otherwise): their starts and
  // steps, and the time it ended at.
  std::vector<std::pair<DynamicState, double>> substeps_;
  double substeps_end_ = 0.0;
  double adaptive_step_ = 0.0;  // [s] the next substep's length (adaptive stepping)
  StepSchedule* schedule_ = nullptr;
};

}  // namespace rodfit
