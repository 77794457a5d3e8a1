// RodModel: validation, rest geometry, held points, lumped loads, the rest shape and start
// states (rod.h).
#include "rodfit/model/rod.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <utility>

#include <Eigen/Dense>
#include <Eigen/Geometry>

#include "rodfit/model/frames.h"
#include "rodfit/model/material_parameters.h"

namespace rodfit {
namespace {

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

bool Finite(const Vec3& v) { return v.allFinite(); }

std::string Num(double v) {
  char b[32];
  std::snprintf(b, sizeof(b), "%.6g", v);
  return b;
}

// Limits of what double precision can solve (docs/model.md, "Limits"). Beyond the stiffness
// ratio the bending response of a stretch-stiff rod falls below the round-off of its stretch
// forces; the rod is then inextensible for every purpose, and a smaller EA gives the same
// answer.
constexpr double kMaxStretchRatio = 1e13;     // EA L^2 / min(B1, B2)
constexpr double kMaxStiffnessRatio = 1e13;   // GJ / B, B1 / B2 and their inverses
constexpr double kMaxLoadStrain = 1.0;        // |load| / EA: more is not a rod's small strain
constexpr double kMaxMomentTurns = 1e4;       // |M| L / (2 pi B): turns a moment winds
constexpr double kMaxHeldStretch = 1.5;       // held points farther apart than this x the rod

// Rotation taking unit a onto unit b (the smallest; a half turn about `fallback_axis` when b =
// -a).
Eigen::Matrix3d RotationBetween(const Vec3& a, const Vec3& b, const Vec3& fallback_axis) {
  if (a.dot(b) < -1.0 + 1e-12) {
    Vec3 axis = fallback_axis - fallback_axis.dot(a) * a;
    return Eigen::AngleAxisd(M_PI, axis.normalized()).toRotationMatrix();
  }
  return Eigen::Quaterniond::FromTwoVectors(a, b).toRotationMatrix();
}

// Discrete bending and twist measures l (k1, k2, tau) of the stencil from frame E = [d1 d2 t]
// of edge e to frame F of edge f, with zero twist angles (u = d1): the same formulas as
// VertexCurvatures (model/vertex_stencil.h) times the Voronoi length.
Vec3 StencilMeasures(const Eigen::Matrix3d& E, const Eigen::Matrix3d& F) {
  const Vec3 te = E.col(2), tf = F.col(2);
  const Vec3 kb = 2.0 * te.cross(tf) / (1.0 + te.dot(tf));
  const Vec3 transported = ParallelTransport<double, double>(te, tf, Vec3(E.col(0)));
  const double twist = SignedAngle<double>(transported, Vec3(F.col(0)), tf);
  return Vec3(0.5 * kb.dot(E.col(0) + F.col(0)), 0.5 * kb.dot(E.col(1) + F.col(1)), twist);
}

// The body rotation Q (frame F = E Q) whose stencil measures are `target` (= l times the rest
// curvature): Newton on the rotation vector, from target itself (exact to first order).
Eigen::Matrix3d RestRotation(const Vec3& target) {
  if (target.squaredNorm() == 0.0) return Eigen::Matrix3d::Identity();
  auto rotation = [](const Vec3& w) {
    const double a = w.norm();
    return a == 0.0 ? Eigen::Matrix3d::Identity()
                    : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
  };
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  Vec3 w = target;
  for (int it = 0; it < 50; ++it) {
    const Vec3 r = StencilMeasures(I, rotation(w)) - target;
    if (r.norm() <= 1e-15 * (1.0 + target.norm())) return rotation(w);
    Eigen::Matrix3d J;
    for (int k = 0; k < 3; ++k) {
      Vec3 dw = Vec3::Zero();
      dw[k] = 1e-7 * (1.0 + w.norm());
      J.col(k) = (StencilMeasures(I, rotation(w + dw)) - StencilMeasures(I, rotation(w - dw))) /
                 (2.0 * dw[k]);
    }
    const Vec3 step = J.fullPivLu().solve(r);
    if (!step.allFinite()) break;
    w -= step;
  }
  const Vec3 r = StencilMeasures(I, rotation(w)) - target;
  Require(r.norm() <= 1e-10 * (1.0 + target.norm()),
          "rod.rest_curvature is too large for the segment length: a vertex would have to turn "
          "by " + Num(target.norm()) + " rad (use more segments)");
  return rotation(w);
}

}  // namespace

std::string HeldVertex::Label() const {
  switch (kind) {
    case Kind::kEndClamp: return "end_clamp";
    case Kind::kEndPin: return "end_pin";
    case Kind::kPin: return "pins[" + std::to_string(index) + "]";
    case Kind::kGrasp: return "grasp";
  }
  return "?";
}

void RodState::SyncEdges() {
  const int n = static_cast<int>(x.cols()) - 1;
  e.resize(3, n);
  for (int j = 0; j < n; ++j) e.col(j) = x.col(j + 1) - x.col(j);
}

void RodState::SyncVertices() {
  for (int j = 0; j < e.cols(); ++j) x.col(j + 1) = x.col(j) + e.col(j);
}

namespace {

// The checks on the rod, its material, gravity, the clamp and the tip loads that need nothing
// built (the rest refuse what the discretisation cannot represent).
void RequireValidSpecs(const RodSpec& rod, const Material& m, const Vec3& gravity,
                       const LoadCase& load_case) {
  Require(rod.segments >= 2, "rod.segments must be at least 2");
  Require(std::isfinite(rod.length) && rod.length > 0, "rod.length must be positive");
  Require(rod.length >= 1e-9 && rod.length <= 1e6,
          "rod.length " + Num(rod.length) + " m is outside [1e-9, 1e6] m");
  Require(std::isfinite(rod.linear_density) && rod.linear_density >= 0,
          "rod.linear_density must be non-negative");
  // 0: a weightless rod (statics); otherwise in its physical range (material_parameters.h).
  Require(rod.linear_density == 0.0 || (rod.linear_density >= kMinLinearDensity &&
                                        rod.linear_density <= kMaxLinearDensity),
          "rod.linear_density " + Num(rod.linear_density) + " kg/m is outside its physical range [" +
              Num(kMinLinearDensity) + ", " + Num(kMaxLinearDensity) + "] kg/m");
  Require(Finite(rod.rest_curvature), "rod.rest_curvature must be finite");
  Require(rod.rest_curvature_s.size() == rod.rest_curvature_profile.size(),
          "rod.rest_curvature_s and rest_curvature_profile must have one entry each");
  for (size_t k = 0; k < rod.rest_curvature_s.size(); ++k) {
    Require(std::isfinite(rod.rest_curvature_s[k]) && Finite(rod.rest_curvature_profile[k]),
            "the rest curvature profile must be finite");
    Require(k == 0 || rod.rest_curvature_s[k] > rod.rest_curvature_s[k - 1],
            "the rest curvature profile's arc lengths must increase strictly");
  }
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    if (row.kind != ParameterKind::kRodStiffness) continue;
    const std::string name = row.name;
    const double value = EffectiveMaterialParameter(m, name);
    Require(std::isfinite(value) && value > 0, std::string(name) + " must be positive");
    Require(value >= row.lowest && value <= row.highest,
            std::string(name) + " " + Num(value) + " is outside [" + Num(row.lowest) + ", " +
                Num(row.highest) + "]");
  }
  const double B = std::min(m.B1(), m.B2());
  Require(m.stretch_stiffness * rod.length * rod.length / B <= kMaxStretchRatio,
          "stretch_stiffness L^2 / bend_stiffness = " +
              Num(m.stretch_stiffness * rod.length * rod.length / B) +
              " exceeds 1e13: the bending response would be below the round-off of the stretch "
              "forces; the rod is inextensible for every purpose at 1e12, use that EA");
  Require(std::max(m.B1(), m.B2()) / B <= kMaxStiffnessRatio,
          "bend_stiffness / bend_stiffness_2 is beyond 1e13 either way");
  Require(m.twist_stiffness / B <= kMaxStiffnessRatio && B / m.twist_stiffness <= kMaxStiffnessRatio,
          "twist_stiffness / bend_stiffness is beyond 1e13 either way");
  Require(Finite(gravity), "gravity must be finite");
  const Clamp& clamp = load_case.clamp;
  Require(Finite(clamp.position) && Finite(clamp.tangent) && Finite(clamp.normal),
          "clamp vectors must be finite");
  Require(clamp.tangent.norm() > 0, "clamp.tangent must not be zero");
  Require(Finite(load_case.tip_force) && Finite(load_case.tip_moment) &&
              Finite(load_case.tip_moment_follower),
          "tip_force and tip moments must be finite");
}

}  // namespace

