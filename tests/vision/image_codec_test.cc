// rodfit's image codec (vision/image_codec.h) against OpenCV's imgcodecs as an independent
// decoder and encoder: what one writes the other reads back, sample for sample where the format
// is lossless; sizes beyond the limits and broken files are refused with a reason.
#include "rodfit/vision/image_codec.h"

#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace rodfit {
namespace {

using ::testing::HasSubstr;

constexpr int kSide = 16384;
constexpr long long kPixels = 1LL << 26;

// A deterministic image with every channel different and gradients in both directions (so a
// swapped channel, flipped row order or lost 16-bit byte shows).
cv::Mat Pattern(int rows, int cols, int depth, int channels) {
  cv::Mat m(rows, cols, CV_MAKETYPE(depth, channels));
  const int top = depth == CV_16U ? 65535 : 255;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      for (int k = 0; k < channels; ++k) {
        const int v = (r * 37 + c * 11 + k * 71 + r * c * 3) % (top + 1);
        if (depth == CV_16U) {
          m.ptr<unsigned short>(r)[c * channels + k] = static_cast<unsigned short>(v * 257 % 65536);
        } else {
          m.ptr<unsigned char>(r)[c * channels + k] = static_cast<unsigned char>(v);
        }
      }
    }
  }
  return m;
}

double MaxDifference(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return -1.0;
  return cv::norm(a, b, cv::NORM_INF);
}

std::string ToString(const std::vector<uchar>& v) { return std::string(v.begin(), v.end()); }

cv::Mat CvDecode(const std::string& bytes) {
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8U,
                       const_cast<char*>(bytes.data()));
  return cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
}

struct Lossless {
  ImageFormat format;
  const char* extension;
  int depth;
  int channels;
};

class LosslessRoundTrip : public ::testing::TestWithParam<Lossless> {};

TEST_P(LosslessRoundTrip, OursAndOpenCvReadEachOthersFilesExactly) {
  const Lossless p = GetParam();
  const cv::Mat image = Pattern(23, 37, p.depth, p.channels);
  std::string ours, why;
  ASSERT_TRUE(EncodeImageBytes(p.format, image, &ours, &why)) << why;
  EXPECT_EQ(SniffImageFormat(ours), p.format);
  // Ours -> ours, ours -> OpenCV.
  cv::Mat back;
  ASSERT_TRUE(DecodeImageBytes(ours, kSide, kPixels, &back, &why)) << why;
  EXPECT_EQ(MaxDifference(back, image), 0.0);
  if (p.format == ImageFormat::kTiff && p.channels == 4 && p.depth == CV_8U) {
    // OpenCV reads 8-bit RGBA TIFF through libtiff's RGBA interface, which multiplies the colour
    // by an unassociated alpha (the file stores it unmultiplied, as written and read back above).
    cv::Mat premultiplied = image.clone();
    for (int r = 0; r < image.rows; ++r) {
      for (int c = 0; c < image.cols; ++c) {
        cv::Vec4b& v = premultiplied.at<cv::Vec4b>(r, c);
        for (int k = 0; k < 3; ++k) v[k] = static_cast<uchar>(v[k] * v[3] / 255.0 + 0.5);
      }
    }
    EXPECT_LE(MaxDifference(CvDecode(ours), premultiplied), 1.0);
  } else {
    EXPECT_EQ(MaxDifference(CvDecode(ours), image), 0.0);
  }
  // OpenCV -> ours.
  std::vector<uchar> theirs;
  ASSERT_TRUE(cv::imencode(p.extension, image, theirs));
  ASSERT_TRUE(DecodeImageBytes(ToString(theirs), kSide, kPixels, &back, &why)) << why;
  EXPECT_EQ(MaxDifference(back, image), 0.0);
}

INSTANTIATE_TEST_SUITE_P(
    Formats, LosslessRoundTrip,
    ::testing::Values(Lossless{ImageFormat::kPng, ".png", CV_8U, 1},
                      Lossless{ImageFormat::kPng, ".png", CV_8U, 3},
                      Lossless{ImageFormat::kPng, ".png", CV_8U, 4},
                      Lossless{ImageFormat::kPng, ".png", CV_16U, 1},
                      Lossless{ImageFormat::kPng, ".png", CV_16U, 3},
                      Lossless{ImageFormat::kTiff, ".tif", CV_8U, 1},
                      Lossless{ImageFormat::kTiff, ".tif", CV_8U, 3},
                      Lossless{ImageFormat::kTiff, ".tif", CV_8U, 4},
                      Lossless{ImageFormat::kTiff, ".tif", CV_16U, 1},
                      Lossless{ImageFormat::kTiff, ".tif", CV_16U, 3},
                      Lossless{ImageFormat::kBmp, ".bmp", CV_8U, 1},
                      Lossless{ImageFormat::kBmp, ".bmp", CV_8U, 3}));

