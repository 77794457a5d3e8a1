// Stiffness, damping and linear density from recorded motion (docs/cli.md, "rollout --fit";
// docs/solvers.md, "Sensitivities in time"): the parameters that minimise the open-loop rollout
// error (solve/rollout.h) over one or more recordings of the same rod. Fit layer.
//
// The default is a least-squares fit: Levenberg–Marquardt (Ceres) in log-parameter space on the
// residuals predicted - recorded coordinate of every marker not driven (NaN samples skipped),
// divided by the marker noise, with the exact Jacobian from the rollout's forward sensitivities
// through the implicit steps. It reports the covariance of the parameters and an identifiability
// verdict by the static fit's rules. The derivative-free search it replaced (NLopt BOBYQA on the
// markers' mean absolute error) is kept as an option.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/scene.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {

struct MotionRecordingData {
  double frame_interval = 0.0;                ///< [s]
  std::vector<Eigen::Matrix3Xd> frames;       ///< 3 x markers per frame, NaN where not seen
};

enum class MotionFitMethod {
  kLevenbergMarquardt,  ///< least squares with the rollout's sensitivities (the default)
  kBobyqa,              ///< derivative-free, on the mean absolute error
};

struct MotionFitOptions {
  MotionFitMethod method = MotionFitMethod::kLevenbergMarquardt;
  int max_evaluations = 150;  ///< rollouts of every recording the search may take
  double range = 100.0;       ///< each parameter within [start / range, start * range]
  /// [m] the markers' noise: the residuals are divided by it. 0: unit weights. The covariance is
  /// scaled by the residual variance either way (as the static fit's without trusted sigmas).
  double marker_sigma = 0.0;
  /// A parameter whose log has a standard deviation above this is not identifiable
  /// (FitOptions::max_log_std).
  double max_log_std = 1.0;
  /// Per fitted name, bounds in SI units overriding [start / range, start * range] (each
  /// vector empty, or one entry per name with NaN where the default applies).
  std::vector<double> lower, upper;
  /// The covariance as the sigmas state it, not scaled by the residual variance.
  bool trusted_sigmas = false;
  bool Check(std::string* why) const;
};

struct MotionFitResult {
  std::vector<std::string> names;
  std::vector<double> start, values;   ///< per name, SI units
  double error_start = 0.0;            ///< [m] mean over recordings of the predicted markers' MAE
  double error_fitted = 0.0;
  int evaluations = 0;                 ///< rollouts of every recording, the covariance's included
  // Added with the least-squares fit; BOBYQA fills them too (at its solution).
  std::string method;                  ///< "levenberg_marquardt" or "bobyqa"
  bool converged = false;              ///< the search met its tolerances within its budget
  std::string message;                 ///< how the search ended
  std::vector<double> std;             ///< per name, SI units; NaN where not identifiable
  std::vector<bool> identifiable;      ///< per name
  std::vector<std::string> reason;     ///< per name: why not identifiable (empty when it is)
  std::vector<bool> at_bound;          ///< per name: the estimate is on its bound (start * range^+-1)
  Eigen::MatrixXd covariance_log;      ///< of the log-parameters (NaN rows: not identifiable)
  int residuals = 0;                   ///< marker coordinates compared
  double residual_variance = 0.0;      ///< sum r^2 / (residuals - parameters), r in sigmas
  /// 1/2 sum r^2 (r in sigmas) at the start and at the solution (least squares only).
  double initial_cost = 0.0, final_cost = 0.0;
  int iterations = 0;                  ///< iterations of the search
  double seconds = 0.0;                ///< wall time of the fit
};

/// The material parameters a motion fit may change: bend_stiffness (B2 follows when tied),
/// bend_stiffness_2, twist_stiffness, stretch_stiffness, damping, bend_damping, twist_damping,
/// stretch_damping. Throws std::invalid_argument for another name.
void SetMaterialParameter(const std::string& name, double value, Material* material);
double MaterialParameter(const std::string& name, const Material& material);

/// Those and linear_density (the rod's, not the material's): the parameters FitMotion takes.
void SetMotionParameter(const std::string& name, double value, Scene* scene);
double MotionParameter(const std::string& name, const Scene& scene);

/// Fits `names` (each with a start value > 0 in the scene) to the recordings. Throws
/// std::invalid_argument for an ill-posed request (no names or recordings, an unknown name, a
/// start value <= 0, a recording the rollout refuses). A fit that does not converge returns its
/// last point with converged false and the reason in `message`; a rollout that fails counts as
/// a very bad point (BOBYQA) or a rejected step (Levenberg–Marquardt).
MotionFitResult FitMotion(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                          const std::vector<std::string>& names, const RolloutOptions& options,
                          const StaticsOptions& statics, const MotionFitOptions& fit_options);

/// A markers3d sequence of one case of a moving scene (docs/formats.md, "Observation entries"):
/// markers identified by their arc length, sampled over time, some samples missing.
struct MarkerSequence {
  int case_index = 0;              ///< into Scene::cases
  std::vector<double> s;           ///< [m] the markers' arc lengths
  std::vector<double> t;           ///< [s] the sample times, ascending
  struct Sample {
    int time = 0, marker = 0;      ///< indices into t and s
    Eigen::Vector3d position;      ///< [m] as recorded
  };
  std::vector<Sample> samples;     ///< the recorded ones (a missing sample is not listed)
  double sigma = 1.0;              ///< [m] per coordinate
};

/// The residuals of a sequence fit at one parameter value, for reports: per sequence, per
/// sample, predicted minus recorded [m] (NaN rows where the run failed).
struct SequenceResiduals {
  bool ok = false;
  std::string reason;
  std::vector<std::vector<Eigen::Vector3d>> error;
};

/// Fits `names` of a moving scene (Scene::dynamics set; each with a start value > 0) to marker
/// sequences of its cases by the least-squares fit above: residuals (predicted - recorded) /
/// sigma for every recorded coordinate, the predictions the open-loop trajectory of the case
/// from its initial state (solve/case_dynamics.h, SampleCaseDynamics) with its exact
/// sensitivities. options.method must be Levenberg–Marquardt; options.marker_sigma is unused
/// (each sequence has its sigma). error_start / error_fitted are the mean absolute coordinate
/// errors over all samples. Throws std::invalid_argument as FitMotion does.
MotionFitResult FitSequences(const Scene& scene, const std::vector<MarkerSequence>& sequences,
                             const std::vector<std::string>& names, const StaticsOptions& statics,
                             const MotionFitOptions& fit_options);

/// The errors of every sample of `sequences` along the scene's trajectories.
SequenceResiduals EvaluateSequences(const Scene& scene, const std::vector<MarkerSequence>& sequences,
                                    const StaticsOptions& statics);

/// FitMotion with the default method, at most `max_evaluations` rollouts of every recording,
/// each parameter within [start / range, start * range].
MotionFitResult FitToRecordings(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                                const std::vector<std::string>& names, const RolloutOptions& options,
                                const StaticsOptions& statics, int max_evaluations = 150,
                                double range = 100.0);

}  // namespace rodfit
