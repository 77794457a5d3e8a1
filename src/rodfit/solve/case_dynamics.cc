#include "rodfit/solve/case_dynamics.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/integration.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit {
namespace {

// Linear interpolation of sample column `which` (0: a, 1: b, 2: c) at t, held at the ends.
Vec3 Interpolate(const TimeSeries& series, int which, double t) {
  const std::vector<Vec3>& v = which == 0 ? series.a : which == 1 ? series.b : series.c;
  const std::vector<double>& ts = series.t;
  if (t <= ts.front()) return v.front();
  if (t >= ts.back()) return v.back();
  const size_t k = static_cast<size_t>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin());
  const double w = (t - ts[k - 1]) / (ts[k] - ts[k - 1]);
  return (1.0 - w) * v[k - 1] + w * v[k];
}

// A symmetric case's drives (docs/model.md, "Mirror symmetry"): the whole rod stays its own
// mirror image only when the end clamp moves as the clamp's mirror image, so its path must be
// that (same times; position, tangent reversed and normal mirrored). The half is driven by the
// clamp's path alone: the returned case has the end clamp's drive removed. Throws
// std::invalid_argument naming what breaks the symmetry.
LoadCase HalfDrives(const RodModel& half, const LoadCase& load_case) {
  if (!load_case.tip_load.empty())
    throw std::invalid_argument("symmetry: a tip load series would break the mirror symmetry");
  const DrivenPoint* clamp = nullptr;
  const DrivenPoint* end = nullptr;
  for (const DrivenPoint& d : load_case.drives) {
    if (d.point == "clamp") clamp = &d;
    else if (d.point == "end_clamp") end = &d;
    else throw std::invalid_argument("symmetry: a symmetric case cannot drive " + d.point);
  }
  LoadCase out = load_case;
  if (!clamp && !end) return out;
  if (!clamp || !end)
    throw std::invalid_argument("symmetry: drive both the clamp and the end clamp (the end "
                                "clamp's path the clamp's mirror image), or neither");
  const TimeSeries& a = clamp->path;
  const TimeSeries& b = end->path;
  const Vec3& nrm = half.symmetry_normal();
  auto reflect = [&](const Vec3& v) { return Vec3(v - 2.0 * v.dot(nrm) * nrm); };
  const double tol = 1e-9 * half.length();
  bool same = a.t.size() == b.t.size() && a.b.size() == b.b.size() && a.c.size() == b.c.size();
  for (size_t k = 0; same && k < a.t.size(); ++k) {
    same = std::abs(a.t[k] - b.t[k]) <= 1e-12 * std::max(1.0, std::abs(a.t[k])) &&
           (half.Mirror(a.a[k]) - b.a[k]).norm() <= tol;
    if (same && !a.b.empty())
      same = (-reflect(a.b[k].normalized()) - b.b[k].normalized()).norm() <= 1e-9;
    if (same && !a.c.empty()) {
      const Vec3 t = b.b[k].normalized();
      const Vec3 want = reflect(a.c[k]), got = b.c[k];
      same = ((want - want.dot(t) * t).normalized() - (got - got.dot(t) * t).normalized()).norm() <=
             1e-9;
    }
    if (!same)
      throw std::invalid_argument("symmetry: the end clamp's path is not the clamp's mirror image "
                                  "(sample " + std::to_string(k) + ")");
  }
  if (!same)
    throw std::invalid_argument("symmetry: the end clamp's path is not the clamp's mirror image "
                                "(its samples or columns differ from the clamp's)");
  out.drives.clear();
  out.drives.push_back(*clamp);
  return out;
}

// A free-dof vector's rows of vertex i (zero for the clamped vertex 0, which has none).
Vec3 VertexRows(const VecX& v, int i) {
  return i == 0 ? Vec3::Zero() : Vec3(v.segment<3>(RodModel::VertexDof(i)));
}
Vec3 VertexRows(const Eigen::MatrixXd& d, int i, int c) {
  return i == 0 ? Vec3::Zero() : Vec3(d.block<3, 1>(RodModel::VertexDof(i), c));
}

// The length [m] of vertex i's cell of drag, as the stepper takes it (its mass over the density).
double DragCell(const RodModel& model, int i) {
  return model.vertex_mass(i) / model.rod().linear_density;
}

