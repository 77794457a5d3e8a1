// Newton solver for the rod's equilibrium (statics.h): banded Cholesky for the potential's
// Hessian, banded LU for the tangent of a case with moments, diagonal shift for indefinite
// matrices, Armijo backtracking, tangent-turn step limit, saddle escapes, load continuation and
// continuation of held points. Every loop has a cap.
#include "rodfit/solve/statics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include <Eigen/Geometry>

#include "rodfit/model/frames.h"
#include "rodfit/solve/linear_solvers.h"
#include "rodfit/solve/moment_loads.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/rod_problem.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics_workspace.h"

namespace rodfit {

bool StaticsOptions::Check(std::string* why) const {
  auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(gradient_tolerance > 0)) return fail("gradient_tolerance must be > 0");
  if (!(step_tolerance > 0)) return fail("step_tolerance must be > 0");
  if (max_load_steps < 1) return fail("max_load_steps must be >= 1");
  if (!(continuation_move > 0 && continuation_move <= 1)) {
    return fail("continuation_move must lie in (0, 1]");
  }
  if (!(continuation_turn > 0 && continuation_turn <= 3)) {
    return fail("continuation_turn must lie in (0, 3] rad");
  }
  if (max_continuation_steps < 1) return fail("max_continuation_steps must be >= 1");
  if (edge_solver_segments < 2) return fail("edge_solver_segments must be >= 2");
  return true;
}

std::shared_ptr<StaticsWorkspace> NewStaticsWorkspace() {
  return std::make_shared<StaticsWorkspace>();
}

std::string StaticsSummary::BriefReport() const {
  char extra[96] = "";
  int k = 0;
  if (chord_steps > 0) k += std::snprintf(extra + k, sizeof(extra) - k, " (%d chord steps)", chord_steps);
  if (continuation_steps > 0)
    k += std::snprintf(extra + k, sizeof(extra) - k, ", %d continuation steps", continuation_steps);
  char buf[400];
  std::snprintf(buf, sizeof(buf),
                "%s%s after %d Newton iterations%s, %d load step(s), |g| = %.3e N, Pi = %.6e J: %s",
                converged ? "converged" : "NOT converged",
                (converged && !stable) ? " (unstable equilibrium)" : "", iterations, extra,
                load_steps, gradient_norm, energy, reason.c_str());
  return buf;
}

