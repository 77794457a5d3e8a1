// The interactive runtime (rodfit/runtime/runtime.h). A quasi-static tick is the equilibrium at
// the tool's new position, solved by the one Newton minimizer (solve/newton_minimizer.h) on a
// tick problem whose every buffer is sized at construction (the statics' continuation and
// summaries build strings and copy states: right for a fit, not for a 1 kHz loop; the minimizer
// itself allocates nothing). Dynamic ticks are one step of the DynamicsStepper, which keeps its
// scratch between steps.
#include "rodfit/runtime/runtime.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "rodfit/model/cross_section.h"
#include "rodfit/solve/banded.h"
#include "rodfit/solve/dynamics.h"
#include "rodfit/solve/linear_solvers.h"
#include "rodfit/solve/newton_minimizer.h"
#include "rodfit/solve/ring.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/rod_problem.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace {

using Clock = std::chrono::steady_clock;

// After a failed tick the next moves a quarter as far (a poke: applies a quarter of the change of
// force), and each converged tick doubles it back up to 1: a failed step is never tried again
// unchanged. The smallest fraction, after ten failures in a row, is a millionth of the move: by
// then a tick that does not move at all converges at once, from the last good equilibrium.
constexpr double kMoveCut = 0.25;
constexpr double kMinMoveScale = 1.0 / (1 << 20);
// A quasi-static solve stopped by its iteration cap or the time budget is resumed by the next
// tick from where it stopped (its target kept), at most this many ticks in a row: a snap of a
// slack thread may need more Newton iterations than one tick has. Then the tick falls back to
// the last good state and a shorter move.
constexpr int kMaxResumedTicks = 4;
// Dynamic mode: after this many failed steps in a row the rod is caught at rest (its rates
// zeroed, BDF2's history dropped): a step that cannot be taken from a fast motion can from rest,
// and the rod's energy only falls by it.
constexpr int kFailuresBeforeRest = 3;
// Dynamic mode: the grasped point's move per tick changes by at most this fraction of the
// largest move (max_tool_move l_min) from one tick to the next. A held point that starts or
// stops at full speed in one step is an impulse the implicit step cannot follow in its Newton
// iterations (measured: the suture at rest, its tip moved 1 mm towards the clamp in one step,
// fails; a quarter of that does not). A steady drag changes its move far less per tick and is
// followed exactly; a tool that jumped is caught up with a ramp up and down.
constexpr double kMoveChange = 0.25;
// The grasp's reach: the tool is pulled to (1 + kReachStrain max_strain) times the arc length from
// each other held point, so that a span pulled taut ends just within max_strain: its own
// curvature and its kink at a clamp add ~1e-4 to the strain of its chord (measured on the suture
// at 10 %), which the strain guard would otherwise cut at every tick at the reach.
constexpr double kReachStrain = 0.99;
// The strain guard: a move that took the rod's largest edge strain past max_strain sets a wall
// across it where the strain (linear in a tick's small move) reaches this fraction of the way
// from where it was to the limit, and a quasi-static tick is taken again to the wall; the wall
// is lifted when the strain is back below this fraction of the limit.
constexpr double kStrainAim = 0.9;
// The grasp's reach (RuntimeOptions::max_strain) is the intersection of a ball per held point;
// the tool is pulled into it by this many rounds of projections onto the balls at most (one
// round for a rod held at one point besides the grasp, the bundled profiles' case).
constexpr int kReachRounds = 8;
// The residual's round-off floor (ResidualFloor: eps EA per edge, at rest) is an estimate: a rod
// pulled taut sums larger forces, and its residual stalls a few times above it (measured: the
// suture held at 10 % strain stalled at 2.8e-9 N against a floor of 2.1e-9 N). A solve stopped
// within this many floors is at round-off.
constexpr double kFloorMargin = 10.0;
// A chord step that cut the residual by less than this is followed by a Newton iteration, which
// renews the kept factor: the next ticks' predictor is made with it.
constexpr double kChordRefresh = 1e-3;
// Moves that differ by less than this fraction of the move count as a steady drag, whose
// predictor correction is extrapolated from the two last ticks'.
constexpr double kSteadyMove = 0.1;
// A tick that took more iterations than this (a slack thread changing its sag, a snap) gives no
// correction to the next: its steps measure more than the move's second-order part.
constexpr int kSmoothTick = 3;

// The tool in the dynamic stepper's pose: a grasp holds its point at the tool's position (every
// other held point at its target); a poke is a dead point force shared by the two vertices
// around the tool's arc length, as the quasi-static poke's (Impl::AddPokeGradient).
class ToolDrive : public Drive {
 public:
  ToolDrive(int held_index, const Vec3* tool) : held_index_(held_index), tool_(tool) {}
  ToolDrive(int point_vertex, double point_weight, const Vec3* force)
      : point_vertex_(point_vertex), point_weight_(point_weight), force_(force) {}
  void PoseAt(const RodModel& model, double t, HeldPose* pose) const override {
    Drive::PoseAt(model, t, pose);
    if (held_index_ >= 0) pose->held[held_index_] = *tool_;
    if (force_) {
      pose->point_force = *force_;
      pose->point_vertex = point_vertex_;
      pose->point_weight = point_weight_;
    }
  }

 private:
  int held_index_ = -1;
  const Vec3* tool_ = nullptr;
  int point_vertex_ = -1;
  double point_weight_ = 0.0;
  const Vec3* force_ = nullptr;  // poke: the tool's force [N], read at each step
};

// The vertices around arc length s and their linear weights (a point force's share).
void Bracket(const RodModel& model, double s, int* j, double* w) {
  const std::vector<double>& arc = model.arc_lengths();
  int k = static_cast<int>(std::upper_bound(arc.begin(), arc.end(), s) - arc.begin()) - 1;
  k = std::max(0, std::min(k, model.num_edges() - 1));
  *j = k;
  *w = (s - arc[k]) / (arc[k + 1] - arc[k]);  // weight of vertex k + 1
}

}  // namespace

const char* ToString(StepStatus status) {
  switch (status) {
    case StepStatus::kConverged: return "converged";
    case StepStatus::kNotConverged: return "not converged (last good state kept)";
    case StepStatus::kTimeBudget: return "time budget exceeded (last good state kept)";
    case StepStatus::kStrainLimit: return "at the strain limit (the tool is out of reach)";
    case StepStatus::kToolRefused: return "tool input refused (last good state kept)";
  }
  return "unknown";
}