// The force m a + c v [N] the moving free vertex i needs beyond the static balance (the clamp
// supplies it), at the step's end.
Vec3 InertiaAndDrag(const RodModel& model, int i, const VecX& v, const VecX& v_before, double dt) {
  return model.vertex_mass(i) * (VertexRows(v, i) - VertexRows(v_before, i)) / dt +
         model.material().damping * DragCell(model, i) * VertexRows(v, i);
}

}  // namespace

LoadCase CaseAtStart(const LoadCase& load_case) {
  LoadCase c = load_case;
  for (const DrivenPoint& d : load_case.drives) {
    const TimeSeries& p = d.path;
    const double t0 = 0.0;
    const Vec3 at = Interpolate(p, 0, t0);
    const bool frame = !p.b.empty();
    if (d.point == "clamp") {
      c.clamp.position = at;
      if (frame) {
        c.clamp.tangent = Interpolate(p, 1, t0);
        if (!p.c.empty()) c.clamp.normal = Interpolate(p, 2, t0);
      }
    } else if (d.point == "end_clamp" && c.end_clamp) {
      c.end_clamp->position = at;
      if (frame) {
        c.end_clamp->tangent = Interpolate(p, 1, t0);
        if (!p.c.empty()) c.end_clamp->normal = Interpolate(p, 2, t0);
      }
    } else if (d.point == "end_pin" && c.end_pin) {
      *c.end_pin = at;
    } else if (d.point == "grasp" && c.grasp) {
      c.grasp->position = at;
    } else if (d.point.rfind("pins[", 0) == 0) {
      const size_t k = std::stoul(d.point.substr(5));
      if (k < c.pins.size()) c.pins[k].position = at;
    }
  }
  return c;
}

CaseDrive::CaseDrive(const RodModel& model, const LoadCase& load_case) {
  held_.assign(model.held().size(), nullptr);
  for (const DrivenPoint& d : load_case.drives) {
    if (d.path.empty()) continue;
    if (d.point == "clamp") {
      clamp_ = &d.path;
      continue;
    }
    bool found = false;
    for (size_t k = 0; k < model.held().size(); ++k) {
      if (model.held()[k].Label() != d.point) continue;
      held_[k] = &d.path;
      if (d.point == "end_clamp") end_clamp_ = &d.path;
      found = true;
    }
    if (!found) throw std::invalid_argument("drive: the case holds no point " + d.point);
  }
  if (!load_case.tip_load.empty()) tip_load_ = &load_case.tip_load;
}

void CaseDrive::PoseAt(const RodModel& model, double t, HeldPose* pose) const {
  Drive::PoseAt(model, t, pose);
  if (clamp_) {
    pose->clamp_position = Interpolate(*clamp_, 0, t);
    if (!clamp_->b.empty()) {
      pose->clamp_tangent = Interpolate(*clamp_, 1, t).normalized();
      pose->clamp_d1 = Interpolate(*clamp_, 2, t);
    }
  }
  for (size_t k = 0; k < held_.size(); ++k)
    if (held_[k]) pose->held[k] = Interpolate(*held_[k], 0, t);
  if (end_clamp_ && !end_clamp_->b.empty()) {
    pose->end_tangent = Interpolate(*end_clamp_, 1, t).normalized();
    if (!end_clamp_->c.empty()) pose->end_d1 = Interpolate(*end_clamp_, 2, t);
  }
  if (tip_load_) {
    pose->tip_force = Interpolate(*tip_load_, 0, t);
    if (!tip_load_->b.empty()) pose->tip_moment = Interpolate(*tip_load_, 1, t);
  }
}

