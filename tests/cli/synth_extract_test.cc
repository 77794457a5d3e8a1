// Tests of `rodfit synth` and `rodfit extract` run as a user would: synthesize a small experiment
// with camera images, extract the centre-line from an image (within a pixel of the projected
// truth in truth.json) or from two (triangulated onto the true centre-line), the same seed giving
// the same bytes; and bad inputs (missing image, malformed camera file, a camera looking away
// from the thread) exiting non-zero with one line on stderr and no output file; clutter kept out
// by --roi and --mask.
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"
#include "rodfit/io/csv.h"
#include "rodfit/observe/camera.h"
#include "rodfit/vision/camera_file.h"

namespace rodfit {
namespace {

using test::RunResult;

namespace fs = std::filesystem;
using test::ReadText;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

const std::string kData = RODFIT_SOURCE_DIR "/tests/data/synth/";

// A sagging thread pulled sideways, markers and an image from each of two cameras.
const char* const kExperiment =
    "rod: {length: 0.2, segments: 40, radius: 2.5e-4, linear_density: 5.6e-5}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-5, fit: true}\n"
    "  twist_stiffness: {value: 8.0e-6}\n"
    "  stretch_stiffness: {value: 245}\n"
    "cases:\n"
    "  - name: sag\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    tip_force: [0, 2.0e-5, 0]\n"
    "    observations:\n"
    "      - {type: markers3d, file: markers.csv, sigma: 3.0e-4, count: 10}\n"
    "      - {type: images, file: front.png, camera: CAMERA, sigma: 0.5, blur: 0.8, noise: 2}\n"
    "      - {type: images, file: top.png, camera: cam_top.yaml, sigma: 0.5}\n";

template <int N>
double DistanceToPolyline(const Eigen::Matrix<double, N, 1>& p,
                          const std::vector<Eigen::Matrix<double, N, 1>>& line) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Matrix<double, N, 1> ab = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - line[i] - t * ab).norm());
  }
  return best;
}

class SynthExtractCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) {
    return test::RunRodfit(dir_, args);
  }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // Writes the experiment (front camera = `camera`) beside copies of the camera files.
  std::string WriteExperiment(const std::string& camera = "cam_front.yaml") {
    for (const char* name : {"cam_front.yaml", "cam_top.yaml", "cam_away.yaml"}) {
      dir_.Write(std::string("in/") + name, ReadText(kData + name));
    }
    std::string text = kExperiment;
    text.replace(text.find("CAMERA"), 6, camera);
    return dir_.Write("in/experiment.yaml", text);
  }

  // The true centre-line from truth.json.
  std::vector<Eigen::Vector3d> Truth(const std::string& out_dir) {
    const auto truth = nlohmann::json::parse(ReadText(out_dir + "/truth.json"));
    std::vector<Eigen::Vector3d> x;
    for (const auto& v : truth["cases"][0]["vertices"]) {
      x.emplace_back(v[0].get<double>(), v[1].get<double>(), v[2].get<double>());
    }
    return x;
  }

  // One line on stderr starting with "rodfit", a non-zero exit.
  static void ExpectOneLineError(const RunResult& run, const std::string& expected) {
    EXPECT_GT(run.status, 0);
    EXPECT_THAT(run.err, StartsWith("rodfit"));
    EXPECT_THAT(run.err, HasSubstr(expected));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }

  TempDir dir_;
};

TEST_F(SynthExtractCliTest, HelpListsTheCommands) {
  RunResult run = Rodfit("--help");
  EXPECT_THAT(run.out, HasSubstr("synth"));
  EXPECT_THAT(run.out, HasSubstr("extract"));
  run = Rodfit("synth --help");
  EXPECT_EQ(run.status, 0);
  EXPECT_THAT(run.out, HasSubstr("--seed"));
  run = Rodfit("extract --help");
  EXPECT_EQ(run.status, 0);
  EXPECT_THAT(run.out, HasSubstr("--stereo"));
}

