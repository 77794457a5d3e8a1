// A fixed number of the runtime benchmark's ticks (tests/bench/bench_runtime.cc: the same bowel
// profiles, tool paths and options), for counting instructions per tick with callgrind, which
// does not vary from run to run as times on a shared machine do (scripts/tick_instructions.sh
// counts two runs and takes the difference, so setup and warm-up cancel).
//   runtime_ticks SEGMENTS TICKS dynamic(0|1) poke(0|1)
// Prints the mean Newton iterations per tick, the ticks that failed, the last tool force and the
// fastest block of 100 ticks' time per tick (after the first 1000 ticks): on a shared machine
// the fastest block is the time least disturbed by other work, the figure to compare builds by.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: runtime_ticks SEGMENTS TICKS DYNAMIC(0|1) POKE(0|1)\n");
    return 2;
  }
  const int segments = std::atoi(argv[1]), ticks = std::atoi(argv[2]);
  const bool dynamic = std::atoi(argv[3]) != 0, poke = std::atoi(argv[4]) != 0;
  rodfit::Profile p = rodfit::LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" +
                                          (poke ? "bowel_poke.json" : "bowel_drag.json"));
  p.scene.rod.segments = segments;
  p.scene.rod.vertex_s.clear();
  rodfit::RuntimeOptions options;
  options.mode = dynamic ? rodfit::RuntimeMode::kDynamic : rodfit::RuntimeMode::kQuasiStatic;
  options.tool = poke ? rodfit::ToolKind::kPoke : rodfit::ToolKind::kGrasp;
  options.tool_s = poke ? 0.075 : 0.1;
  rodfit::Runtime rt(p, options);
  rodfit::TubeMesh mesh;
  if (poke) rt.Mesh(&mesh);
  const rodfit::Vec3 home = rt.ToolPosition();
  long iterations = 0, missed = 0;
  constexpr int kBlock = 100, kWarmUp = 1000;
  double fastest_block = INFINITY;  // [s]
  auto block_start = std::chrono::steady_clock::now();
  for (int tick = 1; tick <= ticks; ++tick) {
    const double phase = 2.0 * M_PI * tick / 1000.0;
    if (poke) {
      rt.SetToolForce(rodfit::Vec3(0.0, 0.0, -0.015 * (1.0 - std::cos(phase))));
    } else {
      rt.SetToolPosition(home + 0.01 * rodfit::Vec3(std::cos(phase) - 1.0, std::sin(phase), 0.0));
    }
    const rodfit::StepReport r = rt.Step();
    iterations += r.iterations;
    if (!r.ok()) ++missed;
    if (poke) rt.Mesh(&mesh);
    if (tick % kBlock == 0) {
      const auto now = std::chrono::steady_clock::now();
      if (tick > kWarmUp)
        fastest_block =
            std::min(fastest_block, std::chrono::duration<double>(now - block_start).count());
      block_start = now;
    }
  }
  const rodfit::Vec3 f = rt.ToolForce();
  std::printf("iterations/tick %.3f  missed %ld  force %.12g %.12g %.12g N",
              static_cast<double>(iterations) / ticks, missed, f.x(), f.y(), f.z());
  if (std::isfinite(fastest_block))
    std::printf("  fastest %.1f us/tick", 1e6 * fastest_block / kBlock);
  std::printf("\n");
  return 0;
}
