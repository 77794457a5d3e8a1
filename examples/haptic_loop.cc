// Example: a 1 kHz haptic loop dragging a fitted rod with a synthetic tool path.
//
// Loads a fitted profile (default: the bundled suture, then the bowel segment of the
// tissue-drag recipe; data/profiles/README.md says how they were made), grasps the rod with the
// tool at one arc length and moves the tool along a horizontal circle for one second, one Runtime::Step
// per millisecond, paced by the clock as a device loop is. Prints the force on the tool every
// 100 ticks and, per run, the median, 99th percentile and largest tick time and how many ticks
// ended without converging (over the time budget, or not converged: the last good state kept).
// Exits 0 unless a runtime cannot be built or a force is not finite; a tick missed on a busy
// machine is reported, not an error. Run from the repository root:
//
//   haptic_loop [PROFILE.json TOOL_S [dynamic]]
//
// Public API used: rodfit/runtime/profile.h (LoadProfile), rodfit/runtime/runtime.h (Runtime).
// Build against an installed rodfit: examples/CMakeLists.txt.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <thread>
#include <vector>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

namespace {

constexpr int kTicks = 1000;        // one second at 1 kHz
constexpr double kTickSeconds = 1e-3;

bool RunLoop(const std::string& path, double tool_s, rodfit::RuntimeMode mode) {
  const rodfit::Profile profile = rodfit::LoadProfile(path);
  rodfit::RuntimeOptions options;
  options.tool_s = tool_s;
  options.mode = mode;
  options.time_step = kTickSeconds;
  // A tick must end in time: give Newton most of the millisecond, then keep the last state.
  options.time_budget = 0.8 * kTickSeconds;
  // A force sensor's resolution, not the fit's: 1e-6 of the load scale is far below what a hand
  // feels, and saves Newton iterations.
  options.gradient_tolerance = 1e-6;
  rodfit::Runtime runtime(profile, options);
  const rodfit::Vec3 home = runtime.ToolPosition();
  const double radius = 0.05 * profile.scene.rod.length;  // the tool's circle [m]
  std::printf("%s (%s, tool at s = %g m): %d segments\n", path.c_str(),
              mode == rodfit::RuntimeMode::kDynamic ? "dynamic" : "quasi-static", tool_s,
              profile.scene.rod.segments);
  std::vector<double> tick_ms;
  tick_ms.reserve(kTicks);
  int over_budget = 0, not_converged = 0;
  bool finite = true;
  using Clock = std::chrono::steady_clock;
  Clock::time_point next = Clock::now();
  for (int k = 1; k <= kTicks; ++k) {
    const double phase = 2.0 * M_PI * k / kTicks;
    // A horizontal circle from where the tool took hold, towards the clamp: the rod between
    // stays slack (a thread pulled taut or snapping through is a case for the dynamic mode).
    runtime.SetToolPosition(home + radius * rodfit::Vec3(std::cos(phase) - 1.0, std::sin(phase),
                                                         0.0));
    const rodfit::StepReport report = runtime.Step();
    tick_ms.push_back(1e3 * report.seconds);
    if (report.status == rodfit::StepStatus::kTimeBudget) ++over_budget;
    if (report.status == rodfit::StepStatus::kNotConverged) ++not_converged;
    const rodfit::Vec3 f = runtime.ToolForce();
    finite = finite && f.allFinite();
    if (k % 100 == 0)
      std::printf("  tick %4d  force [% .4e % .4e % .4e] N  tick %.3f ms  %s\n", k, f.x(), f.y(),
                  f.z(), tick_ms.back(), rodfit::ToString(report.status));
    next += std::chrono::microseconds(1000);
    std::this_thread::sleep_until(next);  // the device's 1 kHz clock
  }
  std::sort(tick_ms.begin(), tick_ms.end());
  std::printf("  tick time: median %.3f ms, p99 %.3f ms, max %.3f ms; of %d ticks %d over the "
              "budget, %d not converged (last good state kept)\n",
              tick_ms[tick_ms.size() / 2], tick_ms[(tick_ms.size() * 99) / 100], tick_ms.back(),
              kTicks, over_budget, not_converged);
  return finite;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc >= 3) {
      const auto mode = argc >= 4 && std::string(argv[3]) == "dynamic"
                            ? rodfit::RuntimeMode::kDynamic
                            : rodfit::RuntimeMode::kQuasiStatic;
      return RunLoop(argv[1], std::atof(argv[2]), mode) ? EXIT_SUCCESS : EXIT_FAILURE;
    }
    bool ok = RunLoop("data/profiles/suture.json", 0.2, rodfit::RuntimeMode::kQuasiStatic);
    ok = RunLoop("data/profiles/suture.json", 0.2, rodfit::RuntimeMode::kDynamic) && ok;
    ok = RunLoop("data/profiles/bowel_drag.json", 0.1, rodfit::RuntimeMode::kQuasiStatic) && ok;
    ok = RunLoop("data/profiles/bowel_drag.json", 0.1, rodfit::RuntimeMode::kDynamic) && ok;
    return ok ? EXIT_SUCCESS : EXIT_FAILURE;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic_loop: %s\n", e.what());
    return EXIT_FAILURE;
  }
}
