// Why a Newton solve stopped (src/rodfit/solve/newton_minimizer.h, the one minimizer every
// solver runs on): a typed termination with a fixed message, which the solvers' summaries carry
// and the CLI and the C API turn into a user's message. Nothing allocates: the haptic ticks read
// it.
#pragma once

namespace rodfit {

/// Why a minimization stopped. The first four are convergence.
enum class Termination : unsigned char {
  kConverged,            ///< the scaled residual is within its tolerance
  kSmallStep,            ///< an unshifted Newton step within the step tolerance
  kContraction,          ///< the steps' contraction puts the error left within the step tolerance
  kRoundOff,             ///< stagnated at round-off: the state is as exact as doubles make it
  kIterationCap,         ///< the iteration cap was reached
  kLineSearchFailed,     ///< no step length lowered the merit
  kNotPositiveDefinite,  ///< no diagonal shift up to its cap made the matrix factor
  kNonFinite,            ///< a NaN or infinity in the merit, residual or matrix
  kTimeBudget,           ///< the wall-time budget ran out
  kRetractionFailed,     ///< the problem could not take any step (an edge would fold back)
};

/// A fixed, static message per termination (no allocation: the haptic loop reads it).
const char* TerminationMessage(Termination termination);
inline bool IsConverged(Termination t) { return t <= Termination::kRoundOff; }

}  // namespace rodfit
