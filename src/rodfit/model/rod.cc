// RodModel: validation, rest geometry, lumped loads and the straight start state (rod.h).
#include "rodfit/model/rod.h"

#include <algorithm>
#include <cmath>
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
                   const LoadCase& load_case)
    : rod_(rod), material_(material), case_(load_case), gravity_(gravity) {
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
  const double weight = rod.linear_density * length_ * gravity_.norm();
  force_scale_ = std::max({weight, load_case.tip_force.norm(), load_case.tip_moment.norm() / length_,
                           point_force_sum, material.B1() / (length_ * length_),
                           material.twist_stiffness / (length_ * length_)});
}

RodState RodModel::StraightState() const {
  RodState s;
  s.x.resize(3, n_ + 1);
  for (int i = 0; i <= n_; ++i) s.x.col(i) = clamp_p_ + arc_[i] * clamp_d3_;
  s.theta.setZero(n_);
  s.ref_u.resize(3, n_);
  s.ref_t.resize(3, n_);
  for (int j = 0; j < n_; ++j) {
    s.ref_u.col(j) = clamp_d1_;
    s.ref_t.col(j) = clamp_d3_;
  }
  s.ref_twist.setZero(n_);
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
