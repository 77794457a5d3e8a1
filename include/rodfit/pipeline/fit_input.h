// From an experiment to the static fit's input (docs/formats.md, "Observation entries"): every
// observation entry read by its kind (rodfit/pipeline/observation_kind.h) from its data file (CSV,
// image) and camera, checked against the rod, into the case's measurements. Errors name the
// file, the row's line and the column or key. Pipeline layer.
#pragma once

#include <string>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"

namespace rodfit {

/// All five parameters of the model in a fixed order, fitted or not; an absent
/// bend_stiffness_2 is left out (tied to bend_stiffness), an absent spring_stiffness is 0.
std::vector<Parameter> FitParametersOf(const Experiment& experiment);

/// Loads every observation of every case. Throws InputError (or CameraFileError) for a missing
/// or malformed file, a missing column, a non-number, a marker with s outside [0, L], a camera
/// that sees none of its points, and an `images` entry nothing can be extracted from.
FitInput BuildFitInput(const Experiment& experiment);

/// The fit options the experiment's `fit:` block states (loss, loss_scale, global,
/// max_iterations, trusted_sigmas); the rest at FitOptions' defaults.
FitOptions FitOptionsOf(const Experiment& experiment);

/// Before a fit: solves every case that has a camera observation at the start values (as
/// `simulate` does) and projects the solved centre-line into each of its cameras. Throws
/// InputError naming the camera file and the case when the whole rod lies behind the camera,
/// or projects entirely outside its image (the camera looks elsewhere): a wrong pose would
/// otherwise end the fit as a failed evaluation with no file named. Cases that do not solve
/// are left to the fit, which reports them.
void CheckCamerasSeeTheStart(const Experiment& experiment);

/// A fit case's name as a person reads it: a haptic sample's case "drag@t=0.16500000000000001"
/// (its name keeps the log's time to the last digit, fit_input.cc) as "drag@t=0.165" (6
/// digits: samples are far more than 1e-6 apart); any other name as it is.
std::string DisplayCaseName(const std::string& name);

}  // namespace rodfit
