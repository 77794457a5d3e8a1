// The interactive runtime's tick (rodfit/runtime/runtime.h) at 50, 100 and 200 segments: the
// fitted bowel segment of data/profiles/bowel_drag.json grasped at 2/3 of its length and dragged
// along a horizontal circle (1 cm radius, one turn per 1000 ticks: 6 cm/s at 1 kHz), quasi-static
// and dynamic (BDF2, 1 ms), and the poked bowel of data/profiles/bowel_poke.json pushed with a
// force that rises and falls, quasi-static and dynamic, each tick followed by the tube mesh with
// the section's dent read into the loop's buffer (Runtime::Mesh(TubeMesh*): no allocation, the
// ring warm-started).
// Setup (loading, the first equilibrium, sizing the mesh buffer) is outside the timed loop; the
// time is per tick. Besides Google Benchmark's mean, each tick is timed on its own and the
// counter `median_us` is the median over all of them (on a shared machine the mean carries every
// preemption; the median does not hide a slow path the way a best block would).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

namespace {

// Each tick's wall time, recorded into storage sized before the loop.
class TickTimes {
 public:
  explicit TickTimes(const benchmark::State& state) {
    us_.reserve(static_cast<size_t>(state.max_iterations));
  }
  void Start() { start_ = std::chrono::steady_clock::now(); }
  void Stop() {
    us_.push_back(
        std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start_)
            .count());
  }
  double Median() {
    if (us_.empty()) return 0.0;
    std::nth_element(us_.begin(), us_.begin() + us_.size() / 2, us_.end());
    return us_[us_.size() / 2];
  }

 private:
  std::vector<double> us_;
  std::chrono::steady_clock::time_point start_;
};

rodfit::Profile Bowel(const char* name, int segments) {
  rodfit::Profile p =
      rodfit::LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + name);
  p.scene.rod.segments = segments;  // the fitted material on a finer or coarser rod
  p.scene.rod.vertex_s.clear();
  return p;
}

void BM_Drag(benchmark::State& state) {
  const int segments = static_cast<int>(state.range(0));
  rodfit::RuntimeOptions options;
  options.mode = state.range(1) ? rodfit::RuntimeMode::kDynamic : rodfit::RuntimeMode::kQuasiStatic;
  options.tool_s = 0.1;
  rodfit::Runtime rt(Bowel("bowel_drag.json", segments), options);
  const rodfit::Vec3 home = rt.ToolPosition();
  long tick = 0, missed = 0, iterations = 0;
  TickTimes times(state);
  for (auto _ : state) {
    times.Start();
    const double phase = 2.0 * M_PI * static_cast<double>(++tick) / 1000.0;
    rt.SetToolPosition(home + 0.01 * rodfit::Vec3(std::cos(phase) - 1.0, std::sin(phase), 0.0));
    const rodfit::StepReport r = rt.Step();
    if (!r.ok()) ++missed;
    iterations += r.iterations;
    benchmark::DoNotOptimize(rt.ToolForce());
    times.Stop();
  }
  state.counters["median_us"] = times.Median();
  state.counters["missed"] = static_cast<double>(missed);
  state.counters["iterations"] = static_cast<double>(iterations) / static_cast<double>(tick);
  state.SetLabel(state.range(1) ? "dynamic" : "quasi-static");
}
BENCHMARK(BM_Drag)
    ->ArgsProduct({{50, 100, 200}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

void BM_PokeWithMesh(benchmark::State& state) {
  const int segments = static_cast<int>(state.range(0));
  rodfit::RuntimeOptions options;
  options.mode = state.range(1) ? rodfit::RuntimeMode::kDynamic : rodfit::RuntimeMode::kQuasiStatic;
  options.tool = rodfit::ToolKind::kPoke;
  options.tool_s = 0.075;
  rodfit::Runtime rt(Bowel("bowel_poke.json", segments), options);
  rodfit::TubeMesh mesh;
  rt.Mesh(&mesh);
  long tick = 0, missed = 0, iterations = 0;
  TickTimes times(state);
  for (auto _ : state) {
    times.Start();
    const double phase = 2.0 * M_PI * static_cast<double>(++tick) / 1000.0;
    rt.SetToolForce(rodfit::Vec3(0.0, 0.0, -0.015 * (1.0 - std::cos(phase))));
    const rodfit::StepReport r = rt.Step();
    if (!r.ok()) ++missed;
    iterations += r.iterations;
    rt.Mesh(&mesh);
    benchmark::DoNotOptimize(mesh.vertices.data());
    times.Stop();
  }
  state.counters["median_us"] = times.Median();
  state.counters["missed"] = static_cast<double>(missed);
  state.counters["iterations"] = static_cast<double>(iterations) / static_cast<double>(tick);
  state.SetLabel(state.range(1) ? "dynamic" : "quasi-static");
}
BENCHMARK(BM_PokeWithMesh)
    ->ArgsProduct({{50, 100, 200}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
