// Tests of the synthetic thread renderer (vision/render.h): analytic coverage values, the
// unbiased mid-line, ink conservation for threads thinner than a pixel, blur and noise
// statistics, determinism of the seeded noise and the input checks.
#include "rodfit/vision/render.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;

RenderOptions Small() {
  RenderOptions o;
  o.width = 200;
  o.height = 160;
  return o;
}

// A horizontal thread across the whole image at row y.
cv::Mat Horizontal(double y, double half_width, const RenderOptions& o) {
  return RenderThreadImage({Vec2(-10, y), Vec2(o.width + 10, y)}, {half_width, half_width}, o);
}

// Darkness of column x in units of full thread contrast, and its centroid row.
void ColumnInk(const cv::Mat& img, int x, double* ink, double* centroid) {
  double sum = 0, sum_y = 0;
  for (int y = 0; y < img.rows; ++y) {
    const double d = (235.0 - img.at<cv::Vec3b>(y, x)[1]) / (235.0 - 40.0);
    sum += d;
    sum_y += d * y;
  }
  *ink = sum;
  *centroid = sum > 0 ? sum_y / sum : 0.0;
}

TEST(RenderTest, ProducesBgrImageOfRequestedSize) {
  const RenderOptions o = Small();
  const cv::Mat img = Horizontal(80, 3, o);
  EXPECT_EQ(img.type(), CV_8UC3);
  EXPECT_EQ(img.rows, 160);
  EXPECT_EQ(img.cols, 200);
  EXPECT_EQ(img.at<cv::Vec3b>(10, 100), cv::Vec3b(235, 235, 235));
  EXPECT_EQ(img.at<cv::Vec3b>(80, 100), cv::Vec3b(40, 40, 40));
}

TEST(RenderTest, CoverageIsTheBoxFilteredEdge) {
  // Edge of a half-width 2 thread at y = 50.25: the pixel row 48 (centre 2.25 px from the
  // centre-line) is covered by a quarter, row 52 (1.75 px) by three quarters.
  const cv::Mat img = Horizontal(50.25, 2.0, Small());
  EXPECT_NEAR(img.at<cv::Vec3b>(48, 100)[0], 235 - 0.25 * 195, 0.51);
  EXPECT_NEAR(img.at<cv::Vec3b>(52, 100)[0], 235 - 0.75 * 195, 0.51);
  EXPECT_EQ(img.at<cv::Vec3b>(47, 100)[0], 235);
  EXPECT_EQ(img.at<cv::Vec3b>(50, 100)[0], 40);
  EXPECT_EQ(img.at<cv::Vec3b>(53, 100)[0], 235);
}

TEST(RenderTest, MidLineIsUnbiasedAndInkIsConservedAtAnyWidth) {
  // Ink per column = 2 w for every half-width, including those below min_half_width that are
  // drawn wider and fainter (tolerance: 8-bit rounding). Pixels integrate over their area, so
  // the sampled centroid of a strip differs from its centre by at most 1/8 px per edge over the
  // ink, 1 / (8 w_drawn), depending on the sub-pixel offset — a real camera's aliasing — and
  // averages out over offsets.
  for (double w : {0.3, 0.5, 0.8, 1.5, 4.0}) {
    const double w_drawn = std::max(w, RenderOptions().min_half_width);
    double mean_error = 0;
    for (int k = 0; k < 10; ++k) {
      const double y = 70 + 0.1 * k;
      double ink, centroid;
      ColumnInk(Horizontal(y, w, Small()), 100, &ink, &centroid);
      EXPECT_NEAR(ink, 2 * w, 0.03 + 0.02 * w) << "w " << w << " at " << y;
      EXPECT_NEAR(centroid, y, 1.0 / (8 * w_drawn) + 0.01) << "w " << w << " at " << y;
      mean_error += (centroid - y) / 10;
    }
    EXPECT_NEAR(mean_error, 0.0, 0.01) << "w " << w;
  }
}

TEST(RenderTest, ThinThreadIsVisibleAtLeastOnePointFivePixelsWide) {
  const cv::Mat img = Horizontal(70.5, 0.3, Small());
  EXPECT_LT(img.at<cv::Vec3b>(70, 100)[0], 235 - 40);
  EXPECT_LT(img.at<cv::Vec3b>(71, 100)[0], 235 - 40);
}

