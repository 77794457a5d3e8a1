// A calibrated pinhole camera with OpenCV's lens distortion (docs/formats.md, "Camera files").
// The model is exactly cv::projectPoints with the five coefficients (k1, k2, p1, p2, k3):
// x_cam = R x_world + t, (x, y) = (X/Z, Y/Z), r2 = x^2 + y^2,
// x'' = x (1 + k1 r2 + k2 r2^2 + k3 r2^3) + 2 p1 x y + p2 (r2 + 2 x^2),
// y'' = y (1 + k1 r2 + k2 r2^2 + k3 r2^3) + p1 (r2 + 2 y^2) + 2 p2 x y,
// u = fx x'' + cx, v = fy y'' + cy. Pixel (0, 0) is the centre of the top-left pixel. The
// projection is templated so that ceres::Jet passes through the point (the camera's own
// parameters stay double); the double overload adds an analytic Jacobian, and PixelRay inverts
// the model (Newton on the distortion) for triangulation.
#pragma once

#include <string>

#include <Eigen/Core>

namespace rodfit {

using Mat23 = Eigen::Matrix<double, 2, 3>;

/// Points with a camera depth Z at or below this are rejected by Project [m].
constexpr double kMinProjectionDepth = 1e-9;

/// OpenCV intrinsics: focal lengths and principal point [px], distortion (dimensionless).
struct CameraIntrinsics {
  double fx = 1.0, fy = 1.0, cx = 0.0, cy = 0.0;      ///< [px]
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0, k3 = 0.0;
  int width = 0, height = 0;                            ///< image size [px]
};

/// A camera: intrinsics and the world-to-camera pose x_cam = R x_world + t.
/// Camera axes follow OpenCV: x right, y down, z along the optical axis.
struct Camera {
  CameraIntrinsics K;
  Eigen::Matrix3d cam_from_world_R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d cam_from_world_t = Eigen::Vector3d::Zero();  ///< [m]
  std::string name;

  /// Optical centre in world coordinates, -R^T t [m].
  Eigen::Vector3d CentreWorld() const;
  /// True when uv lies on the sensor: -0.5 <= u < width - 0.5 and likewise v (pixel centres at
  /// integers), shrunk by margin [px] on each side.
  bool InImage(const Eigen::Vector2d& uv, double margin_px = 0.0) const;
  /// False with the reason when the camera cannot be used (non-positive focal length or image
  /// size, non-finite values, R not a rotation).
  bool Check(std::string* why) const;
};

/// Applies the distortion to normalised image coordinates (x, y) -> (x'', y'').
template <typename T>
void DistortNormalized(const CameraIntrinsics& K, const T& x, const T& y, T* xd, T* yd) {
  const T r2 = x * x + y * y;
  const T radial = T(1.0) + r2 * (T(K.k1) + r2 * (T(K.k2) + r2 * T(K.k3)));
  const T two_xy = T(2.0) * x * y;
  *xd = x * radial + T(K.p1) * two_xy + T(K.p2) * (r2 + T(2.0) * x * x);
  *yd = y * radial + T(K.p1) * (r2 + T(2.0) * y * y) + T(K.p2) * two_xy;
}

/// Projects a world point to pixels. Returns false (uv untouched) for a point at or behind the
/// camera (Z <= kMinProjectionDepth) or a non-finite depth; otherwise the same as
/// cv::projectPoints, including for points outside the image.
template <typename T>
bool Project(const Camera& camera, const Eigen::Matrix<T, 3, 1>& p_world,
             Eigen::Matrix<T, 2, 1>* uv) {
  const Eigen::Matrix<T, 3, 1> p_cam =
      camera.cam_from_world_R.cast<T>() * p_world + camera.cam_from_world_t.cast<T>();
  // Written as !(z > eps) so that a NaN depth is rejected too.
  if (!(p_cam.z() > T(kMinProjectionDepth))) return false;
  const T x = p_cam.x() / p_cam.z();
  const T y = p_cam.y() / p_cam.z();
  T xd, yd;
  DistortNormalized(camera.K, x, y, &xd, &yd);
  (*uv)(0) = T(camera.K.fx) * xd + T(camera.K.cx);
  (*uv)(1) = T(camera.K.fy) * yd + T(camera.K.cy);
  return true;
}

/// Double overload with the analytic Jacobian d uv / d p_world [px/m] (optional).
bool Project(const Camera& camera, const Eigen::Vector3d& p_world, Eigen::Vector2d* uv,
             Mat23* d_uv_d_p = nullptr);

/// d(x'', y'') / d(x, y) of DistortNormalized at (x, y).
Eigen::Matrix2d DistortionJacobian(const CameraIntrinsics& K, double x, double y);

/// Inverts pixel -> normalised coordinates (x, y) = (X/Z, Y/Z) by damped Newton on the
/// distortion (at most 20 iterations, started at the distorted coordinates). On success the
/// residual |distort(x, y) - (x'', y'')| is below 1e-13 in normalised units (about 1e-10 px
/// at f = 1000 px); returns false when it does not converge or lands beyond the fold of the
/// distortion polynomial (det of the distortion Jacobian <= 0), where the model has no unique
/// inverse.
bool UndistortPixel(const CameraIntrinsics& K, const Eigen::Vector2d& uv,
                    Eigen::Vector2d* xy_normalized);

/// The back-projected ray of a pixel: origin the optical centre, unit direction in world
/// coordinates (pointing in front of the camera). Accuracy as UndistortPixel.
struct Ray {
  Eigen::Vector3d origin_world;
  Eigen::Vector3d direction_world;
};
bool PixelRay(const Camera& camera, const Eigen::Vector2d& uv, Ray* ray);

/// A camera at centre_world whose optical axis points at target_world, with the image's "up"
/// (-y) as close to up_world as possible. For synthetic scenes and tests; throws
/// std::invalid_argument when the axis is (nearly) parallel to up_world or has zero length.
Camera CameraLookingAt(const CameraIntrinsics& K, const Eigen::Vector3d& centre_world,
                       const Eigen::Vector3d& target_world, const Eigen::Vector3d& up_world);

}  // namespace rodfit
