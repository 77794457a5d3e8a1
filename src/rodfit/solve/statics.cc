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
#include "rodfit/solve/moment_loads.h"
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
  if (max_line_search_steps < 1) return fail("max_line_search_steps must be >= 1");
  if (!(armijo > 0 && armijo < 0.5)) return fail("armijo must lie in (0, 0.5)");
  if (max_load_steps < 1) return fail("max_load_steps must be >= 1");
  if (!(max_rotation_per_step > 0 && max_rotation_per_step < 3)) {
    return fail("max_rotation_per_step must lie in (0, 3) rad");
  }
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

// Constants of one solve: the convergence measure's weights and tolerances.
struct Tolerances {
  VecX weights;          // ScaledGradientNorm = max_k weights_k |g_k|
  double strict = 0.0;   // [N] gradient tolerance: gradient_tolerance x the load scale
  double force = 0.0;    // [N] the larger of `strict` and the gradient's round-off floor
  double step_x = 0.0;   // [m] Newton step tolerance on positions
  double step_theta = 0.0;
  double shift_base = 0.0;  // first diagonal shift for an indefinite Hessian
  double shift_cap = 0.0;   // beyond this the Hessian is taken as hopeless

  double Norm(const VecX& g) const {
    double worst = 0.0;
    for (int k = 0; k < g.size(); ++k) {
      const double v = weights[k] * std::abs(g[k]);
      if (!(v <= worst)) worst = v;  // a NaN propagates
    }
    return worst;
  }
  /// The largest position and angle entries of `step` (held dofs skipped). One pass with the
  /// two maxima in registers: selecting the maximum to update through a reference made each
  /// entry wait on the store before it (a visible part of a warm re-solve).
  struct StepSize {
    double x = 0.0;      // [m]
    double theta = 0.0;  // [rad]
  };
  StepSize Size(const VecX& step) const {
    StepSize s;
    const int m = static_cast<int>(step.size());
    for (int k = 0; k < m; ++k) {
      const double v = weights[k] == 0.0 ? 0.0 : std::abs(step[k]);
      if (k % 4 == 3) {
        s.theta = std::max(s.theta, v);
      } else {
        s.x = std::max(s.x, v);
      }
    }
    return s;
  }
  bool SmallStep(const StepSize& s, double factor = 1.0) const {
    return s.x <= factor * step_x && s.theta <= factor * step_theta;
  }
  bool SmallStep(const VecX& step, double factor = 1.0) const {
    return SmallStep(Size(step), factor);
  }
  /// Convergence at a state with gradient norm `gnorm` and unshifted Newton step `step`: the
  /// gradient below the load tolerance; or the step below the step tolerance (1e-9 L: the state
  /// is as exact as the iteration can tell); or the gradient at its round-off floor with a step
  /// below 1e3 times the step tolerance (1e-6 L by default: a stiff stretch's floor may sit above
  /// the load tolerance, and the step then tells how far the state still is).
  /// A small step counts only with a gradient near its floor (within 1e3): a factor that lost
  /// the soft modes to round-off gives small steps far from the solution.
  bool Converged(double gnorm, const VecX& step) const {
    if (gnorm <= strict) return true;
    if (!(gnorm <= 1e3 * force)) return false;
    const StepSize s = Size(step);
    return SmallStep(s) || (gnorm <= force && SmallStep(s, 1e3));
  }
};

Tolerances MakeTolerances(const RodModel& model, const StaticsOptions& opt) {
  Tolerances t;
  t.weights = GradientNormWeights(model);
  t.strict = opt.gradient_tolerance * model.force_scale();
  // The gradient's round-off: the stretch forces are EA (|e| / l - 1), with |e| known to ~eps
  // (the edges are the state's primary record), so each carries ~eps EA; a vertex sums two and
  // the scaled norm multiplies by up to L / l.
  const double max_weight = t.weights.size() ? t.weights.maxCoeff() : 1.0;
  const double floor = 64.0 * std::numeric_limits<double>::epsilon() *
                       model.material().stretch_stiffness * max_weight;
  t.force = std::max(t.strict, floor);
  const Material& m = model.material();
  const double l = model.min_rest_edge_length();
  t.shift_base = 1e-6 * std::min({m.B1(), m.B2(), m.twist_stiffness}) / (l * l * l);
  t.shift_cap = 1e6 * std::max({m.stretch_stiffness / l, std::max(m.B1(), m.B2()) / (l * l * l),
                                m.twist_stiffness / l});
  t.step_x = opt.step_tolerance * model.length();
  t.step_theta = opt.step_tolerance;
  return t;
}

double EnergyNoise(const RodModel& model, double energy) {
  return 1e-13 * (std::abs(energy) + model.force_scale() * model.length());
}

