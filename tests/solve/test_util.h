// Shared builders for solver tests and benchmarks: a clamped cantilever along x with EI = 1,
// L = 1, and the benchmark suture.
#pragma once

#include <cmath>

#include "rodfit/model/rod.h"

namespace rodfit::testing {

/// A nearly inextensible cantilever (EA L^2 / EI = 1e6, docs/model.md, "Validation", asks >= 1e5),
/// clamped at the origin along +x with d1 = +z, massless unless `density` is given.
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

/// A heavy, anisotropic, bent and twisted 3-D cantilever (40 segments) with a sideways tip
/// force: the warm-start and chord-step tests' scene.
inline Scene HeavyCantilever() {
  Scene s = Cantilever(40, /*density=*/2.0);
  s.gravity = Vec3(0, 0, -9.81);
  s.material.bend_stiffness_2 = 1.4;
  s.cases[0].clamp.tangent = Vec3(std::cos(0.4), 0, std::sin(0.4));
  s.cases[0].tip_force = Vec3(0, 3.0, 0);
  return s;
}

/// The statics benchmark's suture (tests/bench/bench_statics.cc): nylon, L = 0.2 m,
/// EA L^2 / EI ~ 1e7, clamped 0.5 rad above horizontal, sagging with a sideways tip force.
inline Scene BenchmarkSuture(int segments) {
  Scene s;
  s.rod.length = 0.2;
  s.rod.segments = segments;
  s.rod.radius = 1.25e-4;
  s.rod.linear_density = 5.6e-5;
  s.material.bend_stiffness = 1.0e-6;
  s.material.bend_stiffness_2 = 1.5e-6;
  s.material.twist_stiffness = 8.0e-7;
  s.material.stretch_stiffness = 245.0;
  s.gravity = Vec3(0, 0, -9.81);
  LoadCase c;
  c.name = "heavy";
  c.clamp.tangent = Vec3(std::cos(0.5), 0, std::sin(0.5));
  c.clamp.normal = Vec3(0, 1, 0);
  c.tip_force = Vec3(0, 3e-5, 0);
  s.cases.push_back(c);
  return s;
}

inline RodModel ModelOf(const Scene& s, int k = 0) {
  return RodModel(s.rod, s.material, s.gravity, s.cases[k]);
}

}  // namespace rodfit::testing
