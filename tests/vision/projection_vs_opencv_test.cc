// The camera model of observe/camera.h against OpenCV itself: pixels equal cv::projectPoints to
// 1e-9 px for a grid of points and several distortion sets, and the analytic Jacobian equals
// OpenCV's d uv / d tvec (which is d uv / d p_cam) times R.
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "../observe/camera_fixtures.h"
#include "rodfit/observe/camera.h"

namespace rodfit {
namespace {

TEST(ProjectionVsOpenCV, PixelsAndJacobiansMatchProjectPoints) {
  for (const auto& [name, K] : testing::DistortionSets()) {
    const Camera cam = testing::PosedCamera(K);
    const std::vector<Eigen::Vector3d> points = testing::GridPoints(cam);
    std::vector<cv::Point3d> object;
    for (const Eigen::Vector3d& p : points) object.emplace_back(p.x(), p.y(), p.z());
    cv::Matx33d R_cv;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) R_cv(i, j) = cam.cam_from_world_R(i, j);
    }
    cv::Vec3d rvec;
    cv::Rodrigues(R_cv, rvec);
    const cv::Vec3d tvec(cam.cam_from_world_t.x(), cam.cam_from_world_t.y(),
                         cam.cam_from_world_t.z());
    const cv::Matx33d camera_matrix(K.fx, 0, K.cx, 0, K.fy, K.cy, 0, 0, 1);
    const std::vector<double> dist = {K.k1, K.k2, K.p1, K.p2, K.k3};
    std::vector<cv::Point2d> image;
    cv::Mat jacobian;  // 2N x (3 rvec + 3 tvec + 2 f + 2 c + 5 dist)
    cv::projectPoints(object, rvec, tvec, camera_matrix, dist, image, jacobian);
    ASSERT_EQ(image.size(), points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector2d uv;
      Mat23 J;
      ASSERT_TRUE(Project(cam, points[i], &uv, &J));
      EXPECT_NEAR(uv.x(), image[i].x, 1e-9) << name << " point " << i;
      EXPECT_NEAR(uv.y(), image[i].y, 1e-9) << name << " point " << i;
      Eigen::Matrix<double, 2, 3> d_uv_d_tvec;
      for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 3; ++c) d_uv_d_tvec(r, c) = jacobian.at<double>(2 * i + r, 3 + c);
      }
      // R differs from the Rodrigues round trip by ~1e-16, hence a relative 1e-10.
      const Mat23 J_cv = d_uv_d_tvec * cam.cam_from_world_R;
      EXPECT_LT((J - J_cv).norm(), 1e-10 * J_cv.norm())
          << name << " point " << i << "\nrodfit\n" << J << "\nOpenCV\n" << J_cv;
    }
  }
}

}  // namespace
}  // namespace rodfit
