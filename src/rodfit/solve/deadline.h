// The steady-clock deadline a wall-time budget in seconds sets, for the solvers that stop on one
// (NewtonMinimizer, DynamicsStepper): one conversion, saturated, for every budget a caller may give.
#pragma once

#include <chrono>

namespace rodfit {

/// Now plus `seconds` on the steady clock. A budget of kNeverSeconds or more (1e308 and infinity
/// included: the runtime, its C API, NewtonOptions and DynamicsOptions take any budget >= 0)
/// gives time_point::max(), a deadline never reached: converting it to the clock's 64-bit nanoseconds would overflow, which
/// is undefined behaviour (in practice a deadline in the past, so every step "ran out of time",
/// or a wrapped difference later; the sanitized C API corpus found it).
inline std::chrono::steady_clock::time_point DeadlineAfter(double seconds) {
  using Clock = std::chrono::steady_clock;
  // ~32 years: far beyond any step, and far below the ~292 years of nanoseconds the clock's
  // 64-bit count holds past its epoch (the machine's boot), so the sum below cannot overflow.
  constexpr double kNeverSeconds = 1e9;
  if (!(seconds < kNeverSeconds)) return Clock::time_point::max();
  return Clock::now() +
         std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

}  // namespace rodfit