struct Runtime::Impl {
  Profile profile;
  RuntimeOptions options;
  std::unique_ptr<RodModel> model;
  int tool_vertex = -1;  // grasp: the held vertex; poke: the lower vertex of the bracket
  double poke_weight = 0.0;
  Vec3 tool = Vec3::Zero();        // grasp: the tool's position, as set [m]
  // This tick's target of the grasped point: the goal, or max_tool_move towards it [m]; between
  // ticks, where the state holds the grasped point (the dynamic drive reads it).
  Vec3 target = Vec3::Zero();
  // The tool pulled into the grasp's reach (RuntimeOptions::max_strain) [m], and whether it was.
  Vec3 goal = Vec3::Zero();
  bool strain_limited = false;
  // The strain guard (a grasp): the largest edge strain of the state; a wall the goal may not
  // pass, set where a move took the strain past max_strain (a point and the move's direction),
  // lifted once the strain is back below kStrainAim of the limit; whether this tick's guard
  // acted, and the strain and edge it saw.
  double strain_now = 0.0;
  bool wall = false;
  Vec3 wall_point = Vec3::Zero(), wall_normal = Vec3::Zero();
  bool strain_guarded = false;
  double strain_seen = 0.0;
  int strain_edge = 0;
  double move_scale = 1.0;         // of max_tool_move: cut after a failed tick, regrown after
  Vec3 tool_force = Vec3::Zero();  // poke: the tool's force, as set [N]
  // Poke: the force of this tick's step, and between ticks the force the state is in balance
  // with (the last good step's): a failed or refused tick restores it [N].
  Vec3 applied_force = Vec3::Zero();
  Vec3 last_good_force = Vec3::Zero();
  double max_poke_force = 0.0;     // [N] max_strain EA: a larger push is refused
  Vec3 reaction = Vec3::Zero();    // last good force on the tool [N]
  // The grasp's reach: each other held point (the clamp first) and the distance the grasped
  // point may have from it, (1 + max_strain) times the rod between them [m].
  struct Reach {
    Vec3 centre = Vec3::Zero();
    double radius = 0.0;
    double s = 0.0;  // the held point's arc length [m]
  };
  std::vector<Reach> reach;
  const Reach* reach_limit = nullptr;  // the ball that limited this tick's goal, if one did
  // Why the last tick is not OK (StepReport::message), formatted here: no allocation.
  char message[320] = "";
  Termination termination = Termination::kConverged;  // the last solve's (a tick's or a step's)
  // Quasi-static: a solve the last tick did not finish (iteration cap or time budget), resumed by
  // the next from where it stopped, with its target and the held orientation.
  RodState pending;
  Vec3 pending_target = Vec3::Zero();
  Vec3 pending_force = Vec3::Zero();
  Eigen::Matrix3d pending_rotation = Eigen::Matrix3d::Identity();
  int resumed_ticks = 0;  // how many ticks in a row resumed it (or ended with it kept)
  int failures = 0;       // failed ticks in a row (not the time budget's)
  double force_tolerance = 0.0;    // [N]
  double floor_tolerance = 0.0;    // [N] the residual's round-off floor
  // Quasi-static scratch, sized once.
  RodState state, last_good, trial, moved;
  RodFrames rows_frames;  // GraspLoads' scratch
  VecX g, g_free, step;
  // The sum of this tick's steps after its prediction, and those of the two last converged ticks
  // (with their grasp's moves): the predictor's second-order correction.
  VecX correction, last_correction, older_correction;
  Vec3 last_move = Vec3::Zero(), older_move = Vec3::Zero();
  int corrections = 0;  // how many of the last ticks' corrections are kept (0..2)
  // The Hessian of the factor's state with the held rows left in (K_fh, the predictor's), and
  // the same with Dirichlet rows (what is factored).
  BandedSymmetric hessian_full, hessian;
  BandedCholesky factor;
  // The factor is unshifted and was made at a state of this converged branch (this tick's or an
  // earlier one's): the predictor and the chord steps may use it; a chord step that does not
  // contract fast enough refactors.
  bool factor_near_state = false;
  // The factor was made at a state of this converged branch, shifted or not: it serves the
  // next ticks' predictor all the same. A shifted factor is made where the Hessian is indefinite
  // (a thread pushed towards its clamp, near buckling) and still predicts the stiff part of the
  // rod's response, the part Newton cannot recover within a tick from the grasped vertex moved
  // alone (measured: the suture's tip pushed 2.5 cm towards the clamp lost 11 ticks of 3000
  // without it, none with it).
  bool factor_on_branch = false;
  // The grasp's reaction at the state of the last residual check (its hold-free rows), and
  // whether that check was at the final state.
  Vec3 checked_force = Vec3::Zero();
  bool reaction_current = false;
  // The tick as a Newton problem, and the minimizer (both sized at construction).
  class TickProblem;
  std::unique_ptr<TickProblem> tick;
  std::unique_ptr<BandedCholeskySolver> solver;
  NewtonMinimizer minimizer;
  // An oriented grasp (RuntimeOptions::hold_orientation) holds the edge that ends at the grasped
  // vertex, from vertex w = tool_vertex - 1 (a pin of the model, so that the retraction keeps it)
  // and that edge's twist angle (a Dirichlet row of the runtime's own): the edge is a rigid
  // body in the tool's hand.
  bool oriented = false;
  int edge_vertex = -1;                          // w
  int held_twist = -1;                           // the held edge's twist dof
  Vec3 edge0 = Vec3::Zero();                     // the held edge at the grasp [m]
  Vec3 d1_0 = Vec3::Zero();                      // its material d1 at the grasp
  Eigen::Matrix3d tool_rotation = Eigen::Matrix3d::Identity();  // requested
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();       // held this tick
  Eigen::Matrix3d rotation_good = Eigen::Matrix3d::Identity();
  Vec3 torque = Vec3::Zero(), checked_torque = Vec3::Zero();
  std::vector<char> held_rows;  // the model's held dofs, and the held edge's twist
  // Mesh(): the tube and the dent's scratch (the ring, warm-started from the last dent's when
  // that one converged).
  struct MeshScratch {
    VertexFrames frames;
    TubeMesh tube;
    std::unique_ptr<RingSolver> ring_solver;
    RingResult ring;
    bool ring_warm = false;
    PropagationWorkspace propagation;
    LocalDeformation local;
  };

  MeshScratch mesh_scratch;
  void BuildMesh(MeshScratch* scratch, TubeMesh* mesh) const;
  // Dynamic.
  std::unique_ptr<ToolDrive> drive;
  std::unique_ptr<DynamicsStepper> stepper;
  DynamicState dynamic, dynamic_good;
  bool dynamic_catch_up = false;  // the last dynamic tick ran out of its budget