TEST_F(SynthExtractCliTest, ExtractFindsTheProjectedTruth) {
  const std::string out = dir_.File("out");
  RunResult run = Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out) + " --seed 3");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("front.png"));
  for (const char* name : {"markers.csv", "front.png", "top.png", "cam_front.yaml",
                           "cam_top.yaml", "experiment.yaml", "truth.json"}) {
    EXPECT_TRUE(fs::is_regular_file(out + "/" + name)) << name;
  }

  const std::string csv = dir_.File("points.csv"), overlay = dir_.File("overlay.png");
  run = Rodfit("extract " + Q(out + "/front.png") + " --camera " + Q(out + "/cam_front.yaml") +
               " -o " + Q(csv) + " --overlay " + Q(overlay));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable table = CsvTable::Read(csv);
  EXPECT_EQ(table.header(), std::vector<std::string>({"u", "v"}));
  const Camera camera = LoadCamera(out + "/cam_front.yaml");
  std::vector<Eigen::Vector2d> truth_uv;
  for (const Eigen::Vector3d& x : Truth(out)) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(Project(camera, x, &uv));
    truth_uv.push_back(uv);
  }
  const std::vector<double> u = table.Column("u"), v = table.Column("v");
  ASSERT_GT(u.size(), 500u);
  for (size_t k = 0; k < u.size(); ++k) {
    EXPECT_LT(DistanceToPolyline<2>(Eigen::Vector2d(u[k], v[k]), truth_uv), 1.0) << "row " << k;
  }
  const cv::Mat drawn = cv::imread(overlay);
  EXPECT_EQ(drawn.cols, 1280);
  EXPECT_EQ(drawn.rows, 1024);

  // A start hint at the clamp's projection orders the points from there.
  run = Rodfit("extract " + Q(out + "/front.png") + " --camera " + Q(out + "/cam_front.yaml") +
               " -o " + Q(csv) + " --start " + std::to_string(truth_uv[0].x()) + "," +
               std::to_string(truth_uv[0].y()));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable hinted = CsvTable::Read(csv);
  EXPECT_LT((Eigen::Vector2d(hinted.Column("u")[0], hinted.Column("v")[0]) - truth_uv[0]).norm(),
            3.0);
}

// A photograph's clutter (a dark band, as a table edge) away from the thread breaks the
// extraction; --roi or --mask keeps it out and the points are back on the projected truth.
TEST_F(SynthExtractCliTest, ExtractWithRoiOrMaskIgnoresClutter) {
  const std::string out = dir_.File("out");
  ASSERT_EQ(Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out) + " --seed 3").status, 0);
  const Camera camera = LoadCamera(out + "/cam_front.yaml");
  std::vector<Eigen::Vector2d> truth_uv;
  for (const Eigen::Vector3d& x : Truth(out)) {
    Eigen::Vector2d uv;
    ASSERT_TRUE(Project(camera, x, &uv));
    truth_uv.push_back(uv);
  }
  Eigen::Vector2d lo = truth_uv[0], hi = truth_uv[0];
  for (const Eigen::Vector2d& p : truth_uv) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const int top = hi.y() + 160 < 1024 ? int(hi.y()) + 60 : int(lo.y()) - 160;
  ASSERT_GE(top, 0) << "no room for the band";
  cv::Mat image = cv::imread(out + "/front.png", cv::IMREAD_UNCHANGED);
  image(cv::Rect(0, top, image.cols, 100)).setTo(cv::Scalar::all(90));
  const std::string cluttered = dir_.File("cluttered.png"), csv = dir_.File("points.csv");
  ASSERT_TRUE(cv::imwrite(cluttered, image));
  const std::string base = "extract " + Q(cluttered) + " --camera " + Q(out + "/cam_front.yaml") +
                           " -o " + Q(csv);

  RunResult run = Rodfit(base);
  ExpectOneLineError(run, cluttered + ": centre-line extraction: 2 disjoint pieces");
  EXPECT_FALSE(fs::exists(csv));

  auto expect_on_truth = [&]() {
    const CsvTable table = CsvTable::Read(csv);
    const std::vector<double> u = table.Column("u"), v = table.Column("v");
    ASSERT_GT(u.size(), 500u);
    double worst = 0;
    for (size_t k = 0; k < u.size(); ++k)
      worst = std::max(worst, DistanceToPolyline<2>(Eigen::Vector2d(u[k], v[k]), truth_uv));
    EXPECT_LT(worst, 1.0);
  };
  const std::string roi = std::to_string(std::max(0, int(lo.x()) - 40)) + "," +
                          std::to_string(std::max(0, int(lo.y()) - 40)) + "," +
                          std::to_string(std::min(1280, int(hi.x()) + 40)) + "," +
                          std::to_string(std::min(1024, int(hi.y()) + 40));
  run = Rodfit(base + " --roi " + roi);
  ASSERT_EQ(run.status, 0) << run.err;
  expect_on_truth();

  fs::remove(csv);
  cv::Mat mask(image.rows, image.cols, CV_8UC1, cv::Scalar(255));
  mask(cv::Rect(0, top - 5, image.cols, 110)).setTo(0);
  const std::string mask_file = dir_.File("mask.png");
  ASSERT_TRUE(cv::imwrite(mask_file, mask));
  run = Rodfit(base + " --mask " + Q(mask_file));
  ASSERT_EQ(run.status, 0) << run.err;
  expect_on_truth();

  // Mistakes: one line naming the option (or the mask, or the image), no output.
  fs::remove(csv);
  run = Rodfit(base + " --roi 1,2,3");
  ExpectOneLineError(run, "--roi '1,2,3' is not X0,Y0,X1,Y1 (four integer pixel corners)");
  run = Rodfit(base + " --roi 0,0,10.5,10");
  ExpectOneLineError(run, "--roi '0,0,10.5,10' is not X0,Y0,X1,Y1");
  run = Rodfit(base + " --roi 10,10,5,20");
  ExpectOneLineError(run, "--roi '10,10,5,20' is empty (X1 must exceed X0");
  run = Rodfit(base + " --roi 0,0,2000,100");
  ExpectOneLineError(run, "roi [0, 2000) x [0, 100) is not inside the 1280x1024 px image");
  run = Rodfit(base + " --roi 0,0,10,10 --roi 0,0,20,20");
  ExpectOneLineError(run, "give one --roi per image, or none");
  run = Rodfit(base + " --mask " + Q(dir_.File("nomask.png")));
  ExpectOneLineError(run, dir_.File("nomask.png") + ": cannot read the image");
  run = Rodfit(base + " --mask " + Q(cluttered));
  ExpectOneLineError(run, cluttered + ": a mask must be a single-channel (grey) image");
  EXPECT_FALSE(fs::exists(csv));
  // The mask is an input: no output may overwrite it.
  run = Rodfit("extract " + Q(cluttered) + " --camera " + Q(out + "/cam_front.yaml") + " -o " +
               Q(csv) + " --mask " + Q(mask_file) + " --overlay " + Q(mask_file));
  ExpectOneLineError(run, "is a mask (" + mask_file + "), an input of this run");
  EXPECT_FALSE(fs::exists(csv));
  const cv::Mat kept = cv::imread(mask_file, cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::countNonZero(kept != mask), 0);
}

