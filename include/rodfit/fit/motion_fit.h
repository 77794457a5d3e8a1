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
//
// The same least-squares fit serves a moving experiment's observation sequences (docs/cli.md,
// "fit"): every frame of an entry is a static observation model (observe/observations.h) —
// markers, 3-D points or pixels — evaluated on the case's vertices at its time, its closed-form
// vertex Jacobian chained with the trajectory's sensitivities d x / d log p.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/fit.h"
#include "rodfit/model/scene.h"
#include "rodfit/fit/measurement.h"
#include "rodfit/model/settings_archive.h"
#include "rodfit/solve/rollout.h"

namespace rodfit {

struct MotionRecordingData {
  std::string name;                           ///< how messages name it (its file)
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
  /// The rest shape (the name "rest_curvature"; docs/cli.md, "rollout --fit"): the bending
  /// components (k1°, k2°) of the intrinsic curvature at this many knots evenly along the rod,
  /// linear between them (RodSpec::rest_curvature_s / rest_curvature_profile; the rest twist is
  /// not fitted), within +-max_rest_curvature [1/m], with a smoothness prior: the second
  /// difference over neighbouring knots is 0 with std rest_curvature_smoothness [1/m] (its
  /// residuals count among those the residual variance sums).
  int rest_curvature_knots = 5;
  double rest_curvature_smoothness = 2.0;
  double max_rest_curvature = 30.0;
  /// Called after each Levenberg–Marquardt iteration (`iteration`, `cost`, `seconds`; `budget`
  /// is max_evaluations, `global` false): a caller's progress line.
  std::function<void(const FitIterationInfo&)> progress;
  bool Check(std::string* why) const;
};

/// The motion fit's settings, declared once (docs/cli.md, "rollout", its settings table): each
/// key with its default (the initializers above), range, and for those the command line takes
/// its option and help text (rodfit/model/settings_archive.h). `lower`, `upper` (per fitted
/// name) and `progress` are a caller's, not settings.
void Serialize(SettingsArchive* a, MotionFitOptions* o);

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
  int residuals = 0;                   ///< marker coordinates (or sequence residuals) compared
  /// Of those, the ones that carry noise (fewer for closest-point residuals of sequences).
  int noise_residuals = 0;
  double residual_variance = 0.0;      ///< sum r^2 / (noise_residuals - parameters), r in sigmas
  /// 1/2 sum r^2 (r in sigmas) at the start and at the solution (least squares only).
  double initial_cost = 0.0, final_cost = 0.0;
  int iterations = 0;                  ///< iterations of the search
  double seconds = 0.0;                ///< wall time of the fit
  /// Least squares: Ceres' cost at the start ([0]) and after each iteration, and the wall time
  /// since the fit began [s] at each (the report's convergence plot).
  std::vector<double> cost_per_iteration, seconds_per_iteration;
  /// [s] wall time in the runs (rollouts or case integrations, with their sensitivities when
  /// the search needs them); the rest of `seconds` is the search and the covariance.
  double run_seconds = 0.0;
  /// [m] the markers' noise the residuals were divided by: MotionFitOptions::marker_sigma, or
  /// when that is 0 EstimateMarkerNoise of the recordings (marker_sigma_estimated; 0 when the
  /// recordings are too short to tell: unit weights).
  double marker_sigma = 0.0;
  bool marker_sigma_estimated = false;
  /// With "rest_curvature" fitted: the knots' arc lengths [m]; `names` then ends with
  /// "rest_curvature.k1[j]", "rest_curvature.k2[j]" per knot j, whose start, values and std
  /// are in 1/m (not log-parameters; covariance_log's rows for them are of kappa° L).
  std::vector<double> rest_curvature_s;
  int prior_residuals = 0;  ///< the smoothness prior's rows among `residuals`
};

/// The name FitMotion takes for the rest shape (MotionFitOptions::rest_curvature_knots).
inline constexpr const char* kRestCurvatureParameter = "rest_curvature";

/// The markers' noise [m] from the recordings alone: the median absolute fourth difference in
/// time of every seen coordinate of the markers the rollout predicts (not options' held ones)
/// over 0.6745 sqrt(70) (white noise's; a smooth motion's own is far smaller at motion-capture
/// rates). 0 with fewer than 30 such differences.
double EstimateMarkerNoise(const std::vector<MotionRecordingData>& recordings,
                           const RolloutOptions& options);

/// The parameters a motion fit may change, rows of the parameter table
/// (rodfit/model/material_parameters.h) of the rod's stiffness (bend_stiffness moves B2 too when
/// tied), damping and mass (linear_density, set on the rod): those FitMotion takes. Throws
/// std::invalid_argument for another name.
void SetMotionParameter(const std::string& name, double value, Scene* scene);
double MotionParameter(const std::string& name, const Scene& scene);

/// Fits `names` (each with a start value > 0 in the scene; "rest_curvature": the rest shape,
/// started from the scene's) to the recordings. Throws
/// std::invalid_argument for an ill-posed request (no names or recordings, an unknown name, a
/// start value <= 0, a recording the rollout refuses). A fit that does not converge returns its
/// last point with converged false and the reason in `message`; a rollout that fails counts as
/// a very bad point (BOBYQA) or a rejected step (Levenberg–Marquardt).
MotionFitResult FitMotion(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                          const std::vector<std::string>& names, const RolloutOptions& options,
                          const StaticsOptions& statics, const MotionFitOptions& fit_options);

