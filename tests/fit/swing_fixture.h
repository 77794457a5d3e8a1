// The moving scene of the sequence-fit tests: the suture of data/scenes/suture_swing.yaml on 10
// edges over 0.25 s, released straight from its horizontal clamp and swinging down under its
// weight, with a drag whose time scale (linear_density / damping = 0.28 s) is the run's, so that
// the data determine it; and a camera that sees the whole swing.
#pragma once

#include <Eigen/Core>

#include "rodfit/model/scene.h"
#include "rodfit/observe/camera.h"

namespace rodfit::testing {

inline Scene Swing() {
  Scene s;
  s.rod.length = 0.2;
  s.rod.segments = 10;
  s.rod.radius = 1.25e-4;
  s.rod.linear_density = 5.6e-5;
  s.material.bend_stiffness = 9.6e-7;  // B2 tied to it (isotropic)
  s.material.twist_stiffness = 8.0e-7;
  s.material.stretch_stiffness = 245.0;
  s.material.damping = 2.0e-4;
  DynamicsSpec d;
  d.time_step = 2.5e-3;
  d.duration = 0.25;
  d.integrator = "bdf2";
  s.dynamics = d;
  LoadCase c;
  c.name = "swing";
  c.initial.equilibrium = false;  // released straight, at rest
  s.cases = {c};
  return s;
}

/// A 1280 x 1024 camera 0.6 m in front of the swing plane (x-z, the thread's clamp at the
/// origin), looking along +y at (0.09, 0, -0.07): the thread spans about 330 px, from
/// horizontal to hanging, all on the sensor; 0.5 px is 0.3 mm there.
inline Camera SwingCamera() {
  CameraIntrinsics K;
  K.fx = K.fy = 1000.0;
  K.cx = 639.5;
  K.cy = 511.5;
  K.width = 1280;
  K.height = 1024;
  return CameraLookingAt(K, Eigen::Vector3d(0.09, -0.6, -0.07), Eigen::Vector3d(0.09, 0.0, -0.07),
                         Eigen::Vector3d(0.0, 0.0, 1.0));
}

}  // namespace rodfit::testing