TEST_F(SynthExtractCliTest, StereoExtractTriangulatesTheTruth) {
  const std::string out = dir_.File("out");
  ASSERT_EQ(Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out)).status, 0);
  const std::vector<Eigen::Vector3d> truth = Truth(out);
  // Same expected error as tests/io/image_observations_test.cc: 0.5 px at 0.4 m, f = 2000 px,
  // across a 17 degree triangulation angle.
  const double expected_error_m = 0.4 * 0.5 / 2000.0 / std::sin(17.0 * M_PI / 180.0);
  const std::string images = Q(out + "/front.png") + " " + Q(out + "/top.png");
  for (const std::string& cameras :
       {" --camera " + Q(out + "/cam_front.yaml") + " --camera " + Q(out + "/cam_top.yaml"),
        " --stereo " + Q(kData + "stereo_front_top.yaml")}) {
    SCOPED_TRACE(cameras);
    const std::string csv = dir_.File("xyz.csv");
    const RunResult run = Rodfit("extract " + images + cameras + " -o " + Q(csv));
    ASSERT_EQ(run.status, 0) << run.err;
    const CsvTable table = CsvTable::Read(csv);
    EXPECT_EQ(table.header(), std::vector<std::string>({"x", "y", "z"}));
    const std::vector<double> x = table.Column("x"), y = table.Column("y"), z = table.Column("z");
    ASSERT_GT(x.size(), 500u);
    for (size_t k = 0; k < x.size(); ++k) {
      EXPECT_LT(DistanceToPolyline<3>(Eigen::Vector3d(x[k], y[k], z[k]), truth), expected_error_m)
          << "row " << k;
    }
  }
}

