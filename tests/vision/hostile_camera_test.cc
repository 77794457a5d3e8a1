// Hostile camera files: a file nested 50,000 levels deep in YAML, JSON or XML, or one
// larger than a camera file can be, is refused with one line naming the file before it reaches
// cv::FileStorage (whose parsers overflow the stack on such nesting); absurd distortion
// coefficients and intrinsics are refused by name instead of failing the fit later.
#include <cstdio>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/vision/camera_file.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

std::string DataPath(const std::string& name) {
  return std::string(RODFIT_SOURCE_DIR) + "/tests/data/cameras/" + name;
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Writes `text` to a file of this test and returns LoadCamera's error ("" and a failure if none).
std::string LoadError(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "hostile_camera_" + name;
  std::ofstream(path, std::ios::binary) << text;
  std::string message;
  try {
    LoadCamera(path);
    ADD_FAILURE() << name << " was accepted";
  } catch (const CameraFileError& e) {
    message = e.what();
    EXPECT_THAT(message, StartsWith(path + ": ")) << name;
    EXPECT_EQ(message.find('\n'), std::string::npos);
    EXPECT_LE(message.size(), path.size() + 200);
  }
  std::remove(path.c_str());
  return message;
}

std::string Repeat(const std::string& s, int n) {
  std::string out;
  out.reserve(s.size() * n);
  for (int i = 0; i < n; ++i) out += s;
  return out;
}

TEST(HostileCamera, DeepNestingNeverReachesOpenCV) {
  const int n = 50000;
  EXPECT_THAT(LoadError("deep.json", "{\"a\": " + Repeat("[", n) + Repeat("]", n) + "}\n"),
              HasSubstr("nested"));
  EXPECT_THAT(LoadError("deep_flow.yaml", "%YAML:1.0\na: " + Repeat("[", n) + "\n"),
              HasSubstr("nested"));
  EXPECT_THAT(LoadError("deep.xml", "<?xml version=\"1.0\"?>\n<opencv_storage>" +
                                        Repeat("<a>", n) + Repeat("</a>", n) +
                                        "</opencv_storage>\n"),
              HasSubstr("nested"));
  // Block YAML nested by indentation and by "- - -" entries.
  std::string block = "%YAML:1.0\n";
  for (int i = 0; i < 200; ++i) block += std::string(i, ' ') + "k:\n";
  EXPECT_THAT(LoadError("deep_block.yaml", block), HasSubstr("nested"));
  EXPECT_THAT(LoadError("deep_dash.yaml", "a:\n" + Repeat("- ", 500) + "1\n"),
              HasSubstr("nested"));
  // The sample files, a few levels deep, still load.
  for (const char* file : {"opencv_sample.yaml", "opencv_tutorial.xml", "camera_rt.json",
                           "ros_camera_info.yaml"}) {
    SCOPED_TRACE(file);
    EXPECT_NO_THROW(LoadCamera(DataPath(file)));
  }
}

TEST(HostileCamera, FileLargerThanOneMebibyteIsRefused) {
  // A valid camera padded with a comment past the bound: refused by size, not parsed.
  const std::string text =
      ReadAll(DataPath("opencv_sample.yaml")) + "# " + std::string(1 << 20, 'x') + "\n";
  EXPECT_THAT(LoadError("big.yaml", text), HasSubstr("too large"));
}

TEST(HostileCamera, AbsurdDistortionAndIntrinsicsAreRefused) {
  const std::string sample = ReadAll(DataPath("opencv_sample.yaml"));
  auto with = [&](const std::string& from, const std::string& to) {
    std::string text = sample;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    return text;
  };
  std::string message = LoadError("k1.yaml", with("-2.71e-01, 8.3e-02", "1.0e+300, 8.3e-02"));
  EXPECT_THAT(message, HasSubstr("distortion_coefficients: coefficient k1 = 1e+300 is absurd"));
  message = LoadError("p2.yaml", with("-1.7e-04", "-2.0e+07"));
  EXPECT_THAT(message, HasSubstr("coefficient p2 = -2e+07 is absurd"));
  message = LoadError("k_inf.yaml", with("-2.71e-01, 8.3e-02", ".Inf, 8.3e-02"));
  EXPECT_THAT(message, HasSubstr("distortion_coefficients: non-finite value"));
  message = LoadError("fx.yaml", with("1.2105e+03", "1.0e+200"));
  EXPECT_THAT(message, HasSubstr("camera_matrix: focal length 1e+200 px is absurd"));
  message = LoadError("cx.yaml", with("6.432e+02", "-1.0e+250"));
  EXPECT_THAT(message, HasSubstr("camera_matrix: principal point"));
}

}  // namespace
}  // namespace rodfit
