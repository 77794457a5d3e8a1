// A synthetic motion-capture sequence of the form the held-out lab data has: a 1 m cable held
// at both ends by two grippers that move it, 12 markers at 100 Hz, with noise and dropped
// samples (the rollout and motion-fit tests, and bench_fit).
#pragma once

#include <cmath>
#include <cstdlib>
#include <random>
#include <stdexcept>
#include <vector>

#include "rodfit/solve/case_dynamics.h"
#include "rodfit/solve/rollout.h"

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

// The true grippers of Recording: the clamp's and the end clamp's drives (position, tangent,
// normal; the tangent not normalised), sampled every 10 ms.
inline std::vector<DrivenPoint> GentleGrippers(double seconds) {
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
  return {left, right};
}

// The truth: both grippers (clamps at s = 0 and s = L) moved along smooth paths for `seconds`;
// the markers are vertices (every 4th of 44 edges), sampled at 100 Hz with noise and drops.
inline std::vector<Eigen::Matrix3Xd> Recording(double seconds, double noise, double drop, unsigned seed,
                                                const Material* material = nullptr,
                                                const RodSpec* rod = nullptr) {
  Scene s = Cable();
  if (material) s.material = *material;
  if (rod) s.rod = *rod;  // e.g. curved at rest
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
  c.drives = GentleGrippers(seconds);
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

// Hard recordings (the rollout's corpus: issue "rollouts that never abort"): the cable of
// Cable() between two grippers moved the way that broke fixed-step rollouts of real data.
//  - kWhip: one gripper shaken at 4 Hz with 6 cm amplitude (1.5 m/s at the gripper; the free
//    markers whip at up to ~3 m/s);
//  - kPull: the grippers pulled apart from 0.5 m to 0.97 m of the cable's 1 m, nearly straight;
//  - kLoop: the grippers brought to 0.12 m apart over 1.5 s, the cable hanging in a loop, the
//    clamp turned to and fro;
//  - kFold: over 1.5 s the end gripper comes to 0.1 m from the clamp and turns to face it, the
//    cable folded back on itself.
// The truth is integrated with adaptive steps to a tight local error (1e-6 m); markers every 4th
// vertex at 100 Hz, with noise and drops as Recording's. `material` and `rod` (when given) replace
// the cable's (e.g. curved at rest: the synthetic benchmark of tests/bench/bench_rest_shape.cc).
enum class HardMotion { kWhip, kPull, kLoop, kFold };

inline const char* HardMotionName(HardMotion m) {
  switch (m) {
    case HardMotion::kWhip: return "whip";
    case HardMotion::kPull: return "pull";
    case HardMotion::kLoop: return "loop";
    case HardMotion::kFold: return "fold";
  }
  return "?";
}

// The true grippers of HardRecording: the clamp's and the end clamp's drives (position,
// tangent, normal; the tangent not normalised), sampled every millisecond.
inline std::vector<DrivenPoint> HardGrippers(HardMotion motion, double seconds) {
  DrivenPoint left, right;
  left.point = "clamp";
  right.point = "end_clamp";
  // Smooth start and stop: the grippers' motion ramps in over the first 0.2 s.
  auto ramp = [](double t) {
    const double r = std::min(1.0, t / 0.2);
    return r * r * (3.0 - 2.0 * r);
  };
  // The paths sampled every millisecond (they are interpolated linearly in time).
  for (int k = 0; k <= std::lround(seconds / 1e-3); ++k) {
    const double t = k * 1e-3, r = ramp(t);
    Vec3 a0, b0 = Vec3(1, 0, 0), a1, b1 = Vec3(1, 0, 0);
    switch (motion) {
      case HardMotion::kWhip:
        a0 = Vec3(0, 0.06 * r * std::sin(2 * M_PI * 4.0 * t), 0.03 * r * std::sin(2 * M_PI * 3.0 * t));
        b0 = Vec3(1, 0.4 * r * std::sin(2 * M_PI * 4.0 * t + 0.5), 0);
        a1 = Vec3(0.7, 0, 0);
        break;
      case HardMotion::kPull: {
        const double gap = 0.5 + 0.47 * std::min(1.0, t / std::max(seconds - 0.1, 0.1));
        a0 = Vec3(0, 0, 0);
        a1 = Vec3(gap, 0.02 * std::sin(3.0 * t), 0);
        break;
      }
      case HardMotion::kLoop: {
        // The gap closes over 1.5 s (at most ~0.6 m/s), then the clamp turns to and fro.
        const double closing = std::min(1.0, t / 1.5), c2 = closing * closing * (3.0 - 2.0 * closing);
        const double gap = 0.7 - 0.58 * c2;
        a0 = Vec3(0, 0, 0);
        a1 = Vec3(gap, 0, 0);
        b0 = Vec3(std::cos(0.8 * r * std::sin(2.0 * t)), std::sin(0.8 * r * std::sin(2.0 * t)), 0);
        break;
      }
      case HardMotion::kFold: {
        // Over 1.5 s the end gripper comes to 0.1 m from the clamp and turns to face it.
        const double closing = std::min(1.0, t / 1.5), c2 = closing * closing * (3.0 - 2.0 * closing);
        a0 = Vec3(0, 0, 0);
        a1 = Vec3(0.1 + 0.6 * (1.0 - c2), 0.05 * r * std::sin(4.0 * t), 0);
        b1 = Vec3(std::cos(M_PI * c2), std::sin(M_PI * c2), 0);
        break;
      }
    }
    left.path.t.push_back(t);
    left.path.a.push_back(a0);
    left.path.b.push_back(b0);
    left.path.c.push_back(Vec3(0, 0, 1));
    right.path.t.push_back(t);
    right.path.a.push_back(a1);
    right.path.b.push_back(b1);
    right.path.c.push_back(Vec3(0, 0, 1));
  }
  return {left, right};
}

inline std::vector<Eigen::Matrix3Xd> HardRecording(HardMotion motion, double seconds, double noise,
                                                   double drop, unsigned seed,
                                                   const Material* material = nullptr,
                                                   const RodSpec* rod = nullptr) {
  Scene s = Cable();
  if (material) s.material = *material;
  if (rod) s.rod = *rod;
  // Twist damped with bending's retardation time (DefaultTwistDamping, as `rodfit rollout`
  // does): undamped, the edges' fast twist mode, once a step resolves it, grows until Newton
  // fails (the whip at 2 ms and 0.5 ms steps: at t = 0.12-0.15 s).
  DefaultTwistDamping(&s.material);
  s.dynamics->time_step = kFrameInterval;
  s.dynamics->error_tolerance = 1e-6;
  s.dynamics->min_time_step = 1e-8;
  s.dynamics->duration = seconds;
  s.dynamics->output_every = static_cast<int>(std::lround(kFrameInterval / s.dynamics->time_step));
  LoadCase c;
  c.name = HardMotionName(motion);
  const std::vector<DrivenPoint> grippers = HardGrippers(motion, seconds);
  const DrivenPoint &left = grippers[0], &right = grippers[1];
  c.clamp.position = left.path.a.front();
  c.clamp.tangent = left.path.b.front();
  c.clamp.normal = Vec3(0, 0, 1);
  EndClamp end;
  end.position = right.path.a.front();
  end.tangent = right.path.b.front();
  end.normal = Vec3(0, 0, 1);
  c.end_clamp = end;
  c.drives = {left, right};
  s.cases = {c};
  const CaseTrajectory truth = SimulateCaseDynamics(s, 0, StaticsOptions());
  if (!truth.ok)
    throw std::runtime_error(std::string("the ") + HardMotionName(motion) +
                             " recording did not integrate: " + truth.reason);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);  // scaled by `noise` below
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Eigen::Matrix3Xd> frames;
  for (const TrajectoryFrame& f : truth.frames) {
    Eigen::Matrix3Xd m(3, kMarkers);
    for (int k = 0; k < kMarkers; ++k) {
      m.col(k) = f.x.col(4 * k);
      if (noise > 0.0) m.col(k) += noise * Vec3(gauss(rng), gauss(rng), gauss(rng));
      if (frames.size() >= 2 && uniform(rng) < drop) m.col(k).setConstant(std::nan(""));
    }
    frames.push_back(m);
  }
  return frames;
}

