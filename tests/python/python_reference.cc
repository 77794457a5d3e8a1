// The C++ side of the Python package's tests and overhead figures (tests/python/,
// docs/python.md, "Overhead"):
//
//   python_reference ticks PROFILE.json TOOL_S MODE N
//     runs N runtime ticks of a grasp moving on a horizontal circle (radius 5 % of the rod's
//     length, from where the tool took hold; examples/haptic_loop.cc's path) and prints, per
//     tick, the tool position given and the force returned as C99 hex floats (exact), then the
//     final centre-line. test_runtime.py feeds the same positions through rodfit.Runtime and
//     requires the same bits.
//   python_reference time-ticks PROFILE.json TOOL_S MODE N
//     the same loop, timed: seconds per tick (mean over N, after 10 untimed ticks).
//   python_reference time-fit EXPERIMENT.yaml N
//     seconds per fit (rodfit::FitExperiment, mean over N after one untimed).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/run.h"

namespace {

rodfit::RuntimeOptions OptionsOf(double tool_s, const std::string& mode) {
  rodfit::RuntimeOptions options;
  options.tool_s = tool_s;
  options.mode = mode == "dynamic" ? rodfit::RuntimeMode::kDynamic
                                   : rodfit::RuntimeMode::kQuasiStatic;
  return options;  // no time budget: the results must not depend on the machine's load
}

rodfit::Vec3 ToolAt(const rodfit::Vec3& home, double radius, int k, int ticks) {
  const double phase = 2.0 * M_PI * k / ticks;
  return home + radius * rodfit::Vec3(std::cos(phase) - 1.0, std::sin(phase), 0.0);
}

int Ticks(const std::string& path, double tool_s, const std::string& mode, int ticks, bool timed) {
  const rodfit::Profile profile = rodfit::LoadProfile(path);
  rodfit::Runtime runtime(profile, OptionsOf(tool_s, mode));
  const rodfit::Vec3 home = runtime.ToolPosition();
  const double radius = 0.05 * profile.scene.rod.length;
  if (timed) {
    for (int k = 1; k <= 10; ++k) {
      runtime.SetToolPosition(ToolAt(home, radius, k, ticks));
      runtime.Step();
    }
    const auto start = std::chrono::steady_clock::now();
    double sum = 0.0;  // used, so the loop is not optimised away
    for (int k = 11; k <= ticks + 10; ++k) {
      runtime.SetToolPosition(ToolAt(home, radius, k, ticks));
      runtime.Step();
      sum += runtime.ToolForce().x();
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("%.9g\n", seconds / ticks);
    return std::isfinite(sum) ? EXIT_SUCCESS : EXIT_FAILURE;
  }
  for (int k = 1; k <= ticks; ++k) {
    const rodfit::Vec3 tool = ToolAt(home, radius, k, ticks);
    runtime.SetToolPosition(tool);
    const rodfit::StepReport report = runtime.Step();
    const rodfit::Vec3 f = runtime.ToolForce();
    std::printf("tick %d %a %a %a %a %a %a %d\n", k, tool.x(), tool.y(), tool.z(), f.x(), f.y(),
                f.z(), static_cast<int>(report.status));
  }
  const rodfit::Mat3X& x = runtime.Shape();
  for (int i = 0; i < x.cols(); ++i)
    std::printf("vertex %d %a %a %a\n", i, x(0, i), x(1, i), x(2, i));
  return EXIT_SUCCESS;
}

int TimeFit(const std::string& path, int runs) {
  const rodfit::Experiment experiment = rodfit::LoadExperiment(path);
  if (!rodfit::FitExperiment(experiment).ok) return EXIT_FAILURE;
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < runs; ++k) rodfit::FitExperiment(experiment);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%.9g\n", seconds / runs);
  return EXIT_SUCCESS;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  try {
    if ((command == "ticks" || command == "time-ticks") && argc == 6)
      return Ticks(argv[2], std::stod(argv[3]), argv[4], std::stoi(argv[5]),
                   command == "time-ticks");
    if (command == "time-fit" && argc == 4) return TimeFit(argv[2], std::stoi(argv[3]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "python_reference: %s\n", e.what());
    return EXIT_FAILURE;
  }
  std::fprintf(stderr,
               "usage: python_reference ticks|time-ticks PROFILE TOOL_S MODE N | "
               "time-fit EXPERIMENT N\n");
  return EXIT_FAILURE;
}
