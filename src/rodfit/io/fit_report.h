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

namespace rodfit {

/// Writes the report files (each atomically); creates DIR. Throws InputError on I/O failure.
void WriteFitReport(const std::string& dir, const Experiment& experiment, const FitInput& input,
                    const FitResult& result);

}  // namespace rodfit
