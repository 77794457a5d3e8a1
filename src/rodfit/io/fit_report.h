// The fit report (`rodfit fit --report DIR`): what a lab looks at to judge a calibration.
//   DIR/summary.csv     case,observation,type,count,rms,unit
//   DIR/residuals.csv   case,observation,unit,measurement,e1,e2,e3,norm,norm_sigma
//                       (model - measured per measurement; e3 = 0 for pixels)
//   DIR/CASE_CAMERA.png the fitted centre-line (green) over the image, or over the observed
//                       points (red) on a blank frame when there is no image
//   DIR/residuals.png   |residual| / sigma of every measurement, case by case
#pragma once

#include <string>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"

namespace rodfit {

/// Writes the report files into DIR all at once (a StagedDirectory): on failure DIR is left as
/// it was. Throws InputError on I/O failure.
void WriteFitReport(const std::string& dir, const Experiment& experiment, const FitInput& input,
                    const FitResult& result);

/// Stages the report files in `out` (committed by the caller, e.g. together with the profile).
void WriteFitReport(StagedDirectory* out, const Experiment& experiment, const FitInput& input,
                    const FitResult& result);

}  // namespace rodfit