// OpenCV's stereo_calib sample writes intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml (R T R1 R2
// P1 P2 Q) with cv::FileStorage and no image size (issue 38): extract takes the two files and the
// size from the images, and triangulates in camera 1's frame (the sample poses no camera). The
// same pair as one XML file without a size gives the same points.
TEST_F(SynthExtractCliTest, StereoFilesAsTheOpenCVSampleWritesThem) {
  const std::string out = dir_.File("out");
  ASSERT_EQ(Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out)).status, 0);
  cv::FileStorage reference(kData + "stereo_front_top.yaml", cv::FileStorage::READ);
  ASSERT_TRUE(reference.isOpened());
  auto matrix = [&](const char* key) {
    cv::Mat m;
    reference[key] >> m;
    EXPECT_FALSE(m.empty()) << key;
    return m;
  };
  const std::string intrinsics = dir_.File("intrinsics.yml"), extrinsics = dir_.File("extrinsics.yml");
  {
    cv::FileStorage fs(intrinsics, cv::FileStorage::WRITE);
    fs << "M1" << matrix("M1") << "D1" << matrix("D1") << "M2" << matrix("M2") << "D2" << matrix("D2");
  }
  {
    const cv::Mat eye = cv::Mat::eye(3, 3, CV_64F);
    cv::FileStorage fs(extrinsics, cv::FileStorage::WRITE);
    fs << "R" << matrix("R") << "T" << matrix("T") << "R1" << eye << "R2" << eye;
  }
  const std::string one_xml = dir_.File("stereo.xml");
  {
    cv::FileStorage fs(one_xml, cv::FileStorage::WRITE);
    for (const char* key : {"M1", "D1", "M2", "D2", "R", "T"}) fs << key << matrix(key);
  }
  const std::string images = Q(out + "/front.png") + " " + Q(out + "/top.png");
  const std::string two = dir_.File("two.csv"), one = dir_.File("one.csv");
  RunResult run = Rodfit("extract " + images + " --stereo " + Q(intrinsics) + " " +
                         Q(extrinsics) + " -o " + Q(two));
  ASSERT_EQ(run.status, 0) << run.err;
  run = Rodfit("extract " + images + " --stereo " + Q(one_xml) + " -o " + Q(one));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(ReadText(one), ReadText(two));
  // On the truth, seen from camera 1 (cam_front.yaml's pose): the error bound of
  // StereoExtractTriangulatesTheTruth.
  const Camera front = LoadCamera(out + "/cam_front.yaml");
  std::vector<Eigen::Vector3d> truth_cam;
  for (const Eigen::Vector3d& x : Truth(out))
    truth_cam.push_back(front.cam_from_world_R * x + front.cam_from_world_t);
  const double expected_error_m = 0.4 * 0.5 / 2000.0 / std::sin(17.0 * M_PI / 180.0);
  const CsvTable table = CsvTable::Read(two);
  const std::vector<double> x = table.Column("x"), y = table.Column("y"), z = table.Column("z");
  ASSERT_GT(x.size(), 500u);
  for (size_t k = 0; k < x.size(); ++k)
    EXPECT_LT(DistanceToPolyline<3>(Eigen::Vector3d(x[k], y[k], z[k]), truth_cam),
              expected_error_m) << "row " << k;
  // Without a size, the images must be of one size; each mistake names its file.
  const std::string small = dir_.File("small.png");
  cv::imwrite(small, cv::Mat(512, 640, CV_8UC3, cv::Scalar(235, 235, 235)));
  run = Rodfit("extract " + Q(out + "/front.png") + " " + Q(small) + " --stereo " +
               Q(intrinsics) + " " + Q(extrinsics) + " -o " + Q(one));
  ExpectOneLineError(run, small + ": the image is 640x512 px but " + out + "/front.png is 1280x1024");
  run = Rodfit("extract " + images + " --stereo " + Q(intrinsics) + " -o " + Q(one));
  ExpectOneLineError(run, intrinsics + ": R: missing");
  run = Rodfit("extract " + images + " --stereo " + Q(one_xml) + " " + Q(extrinsics) + " -o " +
               Q(one));
  ExpectOneLineError(run, one_xml + ": R: given here and in the extrinsics file");
}

