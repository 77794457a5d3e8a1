// What a scene declares: the rod, its material, gravity and the load cases (docs/model.md,
// docs/formats.md). Plain data with SI units; io/ fills it from YAML, model/ and solve/ build only
// what it needs.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/cross_section.h"

namespace rodfit {

using Vec3 = Eigen::Vector3d;

/// Geometry and mass of the rod, the `rod:` block of the scene YAML.
struct RodSpec {
  double length = 0.0;          ///< [m]
  int segments = 0;             ///< number of edges n (>= 2)
  double radius = 0.0;          ///< [m]
  double linear_density = 0.0;  ///< [kg/m]
  /// Intrinsic curvature at rest (k1°, k2°, tau°) [1/m]; [0, k, 0] with k > 0 bends the unloaded
  /// rod towards the clamp's normal.
  Vec3 rest_curvature = Vec3::Zero();
  /// The rod's natural shape as intrinsic curvature varying along it (docs/model.md, "Rest
  /// shape"): (k1°, k2°, tau°) [1/m] at the arc lengths `rest_curvature_s` [m] (strictly
  /// increasing, within [0, length]), linear between them and constant beyond, added to
  /// `rest_curvature`. From `rod.rest_shape` (a centre-line at rest) or fitted (the
  /// `rest_curvature` parameters of a motion fit). Empty: none.
  std::vector<double> rest_curvature_s;
  std::vector<Vec3> rest_curvature_profile;
  /// Optional arc lengths of the vertices [m], strictly increasing from 0 to `length`
  /// (segments + 1 values); empty: `segments` equal edges.
  std::vector<double> vertex_s;
};

/// Material parameters (docs/model.md, "Stiffnesses"; the `parameters:` values).
struct Material {
  double bend_stiffness = 0.0;                 ///< B1 [N m^2], resists k1 (rotation about d1)
  std::optional<double> bend_stiffness_2;      ///< B2 [N m^2], resists k2; absent = B1
  double twist_stiffness = 0.0;                ///< GJ [N m^2]
  double stretch_stiffness = 0.0;              ///< EA [N]
  double spring_stiffness = 0.0;               ///< K [N/m^2] of the tissue springs
  /// Stiffness [N/m^2] of spring zones that have a parameter of their own, by parameter name.
  std::map<std::string, double> spring_parameters;
  double ring_bend_stiffness = 0.0;     ///< kb [N m^2] of the cross-section ring (tissue §4)
  double ring_stretch_stiffness = 0.0;  ///< ks [N] of the cross-section ring
  // Damping, read by the dynamics only (docs/model.md, "Dynamics").
  double damping = 0.0;          ///< c [N s/m^2]: external viscous drag per length, -c v
  double bend_damping = 0.0;     ///< eta_B [N m^2 s]: viscosity of the bending rates
  double twist_damping = 0.0;    ///< eta_GJ [N m^2 s]: viscosity of the twist rate
  double stretch_damping = 0.0;  ///< eta_EA [N s]: viscosity of the stretch rate

