// Shared builders for solver tests: a clamped cantilever along x with EI = 1, L = 1.
#pragma once

#include "rodfit/model/rod.h"

namespace rodfit::testing {

/// A nearly inextensible cantilever (EA L^2 / EI = 1e6, DESIGN.md §7 asks >= 1e5), clamped at
/// the origin along +x with d1 = +z, massless unless `density` is given.
inline Scene Cantilever(int segments, double density = 0.0) {
  Scene s;
  s.rod.length = 1.0;
  s.rod.segments = segments;
  s.rod.radius = 0.01;
  s.rod.linear_density = density;
  s.material.bend_stiffness = 1.0;
  s.material.twist_stiffness = 1.0 / 1.3;
  s.material.stretch_stiffness = 1e6;
  s.gravity = Vec3::Zero();
  LoadCase c;
  c.name = "c";
  c.clamp.position = Vec3::Zero();
  c.clamp.tangent = Vec3::UnitX();
  c.clamp.normal = Vec3::UnitZ();
  s.cases.push_back(c);
  return s;
}

inline RodModel ModelOf(const Scene& s, int k = 0) {
  return RodModel(s.rod, s.material, s.gravity, s.cases[k]);
}

}  // namespace rodfit::testing
