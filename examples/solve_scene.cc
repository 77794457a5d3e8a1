// Example: solve every load case of a scene and print where the tip ends up.
//
// Reads data/scenes/cantilever.yaml (a nylon suture clamped at one end, in three load cases),
// solves each case to its static equilibrium with SolveCase — the path `rodfit simulate` takes —
// and prints the tip position [m], the clamp's reaction force [N] and the solver's summary.
// Run from the repository root, no arguments; exits 0 when every case converges.
//
// Public API used: rodfit/pipeline/experiment.h (LoadExperiment), rodfit/solve/case_solve.h
// (SolveCase, CaseSolution). Build against an installed rodfit: examples/CMakeLists.txt.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <vector>

#include "rodfit/io/experiment.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/pipeline/experiment.h"

int main() {
  const char* path = "data/scenes/cantilever.yaml";
  try {
    const rodfit::Experiment experiment = rodfit::LoadExperiment(path);
    const rodfit::Scene& scene = experiment.scene;
    std::vector<rodfit::CaseSolution> solutions;
    for (int k = 0; k < static_cast<int>(scene.cases.size()); ++k) {
      // A case with `start: previous` starts from the case before it.
      const rodfit::CaseSolution* previous = solutions.empty() ? nullptr : &solutions.back();
      solutions.push_back(rodfit::SolveCase(scene, k, previous, experiment.statics));
      const rodfit::CaseSolution& solution = solutions.back();
      if (!solution.ok()) {
        std::fprintf(stderr, "case %s: %s\n", scene.cases[k].name.c_str(),
                     solution.summary.BriefReport().c_str());
        return EXIT_FAILURE;
      }
      const Eigen::Vector3d tip = solution.shape.col(solution.shape.cols() - 1);
      std::printf("%-10s tip = (%+.6f, %+.6f, %+.6f) m", scene.cases[k].name.c_str(), tip.x(),
                  tip.y(), tip.z());
      for (const rodfit::HeldReaction& r : solution.reactions) {
        if (r.point == "clamp")
          std::printf("  clamp force = (%+.3e, %+.3e, %+.3e) N", r.force.x(), r.force.y(),
                      r.force.z());
      }
      std::printf("\n           %s\n", solution.summary.BriefReport().c_str());
    }
  } catch (const std::exception& e) {  // InputError: FILE:LINE: KEY: message
    std::fprintf(stderr, "%s\n", e.what());
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