  // *out = s with the grasped vertex at p and its two edges following it (an oriented grasp:
  // the held edge at `rotation` too, and the edges either side of it following), reference
  // frames transported from s. False when the transport fails.
  bool MoveGrasp(const RodState& s, const Vec3& p, RodState* out) const {
    const int v = tool_vertex;
    *out = s;
    out->x.col(v) = p;
    if (oriented) {
      const int w = edge_vertex;
      out->x.col(w) = p - rotation * edge0;
      if (w >= 1) out->e.col(w - 1) = out->x.col(w) - out->x.col(w - 1);
    }
    out->e.col(v - 1) = out->x.col(v) - out->x.col(v - 1);
    if (v < model->num_edges()) out->e.col(v) = out->x.col(v + 1) - out->x.col(v);
    if (!UpdateReferenceFrames(*model, s, out)) return false;
    HoldTwist(out);
    return true;
  }
  // The held edge's twist angle that turns its material d1 onto the tool's (its reference frame
  // as `s` has it), the branch nearest its current angle.
  void HoldTwist(RodState* s) const {
    if (!oriented) return;
    const int w = edge_vertex;
    const Vec3 t = s->ref_t.col(w), u = s->ref_u.col(w);
    const Vec3 d1 = rotation * d1_0;
    double theta = std::atan2(d1.dot(t.cross(u)), d1.dot(u));
    theta += 2.0 * M_PI * std::round((s->theta[w] - theta) / (2.0 * M_PI));
    s->theta[w] = theta;
  }
  // Force and torque [N, N m] the rod exerts on the tool at state s, from the gradient g of Pi
  // at s with the held rows left in: minus the constraint forces of the held dofs. The torque
  // is about the grasped point: the held edge's far vertex's force on its arm, and the twist
  // moment about the edge.
  void ToolLoads(const RodState& s, const VecX& gradient, Vec3* force, Vec3* moment) const {
    *force = -gradient.segment<3>(RodModel::VertexDof(tool_vertex));
    moment->setZero();
    if (!oriented) return;
    const int w = edge_vertex;
    const Vec3 f_w = -gradient.segment<3>(RodModel::VertexDof(w));
    *force += f_w;
    *moment = (s.x.col(w) - s.x.col(tool_vertex)).cross(f_w) -
              gradient[held_twist] * s.e.col(w).normalized();
  }
  double PokeWork(const RodState& s) const {
    if (options.tool != ToolKind::kPoke) return 0.0;
    const Vec3 x = (1.0 - poke_weight) * s.x.col(tool_vertex) + poke_weight * s.x.col(tool_vertex + 1);
    return applied_force.dot(x);
  }
  double Energy(const RodState& s) const { return PotentialEnergy(*model, s) - PokeWork(s); }
  // The same for a state whose frames `f` are fresh (as ApplyStep leaves them): no transports.
  double Energy(const RodState& s, const RodFrames& f) const {
    return PotentialEnergyFreshFrames(*model, s, EnergyTerms(), &f) - PokeWork(s);
  }
  // The poke's dead force on the free rows of its two vertices.
  void AddPokeGradient(VecX* gradient) const {
    if (options.tool != ToolKind::kPoke) return;
    const std::vector<char>& held = model->held_dofs();
    for (int k = 0; k < 2; ++k) {
      const int i = tool_vertex + k;
      if (i < 1) continue;  // vertex 0 is the clamp's
      const double w = k == 0 ? 1.0 - poke_weight : poke_weight;
      for (int c = 0; c < 3; ++c) {
        const int dof = RodModel::VertexDof(i) + c;
        if (!held[dof]) (*gradient)[dof] -= w * applied_force[c];
      }
    }
  }
  void GraspLoads(const RodState& s, Vec3* force, Vec3* moment) {
    // -dPi/dx at the held dofs with the hold off: the constraint forces' opposite.
    // Only the rows ToolLoads reads (the grasped vertex, an oriented grasp's held edge): the
    // whole rod's gradient was 7 % of a dynamic tick.
    EnergyTerms terms;
    terms.hold = false;
    AssembleGradientRows(*model, s, terms, oriented ? edge_vertex : tool_vertex, tool_vertex,
                         &g_free, &rows_frames);
    ToolLoads(s, g_free, force, moment);
  }
  void UpdateReaction() {
    const RodState& s = options.mode == RuntimeMode::kDynamic ? dynamic.q : state;
    if (options.tool == ToolKind::kGrasp) {
      GraspLoads(s, &reaction, &torque);
    } else {
      reaction = -applied_force;
      torque.setZero();
    }
  }
  // The tick's inputs checked (finite, in range): false with the message when one is not.
  bool CheckInputs();
  // The goal of a grasp: the tool, pulled into the reach of every other held point.
  void UpdateGoal();
  // This tick's target: the grasped point at `from` moved towards the goal by at most
  // max_tool_move (times the move scale) [m].
  Vec3 LimitedMove(const Vec3& from) const;
  // Dynamic mode: the same, with the move changing by at most kMoveChange from the last tick's
  // (held_move), and slowing down in time to stop at the goal.
  // `goal_move`: the goal's own move since the last tick (at most the largest move).
  Vec3 DynamicMove(const Vec3& from, const Vec3& goal_move) const;
  Vec3 held_move = Vec3::Zero();  // dynamic grasp: the last good tick's move of the grasped point [m]
  Vec3 last_goal = Vec3::Zero();  // grasp: the last tick's goal [m]
  Vec3 goal_move = Vec3::Zero();  // grasp: the goal's move since (at most the largest move) [m]
  // A poke's force for this tick: the tool's, or after failed ticks a part of the change.
  void ApplyForce();
  // The message of a tick that is not OK (StepReport::message).
  void Describe(StepReport* report);
  StepReport StepQuasiStatic(Clock::time_point start);
  // Ends a quasi-static tick that failed: the last good state back, a shorter next move, and the
  // solve kept for the next tick to resume when it stopped short (cap, budget) at a finite state.
  StepReport GiveUp(StepStatus status, StepReport report);
  // The tick in the runtime's mode.
  StepReport Advance(Clock::time_point start) {
    return options.mode == RuntimeMode::kDynamic ? StepDynamic() : StepQuasiStatic(start);
  }
  // The largest edge strain |e_j| / l_j - 1 of a state, and its edge.
  double MaxStrain(const RodState& s, int* edge) const {
    double worst = -1.0;
    for (int j = 0; j < model->num_edges(); ++j) {
      const double strain = s.e.col(j).norm() / model->rest_edge_length(j) - 1.0;
      if (strain > worst) worst = strain, *edge = j;
    }
    return worst;
  }
  const RodState& Current() const {
    return options.mode == RuntimeMode::kDynamic ? dynamic.q : state;
  }
  // A grasp's tick whose move took the rod's strain past max_strain (and higher than it was):
  // a wall across the move stops the grasp from then on; a quasi-static tick is taken again from
  // its start to the wall (and keeps its start if that too overstrains the rod).
  void GuardStrain(Clock::time_point start, StepReport* report);
  // Quasi-static: the state at the tick's start again (the tick's solve discarded).
  void RestoreTickStart();
  // The minimizer from `state` until converged, `max_iterations` or the time budget from
  // `start`. `predicted`: the state is this tick's prediction from the kept factor (within the
  // linear response of the equilibrium), so its first Newton step is taken whole and checked by
  // the residual after it, like a chord step.
  StepStatus Newton(Clock::time_point start, int max_iterations, bool predicted,
                    StepReport* report);
  StepReport StepDynamic();
  // Dynamic mode: the rod at rest where it is (rates zero, BDF2's history dropped).
  void CatchAtRest();
  // StepQuasiStatic's steps: a stopped-short solve resumed; a grasp's move predicted.
  StepReport ResumeTick(Clock::time_point start, StepReport report);
  bool PredictGraspMove(const Vec3& d, const Eigen::AngleAxisd& turn);
  // The constructor's steps once the model and its first equilibrium are set: the tool's
  // vertices and targets, the grasp's reach, the kept factor and the minimizer, the dynamic
  // stepper (sized by a throwaway step), the poke mesh's scratch (sized by a throwaway dent).
  void SetUpTool();
  void SetUpReach();
  void SetUpNewton();
  void SetUpDynamics();
  void SizeMeshScratch();
};

// A quasi-static tick as a Newton problem (solve/newton_minimizer.h): Pi of the rod with its held
// points (the grasp at this tick's target) and the poke's dead force, over the free dofs. Its
// matrix is the kept Hessian: assembled with the held rows left in (hessian_full, the next tick's
// predictor reads its columns), then copied with Dirichlet rows (hessian) for the factor. Each
// residual also reads the grasp's reaction from the rows the hold zeroes.
class Runtime::Impl::TickProblem : public RodNewtonProblem {
 public:
  explicit TickProblem(Impl* impl)
      : RodNewtonProblem(*impl->model, impl->options.step_tolerance, impl->model->length()),
        m_(*impl) {
    free_terms_.hold = false;  // held rows kept to read the grasp's reaction, then cleared
  }
  void Evaluate(bool matrix, VecX* g) override {
    const RodFrames& f = CurrentFrames();
    if (matrix) {
      AssembleHessian(model_, current(), free_terms_, g, &m_.hessian_full, &f);
      m_.hessian = m_.hessian_full;  // same size: a copy, no allocation
      ApplyHeldRows(m_.held_rows, nullptr, &m_.hessian);
    } else {
      AssembleGradient(model_, current(), free_terms_, g, &f);
    }
    if (m_.tool_vertex >= 1 && m_.options.tool == ToolKind::kGrasp)
      m_.ToolLoads(current(), *g, &m_.checked_force, &m_.checked_torque);
    ApplyHeldRows(m_.held_rows, g, nullptr);
    m_.AddPokeGradient(g);
  }
  double Energy() override { return m_.Energy(current(), CurrentFrames()); }
  double TrialEnergy() override { return m_.Energy(trial(), TrialFrames()); }
  void TrialResidual(VecX* g) override {
    AssembleGradient(model_, trial(), free_terms_, g, &TrialFrames());
    ApplyHeldRows(m_.held_rows, g, nullptr);
    m_.AddPokeGradient(g);
  }
  NewtonTolerances Tolerances() override { return {m_.force_tolerance, m_.floor_tolerance}; }
  LinearSolver& Solver() override { return *m_.solver; }
  // An unshifted factor may serve later chord steps and the next ticks' predictor.
  void OnFactor(bool shifted) override {
    m_.factor_near_state = !shifted;
    m_.factor_on_branch = true;
  }

 private:
  Impl& m_;
  EnergyTerms free_terms_;
};

namespace {

// A grasp's start: the tool takes hold of the rod where it lies. The equilibrium without the
// tool, on the vertices of the grasped model (which moves its nearest vertex onto tool_s), is
// also the grasped rod's equilibrium with the tool there, and the loop starts from rest. (Holding
// it where the unloaded rest shape has it would start a sagging thread pulled taut.) Sets the
// grasp (and with hold_orientation the pin of the held edge's far vertex, and its rod) in *held.
RodState GraspStart(const Scene& scene, const RuntimeOptions& options,
                    const StaticsOptions& statics, LoadCase* held, RodSpec* held_rod) {
  held->grasp = Grasp{options.tool_s, scene.cases.front().clamp.position};
  const RodModel probe(scene.rod, scene.material, scene.gravity, *held, scene.springs);
  RodSpec rod = scene.rod;
  rod.vertex_s = probe.arc_lengths();
  LoadCase free_case = scene.cases.front();
  const RodModel free_model(rod, scene.material, scene.gravity, free_case, scene.springs);
  RodState start = free_model.RestState();
  const StaticsSummary free_solve = SolveStatics(free_model, statics, &start);
  if (!free_solve.converged)
    throw std::runtime_error("the rod's equilibrium without the tool was not found: " +
                             free_solve.reason);
  held->grasp->position = start.x.col(probe.grasp_vertex());
  if (options.hold_orientation) {
    // The held edge's far vertex is pinned where the free equilibrium has it, on the same
    // vertices (its arc length is a vertex's already).
    const int w = probe.grasp_vertex() - 1;
    if (w < 1)
      throw std::invalid_argument("hold_orientation: tool_s must lie beyond the second vertex");
    held->pins.push_back(Pin{probe.arc_length(w), start.x.col(w)});
    *held_rod = rod;
  }
  return start;
}

}  // namespace

