// Open-loop prediction of a recorded motion (docs/cli.md, "rollout"): a rod held by tracked
// markers (motion capture of a cable moved by robots), started from its first two frames, its
// held markers driven from the recording, the others predicted; the score is the mean absolute
// coordinate error against the recording.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "rodfit/model/scene.h"
#include "rodfit/model/settings_archive.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/statics.h"

namespace rodfit {

struct RolloutOptions {
  /// Markers driven from the recording; negative counts from the last (-1 the last). Marker 0
  /// is the clamp, it must be among them; with marker 1 held the clamp's tangent points at it
  /// (marker 1 itself is then predicted, not pinned), and with markers n-2 and n-1 held the end
  /// is an end clamp at n-1 along n-2 -> n-1, free to turn about its tangent. Other held markers
  /// are pins (n-1 alone: an end pin).
  std::vector<int> held_markers = {0, 1, -2, -1};
  /// Start at rest in the equilibrium with the held markers at frame 0 (then given the first
  /// two frames' velocities), or in the frame-0 marker polyline itself.
  bool initial_equilibrium = true;
  /// The held markers' paths are smoothed by a centred quadratic over +-this many frames
  /// (0: used as recorded).
  int smooth_frames = 5;
  /// How the held end markers hold the rod (markers 0, 1 and n-2, n-1 held).
  enum class HeldEnds {
    /// Marker 0 a clamp whose tangent points at marker 1, markers 1 and n-2 pinned at their
    /// recorded positions, n-1 an end pin (the default until the jaws: the pinned markers carry
    /// the rod's direction near the grippers, which the marker pairs' chords miss by 10-30
    /// degrees where the grippers bend the cable). At the true parameters of bench_rest_shape,
    /// held-out (pull, loop), noise-free: 7.5 mm with true grippers at the end markers, 13.5 mm
    /// with true jaws (markers 3..n-4: 8.6 and 14.3 mm; BM_HeldEndFloors).
    kPinnedPairs,
    /// Grippers as clamps: the rod clamped at marker 0 and at marker n-1, each gripper's
    /// tangent the rod's at its marker in the first frames (a quadratic through the end marker
    /// and its two neighbours) carried rigidly with the chord to the next marker, its roll by
    /// the minimal-twist frame (the normal carried by parallel transport in time; the end's at
    /// t = 0 along the first frame's marker polyline from the clamp's). Markers 1 and n-2 are
    /// predicted. Right where markers 0, 1 (and n-2, n-1) sit on the grippers themselves.
    kGrippers,
    /// Both ends oriented as by kGrippers, the end free to turn about its tangent.
    kFreeRoll,
    /// Grippers as clamps at markers 0 and n-1 as kGrippers, each gripper's tangent estimated at
    /// every time from that time's markers: the tangent at the end marker of the quadratic in
    /// arc length through it and its two neighbours (QuadraticEndTangent), on their smoothed
    /// paths; the roll by the minimal-twist frame. It reads markers 2 and n-3 at every frame, so
    /// they must be held too (then driven, not predicted): `--held 0,1,2,-3,-2,-1`. It follows
    /// the gripper no better than kGrippers: on bench_rest_shape's true grippers the quadratic
    /// through markers 9 cm apart misses the gripper's tangent by 12-23 degrees on average
    /// (kGrippers: 9-25), the cable's turn being concentrated next to the gripper.
    kGrippersPerFrame,
    /// The grippers' jaws span markers 0..1 and n-2..n-1, the cable straight and rigid in them
    /// (the discrete-elastic-rod convention of prescribing an end's first two vertices): the rod
    /// between markers 1 and n-2 clamped at marker 1 along the chord 0 -> 1 and at marker n-2
    /// along n-2 -> n-1, the rolls by the minimal-twist frame (markers 0, 1, n-2, n-1 held; an
    /// end whose two markers are not both held is held as by kPinnedPairs). The default: the best of these models on both of bench_rest_shape's truths
    /// (BM_HeldEndFloors; true parameters, held-out pull and loop, markers 3..n-4, noise-free /
    /// 1 mm noise): true jaws 0.90 / 1.60 mm (pins 14.3 / 16.5, grippers 29.8 / 29.8); true
    /// grippers at the end markers 6.95 / 7.30 mm (pins 8.6 / 13.0, grippers 14.3 / 14.9,
    /// grippers-per-frame 13.5 / 15.1; with the true gripper frames 0.20 / 1.60).
    kJaws,
  };
  HeldEnds held_ends = HeldEnds::kJaws;
  /// With grippers or jaws (every model but kPinnedPairs), per gripper ([0] the clamp at marker
  /// 0, with jaws at marker 1; [1] the end at marker n-1, with jaws at n-2): a constant rotation [rad], a rotation vector in the gripper's own frame
  /// (d1, d2, d3 = the tangent: about d1 and d2 it tilts the tangent, about d3 it turns the
  /// roll), applied on top of the frame the markers give at every time, the start's included
  /// (the equilibrium start is held by the rotated frames). The motion fit's held-frame
  /// nuisances (MotionFitOptions::gripper_prior_deg); zero: the markers' frames as they are.
  /// With kFreeRoll the end's roll is free, so a turn about its tangent does nothing.
  std::array<Vec3, 2> gripper_rotation{Vec3::Zero(), Vec3::Zero()};
  /// A diagnostic (unset: none): with grippers, each gripper's frame [d1 d2 d3] at time t [s]
  /// is replaced by what this returns given the frame the markers give (e.g. the true frame of
  /// a synthetic recording, or its tangent with the markers' roll), before gripper_rotation.
  std::function<Eigen::Matrix3d(int gripper, double t, const Eigen::Matrix3d& from_markers)>
      gripper_frame;
  /// [m] adaptive steps' local error bound (DynamicsOptions::error_tolerance) where the scene's
  /// dynamics block sets none: a rollout adapts its steps instead of aborting on a fast motion
  /// (a whip at 10 ms steps), landing on every frame.
  double error_tolerance = 1e-4;
};

/// The rollout's settings, declared once (docs/cli.md, "rollout", its settings table): each
/// key with its default (the initializers above), range, and the command line's option and help
/// text (rodfit/model/settings_archive.h). `error_tolerance` is the library's alone.
void Serialize(SettingsArchive* a, RolloutOptions* o);

struct RolloutResult {
  bool ok = false;
  std::string reason;
  std::vector<double> marker_s;           ///< [m] the markers' arc lengths (from frame 0)
  std::vector<char> held;                 ///< per marker: driven
  std::vector<Eigen::Matrix3Xd> predicted;  ///< per frame, 3 x markers [m]
  double mae_all = 0.0;        ///< [m] mean |coordinate error| over all markers, frames >= 1
  double mae_predicted = 0.0;  ///< [m] the same over the markers not driven
  int samples = 0;             ///< marker samples compared (present in the recording)
  double seconds = 0.0;        ///< wall time of the integration
  int halved_steps = 0;        ///< steps whose Newton needed halves (dynamics.max_halvings)
};

/// The twist damping a rollout uses when the scene gives none: bending's retardation time
/// (bend_damping / bend_stiffness) times the twist stiffness, one Kelvin-Voigt time for the
/// material (docs/cli.md, "rollout"). The pins at markers 1 and n-2 kink the rod there; turning
/// with the held points, the kinks drive the edges' twist, whose light spin inertia makes it a
/// fast mode (~1e3-1e4 rad/s). Undamped, BDF2 at steps near its period no longer damps it and its
/// Newton iterations stop converging (the smaller the step, the sooner). Sets
/// material->twist_damping and returns true when it was 0 and bend_damping and bend_stiffness
/// are positive; leaves it otherwise.
bool DefaultTwistDamping(Material* material);

/// The unit tangent at x0 of a curve through x0, x1, x2 at arc lengths 0 < s1 < s2 from x0:
/// the derivative at 0 of the quadratic through them in arc length, normalised (pointing from x0
/// towards x1). Second order: sampled every h along a curve, its direction misses the curve's by
/// O(h^2) (an endpoint derivative amplifies noise sigma to ~2.5 sigma / h per axis).
Vec3 QuadraticEndTangent(const Vec3& x0, const Vec3& x1, const Vec3& x2, double s1, double s2);

/// A held marker's path (samples at multiples of frame_interval [s], some frames possibly
/// dropped) resampled every frame_interval / 10 by the C1 piecewise cubic (Hermite) through its
/// samples, each sample's velocity the derivative of the quadratic through it and its two
/// neighbours (one-sided at the ends): the rollout drives the rod along it. The engine reads a
/// drive linearly between samples; between 10 ms frames that velocity jumps at every frame and
/// jerks a rod moved fast, the cubic's is continuous. The samples keep their times and values
/// exactly; a quadratic motion is reproduced exactly, a smooth one to third order in the frame
/// interval. Fewer than 3 samples: linear.
void ResampleHeldPath(TimeSeries* path, double frame_interval);

/// Per marker of a recording with `markers` markers: whether the rollout drives it
/// (options.held_markers, negative counting from the last). Throws std::invalid_argument for a
/// held marker that does not exist or marker 0 not held.
std::vector<char> HeldMarkers(const RolloutOptions& options, int markers);

/// `frames[k]` holds the markers (3 x M, NaN where a marker was not seen) at time
/// k * frame_interval. The scene gives the rod (length, radius, density; `segments` is the
/// target number of edges, spread over the gaps between markers), the material, gravity and
/// `dynamics` (its time_step must divide the frame interval; its duration is the recording's).
/// The material is used as given (`rodfit rollout` first applies DefaultTwistDamping).
/// Throws std::invalid_argument for unusable input (fewer than 3 markers, a held marker missing
/// from every frame, markers 0 and 1 missing in frame 0 or 1, ...).
/// With adaptive steps, `schedule` (when given) records or replays them: a fit replays its base
/// trajectory's steps so that its objective stays smooth (StepSchedule).
RolloutResult Rollout(const Scene& scene, double frame_interval,
                      const std::vector<Eigen::Matrix3Xd>& frames, const RolloutOptions& options,
                      const StaticsOptions& statics = StaticsOptions(),
                      StepSchedule* schedule = nullptr);

/// The same rollout with the derivatives of its predictions (docs/solvers.md, "Sensitivities in
/// time"): (*d_predicted)[k] is 3 M x directions.size() for frame k, rows 3 m .. 3 m + 2 marker
/// m's coordinates [m], one column per direction (d / d log p). Forward sensitivities through
/// every implicit step (backward_euler or bdf2), started from the initial equilibrium's (zero
/// for a start from the frame-0 polyline). The predictions equal Rollout's. Throws like Rollout;
/// a step whose sensitivities cannot be computed stops it (ok false, with the reason).
RolloutResult RolloutWithSensitivities(const Scene& scene, double frame_interval,
                                       const std::vector<Eigen::Matrix3Xd>& frames,
                                       const RolloutOptions& options, const StaticsOptions& statics,
                                       const std::vector<ParameterDirection>& directions,
                                       std::vector<Eigen::MatrixXd>* d_predicted,
                                       StepSchedule* schedule = nullptr);

}  // namespace rodfit
