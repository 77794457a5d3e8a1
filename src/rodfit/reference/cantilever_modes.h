// The free vibration of a cantilever, shared by the dynamics tests, `bench_dynamics` and
// `rodfit bench` (internal, header-only): the nylon suture of data/scenes/cantilever.yaml
// (L 0.2 m, r 0.125 mm, E 5 GPa) clamped along x without gravity or damping, the
// Euler–Bernoulli frequencies and mode shapes of a clamped–free beam, and a rod bent into one.
// Source of beta_n L: the roots of 1 + cos(x) cosh(x) = 0 (S. Timoshenko, "Vibration Problems
// in Engineering", clamped–free beam).
#pragma once

#include <cmath>

#include "rodfit/model/rod.h"
#include "rodfit/model/scene.h"
#include "rodfit/solve/rod_energy.h"

namespace rodfit::reference {

/// beta_n L of a cantilever's first three bending modes.
inline constexpr double kCantileverBetaL[3] = {1.875104, 4.694091, 7.854757};

/// Mode shape `mode` (0, 1, 2) at xi = s / L, unit-free (1 - cos... form, zero at the clamp).
inline double CantileverModeShape(int mode, double xi) {
  const double bl = kCantileverBetaL[mode];
  const double sigma = (std::cosh(bl) + std::cos(bl)) / (std::sinh(bl) + std::sin(bl));
  const double b = bl * xi;
  return std::cosh(b) - std::cos(b) - sigma * (std::sinh(b) - std::sin(b));
}

/// The suture with `segments` edges; Omega(n): the Euler–Bernoulli angular frequency of mode n
/// [rad/s].
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
    const double bl = kCantileverBetaL[mode];
    return bl * bl * std::sqrt(material.B1() / (rod.linear_density * std::pow(rod.length, 4)));
  }
};

/// The rod of `model` (clamped along x) bent into mode `mode` with a tip deflection of about
/// `amplitude` [m] in z: each edge keeps its rest length and turns about y to the slope of
/// amplitude * shape, an unstretched state that does not excite the stretch modes. False when
/// the reference frames cannot be carried to it.
inline bool CantileverModeState(const RodModel& model, int mode, double amplitude, RodState* q) {
  *q = model.StraightState();
  const RodState straight = *q;
  const double L = model.length();
  for (int j = 0; j < model.num_edges(); ++j) {
    const double xi = 0.5 * (model.arc_length(j) + model.arc_length(j + 1)) / L;
    const double h = 1e-6;
    const double slope = amplitude *
                         (CantileverModeShape(mode, xi + h) - CantileverModeShape(mode, xi - h)) /
                         (2.0 * h * L);
    const double angle = std::atan(slope);
    q->e.col(j) = model.rest_edge_length(j) * Vec3(std::cos(angle), 0.0, std::sin(angle));
  }
  q->SyncVertices();
  return UpdateReferenceFrames(model, straight, q);
}

}  // namespace rodfit::reference