// The tool's vertex and targets (a grasp's, with hold_orientation its held edge), the rows the
// ticks hold, the poke's bracket.
void Runtime::Impl::SetUpTool() {
  const RodModel& model = *this->model;
  if (options.tool == ToolKind::kGrasp) {
    tool_vertex = model.grasp_vertex();
    tool = model.grasp_position();
    target = tool;
    goal = tool;
    if (options.hold_orientation) {
      oriented = true;
      edge_vertex = tool_vertex - 1;
      held_twist = RodModel::TwistDof(edge_vertex);
      if (model.held_at_vertex(edge_vertex) < 0)
        throw std::invalid_argument("hold_orientation: the held edge's vertex is not held");
    }
  }
  held_rows = model.held_dofs();
  if (oriented) held_rows[held_twist] = 1;
  if (options.tool == ToolKind::kPoke) {
    Bracket(model, options.tool_s, &tool_vertex, &poke_weight);
  }
}

// The grasp's reach: a ball about the clamp and about every other held point (an oriented
// grasp's own edge aside), of (1 + max_strain) times the rod between.
void Runtime::Impl::SetUpReach() {
  const RodModel& model = *this->model;
  const double s_grasp = model.arc_length(tool_vertex);
  const double stretch = 1.0 + kReachStrain * options.max_strain;
  reach.push_back({state.x.col(0), stretch * s_grasp, 0.0});
  for (const HeldVertex& h : model.held()) {
    if (h.kind == HeldVertex::Kind::kGrasp || (oriented && h.vertex == edge_vertex))
      continue;
    reach.push_back(
        {h.target, stretch * std::abs(s_grasp - h.s), h.s});
  }
}

// The kept factor at the first equilibrium and the minimizer's options; every buffer sized.
void Runtime::Impl::SetUpNewton() {
  const RodModel& model = *this->model;
  EnergyTerms free_terms;
  free_terms.hold = false;
  AssembleHessian(model, state, free_terms, &g, &hessian_full);
  hessian = hessian_full;
  ApplyHeldRows(held_rows, &g, &hessian);
  factor_near_state = factor.Factor(hessian, 0.0);
  factor_on_branch = factor_near_state;
  tick = std::make_unique<Impl::TickProblem>(this);
  tick->Presize();
  solver = std::make_unique<BandedCholeskySolver>(&hessian, &factor);
  solver->ReserveScratch();  // the saddle escape's: sized now, a tick allocates nothing
  NewtonOptions& newton = minimizer.options();
  newton.chords = ChordPolicy::kWhileContracting;
  newton.chord_refresh = kChordRefresh;
  newton.converge_after_small_step = true;
  // A thread pulled taut far off its clamp's axis, or a bowel pulled back through its clamp,
  // sits at an unstable equilibrium that the shifted steps only creep along: it is left along
  // its negative curvature (allocation-free once the solver's scratch is sized).
  newton.saddles = Saddles::kEscape;
  // A grasp's converged tick factors a Hessian assembled at its solution: the next tick's
  // predictor reads that Hessian's columns and solves with its factor, which must be of one
  // matrix. (A poke predicts nothing: its chord steps do as well on the older factor.)
  newton.factor_at_solution =
      options.tool == ToolKind::kGrasp ? FactorAtSolution::kWhenAssembled : FactorAtSolution::kNever;
  minimizer.Reserve(model.num_free_dofs());
  step = g;
  g_free = g;
  correction = VecX::Zero(g.size());
  last_correction = correction;
  older_correction = correction;
}

// Dynamic mode: the tool's drive and the stepper, every buffer sized by a throwaway step.
void Runtime::Impl::SetUpDynamics() {
  const RodModel& model = *this->model;
  int held_index = -1;
  for (size_t k = 0; k < model.held().size(); ++k)
    if (model.held()[k].kind == HeldVertex::Kind::kGrasp) held_index = static_cast<int>(k);
  drive = options.tool == ToolKind::kPoke
              ? std::make_unique<ToolDrive>(tool_vertex, poke_weight, &applied_force)
              : std::make_unique<ToolDrive>(held_index, &target);
  DynamicsOptions dyn;
  dyn.time_step = options.time_step;
  dyn.integrator = Integrator::kBdf2;
  dyn.max_halvings = 0;  // a tick's step is not halved (halving copies states: it allocates)
  dyn.failure_reasons = false;  // a failed tick says so by its status, without the heap
  // A tick ends on its last step's contraction (one gradient fewer), and Newton starts from
  // a steady drag's extrapolated corrections (0.3 solves fewer): together 10 % of a dynamic
  // drag tick's instructions.
  dyn.converge_on_rate = true;
  dyn.extrapolate_corrections = true;
  // The throwaway first step below may take the stepper's default iterations; the ticks then
  // keep options' limits.
  stepper = std::make_unique<DynamicsStepper>(model, dyn);
  dynamic = stepper->AtRest(state);
  // A throwaway step with the tool nudged (a grasp moved by 1e-6 L, a poke pushing with 1e-6
  // of the load scale) sizes every buffer of the stepper (a step at rest converges before it
  // factors anything); the rod is then put back at rest.
  dynamic_good = dynamic;
  const Vec3 home = target;
  if (options.tool == ToolKind::kPoke)
    applied_force = Vec3::Constant(1e-6 * model.force_scale());
  else
    target += Vec3::Constant(1e-6 * model.length());
  const DynamicsStepSummary warm = stepper->Step(*drive, &dynamic);
  target = home;
  applied_force.setZero();
  if (!warm.ok) throw std::runtime_error("the first dynamic step failed (reduce time_step)");
  // Back at rest, the history's buffers kept at their size (BDF2 starts with a backward
  // Euler step without history).
  dynamic.q = dynamic_good.q;
  dynamic.t = dynamic_good.t;
  CatchAtRest();
  dynamic_good = dynamic;
  // The ticks' limits (not the throwaway step's: it must not fail on a slow start).
  stepper->SetNewtonLimits(options.dynamic_newton_iterations, options.time_budget);
}

// A throwaway dent, a gentle push of 1e-3 kb / R^2 along the section's d1, sizes the mesh's
// scratch (the ring's solver and result, the propagation's lists), so that Mesh(TubeMesh*)
// allocates nothing later.
void Runtime::Impl::SizeMeshScratch() {
  const Scene& scene = profile.scene;
  const double R = scene.section->radius;
  const Vec3 d1 = SectionAt(*model, state, options.tool_s).d1;
  applied_force = 1e-3 * scene.material.ring_bend_stiffness / (R * R) * d1;
  TubeMesh throwaway;
  BuildMesh(&mesh_scratch, &throwaway);
  applied_force.setZero();
  mesh_scratch.ring_warm = false;
}

Runtime::Runtime(const Profile& profile, const RuntimeOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.profile = profile;
  m.options = options;
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("runtime options: " + why);
  const Scene& scene = profile.scene;
  if (scene.cases.empty()) throw std::invalid_argument("the profile has no held boundary");
  if (!(options.tool_s <= scene.rod.length))
    throw std::invalid_argument("tool_s must not exceed the rod's length");
  LoadCase held = scene.cases.front();
  RodSpec held_rod = scene.rod;
  StaticsOptions statics;
  statics.gradient_tolerance = options.gradient_tolerance;
  RodState start;
  if (options.tool == ToolKind::kGrasp)
    start = GraspStart(scene, options, statics, &held, &held_rod);
  m.model = std::make_unique<RodModel>(held_rod, scene.material, scene.gravity, held,
                                       scene.springs);
  const RodModel& model = *m.model;
  if (options.tool == ToolKind::kPoke) start = model.RestState();
  m.SetUpTool();
  m.force_tolerance = options.gradient_tolerance * model.force_scale();
  // The stretch forces' round-off, ~eps EA per edge, in the residual's measure.
  m.floor_tolerance = ResidualFloor(model, GradientNormWeights(model));

  // The first equilibrium, by the statics solver (allocation is fine here).
  m.state = start;
  const StaticsSummary first = SolveStatics(model, statics, &m.state);
  if (!first.converged)
    throw std::runtime_error("the rod's first equilibrium was not found: " + first.reason);
  // Size every buffer now: the assembly resizes only when a size changes.
  if (m.oriented) {
    m.edge0 = m.state.e.col(m.edge_vertex);
    m.d1_0 = model.MaterialFrame(m.state, m.edge_vertex).d1;
  }
  m.last_good = m.state;
  m.trial = m.state;
  m.moved = m.state;
  m.pending = m.state;
  m.strain_now = m.MaxStrain(m.state, &m.strain_edge);
  if (options.tool == ToolKind::kGrasp) m.SetUpReach();
  m.max_poke_force = options.max_strain * model.material().stretch_stiffness;
  m.SetUpNewton();
  if (options.mode == RuntimeMode::kDynamic) m.SetUpDynamics();
  if (options.tool == ToolKind::kPoke && scene.section &&
      RingStiffness{scene.material.ring_bend_stiffness, scene.material.ring_stretch_stiffness}
          .Check(nullptr))
    m.SizeMeshScratch();
  m.UpdateReaction();
}

