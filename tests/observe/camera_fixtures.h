// Shared fixtures for the camera and triangulation tests: realistic intrinsics with several
// distortion sets (none, barrel, pincushion, tangential, a typical calibrated lens) and a grid of
// world points inside the field of view of a camera at the origin looking along +z.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rodfit/observe/camera.h"

namespace rodfit::testing {

inline CameraIntrinsics Intrinsics(double k1, double k2, double p1, double p2, double k3) {
  CameraIntrinsics K;
  K.fx = 1210.5;
  K.fy = 1195.25;
  K.cx = 643.2;
  K.cy = 481.7;
  K.k1 = k1;
  K.k2 = k2;
  K.p1 = p1;
  K.p2 = p2;
  K.k3 = k3;
  K.width = 1280;
  K.height = 960;
  return K;
}

struct NamedIntrinsics {
  std::string name;
  CameraIntrinsics K;
};

inline std::vector<NamedIntrinsics> DistortionSets() {
  return {{"none", Intrinsics(0, 0, 0, 0, 0)},
          {"barrel", Intrinsics(-0.32, 0.12, 0, 0, -0.02)},
          {"pincushion", Intrinsics(0.21, 0.05, 0, 0, 0.01)},
          {"tangential", Intrinsics(0, 0, 1.5e-3, -2.2e-3, 0)},
          {"calibrated", Intrinsics(-0.271, 0.083, 3.1e-4, -1.7e-4, -0.011)}};
}

/// A camera with a non-trivial pose whose field of view holds GridPoints().
inline Camera PosedCamera(const CameraIntrinsics& K) {
  Camera cam;
  cam.K = K;
  cam.cam_from_world_R =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -1.0, 0.4).normalized()).toRotationMatrix();
  cam.cam_from_world_t = Eigen::Vector3d(0.05, -0.02, 0.1);
  return cam;
}

/// World points that PosedCamera sees at depths 0.3..0.9 m, normalised |x|, |y| <= 0.45.
inline std::vector<Eigen::Vector3d> GridPoints(const Camera& cam) {
  std::vector<Eigen::Vector3d> points;
  for (double z : {0.3, 0.6, 0.9}) {
    for (double x = -0.45; x <= 0.451; x += 0.15) {
      for (double y = -0.45; y <= 0.451; y += 0.15) {
        const Eigen::Vector3d p_cam(x * z, y * z, z);
        points.push_back(cam.cam_from_world_R.transpose() * (p_cam - cam.cam_from_world_t));
      }
    }
  }
  return points;
}

}  // namespace rodfit::testing