// A gripper's frame [d1 d2 d3] at time t from its drive (the samples linear in time, as the
// engine interpolates them; d3 the tangent, d1 the normal made perpendicular).
inline Eigen::Matrix3d GripperFrameAt(const DrivenPoint& d, double t) {
  const TimeSeries& p = d.path;
  size_t j = 0;
  while (j + 1 < p.t.size() && p.t[j + 1] <= t) ++j;
  Vec3 b = p.b[j], c = p.c[j];
  if (j + 1 < p.t.size() && t > p.t[j]) {
    const double w = (t - p.t[j]) / (p.t[j + 1] - p.t[j]);
    b = (1 - w) * p.b[j] + w * p.b[j + 1];
    c = (1 - w) * p.c[j] + w * p.c[j + 1];
  }
  const Vec3 d3 = b.normalized(), d1 = (c - c.dot(d3) * d3).normalized();
  Eigen::Matrix3d F;
  F << d1, d3.cross(d1), d3;
  return F;
}

// The second truth of the grippers (issue 35): their jaws span markers 0..1 and n-2..n-1, the
// cable straight and rigid in them (the discrete-elastic-rod convention of prescribing an end's
// first two vertices), leaving each jaw at marker 1 (n-2) along the gripper's tangent. Made by
// the engine as the cable between markers 1 and n-2 (the rod's rest shape on that stretch),
// clamped at the jaws' inner edges, a marker gap h = L / 11 inside each gripper's point (the
// drives `grippers`, e.g. HardGrippers) along its tangent; markers 0 and n-1 on the jaws'
// straight stretches, markers 1..n-2 every 4th vertex. Adaptive steps to 1e-6 m as
// HardRecording; noise and drops as Recording's.
inline std::vector<Eigen::Matrix3Xd> JawsRecording(const std::vector<DrivenPoint>& grippers,
                                                   double seconds, double noise, double drop,
                                                   unsigned seed, const Material* material = nullptr,
                                                   const RodSpec* rod = nullptr) {
  Scene s = Cable();
  if (material) s.material = *material;
  if (rod) s.rod = *rod;
  DefaultTwistDamping(&s.material);
  const double L = s.rod.length, h = L / (kMarkers - 1);
  s.rod.length = L - 2 * h;
  s.rod.segments = 4 * (kMarkers - 3);
  s.rod.vertex_s.clear();
  for (double& k : s.rod.rest_curvature_s) k -= h;  // the same rest shape along the cable
  s.dynamics->time_step = kFrameInterval;
  s.dynamics->error_tolerance = 1e-6;
  s.dynamics->min_time_step = 1e-8;
  s.dynamics->duration = seconds;
  s.dynamics->output_every = 1;
  std::vector<DrivenPoint> jaws = grippers;
  for (int g = 0; g < 2; ++g)
    for (size_t k = 0; k < jaws[g].path.t.size(); ++k)
      jaws[g].path.a[k] += (g == 0 ? h : -h) * jaws[g].path.b[k].normalized();
  LoadCase c;
  c.name = "jaws";
  c.clamp.position = jaws[0].path.a.front();
  c.clamp.tangent = jaws[0].path.b.front();
  c.clamp.normal = jaws[0].path.c.front();
  EndClamp end;
  end.position = jaws[1].path.a.front();
  end.tangent = jaws[1].path.b.front();
  end.normal = jaws[1].path.c.front();
  c.end_clamp = end;
  c.drives = jaws;
  s.cases = {c};
  const CaseTrajectory truth = SimulateCaseDynamics(s, 0, StaticsOptions());
  if (!truth.ok) throw std::runtime_error("the jaws recording did not integrate: " + truth.reason);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);  // scaled by `noise` below
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Eigen::Matrix3Xd> frames;
  for (size_t f = 0; f < truth.frames.size(); ++f) {
    const Eigen::Matrix3Xd& x = truth.frames[f].x;
    const double t = f * kFrameInterval;
    Eigen::Matrix3Xd m(3, kMarkers);
    m.col(0) = x.col(0) - h * GripperFrameAt(jaws[0], t).col(2);
    for (int k = 1; k < kMarkers - 1; ++k) m.col(k) = x.col(4 * (k - 1));
    m.col(kMarkers - 1) = x.col(x.cols() - 1) + h * GripperFrameAt(jaws[1], t).col(2);
    for (int k = 0; k < kMarkers; ++k) {
      if (noise > 0.0) m.col(k) += noise * Vec3(gauss(rng), gauss(rng), gauss(rng));
      if (frames.size() >= 2 && uniform(rng) < drop) m.col(k).setConstant(std::nan(""));
    }
    frames.push_back(m);
  }
  return frames;
}

}  // namespace rodfit::testing