Runtime::~Runtime() = default;

void Runtime::SetToolPosition(const Vec3& position_world) { impl_->tool = position_world; }
void Runtime::SetToolForce(const Vec3& force_world) { impl_->tool_force = force_world; }

bool Runtime::Impl::CheckInputs() {
  static const char* const kAxis[3] = {"x", "y", "z"};
  if (options.tool == ToolKind::kGrasp) {
    // Component by component, so that the message names the value (and no norm overflows).
    const double reach_m = kMaxToolReach * model->length();
    const Vec3& clamp = reach.front().centre;
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(tool[c])) {
        std::snprintf(message, sizeof(message), "tool position %s = %g is not finite: refused, last good state kept", kAxis[c],
                      tool[c]);
        return false;
      }
      if (std::abs(tool[c] - clamp[c]) > reach_m) {
        std::snprintf(message, sizeof(message),
                      "tool position %s = %g m is out of range (more than %g rod lengths, %g m, "
                      "from the clamp): refused, last good state kept",
                      kAxis[c], tool[c], kMaxToolReach, reach_m);
        return false;
      }
    }
  }
  if (oriented) {
    for (int k = 0; k < 9; ++k) {
      if (!std::isfinite(tool_rotation(k / 3, k % 3))) {
        std::snprintf(message, sizeof(message),
                      "tool orientation R[%d][%d] = %g is not finite: refused, last good state "
                      "kept",
                      k / 3, k % 3,
                      tool_rotation(k / 3, k % 3));
        return false;
      }
    }
    const double det = tool_rotation.determinant();
    const double off =
        (tool_rotation.transpose() * tool_rotation - Eigen::Matrix3d::Identity())
            .cwiseAbs()
            .maxCoeff();
    if (!(det > 0.0) || off > kRotationTolerance) {
      std::snprintf(message, sizeof(message),
                    "tool orientation is not a rotation: det R = %g (%s), largest |R^T R - I| "
                    "entry %g (at most %g): refused, last good state kept",
                    det,
                    det == 0.0  ? "singular"
                    : det < 0.0 ? "mirrored"
                                : "scaled or sheared",
                    off, kRotationTolerance);
      return false;
    }
  }
  if (options.tool == ToolKind::kPoke) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(tool_force[c])) {
        std::snprintf(message, sizeof(message), "poke force %s = %g is not finite: refused, last good state kept", kAxis[c],
                      tool_force[c]);
        return false;
      }
    }
    const double f = tool_force.stableNorm();  // 1e308 stays 1e308, not inf
    if (f > max_poke_force) {
      std::snprintf(message, sizeof(message),
                    "poke force |f| = %g N is out of range (at most max_strain EA = %g N): "
                    "refused, last good state kept",
                    f,
                    max_poke_force);
      return false;
    }
  }
  return true;
}

void Runtime::Impl::UpdateGoal() {
  last_goal = goal;
  goal = tool;
  strain_limited = false;
  reach_limit = nullptr;
  for (int round = 0; round < kReachRounds; ++round) {
    bool moved = false;
    for (const Reach& r : reach) {
      const Vec3 d = goal - r.centre;
      const double distance = d.norm();
      if (distance > r.radius) {
        goal = r.centre + (r.radius / distance) * d;
        moved = true;
        strain_limited = true;
        reach_limit = &r;
      }
    }
    if (!moved) break;
  }
  if (wall) {
    // Not past the strain guard's wall: the goal's part beyond it taken off.
    const double beyond = (goal - wall_point).dot(wall_normal);
    if (beyond > 0.0) {
      goal -= beyond * wall_normal;
      strain_limited = true;
      reach_limit = nullptr;  // the wall, not a reach, limits it
    }
  }
  goal_move = goal - last_goal;
  const double largest = options.max_tool_move * model->min_rest_edge_length();
  const double goal_move_norm = goal_move.norm();
  if (goal_move_norm > largest) goal_move *= largest / goal_move_norm;
}

Vec3 Runtime::Impl::DynamicMove(const Vec3& from, const Vec3& goal_move) const {
  const double largest = options.max_tool_move * model->min_rest_edge_length();
  const double v_max = largest * move_scale;  // [m per tick]
  const double a = kMoveChange * v_max;       // [m per tick^2]
  const Vec3 to_goal = goal - from;
  const double distance = to_goal.norm();
  // Onto the goal when that move is within this tick's, changes the last move by at most a, and
  // leaves a move within a of the goal's own for the next tick: a steady drag is followed
  // exactly, and a catch-up ends without a jolt.
  if (distance <= v_max && (to_goal - held_move).norm() <= a && (to_goal - goal_move).norm() <= a)
    return goal;
  // Catching up, in the frame that moves with the goal: towards it at the speed from which it
  // can still stop there (moves falling by a per tick sum to s^2 / 2a + s / 2 before they
  // stop), the move changed by at most a.
  const double speed =
      std::min({v_max, distance, -0.5 * a + std::sqrt(0.25 * a * a + 2.0 * a * distance)});
  Vec3 wanted = goal_move;
  if (distance > 0.0) wanted += (speed / distance) * to_goal;
  const double wanted_norm = wanted.norm();
  if (wanted_norm > v_max) wanted *= v_max / wanted_norm;
  Vec3 change = wanted - held_move;
  const double change_norm = change.norm();
  if (change_norm > a) change *= a / change_norm;
  // After a failed tick the move is cut to this tick's largest at once: the failed step is not
  // taken again.
  Vec3 move = held_move + change;
  const double move_norm = move.norm();
  if (move_norm > v_max) move *= v_max / move_norm;
  return from + move;
}

Vec3 Runtime::Impl::LimitedMove(const Vec3& from) const {
  Vec3 d = goal - from;
  const double d_norm = d.norm();
  const double max_move = options.max_tool_move * move_scale * model->min_rest_edge_length();
  if (d_norm > max_move) d *= max_move / d_norm;
  return from + d;
}

void Runtime::Impl::ApplyForce() {
  if (options.tool != ToolKind::kPoke) return;
  // The whole change at once while ticks converge (exactly the tool's force), a part of it
  // after failed ticks.
  applied_force = move_scale >= 1.0 ? tool_force
                                    : Vec3(applied_force + move_scale * (tool_force - applied_force));
}