// Solves H s = b in place with the kept factor: over every free dof, or over the positions
// only when the twist is eliminated (the twist rows of s come back zero; SetZeroTwist makes
// the twist angles follow the step).
void SolveWithFactor(const BandedCholesky& factor, bool positions, VecX* s) {
  if (!positions) {
    factor.SolveInPlace(*s);
    return;
  }
  VecX p;
  GatherPositions(*s, &p);
  factor.SolveInPlace(p);
  ScatterPositions(p, s);
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
bool ChordStep(const BandedCholesky& factor, bool positions, const Eigen::Matrix3Xd& basis_tangents,
               const RodFrames& frames, const VecX& g, VecX* step) {
  const int n = static_cast<int>(basis_tangents.cols());
  const int factor_size = positions ? 3 * (static_cast<int>(g.size()) / 4) : static_cast<int>(g.size());
  if (static_cast<int>(frames.edges.size()) != n + 1 || factor.size() != factor_size) return false;
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
  SolveWithFactor(factor, positions, &s);
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

void KeepTangents(const RodFrames& frames, int n, Eigen::Matrix3Xd* tangents) {
  tangents->resize(3, n);
  for (int j = 0; j < n; ++j) tangents->col(j) = frames.edges[j + 1].t;
}

constexpr double kMaxStrainStep = 0.1;

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


/// How NewtonAtLoad may start from the workspace's factor.
enum class StartFactor {
  kNone,   ///< no usable factor: assemble at the start
  kExact,  ///< the factor of the Hessian at *state for this model: first step reuses it
  kChord,  ///< a factor at *state for another model (a fit's parameter change): chord step
};

/// True when every entry is finite: 0 * x is 0 for a finite x and NaN for inf or NaN, and the sum
/// of those vectorises (Eigen's allFinite tests entry by entry, a measurable part of a warm
/// re-solve on the band).
bool AllFinite(const Eigen::MatrixXd& m) { return (m.array() * 0.0).sum() == 0.0; }

/// Factors H + shift I with the smallest shift of 0, then `base` x 10^k, that succeeds. Returns
/// the shift used (0: H itself), or a negative value when none does (non-finite entries, or no
/// shift up to 1e6 times the largest diagonal entry). The base is set by the soft (bending)
/// scale, not by the diagonal, which the stretch stiffness EA / l dominates: a shift of even 1e-10
/// of that would swamp the bending and stall Newton on a stiff, fine rod.
double FactorShifted(const BandedSymmetric& H, double base, BandedCholesky* factor,
                     double* last_failed) {
  *last_failed = -1.0;
  const double diag_scale = H.band().row(0).cwiseAbs().maxCoeff();
  if (!std::isfinite(diag_scale)) return -1.0;
  const double cap = 1e6 * std::max(diag_scale, 1e-300);
  double shift = 0.0;
  for (int k = 0; k < 80; ++k) {  // 0, then base .. cap in decades
    // A non-finite entry makes a pivot non-finite (every entry of the band's blocks enters one),
    // which Factor refuses: the band is checked only after a failure, not before every factor.
    if (factor->Factor(H, shift)) return shift;
    if (k == 0 && !AllFinite(H.band())) return -1.0;
    *last_failed = shift;
    shift = (shift == 0.0) ? std::min(base, cap) : shift * 10.0;
    if (shift > cap) break;
  }
  return -1.0;
}

/// Looks for a direction of negative curvature of H (held rows excluded) at a state the shifted
/// factorisation `shifted` (H + shift I, shift > 0) was made for: bisects the shift down to the
/// smallest that factors, then inverse iteration with it. Returns the Rayleigh quotient of the
/// direction found (d, scaled to max |d| = 1).
double NegativeCurvature(const BandedSymmetric& H, double shift_ok, double shift_failed,
                         BandedCholesky* factor, VecX* d, int bisections, const VecX& g) {
  double lo = std::max(shift_failed, 0.0), hi = shift_ok;
  BandedCholesky probe;
  for (int k = 0; k < bisections && hi > 1.0001 * lo; ++k) {
    const double mid = lo > 0.0 ? std::sqrt(lo * hi) : 0.5 * hi;
    if (probe.Factor(H, mid)) {
      hi = mid;
      *factor = probe;
    } else {
      lo = mid;
    }
  }
  if (!factor->Factor(H, hi)) return 0.0;
  // Inverse iteration from the descent direction -g (plus a fixed, non-symmetric vector so that
  // no mode is missed): within a degenerate eigenspace (an isotropic column buckles alike in
  // every direction about its axis) it converges to the mode the loads push, so a heavy rod
  // buckles down, not sideways.
  *d = VecX::Ones(H.size());
  for (int k = 0; k < d->size(); k += 3) (*d)[k] = -0.5;
  const double gmax = g.cwiseAbs().maxCoeff();
  if (gmax > 0) *d = 1e-3 * *d - g / gmax;
  double rq = 0.0;
  for (int it = 0; it < 40; ++it) {
    *d = factor->Solve(*d);
    const double scale = d->cwiseAbs().maxCoeff();
    if (!(scale > 0) || !std::isfinite(scale)) return 0.0;
    *d /= scale;
    const double q = d->dot(H.Multiply(*d)) / d->squaredNorm();
    if (it > 3 && std::abs(q - rq) <= 1e-6 * std::abs(q)) {
      rq = q;
      break;
    }
    rq = q;
  }
  return rq;
}

/// NegativeCurvature of H over the free dofs, or over the positions when H is the position-only
/// Hessian (g and the direction d in the free-dof layout either way).
double NegativeCurvatureOf(const BandedSymmetric& H, bool positions, double shift_ok,
                           double shift_failed, BandedCholesky* factor, VecX* d, int bisections,
                           const VecX& g) {
  if (!positions) return NegativeCurvature(H, shift_ok, shift_failed, factor, d, bisections, g);
  VecX gp, dp;
  GatherPositions(g, &gp);
  const double rq = NegativeCurvature(H, shift_ok, shift_failed, factor, &dp, bisections, gp);
  ScatterPositions(dp, d);
  return rq;
}

struct NewtonContext {
  const RodModel& model;
  const StaticsOptions& opt;
  const Tolerances& tol;
  const std::vector<char>& held;
  /// The twist is eliminated (TwistCanBeEliminated and StaticsOptions::eliminate_twist): every
  /// state the solver makes has zero twist, and Newton's system is over the positions.
  bool eliminate_twist = false;
};

/// ApplyStep, then the twist angles set to zero twist when it is eliminated.
bool ApplyNewtonStep(const NewtonContext& ctx, const RodState& state, const VecX& step,
                     double alpha, RodState* out) {
  if (!ApplyStep(ctx.model, state, step, alpha, out)) return false;
  if (ctx.eliminate_twist) SetZeroTwist(ctx.model, out);
  return true;
}

/// Tries to leave a saddle along d (negative curvature): the first step along +-d, from 0.1 L
/// down, that lowers Pi beyond round-off. True when taken (*state, *frames and *energy moved).
bool StepAlongNegativeCurvature(const NewtonContext& ctx, const EnergyTerms& terms, VecX d,
                                RodState* state, RodFrames* frames, double* energy) {
  for (int k = 0; k < d.size(); ++k)
    if (ctx.held[k]) d[k] = 0.0;
  const double dmax = d.cwiseAbs().maxCoeff();
  if (!(dmax > 0)) return false;
  d /= dmax;
  const double noise = EnergyNoise(ctx.model, *energy);
  RodState trial;
  RodFrames trial_frames;
  for (double a = 0.1 * ctx.model.length(); a > 1e-9 * ctx.model.length(); a *= 0.5) {
    for (double sgn : {1.0, -1.0}) {
      if (!ApplyNewtonStep(ctx, *state, d, sgn * a, &trial)) continue;
      ComputeRodFrames(ctx.model, trial, &trial_frames);
      const double e_trial = PotentialEnergyFreshFrames(ctx.model, trial, terms, &trial_frames);
      if (std::isfinite(e_trial) && e_trial < *energy - 10.0 * noise) {
        std::swap(*state, trial);
        std::swap(*frames, trial_frames);
        *energy = e_trial;
        return true;
      }
    }
  }
  return false;
}

/// The lowest Pi along +-d (negative curvature), scanning amplitudes from 0.2 L down by halves
/// and keeping the best; true when it lowers Pi below *energy (*state, *frames, *energy moved).
/// Far from equilibrium an indefinite Hessian (a straight segment compressed between held
/// points, a column past buckling) makes the shifted Newton step tiny, while the buckling mode
/// lowers Pi by orders of magnitude.
bool BestAlongNegativeCurvature(const NewtonContext& ctx, const EnergyTerms& terms, VecX d,
                                RodState* state, RodFrames* frames, double* energy) {
  for (int k = 0; k < d.size(); ++k)
    if (ctx.held[k]) d[k] = 0.0;
  const double dmax = d.cwiseAbs().maxCoeff();
  if (!(dmax > 0)) return false;
  d /= dmax;
  RodState trial, best;
  RodFrames trial_frames, best_frames;
  double best_energy = *energy;
  for (double sgn : {1.0, -1.0}) {
    double previous = std::numeric_limits<double>::infinity();
    for (double a = 0.2 * ctx.model.length(); a > 1e-6 * ctx.model.length(); a *= 0.5) {
      if (!ApplyNewtonStep(ctx, *state, d, sgn * a, &trial)) continue;
      ComputeRodFrames(ctx.model, trial, &trial_frames);
      const double e = PotentialEnergyFreshFrames(ctx.model, trial, terms, &trial_frames);
      if (!std::isfinite(e)) continue;
      if (e < best_energy) {
        best_energy = e;
        best = trial;
        best_frames = trial_frames;
      }
      if (e > previous && previous < *energy) break;  // past the best amplitude on this side
      previous = e;
    }
  }
  if (!(best_energy < *energy - 10.0 * EnergyNoise(ctx.model, *energy))) return false;
  *state = std::move(best);
  *frames = std::move(best_frames);
  *energy = best_energy;
  return true;
}

/// Newton iterations at one load factor for a conservative case. Returns kConverged with *state
/// at equilibrium. With StartFactor::kExact, ws->hessian already holds the factor of the
/// (unshifted) Hessian at *state for this model and load, and ws the energy and gradient there
/// without dead loads, so the first iteration assembles nothing.
// One function, though long: the iteration's steps (assemble, shift, factor, solve, line search,
// the convergence proof) share the workspace's factor and energies, and each step's shortcut
// depends on what the previous one left valid; split, that state would pass through every call.
StepResult NewtonAtLoad(const NewtonContext& solve_ctx, double load_scale, int max_iterations,
                        RodState* state, StaticsWorkspace* ws, StaticsSummary* summary,
                        std::string* why, StartFactor start) {
  const RodModel& model = solve_ctx.model;
  const StaticsOptions& opt = solve_ctx.opt;
  const Tolerances& tol = solve_ctx.tol;
  const int n = model.num_edges();
  EnergyTerms terms;
  terms.load_scale = load_scale;
  VecX g, step;
  // The assembled Hessian's storage is the workspace's: a warm re-solve then neither allocates
  // nor zeroes a band before assembling it (3.5 % of a 100-segment re-solve). It is assembled
  // before any use in an iteration.
  BandedSymmetric& H = ws->scratch_hessian;
  RodState trial;
  const bool factor_at_start = (start == StartFactor::kExact);
  const double force_tol = tol.force;
  // Frames of the current state and of the trial, each computed once and shared by the energy
  // and the assembly at that state. (With the kept factor the first iteration needs no frames;
  // later states arrive with theirs.)
  RodFrames frames, trial_frames;
  // A fine rod's steps come from the edge-coordinate factor (edge_solver.h); the vertex factor
  // still tells definiteness. Chord steps and the kept factor's reuse are for the vertex path.
  const bool use_edge = n >= opt.edge_solver_segments && EdgeSolver::Applies(model);
  // Twist eliminated: Newton's system is over the positions (AssemblePositionHessian), every
  // state has zero twist (on a converged state SetZeroTwist changes nothing, so the kept
  // factor's state is unchanged). The edge-coordinate path keeps the twist.
  const bool positions = solve_ctx.eliminate_twist && !use_edge;
  // The steps of this Newton keep zero twist only when it is over the positions.
  NewtonContext ctx = solve_ctx;
  ctx.eliminate_twist = positions;
  if (positions) SetZeroTwist(model, state);
  summary->twist_eliminated = positions;
  if (!factor_at_start) ComputeRodFrames(model, *state, &frames);
  double energy = factor_at_start ? ws->factor_unloaded_energy +
                                        DeadLoadEnergy(model, *state, load_scale)
                                  : PotentialEnergyFreshFrames(model, *state, terms, &frames);
  if (!std::isfinite(energy)) {
    *why = "non-finite energy (the values are too large to represent)";
    return StepResult::kFailed;
  }
  // On convergence, keeps Pi and its gradient without the dead loads with the factor.
  auto converged = [&](bool stable) {
    summary->stable = stable;
    ws->factor_unloaded_energy = energy - DeadLoadEnergy(model, *state, load_scale);
    ws->factor_unloaded_gradient = g;
    AddDeadLoadGradient(model, -load_scale, /*hold=*/true, &ws->factor_unloaded_gradient);
    return StepResult::kConverged;
  };
  // Chord steps (see ChordStep) converge linearly, at about the rate r = |g_k| / |g_k-1| of the
  // step before (both scale with how far the state moved), and cost about half a Newton step on
  // the benchmark suture (a gradient instead of a Hessian, no factorisation). One is taken where
  // it is predicted to reach the tolerance by itself (r <= 0.1, r |g| <= tol): there it replaces
  // a Newton step. (Two chords cost about one Newton step, which usually gains more than their
  // two rates: not worth the risk.) Where the next |g| is predicted below the tolerance (r |g|
  // after a chord; r^2 |g| after a Newton step, which converges quadratically with an unknown
  // constant, so below ten times the tolerance), the Hessian is assembled straight away: it is
  // needed at the solution anyway, where its factor is kept. A chord step that fails any test is
  // not taken and Newton resumes. Held points (Dirichlet rows) keep to Newton.
  constexpr double kChordRate = 0.1;
  auto chord_pays = [&](double rate, double gnorm) {
    return rate <= kChordRate && rate * gnorm <= force_tol;
  };
  const bool chords_allowed =
      opt.chord_steps && model.held().empty() && !model.has_end_ghost() && !use_edge;
  bool chord_basis = chords_allowed && start != StartFactor::kNone &&
                     ws->factor_tangents.cols() == n;
  bool last_step_full = false, last_step_chord = false;
  double g_last = std::numeric_limits<double>::quiet_NaN(), g_before_last = g_last;
  constexpr int kMaxSaddleEscapes = 5;
  int stagnant = 0;
  double previous_energy = energy;
  double last_move = std::numeric_limits<double>::infinity();  // [m] of the last step taken
  for (int it = 0; it < max_iterations; ++it) {
    const bool reuse = (it == 0 && factor_at_start);
    bool chord = false;
    if (!reuse && chord_basis) {
      if (it == 0) {
        chord = (start == StartFactor::kChord);
      } else if (last_step_full) {
        // After the first step the rate is unknown: a warm start's first step is Newton's (or a
        // chord's) from close by, worth a gradient to find out; a cold start's may be far from
        // Newton's fast regime.
        const double rate = g_last / g_before_last;
        const double predicted = g_last * rate * (last_step_chord ? 1.0 : rate);
        const double margin = last_step_chord ? 1.0 : 10.0;
        chord = std::isnan(rate) ? start != StartFactor::kNone
                                 : predicted > margin * force_tol && chord_pays(rate, predicted);
      }
    }
    if (chord) {
      AssembleGradient(model, *state, terms, &g, &frames);
      const double gnorm = tol.Norm(g);
      summary->gradient_norm = gnorm;
      summary->energy = energy;
      // The first chord step of a solve from the kept factor of another model has no rate yet.
      const bool progress = std::isnan(g_last) || chord_pays(gnorm / g_last, gnorm);
      bool taken = false;
      if (std::isfinite(gnorm) && gnorm > force_tol && progress &&
          ChordStep(ws->hessian, ws->factor_positions, ws->factor_tangents, frames, g, &step)) {
        const double slope = g.dot(step);
        const double noise = EnergyNoise(model, energy);
        if (slope < 0.0 && MaxTangentTurn(model, *state, step) <= opt.max_rotation_per_step &&
            ApplyNewtonStep(ctx, *state, step, 1.0, &trial)) {
          ComputeRodFrames(model, trial, &trial_frames);
          const double e_trial = PotentialEnergyFreshFrames(model, trial, terms, &trial_frames);
          if (std::isfinite(e_trial) && e_trial <= energy + opt.armijo * slope + noise) {
            taken = true;
            energy = e_trial;
            last_move = LargestMove(*state, trial);
            std::swap(*state, trial);
            std::swap(frames, trial_frames);
          }
        }
      }
      if (taken) {
        ++summary->iterations;
        ++summary->chord_steps;
        g_before_last = g_last;
        g_last = gnorm;
        last_step_full = true;
        last_step_chord = true;
        continue;
      }
      chord_basis = false;  // Newton from here on (converged states included: see below)
    }
    if (reuse) {
      g = ws->factor_unloaded_gradient;
      AddDeadLoadGradient(model, load_scale, /*hold=*/true, &g);
    } else if (use_edge) {
      AssembleGradient(model, *state, terms, &g, &frames);
    } else if (positions) {
      AssemblePositionHessian(model, *state, terms, &g, &H, &frames);
    } else {
      AssembleHessian(model, *state, terms, &g, &H, &frames);
    }
    const double gnorm = tol.Norm(g);
    summary->gradient_norm = gnorm;
    summary->energy = energy;
    if (!std::isfinite(gnorm)) {
      *why = "non-finite gradient";
      return StepResult::kFailed;
    }
    // Factor; on failure (indefinite or singular) shift the diagonal, growing the shift tenfold.
    double shift = 0.0, shift_failed = -1.0;
    if (use_edge) {
      // Fine rod: the edge-coordinate tangent, its definiteness on the held points' constraint
      // space from its inertia (edge_solver.h); the vertex factor is not formed at all.
      bool ok = false;
      for (int k = 0; k < 80 && !ok; ++k) {
        ok = ws->edge.Factor(model, *state, frames, terms, 0.0, shift) &&
             ws->edge.positive_definite();
        if (!ok) {
          shift_failed = shift;
          shift = shift == 0.0 ? tol.shift_base : 10.0 * shift;
          if (shift > tol.shift_cap) break;
        }
      }
      if (!ok) {
        *why = "Hessian could not be made positive definite";
        return StepResult::kFailed;
      }
    } else if (!reuse) {
      shift = FactorShifted(H, tol.shift_base, &ws->hessian, &shift_failed);
      if (shift < 0.0) {
        *why = AllFinite(H.band()) ? "Hessian could not be made positive definite"
                                    : "non-finite Hessian";
        return StepResult::kFailed;
      }
    }
    const bool shifted = shift > 0.0;
    if (!reuse && !use_edge) {
      // The new factor is the chord basis from here on, if it is the Hessian's own.
      KeepTangents(frames, n, &ws->factor_tangents);
      ws->factor_positions = positions;
      chord_basis = chords_allowed && !shifted;
    }
    ws->edge_valid = use_edge && !shifted;
    if (use_edge) {
      step = -g;
      ws->edge.SolveInPlace(step);
      if (tol.Converged(gnorm, step)) {
        // Shifted: an equilibrium with a negative direction (no escape on this path).
        ws->factor_valid = false;
        return converged(!shifted);
      }
    } else if (!shifted && gnorm <= force_tol && last_step_full &&
               last_move <= 1e3 * tol.step_x) {
      // At the gradient's floor after a full step that moved no vertex by more than 1e-6 L: the
      // state is that close to the solution (the Converged() test's last clause, without the
      // back-substitution for a step that would be no longer).
      ws->factor_valid = true;
      return converged(true);
    } else {
      step = -g;  // solved in place: no temporary vector per Newton step
      SolveWithFactor(ws->hessian, positions, &step);
    }
    if (!shifted && tol.Converged(gnorm, step)) {
      ws->factor_valid = true;
      return converged(true);
    }
    // With a shift the step is nearly Newton's except along the negative directions.
    if (shifted && !use_edge && tol.Converged(gnorm, step)) {
      // A stationary point with negative curvature is a saddle (a column past its buckling
      // load, kept straight by symmetry): find the most negative curvature direction and, if
      // asked, step along it. No step that lowers Pi beyond round-off means the curvature is
      // round-off around a neutral direction (e.g. an isotropic buckled column turning about
      // its load axis): stable, though the factor is then not the Hessian's own.
      VecX d;
      BandedCholesky probe;
      const double rq = NegativeCurvatureOf(H, positions, shift, shift_failed, &probe, &d, 12, g);
      const double amplitude = 0.01 * model.length() / std::max(d.cwiseAbs().maxCoeff(), 1e-300);
      const bool clearly_negative =
          rq < 0.0 && 0.5 * -rq * d.squaredNorm() * amplitude * amplitude >
                          100.0 * EnergyNoise(model, energy);
      if (opt.escape_saddles && summary->saddle_escapes < kMaxSaddleEscapes &&
          StepAlongNegativeCurvature(ctx, terms, d, state, &frames, &energy)) {
        ++summary->saddle_escapes;
        ++summary->iterations;
        last_step_full = false;
        chord_basis = false;
        continue;
      }
      ws->factor_valid = false;
      return converged(!clearly_negative);
    }
    const double slope = g.dot(step);
    double alpha = 1.0;
    const double turn = MaxTangentTurn(model, *state, step);
    if (turn > opt.max_rotation_per_step) alpha = opt.max_rotation_per_step / turn;
    // Nor may an edge's strain change by more than 10 % in one step: on a fine rod whose edges
    // are soft in stretch against their bending (EA l^2 / EI << 1) a full step would crumple them.
    const double strain = MaxStrainChange(model, *state, step);
    if (alpha * strain > kMaxStrainStep) alpha = kMaxStrainStep / strain;
    // Near convergence Pi changes by round-off only; allow that much so that Newton's final
    // quadratically convergent steps are not rejected by noise.
    const double noise = EnergyNoise(model, energy);
    bool accepted = false;
    for (int ls = 0; ls < opt.max_line_search_steps; ++ls, alpha *= 0.5) {
      if (!ApplyNewtonStep(ctx, *state, step, alpha, &trial)) continue;
      ComputeRodFrames(model, trial, &trial_frames);
      const double e_trial = PotentialEnergyFreshFrames(model, trial, terms, &trial_frames);
      if (std::isfinite(e_trial) && e_trial <= energy + opt.armijo * alpha * slope + noise) {
        accepted = true;
        energy = e_trial;
        break;
      }
    }
    if (shifted && !use_edge) {
      // Compare with the best step along the negative curvature (BestAlongNegativeCurvature).
      VecX d;
      BandedCholesky probe;
      if (NegativeCurvatureOf(H, positions, shift, shift_failed, &probe, &d, 5, g) < 0.0) {
        RodState nc_state = *state;
        RodFrames nc_frames = frames;
        double nc_energy = energy;
        const double newton_energy = accepted ? energy : std::numeric_limits<double>::infinity();
        const double base_energy = PotentialEnergyFreshFrames(model, *state, terms, &frames);
        nc_energy = base_energy;
        if (BestAlongNegativeCurvature(ctx, terms, d, &nc_state, &nc_frames, &nc_energy) &&
            nc_energy < newton_energy) {
          trial = std::move(nc_state);
          trial_frames = std::move(nc_frames);
          energy = nc_energy;
          accepted = true;
          alpha = 0.0;  // not a full Newton step
        }
      }
    }
    ++summary->iterations;
    if (!accepted) {
      // A state at the gradient's round-off floor whose unshifted Newton step is within 1e3 of
      // the step tolerance and cannot lower Pi further is at round-off level. (A small step with
      // a large gradient is not: the factor has lost the soft modes.)
      if (!shifted && gnorm <= 1e3 * force_tol && tol.SmallStep(step, 1e3)) {
        ws->factor_valid = !use_edge;
        return converged(true);
      }
      *why = "line search failed";
      return StepResult::kFailed;
    }
    last_step_full = (alpha == 1.0);
    last_step_chord = false;
    g_before_last = g_last;
    g_last = gnorm;
    // Stagnation at round-off: full unshifted Newton steps that move no vertex by more than
    // 1e3 times the step tolerance (1e-6 L) and change Pi by no more than its round-off, three
    // times running. The gradient's floor is then above the tolerance (fine rods: the bending
    // forces' round-off grows as eps B / l^2), and the state is as good as doubles make it.
    const double moved = LargestMove(*state, trial);
    last_move = moved;
    const double change = std::abs(energy - previous_energy);
    stagnant = (!shifted && alpha == 1.0 && moved <= 1e3 * tol.step_x &&
                change <= 10.0 * EnergyNoise(model, energy))
                   ? stagnant + 1
                   : 0;
    previous_energy = energy;
    std::swap(*state, trial);
    std::swap(frames, trial_frames);
    if (stagnant >= 3) {
      ws->factor_valid = false;
      summary->reason_detail = "stagnated at round-off";
      return converged(true);
    }
  }
  *why = "iteration limit reached";
  return StepResult::kIterationCap;
}

/// Newton on the balance of a case with moments: the tangent is not symmetric (banded LU), and
/// the line search is on the weighted residual 1/2 |W r|^2, for which the Newton step is a
/// descent direction with slope -|W r|^2.
StepResult NewtonNonconservative(const NewtonContext& ctx, double load_scale, double moment_scale,
                                 int max_iterations, RodState* state, StaticsWorkspace* ws,
                                 StaticsSummary* summary, std::string* why) {
  const RodModel& model = ctx.model;
  const StaticsOptions& opt = ctx.opt;
  const Tolerances& tol = ctx.tol;
  EnergyTerms terms;
  terms.load_scale = load_scale;
  VecX g, g_trial, step;
  BandedSymmetric H;
  BandedMatrix J;
  RodState trial;
  RodFrames frames, trial_frames;
  ComputeRodFrames(model, *state, &frames);
  auto merit = [&](const VecX& r) {
    double m = 0.0;
    for (int k = 0; k < r.size(); ++k) m += 0.5 * std::pow(tol.weights[k] * r[k], 2);
    return m;
  };
  const bool use_edge =
      model.num_edges() >= opt.edge_solver_segments && EdgeSolver::Applies(model);
  for (int it = 0; it < max_iterations; ++it) {
    AssembleBalance(model, *state, frames, load_scale, &g, use_edge ? nullptr : &J, &H, true,
                    moment_scale);
    const double gnorm = tol.Norm(g);
    summary->gradient_norm = gnorm;
    summary->energy = PotentialEnergyFreshFrames(model, *state, terms, &frames);
    if (!std::isfinite(gnorm) || (!use_edge && !J.AllFinite())) {
      *why = "non-finite residual or tangent";
      return StepResult::kFailed;
    }
    // LU of the tangent, shifted towards the identity where it is singular (a fine rod's in edge
    // coordinates, edge_solver.h).
    const double diag = use_edge ? tol.shift_cap * 1e-6 : J.MaxDiagonal();
    double shift = 0.0;
    bool factored = false;
    for (int k = 0; k < 80 && !factored; ++k) {
      if (use_edge) {
        factored = ws->edge.Factor(model, *state, frames, terms, moment_scale, shift);
      } else {
        BandedMatrix Js = J;
        if (shift > 0.0)
          for (int r = 0; r < Js.size(); ++r) Js.At(r, r) += shift;
        factored = ws->tangent.Factor(Js);
      }
      if (!factored) {
        shift = shift == 0.0 ? std::min(tol.shift_base, std::max(diag, 1e-300)) : 10.0 * shift;
        if (shift > 1e6 * std::max(diag, 1e-300)) break;
      }
    }
    if (!factored) {
      *why = "the tangent could not be factored";
      return StepResult::kFailed;
    }
    const bool shifted = shift > 0.0;
    ws->edge_valid = use_edge && !shifted;
    auto finish = [&]() {
      // Stable when the symmetric part of the tangent is positive definite (all eigenvalues of
      // the tangent then have positive real parts), on the held points' constraint space.
      if (use_edge) {
        summary->stable = !shifted && ws->edge.positive_definite();
      } else {
        BandedCholesky sym;
        summary->stable = !shifted && sym.Factor(J.SymmetricPart(1));
      }
      ws->tangent_valid = !shifted && !use_edge;
      return StepResult::kConverged;
    };
    if (use_edge) {
      step = -g;
      ws->edge.SolveInPlace(step);
    } else {
      step = -ws->tangent.Solve(g);
    }
    if (!shifted && tol.Converged(gnorm, step)) return finish();
    if (gnorm <= tol.strict) return finish();  // shifted: a singular tangent at a solution
    double alpha = 1.0;
    const double turn = MaxTangentTurn(model, *state, step);
    if (turn > opt.max_rotation_per_step) alpha = opt.max_rotation_per_step / turn;
    // Nor may an edge's strain change by more than 10 % in one step: on a fine rod whose edges
    // are soft in stretch against their bending (EA l^2 / EI << 1) a full step would crumple them.
    const double strain = MaxStrainChange(model, *state, step);
    if (alpha * strain > kMaxStrainStep) alpha = kMaxStrainStep / strain;
    const double m0 = merit(g);
    bool accepted = false;
    for (int ls = 0; ls < opt.max_line_search_steps; ++ls, alpha *= 0.5) {
      if (!ApplyStep(model, *state, step, alpha, &trial)) continue;
      ComputeRodFrames(model, trial, &trial_frames);
      AssembleBalance(model, trial, trial_frames, load_scale, &g_trial, nullptr, nullptr, true,
                      moment_scale);
      const double m1 = merit(g_trial);
      if (std::isfinite(m1) && m1 <= (1.0 - 2.0 * opt.armijo * alpha) * m0 + 1e-24 * m0) {
        accepted = true;
        break;
      }
    }
    ++summary->iterations;
    if (!accepted) {
      if (!shifted && gnorm <= 1e3 * tol.force && tol.SmallStep(step, 1e3)) return finish();
      *why = "line search failed";
      return StepResult::kFailed;
    }
    std::swap(*state, trial);
    std::swap(frames, trial_frames);
  }
  *why = "iteration limit reached";
  return StepResult::kIterationCap;
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

}  // namespace

void BalanceResidual(const RodModel& model, const RodState& state, VecX* residual) {
  RodFrames frames;
  ComputeRodFrames(model, state, &frames);
  AssembleBalance(model, state, frames, 1.0, residual, nullptr, nullptr);
}

// One function, though long: the choice of path (positions or edge coordinates, warm or
// continuation), the retries and the summary are read top to bottom as the order they run in.
StaticsSummary SolveStatics(const RodModel& model, const StaticsOptions& options, RodState* state,
                            StaticsWorkspace* workspace) {
  StaticsSummary summary;
  summary.nonconservative = model.nonconservative();
  std::string why;
  if (!options.Check(&why)) {
    summary.reason = "invalid options: " + why;
    return summary;
  }
  if (state->num_edges() != model.num_edges() || state->x.cols() != model.num_vertices()) {
    summary.reason = "state does not match the model's segment count";
    return summary;
  }
  if (!state->x.allFinite() || !state->theta.allFinite()) {
    summary.reason = "the start state has non-finite values";
    return summary;
  }
  PrepareState(model, state);
  StaticsWorkspace local;
  StaticsWorkspace* ws = workspace ? workspace : &local;
  const Tolerances tol = MakeTolerances(model, options);
  const std::vector<char>& held = HeldDofs(model);
  const bool eliminate = options.eliminate_twist && TwistCanBeEliminated(model);
  const NewtonContext ctx{model, options, tol, held, eliminate};
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

  // Continuation of the held boundary from the state's to the model's.
  const Boundary start = StateBoundary(model, *state), target = TargetBoundary(model, *state);
  double move = 0.0, turn = 0.0;
  BoundaryDistance(start, target, &move, &turn);
  int budget_used = 0;
  if (move > 1e-12 * model.length() || turn > 1e-12) {
    start_factor = StartFactor::kNone;
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
    const NewtonContext moving{model, moving_options, tol, held, eliminate};
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
    // then hinge on round-off. A step whose solution jumps (vertices moving much more than the
    // boundary, the twist changing by more than a quarter turn beyond the ends' own turn) is
    // retried at half the size, until the step is so small that the jump is the rod's own (a
    // snap at a limit point).
    const double planned_step = 1.0 / std::max(1, planned);
    const double smallest_jump_step = planned_step / 64.0;
    double step = planned_step;
    while (done < 1.0) {
      if (summary.continuation_steps >= options.max_continuation_steps)
        return failed("the held points did not reach their targets within " +
                      std::to_string(options.max_continuation_steps) + " continuation steps");
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
      if (r == StepResult::kConverged && step > smallest_jump_step) {
        double step_move = 0.0, step_turn = 0.0;
        BoundaryDistance(now, StateBoundary(model, trial), &step_move, &step_turn);
        // A rod whose held points close in bows out by ~ sqrt(shortening x length) (the
        // length it must put somewhere): that is the rod's own response, not a jump.
        const double allowed_move = 4.0 * (step_move + step_turn * model.length()) +
                                    2.0 * std::sqrt(step_move * model.length()) +
                                    0.01 * model.length();
        const double twist_change = std::abs(TotalTwist(model, trial) - TotalTwist(model, *state));
        if (LargestMove(*state, trial) > allowed_move || twist_change > 0.5 * M_PI + 2.0 * step_turn) {
          r = StepResult::kFailed;
          why = "the equilibrium jumped";
        }
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
          return failed("the held points could not be moved to their targets (continuation "
                        "stalled at " + std::to_string(static_cast<int>(100 * done)) +
                        " %: " + why + ")");
      }
      if (summary.iterations >= options.max_iterations * 20)
        return failed("iteration cap reached while moving the held points to their targets");
    }
    return converged("converged after continuation of the held points");
  }

  const StepResult r = SolveAtBoundary(ctx, state, ws, &summary, &why, start_factor, &budget_used);
  if (r == StepResult::kConverged)
    return converged(summary.load_steps > 1 ? "converged (load continuation)" : "converged");
  return failed("no equilibrium found: " + why);
}

}  // namespace rodfit