  double B1() const { return bend_stiffness; }
  double B2() const { return bend_stiffness_2 ? *bend_stiffness_2 : bend_stiffness; }
};

/// Clamp at s = 0: d3 = tangent, d1 = normal (Gram–Schmidt against the tangent), d2 = d3 x d1.
/// Neither vector needs unit length.
struct Clamp {
  Vec3 position = Vec3::Zero();     ///< [m]
  Vec3 tangent = Vec3::UnitX();
  Vec3 normal = Vec3::UnitZ();
  /// [deg] a fit's nuisance: the frame turned by a fitted rotation vector phi (R = Exp(phi) R,
  /// about the clamp's point) with a zero-mean Gaussian prior of this std per world axis; absent:
  /// the frame is as given. In (0, 90]. Ignored by simulate and synth.
  std::optional<double> rotation_prior_deg;
  /// [m] a fit's nuisance: the held point offset by a fitted 3-vector with a zero-mean Gaussian
  /// prior of this std per world axis (the frame moves with it); absent: as given. In (0, 0.1].
  /// Ignored by simulate and synth.
  std::optional<double> position_prior;
};

/// A stretch of arc length [from, to] [m].
struct Interval {
  double from = 0.0, to = 0.0;
};

/// Springs tying the rod to its rest position over [from, to] (tissue paper: attachment to the
/// surroundings). Stiffness: `spring_stiffness`, or the named parameter when `parameter` is set.
struct SpringZone {
  double from = 0.0, to = 0.0;  ///< [m]
  std::string parameter;        ///< empty: spring_stiffness
};

/// An instrument holding the material point at arc length s at `position` (a grasp). The rod
/// model moves its nearest vertex to s, so the held point is the material point at s.
struct Grasp {
  double s = 0.0;                ///< [m]
  Vec3 position = Vec3::Zero();  ///< [m]
  std::optional<double> position_prior;  ///< [m] as Clamp::position_prior
};

/// A clamp at s = L: position and orientation held, with the conventions of Clamp (d3 =
/// tangent, d1 = normal). Without a normal the end may turn freely about its tangent.
struct EndClamp {
  Vec3 position = Vec3::Zero();   ///< [m]
  Vec3 tangent = Vec3::UnitX();
  std::optional<Vec3> normal;
  /// [deg] as Clamp::rotation_prior_deg (needs the normal).
  std::optional<double> rotation_prior_deg;
  std::optional<double> position_prior;  ///< [m] as Clamp::position_prior
};

/// An interior point held in position only (a pin): the material point at s stays at
/// `position`, free to turn.
struct Pin {
  double s = 0.0;                ///< [m], in (0, L)
  Vec3 position = Vec3::Zero();  ///< [m]
  std::optional<double> position_prior;  ///< [m] as Clamp::position_prior
};

/// A dead moment [N m] applied at arc length s (to the edge there; shared by the two edges
/// around s when s lies between their midpoints).
struct PointMoment {
  double s = 0.0;
  Vec3 moment = Vec3::Zero();
};

/// Where a case's solve starts: the straight rod along the clamp, the previous case's
/// solution (a sweep follows one branch), or a given centre-line resampled to the vertices.
struct StartShape {
  enum class Kind { kStraight, kPrevious, kPoints };
  Kind kind = Kind::kStraight;
  std::string file;        ///< for kPoints: where the points came from (messages)
  std::vector<double> s;   ///< for kPoints: arc lengths of the points, or empty (chord lengths)
  Eigen::Matrix3Xd points; ///< for kPoints: the ordered centre-line [m]
};

/// A mirror plane of the whole case (geometry, loads and held ends): the solver then solves
/// the half from the clamp to the plane, with the plane's conditions at the rod's middle.
struct SymmetryPlane {
  Vec3 point = Vec3::Zero();       ///< [m], a point of the plane
  Vec3 normal = Vec3::UnitX();     ///< the plane's normal, need not be unit
};

/// An instrument pushing the tissue at arc length s: the force acts on the rod (a point force)
/// and, in the section plane, on the cross-section ring (docs/model.md, "Cross-section").
struct Poke {
  double s = 0.0;              ///< [m]
  Vec3 force = Vec3::Zero();   ///< [N]
};

/// A dead force applied at arc length s (linearly shared by the two vertices around s).
struct PointForce {
  double s = 0.0;              ///< [m], in [0, L]
  Vec3 force = Vec3::Zero();   ///< [N]
};

/// Samples of a quantity over time [s], strictly increasing, interpolated linearly between
/// samples and held constant before the first and after the last.
struct TimeSeries {
  std::string file;                ///< where the samples came from (messages)
  std::vector<double> t;           ///< [s]
  std::vector<Vec3> a;             ///< first vector: a position [m] or a force [N]
  std::vector<Vec3> b, c;          ///< optional: tangent and normal, or a moment [N m]
  bool empty() const { return t.empty(); }
};

/// A held point moved along a recorded path (dynamics): `point` is "clamp", "end_clamp",
/// "end_pin", "grasp" or "pins[k]"; `path.a` its position, and for a clamp or end clamp with
/// orientation columns `path.b` its tangent and `path.c` its normal.
struct DrivenPoint {
  std::string point;
  TimeSeries path;
};

/// How a moving case starts: at rest in its equilibrium (the statics from `start`), or at rest
/// or moving in a given shape (the `start` shape itself, with velocities per vertex).
struct InitialMotion {
  bool equilibrium = true;          ///< solve the statics first (else: the start shape as is)
  std::vector<double> velocity_s;   ///< [m] arc lengths of the velocity samples
  Eigen::Matrix3Xd velocity;        ///< [m/s] per sample; empty: at rest
  std::string file;                 ///< where the velocities came from (messages)
};

/// Time stepping of a scene (`dynamics:`): every case is integrated from its initial state.
/// Most halvings of an implicit step (DynamicsSpec::max_halvings): 2^20 substeps.
inline constexpr int kMaxStepHalvings = 20;

/// The defaults of a dynamics setting, declared once (the scene YAML's DynamicsSpec and the
/// library's DynamicsOptions both read them): BDF2 damps the unresolved stiff modes of driven and
/// stiff rods, which the midpoint keeps; a step whose Newton does not converge (a driven rod
/// whose held points jump far in one step leaves Newton's basin) is retried in halves.
inline constexpr const char* kDefaultIntegrator = "bdf2";
inline constexpr int kDefaultMaxHalvings = 4;
inline constexpr double kDefaultTimeStep = 1e-3;  ///< [s]

struct DynamicsSpec {
  double time_step = kDefaultTimeStep;  ///< [s]
  double duration = 1.0;        ///< [s]
  std::string integrator = kDefaultIntegrator;  ///< a registered scheme (explicit, bdf2, ...)
  int output_every = 1;         ///< write every this many steps
  bool substep = false;         ///< explicit: substep a time_step above the stable step
  /// Implicit: a step whose Newton iterations do not converge is retried in halves, down to
  /// time_step / 2^max_halvings (DynamicsOptions::max_halvings); 0: it fails.
  int max_halvings = kDefaultMaxHalvings;
  /// Implicit: adaptive substeps whose local error stays within this many metres
  /// (DynamicsOptions::error_tolerance); 0: fixed steps.
  double error_tolerance = 0.0;
  double min_time_step = 1e-7;  ///< [s] adaptive: the shortest substep
};

/// One quasi-static load case: the rod clamped and loaded, solved to equilibrium.
struct LoadCase {
  std::string name;
  Clamp clamp;
  Vec3 tip_force = Vec3::Zero();    ///< [N] at s = L
  /// [N m] at s = L, fixed in space: the end balance m(L) = M (not conservative in 3-D).
  Vec3 tip_moment = Vec3::Zero();
  /// [N m] at s = L, turning with the end: components along the last edge's d1, d2, d3.
  Vec3 tip_moment_follower = Vec3::Zero();
  std::vector<PointForce> point_forces;
  std::vector<PointMoment> point_moments;
  std::optional<EndClamp> end_clamp;  ///< s = L held in position and orientation
  std::optional<Vec3> end_pin;        ///< s = L held in position only [m]
  std::optional<double> end_pin_position_prior;  ///< [m] as Clamp::position_prior
  std::vector<Pin> pins;              ///< interior points held in position
  StartShape start;                   ///< where the solve starts
  std::optional<SymmetryPlane> symmetry;
  std::vector<Interval> cuts;    ///< springs removed here: tissue cut free (K = 0)
  std::optional<Grasp> grasp;    ///< an instrument holding the rod
  std::optional<Poke> poke;      ///< an instrument pushing the tissue (needs Scene::section)
  // Dynamics only (Scene::dynamics).
  std::vector<DrivenPoint> drives;  ///< held points moved along recorded paths
  TimeSeries tip_load;              ///< extra tip force (a) [N] and moment (b) [N m] over time
  InitialMotion initial;
};

/// A whole scene: one rod and material shared by every case.
struct Scene {
  RodSpec rod;
  Material material;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);  ///< [m/s^2]
  /// [deg] a fit's nuisance per case (the camera's tilt): each case's gravity turned by a fitted
  /// rotation vector perpendicular to it with a zero-mean Gaussian prior of this std per axis;
  /// absent: gravity as given. In (0, 90]. Ignored by simulate and synth.
  std::optional<double> gravity_prior_deg;
  std::vector<SpringZone> springs;        ///< attachment zones shared by every case
  std::optional<SectionSpec> section;     ///< the cross-section model, for pokes
  std::vector<LoadCase> cases;
  std::optional<DynamicsSpec> dynamics;   ///< time stepping instead of statics
};

}  // namespace rodfit