void Runtime::Impl::Describe(StepReport* report) {
  const double lag_mm = 1e3 * report->tool_lag;
  switch (report->status) {
    case StepStatus::kConverged:
    case StepStatus::kToolRefused:  // CheckInputs wrote it
      break;
    case StepStatus::kStrainLimit:
      if (strain_guarded) {
        std::snprintf(message, sizeof(message),
                      "strain limit: this tick's move took the rod's strain to %.3g at edge %d "
                      "(max_strain %g): the grasp stops short of that move; the tool %.4g mm "
                      "from the grasped point",
                      strain_seen, strain_edge, options.max_strain, lag_mm);
      } else if (reach_limit) {
        std::snprintf(message, sizeof(message),
                      "strain limit: the tool is %.4g mm from the grasped point, out of the rod's "
                      "reach at max_strain = %g (%.4g m from the held point at s = %g m)",
                      lag_mm, options.max_strain, reach_limit->radius, reach_limit->s);
      } else {
        std::snprintf(message, sizeof(message),
                      "strain limit: the grasp is held where a move took the rod's strain past "
                      "max_strain = %g; the tool %.4g mm from the grasped point",
                      options.max_strain, lag_mm);
      }
      break;
    case StepStatus::kNotConverged:
    case StepStatus::kTimeBudget: {
      const bool resume = options.mode == RuntimeMode::kQuasiStatic && resumed_ticks > 0;
      const char* why = "";
      if (report->status == StepStatus::kTimeBudget) {
        why = TerminationMessage(Termination::kTimeBudget);
      } else {
        // The minimizer's termination (a quasi-static tick's, or the dynamic step's).
        why = TerminationMessage(termination);
      }
      char lag[64];
      if (options.tool == ToolKind::kGrasp)
        std::snprintf(lag, sizeof(lag), "the tool %.4g mm from the grasped point", lag_mm);
      else
        std::snprintf(lag, sizeof(lag), "the push applied %.4g N short of the tool's",
                      (tool_force - applied_force).norm());
      const char* next = resume ? "the next tick resumes the solve"
                         : report->status == StepStatus::kTimeBudget &&
                                 options.mode == RuntimeMode::kDynamic
                             ? "the next tick catches up without the budget"
                         : options.tool == ToolKind::kPoke
                             ? "the next tick applies a quarter of the change of force"
                             : "the next tick moves a quarter as far";
      std::snprintf(message, sizeof(message),
                    "%s step: %s after %d Newton iterations (residual %.3g N); last good state "
                    "kept, %s; %s",
                    options.mode == RuntimeMode::kDynamic ? "dynamic" : "quasi-static", why,
                    report->iterations, report->residual, lag, next);
      break;
    }
  }
  report->message = message;
}

StepReport Runtime::Step() {
  const Clock::time_point start = Clock::now();
  Impl& m = *impl_;
  StepReport report;
  m.strain_guarded = false;
  if (!m.CheckInputs()) {
    report.status = StepStatus::kToolRefused;
  } else {
    if (m.options.tool == ToolKind::kGrasp) m.UpdateGoal();
    report = m.Advance(start);
    if (m.options.tool == ToolKind::kGrasp && report.ok()) m.GuardStrain(start, &report);
  }
  if (report.ok()) {
    // A quasi-static tick that ended on its residual check has the grasp's reaction from that
    // check's gradient; otherwise it is evaluated at the state.
    if (m.options.mode == RuntimeMode::kQuasiStatic && m.reaction_current &&
        m.options.tool == ToolKind::kGrasp) {
      m.reaction = m.checked_force;
      m.torque = m.checked_torque;
    } else {
      m.UpdateReaction();
    }
    if (m.strain_limited || m.strain_guarded) report.status = StepStatus::kStrainLimit;
  }
  if (m.options.tool == ToolKind::kGrasp)
    report.tool_lag = m.tool.allFinite() ? (m.tool - ToolPosition()).norm()
                                         : std::numeric_limits<double>::infinity();
  if (m.oriented)
    report.tool_turn_lag =
        !m.tool_rotation.allFinite() ? std::numeric_limits<double>::infinity()
        : m.tool_rotation == m.rotation
            ? 0.0
            : Eigen::AngleAxisd(m.tool_rotation * m.rotation.transpose()).angle();
  if (!report.ok()) m.Describe(&report);
  report.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return report;
}

void Runtime::Impl::RestoreTickStart() {
  state = last_good;  // same sizes: no allocation
  rotation = rotation_good;
  applied_force = last_good_force;
  target = state.x.col(tool_vertex);
  factor_near_state = false;  // the factor may belong to the discarded state
  factor_on_branch = false;
  corrections = 0;
  resumed_ticks = 0;
  reaction_current = false;
}

void Runtime::Impl::GuardStrain(Clock::time_point start, StepReport* report) {
  int edge = 0;
  const double strain = MaxStrain(Current(), &edge);
  const Vec3 from =
      (options.mode == RuntimeMode::kDynamic ? dynamic_good.q : last_good).x.col(tool_vertex);
  const Vec3 move = target - from;
  if (wall && strain < kStrainAim * options.max_strain) wall = false;
  if (!(strain > options.max_strain && strain > strain_now) || move.isZero(0.0)) {
    strain_now = strain;
    return;
  }
  // This tick's move took the strain past the limit: the strain being linear in a tick's small
  // move, the wall goes where it reaches kStrainAim of the way from where it was to the limit,
  // across the move.
  strain_guarded = true;
  strain_seen = strain;
  strain_edge = edge;
  const double alpha = std::min(
      1.0, std::max(0.0, kStrainAim * (options.max_strain - strain_now) / (strain - strain_now)));
  wall = true;
  wall_normal = move.normalized();
  wall_point = from + alpha * move;
  if (options.mode == RuntimeMode::kDynamic) {
    // A dynamic step is kept: its time has passed, and its overshoot is partly the rod's own
    // motion, which a shorter move would not undo. The next ticks stop the grasp at the wall.
    strain_now = strain;
    return;
  }
  // Quasi-static: the tick again from its start, to the wall; if that too overstrains the rod,
  // the tick keeps its start, the last good equilibrium, within the limit.
  const int iterations = report->iterations;
  RestoreTickStart();
  UpdateGoal();
  *report = Advance(start);
  report->iterations += iterations;
  if (!report->ok()) return;
  const double again = MaxStrain(Current(), &edge);
  if (again > options.max_strain && again > strain_now) {
    RestoreTickStart();
    wall_point = from;
    return;
  }
  strain_now = again;
}

StepReport Runtime::Impl::GiveUp(StepStatus status, StepReport report) {
  const bool resumable = (termination == Termination::kIterationCap ||
                          termination == Termination::kTimeBudget) &&
                         resumed_ticks < kMaxResumedTicks && state.x.allFinite();
  if (resumable) {
    std::swap(pending, state);  // the solve's iterate, for the next tick (a swap: no copy)
    pending_target = target;
    pending_rotation = rotation;
    pending_force = applied_force;
    ++resumed_ticks;
  } else {
    resumed_ticks = 0;
  }
  state = last_good;  // same sizes: no allocation
  rotation = rotation_good;
  applied_force = last_good_force;
  target = state.x.col(std::max(tool_vertex, 0));
  // The next fresh tick tries a smaller move: a tick lost to the budget leaves the tool further
  // ahead, and trying the whole way again would lose the next one too.
  move_scale = std::max(move_scale * kMoveCut, kMinMoveScale);
  factor_near_state = false;  // the factor may belong to a state far from last_good
  factor_on_branch = false;
  corrections = 0;
  report.status = status;
  return report;
}

// Resumes the solve the last tick stopped short (its iteration cap or the budget): on from where
// it stopped, towards its target, instead of throwing its iterations away. Its merit only fell
// on the way, so the solve goes on as if it had not been cut.
StepReport Runtime::Impl::ResumeTick(Clock::time_point start, StepReport report) {
  std::swap(state, pending);
  target = pending_target;
  rotation = pending_rotation;
  applied_force = pending_force;
  const StepStatus status = Newton(start, options.max_iterations, false, &report);
  if (status != StepStatus::kConverged) return GiveUp(status, report);
  resumed_ticks = 0;
  corrections = 0;
  move_scale = std::min(1.0, 2.0 * move_scale);
  report.status = StepStatus::kConverged;
  return report;
}

