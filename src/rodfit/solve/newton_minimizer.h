// The one Newton minimizer of rodfit (docs/architecture.md, "Solvers"): every problem that
// minimises a merit over a rod's (or a ring's) state with held rows — a static equilibrium, an
// implicit time step's incremental potential, a haptic tick, the section ring — states itself as
// a NewtonProblem and is solved by this loop. Modelled on Ceres' TrustRegionMinimizer: the
// loop's state lives in members and each phase is a method; the linear solve is a strategy
// (LinearSolver, linear_solvers.h); the result is a typed Termination with a fixed message.
//
// What the loop owns, once: the diagonal-shift policy for an indefinite matrix, the Armijo line
// search with the problem's step caps (the largest turn of a tangent), chord steps on a kept
// factor, the NaN-propagating scaled residual norm, the convergence tests (residual, Newton
// step, contraction, stagnation at round-off), the iteration cap and the wall-time budget, and
// the escape from saddles along negative curvature. Every constant is named below with its
// reason. Nothing allocates once the scratch has the problem's size (Reserve), and a failure
// allocates nothing either (TerminationMessage is a fixed table): the haptic ticks rely on it.
#pragma once

#include <chrono>
#include <limits>

#include <Eigen/Core>

#include "rodfit/solve/termination.h"

namespace rodfit {

using VecX = Eigen::VectorXd;

/// The linear solve of a Newton iteration, as a strategy (linear_solvers.h): the problem
/// assembles its matrix into the strategy's storage, the minimizer factors it (with a diagonal
/// shift when it must) and solves with the factor.
class LinearSolver {
 public:
  virtual ~LinearSolver() = default;
  /// Factors the assembled matrix plus `shift` on its diagonal. False when it is not positive
  /// definite (symmetric strategies) or singular (LU), or not finite.
  virtual bool Factor(double shift) = 0;
  /// x <- A^-1 x with the last factor.
  virtual void Solve(VecX* x) const = 0;
  /// The largest |A_ii| of the assembled matrix (the shift's cap); NaN or infinity when the
  /// matrix is not finite.
  virtual double MaxDiagonal() const = 0;
  /// A direction of negative curvature of the assembled (symmetric) matrix, given a shift that
  /// factors and one that does not (-1: none tried): the Rayleigh quotient of the direction found
  /// (< 0 when one is), *d scaled to max |d_k| = 1. Symmetric strategies with a band only;
  /// others return 0 (no saddle escapes).
  virtual double NegativeCurvature(double shift_ok, double shift_failed, int bisections,
                                   const VecX& gradient, VecX* d) {
    (void)shift_ok, (void)shift_failed, (void)bisections, (void)gradient, (void)d;
    return 0.0;
  }
};

/// Tolerances of one solve, in the problem's residual measure (NewtonProblem::NormWeights).
struct NewtonTolerances {
  double residual = 0.0;  ///< converged when the scaled residual is at most this
  /// The residual's round-off floor (>= 0): at or below max(residual, floor) the Newton step, not
  /// the residual, tells how far the state is (a stiff stretch leaves a floor of ~eps EA).
  double floor = 0.0;
};

/// The size of a step relative to the step tolerance, in the problem's two kinds of unknowns
/// (positions and angles for a rod; one kind for a ring): 1 means at the tolerance.
struct RelativeStep {
  double x = 0.0;
  double theta = 0.0;
  bool Within(double factor) const { return x <= factor && theta <= factor; }
};

/// The caps on one step: the largest fraction alpha <= 1 that keeps every tangent's turn (and an
/// edge's strain change) within the problem's limits, and the largest turn [rad] of the full step.
struct StepCaps {
  double alpha = 1.0;
  double turn = 0.0;
};

/// What the minimizer needs of a problem. "Current" is the iterate the loop stands on; a step is
/// tried on a separate "trial" iterate, which AcceptTrial makes current (keeping the old one, so
/// that RestorePrevious can undo the step).
class NewtonProblem {
 public:
  virtual ~NewtonProblem() = default;
  virtual int NumDofs() const = 0;
  /// The residual (the merit's gradient, held rows zero) at the current iterate into *residual;
  /// with `matrix`, also the Newton matrix into the linear solver's storage (held rows identity).
  virtual void Evaluate(bool matrix, VecX* residual) = 0;
  /// The merit at the current iterate (energy merits only).
  virtual double Energy() = 0;
  /// trial = current (+) alpha step. False when the retraction fails (trial then unusable).
  virtual bool Retract(const VecX& step, double alpha) = 0;
  /// The merit and the residual at the trial iterate.
  virtual double TrialEnergy() = 0;
  virtual void TrialResidual(VecX* residual) = 0;
  /// The trial becomes the current iterate; the current one is kept for RestorePrevious.
  virtual void AcceptTrial() = 0;
  virtual void RestorePrevious() = 0;
  virtual StepCaps Caps(const VecX& step) = 0;
  virtual RelativeStep Measure(const VecX& step) = 0;
  /// The largest distance [m] any point moved in the last accepted step (stagnation test).
  virtual double LastMove() { return std::numeric_limits<double>::infinity(); }
  /// The stagnation test's bound on LastMove (1e3 times the step tolerance's length).
  virtual double StagnationMove() { return 0.0; }
  /// Weights w_k of the scaled residual max_k w_k |r_k| (zero on held rows).
  virtual const VecX& NormWeights() = 0;
  /// The round-off of the merit near `energy` (its Armijo tests accept that much rise).
  virtual double EnergyNoise(double energy) = 0;
  /// Known after the first Evaluate (a step's scale may depend on its first residual).
  virtual NewtonTolerances Tolerances() = 0;
  /// The first diagonal shift for an indefinite matrix: a small fraction of the problem's softest
  /// stiffness (not of the diagonal, which a stiff stretch dominates).
  virtual double ShiftBase() = 0;
  virtual LinearSolver& Solver() = 0;
  /// A chord step: *step = -K^-1 residual with a factor kept from an earlier iterate (the
  /// statics carry theirs to the current edge directions). False when it cannot be used.
  virtual bool ChordStep(const VecX& residual, VecX* step) {
    *step = -residual;
    Solver().Solve(step);
    return true;
  }
  /// A new factor was made (unshifted: it may serve chord steps).
  virtual void OnFactor(bool shifted) { (void)shifted; }
  /// The characteristic length [m] of the problem (the saddle search's amplitudes).
  virtual double Length() { return 1.0; }
};

/// The merit the line search descends.
enum class Merit : unsigned char {
  kEnergy,    ///< the problem's energy (a potential, an incremental potential)
  kResidual,  ///< 1/2 |W r|^2: a balance without potential (moments), Newton descends it
  kNone,      ///< no merit: the capped step is taken (a dynamic step with moment loads)
};

/// How chord steps (a kept factor, no new matrix) are used.
enum class ChordPolicy : unsigned char {
  kOff,
  /// Statics: a chord step only where it is predicted to reach the tolerance by itself (the
  /// contraction of the step before is below kChordPredictedRate), checked by the energy; where
  /// convergence is predicted the matrix is assembled instead, so that the factor kept at the
  /// solution is the Hessian's own (sensitivities solve with it).
  kWhenFinishing,
  /// Steps and ticks: after every whole, unshifted step, while each cuts the residual at least
  /// by kChordContraction, checked by the residual at the next iteration (undone if it rose).
  kWhileContracting,
};

/// Whether the factor at the final iterate must be the matrix's own (made there, unshifted).
enum class FactorAtSolution : unsigned char {
  kNever,          ///< no: the solve may end on a chord iteration or after a step
  kWhenAssembled,  ///< where the final iterate's matrix was assembled, it is factored too
  kAlways,         ///< yes: the final iterate's matrix is assembled and factored (sensitivities)
};

/// What the loop does with negative curvature (symmetric strategies that can look for it).
enum class Saddles : unsigned char {
  kIgnore,    ///< nothing: a shifted matrix only gives a descent direction
  /// While shifted, the lowest point along the most negative curvature is taken when it is lower
  /// than the line search's; a stationary point reached with a shifted matrix is classified as
  /// stable (round-off curvature) or not (NewtonSummary::stable).
  kClassify,
  /// kClassify, and a stationary point with negative curvature is left along it (up to
  /// kMaxSaddleEscapes times): a straight column past its buckling load buckles.
  kEscape,
};

struct NewtonOptions {
  int max_iterations = 300;
  int max_line_search_steps = 30;  ///< halvings before a step counts as failed
  Merit merit = Merit::kEnergy;
  ChordPolicy chords = ChordPolicy::kOff;
  /// A whole, unshifted Newton step is taken without the merit's test and verified by the
  /// residual at the next iteration, undone (and the iteration repeated with the line search)
  /// if the residual did not fall: near a solution the energy test costs two evaluations and
  /// cannot resolve the step's decrease anyway.
  bool verify_steps_by_residual = false;
  /// A whole, unshifted step within the step tolerance ends the solve after it is taken (steps
  /// and ticks). Off, the solve ends only at an evaluated iterate (statics: the factor kept at the
  /// solution must be the Hessian there).
  bool converge_after_small_step = false;
  FactorAtSolution factor_at_solution = FactorAtSolution::kNever;
  /// Also converged when the last whole step's size times the contraction of the step sizes
  /// (the estimate of the error left) is within the step tolerance: CVODE's test.
  bool converge_on_rate = false;
  /// Converged after three whole, unshifted steps in a row that move no point by more than
  /// StagnationMove and change the merit by round-off only (a fine rod's gradient floor).
  bool stagnation = false;
  /// Converged when an unshifted Newton step promises a decrease (-r . p) below
  /// kDecrementOfNoise times the merit's round-off: the merit can tell nothing more (the ring,
  /// whose residual floor from cancellation in its turning angles is not known beforehand).
  bool converge_on_decrement = false;
  Saddles saddles = Saddles::kIgnore;
  /// Chord steps (kWhileContracting): one that cut the residual by less than this ratio is
  /// followed by a new factor, so that the next solve starts from a fresh one (0: never).
  double chord_refresh = 0.0;
  /// [s] wall time one Minimize may take (0: no limit), checked before each iteration after
  /// the first.
  double time_budget = 0.0;
};

/// How a Minimize starts.
struct NewtonStart {
  /// The linear solver holds the factor of the matrix at the current iterate: the first
  /// iteration evaluates the residual only and solves with it.
  bool factor_current = false;
  /// The linear solver holds a factor of a nearby iterate (statics: another model's; a tick: the
  /// last tick's): the first iteration is a chord step when chords are on.
  bool factor_nearby = false;
  /// The first whole, unshifted Newton step is verified by the residual (a runtime tick started
  /// from a prediction within the linear response of the equilibrium).
  bool verify_first_step = false;
};

struct NewtonSummary {
  Termination termination = Termination::kIterationCap;
  int iterations = 0;     ///< steps taken (Newton and chord)
  int chord_steps = 0;    ///< of which chord steps
  int factorizations = 0;
  int saddle_escapes = 0;
  bool shifted = false;   ///< the last factor needed a diagonal shift
  int shifted_factors = 0;  ///< iterations whose matrix needed a diagonal shift
  /// False when the solve ended at a stationary point with clearly negative curvature.
  bool stable = true;
  /// The last factor is the unshifted matrix at the final iterate (statics keep it).
  bool factor_at_solution = false;
  /// The last evaluated residual is at the final iterate (its held rows read reactions).
  bool residual_at_solution = false;
  double residual_norm = 0.0;  ///< scaled residual at the last evaluation
  double energy = 0.0;         ///< merit at exit (energy merits)
  bool converged() const { return IsConverged(termination); }
  const char* message() const { return TerminationMessage(termination); }
};

class NewtonMinimizer {
 public:
  explicit NewtonMinimizer(const NewtonOptions& options = NewtonOptions()) : options_(options) {}
  NewtonOptions& options() { return options_; }
  const NewtonOptions& options() const { return options_; }
  /// Sizes the scratch for problems of `dofs` unknowns: later solves of that size allocate
  /// nothing.
  void Reserve(int dofs);
  /// Minimizes from the problem's current iterate, which is left at the last accepted one.
  NewtonSummary Minimize(NewtonProblem* problem, const NewtonStart& start = NewtonStart());
  /// The residual at the last evaluation (the final iterate's when residual_at_solution).
  const VecX& residual() const { return g_; }
  /// The last Newton step (its unshifted solve at the final iterate after kSmallStep).
  const VecX& step() const { return step_; }