std::vector<HeldReaction> MovingReactions(const RodModel& model, const RodState& q, const VecX& v,
                                          const VecX& v_before, double dt, const HeldPose& pose) {
  std::vector<HeldReaction> out = HeldReactions(model, q);
  const int n = model.num_edges();
  const Vec3 x0 = q.x.col(0);
  // The clamp takes what the rest leaves: the pose's dead loads act on the rod (the clamp
  // holds them), the rod's inertia and drag do not reach it.
  Vec3 force = pose.tip_force, moment = (q.x.col(n) - x0).cross(pose.tip_force) + pose.tip_moment;
  if (pose.point_vertex >= 0) {
    const Vec3 at = (1.0 - pose.point_weight) * q.x.col(pose.point_vertex) +
                    pose.point_weight * q.x.col(pose.point_vertex + 1);
    force += pose.point_force;
    moment += (at - x0).cross(pose.point_force);
  }
  if (dt > 0.0)
    for (int i = 1; i <= n; ++i) {
      if (model.held_at_vertex(i) >= 0) continue;  // a held vertex's inertia is its driver's
      const Vec3 f = InertiaAndDrag(model, i, v, v_before, dt);
      force -= f;
      moment -= (q.x.col(i) - x0).cross(f);
    }
  out[0].force += force;
  out[0].moment += moment;
  return out;
}

std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> MovingReactionDerivatives(
    const RodModel& model, const RodState& q, const VecX& v, const VecX& v_before, double dt,
    const HeldPose& pose, const Eigen::MatrixXd& dq, const Eigen::MatrixXd& dv,
    const Eigen::MatrixXd& dv_before, const std::vector<ParameterDirection>& directions) {
  const int n = model.num_edges(), m = static_cast<int>(directions.size());
  // d r / d log p at fixed q of the unconstrained balance r = dPi/dq - Q: the stiffness terms'
  // gradients (U is linear in each) and the weights' (linear in the density).
  Eigen::MatrixXd dr = Eigen::MatrixXd::Zero(model.num_free_dofs(), m);
  VecX g;
  for (int c = 0; c < m; ++c) {
    const ParameterDirection& d = directions[c];
    EnergyTerms terms = EnergyTerms::Only(-1);
    terms.bend1 = d.bend1, terms.bend2 = d.bend2, terms.twist = d.twist, terms.stretch = d.stretch;
    terms.hold = false;
    AssembleGradient(model, q, terms, &g);
    dr.col(c) = g;
    if (d.density != 0.0)
      for (int i = 1; i <= n; ++i)
        dr.block<3, 1>(RodModel::VertexDof(i), c) -= d.density * model.vertex_weight(i);
  }
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> out =
      HeldReactionDerivatives(model, q, dq, dr, std::vector<std::vector<int>>(m));
  const Vec3 x0 = q.x.col(0);
  for (int c = 0; c < m; ++c) {
    const ParameterDirection& d = directions[c];
    Vec3 dforce = Vec3::Zero(), dmoment = VertexRows(dq, n, c).cross(pose.tip_force);
    if (pose.point_vertex >= 0)
      dmoment += ((1.0 - pose.point_weight) * VertexRows(dq, pose.point_vertex, c) +
                  pose.point_weight * VertexRows(dq, pose.point_vertex + 1, c))
                     .cross(pose.point_force);
    // The weights the clamp's balance sums over every vertex (HeldReactions).
    if (d.density != 0.0)
      for (int i = 0; i <= n; ++i) {
        const Vec3 dw = d.density * model.vertex_weight(i);
        dforce += dw;
        dmoment += (q.x.col(i) - x0).cross(dw);
      }
    if (dt > 0.0)
      for (int i = 1; i <= n; ++i) {
        if (model.held_at_vertex(i) >= 0) continue;
        const double cell = DragCell(model, i);
        const double c_drag = model.material().damping;
        const Vec3 f = InertiaAndDrag(model, i, v, v_before, dt);
        const Vec3 df =
            model.vertex_mass(i) *
                (d.density * (VertexRows(v, i) - VertexRows(v_before, i)) +
                 VertexRows(dv, i, c) - VertexRows(dv_before, i, c)) / dt +
            c_drag * cell * (d.drag * VertexRows(v, i) + VertexRows(dv, i, c));
        dforce -= df;
        dmoment -= VertexRows(dq, i, c).cross(f) + (q.x.col(i) - x0).cross(df);
      }
    out[0].block<3, 1>(0, c) += dforce;
    out[0].block<3, 1>(3, c) += dmoment;
  }
  return out;
}

