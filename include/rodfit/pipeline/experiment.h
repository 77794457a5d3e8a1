// Reading an experiment / scene YAML (docs/formats.md) as every command and library entry point
// does: io's reader (rodfit/io/experiment.h) with the observation kinds' keys
// (rodfit/pipeline/observation_kind.h) and the time integrators' names (solve/integrator.h).
#pragma once

#include <string>

#include "rodfit/io/experiment.h"

namespace rodfit {

/// Reads and validates an experiment / scene YAML. Throws InputError (rodfit/io/errors.h).
/// Absent optional keys: rest_curvature, tip_force, tip_moment = 0; gravity = (0, 0, -9.81);
/// spring_stiffness = 0; bend_stiffness_2 = bend_stiffness; case name = "case<index>".
/// Data files are not opened here (synth writes them), only their paths resolved.
/// `parameters_optional`: the `parameters:` block may be absent (a profile supplies the
/// material: `simulate --profile`); the material is then left at its defaults.
Experiment LoadExperiment(const std::string& path, bool parameters_optional = false);

/// The file text variant; `path` names the file in messages and anchors relative paths.
Experiment ParseExperiment(const std::string& text, const std::string& path,
                           bool parameters_optional = false);

}  // namespace rodfit
