// Statics benchmark: solve time against segment count (50 to 100,000) for a 3-D heavy suture
// with a tip load, solved from straight, and a warm-started re-solve after a small load change.
// From 20,000 segments Newton runs in edge coordinates (solve/edge_solver.h).
// Run: build/bench_statics [--benchmark_filter=...]; one core, Release build.
#include <algorithm>

#include <benchmark/benchmark.h>

#include "rodfit/solve/statics.h"
#include "../solve/test_util.h"

namespace rodfit {
namespace {

// A nylon-like suture clamped at 29 degrees above horizontal, sagging under gravity with a
// sideways tip force: a fully 3-D, bent and twisted equilibrium.
Scene HeavySuture(int segments) { return testing::BenchmarkSuture(segments); }

void BM_SolveFromStraight(benchmark::State& st) {
  const Scene s = HeavySuture(static_cast<int>(st.range(0)));
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
  StaticsWorkspace ws;
  StaticsSummary summary;
  for (auto _ : st) {
    RodState state = model.StraightState();
    summary = SolveStatics(model, StaticsOptions(), &state, &ws);
    benchmark::DoNotOptimize(state.x.data());
  }
  if (!summary.converged) st.SkipWithError(summary.BriefReport().c_str());
  st.counters["newton_iterations"] = summary.iterations;
  st.counters["chord_steps"] = summary.chord_steps;
  st.SetComplexityN(st.range(0));
}
BENCHMARK(BM_SolveFromStraight)->Arg(50)->Arg(100)->Arg(500)->Arg(1000)->Arg(5000)->Arg(10000)
    ->Arg(100000)->Unit(benchmark::kMillisecond)->Complexity(benchmark::oN);

// Re-solves alternating between two models (a 1% change of one input), each from the previous
// equilibrium with the previous workspace (and its kept factorisation), as a haptic loop or a
// fit does; one timed iteration is one re-solve.
void AlternatingResolves(benchmark::State& st, const RodModel& a, const RodModel& b) {
  RodState state = a.StraightState();
  StaticsWorkspace ws;
  if (!SolveStatics(a, StaticsOptions(), &state, &ws).converged) st.SkipWithError("base");
  StaticsSummary summary;
  int iterations = 0, chord_steps = 0, solves = 0;
  for (auto _ : st) {
    summary = SolveStatics((solves % 2 == 0) ? b : a, StaticsOptions(), &state, &ws);
    iterations += summary.iterations;
    chord_steps += summary.chord_steps;
    ++solves;
    if (!summary.converged) break;
    benchmark::DoNotOptimize(state.x.data());
  }
  if (!summary.converged) st.SkipWithError(summary.BriefReport().c_str());
  st.counters["newton_iterations"] = double(iterations) / std::max(solves, 1);
  st.counters["chord_steps"] = double(chord_steps) / std::max(solves, 1);
}

// After a 1% change of the tip force (a dead load: the kept factor is the exact Hessian at the
// start, so the first Newton step reuses it).
void BM_WarmResolve(benchmark::State& st) {
  Scene s = HeavySuture(static_cast<int>(st.range(0)));
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
  s.cases[0].tip_force *= 1.01;
  AlternatingResolves(st, model, RodModel(s.rod, s.material, s.gravity, s.cases[0]));
}
BENCHMARK(BM_WarmResolve)->Arg(50)->Arg(100)->Arg(500)->Arg(1000)->Arg(5000)->Arg(10000)
    ->Arg(100000)->Unit(benchmark::kMillisecond);

// After a 1% change of the bending stiffness B1 (what a fit does between two evaluations): the
// Hessian changes, so the kept factor cannot be reused.
void BM_WarmResolveStiffness(benchmark::State& st) {
  Scene s = HeavySuture(static_cast<int>(st.range(0)));
  const RodModel model(s.rod, s.material, s.gravity, s.cases[0]);
  s.material.bend_stiffness *= 1.01;
  AlternatingResolves(st, model, RodModel(s.rod, s.material, s.gravity, s.cases[0]));
}
BENCHMARK(BM_WarmResolveStiffness)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
