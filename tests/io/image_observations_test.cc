// Tests of images -> observations (io/image_observations.h) on images synthesized by
// synth/synth.h: extracted centre-line pixels lie within a pixel of the projected true centre-line
// and start at the clamped end; two views triangulate to the true centre-line within the stereo
// error of the sample cameras; unreadable or mis-sized images are one-line InputErrors.
#include "rodfit/pipeline/image_observations.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/synth/synth.h"
#include "rodfit/vision/camera_file.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

const std::string kCameraFront = RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml";
const std::string kCameraTop = RODFIT_SOURCE_DIR "/tests/data/synth/cam_top.yaml";

// A sagging thread pulled sideways (a 3-D shape) seen by both sample cameras; the front image is
// blurred and noisy as a real one would be.
const std::string kExperiment =
    "rod: {length: 0.2, segments: 40, radius: 2.5e-4, linear_density: 5.6e-5}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-5}\n"
    "  twist_stiffness: {value: 8.0e-6}\n"
    "  stretch_stiffness: {value: 245}\n"
    "cases:\n"
    "  - name: sag\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    tip_force: [0, 2.0e-5, 0]\n"
    "    observations:\n"
    "      - {type: images, file: front.png, camera: " + kCameraFront +
    ", sigma: 0.5, blur: 0.8, noise: 3}\n"
    "      - {type: images, file: top.png, camera: " + kCameraTop + ", sigma: 0.5}\n";

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

class ImageObservationsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Experiment source = LoadExperiment(dir_.Write("src/e.yaml", kExperiment));
    bundle_ = Synthesize(source, dir_.File("out"));
    ex_ = LoadExperiment(dir_.File("out/experiment.yaml"));
    front_ = LoadCamera(ex_.cases[0].observations[0].camera);
    top_ = LoadCamera(ex_.cases[0].observations[1].camera);
    for (int i = 0; i < bundle_.truth[0].x.cols(); ++i) {
      truth_.push_back(bundle_.truth[0].x.col(i));
    }
  }

  std::vector<Eigen::Vector2d> Projected(const Camera& camera) const {
    std::vector<Eigen::Vector2d> uv(truth_.size());
    for (size_t i = 0; i < truth_.size(); ++i) EXPECT_TRUE(Project(camera, truth_[i], &uv[i]));
    return uv;
  }

  TempDir dir_;
  SynthBundle bundle_;
  Experiment ex_;
  Camera front_, top_;
  std::vector<Eigen::Vector3d> truth_;
};

TEST_F(ImageObservationsTest, ExtractedPointsLieOnTheProjectedTruthFromTheClamp) {
  for (int k = 0; k < 2; ++k) {
    SCOPED_TRACE(k == 0 ? "front (blur, noise)" : "top");
    const Camera& camera = k == 0 ? front_ : top_;
    const std::vector<Eigen::Vector2d> uv =
        ImagePointsFromImage(ex_.cases[0].observations[k], camera, ex_.scene.cases[0]);
    const std::vector<Eigen::Vector2d> truth = Projected(camera);
    ASSERT_GT(uv.size(), 500u);  // about one point per pixel of a ~1000 px thread
    double worst = 0.0;
    for (const Eigen::Vector2d& p : uv) worst = std::max(worst, DistanceToPolyline<2>(p, truth));
    EXPECT_LT(worst, 1.0);
    // Ordered from the clamped end to the tip.
    EXPECT_LT((uv.front() - truth.front()).norm(), 3.0);
    EXPECT_LT((uv.back() - truth.back()).norm(), 3.0);
  }
}