// The rod's answer to the grasp's move d (and an oriented grasp's turn) predicted from the
// factor kept at the last equilibrium: x_free += -K_ff^-1 K_fh d, the linear response with the
// held dofs as a Dirichlet boundary, plus the last ticks' second-order correction; taken into
// state through one retraction (true) when it keeps every turn small and the held edge exact.
bool Runtime::Impl::PredictGraspMove(const Vec3& d, const Eigen::AngleAxisd& turn) {
  const RodModel& m = *model;
  const int v = tool_vertex;
  const double d_norm = d.norm();
  // K_fh d from the kept Hessian's columns of the grasped vertex (held rows left in), the
  // Hessian the kept factor was made from: the band couples them to 2 blocks either side.
  // Held moves: the grasped vertex's d; an oriented grasp's far vertex and its twist (to
  // first order, the turn about the edge).
  step.setZero();
  const int p = hessian_full.bandwidth();
  const int rows = static_cast<int>(step.size());
  auto add_column = [&](int c, double move) {
    for (int i = std::max(0, c - p); i <= std::min(rows - 1, c + p); ++i)
      step[i] -= hessian_full.Get(i, c) * move;
  };
  Vec3 d_w = Vec3::Zero();
  double d_twist = 0.0;
  if (oriented) {
    d_w = target - rotation * edge0 - state.x.col(edge_vertex);
    d_twist = turn.angle() * turn.axis().dot(state.e.col(edge_vertex).normalized());
    for (int c = 0; c < 3; ++c) add_column(RodModel::VertexDof(edge_vertex) + c, d_w[c]);
    add_column(held_twist, d_twist);
  }
  for (int c = 0; c < 3; ++c) add_column(RodModel::VertexDof(v) + c, d[c]);
  ApplyHeldRows(held_rows, &step, nullptr);
  factor.SolveInPlace(step);
  if (corrections >= 1 && turn.angle() == 0.0) {
    // The linear response misses the move's second-order part, which along a steady drag
    // changes little from one tick to the next: the last ticks measured it (the sum of
    // their steps after the prediction), scaled here as a quadratic in the move along the
    // last one, and extrapolated from the two last ticks when the moves are steady. This
    // tick's correction counts from the linear prediction, like theirs.
    const double s = d.dot(last_move) / last_move.squaredNorm();
    correction = (s * s) * last_correction;
    if (corrections >= 2 && (d - last_move).norm() <= kSteadyMove * d_norm &&
        (last_move - older_move).norm() <= kSteadyMove * d_norm)
      correction += (s * s) * (last_correction - older_correction);
    step += correction;
  }
  // The whole predicted motion, the grasp's own move included, goes through one edge-wise
  // retraction from the last equilibrium, which changes every edge's length by its linear
  // part only. (Moving the free vertices first and then the grasped vertex would pin it at
  // its old place during the retraction, whose closure pulls the rod before it back by d,
  // and then stretch its edge by the whole move: against a stiff EA a force of EA d / l that
  // Newton must first undo.) ApplyStep keeps held vertices where its input state has them
  // and reads no other vertex position but x_0, so its input is the last equilibrium with
  // the grasped vertex already at the target.
  step.segment<3>(RodModel::VertexDof(v)) = d;
  moved = state;  // same sizes: no allocation
  moved.x.col(v) = target;
  if (oriented) {
    step.segment<3>(RodModel::VertexDof(edge_vertex)) = d_w;
    step[held_twist] = d_twist;
    moved.x.col(edge_vertex) += d_w;
  }
  if (MaxTurnAndStrainChange(m, state, step).turn <= kMaxTurnPerStep &&
      ApplyStep(m, moved, step, 1.0, &trial) && trial.x.allFinite()) {
    bool held_exactly = true;
    if (oriented) {
      // The held edge exactly as the tool holds it (the retraction gave its length to first
      // order), its twist from the tool's d1.
      trial.e.col(edge_vertex) = trial.x.col(v) - trial.x.col(edge_vertex);
      held_exactly = UpdateReferenceFrames(m, state, &trial);
      HoldTwist(&trial);
    }
    if (held_exactly) {
      std::swap(state, trial);
      return true;
    }
  }
  return false;
}

StepReport Runtime::Impl::StepQuasiStatic(Clock::time_point start) {
  StepReport report;
  last_good = state;
  rotation_good = rotation;
  last_good_force = applied_force;
  reaction_current = false;
  correction.setZero();
  // A solve the last tick stopped short is resumed while its target still leads towards the tool
  // (the tool may have moved back since: then a fresh tick, a shorter move from the last good
  // state, goes where it is now).
  if (resumed_ticks > 0) {
    const bool towards =
        options.tool == ToolKind::kGrasp
            ? (goal - pending_target).norm() < (goal - state.x.col(tool_vertex)).norm()
            : (tool_force - pending_force).norm() < (tool_force - applied_force).norm();
    if (!towards) resumed_ticks = 0;
  }
  if (resumed_ticks > 0) return ResumeTick(start, report);
  ApplyForce();
  bool predicted_start = false;
  Vec3 move = Vec3::Zero();  // the grasp's move this tick [m]
  bool turned = false;       // an oriented grasp turned this tick
  if (options.tool == ToolKind::kGrasp) {
    // Predict the rod's answer to the tool's move d from the factor kept at the last
    // equilibrium: x_free += -K_ff^-1 K_fh d, the linear response with the held dofs as a
    // Dirichlet boundary. Moving the grasped vertex alone would compress or stretch its two
    // edges by the whole move: for a thread, EA / l times it is a force many orders above the
    // loads, and Newton would start far from the solution on an indefinite Hessian.
    const int v = tool_vertex;
    // An oriented grasp turns the held edge towards the tool's orientation by at most
    // max_tool_move radians per tick (its far vertex then moves at most that fraction of the
    // edge), like the grasped point.
    Eigen::AngleAxisd turn(Eigen::Matrix3d::Identity());
    if (oriented) {
      turn = Eigen::AngleAxisd(tool_rotation * rotation.transpose());
      if (turn.angle() <= options.max_tool_move * move_scale) {
        rotation = tool_rotation;  // exactly the tool's, not a product rounded
      } else {
        turn.angle() = options.max_tool_move * move_scale;
        rotation = turn.toRotationMatrix() * rotation;
      }
    }
    target = LimitedMove(state.x.col(v));
    const Vec3 d = target - state.x.col(v);
    const double d_norm = d.norm();
    move = d;
    turned = turn.angle() > 0.0;
    const bool predicted = factor_on_branch && factor.valid() &&
                           (d_norm > 0.0 || turn.angle() > 0.0) && PredictGraspMove(d, turn);
    predicted_start = predicted;
    if (!predicted) {
      // No usable factor: the grasped vertex alone moves, Newton brings the rest along.
      if (!MoveGrasp(last_good, target, &trial)) {
        termination = Termination::kRetractionFailed;
        return GiveUp(StepStatus::kNotConverged, report);
      }
      state = trial;
    }
  }
  StepStatus status = Newton(start, options.max_iterations, predicted_start, &report);
  bool retried = false;
  if (status == StepStatus::kNotConverged && predicted_start &&
      report.iterations < options.max_iterations) {
    retried = true;
    // The prediction led Newton astray (a move too large for the linear response): again from
    // the grasped vertex moved alone, with the iterations left.
    if (MoveGrasp(last_good, target, &trial)) {
      std::swap(state, trial);
      status = Newton(start, options.max_iterations - report.iterations, false, &report);
    }
  }
  if (status != StepStatus::kConverged) return GiveUp(status, report);
  if (predicted_start && !retried && !turned && report.iterations <= kSmoothTick) {
    // This tick's correction becomes the last, the last the older (swaps: no copies).
    std::swap(older_correction, last_correction);
    std::swap(last_correction, correction);
    older_move = last_move;
    last_move = move;
    corrections = std::min(2, corrections + 1);
  } else {
    corrections = 0;
  }
  move_scale = std::min(1.0, 2.0 * move_scale);
  report.status = StepStatus::kConverged;
  return report;
}

