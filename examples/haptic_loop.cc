// Example: a 1 kHz haptic loop dragging a fitted rod with a synthetic tool path.
//
// Loads a fitted profile (default: the bundled suture, then the bowel segment of the
// tissue-drag recipe; data/profiles/README.md says how they were made), grasps the rod with the
// tool at one arc length and moves the tool along a horizontal circle for one second, one
// Runtime::Step per millisecond, paced by the clock as a device loop is. Prints the force on the
// tool every 100 ticks, one line per tick that is not OK (its status, the runtime's reason and
// the tool's lag), and per run the median, 99th percentile and largest tick time and one summary
// line:
//
//   ticks: N ok, N over the time budget, N not converged, N at the strain limit, N refused
//
// Each profile runs in its documented mode (docs/library.md, "Choosing the mode"): the suture, a
// thread, in dynamic mode; the bowel on its tissue springs in both. Exits 0 when every tick was
// OK or over the time budget (a busy machine's, reported, not an error); 1 when a tick failed
// for another reason, a force was not finite or a runtime could not be made. `--glitch` plays a
// glitching device (a NaN position at tick 300, the tool 1 m away for ticks 500 to 509): those
// ticks are refused and held at the strain limit, and the program exits 1. Run from the
// repository root:
//
//   haptic_loop [--glitch] [PROFILE.json TOOL_S [dynamic|quasi-static]]
//
// Public API used: rodfit/runtime/profile.h (LoadProfile), rodfit/runtime/runtime.h (Runtime).
// Build against an installed rodfit: examples/CMakeLists.txt.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

namespace {

constexpr int kTicks = 1000;        // one second at 1 kHz
constexpr double kTickSeconds = 1e-3;

// Runs one loop; false when a tick failed for a reason other than the time budget or a force
// was not finite.
bool RunLoop(const std::string& path, double tool_s, rodfit::RuntimeMode mode, bool glitch) {
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
  int ok = 0, over_budget = 0, not_converged = 0, strain = 0, refused = 0;
  bool finite = true;
  using Clock = std::chrono::steady_clock;
  Clock::time_point next = Clock::now();
  for (int k = 1; k <= kTicks; ++k) {
    const double phase = 2.0 * M_PI * k / kTicks;
    // A horizontal circle from where the tool took hold, towards the clamp: the rod between
    // stays slack.
    rodfit::Vec3 tool = home + radius * rodfit::Vec3(std::cos(phase) - 1.0, std::sin(phase), 0.0);
    if (glitch && k == 300) tool.y() = std::numeric_limits<double>::quiet_NaN();
    if (glitch && k >= 500 && k < 510) tool.x() += 1.0;
    runtime.SetToolPosition(tool);
    const rodfit::StepReport report = runtime.Step();
    tick_ms.push_back(1e3 * report.seconds);
    switch (report.status) {
      case rodfit::StepStatus::kConverged: ++ok; break;
      case rodfit::StepStatus::kTimeBudget: ++over_budget; break;
      case rodfit::StepStatus::kNotConverged: ++not_converged; break;
      case rodfit::StepStatus::kStrainLimit: ++strain; break;
      case rodfit::StepStatus::kToolRefused: ++refused; break;
    }
    if (!report.ok())  // the reason names the tool's lag (report.tool_lag)
      std::fprintf(stderr, "  tick %d: %s: %s\n", k, rodfit::ToString(report.status),
                   report.message);
    const rodfit::Vec3 f = runtime.ToolForce();
    finite = finite && f.allFinite();
    if (k % 100 == 0)
      std::printf("  tick %4d  force [% .4e % .4e % .4e] N  tick %.3f ms  %s\n", k, f.x(), f.y(),
                  f.z(), tick_ms.back(), rodfit::ToString(report.status));
    next += std::chrono::microseconds(1000);
    std::this_thread::sleep_until(next);  // the device's 1 kHz clock
  }
  std::sort(tick_ms.begin(), tick_ms.end());
  std::printf("  tick time: median %.3f ms, p99 %.3f ms, max %.3f ms\n",
              tick_ms[tick_ms.size() / 2], tick_ms[(tick_ms.size() * 99) / 100], tick_ms.back());
  std::printf("  ticks: %d ok, %d over the time budget, %d not converged, %d at the strain limit, "
              "%d refused\n",
              ok, over_budget, not_converged, strain, refused);
  if (!finite) std::fprintf(stderr, "haptic_loop: a force was not finite\n");
  return finite && not_converged + strain + refused == 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    std::vector<std::string> args(argv + 1, argv + argc);
    const bool glitch = !args.empty() && args.front() == "--glitch";
    if (glitch) args.erase(args.begin());
    if (args.size() == 1 || args.size() > 3 ||
        (args.size() == 3 && args[2] != "dynamic" && args[2] != "quasi-static")) {
      std::fprintf(stderr,
                   "usage: haptic_loop [--glitch] [PROFILE.json TOOL_S [dynamic|quasi-static]]\n");
      return EXIT_FAILURE;
    }
    if (args.size() >= 2) {
      const auto mode = args.size() == 3 && args[2] == "dynamic" ? rodfit::RuntimeMode::kDynamic
                                                                 : rodfit::RuntimeMode::kQuasiStatic;
      return RunLoop(args[0], std::atof(args[1].c_str()), mode, glitch) ? EXIT_SUCCESS
                                                                         : EXIT_FAILURE;
    }
    // Each bundled profile in its documented mode (docs/library.md, "Choosing the mode").
    bool ok = RunLoop("data/profiles/suture.json", 0.2, rodfit::RuntimeMode::kDynamic, glitch);
    ok = RunLoop("data/profiles/bowel_drag.json", 0.1, rodfit::RuntimeMode::kQuasiStatic, glitch) &&
         ok;
    ok = RunLoop("data/profiles/bowel_drag.json", 0.1, rodfit::RuntimeMode::kDynamic, glitch) && ok;
    return ok ? EXIT_SUCCESS : EXIT_FAILURE;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "haptic_loop: %s\n", e.what());
    return EXIT_FAILURE;
  }
}
