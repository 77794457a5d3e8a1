// The fit report's interactive 3-D view of each case (report/view3d.h; docs/formats.md, "Fit
// report"): the fitted centre-line, the observed markers and points with their residual vectors
// to the model, the held ends with their frames, the loads and measured forces as arrows, the
// dented tube of a poke; over the haptic samples of a case, or over the recorded frames of a
// moving case, a slider.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/fit.h"
#include "rodfit/io/experiment.h"
#include "rodfit/report/view3d.h"

namespace rodfit {

/// The view of static case `c` (input.cases[c], result.shapes[c]); `samples` lists the other
/// fit cases made from it (the grasped cases of a haptic log, "drag@t=1.25"): with any, a slider
/// steps from the case to each of them.
view3d::View StaticCaseView(const Experiment& experiment, const FitInput& input,
                            const FitResult& result, size_t c, const std::vector<size_t>& samples,
                            const std::string& id);

/// The factor a poked section's displacement (deformed - rest ring nodes) is magnified by so
/// that a dent of a fraction of a millimetre shows: 1, 2 or 5 x 10^k making the largest
/// displacement about a fifth of the ring's radius; 1 when it shows as it is (or there is none).
double DentMagnification(const Eigen::Matrix3Xd& rest, const Eigen::Matrix3Xd& deformed);

/// One recorded sample of a moving case's 3-D sequence: where it was seen and where the fitted
/// run puts it at its time [m].
struct RecordedSample {
  double t = 0.0;                 ///< [s]
  double s = NAN;                 ///< [m] a marker's arc length; NaN for a point without one
  Eigen::Vector3d observed = Eigen::Vector3d::Zero();
  Eigen::Vector3d model = Eigen::Vector3d::Constant(NAN);  ///< NaN where not evaluated
  double sigma = 0.0;             ///< [m]
  std::string entry;              ///< "markers3d swing_markers.csv"
};

/// One reading of a load cell at a held point of a moving case, and the fitted run's force there.
struct RecordedForce {
  double t = 0.0;        ///< [s]
  std::string point;     ///< clamp, end_clamp, end_pin
  Eigen::Vector3d measured = Eigen::Vector3d::Zero();              ///< [N]
  Eigen::Vector3d model = Eigen::Vector3d::Constant(NAN);          ///< [N]
};

/// The view of moving case `c` over its run (result.trajectories): the fitted centre-line at each
/// recorded time with the samples seen then, observed and predicted, and a load cell's force
/// read then, measured and fitted, as arrows. False (nothing in *view) when the case has no
/// trajectory.
bool MovingCaseView(const Experiment& experiment, const FitResult& result, size_t c,
                    const std::vector<RecordedSample>& samples,
                    const std::vector<RecordedForce>& forces, const std::string& id,
                    view3d::View* view);

}  // namespace rodfit
