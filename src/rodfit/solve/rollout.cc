#include "rodfit/solve/rollout.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "rodfit/model/check.h"
#include "rodfit/model/frames.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/integration.h"

namespace rodfit {
namespace {

bool Seen(const Eigen::Matrix3Xd& frame, int m) { return frame.col(m).allFinite(); }

// The path of marker m over the frames that saw it (dropped frames are interpolated over).
TimeSeries MarkerPath(const std::vector<Eigen::Matrix3Xd>& frames, int m, double dt) {
  TimeSeries p;
  for (size_t k = 0; k < frames.size(); ++k) {
    if (!Seen(frames[k], m)) continue;
    p.t.push_back(k * dt);
    p.a.push_back(frames[k].col(m));
  }
  return p;
}

// Marker path `of` interpolated linearly at time t (held at its ends), as the engine reads a
// drive. A binary search: the resampled held paths have ten samples a frame.
Vec3 At(const TimeSeries& of, double t) {
  const size_t n = of.t.size();
  size_t j = static_cast<size_t>(std::upper_bound(of.t.begin(), of.t.end(), t) - of.t.begin());
  j = j == 0 ? 0 : j - 1;  // the last sample at or before t (the first when t precedes it)
  if (j + 1 < n && t > of.t[j]) {
    const double w = (t - of.t[j]) / (of.t[j + 1] - of.t[j]);
    return (1 - w) * of.a[j] + w * of.a[j + 1];
  }
  return of.a[j];
}

// A held marker's recorded path smoothed in time: each sample replaced by the value at its time
// of the least-squares quadratic through the samples within +-half_window frames (a centred
// Savitzky-Golay filter, which keeps a quadratic motion exactly). Motion capture's ~1 mm noise
// differenced at 100 Hz is a velocity noise of ~0.1 m/s: driving a stiff rod with it jerks it.
void Smooth(TimeSeries* path, double frame_interval, int half_window) {
  if (half_window <= 0 || path->t.size() < 3) return;
  const std::vector<Vec3> raw = path->a;
  const double reach = (half_window + 0.5) * frame_interval;
  for (size_t k = 0; k < raw.size(); ++k) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Matrix3d B = Eigen::Matrix3d::Zero();  // columns: sum phi_j * x (per coordinate)
    int used = 0;
    for (size_t j = 0; j < raw.size(); ++j) {
      const double d = path->t[j] - path->t[k];
      if (std::abs(d) > reach) continue;
      const Eigen::Vector3d phi(1.0, d / frame_interval, std::pow(d / frame_interval, 2));
      A += phi * phi.transpose();
      B += phi * raw[j].transpose();
      ++used;
    }
    if (used >= 4) path->a[k] = A.ldlt().solve(B).row(0).transpose();
  }
}

// The rod's tangent at marker `end` (0 or M-1) in frames 0 and 1, averaged, from the quadratic
// through it and its two neighbours in arc length (the chord to the next marker is off by half
// the turn of the rod between them, several degrees where a gripper bends a cable): pointing
// along the rod at the clamp (end 0) and out of it at the far end (M-1). Only the first two
// frames are read, as the start is.
Vec3 EndTangent(const std::vector<Eigen::Matrix3Xd>& frames, const std::vector<double>& marker_s,
                int end) {
  const int step = end == 0 ? 1 : -1;
  const int i0 = end, i1 = end + step, i2 = end + 2 * step;
  const double s1 = std::abs(marker_s[i1] - marker_s[i0]);
  const double s2 = std::abs(marker_s[i2] - marker_s[i0]);
  Vec3 sum = Vec3::Zero();
  for (int k = 0; k < 2; ++k) {
    const Eigen::Matrix3Xd& f = frames[k];
    sum += QuadraticEndTangent(f.col(i0), f.col(i1), f.col(i2), s1, s2);
  }
  return (end == 0 ? 1.0 : -1.0) * sum.normalized();
}

// A frame [d1 d2 d3] from a tangent and a normal (made perpendicular).
Eigen::Matrix3d FrameOf(const Vec3& tangent, const Vec3& normal) {
  const Vec3 t = tangent.normalized();
  const Vec3 d1 = (normal - normal.dot(t) * t).normalized();
  Eigen::Matrix3d F;
  F << d1, t.cross(d1), t;
  return F;
}

// The rotation of the rotation vector w [rad].
Eigen::Matrix3d RotationOf(const Vec3& w) {
  const double angle = w.norm();
  if (angle == 0.0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// Gripper `g`'s frame at time t as the rollout holds it: the markers' frame, replaced by the
// diagnostic's (RolloutOptions::gripper_frame) when set, then turned by the gripper's constant
// rotation in its own frame (RolloutOptions::gripper_rotation).
Eigen::Matrix3d GripperFrame(const RolloutOptions& options, int g, double t,
                             const Eigen::Matrix3d& from_markers) {
  Eigen::Matrix3d F = options.gripper_frame ? options.gripper_frame(g, t, from_markers)
                                            : from_markers;
  return F * RotationOf(options.gripper_rotation[g]);
}

// Marker m's recorded path, smoothed (RolloutOptions::smooth_frames), then resampled between
// its frames by its C1 cubic (ResampleHeldPath): every held quantity derived from it (the clamps'
// positions and frames, the pins, the markers in the jaws) follows the cubic.
TimeSeries SmoothedPath(const std::vector<Eigen::Matrix3Xd>& frames, int m, double frame_interval,
                        const RolloutOptions& options) {
  TimeSeries p = MarkerPath(frames, m, frame_interval);
  Smooth(&p, frame_interval, options.smooth_frames);
  ResampleHeldPath(&p, frame_interval);
  return p;
}

// How the rollout holds the rod's ends (RolloutOptions::held_ends with the held markers).
struct HeldEndsPlan {
  bool pinned_pairs = false;     ///< kPinnedPairs
  bool offset_at_start = false;  ///< kGrippers, kFreeRoll: the first frames' tangent offset
  bool per_frame = false;        ///< kGrippersPerFrame: every frame's quadratic tangent
  bool clamp_jaw = false;        ///< kJaws with marker 1 held: the rod starts at marker 1
  bool end_jaw = false;          ///< kJaws with n-2, n-1 held: the rod ends at marker n-2
  bool clamp_oriented = false;   ///< the clamp a gripper (marker 1 held, not pins)
  bool end_oriented = false;     ///< an end clamp (markers n-2, n-1 held, not pins)
  bool end_roll_held = false;    ///< the end clamp's roll held (not kFreeRoll)
};

HeldEndsPlan PlanHeldEnds(const RolloutOptions& options, const std::vector<char>& held) {
  using Ends = RolloutOptions::HeldEnds;
  const int M = static_cast<int>(held.size());
  HeldEndsPlan p;
  p.pinned_pairs = options.held_ends == Ends::kPinnedPairs;
  p.offset_at_start = options.held_ends == Ends::kGrippers || options.held_ends == Ends::kFreeRoll;
  p.per_frame = options.held_ends == Ends::kGrippersPerFrame;
  if (p.per_frame)
    RODFIT_CHECK_ARG(M >= 7 && held[1] && held[2] && held[M - 3] && held[M - 2] && held[M - 1],
                     "held_ends grippers-per-frame reads markers 0, 1, 2 and n-3, n-2, n-1 at "
                     "every frame: hold them (--held 0,1,2,-3,-2,-1) and give at least 7 markers");
  // Marker 1 held: it orients the clamp (its tangent points at marker 1) rather than pinning a
  // second point 1 marker gap away, which noise in the two would stretch against EA.
  p.clamp_oriented = held[1] && !p.pinned_pairs;
  // Markers n-2 and n-1 both held: an end clamp at n-1 along n-2 -> n-1 (the same reason).
  p.end_oriented = held[M - 1] && held[M - 2] && M - 2 > 1 && !p.pinned_pairs;
  p.end_roll_held = p.end_oriented && options.held_ends != Ends::kFreeRoll;
  // The jaws at an end whose two markers are held (else that end is held as by the pins).
  p.clamp_jaw = options.held_ends == Ends::kJaws && held[1];
  p.end_jaw = options.held_ends == Ends::kJaws && p.end_oriented;
  return p;
}

// The recording's checks (a dynamics, at least 2 frames and 3 markers, every marker seen in
// frames 0 and 1), the held markers and the markers' arc lengths (frame 0's polyline scaled to
// the rod's length): result->held and result->marker_s.
void MarkerArcLengths(const Scene& scene, const std::vector<Eigen::Matrix3Xd>& frames,
                      const RolloutOptions& options, RolloutResult* result) {
  RolloutResult& out = *result;
  RODFIT_CHECK_ARG(scene.dynamics, "rollout needs a dynamics: block");
  RODFIT_CHECK_ARG(frames.size() >= 2, "a recording needs at least 2 frames");
  const int M = static_cast<int>(frames[0].cols());
  RODFIT_CHECK_ARG(M >= 3, "a recording needs at least 3 markers");
  out.held = HeldMarkers(options, M);
  for (int m = 0; m < M; ++m) {
    if (!Seen(frames[0], m))
      throw std::invalid_argument("marker " + std::to_string(m) + " is missing in frame 0 (the start)");
    if (!Seen(frames[1], m))
      throw std::invalid_argument("marker " + std::to_string(m) + " is missing in frame 1 (the start's velocity)");
  }
  // Arc lengths from frame 0's polyline, scaled to the rod's length.
  const double L = scene.rod.length;
  std::vector<double> chord(M, 0.0);
  for (int m = 1; m < M; ++m) chord[m] = chord[m - 1] + (frames[0].col(m) - frames[0].col(m - 1)).norm();
  RODFIT_CHECK_ARG(chord[M - 1] > 0.0, "the markers of frame 0 coincide");
  out.marker_s.resize(M);
  for (int m = 0; m < M; ++m) out.marker_s[m] = L * chord[m] / chord[M - 1];
  for (int m = 1; m < M; ++m)
    if (!(out.marker_s[m] > out.marker_s[m - 1]))
      throw std::invalid_argument("markers " + std::to_string(m - 1) + " and " + std::to_string(m) +
                                  " coincide in frame 0");
}

// The rod from marker m_lo to marker m_hi (with jaws 1 and n-2: the jaws hold the rest rigidly;
// else 0 and n-1) with vertices at every marker on it, the gaps between them subdivided in
// proportion to their length (as many as scene.rod.segments over the whole cable): sc->rod's
// length, vertex_s and segments, its rest shape moved onto its own arc length. Returns each
// marker's vertex (-1 off the rod).
std::vector<int> MarkerVertices(const Scene& scene, const std::vector<double>& marker_s, int m_lo,
                                int m_hi, Scene* sc) {
  const double L = scene.rod.length;
  const int M = static_cast<int>(marker_s.size());
  const double s_lo = marker_s[m_lo];
  std::vector<int> marker_vertex(M, -1);
  marker_vertex[m_lo] = 0;
  sc->rod.length = marker_s[m_hi] - s_lo;
  sc->rod.vertex_s = {0.0};
  for (int m = m_lo + 1; m <= m_hi; ++m) {
    const double gap = marker_s[m] - marker_s[m - 1];
    const int pieces = std::max(1, static_cast<int>(std::lround(scene.rod.segments * gap / L)));
    for (int p = 1; p <= pieces; ++p)
      sc->rod.vertex_s.push_back(marker_s[m - 1] - s_lo + gap * p / pieces);
    sc->rod.vertex_s.back() = marker_s[m] - s_lo;
    marker_vertex[m] = static_cast<int>(sc->rod.vertex_s.size()) - 1;
  }
  sc->rod.vertex_s.back() = sc->rod.length;
  sc->rod.segments = static_cast<int>(sc->rod.vertex_s.size()) - 1;
  for (double& s : sc->rod.rest_curvature_s) s -= s_lo;  // the rest shape stays on the cable
  return marker_vertex;
}

// The clamp's frame over time along its path: its tangent towards marker 1 (`held1`: marker 1's
// recorded path, interpolated over frames where either is missing; else the first tangent t0;
// with the clamp's jaw the path is marker 1's and the tangent from marker 0's; per frame the
// quadratic's through markers 0, 1, 2), its normal carried by parallel transport from n0, the
// gripper's offset on top (`oriented`). Appends d3 to clamp_path->b and d1 to clamp_path->c.
void DriveClampFrame(const std::vector<Eigen::Matrix3Xd>& frames, double frame_interval,
                     const RolloutOptions& options, const std::vector<double>& marker_s,
                     bool held1, const HeldEndsPlan& plan, const Vec3& t0, const Vec3& n0,
                     const Eigen::Matrix3d& clamp_offset, TimeSeries* clamp_path) {
  const TimeSeries p0 = plan.clamp_jaw ? SmoothedPath(frames, 0, frame_interval, options)
                                       : TimeSeries();
  const TimeSeries p1 = held1 && !plan.clamp_jaw ? SmoothedPath(frames, 1, frame_interval, options)
                                                 : TimeSeries();
  const TimeSeries p2 = plan.per_frame ? SmoothedPath(frames, 2, frame_interval, options)
                                       : TimeSeries();
  const double s1 = marker_s[1] - marker_s[0], s2 = marker_s[2] - marker_s[0];
  Vec3 normal = n0, tangent = t0;
  TimeSeries& cp = *clamp_path;
  for (size_t k = 0; k < cp.t.size(); ++k) {
    const Vec3 x0 = plan.clamp_jaw ? At(p0, cp.t[k]) : cp.a[k];
    const Vec3 x1 = plan.clamp_jaw ? cp.a[k] : held1 ? At(p1, cp.t[k]) : Vec3(cp.a[k] + t0);
    const Vec3 tn = plan.per_frame ? QuadraticEndTangent(x0, x1, At(p2, cp.t[k]), s1, s2)
                                   : Vec3((x1 - x0).normalized());
    normal = ParallelTransport<double, double>(tangent, tn, normal);
    normal = (normal - normal.dot(tn) * tn).normalized();
    tangent = tn;
    Eigen::Matrix3d F = FrameOf(tangent, normal) * clamp_offset;
    if (plan.clamp_oriented) F = GripperFrame(options, 0, cp.t[k], F);
    cp.b.push_back(F.col(2));
    cp.c.push_back(F.col(0));
  }
}

// The end clamp at marker n-1 along n-2 -> n-1 (with the end's jaw at n-2; per frame along the
// quadratic's tangent through n-1, n-2, n-3): its path, its tangent over time (with
// end_roll_held its normal too), c->end_clamp at its start, d->point. t0, n0: the clamp's
// tangent and normal at t = 0.
void SetUpEndClamp(const std::vector<Eigen::Matrix3Xd>& frames, double frame_interval,
                   const RolloutOptions& options, const std::vector<double>& marker_s,
                   const HeldEndsPlan& plan, const Vec3& t0, const Vec3& n0, DrivenPoint* driven,
                   LoadCase* c) {
  DrivenPoint& d = *driven;
  const int M = static_cast<int>(frames[0].cols());
  d.path = SmoothedPath(frames, plan.end_jaw ? M - 2 : M - 1, frame_interval, options);
  const TimeSeries other = SmoothedPath(frames, plan.end_jaw ? M - 1 : M - 2, frame_interval, options);
  const TimeSeries third = plan.per_frame ? SmoothedPath(frames, M - 3, frame_interval, options)
                                          : TimeSeries();
  const double s1 = marker_s[M - 1] - marker_s[M - 2], s2 = marker_s[M - 1] - marker_s[M - 3];
  // The end's tangents over time (out of the rod), and the end gripper's normal at t = 0: the
  // clamp's carried along the first frame's marker polyline (the rod untwisted at rest).
  std::vector<Vec3> tangents;
  for (size_t k = 0; k < d.path.t.size(); ++k) {
    const double t = d.path.t[k];
    const Vec3 last = plan.end_jaw ? At(other, t) : d.path.a[k];
    const Vec3 before = plan.end_jaw ? d.path.a[k] : At(other, t);
    tangents.push_back(plan.per_frame ? Vec3(-QuadraticEndTangent(last, before, At(third, t), s1, s2))
                                      : Vec3((last - before).normalized()));
  }
  Vec3 normal = n0, tangent = t0;
  for (int k = 1; k < M; ++k) {
    const Vec3 chord = (frames[0].col(k) - frames[0].col(k - 1)).normalized();
    normal = ParallelTransport<double, double>(tangent, chord, normal);
    tangent = chord;
  }
  normal = ParallelTransport<double, double>(tangent, tangents.front(), normal);
  tangent = tangents.front();
  Eigen::Matrix3d end_offset = Eigen::Matrix3d::Identity();
  if (plan.offset_at_start) {
    const Vec3 t_fit = EndTangent(frames, marker_s, M - 1);
    end_offset = FrameOf(tangent, normal).transpose() * FrameOf(t_fit, normal);
  }
  // Over time the frame's normal is carried by parallel transport, the gripper's offset on top;
  // without the roll held (kFreeRoll) only the tangent is.
  for (size_t k = 0; k < tangents.size(); ++k) {
    const Vec3 tn = tangents[k];
    normal = ParallelTransport<double, double>(tangent, tn, normal);
    normal = (normal - normal.dot(tn) * tn).normalized();
    tangent = tn;
    const Eigen::Matrix3d F =
        GripperFrame(options, 1, d.path.t[k], FrameOf(tangent, normal) * end_offset);
    d.path.b.push_back(F.col(2));
    if (plan.end_roll_held) d.path.c.push_back(F.col(0));
  }
  EndClamp end;
  end.position = d.path.a.front();
  end.tangent = d.path.b.front();
  if (plan.end_roll_held) end.normal = d.path.c.front();
  c->end_clamp = end;
  d.point = "end_clamp";
}

// The rollout's time stepping: a frame every per_frame steps (dynamics.time_step must divide
// the frame interval), the options' error tolerance unless the scene sets one, and the
// recording's duration.
void SetUpFrameSteps(double frame_interval, size_t num_frames, const RolloutOptions& options,
                     Scene* sc) {
  const double dt = sc->dynamics->time_step;
  const int per_frame = static_cast<int>(std::lround(frame_interval / dt));
  if (per_frame < 1 || std::abs(per_frame * dt - frame_interval) > 1e-9 * frame_interval)
    throw std::invalid_argument("dynamics.time_step must divide the frame interval (" +
                                std::to_string(frame_interval) + " s)");
  sc->dynamics->output_every = per_frame;
  if (sc->dynamics->error_tolerance == 0.0) sc->dynamics->error_tolerance = options.error_tolerance;

  sc->dynamics->duration = (num_frames - 1) * frame_interval;
}

// The rollout's scene (its one case: the clamp, pins and end driven along the held markers'
// paths, the start) and the vertex of each marker; fills out->held and out->marker_s. Shared by
// Rollout and RolloutWithSensitivities, so both integrate the same problem.
struct RolloutProblem {
  Scene scene;
  std::vector<int> marker_vertex;  ///< -1: a marker off the rod (in a gripper's jaws, kJaws)
  /// [m] the arc length of the rod's s = 0 along the recorded cable (kJaws: marker 1's)
  double s_offset = 0.0;
  std::vector<TimeSeries> off_rod;  ///< per marker off the rod: its (smoothed) held path
  double frame_interval = 0.0;
};

RolloutProblem SetUpRollout(const Scene& scene, double frame_interval,
                            const std::vector<Eigen::Matrix3Xd>& frames,
                            const RolloutOptions& options, RolloutResult* result) {
  RolloutResult& out = *result;
  MarkerArcLengths(scene, frames, options, result);
  const int M = static_cast<int>(frames[0].cols());
  const HeldEndsPlan plan = PlanHeldEnds(options, out.held);
  const int m_lo = plan.clamp_jaw ? 1 : 0, m_hi = plan.end_jaw ? M - 2 : M - 1;
  const double s_lo = out.marker_s[m_lo];
  Scene sc = scene;
  const std::vector<int> marker_vertex = MarkerVertices(scene, out.marker_s, m_lo, m_hi, &sc);
  std::vector<TimeSeries> off_rod(M);
  if (plan.clamp_jaw) off_rod[0] = SmoothedPath(frames, 0, frame_interval, options);
  if (plan.end_jaw) off_rod[M - 1] = SmoothedPath(frames, M - 1, frame_interval, options);

  // The case: the clamp at marker 0 along marker 1 (with jaws: at marker 1 along 0 -> 1), pins
  // at the other held markers (the last one an end pin), each driven along its recorded path.
  LoadCase c;
  c.name = "rollout";
  const Vec3 t0 = (frames[0].col(1) - frames[0].col(0)).normalized();
  Vec3 n0 = std::abs(t0.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX();
  n0 = (n0 - n0.dot(t0) * t0).normalized();
  c.clamp.position = frames[0].col(m_lo);
  c.clamp.tangent = t0;
  c.clamp.normal = n0;
  DrivenPoint clamp_drive;
  clamp_drive.point = "clamp";
  clamp_drive.path = SmoothedPath(frames, m_lo, frame_interval, options);
  // kGrippers: a gripper's frame at t = 0 relative to its marker pair's chord frame (the chord to
  // the next marker, its normal carried by parallel transport): the rod's tangent there from the
  // first frames (EndTangent), held rigidly in the chord frame as it moves.
  Eigen::Matrix3d clamp_offset = Eigen::Matrix3d::Identity();
  if (plan.offset_at_start && out.held[1]) {
    const Vec3 t_fit = EndTangent(frames, out.marker_s, 0);
    clamp_offset = FrameOf(t0, n0).transpose() * FrameOf(t_fit, n0);
    const Eigen::Matrix3d F = GripperFrame(options, 0, 0.0, FrameOf(t_fit, n0));
    c.clamp.tangent = F.col(2);
    c.clamp.normal = F.col(0);
  }
  DriveClampFrame(frames, frame_interval, options, out.marker_s, out.held[1], plan, t0, n0,
                  clamp_offset, &clamp_drive.path);
  if (plan.per_frame || plan.clamp_jaw) {  // the start held as the drive's first sample
    c.clamp.tangent = clamp_drive.path.b.front();
    c.clamp.normal = clamp_drive.path.c.front();
  }
  c.drives.push_back(clamp_drive);
  if (plan.end_oriented) {
    DrivenPoint d;
    SetUpEndClamp(frames, frame_interval, options, out.marker_s, plan, t0, n0, &d, &c);
    c.drives.push_back(d);
  }
  for (int m = plan.clamp_oriented ? 2 : 1; m < M; ++m) {
    if (!out.held[m] || (plan.end_oriented && m >= M - 2)) continue;
    if (plan.per_frame && (m == 2 || m == M - 3)) continue;  // read by the grippers' tangents only
    DrivenPoint d;
    d.path = SmoothedPath(frames, m, frame_interval, options);
    if (m == M - 1) {
      c.end_pin = frames[0].col(m);
      d.point = "end_pin";
    } else {
      Pin pin;
      pin.s = out.marker_s[m] - s_lo;
      pin.position = frames[0].col(m);
      c.pins.push_back(pin);
      d.point = "pins[" + std::to_string(c.pins.size() - 1) + "]";
    }
    c.drives.push_back(d);
  }
  // The start: the equilibrium (or the frame-0 polyline) with the velocities of frames 0 -> 1,
  // of the markers on the rod.
  std::vector<double> on_rod_s;
  Eigen::Matrix3Xd start_points(3, m_hi - m_lo + 1);
  for (int m = m_lo; m <= m_hi; ++m) {
    on_rod_s.push_back(out.marker_s[m] - s_lo);
    start_points.col(m - m_lo) = frames[0].col(m);
  }
  c.initial.equilibrium = options.initial_equilibrium;
  if (!options.initial_equilibrium) {
    c.start.kind = StartShape::Kind::kPoints;
    c.start.s = on_rod_s;
    c.start.points = start_points;
  }
  c.initial.velocity_s = on_rod_s;
  c.initial.velocity =
      (frames[1].middleCols(m_lo, m_hi - m_lo + 1) - start_points) / frame_interval;
  sc.cases = {c};
  sc.springs.clear();
  SetUpFrameSteps(frame_interval, frames.size(), options, &sc);

  return {sc, marker_vertex, s_lo, off_rod, frame_interval};
}

// Marker m at frame k as the rollout predicts it from the rod's state x (3 x vertices): its
// vertex, or for a marker off the rod (in a gripper's jaws) its held path.
Vec3 MarkerAt(const RolloutProblem& problem, const Eigen::Matrix3Xd& x, int m, size_t k) {
  const int i = problem.marker_vertex[m];
  return i >= 0 ? Vec3(x.col(i)) : At(problem.off_rod[m], k * problem.frame_interval);
}

// The scores of out->predicted against the recording.
void Score(const std::vector<Eigen::Matrix3Xd>& frames, RolloutResult* result) {
  RolloutResult& out = *result;
  const int M = static_cast<int>(frames[0].cols());
  double sum_all = 0.0, sum_free = 0.0;
  int n_all = 0, n_free = 0;
  for (size_t k = 0; k < out.predicted.size() && k < frames.size(); ++k) {
    const Eigen::Matrix3Xd& p = out.predicted[k];
    if (k == 0) continue;  // the start is given
    for (int m = 0; m < M; ++m) {
      if (!Seen(frames[k], m)) continue;
      const double e = (p.col(m) - frames[k].col(m)).cwiseAbs().sum() / 3.0;
      sum_all += e;
      ++n_all;
      if (!out.held[m]) {
        sum_free += e;
        ++n_free;
      }
    }
  }
  out.samples = n_all;
  out.mae_all = n_all ? sum_all / n_all : 0.0;
  out.mae_predicted = n_free ? sum_free / n_free : 0.0;
}

}  // namespace

// Samples per frame interval of a held path resampled by its cubic (ResampleHeldPath): the engine
// reads a drive linearly between samples, so the samples must be fine for its velocity to be
// nearly continuous; a tenth of a 10 ms frame is the 1 ms with which the diagnosis drove the
// rod exactly (docs/performance.md, BM_JawsFloorDiagnosis).
constexpr int kHeldPathSamplesPerFrame = 10;

void ResampleHeldPath(TimeSeries* path, double frame_interval) {
  const size_t n = path->t.size();
  if (n < 2) return;
  const std::vector<double>& t = path->t;
  const std::vector<Vec3>& x = path->a;
  std::vector<Vec3> v(n);
  if (n == 2) {
    v[0] = v[1] = (x[1] - x[0]) / (t[1] - t[0]);
  } else {
    for (size_t k = 0; k < n; ++k) {
      // The quadratic through samples i-1, i, i+1 (i clamped inside), differentiated at t[k].
      const size_t i = std::clamp<size_t>(k, 1, n - 2);
      const double h0 = t[i] - t[i - 1], h1 = t[i + 1] - t[i];
      const double d = t[k] - t[i];  // -h0, 0 or h1
      // The Lagrange basis's derivatives on (t[i] - h0, t[i], t[i] + h1) at t[i] + d.
      const double l0 = (2 * d - h1) / (h0 * (h0 + h1));
      const double l1 = -(2 * d + h0 - h1) / (h0 * h1);
      const double l2 = (2 * d + h0) / (h1 * (h0 + h1));
      v[k] = l0 * x[i - 1] + l1 * x[i] + l2 * x[i + 1];
    }
  }
  const double fine = frame_interval / kHeldPathSamplesPerFrame;
  TimeSeries out;
  out.file = path->file;
  for (size_t k = 0; k + 1 < n; ++k) {
    const double h = t[k + 1] - t[k];
    const int pieces = std::max(1, static_cast<int>(std::lround(h / fine)));
    out.t.push_back(t[k]);
    out.a.push_back(x[k]);
    for (int j = 1; j < pieces; ++j) {
      const double s = static_cast<double>(j) / pieces, s2 = s * s, s3 = s2 * s;
      out.t.push_back(t[k] + s * h);
      out.a.push_back((2 * s3 - 3 * s2 + 1) * x[k] + (s3 - 2 * s2 + s) * h * v[k] +
                      (-2 * s3 + 3 * s2) * x[k + 1] + (s3 - s2) * h * v[k + 1]);
    }
  }
  out.t.push_back(t.back());
  out.a.push_back(x.back());
  *path = std::move(out);
}

Vec3 QuadraticEndTangent(const Vec3& x0, const Vec3& x1, const Vec3& x2, double s1, double s2) {
  // Derivatives at s = 0 of the Lagrange basis on (0, s1, s2).
  const double l0 = -(s1 + s2) / (s1 * s2), l1 = s2 / (s1 * (s2 - s1)),
               l2 = -s1 / (s2 * (s2 - s1));
  return (l0 * x0 + l1 * x1 + l2 * x2).normalized();
}

bool DefaultTwistDamping(Material* material) {
  if (material->twist_damping != 0.0 || !(material->bend_damping > 0.0) ||
      !(material->bend_stiffness > 0.0))
    return false;
  material->twist_damping =
      material->bend_damping / material->bend_stiffness * material->twist_stiffness;
  return true;
}

std::vector<char> HeldMarkers(const RolloutOptions& options, int markers) {
  std::vector<char> held(markers, 0);
  for (int h : options.held_markers) {
    const int m = h < 0 ? markers + h : h;
    if (m < 0 || m >= markers)
      throw std::invalid_argument("held marker " + std::to_string(h) + " does not exist");
    held[m] = 1;
  }
  RODFIT_CHECK_ARG(markers >= 1 && held[0], "marker 0 (the clamp) must be held");
  // A rollout whose markers are all driven predicts nothing: its error would read 0 m.
  RODFIT_CHECK_ARG(std::find(held.begin(), held.end(), 0) != held.end(),
                   "every one of the " + std::to_string(markers) +
                       " markers is held (--held): none is left to predict");
  return held;
}

RolloutResult Rollout(const Scene& scene, double frame_interval,
                      const std::vector<Eigen::Matrix3Xd>& frames, const RolloutOptions& options,
                      const StaticsOptions& statics, StepSchedule* schedule) {
  RolloutResult out;
  const RolloutProblem problem = SetUpRollout(scene, frame_interval, frames, options, &out);
  const int M = static_cast<int>(frames[0].cols());
  const CaseTrajectory traj = SimulateCaseDynamics(problem.scene, 0, statics, nullptr, schedule);
  out.seconds = traj.seconds;
  out.halved_steps = traj.halved_steps;
  out.ok = traj.ok;
  out.reason = traj.reason;
  for (size_t k = 0; k < traj.frames.size() && k < frames.size(); ++k) {
    Eigen::Matrix3Xd p(3, M);
    for (int m = 0; m < M; ++m) p.col(m) = MarkerAt(problem, traj.frames[k].x, m, k);
    out.predicted.push_back(p);
  }
  Score(frames, &out);
  return out;
}

RolloutResult RolloutWithSensitivities(const Scene& scene, double frame_interval,
                                       const std::vector<Eigen::Matrix3Xd>& frames,
                                       const RolloutOptions& options, const StaticsOptions& statics,
                                       const std::vector<ParameterDirection>& directions,
                                       std::vector<Eigen::MatrixXd>* d_predicted,
                                       StepSchedule* schedule) {
  RolloutResult out;
  const RolloutProblem problem = SetUpRollout(scene, frame_interval, frames, options, &out);
  const Scene& sc = problem.scene;
  const int M = static_cast<int>(frames[0].cols());
  const int np = static_cast<int>(directions.size());
  // The rest shape's directions on the rod's own arc length (with jaws it starts at marker 1).
  std::vector<ParameterDirection> on_rod = directions;
  for (ParameterDirection& d : on_rod)
    for (double& s_knot : d.rest_curvature_s) s_knot -= problem.s_offset;
  d_predicted->clear();
  // The integration of SimulateCaseDynamics (case_dynamics.cc) with each step's sensitivities
  // propagated after it; only the markers are recorded.
  const DynamicsSpec& spec = *sc.dynamics;
  const RodModel model(sc.rod, sc.material, sc.gravity, CaseAtStart(sc.cases[0]), sc.springs);
  DynamicsStepper stepper(model, DynamicsOptionsFrom(spec));
  stepper.SetSchedule(schedule);
  const CaseDrive drive(model, sc.cases[0]);
  DynamicState s = InitialDynamicState(sc, 0, statics, stepper);
  DynamicSensitivity ds;
  const int N = model.num_free_dofs();
  if (sc.cases[0].initial.equilibrium) {
    if (!EquilibriumSensitivity(model, s.q, on_rod, &ds.dq, &out.reason)) return out;
  } else {
    ds.dq.setZero(N, np);  // the frame-0 polyline does not depend on the parameters
  }
  ds.dv.setZero(N, np);
  auto record = [&]() {
    Eigen::Matrix3Xd p(3, M);
    Eigen::MatrixXd dp = Eigen::MatrixXd::Zero(3 * M, np);
    for (int m = 0; m < M; ++m) {
      const int i = problem.marker_vertex[m];
      p.col(m) = MarkerAt(problem, s.q.x, m, out.predicted.size());
      if (i >= 1) dp.middleRows<3>(3 * m) = ds.dq.middleRows<3>(RodModel::VertexDof(i));
    }
    out.predicted.push_back(p);
    d_predicted->push_back(dp);
  };
  record();
  const int steps = static_cast<int>(std::ceil(spec.duration / spec.time_step - 1e-9));
  int taken = 0;
  const SensitivityCarry carry{&on_rod, &ds};
  const IntegrationStats stats = Integrate(
      stepper, drive, steps, &s,
      [&](const DynamicState&, const DynamicState&, const DynamicsStepSummary&) {
        ++taken;
        if (taken % spec.output_every == 0 || taken == steps) record();
        return true;
      },
      &carry, nullptr, /*energy_envelope=*/true);
  out.halved_steps = stats.halved_steps;
  out.seconds = stats.seconds;
  out.reason = stats.reason;
  out.ok = stats.ok;
  Score(frames, &out);
  return out;
}

}  // namespace rodfit