namespace {

enum class StepResult { kConverged, kFailed, kIterationCap };

bool SameState(const RodState& a, const RodState& b) {
  return a.x.cols() == b.x.cols() && a.e.cols() == b.e.cols() &&
         a.theta.size() == b.theta.size() && a.ref_u.cols() == b.ref_u.cols() &&
         a.ref_t.cols() == b.ref_t.cols() && a.ref_twist.size() == b.ref_twist.size() &&
         a.x == b.x && a.e == b.e && a.theta == b.theta && a.ref_u == b.ref_u &&
         a.ref_t == b.ref_t && a.ref_twist == b.ref_twist && a.clamp_t == b.clamp_t &&
         a.clamp_d1 == b.clamp_d1 && a.end_t == b.end_t && a.end_u == b.end_u &&
         a.end_theta == b.end_theta;
}

// Constants of one solve: the convergence measure's weights, the tolerances and the scales.
struct Tolerances {
  VecX weights;          // ScaledGradientNorm = max_k weights_k |g_k|
  double strict = 0.0;   // [N] gradient tolerance: gradient_tolerance x the load scale
  double floor = 0.0;    // [N] the gradient's round-off floor (ResidualFloor)
  double stiffest = 0.0; // the rod's stiffest scale max(EA / l, B / l^3, GJ / l)
};

Tolerances MakeTolerances(const RodModel& model, const StaticsOptions& opt) {
  Tolerances t;
  t.weights = GradientNormWeights(model);
  t.strict = opt.gradient_tolerance * model.force_scale();
  t.floor = ResidualFloor(model, t.weights);
  const Material& m = model.material();
  const double l = model.min_rest_edge_length();
  t.stiffest = std::max({m.stretch_stiffness / l, std::max(m.B1(), m.B2()) / (l * l * l),
                         m.twist_stiffness / l});
  return t;
}

// Chord steps. A Newton step needs the Hessian at the current state; a chord step reuses the
// factor of a nearby basis state. Plain reuse fails on a suture: the stretch stiffness EA / l
// exceeds the bending stiffness EI / l^3 by ~1e7, and its stiff directions are the edges, which
// have turned since the basis state. A chord step that is 0.4 % off in those directions raises
// |g| a thousandfold instead of lowering it (measured on the benchmark suture). So the factor is
// carried along with the edges: with A the map from vertex to edge coordinates (e_j =
// x_{j+1} - x_j, x_0 clamped) and R the rotations turning each basis tangent into the current
// one (identity on the twists), the chord matrix is
//   H~ = A^T R A^-T H_b A^-1 R^T A,
// whose stretch directions follow the current edges; what is left of H - H~ is soft (bending,
// twist, tension), and the chord steps converge at a rate of the order of the relative change
// of those since the basis state (about the size of the last Newton step). Solving with H~ is
// the factor's solve wrapped in O(n) suffix sums, rotations and prefix sums. Returns false
// when a tangent has turned too far for the transport (> 60 degrees).
bool ChordStep(const LinearSolver& factor, int factor_size,
               const Eigen::Matrix3Xd& basis_tangents, const RodFrames& frames, const VecX& g,
               VecX* step) {
  const int n = static_cast<int>(basis_tangents.cols());
  if (static_cast<int>(frames.edges.size()) != n + 1 || factor_size <= 0) return false;
  for (int j = 0; j < n; ++j)
    if (!(basis_tangents.col(j).dot(frames.edges[j + 1].t) > 0.5)) return false;
  *step = g;
  VecX& s = *step;
  // A^-T (edge gradients: suffix sums over the vertices beyond each edge), then R^T, then A^T.
  Vec3 suffix = Vec3::Zero(), rotated_next = Vec3::Zero();
  for (int j = n - 1; j >= 0; --j) {
    suffix += g.segment<3>(RodModel::VertexDof(j + 1));
    const Vec3 rotated = ParallelTransport<double, double>(frames.edges[j + 1].t,
                                                           Vec3(basis_tangents.col(j)), suffix);
    s.segment<3>(RodModel::VertexDof(j + 1)) = rotated - rotated_next;
    rotated_next = rotated;
  }
  factor.Solve(&s);
  s = -s;
  // A (edge steps), R, then A^-1 (prefix sums from the clamp).
  Vec3 previous = Vec3::Zero(), position = Vec3::Zero();
  for (int j = 0; j < n; ++j) {
    const Vec3 current = s.segment<3>(RodModel::VertexDof(j + 1));
    position += ParallelTransport<double, double>(Vec3(basis_tangents.col(j)), frames.edges[j + 1].t,
                                                  Vec3(current - previous));
    previous = current;
    s.segment<3>(RodModel::VertexDof(j + 1)) = position;
  }
  return true;
}

// The largest distance [m] any vertex moved between two states.
double LargestMove(const RodState& a, const RodState& b) {
  return (a.x - b.x).colwise().norm().maxCoeff();
}

// The rod's total twist [rad]: the material frame's turn about the tangent from the clamp to the
// last edge (or the end clamp's ghost), summed vertex by vertex. Reference twists unwrap near
// their previous values, so a state reached by small steps keeps count of whole turns.
double TotalTwist(const RodModel& model, const RodState& s) {
  const int n = model.num_edges();
  const double last = model.has_end_ghost() ? s.end_theta : s.theta[n - 1];
  return last - s.theta[0] + s.ref_twist.sum();
}

/// How a Newton solve may start from the workspace's factor.
enum class StartFactor {
  kNone,   ///< no usable factor: assemble at the start
  kExact,  ///< the factor of the Hessian at *state for this model: first step reuses it
  kChord,  ///< a factor at *state for another model (a fit's parameter change): chord step
};

struct NewtonContext {
  const RodModel& model;
  const StaticsOptions& opt;
  const Tolerances& tol;
  /// The twist is eliminated (TwistCanBeEliminated and StaticsOptions::eliminate_twist): every
  /// state the solver makes has zero twist, and Newton's system is over the positions.
  bool eliminate_twist = false;
};

// The statics as a Newton problem (newton_minimizer.h): Pi at a load factor, or, for a case with
// moments, the balance's residual with its non-symmetric tangent. The linear solve is the
// workspace's: the banded Cholesky (over every free dof, or over the positions when the twist is
// eliminated), the banded LU of the tangent, or a fine rod's edge coordinates.
class StaticsProblem : public RodNewtonProblem {
 public:
  StaticsProblem(const NewtonContext& ctx, double load_scale, double moment_scale,
                 StaticsWorkspace* ws, bool use_edge, bool positions, StartFactor start)
      : RodNewtonProblem(ctx.model, ctx.opt.step_tolerance, ctx.model.length(), &ctx.tol.weights),
        ctx_(ctx),
        ws_(ws),
        moment_scale_(moment_scale),
        moments_(moment_scale > 0.0),
        use_edge_(use_edge),
        positions_(positions),
        reuse_(start == StartFactor::kExact),
        cholesky_(&ws->scratch_hessian, &ws->hessian, positions),
        lu_(&tangent_, &ws->tangent),
        edge_(&ws->edge, ctx.tol.stiffest) {
    terms_.load_scale = load_scale;
    set_zero_twist(positions);
  }