TEST_F(ImageObservationsTest, TwoViewsTriangulateToTheTrueCentreline) {
  PolylineMatchResult match;
  const std::vector<Eigen::Vector3d> points =
      TriangulatedPoints(ex_.cases[0].observations[0], front_, ex_.cases[0].observations[1], top_,
                         ex_.scene.cases[0], CentrelineOptions(), PolylineMatchOptions(), &match);
  ASSERT_GT(points.size(), 500u);
  // Expected error: up to 0.5 px of extraction error per view, at 0.4 m depth and f = 2000 px,
  // across a triangulation angle of about 17 degrees: 0.4 * 0.5 / 2000 / sin(17 deg) = 0.34 mm.
  const double expected_error_m = 0.4 * 0.5 / 2000.0 / std::sin(17.0 * M_PI / 180.0);
  double worst = 0.0, sum = 0.0;
  for (const Eigen::Vector3d& p : points) {
    const double d = DistanceToPolyline<3>(p, truth_);
    worst = std::max(worst, d);
    sum += d;
  }
  EXPECT_LT(worst, expected_error_m);
  EXPECT_LT(sum / points.size(), 0.3 * expected_error_m);  // typical errors are sub-pixel
  // From the clamp to the tip, covering the thread.
  EXPECT_LT((points.front() - truth_.front()).norm(), 2e-3);
  EXPECT_LT((points.back() - truth_.back()).norm(), 2e-3);
}

// A lab photograph's clutter (a dark band, as a table edge or an instrument) away from the
// thread: the entry's roi or mask keeps it out, and the points are as good as on the clean image.
TEST_F(ImageObservationsTest, ClutterIsKeptOutByTheEntrysRoiOrMask) {
  const std::vector<Eigen::Vector2d> truth = Projected(front_);
  Eigen::Vector2d lo = truth.front(), hi = truth.front();
  for (const Eigen::Vector2d& p : truth) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // A 100 px band across the image, 60 px clear of the thread (below it, or above if no room).
  const int top = hi.y() + 160 < front_.K.height ? int(hi.y()) + 60 : int(lo.y()) - 160;
  ASSERT_GE(top, 0) << "no room for the band";
  ObservationSpec spec = ex_.cases[0].observations[0];
  cv::Mat image = ReadImageFile(spec.file);
  cv::rectangle(image, cv::Rect(0, top, image.cols, 100), cv::Scalar::all(90), cv::FILLED);
  spec.file = dir_.File("out/cluttered.png");
  WriteImageFile(spec.file, image);

  auto worst_distance = [&](const std::vector<Eigen::Vector2d>& uv) {
    double worst = 0.0;
    for (const Eigen::Vector2d& p : uv) worst = std::max(worst, DistanceToPolyline<2>(p, truth));
    return worst;
  };
  // Without a region the band is segmented too: a second piece that cannot be linked.
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const CentrelineError& e) {
    EXPECT_THAT(e.what(), HasSubstr(spec.file + ": centre-line extraction: 2 disjoint pieces"));
  }

  const int margin = 40;  // [px] around the thread, less than the band's clearance
  spec.roi = std::array<int, 4>{std::max(0, int(lo.x()) - margin), std::max(0, int(lo.y()) - margin),
                                std::min(front_.K.width, int(hi.x()) + margin),
                                std::min(front_.K.height, int(hi.y()) + margin)};
  const std::vector<Eigen::Vector2d> with_roi =
      ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
  const std::vector<Eigen::Vector2d> clean =
      ImagePointsFromImage(ex_.cases[0].observations[0], front_, ex_.scene.cases[0]);
  ASSERT_GT(with_roi.size(), 500u);
  EXPECT_LT(worst_distance(with_roi), 1.0);
  EXPECT_LE(worst_distance(with_roi), worst_distance(clean) + 0.05);
  EXPECT_LT((with_roi.front() - truth.front()).norm(), 3.0);  // from the clamped end
  EXPECT_LT((with_roi.back() - truth.back()).norm(), 3.0);

  spec.roi.reset();
  cv::Mat1b mask(image.size(), uchar(255));
  mask(cv::Rect(0, top - 5, image.cols, 110)).setTo(0);
  spec.mask = dir_.File("out/mask.png");
  WriteImageFile(spec.mask, mask);
  const std::vector<Eigen::Vector2d> with_mask =
      ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
  ASSERT_GT(with_mask.size(), 500u);
  EXPECT_LT(worst_distance(with_mask), 1.0);
  EXPECT_LT((with_mask.front() - truth.front()).norm(), 3.0);
  EXPECT_LT((with_mask.back() - truth.back()).norm(), 3.0);

  // A mask in colour, or of another size than the camera's, is named.
  WriteImageFile(spec.mask, cv::Mat(image.size(), CV_8UC3, cv::Scalar::all(255)));
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(spec.mask + ": a mask must be a single-channel (grey) image, "
                                                "this one has 3 channels"));
  }
  WriteImageFile(spec.mask, cv::Mat1b(100, 200, uchar(255)));
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr(spec.mask + ": the mask is 200x100 px but camera front is 1280x1024"));
  }
  // A roi past the image: the extraction names the image and the roi.
  spec.mask.clear();
  spec.roi = std::array<int, 4>{0, 0, 2000, 100};
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const CentrelineError& e) {
    EXPECT_THAT(e.what(), HasSubstr(spec.file + ": centre-line extraction: roi [0, 2000) x "
                                                "[0, 100) is not inside the 1280x1024 px image"));
  }
}

