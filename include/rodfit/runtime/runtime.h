// The interactive runtime (docs/library.md, "Runtime"): what a surgical simulator links to run a
// fitted rod at haptic rate. It loads a profile (rodfit/runtime/profile.h), builds the rod with
// its held ends and an instrument (the tool) at one arc length, and each tick takes the tool's
// position (a grasp) or force (a poke), advances the rod by one step — a quasi-static Newton
// re-solve warm-started from the last tick, or one implicit dynamic step (solve/dynamics.h) — and
// gives back the centre-line, the reaction force and torque on the tool, and on request the
// tissue's tube mesh with the local dent of a poke (model/tube_mesh.h, tissue paper eqs. 12–13).
//
// Real-time guarantees (docs/library.md, "Runtime"):
//  - Step() does not allocate heap memory: every buffer is sized at construction. Nor does
//    Mesh(TubeMesh*) once the mesh it writes into has the tube's shape (after the first call
//    with it); Mesh() returning a new mesh does.
//  - Step() never returns a non-finite state and never loops without a cap: Newton stops at
//    RuntimeOptions::max_iterations or the wall-time budget, and a step that did not converge
//    restores the last good state and says so in its status and message (the tool force stays
//    the last good one, so a haptic device never sees a jump to NaN).
//  - Step() never stalls: a grasp moves at most max_tool_move per tick towards the tool (in both
//    modes), a tick that failed makes the next ones move a quarter as far (a quasi-static solve
//    cut short is resumed), and a converged state is never rolled back, so a tool that jumped
//    ahead is reached in a bounded number of ticks.
//  - Step() does not pull a grasped rod past RuntimeOptions::max_strain, nor takes a tool input
//    that is not finite or out of range: such ticks say so in their status and message.
// Thread-safety: a Runtime is not thread-safe; use one per thread (or guard it). Distinct
// instances share nothing mutable and may step concurrently on different threads.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>

#include "rodfit/model/rod.h"
#include "rodfit/model/settings_archive.h"
#include "rodfit/model/tube_mesh.h"
#include "rodfit/runtime/profile.h"

