// An image entry may name one camera of a stereo calibration file (`camera_index: 1 | 2`, docs/
// formats.md): the fit then projects through that camera, the one LoadStereoCameras gives;
// camera_index on a single-camera file, out of range or on a 3-D entry is a one-line error.
#include <memory>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/observe/observations.h"
#include "rodfit/vision/camera_file.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

std::string CameraData(const std::string& name) {
  return std::string(RODFIT_SOURCE_DIR) + "/tests/data/cameras/" + name;
}

std::string Experiment(const std::string& camera, const std::string& extra) {
  return "rod: {length: 0.2, segments: 20, radius: 1.25e-4, linear_density: 5.6e-5}\n"
         "parameters:\n"
         "  bend_stiffness: {value: 1.0e-6, fit: true}\n"
         "  twist_stiffness: {value: 8.0e-7}\n"
         "  stretch_stiffness: {value: 245}\n"
         "cases:\n"
         "  - name: hang\n"
         "    clamp: {position: [0, 0, 0.3], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
         "    observations:\n"
         "      - {type: image_points, file: px.csv, camera: " + camera + ", sigma: 0.5" + extra +
         "}\n";
}

TEST(StereoCameraEntry, ImagePointsProjectThroughTheIndexedCamera) {
  TempDir dir;
  dir.Write("px.csv", "s,u,v\n0.1,640,480\n0.2,700,500\n");
  const auto pair = LoadStereoCameras(CameraData("stereo_k.yaml"));
  for (int index : {1, 2}) {
    const std::string path = dir.Write(
        "e.yaml", Experiment(CameraData("stereo_k.yaml"),
                             ", camera_index: " + std::to_string(index)));
    const rodfit::Experiment e = LoadExperiment(path);
    EXPECT_EQ(e.cases[0].observations[0].camera_index, index);
    EXPECT_EQ(CameraKey(e.cases[0].observations[0]),
              CameraData("stereo_k.yaml") + "[" + std::to_string(index) + "]");
    const FitInput input = BuildFitInput(e);
    ASSERT_EQ(input.cases.size(), 1u);
    ASSERT_EQ(input.cases[0].measurements.size(), 1u);
    const auto* obs = ModelOf<ImageMarkersObservation>(*input.cases[0].measurements[0]);
    ASSERT_NE(obs, nullptr);
    const Camera& expected = index == 1 ? pair.first : pair.second;
    EXPECT_EQ(obs->camera().K.fx, expected.K.fx);
    EXPECT_EQ(obs->camera().K.cy, expected.K.cy);
    EXPECT_EQ(obs->camera().cam_from_world_R, expected.cam_from_world_R);
    EXPECT_EQ(obs->camera().cam_from_world_t, expected.cam_from_world_t);
  }
}

TEST(StereoCameraEntry, BadIndexIsAOneLineError) {
  TempDir dir;
  dir.Write("px.csv", "s,u,v\n0.1,640,480\n");
  // Out of range: the YAML line and key.
  std::string path = dir.Write("a.yaml", Experiment(CameraData("stereo_k.yaml"), ", camera_index: 3"));
  try {
    LoadExperiment(path);
    ADD_FAILURE() << "camera_index 3 accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("a.yaml:"));
    EXPECT_THAT(e.what(), HasSubstr("camera_index: must be an integer in [1, 2]"));
  }
  // A single-camera file with an index: the camera file's own error (no stereo keys).
  path = dir.Write("b.yaml", Experiment(CameraData("opencv_sample.yaml"), ", camera_index: 1"));
  const rodfit::Experiment e = LoadExperiment(path);
  try {
    BuildFitInput(e);
    ADD_FAILURE() << "a single-camera file loaded as a stereo pair";
  } catch (const std::exception& ex) {
    EXPECT_THAT(ex.what(), HasSubstr("opencv_sample.yaml"));
    EXPECT_EQ(std::string(ex.what()).find('\n'), std::string::npos);
  }
  // Not on a 3-D entry.
  std::string text = Experiment(CameraData("stereo_k.yaml"), ", camera_index: 1");
  text.replace(text.find("type: image_points, file: px.csv, camera: "),
               std::string("type: image_points, file: px.csv, camera: ").size(),
               "type: markers3d, file: px.csv, camera: ");
  path = dir.Write("c.yaml", text);
  EXPECT_THROW(LoadExperiment(path), InputError);
}

}  // namespace
}  // namespace rodfit
