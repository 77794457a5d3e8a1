// Start-up benchmark: the CPU time (user + system, from the child's rusage) of whole `rodfit`
// processes, against the time of the work they do measured in this process.
//  - BM_ProcessHelp: `rodfit --help` (all of it is start-up: loading the shared libraries, static
//    initialisation, parsing the command line).
//  - BM_ProcessSimulate100: `rodfit simulate` of the bundled cantilever scene at 100 segments
//    (three cases) into a temporary directory.
//  - BM_Simulate100InProcess: the same scene's load and solves in this process (what simulate
//    does besides starting and writing its outputs).
//  - BM_ProcessModuleHelp: `rodfit fit --help`, which loads the commands module and with it Ceres
//    and OpenCV (docs/cli.md, "Start-up"): what the commands in the module pay on top of --help.
// BM_ProcessSimulate100 - BM_Simulate100InProcess is the time simulate spends outside the solve.
// Run: build/bench_startup; one core, Release build.
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "rodfit/io/experiment.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/pipeline/experiment.h"

extern char** environ;

namespace rodfit {
namespace {

namespace fs = std::filesystem;

// CPU seconds (user + system) of one run of `args`, its output sent to /dev/null; -1 on failure.
double ChildCpuSeconds(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return -1.0;
  int status = 0;
  struct rusage usage {};
  if (wait4(pid, &status, 0, &usage) != pid || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return -1.0;
  auto seconds = [](const timeval& t) { return t.tv_sec + 1e-6 * t.tv_usec; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

// The bundled cantilever scene with 100 segments, in a temporary directory.
struct Scene100 {
  fs::path dir, scene, out;
  Scene100() {
    dir = fs::temp_directory_path() / ("rodfit_bench_startup_" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::ifstream in(std::string(RODFIT_SOURCE_DIR) + "/data/scenes/cantilever.yaml");
    std::stringstream text;
    text << in.rdbuf();
    std::string yaml = text.str();
    const std::string from = "segments: 50 ", to = "segments: 100";
    const size_t at = yaml.find(from);
    if (at != std::string::npos) yaml.replace(at, from.size(), to);
    scene = dir / "cantilever100.yaml";
    std::ofstream(scene) << yaml;
    out = dir / "out";
  }
  ~Scene100() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

void RunProcess(benchmark::State& st, const std::vector<std::string>& args) {
  for (auto _ : st) {
    const double cpu = ChildCpuSeconds(args);
    if (cpu < 0) {
      st.SkipWithError("the command failed");
      break;
    }
    st.SetIterationTime(cpu);
  }
}

void BM_ProcessHelp(benchmark::State& st) { RunProcess(st, {RODFIT_CLI, "--help"}); }
BENCHMARK(BM_ProcessHelp)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(1.0);

void BM_ProcessModuleHelp(benchmark::State& st) { RunProcess(st, {RODFIT_CLI, "fit", "--help"}); }
BENCHMARK(BM_ProcessModuleHelp)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(1.0);

void BM_ProcessSimulate100(benchmark::State& st) {
  const Scene100 s;
  RunProcess(st, {RODFIT_CLI, "simulate", s.scene.string(), "-o", s.out.string()});
}
BENCHMARK(BM_ProcessSimulate100)->UseManualTime()->Unit(benchmark::kMillisecond)->MinTime(1.0);

void BM_Simulate100InProcess(benchmark::State& st) {
  const Scene100 s;
  for (auto _ : st) {
    const Experiment experiment = LoadExperiment(s.scene.string());
    std::vector<CaseSolution> solutions;
    for (size_t k = 0; k < experiment.scene.cases.size(); ++k) {
      solutions.push_back(SolveCase(experiment.scene, static_cast<int>(k),
                                    solutions.empty() ? nullptr : &solutions.back(),
                                    experiment.statics));
      if (!solutions.back().ok()) st.SkipWithError("a case did not converge");
    }
    benchmark::DoNotOptimize(solutions.data());
  }
}
BENCHMARK(BM_Simulate100InProcess)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace rodfit

BENCHMARK_MAIN();
