// Newton solver for the rod's equilibrium (statics.h): banded Cholesky, diagonal shift for
// indefinite Hessians, Armijo backtracking on Pi, tangent-turn step limit, load continuation.
#include "rodfit/solve/statics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "rodfit/model/frames.h"
#include "rodfit/solve/rod_energy.h"

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
  return true;
}

std::string StaticsSummary::BriefReport() const {
  char chords[48] = "";
  if (chord_steps > 0) std::snprintf(chords, sizeof(chords), " (%d chord steps)", chord_steps);
  char buf[320];
  std::snprintf(buf, sizeof(buf),
                "%s%s after %d Newton iterations%s, %d load step(s), |g| = %.3e N, Pi = %.6e J: %s",
                converged ? "converged" : "NOT converged",
                (converged && !stable) ? " (unstable equilibrium)" : "", iterations, chords,
                load_steps, gradient_norm, energy, reason.c_str());
  return buf;
}

namespace {

enum class StepResult { kConverged, kFailed, kIterationCap };

bool SameState(const RodState& a, const RodState& b) {
  return a.x.cols() == b.x.cols() && a.theta.size() == b.theta.size() &&
         a.ref_u.cols() == b.ref_u.cols() && a.ref_t.cols() == b.ref_t.cols() &&
         a.ref_twist.size() == b.ref_twist.size() && a.x == b.x && a.theta == b.theta &&
         a.ref_u == b.ref_u && a.ref_t == b.ref_t && a.ref_twist == b.ref_twist;
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
bool ChordStep(const BandedCholesky& factor, const Eigen::Matrix3Xd& basis_tangents,
               const RodFrames& frames, const VecX& g, VecX* step) {
  const int n = static_cast<int>(basis_tangents.cols());
  if (static_cast<int>(frames.edges.size()) != n + 1 || factor.size() != g.size()) return false;
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
  factor.SolveInPlace(s);
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

void KeepTangents(const RodFrames& frames, Eigen::Matrix3Xd* tangents) {
  const int n = static_cast<int>(frames.edges.size()) - 1;
  tangents->resize(3, n);
  for (int j = 0; j < n; ++j) tangents->col(j) = frames.edges[j + 1].t;
}

/// How NewtonAtLoad may start from the workspace's factor.
enum class StartFactor {
  kNone,   ///< no usable factor: assemble at the start
  kExact,  ///< the factor of the Hessian at *state for this model: first step reuses it
  kChord,  ///< a factor at *state for another model (a fit's parameter change): chord step
};

/// Newton iterations at one load factor. Returns kConverged with *state at equilibrium.
/// With StartFactor::kExact, ws->hessian already holds the factor of the (unshifted) Hessian at
/// *state for this model and load, and ws the energy and gradient there without dead loads, so
/// the first iteration assembles nothing.
StepResult NewtonAtLoad(const RodModel& model, const StaticsOptions& opt, double load_scale,
                        int max_iterations, RodState* state, StaticsWorkspace* ws,
                        StaticsSummary* summary, std::string* why, StartFactor start) {
  EnergyTerms terms;
  terms.load_scale = load_scale;
  VecX g, step;
  BandedSymmetric H;
  RodState trial;
  const bool factor_at_start = (start == StartFactor::kExact);
  // The gradient cannot be resolved below round-off in the stretch forces, ~ eps EA |x| / l
  // (|x| the coordinates' size): accept that floor when it is above the requested tolerance.
  double coord = model.length();
  for (int i = 0; i < state->x.cols(); ++i) coord = std::max(coord, state->x.col(i).cwiseAbs().maxCoeff());
  const double roundoff_floor = 16.0 * std::numeric_limits<double>::epsilon() *
                                model.material().stretch_stiffness * coord /
                                model.rest_edge_length(0);
  const double force_tol =
      std::max(opt.gradient_tolerance * model.force_scale(), roundoff_floor);
  // Frames of the current state and of the trial, each computed once and shared by the energy
  // and the assembly at that state.
  // (With the kept factor the first iteration needs no frames; later states arrive with theirs.)
  RodFrames frames, trial_frames;
  if (!factor_at_start) ComputeRodFrames(model, *state, &frames);
  double energy = factor_at_start ? ws->factor_unloaded_energy +
                                        DeadLoadEnergy(model, *state, load_scale)
                                  : PotentialEnergyFreshFrames(model, *state, terms, &frames);
  // On convergence, keeps Pi and its gradient without the dead loads with the factor.
  auto converged = [&]() {
    ws->factor_unloaded_energy = energy - DeadLoadEnergy(model, *state, load_scale);
    ws->factor_unloaded_gradient = g;
    AddDeadLoadGradient(model, -load_scale, /*hold_grasp=*/true, &ws->factor_unloaded_gradient);
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
  // not taken and Newton resumes. A fixed grasp (Dirichlet rows) keeps to Newton.
  constexpr double kChordRate = 0.1;
  auto chord_pays = [&](double rate, double gnorm) {
    return rate <= kChordRate && rate * gnorm <= force_tol;
  };
  // The workspace's factor is an unshifted Hessian factor with its tangents in
  // ws->factor_tangents.
  bool chord_basis = opt.chord_steps && model.grasp_vertex() < 1 && start != StartFactor::kNone &&
                     ws->factor_tangents.cols() == model.num_edges();
  bool last_step_full = false, last_step_chord = false;
  double g_last = std::numeric_limits<double>::quiet_NaN(), g_before_last = g_last;
  constexpr int kMaxSaddleEscapes = 5;
  int escapes = 0;
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
      const double gnorm = ScaledGradientNorm(model, g);
      summary->gradient_norm = gnorm;
      summary->energy = energy;
      // The first chord step of a solve from the kept factor of another model has no rate yet.
      const bool progress = std::isnan(g_last) || chord_pays(gnorm / g_last, gnorm);
      bool taken = false;
      if (std::isfinite(gnorm) && gnorm > force_tol && progress &&
          ChordStep(ws->hessian, ws->factor_tangents, frames, g, &step)) {
        const double slope = g.dot(step);
        const double noise = 1e-13 * (std::abs(energy) + model.force_scale() * model.length());
        if (slope < 0.0 && MaxTangentTurn(model, *state, step) <= opt.max_rotation_per_step &&
            ApplyStep(model, *state, step, 1.0, &trial)) {
          ComputeRodFrames(model, trial, &trial_frames);
          const double e_trial = PotentialEnergyFreshFrames(model, trial, terms, &trial_frames);
          if (std::isfinite(e_trial) && e_trial <= energy + opt.armijo * slope + noise) {
            taken = true;
            energy = e_trial;
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
      AddDeadLoadGradient(model, load_scale, /*hold_grasp=*/true, &g);
    } else {
      AssembleHessian(model, *state, terms, &g, &H, &frames);
    }
    const double gnorm = ScaledGradientNorm(model, g);
    summary->gradient_norm = gnorm;
    summary->energy = energy;
    if (!std::isfinite(gnorm)) {
      *why = "non-finite gradient";
      return StepResult::kFailed;
    }
    // Factor; on failure (indefinite or singular) shift the diagonal, growing the shift tenfold.
    double shift = 0.0;
    const double diag_scale =
        reuse ? 0.0 : std::max(H.band().row(0).cwiseAbs().maxCoeff(), 1e-300);
    bool shifted = false;
    while (!reuse && !ws->hessian.Factor(H, shift)) {
      shift = (shift == 0.0) ? 1e-10 * diag_scale : shift * 10.0;
      shifted = true;
      if (shift > 1e6 * diag_scale) {
        *why = "Hessian could not be made positive definite";
        return StepResult::kFailed;
      }
    }
    if (!reuse) {
      // The new factor is the chord basis from here on, if it is the Hessian's own.
      KeepTangents(frames, &ws->factor_tangents);
      chord_basis = opt.chord_steps && model.grasp_vertex() < 1 && !shifted;
    }
    if (gnorm <= force_tol && shifted && escapes < kMaxSaddleEscapes) {
      // A stationary point with negative curvature is a saddle (a column past its buckling
      // load, kept straight by symmetry): step along the most negative curvature direction,
      // found by inverse iteration on the shifted factor, if that lowers Pi.
      ++escapes;
      VecX d = VecX::Ones(g.size());
      for (int k = 0; k < d.size(); k += 3) d[k] = -0.5;  // fixed, non-symmetric start
      for (int k = 0; k < 4; ++k) {
        d = ws->hessian.Solve(d);
        d /= d.cwiseAbs().maxCoeff();
      }
      const double scale = 0.1 * model.rest_edge_length(0);
      bool escaped = false;
      for (double sgn : {1.0, -1.0}) {
        for (double a = scale; a > 1e-6 * scale && !escaped; a *= 0.5) {
          if (!ApplyStep(model, *state, d, sgn * a, &trial)) continue;
          ComputeRodFrames(model, trial, &trial_frames);
          const double e_trial = PotentialEnergyFreshFrames(model, trial, terms, &trial_frames);
          const double noise = 1e-13 * (std::abs(energy) + model.force_scale() * model.length());
          if (e_trial < energy - 10.0 * noise) {
            escaped = true;
            energy = e_trial;
          }
        }
        if (escaped) break;
      }
      if (escaped) {
        std::swap(*state, trial);
        std::swap(frames, trial_frames);
        ++summary->iterations;
        last_step_full = false;
        continue;
      }
      // No step along the most negative curvature lowers Pi beyond round-off: that curvature is
      // round-off around a neutral direction (e.g. an isotropic buckled column turning about its
      // load axis), not a saddle. Stable, but the shifted factor is not the Hessian's own.
      if (gnorm <= force_tol) {
        ws->factor_valid = false;
        summary->stable = true;
        return converged();
      }
    }
    if (gnorm <= force_tol) {
      ws->factor_valid = !shifted;
      summary->stable = !shifted;
      return converged();
    }
    step = -ws->hessian.Solve(g);
    if (gnorm <= 1e-5 * model.force_scale()) {
      double dx = 0.0, dtheta = 0.0;
      for (int k = 0; k < step.size(); ++k)
        ((k % 4 == 3) ? dtheta : dx) = std::max((k % 4 == 3) ? dtheta : dx, std::abs(step[k]));
      if (dx <= opt.step_tolerance * model.rest_edge_length(0) && dtheta <= opt.step_tolerance) {
        ws->factor_valid = !shifted;
        summary->stable = !shifted;
        return converged();
      }
    }
    const double slope = g.dot(step);
    double alpha = 1.0;
    const double turn = MaxTangentTurn(model, *state, step);
    if (turn > opt.max_rotation_per_step) alpha = opt.max_rotation_per_step / turn;
    // Near convergence Pi changes by round-off only; allow that much so that Newton's final
    // quadratically convergent steps are not rejected by noise.
    const double noise = 1e-13 * (std::abs(energy) + model.force_scale() * model.length());
    bool accepted = false;
    for (int ls = 0; ls < opt.max_line_search_steps; ++ls, alpha *= 0.5) {
      if (!ApplyStep(model, *state, step, alpha, &trial)) continue;
      ComputeRodFrames(model, trial, &trial_frames);
      const double e_trial = PotentialEnergyFreshFrames(model, trial, terms, &trial_frames);
      if (std::isfinite(e_trial) && e_trial <= energy + opt.armijo * alpha * slope + noise) {
        accepted = true;
        energy = e_trial;
        break;
      }
    }
    ++summary->iterations;
    if (!accepted) {
      // A converged-looking state whose step cannot lower Pi further is at round-off level.
      if (gnorm <= 1e3 * force_tol) {
        ws->factor_valid = !shifted;
        summary->stable = !shifted;
        return converged();
      }
      *why = "line search failed";
      return StepResult::kFailed;
    }
    last_step_full = (alpha == 1.0);
    last_step_chord = false;
    g_before_last = g_last;
    g_last = gnorm;
    std::swap(*state, trial);
    std::swap(frames, trial_frames);
  }
  *why = "iteration limit reached";
  return StepResult::kIterationCap;
}

}  // namespace

StaticsSummary SolveStatics(const RodModel& model, const StaticsOptions& options, RodState* state,
                            StaticsWorkspace* workspace) {
  StaticsSummary summary;
  std::string why;
  if (!options.Check(&why)) {
    summary.reason = "invalid options: " + why;
    return summary;
  }
  if (state->num_edges() != model.num_edges() || state->x.cols() != model.num_vertices()) {
    summary.reason = "state does not match the model's segment count";
    return summary;
  }
  StaticsWorkspace local;
  StaticsWorkspace* ws = workspace ? workspace : &local;
  // The kept factor belongs to factor_state: from exactly that state it is the Hessian there
  // (same digest) or a chord basis (a model with other stiffnesses).
  StartFactor start_factor = StartFactor::kNone;
  if (ws->factor_valid && SameState(ws->factor_state, *state))
    start_factor = (ws->factor_digest == model.hessian_digest()) ? StartFactor::kExact
                                                                 : StartFactor::kChord;
  ws->factor_valid = false;
  // Keeps the factor's provenance with it: the state and model it was made for.
  auto converged = [&](const char* reason) {
    summary.converged = true;
    summary.reason = reason;
    if (ws->factor_valid) {
      ws->factor_state = *state;
      ws->factor_digest = model.hessian_digest();
    }
    return summary;
  };

  // Full load first; on failure, continuation from the unloaded equilibrium.
  const RodState start = *state;
  int budget = options.max_iterations;
  StepResult r =
      NewtonAtLoad(model, options, 1.0, budget, state, ws, &summary, &why, start_factor);
  if (r == StepResult::kConverged) return converged("gradient below tolerance");
  *state = start;
  summary.load_steps = 0;
  double done = 0.0, increment = 0.25;
  bool have_base = false;
  while (summary.load_steps < options.max_load_steps) {
    budget = options.max_iterations - summary.iterations;
    if (budget <= 0) break;
    const double target = have_base ? std::min(1.0, done + increment) : 0.0;
    RodState saved = *state;
    const int per_step = std::min(budget, 50);
    r = NewtonAtLoad(model, options, target, per_step, state, ws, &summary, &why,
                     StartFactor::kNone);
    ++summary.load_steps;
    if (r == StepResult::kConverged) {
      if (!have_base) {
        have_base = true;
        continue;
      }
      done = target;
      if (done >= 1.0) return converged("gradient below tolerance (load continuation)");
      increment = std::min(0.5, increment * 1.5);
    } else {
      *state = saved;
      if (!have_base) break;  // cannot even find the unloaded equilibrium
      increment *= 0.25;
      if (increment < 1e-6) break;
    }
  }
  summary.converged = false;
  summary.reason = "no equilibrium found: " + why +
                   (summary.iterations >= options.max_iterations ? " (iteration cap)" : "");
  ws->factor_valid = false;
  return summary;
}

}  // namespace rodfit
