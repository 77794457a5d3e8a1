// Statics benchmark: solve time against segment count (50 to 100,000) for a 3-D heavy suture
// with a tip load, solved from straight, and a warm-started re-solve after a small load change;
// a wire held by two clamps (its end clamp reached by continuation from the straight rod), whole
// and as a symmetric half.
// From 20,000 segments Newton runs in edge coordinates (solve/edge_solver.h).
// Run: build/bench_statics [--benchmark_filter=...]; one core, Release build.
#include <algorithm>

#include <benchmark/benchmark.h>

#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/statics.h"
#include "rodfit/solve/statics_workspace.h"
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


// A heavy wire 1.5 m long between two clamps 1 m apart, tilted out of the plane of gravity
// (a 3-D, twisted sag), mirror images in the plane x = 0.5 m: the whole rod (`symmetric` 0) or
// the half (1). Segments odd (an edge crosses the plane).
Scene TwoClampWire(int segments, bool symmetric) {
  Scene s;
  s.rod.length = 1.5;
  s.rod.segments = segments;
  s.rod.radius = 1e-3;
  s.rod.linear_density = 0.05;
  s.material.bend_stiffness = 1e-3;
  s.material.twist_stiffness = 8e-4;
  s.material.stretch_stiffness = 1e5;
  s.gravity = Vec3(0, 0, -9.81);
  LoadCase c;
  c.name = "bridge";
  c.clamp.tangent = Vec3(1, 0.5, 0.3);
  c.clamp.normal = Vec3(0, 0, 1);
  EndClamp ec;
  ec.position = Vec3(1.0, 0, 0);
  ec.tangent = Vec3(1, -0.5, -0.3);
  const Vec3 d3 = c.clamp.tangent.normalized();
  Vec3 d1 = (c.clamp.normal - c.clamp.normal.dot(d3) * d3).normalized();
  d1.x() = -d1.x();
  ec.normal = d1;
  c.end_clamp = ec;
  if (symmetric) c.symmetry = SymmetryPlane{Vec3(0.5, 0, 0), Vec3(1, 0, 0)};
  s.cases.push_back(c);
  return s;
}

// From the straight rod: the end clamp (or the half's plane) moved in by continuation.
void BM_TwoClampsFromStraight(benchmark::State& st) {
  const Scene s = TwoClampWire(static_cast<int>(st.range(0)), st.range(1) != 0);
  CaseSolution solution;
  for (auto _ : st) {
    solution = SolveCase(s, 0, nullptr);
    benchmark::DoNotOptimize(solution.state.x.data());
  }
  if (!solution.ok()) st.SkipWithError(solution.summary.BriefReport().c_str());
  st.counters["newton_iterations"] = solution.summary.iterations;
  st.counters["continuation_steps"] = solution.summary.continuation_steps;
}
BENCHMARK(BM_TwoClampsFromStraight)->ArgsProduct({{101, 1001, 10001}, {0, 1}})
    ->ArgNames({"segments", "symmetric"})->Unit(benchmark::kMillisecond);

// Warm re-solves after a 1 % change of gravity, whole rod against half.
void BM_TwoClampsWarmResolve(benchmark::State& st) {
  Scene s = TwoClampWire(static_cast<int>(st.range(0)), st.range(1) != 0);
  const CaseSolution base = SolveCase(s, 0, nullptr);
  if (!base.ok()) {
    st.SkipWithError(base.summary.BriefReport().c_str());
    return;
  }
  const RodModel& model = *base.model;
  s.gravity *= 1.01;
  const RodModel heavier(s.rod, s.material, s.gravity, s.cases[0]);
  AlternatingResolves(st, model, heavier);
}
BENCHMARK(BM_TwoClampsWarmResolve)->ArgsProduct({{101, 1001, 10001}, {0, 1}})
    ->ArgNames({"segments", "symmetric"})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
