// One case of a scene integrated in time (docs/solvers.md, "Dynamics"): the initial state (the
// case's equilibrium with its driven points where their paths start, or its start shape with
// given velocities), the driven points and the tip load over time, and the frames written out.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rodfit/model/rod.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

/// The pose of a case's held boundary from its driven points' paths and its tip load series
/// (held points without a path stay at the case's targets).
class CaseDrive : public Drive {
 public:
  /// Throws std::invalid_argument for a driven point the case does not hold.
  CaseDrive(const RodModel& model, const LoadCase& load_case);
  void PoseAt(const RodModel& model, double t, HeldPose* pose) const override;

 private:
  const TimeSeries* clamp_ = nullptr;
  const TimeSeries* end_clamp_ = nullptr;
  std::vector<const TimeSeries*> held_;  // per RodModel::held(), null when not driven
  const TimeSeries* tip_load_ = nullptr;
};

/// One written frame: the time, the vertices and the held points' reactions (the clamp's
/// includes the rod's inertia and drag: its balance is that of the moving rod).
struct TrajectoryFrame {
  double t = 0.0;
  Mat3X x;
  std::vector<HeldReaction> reactions;
};

struct CaseTrajectory {
  bool ok = false;
  std::string reason;                 ///< why it stopped early (empty when it ran to the end)
  std::vector<double> s;              ///< [m] the vertices' arc lengths
  std::vector<TrajectoryFrame> frames;
  int steps = 0;
  int halved_steps = 0;               ///< implicit: steps taken in halves (max_halvings)
  int newton_iterations = 0;          ///< implicit: in all
  double stable_step = 0.0;           ///< explicit: the stable step at the start [s]
  double seconds = 0.0;               ///< wall time of the integration
  /// The largest excess of the rod's energy over its start plus the work done on it, over the
  /// energy envelope's margin (integration.h, kEnergyEnvelopeMargin): above 1 it stopped.
  double energy_excess_ratio = 0.0;
};

/// The held points' reactions of a moving rod at the end of a step (docs/formats.md,
/// `reactions.csv`): HeldReactions at the state `q`, with the clamp's balance that of the moving
/// rod — less each free vertex's inertia and external drag m a + c v (a = (v - v_before) / dt,
/// the step's change of rate; none when dt = 0) and plus the pose's dead loads over time (its
/// tip force and moment, its point force). v and v_before are the model's free-dof rates. Left
/// out: the edges' spin inertia (~r^2 / L^2 of the inertia kept) and the internal damping's
/// forces on held vertices.
std::vector<HeldReaction> MovingReactions(const RodModel& model, const RodState& q, const VecX& v,
                                          const VecX& v_before, double dt, const HeldPose& pose);

/// Derivatives of MovingReactions along parameter directions: for each held point (same order)
/// a 6 x m matrix, rows d force and d moment, given the state's sensitivities dq, dv and
/// dv_before (num_free_dofs x m, DynamicSensitivity's layout). Moment loads are not supported.
std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> MovingReactionDerivatives(
    const RodModel& model, const RodState& q, const VecX& v, const VecX& v_before, double dt,
    const HeldPose& pose, const Eigen::MatrixXd& dq, const Eigen::MatrixXd& dv,
    const Eigen::MatrixXd& dv_before, const std::vector<ParameterDirection>& directions);

/// The case's state at t = 0 (see InitialMotion); throws std::runtime_error when the initial
/// equilibrium does not converge.
DynamicState InitialDynamicState(const Scene& scene, int index, const StaticsOptions& statics,
                                 const DynamicsStepper& stepper);

/// Integrates case `index` of a scene with `scene.dynamics` (which must be set). `progress`, when
/// given, is called with the simulated time after each step; with adaptive steps, `schedule`
/// (when given) records or replays them (DynamicsStepper::SetSchedule).
CaseTrajectory SimulateCaseDynamics(const Scene& scene, int index, const StaticsOptions& statics,
                                    const std::function<void(double)>& progress = nullptr,
                                    StepSchedule* schedule = nullptr);

/// The model of a case for dynamics: its held points where the driven paths start.
LoadCase CaseAtStart(const LoadCase& load_case);

/// Points of the centre-line at given arc lengths and times along a case's trajectory (at the
/// vertices' arc lengths: the shapes an observation sequence's frames are evaluated on,
/// docs/formats.md, "Observation sequences").
struct CaseSamples {
  bool ok = false;
  std::string reason;                 ///< why the integration stopped early
  std::vector<Eigen::Matrix3Xd> x;    ///< per time, 3 x points [m]
  /// Per time, 3 points x directions: d x / d log p (rows 3 m .. 3 m + 2 point m's
  /// coordinates); empty without directions.
  std::vector<Eigen::MatrixXd> dx;
  /// With reactions asked for: per time, every held point's reaction of the whole rod
  /// (MovingReactions, linear between the steps around it), and with directions their
  /// derivatives (per time, per point, 6 x directions).
  std::vector<std::vector<HeldReaction>> reactions;
  std::vector<std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>>> d_reactions;
  int steps = 0;
  double seconds = 0.0;               ///< wall time of the integration
};

/// Integrates case `index` of a scene with `scene.dynamics` from its initial state (as
/// SimulateCaseDynamics) up to the last of `t` and returns the centre-line at each arc length
/// of `s` (linear between the vertices around it, in the reference arc length) at each time of
/// `t` (linear between the steps around it, exact on a step). With `directions`, also their
/// forward sensitivities through the implicit steps (docs/solvers.md, "Sensitivities in time";
/// backward_euler and bdf2 only: another integrator stops with the reason); with
/// `with_reactions`, the held points' reactions (and their derivatives) at each time. Throws
/// std::invalid_argument for `t` not ascending within [0, dynamics.duration] or `s` outside
/// [0, L]; std::runtime_error when the initial equilibrium does not converge.
CaseSamples SampleCaseDynamics(const Scene& scene, int index, const StaticsOptions& statics,
                               const std::vector<double>& s, const std::vector<double>& t,
                               const std::vector<ParameterDirection>& directions,
                               bool with_reactions = false);

}  // namespace rodfit