RodModel::RodModel(const RodSpec& rod, const Material& material, const Vec3& gravity,
                   const LoadCase& load_case, const std::vector<SpringZone>& springs)
    : rod_(rod), material_(material), case_(load_case), gravity_(gravity), zones_(springs) {
  RequireValidSpecs(rod, material, gravity, load_case);
  n_ = rod.segments;
  length_ = rod.length;
  SetUpEnds();
  if (load_case.symmetry) SetUpSymmetry();
  BuildVertices();
  PlaceHeldPoints();

  // Positions must be resolvable at the scale of an edge (a coordinate of 1e300 m leaves no
  // digits for the rod).
  auto resolvable = [&](const Vec3& p, const std::string& what) {
    Require(p.cwiseAbs().maxCoeff() * std::numeric_limits<double>::epsilon() <= 1e-7 * min_edge_,
            what + " is too far from the origin (" + Num(p.norm()) +
                " m) to resolve edges of " + Num(min_edge_) + " m in double precision");
  };
  resolvable(clamp_p_, "clamp.position");
  for (const HeldVertex& h : held_) resolvable(h.target, h.Label() + " position");

  const Loads loads = LumpLoads();
  SetUpSpringZones();
  // Springs pull towards the rest shape, rest curvature included.
  anchor_ = RestState().x;
  RequireCarryable(loads);

  held_dofs_.assign(num_free_dofs(), 0);
  for (const HeldVertex& hv : held_)
    for (int r = 0; r < 3; ++r) held_dofs_[VertexDof(hv.vertex) + r] = 1;
  if (has_end_ghost()) {
    for (int r = 0; r < 3; ++r) held_dofs_[VertexDof(n_ + 1) + r] = 1;  // ghost's far vertex
    if (end_twist_held_) held_dofs_[TwistDof(n_)] = 1;
  }

  hessian_digest_ = HessianDigest();
  force_scale_ = ForceScale(loads);
}

// The clamp's frame and the far end's hold (end clamp or end pin), with the loads the held end
// takes instead.
void RodModel::SetUpEnds() {
  const LoadCase& load_case = case_;
  const Clamp& clamp = load_case.clamp;
  clamp_p_ = clamp.position;
  clamp_d3_ = clamp.tangent.normalized();
  const Vec3 normal_perp = clamp.normal - clamp.normal.dot(clamp_d3_) * clamp_d3_;
  // Gram–Schmidt; a normal within ~0.06 degrees of the tangent has no usable direction.
  Require(clamp.normal.norm() > 0 && normal_perp.norm() > 1e-3 * clamp.normal.norm(),
          "clamp.normal must not be (nearly) parallel to clamp.tangent");
  clamp_d1_ = normal_perp.normalized();

  if (load_case.end_clamp && load_case.end_pin)
    throw std::invalid_argument("end_clamp and end_pin both hold s = L: give one");
  if (const auto& ec = load_case.end_clamp; ec && !load_case.symmetry) {
    Require(Finite(ec->position) && Finite(ec->tangent) && (!ec->normal || Finite(*ec->normal)),
            "end_clamp vectors must be finite");
    Require(ec->tangent.norm() > 0, "end_clamp.tangent must not be zero");
    end_clamp_ = true;
    end_d3_ = ec->tangent.normalized();
    if (ec->normal) {
      const Vec3 perp = *ec->normal - ec->normal->dot(end_d3_) * end_d3_;
      Require(ec->normal->norm() > 0 && perp.norm() > 1e-3 * ec->normal->norm(),
              "end_clamp.normal must not be (nearly) parallel to end_clamp.tangent");
      end_twist_held_ = true;
      end_d1_ = perp.normalized();
    }
  }
  if (load_case.end_pin) Require(Finite(*load_case.end_pin), "end_pin must be finite");
  const bool end_held = load_case.end_clamp || load_case.end_pin;
  Require(!(end_held && load_case.tip_force.squaredNorm() > 0),
          "tip_force acts on the held end s = L, which the end_clamp / end_pin takes: remove it");
  Require(!(load_case.end_clamp && (load_case.tip_moment.squaredNorm() > 0 ||
                                    load_case.tip_moment_follower.squaredNorm() > 0)),
          "a tip moment acts on the clamped end s = L, which the end_clamp takes: remove it");
}

