// The fit report (`rodfit fit --report DIR`): what a lab looks at to judge a calibration
// (docs/formats.md, "Fit report").
//   DIR/index.html      one self-contained page: parameter and correlation tables, per case the
//                       camera views, 3-D projections, poked sections, force logs and residuals,
//                       the residual histogram, cost per iteration and timing (fit_report_page.h)
//   DIR/figures/*.svg   each of the page's figures as a file of its own
//   DIR/summary.csv     case,observation,type,count,rms,unit,rms_moment
//   DIR/residuals.csv   case,observation,unit,measurement,e1,e2,e3,norm,norm_sigma
//                       (model - measured per measurement; e3 = 0 for pixels)
#pragma once

#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/pipeline/fit_input.h"  // DisplayCaseName

namespace rodfit {

/// Writes the report files into DIR all at once (a StagedDirectory): on failure DIR is left as
/// it was. Throws InputError on I/O failure. `warnings`: the run's warnings, each with what to
/// do about it, listed in the page's summary. Returns the report's own warnings (e.g. written
/// without its 3-D views), which the caller prints.
std::vector<std::string> WriteFitReport(const std::string& dir, const Experiment& experiment,
                                        const FitInput& input, const FitResult& result,
                                        const std::vector<std::string>& warnings = {});

/// Stages the report files in `out` (committed by the caller, e.g. together with the profile).
std::vector<std::string> WriteFitReport(StagedDirectory* out, const Experiment& experiment,
                                        const FitInput& input, const FitResult& result,
                                        const std::vector<std::string>& warnings = {});

}  // namespace rodfit