  void Evaluate(bool matrix, VecX* g) override {
    if (reuse_) {
      // The kept factor's state: Pi and its gradient without the dead loads were kept with it,
      // and Pi is linear in the dead loads: nothing is assembled.
      reuse_ = false;
      *g = ws_->factor_unloaded_gradient;
      AddDeadLoadGradient(model_, terms_.load_scale, /*hold=*/true, g);
      return;
    }
    const RodFrames& frames = CurrentFrames();
    if (moments_) {
      AssembleBalance(model_, current(), frames, terms_.load_scale, g,
                      matrix && !use_edge_ ? &tangent_ : nullptr, &ws_->scratch_hessian, true,
                      moment_scale_);
    } else if (!matrix || use_edge_) {
      AssembleGradient(model_, current(), terms_, g, &frames);
    } else if (positions_) {
      AssemblePositionHessian(model_, current(), terms_, g, &ws_->scratch_hessian, &frames);
    } else {
      AssembleHessian(model_, current(), terms_, g, &ws_->scratch_hessian, &frames);
    }
    if (matrix && use_edge_)
      edge_.At(&model_, &current(), &frames, &terms_, moments_ ? moment_scale_ : 0.0);
  }
  double Energy() override {
    if (kept_energy_) {
      kept_energy_ = false;
      return ws_->factor_unloaded_energy + DeadLoadEnergy(model_, current(), terms_.load_scale);
    }
    return PotentialEnergyFreshFrames(model_, current(), terms_, &CurrentFrames());
  }
  double TrialEnergy() override {
    return PotentialEnergyFreshFrames(model_, trial(), terms_, &TrialFrames());
  }
  void TrialResidual(VecX* g) override {
    if (moments_) {
      AssembleBalance(model_, trial(), TrialFrames(), terms_.load_scale, g, nullptr, nullptr,
                      true, moment_scale_);
    } else {
      AssembleGradient(model_, trial(), terms_, g, &TrialFrames());
    }
  }
  void AcceptTrial() override {
    kept_energy_ = false;
    RodNewtonProblem::AcceptTrial();
  }
  NewtonTolerances Tolerances() override { return {ctx_.tol.strict, ctx_.tol.floor}; }
  double ShiftBase() override {
    // With moments the tangent's first shift is also bounded by its diagonal.
    const double base = RodNewtonProblem::ShiftBase();
    return moments_ && !use_edge_ ? std::min(base, std::max(tangent_.MaxDiagonal(), 1e-300))
                                  : base;
  }
  LinearSolver& Solver() override {
    if (use_edge_) return edge_;
    if (moments_) return lu_;
    return cholesky_;
  }
  bool ChordStep(const VecX& g, VecX* step) override {
    const int size = ws_->factor_positions ? NumPositionDofs(model_) : model_.num_free_dofs();
    if (ws_->hessian.size() != size || ws_->factor_tangents.cols() != model_.num_edges())
      return false;
    const BandedCholeskySolver kept(&ws_->scratch_hessian, &ws_->hessian, ws_->factor_positions);
    return rodfit::ChordStep(kept, size, ws_->factor_tangents, CurrentFrames(), g, step);
  }
  void OnFactor(bool shifted) override {
    if (use_edge_) {
      ws_->edge_valid = !shifted;
      return;
    }
    if (moments_) return;
    // The new factor is the chord basis from here on, if it is the Hessian's own.
    const int n = model_.num_edges();
    const RodFrames& frames = CurrentFrames();
    ws_->factor_tangents.resize(3, n);
    for (int j = 0; j < n; ++j) ws_->factor_tangents.col(j) = frames.edges[j + 1].t;
    ws_->factor_positions = positions_;
  }
  /// The first energy asked for is the kept factor's (StartFactor::kExact).
  void UseKeptEnergy() { kept_energy_ = true; }