TEST_F(ImageObservationsTest, BadImagesAreOneLineErrors) {
  ObservationSpec spec = ex_.cases[0].observations[0];
  spec.file = dir_.File("out/missing.png");
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(spec.file + ": cannot read the image"));
  }
  spec.file = dir_.Write("out/not_an_image.png", "hello");
  EXPECT_THROW(ImagePointsFromImage(spec, front_, ex_.scene.cases[0]), InputError);

  // An image of another size than the camera's.
  spec.file = dir_.File("out/small.png");
  cv::imwrite(spec.file, cv::Mat(100, 200, CV_8UC3, cv::Scalar(235, 235, 235)));
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the image is 200x100 px but camera front is 1280x1024"));
  }

  // A blank image: nothing to extract.
  spec.file = dir_.File("out/blank.png");
  cv::imwrite(spec.file, cv::Mat(1024, 1280, CV_8UC3, cv::Scalar(235, 235, 235)));
  try {
    ImagePointsFromImage(spec, front_, ex_.scene.cases[0]);
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr(spec.file));
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
  }
}

TEST_F(ImageObservationsTest, EncodeImageNeedsAKnownExtension) {
  const cv::Mat image(4, 4, CV_8UC3, cv::Scalar(1, 2, 3));
  EXPECT_FALSE(EncodeImage("x.png", image).empty());
  EXPECT_THROW(EncodeImage("x.unknown", image), InputError);
  EXPECT_THROW(EncodeImage("noextension", image), InputError);
}

}  // namespace
}  // namespace rodfit

namespace rodfit {
namespace {

// The header's size is read without decoding (PNG, BMP, JPEG), and an image whose header claims
// more than the limit is refused before the decoder would allocate it.
TEST(ImageHeader, SizeIsReadFromTheHeaderAndBoundedBeforeDecoding) {
  TempDir dir;
  std::vector<uchar> png, jpg, bmp;
  const cv::Mat image(48, 64, CV_8UC1, cv::Scalar(200));
  ASSERT_TRUE(cv::imencode(".png", image, png));
  ASSERT_TRUE(cv::imencode(".jpg", image, jpg));
  ASSERT_TRUE(cv::imencode(".bmp", image, bmp));
  for (const auto* bytes : {&png, &jpg, &bmp}) {
    int w = 0, h = 0;
    ASSERT_TRUE(ImageHeaderSize(std::string(bytes->begin(), bytes->end()), &w, &h));
    EXPECT_EQ(w, 64);
    EXPECT_EQ(h, 48);
  }
  int w = 0, h = 0;
  EXPECT_FALSE(ImageHeaderSize("not an image", &w, &h));
  // The same PNG with its header claiming 10000 x 10000 (100 M pixels): refused unread.
  std::string big(png.begin(), png.end());
  for (int at : {16, 20}) {
    big[at] = 0, big[at + 1] = 0, big[at + 2] = static_cast<char>(0x27),
    big[at + 3] = static_cast<char>(0x10);
  }
  const std::string path = dir.Write("big.png", big);
  try {
    ReadImageFile(path);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the image is 10000x10000 px, more than 16384 px a side or "
                                    "67108864 pixels (the limit)"));
  }
}

}  // namespace
}  // namespace rodfit