TEST(RenderTest, DiagonalThreadCentroidAcrossTheNormal) {
  // A 30 degree line: the ink centroid of each column lies on the line.
  RenderOptions o = Small();
  const double slope = std::tan(30.0 * M_PI / 180.0);
  const cv::Mat img = RenderThreadImage({Vec2(-20, 20 - 20 * slope), Vec2(220, 20 + 220 * slope)},
                                        {2.0, 2.0}, o);
  for (int x = 40; x < 140; x += 7) {
    double ink, centroid;
    ColumnInk(img, x, &ink, &centroid);
    EXPECT_NEAR(centroid, 20 + x * slope, 0.05) << "column " << x;
    EXPECT_NEAR(ink, 4.0 / std::cos(30.0 * M_PI / 180.0), 0.1) << "column " << x;
  }
}

TEST(RenderTest, TaperedWidthFollowsTheVertices) {
  const RenderOptions o = Small();
  const cv::Mat img = RenderThreadImage({Vec2(20, 80), Vec2(180, 80)}, {1.0, 5.0}, o);
  double ink_a, ink_b, c;
  ColumnInk(img, 60, &ink_a, &c);   // w = 2
  ColumnInk(img, 140, &ink_b, &c);  // w = 4
  EXPECT_NEAR(ink_a, 4.0, 0.1);
  EXPECT_NEAR(ink_b, 8.0, 0.1);
}

TEST(RenderTest, BlurKeepsInkAndNoiseHasTheRequestedSigma) {
  RenderOptions o = Small();
  o.blur_sigma = 1.5;
  double ink, centroid;
  ColumnInk(Horizontal(70.3, 1.0, o), 100, &ink, &centroid);
  EXPECT_NEAR(ink, 2.0, 0.05);
  EXPECT_NEAR(centroid, 70.3, 0.05);

  o.blur_sigma = 0;
  o.noise_sigma = 5;
  o.seed = 11;
  const cv::Mat img = Horizontal(150, 1.0, o);
  cv::Scalar mean, stddev;
  cv::meanStdDev(img(cv::Rect(0, 0, 200, 120)), mean, stddev);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(mean[c], 235, 0.2);   // 24000 samples: standard error 0.03
    EXPECT_NEAR(stddev[c], 5, 0.15);  // rounding to integers adds 1/12 to the variance
  }
}

TEST(RenderTest, SameSeedSameBytesAndOtherSeedOtherBytes) {
  RenderOptions o;
  o.blur_sigma = 1.0;
  o.noise_sigma = 4.0;
  o.seed = 7;
  const std::vector<Vec2> uv{Vec2(100, 100), Vec2(600, 700), Vec2(1200, 300)};
  const std::vector<double> w{1.0, 3.0, 2.0};
  const cv::Mat a = RenderThreadImage(uv, w, o), b = RenderThreadImage(uv, w, o);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  o.seed = 8;
  EXPECT_GT(cv::norm(a, RenderThreadImage(uv, w, o), cv::NORM_INF), 0.0);

  std::mt19937 rng1(42), rng2(42);
  o.rng = &rng1;
  const cv::Mat c = RenderThreadImage(uv, w, o);
  o.rng = &rng2;
  EXPECT_EQ(cv::norm(c, RenderThreadImage(uv, w, o), cv::NORM_INF), 0.0);
  EXPECT_EQ(rng1, rng2);
  EXPECT_NE(rng1, std::mt19937(42));  // the caller's generator was advanced
}

TEST(RenderTest, ClipsThreadsOutsideTheImage) {
  const RenderOptions o = Small();
  const cv::Mat img = RenderThreadImage({Vec2(-500, -500), Vec2(-100, 900)}, {3, 3}, o);
  EXPECT_EQ(cv::countNonZero(img.reshape(1) != 235), 0);
  const cv::Mat dot = RenderThreadImage({Vec2(50, 50)}, {3}, o);
  EXPECT_EQ(dot.at<cv::Vec3b>(50, 50)[0], 40);
}

TEST(RenderTest, RejectsBadInput) {
  const RenderOptions o = Small();
  EXPECT_THROW(RenderThreadImage({}, {}, o), std::invalid_argument);
  EXPECT_THROW(RenderThreadImage({Vec2(1, 1), Vec2(2, 2)}, {1.0}, o), std::invalid_argument);
  EXPECT_THROW(RenderThreadImage({Vec2(1, NAN)}, {1.0}, o), std::invalid_argument);
  EXPECT_THROW(RenderThreadImage({Vec2(1, 1)}, {-1.0}, o), std::invalid_argument);
  RenderOptions bad = o;
  bad.width = 0;
  EXPECT_THROW(RenderThreadImage({Vec2(1, 1)}, {1.0}, bad), std::invalid_argument);
  bad = o;
  bad.noise_sigma = -1;
  std::string why;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_NE(why.find("noise_sigma"), std::string::npos);
}

}  // namespace
}  // namespace rodfit