 private:
  const NewtonContext& ctx_;
  StaticsWorkspace* ws_;
  EnergyTerms terms_;
  double moment_scale_;
  bool moments_;
  bool use_edge_, positions_;
  bool reuse_ = false, kept_energy_ = false;
  BandedMatrix tangent_;
  BandedCholeskySolver cholesky_;
  BandedLUSolver lu_;
  EdgeCoordinateSolver edge_;
};

/// Newton at one load factor (and, for a case with moments, one moment factor > 0; 0: the
/// potential alone) from *state, on the one minimizer. Returns kConverged with *state at
/// equilibrium, the workspace's factor kept there when it is the Hessian's (or the tangent's)
/// own. With StartFactor::kExact, ws->hessian already holds the factor of the (unshifted)
/// Hessian at *state for this model and load, and ws the energy and gradient there without dead
/// loads, so the first iteration assembles nothing.
StepResult NewtonSolve(const NewtonContext& ctx, double load_scale, double moment_scale,
                       int max_iterations, RodState* state, StaticsWorkspace* ws,
                       StaticsSummary* summary, std::string* why, StartFactor start) {
  const RodModel& model = ctx.model;
  const StaticsOptions& opt = ctx.opt;
  const int n = model.num_edges();
  const bool moments = moment_scale > 0.0;
  // A fine rod's steps come from the edge-coordinate factor (edge_solver.h).
  const bool use_edge = n >= opt.edge_solver_segments && EdgeSolver::Applies(model);
  // Twist eliminated: Newton's system is over the positions (AssemblePositionHessian), every
  // state has zero twist (on a converged state SetZeroTwist changes nothing, so the kept
  // factor's state is unchanged). The edge-coordinate path keeps the twist.
  const bool positions = ctx.eliminate_twist && !use_edge && !moments;
  if (positions) SetZeroTwist(model, state);
  summary->twist_eliminated = positions;
  StaticsProblem problem(ctx, load_scale, moment_scale, ws, use_edge, positions,
                         moments ? StartFactor::kNone : start);
  std::swap(problem.current(), *state);  // no copy: the state is the problem's while it runs
  problem.CurrentChanged();
  NewtonOptions o;
  o.max_iterations = max_iterations;
  o.factor_at_solution = FactorAtSolution::kAlways;
  NewtonStart begin;
  if (moments) {
    o.merit = Merit::kResidual;
  } else {
    o.stagnation = true;
    o.saddles = use_edge ? Saddles::kClassify
                         : (opt.escape_saddles ? Saddles::kEscape : Saddles::kClassify);
    // Chord steps carry the vertex factor along the edges; held points (Dirichlet rows) keep to
    // Newton.
    const bool chords_allowed =
        opt.chord_steps && model.held().empty() && !model.has_end_ghost() && !use_edge;
    if (chords_allowed) o.chords = ChordPolicy::kWhenFinishing;
    begin.factor_current = start == StartFactor::kExact;
    begin.factor_nearby = start == StartFactor::kChord && chords_allowed;
    if (begin.factor_current) problem.UseKeptEnergy();
  }
  NewtonMinimizer minimizer(o);
  const NewtonSummary r = minimizer.Minimize(&problem, begin);
  std::swap(*state, problem.current());
  summary->iterations += r.iterations;
  summary->chord_steps += r.chord_steps;
  summary->saddle_escapes += r.saddle_escapes;
  summary->gradient_norm = r.residual_norm;
  if (!moments) summary->energy = r.energy;
  if (!r.converged()) {
    *why = r.termination == Termination::kNonFinite ? "non-finite energy, gradient or Hessian"
                                                    : r.message();
    return r.termination == Termination::kIterationCap ? StepResult::kIterationCap
                                                       : StepResult::kFailed;
  }
  if (r.termination == Termination::kRoundOff) summary->reason_detail = "stagnated at round-off";
  if (moments) {
    summary->energy = PotentialEnergy(model, *state, EnergyTerms());
    // Stable when the symmetric part of the tangent is positive definite (all eigenvalues of
    // the tangent then have positive real parts), on the held points' constraint space.
    if (use_edge) {
      summary->stable = !r.shifted && ws->edge.positive_definite();
    } else {
      RodFrames frames;
      ComputeRodFrames(model, *state, &frames);
      VecX g;
      BandedMatrix J;
      BandedSymmetric H;
      AssembleBalance(model, *state, frames, load_scale, &g, &J, &H, true, moment_scale);
      BandedCholesky sym;
      summary->stable = !r.shifted && sym.Factor(J.SymmetricPart(1));
    }
    ws->tangent_valid = r.factor_at_solution && !use_edge;
    return StepResult::kConverged;
  }
  summary->stable = r.stable;
  ws->factor_valid = r.factor_at_solution && !use_edge;
  // Pi and its gradient without the dead loads, kept with the factor.
  ws->factor_unloaded_energy = r.energy - DeadLoadEnergy(model, *state, load_scale);
  ws->factor_unloaded_gradient = minimizer.residual();
  AddDeadLoadGradient(model, -load_scale, /*hold=*/true, &ws->factor_unloaded_gradient);
  return StepResult::kConverged;
}

StepResult NewtonAtLoad(const NewtonContext& ctx, double load_scale, int max_iterations,
                        RodState* state, StaticsWorkspace* ws, StaticsSummary* summary,
                        std::string* why, StartFactor start) {
  return NewtonSolve(ctx, load_scale, 0.0, max_iterations, state, ws, summary, why, start);
}

StepResult NewtonNonconservative(const NewtonContext& ctx, double load_scale, double moment_scale,
                                 int max_iterations, RodState* state, StaticsWorkspace* ws,
                                 StaticsSummary* summary, std::string* why) {
  return NewtonSolve(ctx, load_scale, moment_scale, max_iterations, state, ws, summary, why,
                     StartFactor::kNone);
}

StepResult NewtonAny(const NewtonContext& ctx, double load_scale, int max_iterations,
                     RodState* state, StaticsWorkspace* ws, StaticsSummary* summary,
                     std::string* why, StartFactor start) {
  if (!ctx.model.nonconservative())
    return NewtonAtLoad(ctx, load_scale, max_iterations, state, ws, summary, why, start);
  // With moments the balance has no potential to descend, and Newton on the residual may land
  // on any equilibrium. A warm start near the solution (a fit's or a haptic loop's re-solve)
  // converges straight there: taken when it stays close (0.05 L) and is stable. Otherwise the
  // moments are ramped up from the equilibrium without them (found on the potential, with its
  // line search and saddle escapes), so the solution is the one the loading path reaches.
  const RodState initial = *state;
  const StaticsSummary before = *summary;
  const double L = ctx.model.length();
  StepResult r = NewtonNonconservative(ctx, load_scale, 1.0, std::min(max_iterations, 12), state,
                                       ws, summary, why);
  if (r == StepResult::kConverged && summary->stable && LargestMove(initial, *state) <= 0.05 * L)
    return r;
  const int used = summary->iterations - before.iterations;
  *state = initial;
  *summary = before;
  summary->iterations += used;
  r = NewtonAtLoad(ctx, load_scale, max_iterations, state, ws, summary, why, StartFactor::kNone);
  if (r != StepResult::kConverged) {
    *why = "without its moments: " + *why;
    return r;
  }
  ws->factor_valid = false;
  double done = 0.0, step = 0.25;
  for (int k = 0; k < 400 && done < 1.0; ++k) {
    const double target = std::min(1.0, done + step);
    RodState trial = *state;
    r = NewtonNonconservative(ctx, load_scale, target, 40, &trial, ws, summary, why);
    if (r == StepResult::kConverged) {
      *state = trial;
      done = target;
      step = std::min(2.0 * step, 0.5);
    } else {
      step *= 0.5;
      if (step < 1e-4) break;
    }
    if (summary->iterations - before.iterations >= 10 * max_iterations) break;
  }
  if (done < 1.0) {
    *why = "the moments could not be ramped up to their full value (" + *why + ")";
    return StepResult::kFailed;
  }
  return StepResult::kConverged;
}

/// Full load first; on failure, load continuation from the unloaded equilibrium.
StepResult SolveAtBoundary(const NewtonContext& ctx, RodState* state, StaticsWorkspace* ws,
                           StaticsSummary* summary, std::string* why, StartFactor start,
                           int* budget_used) {
  const StaticsOptions& opt = ctx.opt;
  const RodState initial = *state;
  const int first_iterations = summary->iterations;
  auto budget = [&]() { return opt.max_iterations - (summary->iterations - first_iterations) - *budget_used; };
  StepResult r = NewtonAny(ctx, 1.0, std::max(1, budget()), state, ws, summary, why, start);
  if (r == StepResult::kConverged) return r;
  *state = initial;
  int load_steps = 0;
  double done = 0.0, increment = 0.25;
  bool have_base = false;
  while (load_steps < opt.max_load_steps) {
    if (budget() <= 0) break;
    const double target = have_base ? std::min(1.0, done + increment) : 0.0;
    RodState saved = *state;
    const int per_step = std::min(budget(), 50);
    r = NewtonAny(ctx, target, per_step, state, ws, summary, why, StartFactor::kNone);
    ++load_steps;
    summary->load_steps = load_steps;
    if (r == StepResult::kConverged) {
      if (!have_base) {
        have_base = true;
        continue;
      }
      done = target;
      if (done >= 1.0) return r;
      increment = std::min(0.5, increment * 1.5);
    } else {
      *state = saved;
      if (!have_base) break;  // cannot even find the unloaded equilibrium
      increment *= 0.25;
      if (increment < 1e-6) break;
    }
  }
  if (summary->iterations - first_iterations >= opt.max_iterations) *why += " (iteration cap)";
  return StepResult::kFailed;
}

// The held boundary: the clamp's position and frame, the held vertices' positions and the end
// clamp's frame (d3, d1; for a free-turning end only d3 matters).
struct Boundary {
  Vec3 clamp_p;
  Vec3 plane_point = Vec3::Zero();  // a symmetric half's plane (its normal is end_R's d3)
  Eigen::Matrix3d clamp_R;  // [d1 d2 d3]
  std::vector<Vec3> held;
  Eigen::Matrix3d end_R = Eigen::Matrix3d::Identity();
};

Eigen::Matrix3d FrameOf(const Vec3& d1, const Vec3& d3) {
  Eigen::Matrix3d R;
  R << d1, d3.cross(d1), d3;
  return R;
}

Boundary StateBoundary(const RodModel& model, const RodState& s) {
  Boundary b;
  b.clamp_p = s.x.col(0);
  b.plane_point = s.plane_point;
  b.clamp_R = FrameOf(s.clamp_d1, s.clamp_t);
  for (const HeldVertex& h : model.held()) b.held.push_back(s.x.col(h.vertex));
  if (model.has_end_ghost()) {
    const Vec3 d1 = std::cos(s.end_theta) * s.end_u + std::sin(s.end_theta) * s.end_t.cross(s.end_u);
    b.end_R = FrameOf(d1, s.end_t);
  }
  return b;
}

Boundary TargetBoundary(const RodModel& model, const RodState& s) {
  Boundary b;
  b.clamp_p = model.clamp_position();
  if (model.symmetric()) {
    // The point of the case's plane nearest to the state's plane point: the plane moves the
    // least.
    const Vec3& n = model.symmetry_normal();
    b.plane_point = s.plane_point - (s.plane_point - model.symmetry_point()).dot(n) * n;
  }
  b.clamp_R = FrameOf(model.clamp_d1(), model.clamp_tangent());
  for (const HeldVertex& h : model.held()) b.held.push_back(h.target);
  if (model.has_end_ghost()) {
    if (model.end_twist_held()) {
      b.end_R = FrameOf(model.end_d1(), model.end_tangent());
    } else {
      // Only the tangent is held: turn the state's end frame by the smallest rotation.
      const Boundary now = StateBoundary(model, s);
      const Eigen::Matrix3d turn =
          Eigen::Quaterniond::FromTwoVectors(Vec3(now.end_R.col(2)), model.end_tangent())
              .toRotationMatrix();
      b.end_R = turn * now.end_R;
    }
  }
  return b;
}

double RotationAngle(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(B * A.transpose()).angle();
}

// A = the largest move [m] and B = the largest turn [rad] between two boundaries.
void BoundaryDistance(const Boundary& a, const Boundary& b, double* move, double* turn) {
  *move = std::max((a.clamp_p - b.clamp_p).norm(), (a.plane_point - b.plane_point).norm());
  for (size_t k = 0; k < a.held.size(); ++k) *move = std::max(*move, (a.held[k] - b.held[k]).norm());
  *turn = std::max(RotationAngle(a.clamp_R, b.clamp_R), RotationAngle(a.end_R, b.end_R));
}

Eigen::Matrix3d Slerp(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B, double t) {
  const Eigen::Quaterniond qa(A), qb(B);
  return qa.slerp(t, qb).toRotationMatrix();
}

/// Moves *state's boundary from `from` to the interpolation of from -> to at t: the clamp's
/// motion moves the whole rod rigidly, and each held vertex's displacement is spread linearly
/// in arc length over the free vertices since the previous held point (the rod beyond the last
/// one moves with it). Reference frames are transported in time.
/// A held point moved towards its neighbour anchor shortens the chord of the rod between them.
/// Spread along that rod as a displacement, the shortening would compress every edge, and a
/// compressed straight rod is a saddle with many falling directions: Newton then creeps along
/// heavily shifted steps. The rod takes the shortening by bending out of its chord, so the trial
/// is given that bend: the vertices strictly between anchors v0 and v1 move by a * phi(s) * d,
/// phi = sin^2(pi (s - s0) / (s1 - s0)) (zero, with zero slope, at both anchors: the clamped
/// buckling mode), with a >= 0 such that the edges between the anchors regain their rest length.
/// d is the way the rod already bows off its chord, else gravity's part across the chord, else
/// `clamp_d1` across it (zero when saddles are not to be escaped: an unloaded straight column
/// then stays the straight saddle it is).
void BowToRestLength(const RodModel& model, int v0, int v1, const Vec3& clamp_d1,
                     const Vec3* plane_normal, RodState* state) {
  if (v1 - v0 < 2) return;
  // At a symmetric half's plane (v1 = n, free in the plane) the bow is a quarter wave,
  // sin^2(pi/2 (s - s0) / (s1 - s0)): the end keeps its tangent along the plane's normal and
  // moves in the plane.
  const double period = plane_normal ? 0.5 * M_PI : M_PI;
  const int last_moved = plane_normal ? v1 : v1 - 1;
  double rest = 0.0;
  for (int j = v0; j < v1; ++j) rest += model.rest_edge_length(j);
  auto length_at = [&](double a, const Vec3& d) {
    double total = 0.0;
    const double s0 = model.arc_length(v0), s1 = model.arc_length(v1);
    Vec3 prev = state->x.col(v0);
    for (int i = v0 + 1; i <= v1; ++i) {
      const double phase = period * (model.arc_length(i) - s0) / (s1 - s0);
      const Vec3 now = state->x.col(i) + a * std::pow(std::sin(phase), 2) * d;
      total += (now - prev).norm();
      prev = now;
    }
    return total;
  };
  const double now = length_at(0.0, Vec3::Zero());
  if (!(now < (1.0 - 1e-6) * rest)) return;
  const Vec3 chord = state->x.col(v1) - state->x.col(v0);
  const double chord_len = chord.norm();
  if (!(chord_len > 0.0)) return;
  const Vec3 c = chord / chord_len;
  auto across = [&](const Vec3& v) { return Vec3(v - v.dot(c) * c); };
  Vec3 bow = Vec3::Zero();
  for (int i = v0 + 1; i < v1; ++i) bow += across(state->x.col(i) - state->x.col(v0));
  Vec3 d;
  const double scale = rest;
  if (bow.norm() / (v1 - v0 - 1) > 1e-3 * scale) {
    d = bow.normalized();
  } else if (across(model.gravity()).norm() > 1e-3 * model.gravity().norm() &&
             model.gravity().norm() > 0.0) {
    d = across(model.gravity()).normalized();
  } else if (across(clamp_d1).norm() > 1e-3) {
    d = across(clamp_d1).normalized();
  } else {
    return;
  }
  // Bisection on a in [0, hi]: the bowed length grows without bound in a.
  double lo = 0.0, hi = 0.1 * rest;
  for (int k = 0; k < 60 && length_at(hi, d) < rest; ++k) hi *= 2.0;
  if (!(length_at(hi, d) >= rest)) return;
  for (int k = 0; k < 60; ++k) {
    const double mid = 0.5 * (lo + hi);
    (length_at(mid, d) < rest ? lo : hi) = mid;
  }
  const double s0 = model.arc_length(v0), s1 = model.arc_length(v1);
  for (int i = v0 + 1; i <= last_moved; ++i) {
    const double phase = period * (model.arc_length(i) - s0) / (s1 - s0);
    state->x.col(i) += hi * std::pow(std::sin(phase), 2) * d;
  }
  // The bow restores the total length, not each edge's: edges near the anchors stay short and
  // those mid-way grow. Each edge is given its rest length along its own direction, and the
  // anchor missed by that is closed by turning the edges, each by its compliance (as ApplyStep
  // closes a held vertex), which changes lengths only to second order; a few rounds.
  const Material& m = model.material();
  const double B = std::min(m.B1(), m.B2()), EA = m.stretch_stiffness;
  const Vec3 anchor = state->x.col(v1);
  for (int round = 0; round < 4; ++round) {
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    Vec3 end = state->x.col(v0);
    std::vector<Vec3> edges(v1 - v0);
    for (int j = v0; j < v1; ++j) {
      const Vec3 e = state->x.col(j + 1) - state->x.col(j);
      if (!(e.norm() > 0.0)) return;
      const Vec3 t = e.normalized();
      edges[j - v0] = model.rest_edge_length(j) * t;
      end += edges[j - v0];
      const double lj = model.rest_edge_length(j);
      const double r = std::min(1.0, B / (EA * lj * lj));
      sum += Eigen::Matrix3d::Identity() - (1.0 - r) * t * t.transpose();
    }
    const Vec3 gap = end - anchor;
    const Vec3 w = plane_normal
                       ? Vec3((plane_normal->dot(gap) / plane_normal->dot(sum * *plane_normal)) *
                              *plane_normal)
                       : Vec3(sum.ldlt().solve(gap));
    if (!w.allFinite()) return;
    for (int j = v0; j < v1; ++j) {
      const Vec3 t = edges[j - v0].normalized();
      const double lj = model.rest_edge_length(j);
      const double r = std::min(1.0, B / (EA * lj * lj));
      edges[j - v0] -= w - (1.0 - r) * t * t.dot(w);
      state->x.col(j + 1) = state->x.col(j) + edges[j - v0];
    }
  }
  if (!plane_normal) state->x.col(v1) = anchor;
}

bool MoveBoundary(const RodModel& model, const Boundary& from, const Boundary& to, double t,
                  bool bow_unloaded, RodState* state) {
  const int n = model.num_edges();
  const RodState before = *state;
  const Vec3 p = (1 - t) * from.clamp_p + t * to.clamp_p;
  const Eigen::Matrix3d R = Slerp(from.clamp_R, to.clamp_R, t);
  const Eigen::Matrix3d rigid = R * from.clamp_R.transpose();
  const Vec3 p_now = state->x.col(0);
  for (int i = 0; i <= n; ++i) state->x.col(i) = p + rigid * (state->x.col(i) - p_now);
  state->clamp_t = R.col(2);
  state->clamp_d1 = R.col(0);
  // Held vertices: displacement spread by arc length since the previous anchor.
  int prev_vertex = 0;
  Vec3 prev_disp = Vec3::Zero();
  const auto& held = model.held();
  for (size_t k = 0; k < held.size(); ++k) {
    const int v = held[k].vertex;
    const Vec3 target = (1 - t) * from.held[k] + t * to.held[k];
    const Vec3 disp = target - state->x.col(v);
    const double s0 = model.arc_length(prev_vertex), s1 = model.arc_length(v);
    for (int i = prev_vertex + 1; i <= v; ++i) {
      const double a = (model.arc_length(i) - s0) / (s1 - s0);
      state->x.col(i) += (1 - a) * prev_disp + a * disp;
    }
    state->x.col(v) = target;
    prev_vertex = v;
    prev_disp = disp;
  }
  for (int i = prev_vertex + 1; i <= n; ++i) state->x.col(i) += prev_disp;
  {
    int v0 = 0;
    for (const HeldVertex& h : held) {
      BowToRestLength(model, v0, h.vertex, bow_unloaded ? Vec3(R.col(0)) : Vec3(Vec3::Zero()), nullptr, state);
      v0 = h.vertex;
    }
  }
  state->SyncEdges();
  const Eigen::Matrix3d E = Slerp(from.end_R, to.end_R, t);
  if (model.symmetric()) {
    // A symmetric half's last vertex follows its plane, half a crossing edge before it (the
    // crossing edge unstrained), the displacement spread over the half like a held point's.
    state->plane_point = (1 - t) * from.plane_point + t * to.plane_point;
    const Vec3 normal = E.col(2);
    const double d = (state->plane_point - state->x.col(n)).dot(normal);
    const Vec3 disp = (d - 0.5 * model.crossing_length()) * normal;
    const double s0 = model.arc_length(prev_vertex), s1 = model.arc_length(n);
    for (int i = prev_vertex + 1; i <= n; ++i)
      state->x.col(i) += ((model.arc_length(i) - s0) / (s1 - s0)) * disp;
    BowToRestLength(model, prev_vertex, n, bow_unloaded ? Vec3(R.col(0)) : Vec3(Vec3::Zero()), &normal, state);
    state->SyncEdges();
  }
  if (model.has_end_ghost()) {
    // The ghost's reference director is transported in time; its twist angle keeps the frame.
    const Vec3 t_new = E.col(2);
    Vec3 u = ParallelTransport<double, double>(state->end_t, t_new, state->end_u);
    u = (u - u.dot(t_new) * t_new).normalized();
    state->end_t = t_new;
    state->end_u = u;
    state->end_theta = SignedAngle<double>(u, Vec3(E.col(0)), t_new);
  }
  // The reference frames follow the rigid motion, then the edges' own turns.
  RodState rotated = before;
  for (int j = 0; j < n; ++j) {
    rotated.ref_t.col(j) = rigid * before.ref_t.col(j);
    rotated.ref_u.col(j) = rigid * before.ref_u.col(j);
  }
  return UpdateReferenceFrames(model, rotated, state);
}

/// Makes a state from an older layout usable (edges, end frames, twist sizes).
void PrepareState(const RodModel& model, RodState* s) {
  const int n = model.num_edges();
  if (s->e.cols() != n) s->SyncEdges();
  if (s->ref_twist.size() != n + 1) {
    const VecX old = s->ref_twist;
    s->ref_twist.setZero(n + 1);
    s->ref_twist.head(std::min<int>(n, old.size())) = old.head(std::min<int>(n, old.size()));
  }
  if (model.has_end_ghost() && s->end_t.squaredNorm() == 0.0) {
    s->end_t = s->ref_t.col(n - 1);
    s->end_u = s->ref_u.col(n - 1);
    s->end_theta = s->theta[n - 1];
    if (model.symmetric()) s->plane_point = s->x.col(n) + 0.5 * model.crossing_length() * s->end_t;
    UpdateReferenceFrames(model, *s, s);
  }
}

// Why the statics cannot start from this state with these options ("" when they can).
std::string InvalidStart(const RodModel& model, const StaticsOptions& options,
                         const RodState& state) {
  std::string why;
  if (!options.Check(&why)) return "invalid options: " + why;
  if (state.num_edges() != model.num_edges() || state.x.cols() != model.num_vertices())
    return "state does not match the model's segment count";
  if (!state.x.allFinite() || !state.theta.allFinite())
    return "the start state has non-finite values";
  return "";
}

// Whether a step solved at next (of the continuation from *state, whose boundary is now)
// jumped to another equilibrium: vertices moving much more than the boundary, or the twist
// changing by more than a quarter turn beyond the ends' own turn.
bool Jumped(const RodModel& model, const Boundary& now, const RodState& state,
            const RodState& next) {
  double step_move = 0.0, step_turn = 0.0;
  BoundaryDistance(now, StateBoundary(model, next), &step_move, &step_turn);
  // A rod whose held points close in bows out by ~ sqrt(shortening x length) (the
  // length it must put somewhere): that is the rod's own response, not a jump.
  const double allowed_move = 4.0 * (step_move + step_turn * model.length()) +
                              2.0 * std::sqrt(step_move * model.length()) +
                              0.01 * model.length();
  const double twist_change = std::abs(TotalTwist(model, next) - TotalTwist(model, state));
  return LargestMove(state, next) > allowed_move || twist_change > 0.5 * M_PI + 2.0 * step_turn;
}

// Continuation of the held boundary from the state's to target (move [m] and turn [rad] apart):
// "" when the held points reached it, else why not. The summary counts the steps and iterations.
std::string MoveHeldPoints(const NewtonContext& ctx, const Boundary& target, double move,
                           double turn, RodState* state, StaticsWorkspace* ws,
                           StaticsSummary* summary_out) {
  const RodModel& model = ctx.model;
  const StaticsOptions& options = ctx.opt;
  StaticsSummary& summary = *summary_out;
  std::string why;
  int budget_used = 0;
  // The loading path starts from the equilibrium at the start's own held points (a straight
  // rod sags under its loads before its end is moved): moving the held points then deforms a
  // loaded rod gradually, and a compressed rod bends the way its loads already bend it instead
  // of buckling from a perfectly straight state in an arbitrary direction.
  // While held points move, the states are far from equilibrium and often indefinite, where
  // the vertex factor's lost soft modes cost many shifted steps and saddle searches long
  // before 20,000 segments (a wire between two clamps at 10,000 segments: 12 s against 2 s in
  // edge coordinates); from kEdgeContinuationSegments the continuation runs in edge
  // coordinates.
  StaticsOptions moving_options = options;
  moving_options.edge_solver_segments =
      std::min(options.edge_solver_segments, kEdgeContinuationSegments);
  const NewtonContext moving{model, moving_options, ctx.tol, ctx.eliminate_twist};
  {
    RodState at_start = *state;
    StaticsSummary attempt = summary;
    if (SolveAtBoundary(moving, &at_start, ws, &attempt, &why, StartFactor::kNone, &budget_used) ==
        StepResult::kConverged) {
      *state = at_start;
      summary.iterations = attempt.iterations;
    }
  }
  double done = 0.0;
  const int planned = static_cast<int>(std::ceil(std::max(
      move / (options.continuation_move * model.length()), turn / options.continuation_turn)));
  // Steps grow back to the planned size, never beyond it: a large step lets Newton land on
  // another equilibrium (a loop flipped, a whole extra turn of twist), and which one could
  // then hinge on round-off. A step whose solution jumps is retried at half the size, until the
  // step is so small that the jump is the rod's own (a snap at a limit point).
  const double planned_step = 1.0 / std::max(1, planned);
  const double smallest_jump_step = planned_step / 64.0;
  double step = planned_step;
  while (done < 1.0) {
    if (summary.continuation_steps >= options.max_continuation_steps)
      return "the held points did not reach their targets within " +
             std::to_string(options.max_continuation_steps) + " continuation steps";
    const double next = std::min(1.0, done + step);
    RodState trial = *state;
    // Interpolate from the start boundary: the boundary at `done` is the state's own.
    const Boundary now = StateBoundary(model, *state);
    const double t_rel = (next - done) / (1.0 - done);
    bool ok = MoveBoundary(model, now, target, t_rel, options.escape_saddles, &trial);
    StepResult r = StepResult::kFailed;
    StaticsSummary attempt = summary;
    if (ok) r = SolveAtBoundary(moving, &trial, ws, &attempt, &why, StartFactor::kNone, &budget_used);
    ++summary.continuation_steps;
    if (r == StepResult::kConverged && step > smallest_jump_step &&
        Jumped(model, now, *state, trial)) {
      r = StepResult::kFailed;
      why = "the equilibrium jumped";
    }
    if (r == StepResult::kConverged) {
      attempt.continuation_steps = summary.continuation_steps;
      summary = attempt;
      *state = trial;
      done = next;
      step = std::min(2.0 * step, planned_step);
    } else {
      summary.iterations = attempt.iterations;
      step *= 0.5;
      if (step < 1e-5)
        return "the held points could not be moved to their targets (continuation "
               "stalled at " + std::to_string(static_cast<int>(100 * done)) +
               " %: " + why + ")";
    }
    if (summary.iterations >= options.max_iterations * 20)
      return "iteration cap reached while moving the held points to their targets";
  }
  return "";
}

}  // namespace