  // The constants of the loop, each once, with its reason.
  /// Armijo's sufficient-decrease constant (Nocedal & Wright's usual 1e-4).
  static constexpr double kArmijo = 1e-4;
  /// Diagonal shifts grow tenfold per failed factorisation (a decade search: a few factors find
  /// the smallest that works within a factor ten).
  static constexpr double kShiftGrowth = 10.0;
  /// ... and stop at this times the largest diagonal entry: beyond it the step is a gradient
  /// step too short to matter, and the matrix is taken as hopeless.
  static constexpr double kShiftCap = 1e6;
  /// Relaxations of the step test at the residual's round-off floor: a step within this times
  /// the step tolerance counts there; and a small step counts only with the residual within this
  /// times its floor (a factor that lost the soft modes to round-off gives small steps far from
  /// the solution).
  static constexpr double kFloorRelaxation = 1e3;
  /// kWhenFinishing: a chord step is taken where the rate of the step before predicts it reaches
  /// the tolerance by itself at this rate or better (two chords cost about one Newton step).
  static constexpr double kChordPredictedRate = 0.1;
  /// kWhileContracting: a chord step that cut the residual by less than this is replaced by a
  /// Newton iteration (the mass-dominated matrix of a time step changes little within a step).
  static constexpr double kChordContraction = 0.25;
  /// Saddle escapes per solve (each a step along negative curvature).
  static constexpr int kMaxSaddleEscapes = 5;
  /// Bisections of the shift when a direction of negative curvature is looked for: at a
  /// stationary point (to tell a saddle from round-off) and while shifted (to compare).
  static constexpr int kSaddleBisections = 12;
  static constexpr int kShiftedBisections = 5;
  /// A full, unshifted step is judged by the residual instead of the energy where its decrease
  /// is below what the energy resolves: its largest turn [rad] below this, or its slope within
  /// this times the energy's round-off.
  static constexpr double kSmallCorrectionTurn = 1e-3;
  static constexpr double kUnresolvedDecrease = 1e3;
  /// converge_on_decrement: the fraction of the merit's round-off a Newton decrement may promise.
  static constexpr double kDecrementOfNoise = 0.25;