// The lumped loads: vertex masses and their weights, the tip and point forces on the vertices
// around them, the moments on edges; their sizes for the load checks and the load scale.
RodModel::Loads RodModel::LumpLoads() {
  const LoadCase& load_case = case_;
  const double density = rod_.linear_density;
  Loads loads;
  vertex_mass_.assign(n_ + 1, 0.0);
  for (int j = 0; j < n_; ++j) {
    vertex_mass_[j] += 0.5 * density * rest_edge_[j];
    vertex_mass_[j + 1] += 0.5 * density * rest_edge_[j];
  }
  if (symmetric_) vertex_mass_[n_] += 0.5 * density * crossing_length_;
  vertex_forces_.setZero(3, n_ + 1);
  for (int i = 0; i <= n_; ++i) vertex_forces_.col(i) = vertex_mass_[i] * gravity_;
  vertex_forces_.col(n_) += load_case.tip_force;
  // A force at s acts on the interpolated point x(s) = (1 - a) x_k + a x_{k+1}.
  auto locate = [&](double s, int* k, double* a) {
    *k = static_cast<int>(std::upper_bound(arc_.begin(), arc_.end(), s) - arc_.begin()) - 1;
    *k = std::clamp(*k, 0, n_ - 1);
    *a = std::clamp((s - arc_[*k]) / rest_edge_[*k], 0.0, 1.0);
  };
  auto add_point_force = [&](double s, const Vec3& force, const char* what) {
    Require(std::isfinite(s) && s >= 0 && s <= length_ * (1 + 1e-12) && Finite(force),
            std::string(what) + " s must lie in [0, length] and its force be finite");
    int k;
    double a;
    locate(s, &k, &a);
    vertex_forces_.col(k) += (1.0 - a) * force;
    vertex_forces_.col(k + 1) += a * force;
    loads.point_force_sum += force.stableNorm();
  };
  for (const PointForce& pf : load_case.point_forces) add_point_force(pf.s, pf.force, "point force");
  if (load_case.poke) add_point_force(load_case.poke->s, load_case.poke->force, "poke");

  // Moments on edges. A point moment between two edge midpoints is shared linearly.
  auto add_moment = [&](int edge, const Vec3& M, bool follower) {
    if (M.squaredNorm() == 0.0) return;
    edge_moments_.push_back({edge, M, follower});
  };
  add_moment(n_ - 1, load_case.tip_moment, false);
  // A follower moment turns with the end's frame at s = L; the last edge's frame sits half an
  // edge before it. The two differ by the rotation (l/2) u_tip, u_tip = K^-1 m + rest curvature
  // the body curvature that the moment itself sets at the free end (m(L) = R(L) m_b), so the
  // moment on the edge has the components exp((l/2) [u_tip]x) m_b: second order in l, where the
  // edge's own frame would be first order.
  if (load_case.tip_moment_follower.squaredNorm() > 0) {
    const Material& m = material_;
    const Vec3& mb = load_case.tip_moment_follower;
    const Vec3 u_tip = Vec3(mb[0] / m.B1(), mb[1] / m.B2(), mb[2] / m.twist_stiffness) +
                       rest_curvature_[n_ - 1];
    const Vec3 w = 0.5 * rest_edge_[n_ - 1] * u_tip;
    const double angle = w.norm();
    const Vec3 mb_tip =
        angle > 0 ? Vec3(Eigen::AngleAxisd(angle, w / angle) * mb) : mb;
    add_moment(n_ - 1, mb_tip, true);
  }
  loads.moment_sum +=
      load_case.tip_moment.stableNorm() + load_case.tip_moment_follower.stableNorm();
  for (const PointMoment& pm : load_case.point_moments) {
    Require(std::isfinite(pm.s) && pm.s >= 0 && pm.s <= length_ * (1 + 1e-12) && Finite(pm.moment),
            "point moment s must lie in [0, length] and its moment be finite");
    const double first_mid = 0.5 * (arc_[0] + arc_[1]), last_mid = 0.5 * (arc_[n_ - 1] + arc_[n_]);
    if (pm.s <= first_mid) {
      add_moment(0, pm.moment, false);
    } else if (pm.s >= last_mid) {
      add_moment(n_ - 1, pm.moment, false);
    } else {
      int j = 0;
      while (j + 1 < n_ && 0.5 * (arc_[j + 1] + arc_[j + 2]) < pm.s) ++j;
      const double m0 = 0.5 * (arc_[j] + arc_[j + 1]), m1 = 0.5 * (arc_[j + 1] + arc_[j + 2]);
      const double a = (pm.s - m0) / (m1 - m0);
      add_moment(j, (1.0 - a) * pm.moment, false);
      add_moment(j + 1, a * pm.moment, false);
    }
    loads.moment_sum += pm.moment.stableNorm();
  }
  loads.weight = density * length_ * gravity_.stableNorm();
  return loads;
}

