// A moving experiment's observations (docs/formats.md, "Observation sequences"): every case's
// sequences (the observation kinds that may move: markers3d, points3d, image_points, reaction)
// read by their kinds into the motion fit's input (fit/motion_fit.h, ObservationSequence: one
// measurement per frame), and the motion fit's result in the static fit's terms, so that the
// profile and the report are written as for a static experiment. Pipeline layer.
#pragma once

#include <string>
#include <vector>

#include "rodfit/fit/fit.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/experiment.h"

namespace rodfit {

inline constexpr int kMaxSequenceTimes = 100000;  ///< distinct sample times in one file

struct SequenceInput {
  std::vector<ObservationSequence> sequences;  ///< in the order of the cases and their entries
  std::vector<std::string> labels;             ///< per sequence: "TYPE FILE"
};

/// Reads every sequence of an experiment with a dynamics: block: markers3d (`t,s,x,y,z`),
/// points3d (`t,x,y,z`), image_points (`t,s,u,v` or `t,u,v`, through the entry's camera); a
/// `frame` column with the entry's frame_rate instead of `t`. Each frame holds the samples seen
/// at one time, numbered in the file's order. Throws InputError naming the file, the row's line
/// and the column for a missing file or column, a non-number, a time outside
/// [0, dynamics.duration], an s outside [0, L], a marker's sample given twice, a row with some
/// coordinates missing and others not, a point more than 100 rod lengths from the clamp, a
/// pixel off its camera's sensor (by more than a quarter of the image), a `frame` column
/// without the entry's frame_rate, and a file with no recorded sample; naming the experiment
/// for one without dynamics:; CameraFileError for a camera file that cannot be read.
SequenceInput BuildSequenceInput(const Experiment& experiment);

/// The motion fit's settings from the experiment: each fitted parameter's min and max as its
/// bounds (else start / 100 .. start * 100), fit.max_iterations as the budget of runs,
/// fit.trusted_sigmas.
MotionFitOptions SequenceFitOptionsOf(const Experiment& experiment,
                                      const std::vector<std::string>& names);

/// The names with `fit: true`, in the order of the material parameter table.
std::vector<std::string> FittedNames(const Experiment& experiment);

/// The motion fit as a FitResult (what ProfileJson and the report read): every parameter of the
/// experiment with its estimate, the correlations, and per sequence the RMS of its samples'
/// error norms at the fit in its unit (m or px; `residuals`, EvaluateSequences at the fitted
/// values) and each sample's error for the report.
FitResult SequenceFitResult(const Experiment& experiment, const SequenceInput& input,
                            const MotionFitResult& motion, const SequenceResiduals& residuals);

}  // namespace rodfit