StepStatus Runtime::Impl::Newton(Clock::time_point start, int max_iterations, bool predicted,
                                 StepReport* report) {
  // Chord steps reuse the kept factor: a tick moves the tool by a fraction of an edge, so the
  // Hessian of the last tick's solve still contracts the residual by orders of magnitude per
  // step, and a step then costs a gradient and a back-substitution instead of an assembly of
  // the Hessian and its factorisation. Convergence is decided by the same residual test as a
  // Newton iteration's, so the answer is to the same tolerance.
  // A tick that starts from a prediction starts with a Newton iteration instead: the Hessian at
  // the prediction converges it in one step (the kept factor, a tick old, only gains ~300x per
  // step there: a stiff edge near the tool turns by ~l/20 per tick), and its factor, made at a
  // state within ~1e-6 N of the equilibrium, serves the next tick's prediction; that first step
  // is taken whole and checked by the residual after it, which spares the line search's two
  // energies.
  NewtonOptions& o = minimizer.options();
  o.max_iterations = max_iterations;
  o.time_budget = 0.0;
  if (options.time_budget > 0.0) {
    const double used = std::chrono::duration<double>(Clock::now() - start).count();
    o.time_budget = std::max(options.time_budget - used, 1e-12);
  }
  NewtonStart begin;
  begin.factor_nearby = factor_near_state && factor.valid() && !predicted;
  begin.verify_first_step = predicted;
  std::swap(state, tick->current());  // the tick's iterate (swaps: no copies)
  tick->CurrentChanged();
  tick->set_track_steps(&correction);
  const NewtonSummary r = minimizer.Minimize(tick.get(), begin);
  std::swap(state, tick->current());
  report->iterations += r.iterations;
  report->residual = r.residual_norm;
  reaction_current = r.residual_at_solution;
  termination = r.termination;
  if (!state.x.allFinite()) {
    termination = Termination::kNonFinite;
    return StepStatus::kNotConverged;
  }
  if (r.converged()) return StepStatus::kConverged;
  // A solve stopped (by its cap, the budget or a line search that found nothing lower) at a
  // state whose residual, evaluated there, is within the tolerance or at the round-off floor is
  // the solution as exactly as doubles make it: the balance of forces the tick renders is then
  // exact to that floor. A soft mode (a slack thread near buckling) can keep Newton's steps
  // large there, which the minimizer's step tests need; a tick does not roll such a state back
  // (measured: the suture's tip pushed 2.5 cm towards the clamp stalled at residuals of
  // 7e-12 N, a floor of 2e-9 N and a tolerance of 4e-13 N, every tick).
  if (r.residual_at_solution &&
      r.residual_norm <= std::max(force_tolerance, kFloorMargin * floor_tolerance)) {
    termination = Termination::kRoundOff;
    return StepStatus::kConverged;
  }
  return r.termination == Termination::kTimeBudget ? StepStatus::kTimeBudget
                                                   : StepStatus::kNotConverged;
}

StepReport Runtime::Impl::StepDynamic() {
  StepReport report;
  dynamic_good = dynamic;  // same sizes: no allocation
  last_good_force = applied_force;
  ApplyForce();
  // The grasp's drive holds the grasped vertex at this tick's target: at most max_tool_move
  // towards the goal, as in quasi-static mode (a held point jumping centimetres in one step
  // would need forces of its mass times the jump over dt^2, which no Newton of a step follows).
  if (options.tool == ToolKind::kGrasp) target = DynamicMove(dynamic.q.x.col(tool_vertex), goal_move);
  // A tick lost to the budget leaves the rod a step behind the tool, whose next move is then
  // the larger: under the same budget that tick would likely be lost too, and so on (measured:
  // 768 of 1000 ticks of the suture's loop after one preempted tick). The tick after a lost one
  // therefore has no budget, only the iteration cap, and catches up.
  stepper->SetNewtonLimits(options.dynamic_newton_iterations,
                           dynamic_catch_up ? 0.0 : options.time_budget);
  const DynamicsStepSummary s = stepper->Step(*drive, &dynamic);
  report.iterations = s.newton_iterations;
  report.residual = s.residual;
  termination = s.termination;
  if (!s.ok || !dynamic.q.x.allFinite() || !dynamic.v.allFinite()) {
    dynamic = dynamic_good;
    applied_force = last_good_force;
    if (options.tool == ToolKind::kGrasp) target = dynamic.q.x.col(tool_vertex);
    dynamic_catch_up = s.out_of_time;
    if (!s.out_of_time) {
      // The step the integrator could not take is not tried again: the next moves a quarter
      // as far (a poke: applies a quarter of the change of force); after a few failures in a
      // row the rod is caught at rest, from which a short move is a gentle step.
      move_scale = std::max(move_scale * kMoveCut, kMinMoveScale);
      if (++failures >= kFailuresBeforeRest) {
        CatchAtRest();
        held_move.setZero();
        failures = 0;
      }
    }
    report.status = s.out_of_time ? StepStatus::kTimeBudget : StepStatus::kNotConverged;
    return report;
  }
  failures = 0;
  dynamic_catch_up = false;
  move_scale = std::min(1.0, 2.0 * move_scale);
  if (options.tool == ToolKind::kGrasp) held_move = target - dynamic_good.q.x.col(tool_vertex);
  report.status = StepStatus::kConverged;
  return report;
}

void Runtime::Impl::CatchAtRest() {
  // Every buffer at the rates' size (the history's too, for the steps to come): after the
  // constructor sizes them, no allocation.
  const Eigen::Index n = dynamic.v.size();
  dynamic.v.setZero(n);
  dynamic.has_history = false;
  dynamic.last_step.setZero(n);
  dynamic.last_v.setZero(n);
  dynamic.has_older = false;
  dynamic.older_v.setZero(n);
  dynamic.num_corrections = 0;
  dynamic.last_correction.setZero(n);
  dynamic.older_correction.setZero(n);
}

const Mat3X& Runtime::Shape() const { return state().x; }
Vec3 Runtime::ToolForce() const { return impl_->reaction; }
Vec3 Runtime::ToolTorque() const { return impl_->torque; }

void Runtime::SetToolOrientation(const Eigen::Matrix3d& rotation_world) {
  impl_->tool_rotation = rotation_world;
}
Eigen::Matrix3d Runtime::ToolOrientation() const { return impl_->rotation; }

Vec3 Runtime::ToolPosition() const {
  const RodState& s = state();
  if (impl_->options.tool == ToolKind::kGrasp) return s.x.col(impl_->tool_vertex);
  const double w = impl_->poke_weight;
  return (1.0 - w) * s.x.col(impl_->tool_vertex) + w * s.x.col(impl_->tool_vertex + 1);
}

double Runtime::Energy() const {
  if (impl_->options.mode == RuntimeMode::kDynamic)
    return impl_->stepper->PotentialEnergy(impl_->dynamic.q) - impl_->PokeWork(impl_->dynamic.q);
  return impl_->Energy(impl_->state);
}

double Runtime::KineticEnergy() const {
  return impl_->stepper ? impl_->stepper->KineticEnergy(impl_->dynamic) : 0.0;
}

void Runtime::Impl::BuildMesh(MeshScratch* w, TubeMesh* mesh) const {
  const RodState& s = options.mode == RuntimeMode::kDynamic ? dynamic.q : state;
  const std::optional<SectionSpec>& section = profile.scene.section;
  const double radius = section ? section->radius : model->rod().radius;
  if (!(radius > 0.0)) throw std::invalid_argument("the profile's rod has no radius for a mesh");
  RodVertexFrames(*model, s, &w->frames);
  if (options.tool != ToolKind::kPoke || !section || applied_force.isZero(0.0)) {
    BuildTube(w->frames, radius, options.mesh_ring_vertices, mesh);
    return;
  }
  BuildTube(w->frames, radius, options.mesh_ring_vertices, &w->tube);
  // The dent: the section ring at the tool under the force's in-plane part (tissue §4), then
  // propagated onto the tube by eqs. 12–13.
  const SectionPlacement placement = SectionAt(*model, s, options.tool_s);
  if (!w->ring_solver) {
    RingSolveOptions ring_options;
    ring_options.compute_sensitivities = false;
    w->ring_solver = std::make_unique<RingSolver>(
        *section,
        RingStiffness{model->material().ring_bend_stiffness,
                      model->material().ring_stretch_stiffness},
        ring_options);
  }
  w->ring_solver->Solve(ProjectToSection(applied_force, placement),
                        w->ring_warm ? &w->ring.nodes : nullptr, &w->ring);
  w->ring_warm = w->ring.summary.IsUsable();
  if (!w->ring.summary.IsUsable()) {
    *mesh = w->tube;  // the same storage once sized: a copy, no allocation
    return;
  }
  PropagateLocalDeformation(w->tube, placement, *section, w->ring, &w->propagation, &w->local);
  *mesh = w->local.mesh;
}

TubeMesh Runtime::Mesh() const {
  Impl::MeshScratch scratch;
  TubeMesh mesh;
  impl_->BuildMesh(&scratch, &mesh);
  return mesh;
}

void Runtime::Mesh(TubeMesh* mesh) { impl_->BuildMesh(&impl_->mesh_scratch, mesh); }

const RodModel& Runtime::model() const { return *impl_->model; }
const Profile& Runtime::profile() const { return impl_->profile; }
const RodState& Runtime::state() const {
  return impl_->options.mode == RuntimeMode::kDynamic ? impl_->dynamic.q : impl_->state;
}
const RuntimeOptions& Runtime::options() const { return impl_->options; }
double Runtime::time() const { return impl_->options.mode == RuntimeMode::kDynamic ? impl_->dynamic.t : 0.0; }

}  // namespace rodfit