// Springs: per zone and vertex, the length of the vertex's cell [s_i - l_{i-1}/2, s_i + l_i/2]
// within [0, L] that the zone covers and no cut removes (the exact integral of a piecewise
// constant K(s) over the cell).
void RodModel::SetUpSpringZones() {
  const LoadCase& load_case = case_;
  auto inside = [&](const Interval& iv, const char* what) {
    Require(std::isfinite(iv.from) && std::isfinite(iv.to) && iv.from >= 0 &&
                iv.to <= length_ * (1 + 1e-12) && iv.from < iv.to,
            std::string(what) + " must satisfy 0 <= from < to <= length");
  };
  for (size_t z = 0; z < zones_.size(); ++z) {
    inside({zones_[z].from, zones_[z].to}, "spring zone");
    for (size_t w = 0; w < z; ++w)
      Require(zones_[z].to <= zones_[w].from || zones_[w].to <= zones_[z].from,
              "spring zones must not overlap");
    Require(zones_[z].parameter.empty() ||
                material_.spring_parameters.count(zones_[z].parameter) > 0,
            "spring zone parameter " + zones_[z].parameter + " has no value");
  }
  for (const Interval& cut : load_case.cuts) inside(cut, "cut");
  for (int z = 0; z < num_spring_zones(); ++z)
    Require(std::isfinite(zone_stiffness(z)) && zone_stiffness(z) >= 0 &&
                zone_stiffness(z) <= 1e30,
            "spring stiffness must be finite, non-negative and at most 1e30");
  auto overlap = [](double a0, double a1, double b0, double b1) {
    return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
  };
  zone_length_.assign(zones_.size(), std::vector<double>(n_ + 1, 0.0));
  for (size_t z = 0; z < zones_.size(); ++z) {
    for (int i = 1; i <= n_; ++i) {
      const double c0 = arc_[i] - 0.5 * rest_edge_[i - 1];
      const double c1 = i < n_ ? arc_[i] + 0.5 * rest_edge_[i] : length_;
      const double z0 = zones_[z].from, z1 = zones_[z].to;
      double covered = overlap(c0, c1, z0, z1);
      // Cuts may overlap each other: subtract the union of their parts inside cell and zone.
      std::vector<std::pair<double, double>> parts;
      for (const Interval& cut : load_case.cuts) {
        const double a = std::max({c0, z0, cut.from}), b = std::min({c1, z1, cut.to});
        if (b > a) parts.emplace_back(a, b);
      }
      std::sort(parts.begin(), parts.end());
      double reach = -1e300;
      for (const auto& [a, b] : parts) {
        const double a2 = std::max(a, reach);
        if (b > a2) covered -= b - a2;
        reach = std::max(reach, b);
      }
      zone_length_[z][i] = std::max(0.0, covered);
    }
  }
}

// Loads a small-strain rod can carry: refuse what would stretch it past its length or wind it
// into thousands of turns (such inputs are unit mistakes, and the answer would be noise).
void RodModel::RequireCarryable(const Loads& loads) const {
  const Material& m = material_;
  const double B = std::min(m.B1(), m.B2());
  const double applied = loads.weight + case_.tip_force.stableNorm() + loads.point_force_sum;
  Require(std::isfinite(applied) && applied <= kMaxLoadStrain * m.stretch_stiffness,
          "the loads (" + Num(applied) + " N) would stretch the rod by more than " +
              Num(100 * kMaxLoadStrain) + " % (stretch_stiffness " + Num(m.stretch_stiffness) +
              " N): outside a rod model, check the units");
  Require(std::isfinite(loads.moment_sum) &&
              loads.moment_sum * length_ / (2 * M_PI * B) <= kMaxMomentTurns,
          "the moments (" + Num(loads.moment_sum) + " N m) would wind the rod into more than 1e4 "
          "turns: check the units");
  for (int z = 0; z < num_spring_zones(); ++z)
    Require(zone_stiffness(z) * length_ * length_ <= 1e3 * m.stretch_stiffness,
            "spring stiffness K L^2 is more than 1e3 x stretch_stiffness: the springs would "
            "crush the rod; check the units");
}

// Hessian digest over the bytes of every number the Hessian reads (see rod.h).
uint64_t RodModel::HessianDigest() const {
  uint64_t h = 1469598103934665603ULL;
  auto mix = [&h](double v) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ULL;
  };
  auto mix3 = [&mix](const Vec3& v) { mix(v[0]), mix(v[1]), mix(v[2]); };
  mix(n_);
  for (int j = 0; j < n_; ++j) mix(rest_edge_[j]);
  for (double v : voronoi_) mix(v);
  mix(material_.B1()), mix(material_.B2());
  mix(material_.twist_stiffness), mix(material_.stretch_stiffness);
  for (const Vec3& k : rest_curvature_) mix3(k);
  mix3(clamp_p_), mix3(clamp_d3_), mix3(clamp_d1_);
  mix(end_clamp_), mix(end_twist_held_), mix3(end_d3_), mix3(end_d1_);
  mix(symmetric_), mix3(sym_point_), mix3(sym_normal_), mix(crossing_length_);
  for (const EdgeMoment& em : edge_moments_) mix(em.edge), mix3(em.moment), mix(em.follower);
  for (int z = 0; z < num_spring_zones(); ++z)
    for (int i = 0; i <= n_; ++i) mix(zone_stiffness(z) * zone_length_[z][i]);
  for (const HeldVertex& hv : held_) mix(hv.vertex), mix(static_cast<int>(hv.kind));
  return h;
}

// The load scale (rod.h): loads, and the elastic forces of imposed shapes.
double RodModel::ForceScale(const Loads& loads) const {
  const double B = std::min(material_.B1(), material_.B2());
  double imposed = 0.0;
  for (const HeldVertex& hv : held_) {
    const Vec3 straight = clamp_p_ + hv.s * clamp_d3_;
    imposed = std::max(imposed, (hv.target - straight).norm() / length_);
  }
  if (end_clamp_ || symmetric_) imposed = std::max(imposed, 1.0);  // an end frame: ~1 / L
  for (const Vec3& k : rest_curvature_) imposed = std::max(imposed, k.norm() * length_);
  double spring_max = 0.0;
  for (int z = 0; z < num_spring_zones(); ++z) spring_max = std::max(spring_max, zone_stiffness(z));
  const double imposed_force = imposed * (B / (length_ * length_) + spring_max * length_ * length_);
  const double scale = std::max({loads.weight, case_.tip_force.norm(), loads.point_force_sum,
                                 loads.moment_sum / length_, imposed_force});
  // Nothing loads the rod: the straight (or rest) rod is the answer; any scale serves.
  if (!(scale > 0)) return B / (length_ * length_);
  return scale;
}

