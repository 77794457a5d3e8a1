// Dynamics benchmark: the cost of one time step of the real suture (nylon, L 0.2 m, r 0.125 mm,
// E 5 GPa; data/scenes/suture_swing.yaml) swinging down under gravity from horizontal, for the
// implicit integrators at dt = 1 ms (50, 100, 1000 segments) and the explicit one at its stable
// step; the explicit stable step; simulated seconds per wall-clock second; and the swing over a
// whole second, implicit at 1 ms against explicit at its stable step (largest vertex distance
// and the cost ratio). Run: build/bench_dynamics; one core, Release build.
#include <chrono>
#include <cmath>

#include <benchmark/benchmark.h>

#include "rodfit/solve/dynamics.h"
#include "rodfit/reference/cantilever_modes.h"

namespace rodfit {
namespace {

// The suture with air drag.
struct SutureSwing : reference::Suture {
  explicit SutureSwing(int segments) : reference::Suture(segments) { material.damping = 1e-5; }
};

const Vec3 kGravity(0, 0, -9.81);

// Steps the swing; restarts it from horizontal every `restart` steps so every timed step is
// of a rod in large motion.
void StepBenchmark(benchmark::State& st, Integrator integrator) {
  const SutureSwing swing(static_cast<int>(st.range(0)));
  const RodModel model(swing.rod, swing.material, kGravity, swing.load_case);
  DynamicsOptions options;
  options.integrator = integrator;
  if (integrator == Integrator::kExplicit) {
    DynamicsStepper probe(model, options);
    options.time_step = 0.8 * probe.StableTimeStep(model.StraightState());
  } else {
    options.time_step = 1e-3;
  }
  DynamicsStepper stepper(model, options);
  const DynamicState start = stepper.AtRest(model.StraightState());
  DynamicState s = start;
  const int restart = integrator == Integrator::kExplicit ? 200000 : 400;
  int steps = 0, newton = 0;
  for (auto _ : st) {
    if (steps % restart == 0) s = start;
    const DynamicsStepSummary r = stepper.Step(Drive(), &s);
    if (!r.ok) {
      st.SkipWithError(r.reason.c_str());
      break;
    }
    newton += r.newton_iterations;
    ++steps;
  }
  st.counters["time_step_s"] = options.time_step;
  st.counters["newton_per_step"] = steps ? static_cast<double>(newton) / steps : 0.0;
  // Simulated seconds per wall second: time_step / (wall time per step).
  st.counters["sim_s_per_wall_s"] =
      benchmark::Counter(options.time_step, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_Bdf2Step(benchmark::State& st) { StepBenchmark(st, Integrator::kBdf2); }
void BM_MidpointStep(benchmark::State& st) { StepBenchmark(st, Integrator::kMidpoint); }
void BM_BackwardEulerStep(benchmark::State& st) { StepBenchmark(st, Integrator::kBackwardEuler); }
void BM_ExplicitStep(benchmark::State& st) { StepBenchmark(st, Integrator::kExplicit); }
BENCHMARK(BM_Bdf2Step)->Arg(50)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MidpointStep)->Arg(50)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BackwardEulerStep)->Arg(50)->Arg(100)->Arg(1000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ExplicitStep)->Arg(50)->Arg(100)->Unit(benchmark::kMicrosecond);

// One second of the swing at 50 segments: BDF2 at 1 ms against the explicit integrator at 0.8
// of its stable step. Counters: the largest vertex distance over the second's 10 ms frames [mm],
// each run's wall time [s] and their ratio.
void BM_SwingOneSecondImplicitVersusExplicit(benchmark::State& st) {
  const SutureSwing swing(50);
  const RodModel model(swing.rod, swing.material, kGravity, swing.load_case);
  auto run = [&](Integrator integrator, double dt, std::vector<Mat3X>* frames, double* seconds) {
    DynamicsOptions options;
    options.integrator = integrator;
    options.time_step = dt;
    DynamicsStepper stepper(model, options);
    DynamicState s = stepper.AtRest(model.StraightState());
    const auto t0 = std::chrono::steady_clock::now();
    const int per_frame = static_cast<int>(std::lround(0.01 / dt));
    for (int f = 0; f < 100; ++f) {
      for (int k = 0; k < per_frame; ++k) {
        if (!stepper.Step(Drive(), &s).ok) return false;
      }
      frames->push_back(s.q.x);
    }
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return true;
  };
  DynamicsOptions probe_options;
  probe_options.integrator = Integrator::kExplicit;
  DynamicsStepper probe(model, probe_options);
  const double stable = probe.StableTimeStep(model.StraightState());
  const double explicit_dt = 0.01 / std::ceil(0.01 / (0.8 * stable));
  for (auto _ : st) {
    std::vector<Mat3X> implicit_frames, explicit_frames;
    double implicit_s = 0.0, explicit_s = 0.0;
    if (!run(Integrator::kBdf2, 1e-3, &implicit_frames, &implicit_s) ||
        !run(Integrator::kExplicit, explicit_dt, &explicit_frames, &explicit_s)) {
      st.SkipWithError("a run failed");
      break;
    }
    double worst = 0.0;
    for (size_t f = 0; f < implicit_frames.size(); ++f)
      worst = std::max(worst,
                       (implicit_frames[f] - explicit_frames[f]).colwise().norm().maxCoeff());
    st.counters["max_distance_mm"] = 1e3 * worst;
    st.counters["implicit_s"] = implicit_s;
    st.counters["explicit_s"] = explicit_s;
    st.counters["explicit_dt_s"] = explicit_dt;
    st.counters["cost_ratio"] = explicit_s / implicit_s;
  }
}
BENCHMARK(BM_SwingOneSecondImplicitVersusExplicit)->Iterations(1)->Unit(benchmark::kSecond);

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
