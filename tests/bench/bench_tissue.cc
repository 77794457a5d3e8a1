// Tissue benchmark: the cost of a case with springs and a grasp against the same case
// without them. A scene without springs builds no spring term (RodModel has no zones, the
// assembly loop over zones is empty), so its cost must equal the plain rod's.
// Run: build/bench_tissue; one core, Release build.
#include <benchmark/benchmark.h>

#include "rodfit/solve/poke.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

struct Setup {
  RodSpec rod;
  Material material;
  LoadCase load_case;
  std::vector<SpringZone> zones;
};

// A bowel-like segment under gravity; variant 0: free, 1: springs in two zones, 2: springs and
// a grasp lifting s = 2L/3.
Setup Bowel(int segments, int variant) {
  Setup s;
  s.rod.length = 0.15;
  s.rod.segments = segments;
  s.rod.radius = 0.012;
  s.rod.linear_density = 0.45;
  s.material.bend_stiffness = 2e-4;
  s.material.twist_stiffness = 1.5e-4;
  s.material.stretch_stiffness = 40;
  s.material.spring_stiffness = 150;
  s.material.spring_parameters["mesentery"] = 400;
  s.load_case.clamp.tangent = Vec3(1, 0, 0);
  s.load_case.clamp.normal = Vec3(0, 0, 1);
  if (variant >= 1) s.zones = {{0.0, 0.07, ""}, {0.07, 0.15, "mesentery"}};
  if (variant >= 2) s.load_case.grasp = Grasp{0.1, Vec3(0.1, 0.005, 0.02)};
  return s;
}

void BM_Bowel(benchmark::State& st) {
  const Setup s = Bowel(static_cast<int>(st.range(0)), static_cast<int>(st.range(1)));
  const RodModel model(s.rod, s.material, Vec3(0, 0, -9.81), s.load_case, s.zones);
  StaticsSummary summary;
  for (auto _ : st) {
    RodState state = model.StraightState();
    summary = SolveStatics(model, StaticsOptions(), &state);
    benchmark::DoNotOptimize(state.x.data());
  }
  if (!summary.converged) st.SkipWithError(summary.BriefReport().c_str());
  st.counters["newton_iterations"] = summary.iterations;
  st.SetLabel(st.range(1) == 0 ? "free" : st.range(1) == 1 ? "springs" : "springs+grasp");
}
BENCHMARK(BM_Bowel)->ArgsProduct({{50, 200}, {0, 1, 2}})->Unit(benchmark::kMillisecond);

// The cross-section on top of a solved rod: the ring solve at the poke and the tube mesh with
// the dent propagated (eqs. 12-13). A case without a poke builds neither.
void BM_Poke(benchmark::State& st) {
  Setup s = Bowel(static_cast<int>(st.range(0)), 1);
  s.load_case.poke = Poke{0.075, Vec3(0, -0.02, 0)};
  SectionSpec section;
  section.radius = 0.012;
  section.nodes = 32;
  section.stop_factor = 0.002;
  const RodModel model(s.rod, s.material, Vec3(0, 0, -9.81), s.load_case, s.zones);
  RodState state = model.StraightState();
  if (!SolveStatics(model, StaticsOptions(), &state).converged) st.SkipWithError("rod");
  const RingStiffness ring{2e-5, 5.0};
  for (auto _ : st) {
    const PokeResult poke = SolvePoke(model, state, section, ring);
    if (st.range(1)) benchmark::DoNotOptimize(PokedTube(model, state, section, poke).vertices.data());
    benchmark::DoNotOptimize(poke.ring.nodes.data());
  }
  st.SetLabel(st.range(1) ? "ring + tube mesh" : "ring only");
}
BENCHMARK(BM_Poke)->ArgsProduct({{50, 200}, {0, 1}})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
