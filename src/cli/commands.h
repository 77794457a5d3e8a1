// Subcommands defined outside main.cc, one file each, registered in main.cc's table. The `rodfit`
// executable holds the commands that need no Ceres and no OpenCV (simulate, export) so that they
// start without loading either; the others are in the commands module, which main.cc loads only
// for them (docs/cli.md, "Start-up").
#pragma once

#include <string>

// --- In the executable.

int RunExport(int argc, char** argv);

namespace rodfit {
struct Experiment;
}

/// `rodfit simulate` on a scene with a `dynamics:` block (simulate_dynamics.cc): integrates
/// every case in time and writes DIR/trajectory.csv, DIR/reactions.csv and DIR/summary.csv.
/// A synthetic motion-capture recording of a moving scene (simulate --markers).
struct MarkerSampling {
  int count = 0;             ///< markers evenly spaced in s (0: none written)
  double noise = 0.0;        ///< [m] Gaussian, per coordinate
  double drop = 0.0;         ///< fraction of samples left out (never in frames 0 and 1)
  unsigned seed = 1;
};
int SimulateMotion(const rodfit::Experiment& experiment, const std::string& scene_path,
                   const std::string& output_dir, bool keep_going,
                   const MarkerSampling& markers = MarkerSampling(), bool quiet = false);

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