std::string SymmetryProblem(const RodSpec& rod, const Vec3& gravity, const LoadCase& c,
                            bool has_springs) {
  if (!c.symmetry) return "";
  const SymmetryPlane& sp = *c.symmetry;
  const int n = rod.segments;
  if (!(Finite(sp.point) && Finite(sp.normal) && sp.normal.norm() > 0))
    return "symmetry: point and normal must be finite, the normal not zero";
  if (n % 2 != 1)
    return "symmetry needs an odd number of segments (an edge crossing the plane at the rod's "
           "middle), got " + std::to_string(n) + ": use " + std::to_string(n - 1) + " or " +
           std::to_string(n + 1);
  if (!rod.vertex_s.empty()) return "symmetry needs evenly spaced vertices (no rod.vertex_s)";
  if (!c.end_clamp)
    return "symmetry: the rod's end must be held by an end_clamp, the mirror image of the clamp";
  if (c.end_pin || !c.pins.empty() || c.grasp || !c.point_forces.empty() ||
      !c.point_moments.empty() || c.poke || c.tip_force.squaredNorm() != 0 ||
      c.tip_moment.squaredNorm() != 0 || c.tip_moment_follower.squaredNorm() != 0)
    return "symmetry: a symmetric case holds the rod by its two clamps under gravity only (no "
           "pins, grasp, point or tip loads, poke)";
  if (has_springs) return "symmetry: not with springs";
  if (rod.rest_curvature.squaredNorm() != 0 || !rod.rest_curvature_s.empty())
    return "symmetry: not with rest_curvature (a curved rod's mirror image is another rod)";
  const Clamp& clamp = c.clamp;
  if (!(Finite(clamp.position) && Finite(clamp.tangent) && Finite(clamp.normal)) ||
      clamp.tangent.norm() == 0)
    return "clamp vectors must be finite, the tangent not zero";
  Vec3 normal = sp.normal.normalized();
  const double side = (clamp.position - sp.point).dot(normal);
  if (!(std::abs(side) > 1e-9 * rod.length)) return "symmetry: the clamp lies on the plane";
  if (side > 0) normal = -normal;  // from the clamp's half towards the plane
  auto reflect = [&](const Vec3& v) { return Vec3(v - 2.0 * v.dot(normal) * normal); };
  const EndClamp& ec = *c.end_clamp;
  const double tol = 1e-9;
  if (!(Finite(ec.position) && Finite(ec.tangent) && ec.tangent.norm() > 0))
    return "end_clamp vectors must be finite, the tangent not zero";
  const Vec3 mirrored = clamp.position - 2.0 * (clamp.position - sp.point).dot(normal) * normal;
  if (!((ec.position - mirrored).norm() <= tol * rod.length))
    return "symmetry: the end_clamp's position is not the mirror image of the clamp's";
  // r(L - s) = mirror(r(s)): d3(L) = -mirror(d3(0)), d1(L) = mirror(d1(0)).
  const Vec3 d3 = clamp.tangent.normalized();
  if (!((ec.tangent.normalized() + reflect(d3)).norm() <= tol))
    return "symmetry: the end_clamp's tangent is not the mirror image of the clamp's (reversed)";
  if (ec.normal) {
    const Vec3 t = ec.tangent.normalized();
    const Vec3 d1 = (*ec.normal - ec.normal->dot(t) * t).normalized();
    const Vec3 d1_clamp = (clamp.normal - clamp.normal.dot(d3) * d3).normalized();
    if (!((d1 - reflect(d1_clamp)).norm() <= 1e-6))
      return "symmetry: the end_clamp's normal is not the mirror image of the clamp's";
  }
  if (!(std::abs(gravity.dot(normal)) <= 1e-12 * gravity.norm()))
    return "symmetry: gravity crosses the plane (it must lie in it)";
  return "";
}

void RodModel::SetUpSymmetry() {
  const std::string problem = SymmetryProblem(rod_, gravity_, case_, !zones_.empty());
  Require(problem.empty(), problem);
  const int n = rod_.segments;
  sym_point_ = case_.symmetry->point;
  sym_normal_ = case_.symmetry->normal.normalized();
  if ((clamp_p_ - sym_point_).dot(sym_normal_) > 0) sym_normal_ = -sym_normal_;
  symmetric_ = true;
  crossing_length_ = rod_.length / n;
  n_ = (n - 1) / 2;
  length_ = rod_.length * n_ / n;
  end_d3_ = sym_normal_;
  end_twist_held_ = false;
}

void RodModel::BuildVertices() {
  arc_.resize(n_ + 1);
  if (!rod_.vertex_s.empty()) {
    Require(static_cast<int>(rod_.vertex_s.size()) == n_ + 1,
            "rod.vertex_s must have segments + 1 values");
    Require(rod_.vertex_s.front() == 0.0 && std::abs(rod_.vertex_s.back() - length_) <= 1e-12 * length_,
            "rod.vertex_s must run from 0 to rod.length");
    for (int i = 0; i <= n_; ++i) {
      Require(std::isfinite(rod_.vertex_s[i]), "rod.vertex_s must be finite");
      if (i > 0)
        Require(rod_.vertex_s[i] > rod_.vertex_s[i - 1], "rod.vertex_s must increase strictly");
      arc_[i] = rod_.vertex_s[i];
    }
    arc_[n_] = length_;
  } else {
    for (int i = 0; i <= n_; ++i) arc_[i] = length_ * i / n_;
  }
}

