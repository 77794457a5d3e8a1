// Tests of camera files (vision/camera_file.h): every spelling in tests/data/cameras/ gives the
// same calibrated camera, poses from rvec/tvec, R/T and stereo R/T are composed correctly, files
// written by cv::FileStorage itself round-trip, and each bad file fails with one line naming the
// file and the key.
#include "rodfit/vision/camera_file.h"

#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace rodfit {
namespace {

std::string DataPath(const std::string& name) {
  return std::string(RODFIT_SOURCE_DIR) + "/tests/data/cameras/" + name;
}

// The calibration all sample files encode (opencv_sample.yaml).
void ExpectSampleIntrinsics(const CameraIntrinsics& K, bool has_k3 = true) {
  EXPECT_EQ(K.fx, 1210.5);
  EXPECT_EQ(K.fy, 1195.25);
  EXPECT_EQ(K.cx, 643.2);
  EXPECT_EQ(K.cy, 481.7);
  EXPECT_EQ(K.k1, -0.271);
  EXPECT_EQ(K.k2, 0.083);
  EXPECT_EQ(K.p1, 3.1e-4);
  EXPECT_EQ(K.p2, -1.7e-4);
  EXPECT_EQ(K.k3, has_k3 ? -0.011 : 0.0);
  EXPECT_EQ(K.width, 1280);
  EXPECT_EQ(K.height, 960);
}

Eigen::Matrix3d Rodrigues(double x, double y, double z) {
  cv::Matx33d R;
  cv::Rodrigues(cv::Vec3d(x, y, z), R);
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out(i, j) = R(i, j);
  }
  return out;
}

TEST(CameraFile, OpenCVSampleWithRvecTvec) {
  const Camera cam = LoadCamera(DataPath("opencv_sample.yaml"));
  ExpectSampleIntrinsics(cam.K);
  EXPECT_EQ(cam.name, "opencv_sample");
  EXPECT_LT((cam.cam_from_world_R - Rodrigues(0.1, -0.2, 0.05)).norm(), 1e-15);
  EXPECT_EQ(cam.cam_from_world_t, Eigen::Vector3d(0.01, -0.02, 0.4));
}

TEST(CameraFile, TutorialSpellingsInXmlAndYamlWithoutPose) {
  for (const char* file : {"opencv_tutorial.xml", "opencv_tutorial.yml"}) {
    SCOPED_TRACE(file);
    const Camera cam = LoadCamera(DataPath(file));
    ExpectSampleIntrinsics(cam.K);
    EXPECT_EQ(cam.cam_from_world_R, Eigen::Matrix3d::Identity());
    EXPECT_EQ(cam.cam_from_world_t, Eigen::Vector3d::Zero());
  }
}

TEST(CameraFile, RosCameraInfoWithoutYamlHeader) {
  const Camera cam = LoadCamera(DataPath("ros_camera_info.yaml"));
  ExpectSampleIntrinsics(cam.K);
  EXPECT_EQ(cam.name, "thread_cam_left");
  EXPECT_EQ(cam.cam_from_world_R, Eigen::Matrix3d::Identity());
}

TEST(CameraFile, JsonWithRAndTAndFourDistortionCoefficients) {
  const Camera cam = LoadCamera(DataPath("camera_rt.json"));
  ExpectSampleIntrinsics(cam.K, /*has_k3=*/false);
  // The same pose as opencv_sample.yaml's rvec/tvec, written as a matrix to 17 digits.
  const Camera reference = LoadCamera(DataPath("opencv_sample.yaml"));
  EXPECT_LT((cam.cam_from_world_R - reference.cam_from_world_R).norm(), 1e-15);
  EXPECT_EQ(cam.cam_from_world_t, reference.cam_from_world_t);
}

TEST(CameraFile, StereoSampleKeys) {
  const auto [first, second] = LoadStereoCameras(DataPath("stereo.yaml"));
  ExpectSampleIntrinsics(first.K);
  EXPECT_EQ(second.K.fx, 1203.1);
  EXPECT_EQ(second.K.cy, 486.2);
  EXPECT_EQ(second.K.k3, -9.0e-3);
  EXPECT_EQ(second.K.width, 1280);
  EXPECT_EQ(first.name, "stereo[1]");
  EXPECT_EQ(second.name, "stereo[2]");
  EXPECT_EQ(first.cam_from_world_R, Eigen::Matrix3d::Identity());
  EXPECT_EQ(first.cam_from_world_t, Eigen::Vector3d::Zero());
  // x2 = R x1 + T: the rotation (Rodrigues of (0.01, -0.35, 0.02)) and T as written.
  EXPECT_LT((second.cam_from_world_R - Rodrigues(0.01, -0.35, 0.02)).norm(), 1e-15);
  EXPECT_EQ(second.cam_from_world_t, Eigen::Vector3d(-0.12, 1e-3, 2.5e-2));
  // Camera 2 sits at -R^T T in camera 1's frame, about 12 cm to the right.
  EXPECT_NEAR(second.CentreWorld().x(), 0.12, 0.02);
}