DynamicState InitialDynamicState(const Scene& scene, int index, const StaticsOptions& statics,
                                 const DynamicsStepper& stepper) {
  const RodModel& model = stepper.model();
  const LoadCase& lc = scene.cases[index];
  RodState q;
  if (lc.initial.equilibrium) {
    // The equilibrium under the loads at t = 0 (the tip load series included).
    Scene at_start = scene;
    at_start.dynamics.reset();
    LoadCase& c = at_start.cases[index];
    c = CaseAtStart(lc);
    if (!lc.tip_load.empty()) {
      c.tip_force += lc.tip_load.a.front();
      if (!lc.tip_load.b.empty()) c.tip_moment += lc.tip_load.b.front();
    }
    const CaseSolution solution = SolveCase(at_start, index, nullptr, statics);
    if (!solution.ok())
      throw std::runtime_error("the initial equilibrium: " + solution.summary.BriefReport());
    q = solution.state;
  } else {
    q = StartState(model, nullptr);
  }
  DynamicState s = stepper.AtRest(q);
  if (lc.initial.velocity.cols() > 0) {
    // Velocity samples interpolated linearly in arc length to the free vertices.
    const std::vector<double>& vs = lc.initial.velocity_s;
    for (int i = 1; i <= model.num_edges(); ++i) {
      if (model.held_at_vertex(i) >= 0) continue;
      const double si = model.arc_length(i);
      Vec3 v;
      if (si <= vs.front()) {
        v = lc.initial.velocity.col(0);
      } else if (si >= vs.back()) {
        v = lc.initial.velocity.col(vs.size() - 1);
      } else {
        const size_t k = static_cast<size_t>(std::upper_bound(vs.begin(), vs.end(), si) - vs.begin());
        const double w = (si - vs[k - 1]) / (vs[k] - vs[k - 1]);
        v = (1.0 - w) * lc.initial.velocity.col(k - 1) + w * lc.initial.velocity.col(k);
      }
      s.v.segment<3>(RodModel::VertexDof(i)) = v;
    }
  }
  return s;
}