void RodModel::PlaceHeldPoints() {
  held_.clear();
  struct Request {
    HeldVertex::Kind kind;
    double s;
    Vec3 target;
    int index;
  };
  std::vector<Request> requests;
  if (case_.grasp) {
    const Grasp& g = *case_.grasp;
    Require(std::isfinite(g.s) && g.s >= 0 && g.s <= length_ * (1 + 1e-12) && Finite(g.position),
            "grasp s must lie in [0, length] and its position be finite");
    requests.push_back({HeldVertex::Kind::kGrasp, std::min(g.s, length_), g.position, 0});
  }
  for (size_t k = 0; k < case_.pins.size(); ++k) {
    const Pin& p = case_.pins[k];
    Require(std::isfinite(p.s) && p.s > 0 && p.s < length_ && Finite(p.position),
            "pins[" + std::to_string(k) + "].s must lie inside (0, length) and its position be "
            "finite (use end_pin for s = L)");
    requests.push_back({HeldVertex::Kind::kPin, p.s, p.position, static_cast<int>(k)});
  }
  std::vector<int> taken(n_ + 1, -1);
  auto name_of = [&](const Request& r) {
    HeldVertex h;
    h.kind = r.kind, h.index = r.index;
    return h.Label() + " (s = " + Num(r.s) + ")";
  };
  // The end is held at vertex n without moving anything (a symmetric half's end clamp belongs
  // to the other half).
  const bool end_held = !symmetric_ && (case_.end_clamp || case_.end_pin);
  if (end_held) taken[n_] = -2;
  for (size_t q = 0; q < requests.size(); ++q) {
    const Request& r = requests[q];
    int k = 0;
    for (int i = 1; i <= n_; ++i)
      if (std::abs(arc_[i] - r.s) < std::abs(arc_[k] - r.s)) k = i;
    Require(k >= 1, name_of(r) + " is at the clamp (its nearest vertex is vertex 0)");
    if (taken[k] != -1) {
      const std::string other =
          taken[k] == -2 ? std::string("the held end") : name_of(requests[taken[k]]);
      throw std::invalid_argument(name_of(r) + " and " + other +
                                  " fall on the same vertex: use more segments");
    }
    taken[k] = static_cast<int>(q);
    arc_[k] = r.s;
  }
  SetUpRestGeometry();

  held_of_vertex_.assign(n_ + 1, -1);
  for (int k = 1; k <= n_; ++k) {
    if (taken[k] < 0) continue;
    const Request& r = requests[taken[k]];
    HeldVertex h;
    h.kind = r.kind, h.vertex = k, h.s = arc_[k], h.target = r.target, h.index = r.index;
    held_.push_back(h);
  }
  if (end_held) {
    HeldVertex h;
    h.kind = case_.end_clamp ? HeldVertex::Kind::kEndClamp : HeldVertex::Kind::kEndPin;
    h.vertex = n_, h.s = length_;
    h.target = case_.end_clamp ? case_.end_clamp->position : *case_.end_pin;
    held_.push_back(h);
  }
  std::sort(held_.begin(), held_.end(),
            [](const HeldVertex& a, const HeldVertex& b) { return a.vertex < b.vertex; });
  for (size_t q = 0; q < held_.size(); ++q) {
    held_of_vertex_[held_[q].vertex] = static_cast<int>(q);
    if (held_[q].kind == HeldVertex::Kind::kGrasp) {
      grasp_vertex_ = held_[q].vertex;
      grasp_position_ = held_[q].target;
    }
  }
  // Consecutive held points (the clamp first) must be reachable by the rod between them.
  ForEachHeldSpan([](double gap, double rod_between, const std::string& earlier,
                     const std::string& later) {
    Require(gap <= kMaxHeldStretch * rod_between,
            later + " is " + Num(gap) + " m from " + earlier + ", but only " + Num(rod_between) +
                " m of rod lies between them");
  });
}

// The rest geometry from the vertices' arc lengths, held points moved onto their vertices:
// edge lengths, Voronoi cells, the rest curvature of every bending vertex.
void RodModel::SetUpRestGeometry() {
  const double uniform = length_ / n_;
  rest_edge_.resize(n_);
  for (int j = 0; j < n_; ++j) {
    rest_edge_[j] = arc_[j + 1] - arc_[j];
    Require(rest_edge_[j] > 0.1 * (rod_.vertex_s.empty() ? uniform : 0.0),
            "held points at s = " + Num(arc_[j]) + " and " + Num(arc_[j + 1]) +
                " are too close for the segment length: use more segments");
    Require(rest_edge_[j] > 1e-12 * length_, "an edge of the rod has (nearly) zero length");
  }
  min_edge_ = *std::min_element(rest_edge_.begin(), rest_edge_.end());
  voronoi_.assign(n_ + 1, 0.0);
  voronoi_[0] = 0.5 * rest_edge_[0];  // half cell against the clamp (see the file comment)
  for (int i = 1; i < n_; ++i) voronoi_[i] = 0.5 * (rest_edge_[i - 1] + rest_edge_[i]);
  // With an end clamp: half a cell against its ghost. A symmetric half's last vertex has the
  // full cell it has in the whole rod, up to the middle of the crossing edge.
  voronoi_[n_] = 0.5 * (rest_edge_[n_ - 1] + (symmetric_ ? crossing_length_ : 0.0));
  // The rest curvature of every bending vertex: the uniform part and the profile's value at the
  // vertex's arc length (linear between its points, constant beyond).
  rest_curvature_.assign(n_ + 1, rod_.rest_curvature);
  if (!rod_.rest_curvature_s.empty()) {
    const std::vector<double>& ps = rod_.rest_curvature_s;
    const std::vector<Vec3>& pk = rod_.rest_curvature_profile;
    for (int i = 0; i <= n_; ++i) rest_curvature_[i] += RestCurvatureProfileAt(ps, pk, arc_[i]);
  }
  for (const Vec3& k : rest_curvature_) curved_ = curved_ || k.squaredNorm() != 0.0;
}