TEST(CameraFile, StereoKeySpellingsGiveTheSamePair) {
  // K1 D1 K2 D2 (lab tools, OpenCV's Python examples) and cameraMatrix1/2 with distCoeffs1/2
  // (cv::stereoCalibrate's names): the same values as the M1/M2 sample give the same cameras.
  const auto reference = LoadStereoCameras(DataPath("stereo.yaml"));
  for (const char* file : {"stereo_k.yaml", "stereo_cv.yaml"}) {
    SCOPED_TRACE(file);
    const auto pair = LoadStereoCameras(DataPath(file));
    for (const auto& [a, b] : {std::make_pair(pair.first, reference.first),
                               std::make_pair(pair.second, reference.second)}) {
      EXPECT_EQ(a.K.fx, b.K.fx);
      EXPECT_EQ(a.K.fy, b.K.fy);
      EXPECT_EQ(a.K.cx, b.K.cx);
      EXPECT_EQ(a.K.cy, b.K.cy);
      EXPECT_EQ(a.K.k1, b.K.k1);
      EXPECT_EQ(a.K.k3, b.K.k3);
      EXPECT_EQ(a.K.width, b.K.width);
      EXPECT_EQ(a.cam_from_world_R, b.cam_from_world_R);
      EXPECT_EQ(a.cam_from_world_t, b.cam_from_world_t);
    }
  }
  // A single-camera load of a K1/K2 file says it is a stereo file.
  try {
    LoadCamera(DataPath("stereo_k.yaml"));
    ADD_FAILURE() << "a stereo file loaded as one camera";
  } catch (const CameraFileError& e) {
    EXPECT_NE(std::string(e.what()).find("stereo file (K1)"), std::string::npos) << e.what();
  }
}

TEST(CameraFile, FilesWrittenByOpenCVRoundTrip) {
  // YAML, JSON and XML as cv::FileStorage writes them (Mat-valued distortion, Vec3d poses).
  for (const char* ext : {".yaml", ".json", ".xml"}) {
    SCOPED_TRACE(ext);
    const std::string path = ::testing::TempDir() + "rodfit_camera_roundtrip" + ext;
    {
      cv::FileStorage fs(path, cv::FileStorage::WRITE);
      fs << "image_width" << 800 << "image_height" << 600;
      fs << "camera_matrix" << cv::Mat(cv::Matx33d(900.25, 0, 401.5, 0, 905.5, 299.75, 0, 0, 1));
      fs << "distortion_coefficients"
         << cv::Mat(cv::Matx<double, 1, 5>(-0.1, 0.02, 1e-3, 0, 0.001));
      fs << "rvec" << cv::Mat(cv::Vec3d(-0.3, 0.2, 0.1));
      fs << "tvec" << cv::Mat(cv::Vec3d(0, 0.1, 0.5));
    }
    const Camera cam = LoadCamera(path);
    std::remove(path.c_str());
    EXPECT_EQ(cam.K.fx, 900.25);
    EXPECT_EQ(cam.K.cy, 299.75);
    EXPECT_EQ(cam.K.k1, -0.1);
    EXPECT_EQ(cam.K.k3, 0.001);
    EXPECT_EQ(cam.K.height, 600);
    EXPECT_LT((cam.cam_from_world_R - Rodrigues(-0.3, 0.2, 0.1)).norm(), 1e-15);
    EXPECT_EQ(cam.cam_from_world_t, Eigen::Vector3d(0, 0.1, 0.5));
  }
}

std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(CameraFile, MatrixLayoutsImageSizeListAndEmptyDistortion) {
  // Lists of rows, image_size: [w, h], and an empty distortion vector (a rectified camera).
  const Camera cam = LoadCamera(WriteTemp(
      "rodfit_layouts.json",
      R"({"cameraMatrix": [[800, 0, 320.5], [0, 810, 240.25], [0, 0, 1]], "distCoeffs": [],
          "image_size": [640, 480], "rvec": [0, 0, 0], "tvec": [[0], [0], [1]]})"));
  EXPECT_EQ(cam.K.fx, 800.0);
  EXPECT_EQ(cam.K.fy, 810.0);
  EXPECT_EQ(cam.K.cx, 320.5);
  EXPECT_EQ(cam.K.k1, 0.0);
  EXPECT_EQ(cam.K.width, 640);
  EXPECT_EQ(cam.K.height, 480);
  EXPECT_EQ(cam.cam_from_world_t, Eigen::Vector3d(0, 0, 1));
}

