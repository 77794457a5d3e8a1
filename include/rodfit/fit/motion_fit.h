// Stiffness and damping from recorded motion (docs/cli.md, "rollout --fit"): the parameters that
// minimise the open-loop rollout error (solve/rollout.h) over one or more recordings of the same
// rod. A derivative-free local search (NLopt BOBYQA, in log space): the rollout's sensitivities
// through the implicit steps are not implemented yet.
#pragma once

#include <string>
#include <vector>

#include "rodfit/model/scene.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {

struct MotionRecordingData {
  double frame_interval = 0.0;                ///< [s]
  std::vector<Eigen::Matrix3Xd> frames;       ///< 3 x markers per frame, NaN where not seen
};

struct MotionFitResult {
  std::vector<std::string> names;
  std::vector<double> start, values;   ///< per name, SI units
  double error_start = 0.0;            ///< [m] mean over recordings of the predicted markers' MAE
  double error_fitted = 0.0;
  int evaluations = 0;
};

/// The material parameters a motion fit may change: bend_stiffness (B2 follows when tied),
/// bend_stiffness_2, twist_stiffness, stretch_stiffness, damping, bend_damping, twist_damping,
/// stretch_damping. Throws std::invalid_argument for another name.
void SetMaterialParameter(const std::string& name, double value, Material* material);
double MaterialParameter(const std::string& name, const Material& material);

/// Fits `names` (each with a start value > 0 in scene.material) within [start / range, start *
/// range], at most `max_evaluations` rollouts of every recording. A rollout that fails counts as
/// a very bad point.
MotionFitResult FitToRecordings(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                                const std::vector<std::string>& names, const RolloutOptions& options,
                                const StaticsOptions& statics, int max_evaluations = 150,
                                double range = 100.0);

}  // namespace rodfit