CaseTrajectory SimulateCaseDynamics(const Scene& scene, int index, const StaticsOptions& statics,
                                    const std::function<void(double)>& progress,
                                    StepSchedule* schedule) {
  const DynamicsSpec& spec = *scene.dynamics;
  const LoadCase start_case = CaseAtStart(scene.cases[index]);
  const RodModel model(scene.rod, scene.material, scene.gravity, start_case, scene.springs);
  const DynamicsOptions options = DynamicsOptionsFrom(spec);
  DynamicsStepper stepper(model, options);
  stepper.SetSchedule(schedule);
  const LoadCase driven =
      model.symmetric() ? HalfDrives(model, scene.cases[index]) : scene.cases[index];
  const CaseDrive drive(model, driven);  // keeps pointers into `driven`'s paths
  // What is written: the case's rod, or for a symmetric case the whole rod (the half and its
  // mirror image, as the statics write it), with the whole rod's reactions.
  std::optional<RodModel> whole;
  if (model.symmetric()) {
    LoadCase full_case = start_case;
    full_case.symmetry.reset();
    whole.emplace(scene.rod, scene.material, scene.gravity, full_case, scene.springs);
  }
  const RodModel& written = whole ? *whole : model;
  CaseTrajectory out;
  out.s = written.arc_lengths();
  DynamicState s = InitialDynamicState(scene, index, statics, stepper);
  if (options.integrator == Integrator::kExplicit) out.stable_step = stepper.StableTimeStep(s.q);
  VecX v_before = s.v;
  // Velocity of the written rod's vertex j from the stepper's: a mirrored vertex moves as the
  // mirror image of its half's.
  const int m = model.num_edges();
  auto velocity = [&](const VecX& v, int j) -> Vec3 {
    if (j <= m) return v.segment<3>(RodModel::VertexDof(j));
    const Vec3& nrm = model.symmetry_normal();
    const Vec3 w = v.segment<3>(RodModel::VertexDof(written.num_edges() - j));
    return w - 2.0 * w.dot(nrm) * nrm;
  };
  // The written rod's rates from the stepper's (a mirrored vertex moves as the mirror image of
  // its half's; only the vertices' rows are read).
  auto written_rates = [&](const VecX& v) -> VecX {
    if (!whole) return v;
    VecX w = VecX::Zero(written.num_free_dofs());
    for (int j = 1; j <= written.num_edges(); ++j)
      if (written.held_at_vertex(j) < 0) w.segment<3>(RodModel::VertexDof(j)) = velocity(v, j);
    return w;
  };
  HeldPose pose;
  auto record = [&](double dt) {
    TrajectoryFrame f;
    f.t = s.t;
    const RodState shown = whole ? MirroredState(model, s.q, *whole) : s.q;
    f.x = shown.x;
    // A symmetric case has no tip loads (HalfDrives): the default pose's are zero.
    pose.held.assign(model.held().size(), Vec3::Zero());
    if (!whole) drive.PoseAt(model, s.t, &pose);
    f.reactions = MovingReactions(written, shown, written_rates(s.v), written_rates(v_before), dt, pose);
    out.frames.push_back(std::move(f));
  };
  record(0.0);
  const int steps = static_cast<int>(std::ceil(spec.duration / spec.time_step - 1e-9));
  int taken = 0;
  // Physical sanity of what is returned: a step that leaves the rod model's small-strain
  // envelope (kSmallStrainLimit; an end driven beyond the rod's reach, a load the rod cannot
  // carry) stops the case there with the time and the edge, as the statics refuse unreachable
  // held points; the frames up to it are kept (simulate --keep-going writes them).
  std::string out_of_range;
  const IntegrationStats stats = Integrate(
      stepper, drive, steps, &s,
      [&](const DynamicState& before, const DynamicState& after, const DynamicsStepSummary&) {
        v_before = before.v;
        ++taken;
        if (taken % spec.output_every == 0 || taken == steps) record(spec.time_step);
        int edge = 0;
        const double strain = LargestEdgeStrain(model, after.q, &edge);
        if (strain > kSmallStrainLimit) {
          char text[320];
          std::snprintf(text, sizeof(text),
                        "t = %.6g s: edge %d is strained by %.3g %%, beyond the rod model's "
                        "small-strain limit of %.3g %% (held points driven beyond the rod's "
                        "reach, or a load the rod cannot carry?)",
                        after.t, edge, 100.0 * strain, 100.0 * kSmallStrainLimit);
          out_of_range = text;
          return false;
        }
        return true;
      },
      nullptr, progress, /*energy_envelope=*/true);
  out.steps = stats.steps;
  out.energy_excess_ratio = stats.energy_excess_ratio;
  out.halved_steps = stats.halved_steps;
  out.newton_iterations = stats.newton_iterations;
  out.seconds = stats.seconds;
  out.reason = out_of_range.empty() ? stats.reason : out_of_range;
  out.ok = stats.ok && out_of_range.empty();
  return out;
}