void RodModel::ForEachHeldSpan(const std::function<void(double, double, const std::string&,
                                                        const std::string&)>& visit) const {
  Vec3 prev_p = clamp_p_;
  double prev_s = 0.0;
  std::string prev_name = "the clamp (s = 0)";
  for (const HeldVertex& h : held_) {
    const std::string name = h.Label() + " (s = " + Num(h.s) + ")";
    visit((h.target - prev_p).norm(), h.s - prev_s, prev_name, name);
    prev_p = h.target, prev_s = h.s;
    prev_name = name;
  }
}

std::vector<std::string> RodModel::StretchedSpans(double strain) const {
  std::vector<std::string> out;
  ForEachHeldSpan([&](double gap, double rod_between, const std::string& earlier,
                      const std::string& later) {
    if (gap > (1.0 + strain) * rod_between)
      out.push_back(later + " is " + Num(gap) + " m from " + earlier + ", " +
                    Num(100.0 * (gap / rod_between - 1.0)) + " % more than the " +
                    Num(rod_between) + " m of rod between them: the rod must stretch to reach it");
  });
  return out;
}

double RodModel::zone_stiffness(int z) const {
  const std::string& p = zones_[z].parameter;
  return p.empty() ? material_.spring_stiffness : material_.spring_parameters.at(p);
}

void RodModel::InitialiseFrames(RodState* s) const {
  const int n = n_;
  s->theta.setZero(n);
  s->ref_u.resize(3, n);
  s->ref_t.resize(3, n);
  s->ref_twist.setZero(n + 1);
  s->clamp_t = clamp_d3_;
  s->clamp_d1 = clamp_d1_;
  // Reference directors transported along the rod from the clamp (space-parallel): the
  // reference twist is then zero at every vertex.
  Vec3 t_prev = clamp_d3_, u_prev = clamp_d1_;
  for (int j = 0; j < n; ++j) {
    const Vec3 t = s->e.col(j).normalized();
    Vec3 u = ParallelTransport<double, double>(t_prev, t, u_prev);
    u = (u - u.dot(t) * t).normalized();
    s->ref_t.col(j) = t;
    s->ref_u.col(j) = u;
    t_prev = t, u_prev = u;
  }
  for (int i = 0; i < n; ++i) {
    const Vec3 te = i == 0 ? clamp_d3_ : Vec3(s->ref_t.col(i - 1));
    const Vec3 ue = i == 0 ? clamp_d1_ : Vec3(s->ref_u.col(i - 1));
    s->ref_twist[i] = SignedAngle<double>(ParallelTransport<double, double>(te, s->ref_t.col(i), ue),
                                          s->ref_u.col(i), s->ref_t.col(i));
  }
  if (has_end_ghost()) {  // the ghost continues the last edge: no kink, no twist at vertex n
    s->end_t = s->ref_t.col(n - 1);
    s->end_u = s->ref_u.col(n - 1);
    s->end_theta = 0.0;
    // A symmetric half's plane: perpendicular to the last edge half a crossing edge beyond it
    // (where the whole rod, as the state has it, would be mirror symmetric).
    if (symmetric_) s->plane_point = s->x.col(n) + 0.5 * crossing_length_ * s->end_t;
  } else {
    s->end_t.setZero();
    s->end_u.setZero();
    s->end_theta = 0.0;
  }
}

RodState RodModel::StraightState() const {
  RodState s;
  s.x.resize(3, n_ + 1);
  s.e.resize(3, n_);
  s.x.col(0) = clamp_p_;
  for (int j = 0; j < n_; ++j) s.e.col(j) = rest_edge_[j] * clamp_d3_;
  s.SyncVertices();
  InitialiseFrames(&s);
  return s;
}

Vec3 RestCurvatureProfileAt(const std::vector<double>& s, const std::vector<Vec3>& profile,
                            double at) {
  if (s.empty()) return Vec3::Zero();
  if (at <= s.front()) return profile.front();
  if (at >= s.back()) return profile.back();
  const size_t j = static_cast<size_t>(std::upper_bound(s.begin(), s.end(), at) - s.begin());
  const double w = (at - s[j - 1]) / (s[j] - s[j - 1]);
  return profile[j - 1] + w * (profile[j] - profile[j - 1]);  // exact where neighbours are equal
}

RodState RodModel::RestState() const {
  RodState s;
  s.x.resize(3, n_ + 1);
  s.e.resize(3, n_);
  s.x.col(0) = clamp_p_;
  // Frames [d1 d2 d3] edge by edge from the ghost's, each turned by the rotation whose stencil
  // measures are the vertex's rest curvature times its Voronoi length.
  std::vector<Eigen::Matrix3d> frames(n_);
  Eigen::Matrix3d F;
  F << clamp_d1_, clamp_d3_.cross(clamp_d1_), clamp_d3_;
  std::vector<std::pair<Vec3, Eigen::Matrix3d>> cache;  // rotations by turn (uniform rods repeat)
  for (int j = 0; j < n_; ++j) {
    const Vec3 turn = voronoi_[j] * rest_curvature_[j];
    auto hit = std::find_if(cache.begin(), cache.end(),
                            [&turn](const auto& c) { return c.first == turn; });
    if (hit == cache.end()) {
      cache.emplace_back(turn, RestRotation(turn));
      hit = cache.end() - 1;
    }
    F = F * hit->second;
    frames[j] = F;
    s.e.col(j) = rest_edge_[j] * F.col(2);
  }
  s.SyncVertices();
  InitialiseFrames(&s);
  // With space-parallel reference directors the material angles carry the accumulated twist.
  for (int j = 0; j < n_; ++j)
    s.theta[j] = SignedAngle<double>(Vec3(s.ref_u.col(j)), Vec3(frames[j].col(0)),
                                     Vec3(s.ref_t.col(j)));
  return s;
}

