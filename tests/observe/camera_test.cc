// Tests of the OpenCV pinhole + distortion camera (observe/camera.h): Jet derivatives against
// central differences, the analytic Jacobian against Jets, rejection of points behind the camera,
// and the pixel ray (Newton undistortion) against the projection. The comparison with
// cv::projectPoints itself is in tests/vision/projection_vs_opencv_test.cc (needs OpenCV).
#include "rodfit/observe/camera.h"

#include <cmath>
#include <limits>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "camera_fixtures.h"

namespace rodfit {
namespace {

using testing::DistortionSets;
using testing::GridPoints;
using testing::PosedCamera;
using Jet3 = ceres::Jet<double, 3>;

Mat23 JetJacobian(const Camera& cam, const Eigen::Vector3d& p, Eigen::Vector2d* uv) {
  Eigen::Matrix<Jet3, 3, 1> pj;
  for (int i = 0; i < 3; ++i) pj(i) = Jet3(p(i), i);
  Eigen::Matrix<Jet3, 2, 1> uvj;
  EXPECT_TRUE(Project(cam, pj, &uvj));
  Mat23 J;
  for (int r = 0; r < 2; ++r) {
    (*uv)(r) = uvj(r).a;
    J.row(r) = uvj(r).v.transpose();
  }
  return J;
}

TEST(Camera, JetDerivativesMatchCentralDifferences) {
  // h = 1e-6 m at depths >= 0.3 m: truncation ~ h^2 |d3 uv| and rounding ~ 1e-13 px / h are
  // both far below 1e-6 of the Jacobian's scale (f / Z ~ 4000 px/m).
  const double h = 1e-6;
  for (const auto& [name, K] : DistortionSets()) {
    const Camera cam = PosedCamera(K);
    for (const Eigen::Vector3d& p : GridPoints(cam)) {
      Eigen::Vector2d uv_jet;
      const Mat23 J = JetJacobian(cam, p, &uv_jet);
      Eigen::Vector2d uv;
      ASSERT_TRUE(Project(cam, p, &uv));
      EXPECT_LT((uv - uv_jet).norm(), 1e-12) << name;
      Mat23 numeric;
      for (int i = 0; i < 3; ++i) {
        Eigen::Vector2d plus, minus;
        ASSERT_TRUE(Project(cam, Eigen::Vector3d(p + h * Eigen::Vector3d::Unit(i)), &plus));
        ASSERT_TRUE(Project(cam, Eigen::Vector3d(p - h * Eigen::Vector3d::Unit(i)), &minus));
        numeric.col(i) = (plus - minus) / (2.0 * h);
      }
      EXPECT_LT((J - numeric).norm(), 1e-6 * J.norm())
          << name << " at " << p.transpose() << "\njet\n" << J << "\nnumeric\n" << numeric;
    }
  }
}

TEST(Camera, AnalyticJacobianMatchesJet) {
  for (const auto& [name, K] : DistortionSets()) {
    const Camera cam = PosedCamera(K);
    for (const Eigen::Vector3d& p : GridPoints(cam)) {
      Eigen::Vector2d uv_jet, uv;
      const Mat23 J_jet = JetJacobian(cam, p, &uv_jet);
      Mat23 J;
      ASSERT_TRUE(Project(cam, p, &uv, &J));
      EXPECT_LT((J - J_jet).norm(), 1e-12 * J_jet.norm())
          << name << " at " << p.transpose() << "\nanalytic\n" << J << "\njet\n" << J_jet;
    }
  }
}

TEST(Camera, RejectsPointsAtOrBehindTheCamera) {
  const Camera cam = PosedCamera(DistortionSets().back().K);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double z : {0.0, 0.5 * kMinProjectionDepth, -1e-3, -0.5, nan}) {
    const Eigen::Vector3d p_cam(0.01, -0.02, z);
    const Eigen::Vector3d p = cam.cam_from_world_R.transpose() * (p_cam - cam.cam_from_world_t);
    Eigen::Vector2d uv(-7.0, -7.0);
    Mat23 J = Mat23::Constant(-7.0);
    EXPECT_FALSE(Project(cam, p, &uv, &J)) << "z = " << z;
    EXPECT_EQ(uv, Eigen::Vector2d(-7.0, -7.0)) << "uv must be untouched";
    EXPECT_EQ(J, Mat23::Constant(-7.0)) << "Jacobian must be untouched";
    Eigen::Matrix<Jet3, 3, 1> pj = p.cast<Jet3>();
    Eigen::Matrix<Jet3, 2, 1> uvj;
    EXPECT_FALSE(Project(cam, pj, &uvj)) << "z = " << z;
  }
  const Eigen::Vector3d p = cam.cam_from_world_R.transpose() *
                            (Eigen::Vector3d(0.0, 0.0, 1e-3) - cam.cam_from_world_t);
  Eigen::Vector2d uv;
  EXPECT_TRUE(Project(cam, p, &uv));
  EXPECT_NEAR(uv.x(), cam.K.cx, 1e-6);
  EXPECT_NEAR(uv.y(), cam.K.cy, 1e-6);
}

TEST(Camera, PixelRayPassesThroughTheProjectedPoint) {
  for (const auto& [name, K] : DistortionSets()) {
    const Camera cam = PosedCamera(K);
    for (const Eigen::Vector3d& p : GridPoints(cam)) {
      Eigen::Vector2d uv;
      ASSERT_TRUE(Project(cam, p, &uv));
      Ray ray;
      ASSERT_TRUE(PixelRay(cam, uv, &ray)) << name << " uv " << uv.transpose();
      EXPECT_LT((ray.origin_world - cam.CentreWorld()).norm(), 1e-15);
      EXPECT_NEAR(ray.direction_world.norm(), 1.0, 1e-15);
      const Eigen::Vector3d v = p - ray.origin_world;
      EXPECT_GT(v.dot(ray.direction_world), 0.0);
      // Distance of p from the ray: 1e-13 normalised units at depth <= 0.9 m, plus rounding.
      EXPECT_LT((v - v.dot(ray.direction_world) * ray.direction_world).norm(), 1e-12) << name;
    }
  }
}

TEST(Camera, UndistortFailsBeyondTheFoldOfStrongBarrelDistortion) {
  // With k1 = -0.5 alone, x'' = x (1 - 0.5 r^2) peaks at r = sqrt(2/3), x'' = 0.544: a pixel at
  // normalised radius 0.6 has no preimage.
  CameraIntrinsics K = testing::Intrinsics(-0.5, 0.0, 0.0, 0.0, 0.0);
  Eigen::Vector2d xy;
  EXPECT_TRUE(UndistortPixel(K, Eigen::Vector2d(K.cx + 0.5 * K.fx, K.cy), &xy));
  EXPECT_NEAR(xy.x() * (1.0 - 0.5 * xy.x() * xy.x()), 0.5, 1e-13);
  EXPECT_FALSE(UndistortPixel(K, Eigen::Vector2d(K.cx + 0.6 * K.fx, K.cy), &xy));
}

TEST(Camera, InImageUsesPixelCentresAtIntegers) {
  Camera cam;
  cam.K.width = 640;
  cam.K.height = 480;
  EXPECT_TRUE(cam.InImage({-0.5, -0.5}));
  EXPECT_TRUE(cam.InImage({639.49, 479.49}));
  EXPECT_FALSE(cam.InImage({639.5, 10.0}));
  EXPECT_FALSE(cam.InImage({10.0, -0.51}));
  EXPECT_FALSE(cam.InImage({5.0, 5.0}, 6.0));
  EXPECT_FALSE(cam.InImage({std::nan(""), 5.0}));
}

TEST(Camera, LookingAtPutsTheTargetOnTheOpticalAxisAndUpAtTheTop) {
  const Camera cam = CameraLookingAt(testing::Intrinsics(0, 0, 0, 0, 0), {0.3, -0.4, 0.2},
                                     {0.0, 0.0, 0.05}, {0, 0, 1});
  std::string why;
  EXPECT_TRUE(cam.Check(&why)) << why;
  EXPECT_LT((cam.CentreWorld() - Eigen::Vector3d(0.3, -0.4, 0.2)).norm(), 1e-15);
  Eigen::Vector2d target, above;
  ASSERT_TRUE(Project(cam, Eigen::Vector3d(0.0, 0.0, 0.05), &target));
  ASSERT_TRUE(Project(cam, Eigen::Vector3d(0.0, 0.0, 0.10), &above));
  EXPECT_NEAR(target.x(), cam.K.cx, 1e-9);
  EXPECT_NEAR(target.y(), cam.K.cy, 1e-9);
  EXPECT_LT(above.y(), target.y());
  EXPECT_THROW(CameraLookingAt(cam.K, {0, 0, 0}, {0, 0, 1}, {0, 0, 2}), std::invalid_argument);
}

TEST(Camera, CheckNamesTheProblem) {
  Camera cam = PosedCamera(DistortionSets()[0].K);
  std::string why;
  EXPECT_TRUE(cam.Check(&why));
  cam.K.fy = 0.0;
  EXPECT_FALSE(cam.Check(&why));
  EXPECT_NE(why.find("focal"), std::string::npos) << why;
  cam.K.fy = 1000.0;
  cam.K.height = 0;
  EXPECT_FALSE(cam.Check(&why));
  EXPECT_NE(why.find("image size"), std::string::npos) << why;
  cam.K.height = 10;
  cam.cam_from_world_R(0, 0) = 2.0;
  EXPECT_FALSE(cam.Check(&why));
  EXPECT_NE(why.find("rotation"), std::string::npos) << why;
}

}  // namespace
}  // namespace rodfit
