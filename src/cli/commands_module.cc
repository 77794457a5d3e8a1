// The commands module (rodfit-commands.so): the commands that need Ceres, OpenCV or the fit, in a
// library that the `rodfit` executable loads with dlopen only when one of them is run, so that
// `--help`, `--version`, `simulate` and `export` start without loading those libraries and their
// ~45 dependencies (docs/cli.md, "Start-up"). Built with hidden symbols: only the entry point is
// visible, so no state is shared with the executable's own copy of the libraries.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <type_traits>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/version.h"

namespace {

struct ModuleCommand {
  const char* name;
  int (*run)(int argc, char** argv);
};

// The names main.cc's table marks as in the module.
constexpr ModuleCommand kCommands[] = {
    {"synth", &RunSynth}, {"extract", &RunExtract}, {"fit", &RunFit},
    {"rollout", &RunRollout}, {"bench", &RunBench},
};

}  // namespace

extern "C" __attribute__((visibility("default"))) int rodfit_run_command(const char* version,
                                                                         const char* command,
                                                                         int argc, char** argv) {
  // Checked against the type main.cc calls through.
  static_assert(std::is_same_v<decltype(&rodfit_run_command), RodfitRunCommand>);
  if (std::strcmp(version, RODFIT_VERSION) != 0) {
    std::fprintf(stderr,
                 "rodfit: the commands module is version %s, the rodfit executable %s "
                 "(reinstall rodfit)\n",
                 RODFIT_VERSION, version);
    return EXIT_FAILURE;
  }
  for (const ModuleCommand& c : kCommands) {
    if (std::strcmp(command, c.name) == 0) return RunReportingErrors(c.name, c.run, argc, argv);
  }
  std::fprintf(stderr, "rodfit: the commands module has no command '%s'\n", command);
  return EXIT_FAILURE;
}