/// An observation entry of a moving case over time (docs/formats.md, "Observation sequences"):
/// at each of its frames, the measurement of what was seen then (fit/measurement.h: markers3d,
/// points3d, image_points with or without s on the vertices of the case's whole rod,
/// CaseVertexArcLengths; or a load cell's reading at one of its held points, ForceReadings with
/// one reading). Every frame's measurement is of one type, unit and sigma (a reading's: of one
/// point, sigma and sigma_moment); none may need the whole state (needs_state) or a section.
struct ObservationSequence {
  struct Frame {
    double t = 0.0;  ///< [s]
    std::shared_ptr<const Measurement> measurement;  ///< what was seen at t
    /// Per sample of `measurement` (Measurement::num_samples): its index among the entry's
    /// samples (the report lists the samples in that order, e.g. the file's rows that were
    /// seen). Empty in every frame: the frames' samples in turn.
    std::vector<int> sample;
  };
  int case_index = 0;         ///< into Scene::cases
  std::vector<Frame> frames;  ///< t ascending, each within [0, dynamics.duration]

  /// The samples of all frames (the entry's recorded samples; a reading's force and moment
  /// count as two).
  int num_samples() const;
  /// A `reaction` sequence (its frames hold readings).
  bool is_reaction() const {
    return !frames.empty() && frames.front().measurement->needs_reactions();
  }
};

/// The rest arc lengths [m] of the vertices a sequence of case `index` is observed on: those of
/// the case's whole rod (a symmetric case's too, as the fit runs it), held points on the vertex
/// nearest them. Throws std::invalid_argument for a case that is not a valid rod.
std::vector<double> CaseVertexArcLengths(const Scene& scene, int index);

/// The sequences' weighted residuals (model - measured) / sigma at one parameter value, laid out
/// sequence by sequence, frame by frame, as the frame's observation lays out its own, and with
/// fitted names their Jacobian d r / d log p from the forward sensitivities.
struct SequenceEvaluation {
  bool ok = false;
  std::string reason;           ///< the first case or frame that could not be evaluated
  Eigen::VectorXd residuals;    ///< NaN rows where a case's run or a frame's model failed
  Eigen::MatrixXd jacobian;     ///< residuals x names (empty without names)
  int noise_residuals = 0;      ///< rows that carry noise (Measurement::num_noise_residuals)
};

/// Runs each case that has sequences once from its initial state (SampleCaseDynamics at every
/// vertex, at the union of its sequences' frame times; with `names`, with the sensitivities of
/// their logs) and evaluates every frame's observation on the vertices at its time, chained with
/// d x / d log p. Throws std::invalid_argument as FitSequences.
SequenceEvaluation EvaluateSequenceResiduals(const Scene& scene,
                                             const std::vector<ObservationSequence>& sequences,
                                             const std::vector<std::string>& names,
                                             const StaticsOptions& statics);

/// The errors of a sequence fit at one parameter value, for reports: per sequence, per sample
/// (ObservationSequence::Frame::sample), model minus measured in the entry's unit ([m]; [px]
/// with the third component 0; a reading's force [N], then its moment [N m]), NaN where the run
/// or the frame's model failed.
struct SequenceResiduals {
  bool ok = false;
  std::string reason;
  std::vector<std::vector<Eigen::Vector3d>> error;
  /// Per case with sequences, its run at the union of their frame times (every vertex): what
  /// the report draws over time.
  std::vector<FittedRun> trajectories;
};

/// Fits `names` of a moving scene (Scene::dynamics set; each with a start value > 0) to
/// observation sequences of its cases by the least-squares fit above on the residuals of
/// EvaluateSequenceResiduals: the predictions the open-loop trajectory of each case from its
/// initial state (solve/case_dynamics.h), each case integrated once per evaluation with its
/// exact sensitivities; a reaction sequence's readings against the run's held-point reactions
/// (MovingReactions) and their derivatives. options.method must be Levenberg–Marquardt;
/// options.marker_sigma is unused (each frame's observation or reading has its sigma). The residual variance counts the residuals
/// that carry noise (a closest-point residual fewer, Observation::num_noise_residuals).
/// error_start / error_fitted are the mean absolute residual components times their sigma
/// (in the entries' units). Throws std::invalid_argument as FitMotion does, and for a sequence
/// with no frames, a frame without an observation or reading (or with both), with another
/// case's vertex count, at a time outside the run or out of order, a reading at a point the
/// case does not hold (a moment other than a clamp's), readings of one sequence that differ in
/// point or sigma, or with a sample index list that is not a numbering of the entry's samples.
MotionFitResult FitSequences(const Scene& scene, const std::vector<ObservationSequence>& sequences,
                             const std::vector<std::string>& names, const StaticsOptions& statics,
                             const MotionFitOptions& fit_options);

/// The errors of every sample of `sequences` along the scene's trajectories.
SequenceResiduals EvaluateSequences(const Scene& scene,
                                    const std::vector<ObservationSequence>& sequences,
                                    const StaticsOptions& statics);

/// FitMotion with the default method, at most `max_evaluations` rollouts of every recording,
/// each parameter within [start / range, start * range].
MotionFitResult FitToRecordings(const Scene& scene, const std::vector<MotionRecordingData>& recordings,
                                const std::vector<std::string>& names, const RolloutOptions& options,
                                const StaticsOptions& statics, int max_evaluations = 150,
                                double range = 100.0);

}  // namespace rodfit