// Loading `path` fails with one line "PATH: KEY: ..." containing `fragment`.
void ExpectErrorAt(const std::string& path, const std::string& key, const std::string& fragment,
                   bool stereo = false) {
  SCOPED_TRACE(path);
  try {
    if (stereo) LoadStereoCameras(path);
    else LoadCamera(path);
    ADD_FAILURE() << "no error";
  } catch (const CameraFileError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file, path);
    EXPECT_EQ(e.key, key);
    const std::string prefix = key.empty() ? path + ": " : path + ": " + key + ": ";
    EXPECT_EQ(what.rfind(prefix, 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

void ExpectError(const std::string& file, const std::string& key, const std::string& fragment,
                 bool stereo = false) {
  ExpectErrorAt(DataPath(file), key, fragment, stereo);
}

TEST(CameraFile, BadFilesNameTheFileAndTheKey) {
  ExpectError("no_such_camera.yaml", "", "cannot open");
  ExpectError("bad_malformed.yaml", "", "malformed file: line");
  ExpectError("bad_missing_camera_matrix.yaml", "camera_matrix", "missing");
  ExpectError("bad_camera_matrix_2x3.yaml", "camera_matrix", "expected a 3x3 matrix, got 2x3");
  ExpectError("bad_nan.yaml", "distortion_coefficients", "non-finite");
  ExpectError("bad_negative_focal.yaml", "camera_matrix", "focal lengths must be positive");
  ExpectError("bad_missing_image_size.yaml", "image_width", "missing");
  ExpectError("bad_rational_distortion.yaml", "distortion_coefficients", "k4");
  ExpectError("bad_rvec_without_tvec.yaml", "tvec", "missing");
  ExpectError("stereo.yaml", "camera_matrix", "stereo file");
  ExpectError("opencv_sample.yaml", "M1", "missing", /*stereo=*/true);
}

TEST(CameraFile, MoreMistakesNameTheKey) {
  const std::string size = "image_width: 640\nimage_height: 480\n";
  const std::string K = "camera_matrix: [800, 0, 320, 0, 800, 240, 0, 0, 1]\n";
  const std::string D = "distortion_coefficients: [0, 0, 0, 0]\n";
  const std::string T = "T: [0, 0, 1]\n";
  auto temp = [](const std::string& name, const std::string& text) {
    return WriteTemp("rodfit_" + name, text);
  };
  ExpectErrorAt(temp("dup.yaml", size + K + "Camera_Matrix: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"),
                "Camera_Matrix", "given together with camera_matrix");
  ExpectErrorAt(temp("d3.yaml", size + K + "distortion_coefficients: [0.1, 0, 0]\n"),
                "distortion_coefficients", "got 3");
  ExpectErrorAt(temp("fisheye.yaml", size + K + D + "distortion_model: equidistant\n"),
                "distortion_model", "equidistant");
  ExpectErrorAt(temp("R2x2.yaml", size + K + D + "R: [[1, 0], [0, 1]]\n" + T), "R",
                "expected a 3x3 rotation");
  ExpectErrorAt(temp("Rscaled.yaml", size + K + D + "R: [1, 0, 0, 0, 1, 0, 0, 0, 1.01]\n" + T),
                "R", "not a rotation");
  ExpectErrorAt(temp("RnoT.yaml", size + K + D + "R: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n"), "T",
                "missing");
  ExpectErrorAt(temp("height.yaml", "image_width: 640\n" + K + D), "image_height", "missing");
  ExpectErrorAt(temp("width.yaml", "image_width: 640.5\nimage_height: 480\n" + K + D),
                "image_width", "positive integer");
  ExpectErrorAt(temp("skew.yaml", size + "camera_matrix: [800, 2, 320, 0, 800, 240, 0, 0, 1]\n"),
                "camera_matrix", "skew");
  ExpectErrorAt(temp("rows.yaml", size + "camera_matrix: {rows: 3, cols: 3, data: [1, 2]}\n"),
                "camera_matrix", "does not match 2 data values");
  ExpectErrorAt(temp("nan.json", R"({"camera_matrix": [1, NaN]})"), "", "malformed file");
  ExpectErrorAt(temp("empty.yaml", "  \n"), "", "empty");
  ExpectErrorAt(::testing::TempDir(), "", "cannot open");
}

}  // namespace
}  // namespace rodfit