TEST_F(SynthExtractCliTest, SameSeedSameBytes) {
  const std::string experiment = WriteExperiment();
  ASSERT_EQ(Rodfit("synth " + Q(experiment) + " -o " + Q(dir_.File("a")) + " --seed 9").status, 0);
  ASSERT_EQ(Rodfit("synth " + Q(experiment) + " -o " + Q(dir_.File("b")) + " --seed 9").status, 0);
  ASSERT_EQ(Rodfit("synth " + Q(experiment) + " -o " + Q(dir_.File("c")) + " --seed 10").status,
            0);
  for (const char* name : {"markers.csv", "front.png", "top.png", "experiment.yaml",
                           "truth.json"}) {
    EXPECT_EQ(ReadText(dir_.File("a/") + name), ReadText(dir_.File("b/") + name)) << name;
  }
  EXPECT_NE(ReadText(dir_.File("a/front.png")), ReadText(dir_.File("c/front.png")));
  EXPECT_NE(ReadText(dir_.File("a/markers.csv")), ReadText(dir_.File("c/markers.csv")));
}

TEST_F(SynthExtractCliTest, NoiseFreeMarkersAreOnTheTruth) {
  const std::string out = dir_.File("out");
  ASSERT_EQ(Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out) + " --noise-free").status, 0);
  const CsvTable markers = CsvTable::Read(out + "/markers.csv");
  ASSERT_EQ(markers.num_rows(), 10);
  // The last marker is at the tip, which is the last vertex of the truth, to the last bit.
  const Eigen::Vector3d tip(markers.Column("x")[9], markers.Column("y")[9],
                            markers.Column("z")[9]);
  EXPECT_EQ(tip, Truth(out).back());
}

TEST_F(SynthExtractCliTest, BadInputsAreOneLineErrorsWithNoOutput) {
  const std::string out = dir_.File("out");
  // A camera looking away from the thread: synth names the camera file and the case.
  RunResult run = Rodfit("synth " + Q(WriteExperiment("cam_away.yaml")) + " -o " + Q(out));
  ExpectOneLineError(run, "cam_away.yaml sees nothing of the rod in case 'sag'");
  EXPECT_FALSE(fs::exists(out));

  ASSERT_EQ(Rodfit("synth " + Q(WriteExperiment()) + " -o " + Q(out)).status, 0);
  const std::string csv = dir_.File("points.csv");
  const std::string camera = " --camera " + Q(out + "/cam_front.yaml");

  run = Rodfit("extract " + Q(dir_.File("missing.png")) + camera + " -o " + Q(csv));
  ExpectOneLineError(run, dir_.File("missing.png") + ": cannot read the image");
  EXPECT_FALSE(fs::exists(csv));

  const std::string malformed = RODFIT_SOURCE_DIR "/tests/data/cameras/bad_malformed.yaml";
  run = Rodfit("extract " + Q(out + "/front.png") + " --camera " + Q(malformed) + " -o " + Q(csv));
  ExpectOneLineError(run, malformed);
  EXPECT_FALSE(fs::exists(csv));

  run = Rodfit("extract " + Q(out + "/front.png") + " --camera " + Q(dir_.File("nocam.yaml")) +
               " -o " + Q(csv));
  ExpectOneLineError(run, dir_.File("nocam.yaml"));
  EXPECT_FALSE(fs::exists(csv));

  // An image with no thread in it.
  const std::string blank = dir_.File("blank.png");
  cv::imwrite(blank, cv::Mat(1024, 1280, CV_8UC3, cv::Scalar(235, 235, 235)));
  run = Rodfit("extract " + Q(blank) + camera + " -o " + Q(csv));
  ExpectOneLineError(run, blank);
  EXPECT_FALSE(fs::exists(csv));

  // An overlay OpenCV cannot encode: nothing written, not even the CSV.
  run = Rodfit("extract " + Q(out + "/front.png") + camera + " -o " + Q(csv) + " --overlay " +
               Q(dir_.File("overlay.nope")));
  ExpectOneLineError(run, "overlay.nope");
  EXPECT_FALSE(fs::exists(csv));

  // Argument mistakes.
  run = Rodfit("extract " + Q(out + "/front.png") + " " + Q(out + "/top.png") + camera + " -o " +
               Q(csv));
  ExpectOneLineError(run, "give one --camera per image, or --stereo");
  run = Rodfit("extract " + Q(out + "/front.png") + camera + " -o " + Q(csv) + " --start 3");
  ExpectOneLineError(run, "--start '3' is not U,V");
  run = Rodfit("extract " + Q(out + "/front.png") + " --stereo " +
               Q(kData + "stereo_front_top.yaml") + " -o " + Q(csv));
  ExpectOneLineError(run, "--stereo needs two images");
  EXPECT_FALSE(fs::exists(csv));
}

}  // namespace
}  // namespace rodfit