void BalanceResidual(const RodModel& model, const RodState& state, VecX* residual) {
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  AssembleBalance(model, state, frames, 1.0, residual, nullptr, nullptr);
}

// The choice of path (the held points moved by continuation, or solved where they are from the
// kept factor when it is this state's), then the summary and the workspace's kept factor.
StaticsSummary SolveStatics(const RodModel& model, const StaticsOptions& options, RodState* state,
                            StaticsWorkspace* workspace) {
  StaticsSummary summary;
  summary.nonconservative = model.nonconservative();
  if (std::string invalid = InvalidStart(model, options, *state); !invalid.empty()) {
    summary.reason = std::move(invalid);
    return summary;
  }
  PrepareState(model, state);
  StaticsWorkspace local;
  StaticsWorkspace* ws = workspace ? workspace : &local;
  const Tolerances tol = MakeTolerances(model, options);
  const bool eliminate = options.eliminate_twist && TwistCanBeEliminated(model);
  const NewtonContext ctx{model, options, tol, eliminate};
  // The kept factor belongs to factor_state: from exactly that state it is the Hessian there
  // (same digest) or a chord basis (a model with other stiffnesses).
  StartFactor start_factor = StartFactor::kNone;
  const bool fine = model.num_edges() >= options.edge_solver_segments;
  if (!fine && ws->factor_valid && !model.nonconservative() &&
      ws->factor_positions == eliminate && SameState(ws->factor_state, *state))
    start_factor = (ws->factor_digest == model.hessian_digest()) ? StartFactor::kExact
                                                                 : StartFactor::kChord;
  ws->factor_valid = false;
  ws->tangent_valid = false;
  ws->edge_valid = false;
  auto converged = [&](const char* reason) {
    summary.converged = true;
    summary.reason = reason;
    if (!summary.reason_detail.empty()) summary.reason += " (" + summary.reason_detail + ")";
    if (ws->factor_valid) {
      ws->factor_state = *state;
      ws->factor_digest = model.hessian_digest();
    }
    return summary;
  };
  auto failed = [&](const std::string& reason) {
    summary.converged = false;
    summary.reason = reason;
    ws->factor_valid = false;
    ws->tangent_valid = false;
    ws->edge_valid = false;
    return summary;
  };

  const Boundary start = StateBoundary(model, *state), target = TargetBoundary(model, *state);
  double move = 0.0, turn = 0.0;
  BoundaryDistance(start, target, &move, &turn);
  if (move > 1e-12 * model.length() || turn > 1e-12) {
    const std::string why = MoveHeldPoints(ctx, target, move, turn, state, ws, &summary);
    if (!why.empty()) return failed(why);
    return converged("converged after continuation of the held points");
  }

  std::string why;
  int budget_used = 0;
  const StepResult r = SolveAtBoundary(ctx, state, ws, &summary, &why, start_factor, &budget_used);
  if (r == StepResult::kConverged)
    return converged(summary.load_steps > 1 ? "converged (load continuation)" : "converged");
  return failed("no equilibrium found: " + why);
}

}  // namespace rodfit
