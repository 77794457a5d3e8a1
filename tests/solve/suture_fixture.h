// The nylon suture of data/scenes/cantilever.yaml (L 0.2 m, r 0.125 mm, E 5 GPa), clamped along
// x, without gravity or damping: the dynamics tests' and bench_dynamics' rod.
#pragma once

#include <cmath>

#include "rodfit/model/scene.h"

namespace rodfit::testing {

/// beta_n L of a cantilever's first three bending modes: the roots of 1 + cos(x) cosh(x) = 0.
inline constexpr double kBetaL[3] = {1.875104, 4.694091, 7.854757};

/// The suture with `segments` edges; Omega(n): Euler-Bernoulli angular frequency of mode n.
struct Suture {
  RodSpec rod;
  Material material;
  LoadCase load_case;
  explicit Suture(int segments) {
    rod.length = 0.2;
    rod.segments = segments;
    rod.radius = 1.25e-4;
    rod.linear_density = 5.6e-5;
    material.bend_stiffness = 9.6e-7;
    material.twist_stiffness = 8.0e-7;
    material.stretch_stiffness = 245.0;
    load_case.clamp.tangent = Vec3::UnitX();
    load_case.clamp.normal = Vec3::UnitZ();
  }
  double Omega(int mode) const {
    const double bl = kBetaL[mode];
    return bl * bl * std::sqrt(material.B1() / (rod.linear_density * std::pow(rod.length, 4)));
  }
};

}  // namespace rodfit::testing