namespace {

// The sample points at arc lengths s: each between vertices vertex[m] and vertex[m] + 1, with
// weight[m] on the latter.
void LocateSamplePoints(const RodModel& model, const std::vector<double>& s,
                        std::vector<int>* vertex, std::vector<double>* weight) {
  const std::vector<double>& arc = model.arc_lengths();
  const int n = model.num_edges();
  vertex->resize(s.size());
  weight->resize(s.size());
  for (size_t m = 0; m < s.size(); ++m) {
    if (!(s[m] >= 0.0 && s[m] <= arc[n] * (1.0 + 1e-12)))
      throw std::invalid_argument("arc lengths must lie in [0, rod.length]");
    const int i = std::min<int>(
        n - 1, static_cast<int>(std::upper_bound(arc.begin(), arc.end(), s[m]) - arc.begin()) - 1);
    const int v = (*vertex)[m] = std::max(i, 0);
    (*weight)[m] = std::clamp((s[m] - arc[v]) / (arc[v + 1] - arc[v]), 0.0, 1.0);
  }
}

// The sample points at state q (LocateSamplePoints' vertex and weight), and with np directions
// their derivatives from dq (three rows per point). Vertex 0 is the clamp: no dofs.
void SamplePointsAt(const RodState& q, const Eigen::MatrixXd& dq, int np,
                    const std::vector<int>& vertex, const std::vector<double>& weight,
                    Eigen::Matrix3Xd* x, Eigen::MatrixXd* d) {
  d->setZero();
  for (size_t m = 0; m < vertex.size(); ++m) {
    const int i = vertex[m];
    const double w = weight[m];
    x->col(m) = (1.0 - w) * q.x.col(i) + w * q.x.col(i + 1);
    if (np == 0) continue;
    if (i >= 1) d->middleRows<3>(3 * m) += (1.0 - w) * dq.middleRows<3>(RodModel::VertexDof(i));
    d->middleRows<3>(3 * m) += w * dq.middleRows<3>(RodModel::VertexDof(i + 1));
  }
}

// The held points' reactions at weight w between the ends of a step (w = 1: at its end).
std::vector<HeldReaction> LerpReactions(const std::vector<HeldReaction>& before,
                                        const std::vector<HeldReaction>& after, double w) {
  std::vector<HeldReaction> r = after;
  for (size_t k = 0; k < r.size(); ++k) {
    r[k].position = (1.0 - w) * before[k].position + w * after[k].position;
    r[k].force = (1.0 - w) * before[k].force + w * after[k].force;
    r[k].moment = (1.0 - w) * before[k].moment + w * after[k].moment;
  }
  return r;
}

// ... and their derivatives (force and moment per direction).
using Reaction6 = Eigen::Matrix<double, 6, Eigen::Dynamic>;
std::vector<Reaction6> LerpReactionDerivatives(const std::vector<Reaction6>& before,
                                               const std::vector<Reaction6>& after, double w) {
  std::vector<Reaction6> d(after.size());
  for (size_t k = 0; k < d.size(); ++k) d[k] = (1.0 - w) * before[k] + w * after[k];
  return d;
}

// Sample times ascend within [0, duration].
void RequireSampleTimes(const std::vector<double>& t, double duration) {
  for (size_t k = 0; k < t.size(); ++k)
    if (!(t[k] >= 0.0 && t[k] <= duration * (1.0 + 1e-12)) || (k > 0 && !(t[k] >= t[k - 1])))
      throw std::invalid_argument("sample times must ascend within [0, dynamics.duration]");
}

// The start state's sensitivities to the directions: an equilibrium's (false, with why, when
// they cannot be had), zero for a given start shape (the parameters' own) and for the velocity.
bool StartSensitivity(const RodModel& model, const LoadCase& c, const DynamicState& state,
                      const std::vector<ParameterDirection>& directions, DynamicSensitivity* ds,
                      std::string* why) {
  const int np = static_cast<int>(directions.size());
  if (c.initial.equilibrium) {
    if (!EquilibriumSensitivity(model, state.q, directions, &ds->dq, why)) return false;
  } else {
    ds->dq.setZero(model.num_free_dofs(), np);
  }
  ds->dv.setZero(model.num_free_dofs(), np);
  return true;
}

// SampleCaseDynamics on a case without a symmetry plane.
CaseSamples SampleWholeRod(const Scene& scene, int index, const StaticsOptions& statics,
                           const std::vector<double>& s, const std::vector<double>& t,
                           const std::vector<ParameterDirection>& directions,
                           bool with_reactions) {
  const DynamicsSpec& spec = *scene.dynamics;
  RequireSampleTimes(t, spec.duration);
  const RodModel model(scene.rod, scene.material, scene.gravity, CaseAtStart(scene.cases[index]),
                       scene.springs);
  std::vector<int> vertex;
  std::vector<double> weight;
  LocateSamplePoints(model, s, &vertex, &weight);
  DynamicsStepper stepper(model, DynamicsOptionsFrom(spec));
  const CaseDrive drive(model, scene.cases[index]);
  CaseSamples out;
  DynamicState state = InitialDynamicState(scene, index, statics, stepper);
  const int np = static_cast<int>(directions.size());
  const int M = static_cast<int>(s.size());
  DynamicSensitivity ds;
  if (np > 0 && !StartSensitivity(model, scene.cases[index], state, directions, &ds, &out.reason))
    return out;
  // The points (and their derivatives) at the current state.
  Eigen::Matrix3Xd x_now(3, M), x_before(3, M);
  Eigen::MatrixXd d_now = Eigen::MatrixXd::Zero(3 * M, np), d_before = d_now;
  auto points = [&]() { SamplePointsAt(state.q, ds.dq, np, vertex, weight, &x_now, &d_now); };
  points();
  // The held points' reactions at the state (and their derivatives), computed at the end of a
  // step only when a sample time lies within the step after it or the one before.
  std::vector<HeldReaction> r_now, r_before;
  std::vector<Reaction6> dr_now, dr_before;
  VecX v_step_start = state.v;
  Eigen::MatrixXd dv_step_start = ds.dv;
  Eigen::MatrixXd dv_before_step = ds.dv;  // ds.dv before the step in progress
  HeldPose pose;
  auto reactions = [&](double step) {
    pose.held.assign(model.held().size(), Vec3::Zero());
    drive.PoseAt(model, state.t, &pose);
    r_now = MovingReactions(model, state.q, state.v, v_step_start, step, pose);
    if (np > 0)
      dr_now = MovingReactionDerivatives(model, state.q, state.v, v_step_start, step, pose, ds.dq,
                                         ds.dv, dv_step_start, directions);
  };
  auto lerp_reactions = [&](double w) {
    out.reactions.push_back(LerpReactions(r_before, r_now, w));
    if (np > 0) out.d_reactions.push_back(LerpReactionDerivatives(dr_before, dr_now, w));
  };
  const double dt = spec.time_step;
  auto reactions_needed = [&](size_t next) {
    return with_reactions && next < t.size() && t[next] <= state.t + dt * (1.0 + 1e-9);
  };
  size_t next = 0;
  out.x.reserve(t.size());
  if (reactions_needed(0)) reactions(0.0);
  // Samples at t = 0 are the initial state itself.
  for (; next < t.size() && t[next] <= 0.0; ++next) {
    out.x.push_back(x_now);
    if (np > 0) out.dx.push_back(d_now);
    if (with_reactions) {
      r_before = r_now, dr_before = dr_now;
      lerp_reactions(1.0);
    }
  }
  // Steps until every sample time is covered (within round-off of the step count), each step's
  // samples interpolated between the states around them.
  const int steps = t.empty() ? 0 : static_cast<int>(std::ceil(t.back() / dt - 1e-9)) + 1;
  const SensitivityCarry carry{&directions, &ds};
  const IntegrationStats stats = Integrate(
      stepper, drive, next < t.size() ? steps : 0, &state,
      [&](const DynamicState& before, const DynamicState&, const DynamicsStepSummary&) {
        const double t_before = before.t;
        x_before = x_now;
        d_before = d_now;
        r_before.swap(r_now);
        dr_before.swap(dr_now);
        v_step_start = before.v;
        if (np > 0) dv_step_start = dv_before_step;
        if (np > 0) dv_before_step = ds.dv;
        points();
        if (reactions_needed(next)) reactions(state.t - t_before);
        for (; next < t.size() && t[next] <= state.t + 1e-9 * dt; ++next) {
          const double w = std::clamp((t[next] - t_before) / (state.t - t_before), 0.0, 1.0);
          out.x.push_back((1.0 - w) * x_before + w * x_now);
          if (np > 0) out.dx.push_back((1.0 - w) * d_before + w * d_now);
          if (with_reactions) lerp_reactions(w);
        }
        return next < t.size();
      },
      np > 0 ? &carry : nullptr);
  out.steps = stats.steps;
  out.seconds = stats.seconds;
  out.reason = stats.reason;
  out.ok = stats.ok;
  return out;
}

}  // namespace

CaseSamples SampleCaseDynamics(const Scene& scene, int index, const StaticsOptions& statics,
                               const std::vector<double>& s, const std::vector<double>& t,
                               const std::vector<ParameterDirection>& directions,
                               bool with_reactions) {
  if (!scene.cases[index].symmetry)
    return SampleWholeRod(scene, index, statics, s, t, directions, with_reactions);
  // As the static fit does, a symmetric case is sampled on the whole rod: its markers lie on
  // both halves, and the sensitivities are those of the whole rod's steps.
  Scene whole = scene;
  whole.cases[index].symmetry.reset();
  return SampleWholeRod(whole, index, statics, s, t, directions, with_reactions);
}

}  // namespace rodfit