RodState RodModel::StateFromCentreline(const std::vector<double>& s_in,
                                       const Mat3X& points) const {
  const int m = static_cast<int>(points.cols());
  Require(m >= 2, "a start shape needs at least 2 points, got " + std::to_string(m));
  Require(points.allFinite(), "a start shape's points must be finite");
  std::vector<double> s(m, 0.0);
  if (!s_in.empty()) {
    Require(static_cast<int>(s_in.size()) == m, "start shape: one s per point");
    for (int k = 0; k < m; ++k) {
      Require(std::isfinite(s_in[k]), "start shape: s must be finite");
      if (k > 0) Require(s_in[k] > s_in[k - 1], "start shape: s must increase strictly");
      s[k] = s_in[k];
    }
    const double reach = 1.01 * *std::max_element(rest_edge_.begin(), rest_edge_.end());
    Require(s.front() <= reach && s.back() >= length_ - reach,
            "start shape covers s in [" + Num(s.front()) + ", " + Num(s.back()) +
                "], not the rod's [0, " + Num(length_) + "]");
  } else {
    for (int k = 1; k < m; ++k) {
      const double d = (points.col(k) - points.col(k - 1)).norm();
      Require(d > 0, "start shape: points " + std::to_string(k) + " and " + std::to_string(k + 1) +
                         " coincide");
      s[k] = s[k - 1] + d;
    }
    for (int k = 0; k < m; ++k) s[k] *= length_ / s[m - 1];
  }
  auto at = [&](double t) -> Vec3 {  // piecewise linear, extended linearly past the ends
    int k = static_cast<int>(std::upper_bound(s.begin(), s.end(), t) - s.begin()) - 1;
    k = std::clamp(k, 0, m - 2);
    const double a = (t - s[k]) / (s[k + 1] - s[k]);
    return (1.0 - a) * points.col(k) + a * points.col(k + 1);
  };
  RodState st;
  st.x.resize(3, n_ + 1);
  st.e.resize(3, n_);
  std::vector<Vec3> dirs(n_);
  for (int j = 0; j < n_; ++j) {
    const Vec3 d = at(arc_[j + 1]) - at(arc_[j]);
    Require(d.norm() > 1e-9 * rest_edge_[j],
            "start shape: the rod's edge " + std::to_string(j) + " maps to a single point");
    dirs[j] = d.normalized();
  }
  const Eigen::Matrix3d R = RotationBetween(dirs[0], clamp_d3_, clamp_d1_);
  st.x.col(0) = clamp_p_;
  for (int j = 0; j < n_; ++j) st.e.col(j) = rest_edge_[j] * (R * dirs[j]);
  st.SyncVertices();
  InitialiseFrames(&st);
  return st;
}

EdgeFrame RodModel::MaterialFrame(const RodState& state, int j) const {
  EdgeFrame f;
  f.d3 = state.e.col(j).normalized();
  const Vec3 t_old = state.ref_t.col(j);
  const Vec3 u_old = state.ref_u.col(j);
  const Vec3 u = ParallelTransport<double, double>(t_old, f.d3, u_old).normalized();
  const Vec3 v = f.d3.cross(u);
  const double c = std::cos(state.theta[j]), s = std::sin(state.theta[j]);
  f.d1 = c * u + s * v;
  f.d2 = -s * u + c * v;
  return f;
}

void RestCurvatureOfCentreline(const std::vector<double>& s_in, const Mat3X& points,
                               const Vec3& normal, double length,
                               std::vector<double>* profile_s, std::vector<Vec3>* profile) {
  const int m = static_cast<int>(points.cols());
  Require(m >= 3, "a rest shape needs at least 3 points, got " + std::to_string(m));
  Require(points.allFinite() && Finite(normal), "a rest shape's values must be finite");
  Require(s_in.empty() || static_cast<int>(s_in.size()) == m, "a rest shape: one s per point");
  std::vector<double> s(m, 0.0);
  std::vector<Vec3> t(m - 1);
  for (int k = 0; k + 1 < m; ++k) {
    const Vec3 e = points.col(k + 1) - points.col(k);
    Require(e.norm() > 0.0, "a rest shape's points " + std::to_string(k + 1) + " and " +
                                std::to_string(k + 2) + " coincide");
    t[k] = e.normalized();
    s[k + 1] = s_in.empty() ? s[k] + e.norm() : s_in[k + 1] - s_in[0];
    Require(s[k + 1] > s[k], "a rest shape's s must increase strictly");
  }
  const double scale = length / s[m - 1];
  Vec3 d1 = normal - normal.dot(t[0]) * t[0];
  Require(d1.norm() > 1e-3 * normal.norm(), "a rest shape's normal is along its first tangent");
  d1.normalize();
  profile_s->assign(1, 0.0);
  profile->assign(1, Vec3::Zero());
  Vec3 d1_prev = d1;
  for (int k = 1; k + 1 < m; ++k) {
    // d1 carried to edge k by parallel transport (Bishop frame: no rest twist).
    Vec3 d1_next = ParallelTransport<double, double>(t[k - 1], t[k], d1_prev);
    d1_next = (d1_next - d1_next.dot(t[k]) * t[k]).normalized();
    const Vec3 kb = 2.0 * t[k - 1].cross(t[k]) / (1.0 + t[k - 1].dot(t[k]));
    const double l = 0.5 * scale * (s[k + 1] - s[k - 1]);
    const Vec3 a1 = 0.5 * (d1_prev + d1_next);
    const Vec3 a2 = 0.5 * (t[k - 1].cross(d1_prev) + t[k].cross(d1_next));
    profile_s->push_back(scale * s[k]);
    profile->push_back(Vec3(kb.dot(a1) / l, kb.dot(a2) / l, 0.0));
    d1_prev = d1_next;
  }
  // Constant beyond the interior points: the ends take their neighbours' values.
  (*profile)[0] = (*profile)[1];
  profile_s->push_back(length);
  profile->push_back(profile->back());
}

double LargestEdgeStrain(const RodModel& model, const RodState& state, int* edge) {
  double worst = 0.0;
  int where = 0;
  for (int j = 0; j < model.num_edges(); ++j) {
    const double strain = std::abs(state.e.col(j).norm() / model.rest_edge_length(j) - 1.0);
    if (strain > worst) worst = strain, where = j;
  }
  if (edge != nullptr) *edge = where;
  return worst;
}

}  // namespace rodfit