namespace rodfit {

/// How a tick advances the rod.
enum class RuntimeMode {
  kQuasiStatic,  ///< the equilibrium at the tool's new position (Newton, warm-started)
  kDynamic,      ///< one implicit time step (BDF2) of the rod with its mass and damping
};

/// What the tool does at arc length RuntimeOptions::tool_s.
enum class ToolKind {
  /// holds the material point at tool_s at the tool's position (free to turn, or with
  /// RuntimeOptions::hold_orientation the edge ending there held at the tool's orientation)
  kGrasp,
  /// pushes the tissue there with a dead force (in dynamic mode the stepper's point force,
  /// shared by the two vertices around tool_s); dents the section
  kPoke,
};

struct RuntimeOptions {
  RuntimeMode mode = RuntimeMode::kQuasiStatic;
  ToolKind tool = ToolKind::kGrasp;
  double tool_s = -1.0;             ///< [m] the tool's arc length, in (0, L]; required
  int max_iterations = 20;          ///< Newton iterations per quasi-static step
  /// Converged when the scaled residual (RodModel's convergence measure) is below this times
  /// the rod's load scale [-] (the statics solver's default).
  double gradient_tolerance = 1e-9;
  /// ... or when a full Newton step moves no vertex by more than this times min(L, 1 m) (and no
  /// twist by more than that in radians) [-]: the statics solver's step test.
  double step_tolerance = 1e-9;
  /// [s] wall time a step may take before it gives up (0: no limit; the iteration cap holds).
  /// Checked before every Newton iteration after the first, in both modes; in dynamic mode the
  /// tick after one lost to it runs without it, to catch up (docs/library.md, "Runtime").
  double time_budget = 0.0;
  /// A grasp, in both modes: the largest move of the grasped point in one tick, as a fraction
  /// of the shortest rest edge l_min [-], in (0, 1]. A tool that ran further ahead (a device
  /// glitch, a tick lost to the time budget) is followed over several ticks
  /// (StepReport::tool_lag), so that one far jump cannot keep every later tick from converging:
  /// a jump of d is reached in ceil(d / (max_tool_move l_min)) ticks (dynamic mode: 5 more, its
  /// move ramping up and down by a quarter per tick) when they converge. After a tick that
  /// failed the next ones move a quarter as far (a poke: apply a quarter of the change of
  /// force), growing back twofold per converged tick.
  double max_tool_move = 0.25;
  /// A grasp, in both modes: the largest strain [-] the tool may pull the rod to, in (0, 1].
  /// The grasped point is kept within (1 + 0.99 max_strain) times the arc length between it and
  /// every other held point (the clamp, pins, an end clamp), and a move that takes the largest
  /// edge strain past max_strain sets a wall across it (a quasi-static tick is taken again to
  /// the wall, so its strain stays within the limit; a dynamic rod's own waves may carry it over
  /// for a few ticks). A tool beyond is followed to that reach, and each such tick says so
  /// (StepStatus::kStrainLimit). A poke's force is refused above max_strain times the rod's
  /// stretch stiffness EA (the force that would stretch it so far).
  double max_strain = kSmallStrainLimit;
  /// [s] dynamic mode: the step of one tick, a BDF2 step of DynamicsStepper to its default
  /// tolerances, with DynamicsOptions::extrapolate_corrections and converge_on_rate on.
  double time_step = 1e-3;
  int dynamic_newton_iterations = 25;  ///< dynamic mode: Newton iterations per step
  int mesh_ring_vertices = 16;      ///< Mesh(): vertices per ring of the tube, in [3, 1024]
  /// Quasi-static grasp only: the tool also holds the orientation of the rod there — the edge
  /// that ends at the grasped vertex is held as a rigid body in the tool's hand (its far vertex
  /// and its twist), so the grasp is a clamp, and ToolTorque() reports the torque on the tool.
  /// SetToolOrientation turns it; tool_s must lie beyond the rod's second vertex.
  bool hold_orientation = false;
  bool Check(std::string* why) const;
};

/// The runtime's options, declared once (docs/library.md, "Runtime", its options table): each
/// key with its default (the initializers above) and range; Check holds the options to them.
/// The C API's rodfit_options and Python's keywords take their defaults from RuntimeOptions.
void Serialize(SettingsArchive* a, RuntimeOptions* o);

enum class StepStatus {
  kConverged,      ///< the new state is the step's solution
  kNotConverged,   ///< iteration cap or failed step: the last good state is kept
  kTimeBudget,     ///< the wall-time budget ran out: the last good state is kept
  /// the step converged, but towards the tool pulled back to RuntimeOptions::max_strain: the tool
  /// is out of the rod's reach (StepReport::tool_lag says how far)
  kStrainLimit,
  /// the tool's position, orientation or force is not finite or out of range (the message
  /// names the value): refused, the last good state kept
  kToolRefused,
};
const char* ToString(StepStatus status);

/// Limits of the tool inputs a step accepts (beyond them it refuses the tick).
/// A grasp farther than this many rod lengths from the clamp is refused (1 m from a 0.2 m suture
/// is not: it is followed to the strain limit).
inline constexpr double kMaxToolReach = 1e3;
/// A tool orientation whose |R^T R - I| (largest entry) exceeds this, or whose determinant is
/// not positive, is not a rotation (scaled, sheared, mirrored or zero) and is refused.
inline constexpr double kRotationTolerance = 1e-6;
/// Mesh rings: at most this many vertices (RuntimeOptions::mesh_ring_vertices).
inline constexpr int kMaxMeshRingVertices = 1024;

struct StepReport {
  StepStatus status = StepStatus::kConverged;
  int iterations = 0;      ///< Newton iterations
  double residual = 0.0;   ///< [N] scaled residual at exit
  double seconds = 0.0;    ///< wall time of the step
  double tool_lag = 0.0;   ///< [m] how far the grasped point is from the tool after the step
  /// [rad] an oriented grasp: the angle between the held and the tool's orientation after the
  /// step (it turns at most max_tool_move radians per tick, like tool_lag).
  double tool_turn_lag = 0.0;
  /// Why a tick is not OK ("" when it is): a fixed text or one formatted into the runtime's own
  /// buffer (no allocation), valid until the next Step().
  const char* message = "";
  bool ok() const { return status == StepStatus::kConverged; }
  /// The tick moved the rod to a new state (converged, or converged at the strain limit).
  bool advanced() const { return ok() || status == StepStatus::kStrainLimit; }
};

class Runtime {
 public:
  /// Builds the rod of `profile` with the tool at options.tool_s and solves its equilibrium
  /// (the tool where the rest shape puts that point, or, for a poke, no force). Throws
  /// std::invalid_argument with the reason for invalid options or a rod that cannot be built,
  /// std::runtime_error when the first equilibrium is not found.
  Runtime(const Profile& profile, const RuntimeOptions& options);
  ~Runtime();
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

