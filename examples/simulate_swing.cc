// Example: integrate a moving scene in time for 0.1 s and print the tip's path.
//
// Reads data/scenes/suture_swing.yaml (the suture of cantilever.yaml released straight and
// horizontal from its clamp, swinging down under its own weight; BDF2, 1 ms steps), shortens its
// `dynamics:` duration from 1 s to 0.1 s, integrates its case with SimulateCaseDynamics — the
// path `rodfit simulate` takes for a scene with `dynamics:` — and prints the tip position [m]
// and the clamp's reaction force [N] of every written frame (every 10 ms).
// Run from the repository root, no arguments; exits 0 when the integration reaches 0.1 s.
//
// Public API used: rodfit/pipeline/experiment.h (LoadExperiment), rodfit/solve/case_dynamics.h
// (SimulateCaseDynamics, CaseTrajectory). A simulator stepping frame by frame uses
// rodfit/solve/dynamics.h (DynamicsStepper::Step with its own Drive) instead.
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "rodfit/io/experiment.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/pipeline/experiment.h"

int main() {
  const char* path = "data/scenes/suture_swing.yaml";
  try {
    rodfit::Experiment experiment = rodfit::LoadExperiment(path);
    rodfit::Scene& scene = experiment.scene;
    if (!scene.dynamics) {
      std::fprintf(stderr, "%s: no dynamics: block\n", path);
      return EXIT_FAILURE;
    }
    scene.dynamics->duration = 0.1;  // [s]
    const rodfit::CaseTrajectory trajectory =
        rodfit::SimulateCaseDynamics(scene, 0, experiment.statics);
    if (!trajectory.ok) {
      std::fprintf(stderr, "%s: %s\n", path, trajectory.reason.c_str());
      return EXIT_FAILURE;
    }
    std::printf("%d steps, %d Newton iterations\n", trajectory.steps,
                trajectory.newton_iterations);
    std::printf("%8s %12s %12s %12s %14s\n", "t [s]", "tip x [m]", "tip y [m]", "tip z [m]",
                "clamp fz [N]");
    for (const rodfit::TrajectoryFrame& frame : trajectory.frames) {
      const Eigen::Vector3d tip = frame.x.col(frame.x.cols() - 1);
      // The clamp's reaction comes first (solve/reactions.h).
      const double fz = frame.reactions.empty() ? 0.0 : frame.reactions.front().force.z();
      std::printf("%8.3f %+12.6f %+12.6f %+12.6f %+14.4e\n", frame.t, tip.x(), tip.y(), tip.z(),
                  fz);
    }
  } catch (const std::exception& e) {  // InputError, std::runtime_error (initial state)
    std::fprintf(stderr, "%s\n", e.what());
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
