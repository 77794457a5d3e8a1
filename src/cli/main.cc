// The rodfit command (docs/cli.md): a thin table of subcommands in the manner of COLMAP's
// `commands.emplace_back("name", &RunName)`. Each Run* parses its options with CLI11, calls the
// library and turns a failure into one line on stderr and a non-zero exit. No physics here.
//
// Start-up (docs/cli.md, "Start-up"): this executable links only what `--help`, `--version`,
// `simulate` and `export` need (model, solve, io's readers and writers, runtime; no Ceres, no
// OpenCV). The commands that need more are in the commands module (commands_module.cc), which
// is loaded with dlopen only when one of them is run: loading the ~50 shared libraries of Ceres,
// SuiteSparse, glog and OpenCV was most of the CPU time of a `--help`.
#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/progress.h"
#include "rodfit/runtime/profile.h"
#include "rodfit/version.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/run.h"

namespace {

int RunSimulate(int argc, char** argv) {
  CLI::App app(
      "Solve every load case of a scene to static equilibrium and write DIR/shapes.csv "
      "(case,vertex,s,x,y,z), DIR/forces.csv (the force and moment on every held point), "
      "DIR/summary.csv (how each solve ended); DIR/sections.csv and DIR/CASE.obj for poked "
      "cases. Cases that converge to an unstable equilibrium are warned about on stderr. "
      "A scene with a dynamics: block is integrated in time instead: DIR/trajectory.csv "
      "(case,t,vertex,s,x,y,z), DIR/reactions.csv (held points' forces over time), "
      "DIR/summary.csv.",
      "rodfit simulate");
  std::string scene_path, output_dir;
  rodfit::SimulateOptions options;
  app.add_option("scene", scene_path, "scene YAML (docs/formats.md)")->required();
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_option("--markers", options.marker_count,
                 "moving scene: also write DIR/markers.csv, a synthetic motion-capture recording "
                 "(t,marker,x,y,z) of this many markers evenly spaced in s, at every written frame")
      ->check(CLI::Range(2, 10000));
  app.add_option("--marker-noise", options.marker_noise, "[m] Gaussian noise per coordinate of markers.csv")
      ->check(FiniteRange(0.0, 1.0));
  app.add_option("--marker-drop", options.marker_drop, "fraction of markers.csv samples dropped (not in frames 0-1)")
      ->check(FiniteRange(0.0, 0.9));
  app.add_option("--seed", options.seed, "random seed of the marker noise and drops");
  app.add_flag("--large", options.large,
               "moving scene: run it even when its estimated work or output is above the limits "
               "(docs/formats.md, \"Limits\")");
  app.add_flag("--keep-going", options.keep_going,
               "write the cases that converged and summary.csv even when one fails (exit 3)");
  bool quiet = false;
  app.add_flag("-q,--quiet", quiet, "no progress line");
  std::string profile_path;
  std::vector<std::string> sets;
  app.add_option("--profile", profile_path,
                 "profile JSON (rodfit fit) whose parameters replace the scene's parameters: "
                 "block, which may then be left out; the scene's rod must be the profile's");
  app.add_option("--set", sets,
                 "NAME=VALUE [SI]: with --profile, a value for a parameter the profile leaves "
                 "undetermined (value null) or one to replace (repeatable)");
  if (const int status = Parse(app, argc, argv); status >= 0) return status;
  // -o '' would mean "write nothing" to the library (and the working directory to a user):
  // refused with the output rule's message before anything runs.
  rodfit::CheckOutputDirectory(output_dir, {}, {});
  if (!sets.empty() && profile_path.empty())
    throw std::invalid_argument("--set needs --profile");

  rodfit::Experiment experiment =
      rodfit::LoadExperiment(scene_path, /*parameters_optional=*/!profile_path.empty());
  if (!profile_path.empty()) {
    rodfit::ProfileReadOptions read;
    for (const std::string& set : sets) {
      std::string why;
      if (!rodfit::ParseOverride(set, &read.overrides, &why))
        throw std::invalid_argument("--set " + why);
    }
    rodfit::UseProfileMaterial(rodfit::LoadProfile(profile_path, read), &experiment.scene);
  }
  // Many cases or long rods: which case it is on (a terminal only; io/progress.h).
  rodfit::ProgressLine progress(quiet, 2);
  if (progress.enabled() || progress.plain())
    options.progress = [&progress](const std::string& text, double fraction) {
      progress.Update(text, fraction);
    };
  options.output_dir = output_dir;
  const rodfit::SimulateRun run = rodfit::SimulateScene(experiment, options);
  progress.Finish();
  if (!run.first_failure.empty() && !options.keep_going) {
    std::cerr << "rodfit simulate: " << run.first_failure << "\n";
    return EXIT_FAILURE;
  }
  if (run.moving) {
    if (!run.first_failure.empty()) {
      std::cerr << "rodfit simulate: " << run.first_failure
                << " (the frames up to there written)\n";
      return 3;
    }
    // The time goes to stdout, not into the files (outputs are reproducible byte for byte).
    std::printf("integrated %zu cases (%d steps) in %.3f s; wrote %s\n",
                run.motion_summary.size(), run.steps, run.seconds, output_dir.c_str());
    return EXIT_SUCCESS;
  }
  // The time goes to stdout, not into a file: the same scene writes the same bytes.
  std::printf("solved %zu cases in %.3f s; wrote %s\n", run.summary.size(), run.seconds,
              output_dir.c_str());
  for (const std::string& w : run.warnings) std::cerr << "rodfit simulate: warning: " << w << "\n";
  if (!run.first_failure.empty()) {
    std::cerr << "rodfit simulate: " << run.first_failure << " (other cases written)\n";
    return 3;
  }
  return EXIT_SUCCESS;
}

struct Command {
  const char* name;
  const char* help;
  int (*run)(int argc, char** argv);  ///< nullptr: in the commands module
};

// Every command, in the order --help lists them (docs/cli.md has one section each). The help
// lines of the module's commands are here too, so that --help does not load it.
const std::vector<Command>& Commands() {
  static const std::vector<Command> commands = {
      {"simulate", "solve every case of a scene; write DIR/shapes.csv", &RunSimulate},
      {"synth", "synthesize an experiment's observation files from its parameters", nullptr},
      {"extract", "image(s) of a thread -> centre-line pixels or triangulated points", nullptr},
      {"fit", "fit an experiment's parameters to its observations; write the profile JSON",
       nullptr},
      {"rollout", "predict a recorded motion open-loop from its first frames; its error",
       nullptr},
      {"bench", "reference problems: error against time over settings; --stress", nullptr},
      {"export", "a fitted profile for another simulator: sofa, mujoco, xpbd or json", &RunExport},
  };
  return commands;
}

// Where the commands module may be, in this order: beside the executable (the build tree), then
// the install's lib/rodfit, found from the executable's own path (/proc/self/exe), so that an
// installed tree can be moved as a whole.
std::vector<std::filesystem::path> ModuleCandidates() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const std::filesystem::path bin = exe.parent_path();
  return {bin / RODFIT_COMMANDS_MODULE,
          (bin / RODFIT_MODULE_DIR_FROM_BIN / RODFIT_COMMANDS_MODULE).lexically_normal()};
}

