// The one Newton minimizer (newton_minimizer.h). The loop below is the only place in rodfit
// that shifts a diagonal, backtracks a step or decides convergence; the problems only evaluate,
// retract and measure.
#include "rodfit/solve/newton_minimizer.h"

#include <algorithm>
#include <cmath>

#include "rodfit/solve/deadline.h"

namespace rodfit {

const char* TerminationMessage(Termination termination) {
  switch (termination) {
    case Termination::kConverged: return "converged";
    case Termination::kSmallStep: return "converged (Newton step within tolerance)";
    case Termination::kContraction: return "converged (contraction within tolerance)";
    case Termination::kRoundOff: return "converged (stagnated at round-off)";
    case Termination::kIterationCap: return "iteration limit reached";
    case Termination::kLineSearchFailed: return "line search failed";
    case Termination::kNotPositiveDefinite:
      return "the Newton matrix could not be made positive definite";
    case Termination::kNonFinite: return "non-finite merit, residual or matrix";
    case Termination::kTimeBudget: return "time budget exceeded";
    case Termination::kRetractionFailed: return "no step could be taken (an edge would fold back)";
  }
  return "unknown termination";
}

void NewtonMinimizer::Reserve(int dofs) {
  // Sized, not zeroed: each is written before it is read.
  for (VecX* v : {&g_, &g_trial_, &step_, &d_})
    if (v->size() != dofs) v->resize(dofs);
}

// The scaled residual max_k w_k |r_k|. A NaN or an infinity in any entry makes it NaN: std::max
// drops a NaN, and so did the "if (!(v <= worst)) worst = v" of the loops this one replaced,
// whose NaN survived only when no finite entry came after it (a step whose other rows were small
// "converged" through NaN rows). The probe sums v * 0, which is NaN exactly for those entries.
double NewtonMinimizer::Norm(const VecX& r) const {
  const VecX& w = p_->NormWeights();
  double worst = 0.0, probe = 0.0;
  for (int k = 0; k < r.size(); ++k) {
    const double v = w[k] * std::abs(r[k]);
    worst = std::max(worst, v);
    probe += v * 0.0;
  }
  return probe == 0.0 ? worst : std::numeric_limits<double>::quiet_NaN();
}

bool NewtonMinimizer::Evaluate(bool matrix) {
  p_->Evaluate(matrix, &g_);
  gnorm_ = Norm(g_);
  summary_.residual_norm = gnorm_;
  return std::isfinite(gnorm_);
}

double NewtonMinimizer::Merit() {
  if (!energy_known_) {
    energy_ = options_.merit == Merit::kResidual ? 0.5 * [&] {
      const VecX& w = p_->NormWeights();
      double m = 0.0;
      for (int k = 0; k < g_.size(); ++k) m += (w[k] * g_[k]) * (w[k] * g_[k]);
      return m;
    }() : p_->Energy();
    energy_known_ = true;
  }
  return energy_;
}

double NewtonMinimizer::TrialMerit() {
  if (options_.merit != Merit::kResidual) return p_->TrialEnergy();
  p_->TrialResidual(&g_trial_);
  const VecX& w = p_->NormWeights();
  double m = 0.0;
  for (int k = 0; k < g_trial_.size(); ++k) m += (w[k] * g_trial_[k]) * (w[k] * g_trial_[k]);
  return 0.5 * m;
}

// Factors the assembled matrix with the smallest shift of 0, then ShiftBase() x 10^k, that works,
// up to kShiftCap times its largest diagonal entry. *shift_failed: the last shift that failed
// (-1: none).
// A shift s that factors H + s I factors it with every larger one (positive definiteness is
// monotone in s), so the lowest rung that works is searched for rather than climbed to: from the
// rung the last call needed (a step's matrices, and the shift they need, change little from one
// iteration or step to the next), downwards while it factors and upwards with a doubling stride
// while it does not, then by bisection between the highest rung known to fail and the lowest
// known to work. It is the rung a climb from the bottom finds: on the six-recording motion-fit
// benchmark (grippers whipping a cable, whose Newton matrices need shifts of ~10^8 ShiftBase at
// the predictor) a climb took 8.5 failed factorizations per shifted iteration.
bool NewtonMinimizer::FactorWithShift(double* shift, double* shift_failed) {
  LinearSolver& solver = p_->Solver();
  *shift = 0.0;
  *shift_failed = -1.0;
  ++summary_.factorizations;
  if (solver.Factor(0.0)) return true;
  const double diagonal = solver.MaxDiagonal();
  if (!std::isfinite(diagonal)) return false;
  const double cap = kShiftCap * std::max(diagonal, 1e-300);
  *shift_failed = 0.0;
  // The rungs first x kShiftGrowth^i up to the cap, each by the same products as a climb takes;
  // a first rung of 0 (or below) is the only one.
  const double first = std::min(p_->ShiftBase(), cap);
  auto rung = [&](int i) {
    double s = first;
    for (int k = 0; k < i; ++k) s *= kShiftGrowth;
    return s;
  };
  int rungs = 0;
  for (double s = first; s <= cap; s *= kShiftGrowth) {
    ++rungs;
    if (!(s > 0.0)) break;
  }
  if (rungs == 0) return false;
  int fail = -1;     // the highest rung known to fail (-1: the unshifted matrix)
  int works = rungs;  // the lowest rung known to work (rungs: none)
  int held = -1;     // the rung whose factor the solver holds
  auto probe = [&](int i) {
    ++summary_.factorizations;
    held = i;
    const bool ok = solver.Factor(rung(i));
    (ok ? works : fail) = i;
    return ok;
  };
  if (probe(std::clamp(shift_rung_, 0, rungs - 1))) {
    for (int stride = 1; fail < works - 1; stride *= 2)
      if (!probe(std::max(fail + 1, works - stride))) break;
  } else {
    for (int stride = 1; works == rungs && fail < rungs - 1; stride *= 2)
      probe(std::min(rungs - 1, fail + stride));
  }
  while (works - fail > 1) probe((fail + works) / 2);
  if (fail >= 0) *shift_failed = rung(fail);
  if (works == rungs) return false;
  shift_rung_ = works;
  *shift = rung(works);
  if (held != works) {
    ++summary_.factorizations;
    solver.Factor(*shift);
  }
  return true;
}

// Convergence by the residual alone.
bool NewtonMinimizer::ResidualConverged() const { return gnorm_ <= tol_.residual; }

// Convergence by an unshifted Newton step of relative size s at the current residual: within the
// step tolerance, or within kFloorRelaxation of it where the residual is at its round-off floor.
// A step computed at the iterate (not taken) counts only with the residual within
// kFloorRelaxation of its floor: a factor that lost the soft modes to round-off (a fine, stiff
// rod's Hessian) gives small steps far from the solution. A step just taken (converge_after_
// small_step, whose problems' matrices the inertia keeps well conditioned) needs no such guard:
// Newton's error after it is of the order of its square.
bool NewtonMinimizer::StepConverged(const RelativeStep& s, bool taken) const {
  const double floor = std::max(tol_.residual, tol_.floor);
  if (!taken && !(gnorm_ <= kFloorRelaxation * floor)) return false;
  return s.Within(1.0) || (gnorm_ <= floor && s.Within(kFloorRelaxation));
}

// Armijo backtracking from alpha along step_ (slope = r . step < 0 for a descent direction).
// A whole, unshifted step whose decrease the merit cannot resolve (a small correction near the
// solution) is judged by the residual instead: taken when it lowers the scaled residual.
bool NewtonMinimizer::LineSearch(double slope, double turn, bool shifted, double* alpha) {
  merit_not_finite_ = false;
  const double e0 = Merit();
  if (!std::isfinite(e0)) {
    merit_not_finite_ = true;
    return false;
  }
  const double noise = p_->EnergyNoise(e0);
  bool any_finite = false, any_retracted = false;
  for (int ls = 0; ls < options_.max_line_search_steps; ++ls, *alpha *= 0.5) {
    if (!p_->Retract(step_, *alpha)) continue;
    any_retracted = true;
    const double e1 = TrialMerit();
    any_finite = any_finite || std::isfinite(e1);
    const bool armijo =
        options_.merit == Merit::kResidual
            ? e1 <= (1.0 - 2.0 * kArmijo * *alpha) * e0 + 1e-24 * e0
            : e1 <= e0 + kArmijo * *alpha * slope + noise;
    if (std::isfinite(e1) && armijo) {
      energy_ = e1;
      energy_known_ = true;
      return true;
    }
    if (ls == 0 && *alpha == 1.0 && !shifted && options_.merit == Merit::kEnergy &&
        (turn <= kSmallCorrectionTurn || -slope <= kUnresolvedDecrease * noise)) {
      p_->TrialResidual(&g_trial_);
      if (Norm(g_trial_) < gnorm_) {
        energy_ = e1;
        energy_known_ = std::isfinite(e1);
        return true;
      }
    }
  }
  // Every trial's merit was a NaN or an infinity: the problem's values are not finite, which is
  // no failure of the line search's.
  merit_not_finite_ = any_retracted && !any_finite;
  return false;
}

// Leaves a saddle along d (negative curvature): the first step along +-d, from 0.1 L down by
// halves, that lowers the merit beyond round-off.
bool NewtonMinimizer::EscapeSaddle() {
  VecX& d = d_;  // the direction, in place (no copy: the runtime's ticks allocate nothing)
  const VecX& w = p_->NormWeights();
  for (int k = 0; k < d.size(); ++k)
    if (w[k] == 0.0) d[k] = 0.0;  // held rows
  const double dmax = d.cwiseAbs().maxCoeff();
  if (!(dmax > 0.0)) return false;
  d /= dmax;
  const double e0 = Merit();
  const double noise = p_->EnergyNoise(e0);
  const double L = p_->Length();
  for (double a = 0.1 * L; a > 1e-9 * L; a *= 0.5) {
    for (double sgn : {1.0, -1.0}) {
      if (!p_->Retract(d, sgn * a)) continue;
      const double e = p_->TrialEnergy();
      if (std::isfinite(e) && e < e0 - 10.0 * noise) {
        p_->AcceptTrial();
        energy_ = e;
        energy_known_ = true;
        return true;
      }
    }
  }
  return false;
}

// The lowest merit along +-d (negative curvature), scanning amplitudes from 0.2 L down by halves:
// its signed amplitude and merit, when it lowers the merit beyond round-off. Far from
// equilibrium an indefinite Hessian (a straight segment compressed between held points) makes
// the shifted Newton step tiny while the buckling mode lowers the merit by orders of magnitude.
bool NewtonMinimizer::BestAlongNegativeCurvature(double* best_amplitude, double* best_energy) {
  const VecX& w = p_->NormWeights();
  for (int k = 0; k < d_.size(); ++k)
    if (w[k] == 0.0) d_[k] = 0.0;
  const double dmax = d_.cwiseAbs().maxCoeff();
  if (!(dmax > 0.0)) return false;
  d_ /= dmax;
  const double e0 = Merit();
  const double L = p_->Length();
  double best = e0;
  for (double sgn : {1.0, -1.0}) {
    double previous = std::numeric_limits<double>::infinity();
    for (double a = 0.2 * L; a > 1e-6 * L; a *= 0.5) {
      if (!p_->Retract(d_, sgn * a)) continue;
      const double e = p_->TrialEnergy();
      if (!std::isfinite(e)) continue;
      if (e < best) {
        best = e;
        *best_amplitude = sgn * a;
      }
      if (e > previous && previous < e0) break;  // past the best amplitude on this side
      previous = e;
    }
  }
  *best_energy = best;
  return best < e0 - 10.0 * p_->EnergyNoise(e0);
}

NewtonSummary NewtonMinimizer::Finish(Termination t) {
  summary_.termination = t;
  if (options_.merit == Merit::kEnergy && energy_known_) summary_.energy = energy_;
  return summary_;
}

// The iteration's phases (choose, evaluate and verify, test, factor, solve, take the step,
// book-keep) share the chord, verification and rate state in loop_, which each phase reads as the
// previous one left it, and the iteration's own decisions in k.
NewtonSummary NewtonMinimizer::Minimize(NewtonProblem* problem, const NewtonStart& start) {
  p_ = problem;
  summary_ = NewtonSummary();
  Reserve(p_->NumDofs());
  energy_known_ = false;
  if (options_.time_budget > 0.0)
    deadline_ = DeadlineAfter(options_.time_budget);
  loop_ = Loop();
  loop_.chord_basis = options_.chords == ChordPolicy::kWhenFinishing &&
                      (start.factor_current || start.factor_nearby);
  loop_.chord_next = options_.chords == ChordPolicy::kWhileContracting && start.factor_nearby;
  loop_.line_search = options_.merit != Merit::kEnergy || !options_.verify_steps_by_residual;
  // Iterations repeated at the same iterate (a chord replaced by Newton, a step undone) do not
  // count; this bounds them all the same.
  int evaluations_left = 4 * options_.max_iterations + 8;
  for (int it = 0;; ++it) {
    if (--evaluations_left < 0) return Finish(Termination::kIterationCap);
    Iteration k;
    k.it = it;
    k.reuse = it == 0 && start.factor_current;
    k.chord = ChooseChord(k, start);
    Flow flow = EvaluateAndVerify(k);
    if (flow == Flow::kGoOn && k.chord && options_.chords == ChordPolicy::kWhenFinishing)
      flow = FinishingChord(k);
    if (flow == Flow::kGoOn) flow = BeforeFactor(k);
    if (flow == Flow::kGoOn) flow = FactorAndTest(k);
    if (flow == Flow::kGoOn) flow = SolveAndTestStep(k);
    if (flow == Flow::kGoOn) flow = ClassifyStationaryPoint(k);
    if (flow == Flow::kGoOn) flow = TakeStep(k, start);
    if (flow == Flow::kGoOn) flow = AfterStep(k);
    if (flow == Flow::kStop) return Finish(loop_.stop);
    if (flow == Flow::kRepeat) --it;
  }
}

// Whether this iteration is a chord iteration: kWhenFinishing where the last steps' rate
// predicts a chord step reaches the tolerance, kWhileContracting while the kept factor contracts.
bool NewtonMinimizer::ChooseChord(const Iteration& k, const NewtonStart& start) const {
  if (options_.chords == ChordPolicy::kWhenFinishing && !k.reuse && loop_.chord_basis) {
    if (k.it == 0) return start.factor_nearby;
    if (!loop_.last_step_full) return false;
    const double rate = loop_.g_last / loop_.g_before_last;
    const double predicted = loop_.g_last * rate * (loop_.last_step_chord ? 1.0 : rate);
    const double margin = loop_.last_step_chord ? 1.0 : 10.0;
    const double floor_tol = std::max(tol_.residual, tol_.floor);
    // After the first step the rate is unknown: a warm start's first step is Newton's (or
    // a chord's) from close by, worth a residual to find out.
    return std::isnan(rate) || (predicted > margin * floor_tol &&
                                rate <= kChordPredictedRate && rate * predicted <= floor_tol);
  }
  if (options_.chords == ChordPolicy::kWhileContracting) return loop_.chord_next;
  return false;
}

// Evaluates the residual (and the matrix unless a chord or a kept factor serves), and verifies
// the whole step the last iteration took without the merit's test.
NewtonMinimizer::Flow NewtonMinimizer::EvaluateAndVerify(Iteration& k) {
  k.matrix = !k.chord && !k.reuse;
  const bool finite = Evaluate(k.matrix);
  if (!loop_.tolerances_known) {
    tol_ = p_->Tolerances();
    loop_.tolerances_known = true;
  }
  k.floor_tol = std::max(tol_.residual, tol_.floor);
  summary_.residual_at_solution = true;
  if (loop_.verify_pending) {
    loop_.verify_pending = false;
    // The whole step did not lower the residual (above its round-off floor, where a rise is
    // noise): back to the iterate before it, and this iteration again there.
    if (!finite || (!(gnorm_ < loop_.verify_from) && gnorm_ > tol_.floor && !ResidualConverged())) {
      p_->RestorePrevious();
      loop_.line_search = loop_.line_search || !loop_.verify_chord;
      loop_.chord_next = false;
      loop_.previous_gnorm = std::numeric_limits<double>::infinity();
      loop_.last_full = {-1.0, -1.0};
      energy_known_ = false;
      return Flow::kRepeat;
    }
  }
  if (!finite) return Stop(Termination::kNonFinite);
  return Flow::kGoOn;
}

// kWhenFinishing: a chord step where it is predicted to finish, checked by the energy; otherwise
// Newton from here (the matrix assembled at this iterate).
NewtonMinimizer::Flow NewtonMinimizer::FinishingChord(const Iteration& k) {
  const double g_last = loop_.g_last;
  const bool progress = std::isnan(g_last) || (gnorm_ / g_last <= kChordPredictedRate &&
                                               (gnorm_ / g_last) * gnorm_ <= k.floor_tol);
  bool taken = false;
  if (gnorm_ > k.floor_tol && progress && p_->ChordStep(g_, &step_)) {
    const double slope = g_.dot(step_);
    const double e0 = Merit();
    if (slope < 0.0 && p_->Caps(step_).alpha >= 1.0 && p_->Retract(step_, 1.0)) {
      const double e1 = p_->TrialEnergy();
      if (std::isfinite(e1) && e1 <= e0 + kArmijo * slope + p_->EnergyNoise(e0)) {
        p_->AcceptTrial();
        energy_ = e1;
        energy_known_ = true;
        taken = true;
      }
    }
  }
  if (taken) {
    ++summary_.iterations;
    ++summary_.chord_steps;
    loop_.g_before_last = loop_.g_last;
    loop_.g_last = gnorm_;
    loop_.last_step_full = loop_.last_step_chord = true;
    return Flow::kNext;
  }
  loop_.chord_basis = false;
  return Flow::kRepeat;
}

// The iteration and time caps, tested where no factor is owed at the solution.
NewtonMinimizer::Flow NewtonMinimizer::Capped(int it) {
  if (it >= options_.max_iterations) return Stop(Termination::kIterationCap);
  if (options_.time_budget > 0.0 && it > 0 && Clock::now() > deadline_)
    return Stop(Termination::kTimeBudget);
  return Flow::kGoOn;
}

// Before the factor: converged by the residual when no factor is wanted at the solution; the
// caps; kWhileContracting's test of the kept factor.
NewtonMinimizer::Flow NewtonMinimizer::BeforeFactor(Iteration& k) {
  k.factor_here = k.matrix && options_.factor_at_solution != FactorAtSolution::kNever;
  if (!k.factor_here && ResidualConverged()) {
    if (k.reuse) summary_.factor_at_solution = true;
    if (k.chord && options_.factor_at_solution == FactorAtSolution::kAlways) {
      loop_.chord_next = false;  // the matrix at the solution, for the factor kept there
      return Flow::kRepeat;
    }
    return Stop(Termination::kConverged);
  }
  if (!k.factor_here && Capped(k.it) == Flow::kStop) return Flow::kStop;
  const bool contracting = options_.chords == ChordPolicy::kWhileContracting;
  if (contracting && k.chord && gnorm_ > kChordContraction * loop_.previous_gnorm) {
    // The kept factor no longer contracts fast: this iteration again with the matrix.
    loop_.chord_next = false;
    loop_.previous_gnorm = std::numeric_limits<double>::infinity();
    return Flow::kRepeat;
  }
  k.refresh = contracting && k.chord && options_.chord_refresh > 0.0 &&
              gnorm_ > options_.chord_refresh * loop_.previous_gnorm;
  loop_.previous_gnorm = gnorm_;
  return Flow::kGoOn;
}

// Factors the matrix (shifted until it factors), then the tests that need the factor: converged
// with the factor kept at the solution, the caps, stagnation at the residual's floor.
NewtonMinimizer::Flow NewtonMinimizer::FactorAndTest(Iteration& k) {
  if (k.matrix) {
    if (!FactorWithShift(&k.shift, &k.shift_failed)) {
      const bool nan = !std::isfinite(p_->Solver().MaxDiagonal());
      return Stop(nan ? Termination::kNonFinite : Termination::kNotPositiveDefinite);
    }
    p_->OnFactor(k.shift > 0.0);
    loop_.chord_basis = options_.chords == ChordPolicy::kWhenFinishing && k.shift == 0.0;
  }
  k.shifted = k.shift > 0.0;
  summary_.shifted = k.shifted;
  if (k.shifted) ++summary_.shifted_factors;
  k.classify = options_.saddles != Saddles::kIgnore;
  if (k.factor_here && ResidualConverged() && !(k.shifted && k.classify)) {
    summary_.factor_at_solution = !k.shifted;
    return Stop(Termination::kConverged);
  }
  if (k.factor_here && Capped(k.it) == Flow::kStop) return Flow::kStop;
  if (options_.stagnation && !k.shifted && !k.chord && gnorm_ <= k.floor_tol &&
      loop_.last_step_full && p_->LastMove() <= p_->StagnationMove()) {
    // At the residual's floor after a whole step that moved no point by more than the
    // stagnation bound: the state is that close to the solution (no back-substitution needed).
    summary_.factor_at_solution = k.matrix || k.reuse;
    return Stop(Termination::kSmallStep);
  }
  return Flow::kGoOn;
}

// The step (the kept factor's chord step or Newton's), measured once for every test after it;
// converged when it is small and unshifted.
NewtonMinimizer::Flow NewtonMinimizer::SolveAndTestStep(Iteration& k) {
  if (k.chord) {
    if (!p_->ChordStep(g_, &step_)) {
      loop_.chord_next = false;
      return Flow::kRepeat;
    }
  } else {
    step_ = -g_;  // solved in place: no temporary per step
    p_->Solver().Solve(&step_);
  }
  k.measured = p_->Measure(step_);
  // A small unshifted step: converged. With converge_after_small_step the step is taken first
  // (Newton's error after it is of the order of its square); otherwise the iterate is within
  // the step of the solution and is kept (its factor, made here, is then the matrix's own).
  const bool after = options_.converge_after_small_step;
  if (!k.shifted && (!k.chord || after) &&
      (StepConverged(k.measured, after) ||
       (options_.converge_on_decrement && options_.merit == Merit::kEnergy &&
        -g_.dot(step_) <= kDecrementOfNoise * p_->EnergyNoise(Merit())))) {
    if (!after) {
      summary_.factor_at_solution = k.matrix || k.reuse;
      return Stop(ResidualConverged() ? Termination::kConverged : Termination::kSmallStep);
    }
    if (p_->Retract(step_, 1.0)) {
      p_->AcceptTrial();
      energy_known_ = false;
      ++summary_.iterations;
      if (k.chord) ++summary_.chord_steps;
      summary_.residual_at_solution = false;
      return Stop(Termination::kSmallStep);
    }
  }
  return Flow::kGoOn;
}

// A stationary point with negative curvature is a saddle (a column past its buckling load, kept
// straight by symmetry): step along the most negative curvature. No step that lowers the merit
// beyond round-off means the curvature is round-off around a neutral direction (an isotropic
// buckled column turning about its load axis): stable, though the factor is then not the
// matrix's own. A strategy that cannot look (NaN) reports it unstable.
NewtonMinimizer::Flow NewtonMinimizer::ClassifyStationaryPoint(const Iteration& k) {
  if (!(!k.chord && k.shifted && k.classify &&
        (ResidualConverged() || StepConverged(k.measured))))
    return Flow::kGoOn;
  const double rq = p_->Solver().NegativeCurvature(k.shift, k.shift_failed, kSaddleBisections,
                                                   g_, &d_);
  if (std::isnan(rq)) {
    summary_.stable = false;
    return Stop(Termination::kSmallStep);
  }
  const double dmax = std::max(d_.cwiseAbs().maxCoeff(), 1e-300);
  const double amplitude = 0.01 * p_->Length() / dmax;
  const bool clearly_negative =
      rq < 0.0 && 0.5 * -rq * d_.squaredNorm() * amplitude * amplitude >
                      100.0 * p_->EnergyNoise(Merit());
  if (options_.saddles == Saddles::kEscape && summary_.saddle_escapes < kMaxSaddleEscapes &&
      EscapeSaddle()) {
    ++summary_.saddle_escapes;
    ++summary_.iterations;
    loop_.last_step_full = false;
    loop_.chord_basis = false;
    loop_.chord_next = false;
    return Flow::kNext;
  }
  summary_.stable = !clearly_negative;
  return Stop(Termination::kSmallStep);
}

// Takes the step: whole and verified by the next residual, retracted as far as it goes (no
// merit), or by the line search, compared while shifted with the best point along the negative
// curvature.
NewtonMinimizer::Flow NewtonMinimizer::TakeStep(Iteration& k, const NewtonStart& start) {
  ++summary_.iterations;
  if (k.chord) ++summary_.chord_steps;
  const StepCaps caps = p_->Caps(step_);
  double& alpha = k.alpha;
  alpha = caps.alpha;
  const double slope = g_.dot(step_);
  bool accepted = false;
  const bool whole = !k.shifted && alpha >= 1.0;
  if (options_.merit == Merit::kEnergy && whole &&
      (k.chord || !loop_.line_search || (k.it == 0 && start.verify_first_step))) {
    // Taken as it is and verified by the residual at the next iteration.
    if (p_->Retract(step_, 1.0)) {
      p_->AcceptTrial();
      accepted = k.unchecked = true;
      alpha = 1.0;
      energy_known_ = false;
      loop_.verify_pending = true;
      loop_.verify_chord = k.chord;
      loop_.verify_from = gnorm_;
    } else if (k.chord) {
      loop_.chord_next = false;
      --summary_.iterations;
      --summary_.chord_steps;
      return Flow::kRepeat;
    }
  }
  if (!accepted && options_.merit == Merit::kNone) {
    for (int ls = 0; ls < options_.max_line_search_steps && !accepted; ++ls, alpha *= 0.5)
      accepted = p_->Retract(step_, alpha);
    if (accepted) {
      alpha *= 2.0;
      p_->AcceptTrial();
      energy_known_ = false;
    }
  } else if (!accepted) {
    // While shifted, the lowest point along the negative curvature is found first (its scan
    // uses the trial iterate), and preferred to the line search's when lower.
    double nc_amplitude = 0.0, nc_energy = std::numeric_limits<double>::infinity();
    bool nc = false;
    if (k.shifted && k.classify) {
      const double rq = p_->Solver().NegativeCurvature(k.shift, k.shift_failed,
                                                       kShiftedBisections, g_, &d_);
      if (rq < 0.0) nc = BestAlongNegativeCurvature(&nc_amplitude, &nc_energy);
    }
    accepted = LineSearch(slope, caps.turn, k.shifted, &alpha);
    const double newton_energy = accepted ? energy_ : std::numeric_limits<double>::infinity();
    if (nc && nc_energy < newton_energy && p_->Retract(d_, nc_amplitude)) {
      energy_ = p_->TrialEnergy();
      energy_known_ = true;
      accepted = true;
      alpha = 0.0;  // not a whole Newton step
    }
    if (accepted) p_->AcceptTrial();
  }
  if (accepted) return Flow::kGoOn;
  // An iterate at the residual's round-off floor whose unshifted Newton step is within
  // kFloorRelaxation of the step tolerance and cannot lower the merit further is at round-off.
  // (A small step with a large residual is not: the factor lost the soft modes.)
  if (!k.shifted && !k.chord && gnorm_ <= kFloorRelaxation * k.floor_tol &&
      k.measured.Within(kFloorRelaxation)) {
    summary_.factor_at_solution = k.matrix || k.reuse;
    return Stop(Termination::kRoundOff);
  }
  if (merit_not_finite_) return Stop(Termination::kNonFinite);
  return Stop(options_.merit == Merit::kNone ? Termination::kRetractionFailed
                                             : Termination::kLineSearchFailed);
}

// After a step taken: the rates and chords' book-keeping, stagnation at round-off, and
// convergence by the contraction of whole steps.
NewtonMinimizer::Flow NewtonMinimizer::AfterStep(const Iteration& k) {
  summary_.residual_at_solution = false;
  loop_.last_step_full = k.alpha == 1.0;
  loop_.last_step_chord = k.chord;
  loop_.g_before_last = loop_.g_last;
  loop_.g_last = gnorm_;
  if (options_.chords == ChordPolicy::kWhileContracting)
    loop_.chord_next = k.alpha == 1.0 && !k.shifted && !k.refresh;
  if (options_.stagnation) {
    // Stagnation at round-off: whole unshifted steps that move no point by more than the
    // stagnation bound and change the merit by its round-off only, three times running.
    const double e = k.unchecked ? std::numeric_limits<double>::quiet_NaN() : energy_;
    const double change = std::abs(e - loop_.previous_energy);
    loop_.stagnant = (!k.shifted && k.alpha == 1.0 && p_->LastMove() <= p_->StagnationMove() &&
                      change <= 10.0 * p_->EnergyNoise(e))
                         ? loop_.stagnant + 1
                         : 0;
    loop_.previous_energy = e;
    if (loop_.stagnant >= 3) return Stop(Termination::kRoundOff);
  }
  if (k.alpha == 1.0 && !k.shifted) {
    const RelativeStep& s = k.measured;
    if (options_.converge_on_rate && loop_.last_full.x >= 0.0) {
      // Newton and chord iterates converge linearly at least: the error left after this
      // step is about its size times the contraction of the step sizes.
      const double tiny = std::numeric_limits<double>::min();
      const double rate = std::max(s.x / std::max(loop_.last_full.x, tiny),
                                   s.theta / std::max(loop_.last_full.theta, tiny));
      if (rate < 1.0 && StepConverged({s.x * rate, s.theta * rate}, /*taken=*/true))
        return Stop(Termination::kContraction);
    }
    loop_.last_full = s;
  } else {
    loop_.last_full = {-1.0, -1.0};  // a damped or shifted step measures no contraction
  }
  return Flow::kNext;
}

}  // namespace rodfit
