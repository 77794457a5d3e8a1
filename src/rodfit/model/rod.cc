// RodModel: validation, rest geometry, lumped loads and the straight start state (rod.h).
#include "rodfit/model/rod.h"

#include <algorithm>
#include <utility>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "rodfit/model/frames.h"

namespace rodfit {
namespace {

void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

bool Finite(const Vec3& v) { return v.allFinite(); }

}  // namespace

RodModel::RodModel(const RodSpec& rod, const Material& material, const Vec3& gravity,
                   const LoadCase& load_case, const std::vector<SpringZone>& springs)
    : rod_(rod), material_(material), case_(load_case), gravity_(gravity), zones_(springs) {
  Require(rod.segments >= 2, "rod.segments must be at least 2");
  Require(std::isfinite(rod.length) && rod.length > 0, "rod.length must be positive");
  Require(std::isfinite(rod.linear_density) && rod.linear_density >= 0,
          "rod.linear_density must be non-negative");
  Require(Finite(rod.rest_curvature), "rod.rest_curvature must be finite");
  Require(std::isfinite(material.B1()) && material.B1() > 0, "bend_stiffness must be positive");
  Require(std::isfinite(material.B2()) && material.B2() > 0, "bend_stiffness_2 must be positive");
  Require(std::isfinite(material.twist_stiffness) && material.twist_stiffness > 0,
          "twist_stiffness must be positive");
  Require(std::isfinite(material.stretch_stiffness) && material.stretch_stiffness > 0,
          "stretch_stiffness must be positive");
  Require(Finite(gravity), "gravity must be finite");
  const Clamp& clamp = load_case.clamp;
  Require(Finite(clamp.position) && Finite(clamp.tangent) && Finite(clamp.normal),
          "clamp vectors must be finite");
  Require(clamp.tangent.norm() > 0, "clamp.tangent must not be zero");
  Require(Finite(load_case.tip_force) && Finite(load_case.tip_moment),
          "tip_force and tip_moment must be finite");

  n_ = rod.segments;
  length_ = rod.length;
  clamp_p_ = clamp.position;
  clamp_d3_ = clamp.tangent.normalized();
  const Vec3 normal_perp = clamp.normal - clamp.normal.dot(clamp_d3_) * clamp_d3_;
  // Gram–Schmidt; a normal within ~0.06 degrees of the tangent has no usable direction.
  Require(clamp.normal.norm() > 0 && normal_perp.norm() > 1e-3 * clamp.normal.norm(),
          "clamp.normal must not be (nearly) parallel to clamp.tangent");
  clamp_d1_ = normal_perp.normalized();

  const double l = length_ / n_;
  rest_edge_.assign(n_, l);
  voronoi_.assign(n_, l);
  voronoi_[0] = 0.5 * l;  // half cell against the clamp (see the file comment in rod.h)
  arc_.resize(n_ + 1);
  for (int i = 0; i <= n_; ++i) arc_[i] = i * l;
  vertex_mass_.assign(n_ + 1, rod.linear_density * l);
  vertex_mass_[0] = vertex_mass_[n_] = 0.5 * rod.linear_density * l;

  vertex_forces_.setZero(3, n_ + 1);
  for (int i = 0; i <= n_; ++i) vertex_forces_.col(i) = vertex_mass_[i] * gravity_;
  vertex_forces_.col(n_) += load_case.tip_force;
  double point_force_sum = 0.0;
  for (const PointForce& pf : load_case.point_forces) {
    Require(std::isfinite(pf.s) && pf.s >= 0 && pf.s <= length_ && Finite(pf.force),
            "point force s must lie in [0, length] and its force be finite");
    // Linear interpolation x(s) = (1 - a) x_k + a x_{k+1}; the force does work on x(s).
    const double u = pf.s / l;
    const int k = std::min(static_cast<int>(std::floor(u)), n_ - 1);
    const double a = u - k;
    vertex_forces_.col(k) += (1.0 - a) * pf.force;
    vertex_forces_.col(k + 1) += a * pf.force;
    point_force_sum += pf.force.norm();
  }
  // Springs: per zone and vertex, the length of the vertex's cell [s_i - l/2, s_i + l/2] within
  // [0, L] that the zone covers and no cut removes (the exact integral of a piecewise constant
  // K(s) over the cell).
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
                material.spring_parameters.count(zones_[z].parameter) > 0,
            "spring zone parameter " + zones_[z].parameter + " has no value");
  }
  for (const Interval& cut : load_case.cuts) inside(cut, "cut");
  if (!zones_.empty()) {
    Require(rod.rest_curvature.squaredNorm() == 0.0,
            "springs tie the rod to its straight rest position: a rod with springs must have no "
            "rest_curvature");
    for (int z = 0; z < num_spring_zones(); ++z)
      Require(std::isfinite(zone_stiffness(z)) && zone_stiffness(z) >= 0,
              "spring stiffness must be finite and non-negative");
  }
  auto overlap = [](double a0, double a1, double b0, double b1) {
    return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
  };
  zone_length_.assign(zones_.size(), std::vector<double>(n_ + 1, 0.0));
  for (size_t z = 0; z < zones_.size(); ++z) {
    for (int i = 1; i <= n_; ++i) {
      const double c0 = std::max(0.0, arc_[i] - 0.5 * l), c1 = std::min(length_, arc_[i] + 0.5 * l);
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
  anchor_.resize(3, n_ + 1);
  for (int i = 0; i <= n_; ++i) anchor_.col(i) = clamp_p_ + arc_[i] * clamp_d3_;

  if (load_case.grasp) {
    const Grasp& g = *load_case.grasp;
    Require(std::isfinite(g.s) && g.s >= 0 && g.s <= length_ * (1 + 1e-12) && Finite(g.position),
            "grasp s must lie in [0, length] and its position be finite");
    grasp_vertex_ = static_cast<int>(std::lround(g.s / l));
    Require(grasp_vertex_ >= 1, "grasp s is at the clamp (nearest vertex 0)");
    grasp_position_ = g.position;
  }

  if (load_case.poke) {  // the poke's force acts on the rod like a point force at s
    const Poke& pk = *load_case.poke;
    Require(std::isfinite(pk.s) && pk.s >= 0 && pk.s <= length_ && Finite(pk.force),
            "poke s must lie in [0, length] and its force be finite");
    const double u = pk.s / l;
    const int k = std::min(static_cast<int>(std::floor(u)), n_ - 1);
    vertex_forces_.col(k) += (1.0 - (u - k)) * pk.force;
    vertex_forces_.col(k + 1) += (u - k) * pk.force;
    point_force_sum += pk.force.norm();
  }
  // Hessian digest over the bytes of every number Assemble's Hessian reads (see rod.h).
  uint64_t h = 1469598103934665603ULL;
  auto mix = [&h](double v) {
    unsigned char bytes[sizeof v];
    std::memcpy(bytes, &v, sizeof v);
    for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ULL;
  };
  auto mix3 = [&mix](const Vec3& v) { mix(v[0]), mix(v[1]), mix(v[2]); };
  mix(n_);
  for (int j = 0; j < n_; ++j) mix(rest_edge_[j]), mix(voronoi_[j]);
  mix(material_.B1()), mix(material_.B2());
  mix(material_.twist_stiffness), mix(material_.stretch_stiffness);
  mix3(rod_.rest_curvature);
  mix3(clamp_p_), mix3(clamp_d3_), mix3(clamp_d1_);
  mix3(case_.tip_moment);
  for (int z = 0; z < num_spring_zones(); ++z)
    for (int i = 0; i <= n_; ++i) mix(zone_stiffness(z) * zone_length_[z][i]);
  mix(grasp_vertex_);
  hessian_digest_ = h;

  const double weight = rod.linear_density * length_ * gravity_.norm();
  force_scale_ = std::max({weight, load_case.tip_force.norm(), load_case.tip_moment.norm() / length_,
                           point_force_sum, material.B1() / (length_ * length_),
                           material.twist_stiffness / (length_ * length_)});
}

double RodModel::zone_stiffness(int z) const {
  const std::string& p = zones_[z].parameter;
  return p.empty() ? material_.spring_stiffness : material_.spring_parameters.at(p);
}

RodState RodModel::StraightState() const {
  RodState s;
  s.x.resize(3, n_ + 1);
  for (int i = 0; i <= n_; ++i) s.x.col(i) = clamp_p_ + arc_[i] * clamp_d3_;
  if (grasp_vertex_ >= 1) {
    // Lay the rod straight from the clamp to the grasp, then on in the same direction. The
    // first edge keeps the clamp tangent's side so the clamp turn is below pi.
    const int k = grasp_vertex_;
    Vec3 dir = grasp_position_ - clamp_p_;
    const double reach = dir.norm();
    dir = reach > 1e-12 * length_ ? Vec3(dir / reach) : clamp_d3_;
    if (dir.dot(clamp_d3_) < -0.9) dir = (dir + 0.5 * clamp_d1_).normalized();
    for (int i = 1; i <= k; ++i) s.x.col(i) = clamp_p_ + (grasp_position_ - clamp_p_) * (double(i) / k);
    if (reach <= 1e-12 * length_)  // grasp at the clamp position: a small loop start
      for (int i = 1; i < k; ++i) s.x.col(i) = clamp_p_ + arc_[i] * 1e-3 * clamp_d3_;
    for (int i = k + 1; i <= n_; ++i) s.x.col(i) = s.x.col(k) + (arc_[i] - arc_[k]) * dir;
  }
  s.theta.setZero(n_);
  s.ref_u.resize(3, n_);
  s.ref_t.resize(3, n_);
  for (int j = 0; j < n_; ++j) {
    // Reference frames: the clamp frame transported onto each edge's tangent.
    const Vec3 t = (s.x.col(j + 1) - s.x.col(j)).normalized();
    s.ref_t.col(j) = t;
    s.ref_u.col(j) = ParallelTransport<double, double>(clamp_d3_, t, clamp_d1_).normalized();
  }
  s.ref_twist.setZero(n_);
  for (int i = 0; i < n_; ++i) {  // zero on a straight rod; the grasp's kink may twist
    const Vec3 te = i == 0 ? clamp_d3_ : Vec3(s.ref_t.col(i - 1));
    const Vec3 ue = i == 0 ? clamp_d1_ : Vec3(s.ref_u.col(i - 1));
    const Vec3 tf = s.ref_t.col(i), uf = s.ref_u.col(i);
    s.ref_twist[i] = SignedAngle<double>(ParallelTransport<double, double>(te, tf, ue), uf, tf);
  }
  return s;
}

EdgeFrame RodModel::MaterialFrame(const RodState& state, int j) const {
  EdgeFrame f;
  f.d3 = (state.x.col(j + 1) - state.x.col(j)).normalized();
  const Vec3 t_old = state.ref_t.col(j);
  const Vec3 u_old = state.ref_u.col(j);
  const Vec3 u = ParallelTransport<double, double>(t_old, f.d3, u_old).normalized();
  const Vec3 v = f.d3.cross(u);
  const double c = std::cos(state.theta[j]), s = std::sin(state.theta[j]);
  f.d1 = c * u + s * v;
  f.d2 = -s * u + c * v;
  return f;
}

}  // namespace rodfit