// Runs a command of the module; a module that is missing or cannot be loaded is one line.
int RunInModule(const char* command, int argc, char** argv) {
  const std::vector<std::filesystem::path> candidates = ModuleCandidates();
  for (const std::filesystem::path& path : candidates) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) continue;
    // RTLD_LOCAL: the module's copies of the libraries stay its own. RTLD_LAZY, not RTLD_NOW:
    // binding every symbol of the module and its ~45 libraries up front costs 5 ms of CPU per
    // command (bench_startup, BM_ProcessModuleHelp: 19 ms against 14 ms); the module is linked
    // with --no-undefined, so nothing of its own is left to fail later, and its entry point
    // refuses a module of another version. The handle stays open until the process exits.
    void* module = dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL);
    if (module == nullptr) {
      std::cerr << "rodfit: cannot load " << path.string() << " for " << command << ": "
                << OneLine(dlerror()) << "\n";
      return EXIT_FAILURE;
    }
    const auto run = reinterpret_cast<RodfitRunCommand>(dlsym(module, kRunCommandSymbol));
    if (run == nullptr) {
      std::cerr << "rodfit: " << path.string() << " has no " << kRunCommandSymbol
                << " (not a rodfit commands module)\n";
      return EXIT_FAILURE;
    }
    return run(RODFIT_VERSION, command, argc, argv);
  }
  std::string where;
  for (const std::filesystem::path& path : candidates)
    where += (where.empty() ? "" : " nor in ") + path.parent_path().string();
  if (where.empty()) where = "the executable's directory (/proc/self/exe cannot be read)";
  std::cerr << "rodfit: " << command << " needs the commands module " << RODFIT_COMMANDS_MODULE
            << ", which is neither in " << where
            << " (build the rodfit-cli target, or reinstall rodfit)\n";
  return EXIT_FAILURE;
}

void PrintUsage(std::ostream& out) {
  out << "Usage: rodfit COMMAND [OPTIONS]   (rodfit COMMAND --help for its options)\n"
      << "       rodfit --version\n\n"
      << "Commands:\n";
  // Names padded to one column, so the descriptions line up.
  for (const Command& c : Commands()) {
    const std::string name = c.name;
    out << "  " << name << std::string(name.size() < 10 ? 10 - name.size() : 1, ' ') << c.help
        << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "rodfit: no command given (see rodfit --help)\n";
    return EXIT_FAILURE;
  }
  const std::string name = argv[1];
  if (name == "-h" || name == "--help" || name == "help") {
    PrintUsage(std::cout);
    return EXIT_SUCCESS;
  }
  if (name == "--version") {
    std::cout << "rodfit " << RODFIT_VERSION << "\n";
    return EXIT_SUCCESS;
  }
  for (const Command& c : Commands()) {
    if (name != c.name) continue;
    if (c.run == nullptr) return RunInModule(c.name, argc - 1, argv + 1);
    return RunReportingErrors(c.name, c.run, argc - 1, argv + 1);
  }
  std::cerr << "rodfit: unknown command '" << name << "' (see rodfit --help)\n";
  return EXIT_FAILURE;
}
