// Subcommands defined outside main.cc, one file each, registered in main.cc's table. The `rodfit`
// executable holds the commands that need no Ceres and no OpenCV (simulate, export) so that they
// start without loading either; the others are in the commands module, which main.cc loads only
// for them (docs/cli.md, "Start-up").
#pragma once

#include <string>

// --- In the executable.

int RunExport(int argc, char** argv);

// --- In the commands module (commands_module.cc).

int RunSynth(int argc, char** argv);
int RunExtract(int argc, char** argv);
int RunFit(int argc, char** argv);
int RunRollout(int argc, char** argv);
/// Keeps Ceres' glog lines off stderr (the fits report for themselves).
void SilenceCeresLogging();
int RunBench(int argc, char** argv);

/// The module's one entry point, looked up by this name with dlsym: runs `command` (a name of
/// the module's table) on argv as main would, after checking that the module was built with the
/// executable's `version` (an older module left in an install would otherwise run silently).
/// Only C types cross between the two, and nothing the module allocates outlives the call.
extern "C" {
using RodfitRunCommand = int (*)(const char* version, const char* command, int argc, char** argv);
}
inline constexpr char kRunCommandSymbol[] = "rodfit_run_command";
