// The non-template parts of the OpenCV pinhole + distortion camera (camera.h): the analytic
// projection Jacobian, the Newton inversion of the distortion and the back-projected ray.
#include "rodfit/observe/camera.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <Eigen/LU>

namespace rodfit {

Eigen::Vector3d Camera::CentreWorld() const {
  return -cam_from_world_R.transpose() * cam_from_world_t;
}

bool Camera::InImage(const Eigen::Vector2d& uv, double margin_px) const {
  return uv.x() >= -0.5 + margin_px && uv.x() < K.width - 0.5 - margin_px &&
         uv.y() >= -0.5 + margin_px && uv.y() < K.height - 0.5 - margin_px;
}

bool Camera::Check(std::string* why) const {
  std::ostringstream out;
  const double values[] = {K.fx, K.fy, K.cx, K.cy, K.k1, K.k2, K.p1, K.p2, K.k3};
  bool finite = cam_from_world_R.allFinite() && cam_from_world_t.allFinite();
  for (double v : values) finite = finite && std::isfinite(v);
  if (!finite) {
    out << "non-finite intrinsics or pose";
  } else if (!(K.fx > 0.0 && K.fy > 0.0)) {
    out << "focal length must be positive (fx " << K.fx << ", fy " << K.fy << ")";
  } else if (K.width <= 0 || K.height <= 0) {
    out << "image size must be positive (" << K.width << " x " << K.height << ")";
  } else if ((cam_from_world_R.transpose() * cam_from_world_R -
              Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
             cam_from_world_R.determinant() < 0.0) {
    out << "cam_from_world_R is not a rotation";
  } else {
    return true;
  }
  if (why) *why = out.str();
  return false;
}

Eigen::Matrix2d DistortionJacobian(const CameraIntrinsics& K, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (K.k1 + r2 * (K.k2 + r2 * K.k3));
  const double d_radial_d_r2 = K.k1 + r2 * (2.0 * K.k2 + 3.0 * r2 * K.k3);
  // d r2 / dx = 2x; the cross term is symmetric.
  const double off = 2.0 * x * y * d_radial_d_r2 + 2.0 * K.p1 * x + 2.0 * K.p2 * y;
  Eigen::Matrix2d J;
  J << radial + 2.0 * x * x * d_radial_d_r2 + 2.0 * K.p1 * y + 6.0 * K.p2 * x, off,
      off, radial + 2.0 * y * y * d_radial_d_r2 + 6.0 * K.p1 * y + 2.0 * K.p2 * x;
  return J;
}

bool Project(const Camera& camera, const Eigen::Vector3d& p_world, Eigen::Vector2d* uv,
             Mat23* d_uv_d_p) {
  if (!Project<double>(camera, p_world, uv)) return false;
  if (d_uv_d_p) {
    const Eigen::Vector3d p_cam = camera.cam_from_world_R * p_world + camera.cam_from_world_t;
    const double inv_z = 1.0 / p_cam.z();
    const double x = p_cam.x() * inv_z, y = p_cam.y() * inv_z;
    Mat23 d_xy_d_pcam;
    d_xy_d_pcam << inv_z, 0.0, -x * inv_z, 0.0, inv_z, -y * inv_z;
    const Eigen::Vector2d focal(camera.K.fx, camera.K.fy);
    *d_uv_d_p = focal.asDiagonal() * DistortionJacobian(camera.K, x, y) * d_xy_d_pcam *
                camera.cam_from_world_R;
  }
  return true;
}

bool UndistortPixel(const CameraIntrinsics& K, const Eigen::Vector2d& uv,
                    Eigen::Vector2d* xy_normalized) {
  constexpr int kMaxIterations = 20;
  constexpr double kTolerance = 1e-13;  // normalised units, ~1e-10 px at f = 1000 px
  const Eigen::Vector2d target((uv.x() - K.cx) / K.fx, (uv.y() - K.cy) / K.fy);
  if (!target.allFinite()) return false;
  auto residual = [&](const Eigen::Vector2d& xy) {
    Eigen::Vector2d d;
    DistortNormalized(K, xy.x(), xy.y(), &d.x(), &d.y());
    return Eigen::Vector2d(d - target);
  };
  Eigen::Vector2d xy = target;  // exact without distortion, close for mild distortion
  Eigen::Vector2d r = residual(xy);
  for (int it = 0; it < kMaxIterations && r.norm() >= kTolerance; ++it) {
    const Eigen::Matrix2d J = DistortionJacobian(K, xy.x(), xy.y());
    if (!(std::abs(J.determinant()) > 1e-12)) return false;
    const Eigen::Vector2d step = J.inverse() * r;
    // Halve the step until the residual falls: strong barrel distortion folds the map, and a
    // full Newton step from far away can jump across the fold.
    double scale = 1.0;
    Eigen::Vector2d trial = xy - step, r_trial = residual(trial);
    for (int h = 0; h < 10 && !(r_trial.norm() < r.norm()); ++h) {
      scale *= 0.5;
      trial = xy - scale * step;
      r_trial = residual(trial);
    }
    if (!(r_trial.norm() < r.norm())) return false;
    xy = trial;
    r = r_trial;
  }
  if (!(r.norm() < kTolerance)) return false;
  if (!(DistortionJacobian(K, xy.x(), xy.y()).determinant() > 0.0)) return false;
  *xy_normalized = xy;
  return true;
}

bool PixelRay(const Camera& camera, const Eigen::Vector2d& uv, Ray* ray) {
  Eigen::Vector2d xy;
  if (!UndistortPixel(camera.K, uv, &xy)) return false;
  ray->origin_world = camera.CentreWorld();
  ray->direction_world =
      (camera.cam_from_world_R.transpose() * Eigen::Vector3d(xy.x(), xy.y(), 1.0)).normalized();
  return true;
}

Camera CameraLookingAt(const CameraIntrinsics& K, const Eigen::Vector3d& centre_world,
                       const Eigen::Vector3d& target_world, const Eigen::Vector3d& up_world) {
  const Eigen::Vector3d axis = target_world - centre_world;
  const Eigen::Vector3d right = axis.cross(up_world);
  if (!(axis.norm() > 0.0) || !(right.norm() > 1e-9 * axis.norm() * up_world.norm())) {
    throw std::invalid_argument(
        "CameraLookingAt: target == centre or optical axis parallel to up_world");
  }
  const Eigen::Vector3d z = axis.normalized();
  const Eigen::Vector3d x = right.normalized();
  const Eigen::Vector3d y = z.cross(x);  // image down, opposite to up_world
  Camera camera;
  camera.K = K;
  camera.cam_from_world_R.row(0) = x.transpose();
  camera.cam_from_world_R.row(1) = y.transpose();
  camera.cam_from_world_R.row(2) = z.transpose();
  camera.cam_from_world_t = -camera.cam_from_world_R * centre_world;
  return camera;
}

}  // namespace rodfit