  /// Grasp: where the tool holds its point from the next Step() on [m].
  void SetToolPosition(const Vec3& position_world);
  /// Oriented grasp (RuntimeOptions::hold_orientation): the tool's rotation, world from tool,
  /// from the next Step() on. The identity is the orientation at construction: the held edge
  /// and its material frame turn by this rotation about the grasped point.
  void SetToolOrientation(const Eigen::Matrix3d& rotation_world);
  /// The rotation the held edge has now (the identity without an oriented grasp).
  Eigen::Matrix3d ToolOrientation() const;
  /// Poke: the force the tool applies to the tissue from the next Step() on [N].
  void SetToolForce(const Vec3& force_world);
  // The setters take any value; Step() checks those it uses (finite; a grasp's position within
  // kMaxToolReach rod lengths of the clamp, an oriented grasp's rotation within
  // kRotationTolerance, a poke's force within max_strain EA) and refuses the tick with
  // StepStatus::kToolRefused when one is not.

  /// One tick. Never allocates; see the file comment.
  StepReport Step();

  /// Centre-line, column per vertex [m] (the current state).
  const Mat3X& Shape() const;
  /// Force [N] and torque [N m] the rod exerts on the tool. The torque is about the grasped
  /// point, -dPi*/d(tool rotation); zero unless the grasp holds the orientation. A poke is
  /// force-controlled: the force is minus the last good step's applied force, in both modes (in
  /// dynamic mode the rod's elastic push-back equals it only once the rod has settled; until
  /// then the difference accelerates the rod).
  Vec3 ToolForce() const;
  Vec3 ToolTorque() const;
  /// Where the tool is: the grasped point, or the poked point of the centre-line [m].
  Vec3 ToolPosition() const;
  /// Potential energy of the rod at the current state, the tool's work included (a poke's
  /// -f . x(tool_s), in both modes) [J].
  double Energy() const;
  /// Kinetic energy [J] (dynamic mode; 0 in quasi-static mode).
  double KineticEnergy() const;
  /// The tissue's surface: the tube swept along the rod (radius: the section's, else the rod's)
  /// with, for a poke and a section, the dent of the section ring under the last good step's
  /// applied force (a refused or failed force leaves the last good mesh).
  /// Allocates (a new mesh, the ring solved from rest); Mesh(TubeMesh*) is for the loop. Throws
  /// std::invalid_argument when the profile gives no radius.
  TubeMesh Mesh() const;
  /// The same into *mesh, reusing its storage and the runtime's scratch: no heap allocation once
  /// *mesh has the tube's shape (the first call sizes it). The dent's ring is warm-started from
  /// the last call's, and solved to the same tolerance.
  void Mesh(TubeMesh* mesh);

  const RodModel& model() const;
  /// The profile the rod was built from (its rest shape: scene.rod.rest_curvature_s / _profile).
  const Profile& profile() const;
  const RodState& state() const;
  const RuntimeOptions& options() const;
  double time() const;  ///< [s] simulated time (dynamic mode)

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rodfit
