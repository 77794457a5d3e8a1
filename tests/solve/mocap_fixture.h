// A synthetic motion-capture sequence of the form the held-out lab data has: a 1 m cable held
// at both ends by two grippers that move it, 12 markers at 100 Hz, with noise and dropped
// samples (the rollout and motion-fit tests, and bench_fit).
#pragma once

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "rodfit/solve/case_dynamics.h"

namespace rodfit::testing {

constexpr int kMarkers = 12;
constexpr double kFrameInterval = 0.01;  // [s], 100 Hz

inline Scene Cable() {
  Scene s;
  s.rod.length = 1.0;
  s.rod.segments = 44;
  s.rod.radius = 2.5e-3;
  s.rod.linear_density = 0.04;
  s.material.bend_stiffness = 2e-3;
  s.material.twist_stiffness = 1.5e-3;
  s.material.stretch_stiffness = 2e4;
  s.material.damping = 0.05;
  s.material.bend_damping = 2e-5;
  s.gravity = Vec3(0, 0, -9.81);
  DynamicsSpec d;
  d.time_step = 2e-3;
  d.integrator = "bdf2";
  s.dynamics = d;
  return s;
}

// The truth: both grippers (clamps at s = 0 and s = L) moved along smooth paths for `seconds`;
// the markers are vertices (every 4th of 44 edges), sampled at 100 Hz with noise and drops.
inline std::vector<Eigen::Matrix3Xd> Recording(double seconds, double noise, double drop, unsigned seed,
                                                const Material* material = nullptr) {
  Scene s = Cable();
  if (material) s.material = *material;
  const int steps_per_frame = static_cast<int>(std::lround(kFrameInterval / s.dynamics->time_step));
  s.dynamics->duration = seconds;
  s.dynamics->output_every = steps_per_frame;
  LoadCase c;
  c.name = "truth";
  c.clamp.tangent = Vec3(1, 0, 0);
  c.clamp.normal = Vec3(0, 0, 1);
  EndClamp end;
  end.position = Vec3(0.7, 0, 0);
  end.tangent = Vec3(1, 0, 0);
  end.normal = Vec3(0, 0, 1);
  c.end_clamp = end;
  DrivenPoint left, right;
  left.point = "clamp";
  right.point = "end_clamp";
  for (int k = 0; k <= 100 * seconds; ++k) {
    const double t = 0.01 * k;
    left.path.t.push_back(t);
    left.path.a.push_back(Vec3(0.05 * std::sin(2.0 * t), 0.08 * std::sin(1.3 * t), 0.04 * std::sin(3.1 * t)));
    left.path.b.push_back(Vec3(1, 0.2 * std::sin(1.7 * t), 0));
    left.path.c.push_back(Vec3(0, 0, 1));
    right.path.t.push_back(t);
    right.path.a.push_back(Vec3(0.7 + 0.1 * std::sin(1.5 * t), 0.15 * std::sin(2.3 * t), 0.1 * (1 - std::cos(1.9 * t))));
    right.path.b.push_back(Vec3(1, 0, 0.3 * std::sin(1.1 * t)));
    right.path.c.push_back(Vec3(0, 0, 1));
  }
  c.drives = {left, right};
  s.cases = {c};
  const CaseTrajectory truth = SimulateCaseDynamics(s, 0, StaticsOptions());
  // No test framework here: the benchmarks build recordings too.
  if (!truth.ok) throw std::runtime_error("the synthetic recording did not integrate: " + truth.reason);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Eigen::Matrix3Xd> frames;
  for (const TrajectoryFrame& f : truth.frames) {
    Eigen::Matrix3Xd m(3, kMarkers);
    for (int k = 0; k < kMarkers; ++k) {
      m.col(k) = f.x.col(4 * k) + Vec3(gauss(rng), gauss(rng), gauss(rng));
      // Drops: never in the first two frames (the start) nor on the held markers' every frame.
      if (frames.size() >= 2 && uniform(rng) < drop) m.col(k).setConstant(std::nan(""));
    }
    frames.push_back(m);
  }
  return frames;
}

}  // namespace rodfit::testing
