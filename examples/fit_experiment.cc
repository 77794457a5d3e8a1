// Example: fit a calibration experiment and print the parameters with their standard deviations.
//
// Reads calibration/suture_cantilever/experiment.yaml (a suture in four clamp orientations, seen
// as 3-D markers and as pixels in two cameras; README there), loads its observation files and
// cameras, fits the two bending stiffnesses B1 and B2 (Levenberg–Marquardt in log space, a few
// iterations, well under a second) and prints every parameter: value ± std, unit, and why the
// data cannot determine it when they cannot. The same fit as `rodfit fit`, without the profile.
// Run from the repository root, no arguments; exits 0 when the fit succeeds.
//
// Public API used: rodfit/io/experiment.h (LoadExperiment), rodfit/io/fit_input.h
// (BuildFitInput, FitOptionsOf), rodfit/fit/fit.h (Fit, FitOptions, FitResult).
#include <cstdio>
#include <cstdlib>
#include <exception>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/experiment.h"

int main() {
  const char* path = "calibration/suture_cantilever/experiment.yaml";
  try {
    const rodfit::Experiment experiment = rodfit::LoadExperiment(path);
    // Reads every observation's CSV and camera file (paths relative to the YAML's folder).
    const rodfit::FitInput input = rodfit::BuildFitInput(experiment);
    // The file's optional `fit:` block (docs/formats.md); defaults otherwise.
    const rodfit::FitOptions options = rodfit::FitOptionsOf(experiment);

    const rodfit::FitResult result = rodfit::Fit(input, options);
    if (!result.success) {
      std::fprintf(stderr, "%s: fit failed: %s\n", path, result.message.c_str());
      return EXIT_FAILURE;
    }
    std::printf("%d iterations, residual variance %.3f (about 1: the sigmas are right)\n",
                result.iterations, result.residual_variance);
    for (const rodfit::Parameter& p : result.parameters) {
      std::printf("%-18s %.6e", p.name.c_str(), p.value);
      if (p.std) std::printf(" ± %.2e", *p.std);
      std::printf(" %s%s", p.unit(), p.fit ? "" : "  (held)");
      if (!p.identifiable) std::printf("  NOT IDENTIFIABLE: %s", p.reason.c_str());
      std::printf("\n");
    }
  } catch (const std::exception& e) {  // InputError, CameraFileError, std::invalid_argument
    std::fprintf(stderr, "%s\n", e.what());
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
