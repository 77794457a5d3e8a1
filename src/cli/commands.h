// Subcommands defined outside main.cc, one file each, registered in main.cc's table.
#pragma once

#include <string>

int RunFit(int argc, char** argv);
int RunRollout(int argc, char** argv);
/// Keeps Ceres' glog lines off stderr (the fits report for themselves).
void SilenceCeresLogging();
int RunBench(int argc, char** argv);
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
                   const MarkerSampling& markers = MarkerSampling());