TEST(ImageCodecTest, JpegMatchesOpenCvWithinQuantisation) {
  // A smooth image (JPEG's case); both decoders use libjpeg's inverse DCT, so the same bytes
  // decode to within a grey level of each other, and the image to within JPEG's error.
  cv::Mat image(48, 64, CV_8UC3);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      image.at<cv::Vec3b>(r, c) = cv::Vec3b(static_cast<uchar>(2 * c), static_cast<uchar>(3 * r),
                                            static_cast<uchar>(100 + r + c));
    }
  }
  for (const cv::Mat& input : {image, Pattern(48, 64, CV_8U, 1)}) {
    std::string ours, why;
    ASSERT_TRUE(EncodeImageBytes(ImageFormat::kJpeg, input, &ours, &why)) << why;
    cv::Mat back;
    ASSERT_TRUE(DecodeImageBytes(ours, kSide, kPixels, &back, &why)) << why;
    ASSERT_EQ(back.type(), input.type());
    EXPECT_LE(MaxDifference(back, CvDecode(ours)), 1.0);
    if (input.channels() == 3) {
      EXPECT_LE(MaxDifference(back, input), 8.0);
    }
    std::vector<uchar> theirs;
    ASSERT_TRUE(cv::imencode(".jpg", input, theirs));
    ASSERT_TRUE(DecodeImageBytes(ToString(theirs), kSide, kPixels, &back, &why)) << why;
    EXPECT_LE(MaxDifference(back, CvDecode(ToString(theirs))), 1.0);
  }
}

TEST(ImageCodecTest, Bgra16BitPngKeepsChannelOrderAndBytes) {
  // 16-bit colour with alpha: channel order (BGRA in memory, RGBA in the file) and byte order
  // (big-endian in the file) both show in a pattern whose channels and bytes all differ.
  const cv::Mat bgra = Pattern(9, 13, CV_16U, 4);
  std::string ours, why;
  ASSERT_TRUE(EncodeImageBytes(ImageFormat::kPng, bgra, &ours, &why)) << why;
  cv::Mat back;
  ASSERT_TRUE(DecodeImageBytes(ours, kSide, kPixels, &back, &why)) << why;
  EXPECT_EQ(MaxDifference(back, bgra), 0.0);
  EXPECT_EQ(MaxDifference(CvDecode(ours), bgra), 0.0);
}

TEST(ImageCodecTest, RefusesSizesBeyondTheLimitsBeforeDecoding) {
  std::string bytes, why;
  ASSERT_TRUE(EncodeImageBytes(ImageFormat::kPng, Pattern(40, 30, CV_8U, 1), &bytes, &why));
  cv::Mat image;
  EXPECT_FALSE(DecodeImageBytes(bytes, 32, kPixels, &image, &why));
  EXPECT_THAT(why, HasSubstr("30x40 px, more than 32 px a side"));
  EXPECT_TRUE(image.empty());
  for (ImageFormat f : {ImageFormat::kJpeg, ImageFormat::kTiff, ImageFormat::kBmp}) {
    ASSERT_TRUE(EncodeImageBytes(f, Pattern(40, 30, CV_8U, 3), &bytes, &why));
    EXPECT_FALSE(DecodeImageBytes(bytes, kSide, 1000, &image, &why));
    EXPECT_THAT(why, HasSubstr("1000 pixels (the limit)"));
  }
}

TEST(ImageCodecTest, BrokenFilesAreRefusedWithAReason) {
  cv::Mat image;
  std::string why;
  EXPECT_FALSE(DecodeImageBytes("not an image at all", kSide, kPixels, &image, &why));
  EXPECT_THAT(why, HasSubstr("not a PNG, JPEG, TIFF or BMP image"));
  for (ImageFormat f : {ImageFormat::kPng, ImageFormat::kJpeg, ImageFormat::kTiff,
                        ImageFormat::kBmp}) {
    std::string bytes;
    ASSERT_TRUE(EncodeImageBytes(f, Pattern(64, 64, CV_8U, 3), &bytes, &why));
    // Cut inside the header, then inside the pixels: a reason, never a crash.
    for (size_t keep : {size_t{12}, bytes.size() / 3}) {
      why.clear();
      const bool ok = DecodeImageBytes(bytes.substr(0, keep), kSide, kPixels, &image, &why);
      if (!ok) {
        EXPECT_FALSE(why.empty());
        EXPECT_TRUE(image.empty());
      } else {
        // libjpeg fills a truncated scan with grey (a warning, as OpenCV also accepts it).
        EXPECT_EQ(f, ImageFormat::kJpeg);
        EXPECT_EQ(image.size(), cv::Size(64, 64));
      }
    }
  }
}

TEST(ImageCodecTest, EncodingNeedsAKnownFormatAndSupportedSamples) {
  std::string bytes, why;
  EXPECT_FALSE(EncodeImageBytes(ImageFormat::kUnknown, Pattern(4, 4, CV_8U, 1), &bytes, &why));
  EXPECT_FALSE(EncodeImageBytes(ImageFormat::kJpeg, Pattern(4, 4, CV_16U, 1), &bytes, &why));
  EXPECT_FALSE(EncodeImageBytes(ImageFormat::kPng, cv::Mat(4, 4, CV_32FC1), &bytes, &why));
  EXPECT_FALSE(EncodeImageBytes(ImageFormat::kPng, cv::Mat(), &bytes, &why));
  EXPECT_EQ(ImageFormatFromExtension(".JPEG"), ImageFormat::kJpeg);
  EXPECT_EQ(ImageFormatFromExtension(".tiff"), ImageFormat::kTiff);
  EXPECT_EQ(ImageFormatFromExtension(".gif"), ImageFormat::kUnknown);
}

}  // namespace
}  // namespace rodfit