 private:
  using Clock = std::chrono::steady_clock;
  double Norm(const VecX& r) const;
  bool Evaluate(bool matrix);
  bool FactorWithShift(double* shift, double* shift_failed);
  bool ResidualConverged() const;
  bool StepConverged(const RelativeStep& s, bool taken = false) const;
  bool LineSearch(double slope, double turn, bool shifted, double* alpha);
  bool EscapeSaddle();
  bool BestAlongNegativeCurvature(double* best_amplitude, double* best_energy);
  double Merit();
  double TrialMerit();

  // Minimize's iteration, phase by phase. Each phase returns what the loop does next: the next
  // phase (kGoOn), the next iteration (kNext), this iteration again at the same iterate, not
  // counted (kRepeat), or stop with loop_.stop (kStop).
  enum class Flow { kGoOn, kNext, kRepeat, kStop };
  // What one iteration decided, read by its later phases.
  struct Iteration {
    int it = 0;
    bool reuse = false;        // the first iteration solves with the start's factor
    bool chord = false;        // a chord iteration (the kept factor, no matrix)
    bool matrix = false;       // the matrix is assembled (and factored) here
    double floor_tol = 0.0;    // max(residual tolerance, its round-off floor)
    bool factor_here = false;  // the matrix is factored even at the solution
    bool refresh = false;      // kWhileContracting: the chord contracts too slowly to keep
    double shift = 0.0, shift_failed = -1.0;  // FactorWithShift's
    bool shifted = false;
    bool classify = false;     // saddles are looked for
    RelativeStep measured;     // the step's size against its tolerance
    double alpha = 0.0;        // the step length taken
    bool unchecked = false;    // taken whole, to be verified by the next residual
  };
  // The state one iteration leaves to the next (chords, verification, rates, stagnation).
  struct Loop {
    // kWhenFinishing: a kept factor usable for chord steps (from the start, or the last
    // unshifted factor), and the residuals of the last two steps (their ratio is the rate).
    bool chord_basis = false;
    double g_last = std::numeric_limits<double>::quiet_NaN();
    double g_before_last = std::numeric_limits<double>::quiet_NaN();
    bool last_step_full = false, last_step_chord = false;
    // kWhileContracting: the next iteration is a chord iteration; the residual before it.
    bool chord_next = false;
    double previous_gnorm = std::numeric_limits<double>::infinity();
    // A whole step taken without the merit's test, to be verified by the next residual.
    bool verify_pending = false, verify_chord = false;
    double verify_from = 0.0;
    bool line_search = true;
    RelativeStep last_full{-1.0, -1.0};  // converge_on_rate: the last whole step's size
    int stagnant = 0;
    double previous_energy = std::numeric_limits<double>::quiet_NaN();
    bool tolerances_known = false;
    Termination stop = Termination::kConverged;  // the termination of a kStop
  };
  Flow Stop(Termination t) {
    loop_.stop = t;
    return Flow::kStop;
  }
  NewtonSummary Finish(Termination t);
  bool ChooseChord(const Iteration& k, const NewtonStart& start) const;
  Flow EvaluateAndVerify(Iteration& k);
  Flow FinishingChord(const Iteration& k);
  Flow Capped(int it);
  Flow BeforeFactor(Iteration& k);
  Flow FactorAndTest(Iteration& k);
  Flow SolveAndTestStep(Iteration& k);
  Flow ClassifyStationaryPoint(const Iteration& k);
  Flow TakeStep(Iteration& k, const NewtonStart& start);
  Flow AfterStep(const Iteration& k);

  NewtonOptions options_;
  NewtonProblem* p_ = nullptr;
  NewtonSummary summary_;
  NewtonTolerances tol_;
  VecX g_, g_trial_, step_, d_;
  double gnorm_ = 0.0;
  double energy_ = 0.0;
  bool energy_known_ = false;
  bool merit_not_finite_ = false;  // the last line search met only non-finite merits
  int shift_rung_ = 0;  // the ladder's rung the last shifted factor needed (FactorWithShift)
  Loop loop_;  // Minimize's state between iterations
  Clock::time_point deadline_;
};

}  // namespace rodfit
