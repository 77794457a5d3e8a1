// Stereo calibration files as labs have them (vision/camera_file.h, LoadStereoCameras): the
// layout OpenCV's stereo_calib sample writes (intrinsics.yml with M1 D1 M2 D2, extrinsics.yml
// with R T R1 R2 P1 P2 Q, no image size), the K1/K2 and cv::stereoCalibrate spellings, in each
// of cv::FileStorage's three formats (YAML, XML, JSON; written here from the format's
// documentation, and once more by cv::FileStorage itself), with and without an image size. Each
// gives the pair tests/data/cameras/stereo.yaml holds; a missing size comes from the images (the
// caller's callback) and, without one, is an error naming the file and key.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "rodfit/vision/camera_file.h"

namespace rodfit {
namespace {

std::string DataPath(const std::string& name) {
  return std::string(RODFIT_SOURCE_DIR) + "/tests/data/cameras/" + name;
}

std::string WriteTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + "rodfit_stereo_" + name;
  std::ofstream(path) << text;
  return path;
}

// The values of tests/data/cameras/stereo.yaml, as matrices in row-major order.
struct Matrix {
  const char* key;
  int rows, cols;
  std::vector<double> data;
};
const std::vector<Matrix> kIntrinsics = {
    {"M1", 3, 3, {1210.5, 0, 643.2, 0, 1195.25, 481.7, 0, 0, 1}},
    {"D1", 1, 5, {-0.271, 0.083, 3.1e-4, -1.7e-4, -0.011}},
    {"M2", 3, 3, {1203.1, 0, 638.9, 0, 1201.9, 486.2, 0, 0, 1}},
    // Eight coefficients, as the sample's CALIB_RATIONAL_MODEL writes them (k4, k5, k6 zero).
    {"D2", 1, 8, {-0.265, 0.079, -1.2e-4, 2.2e-4, -9.0e-3, 0, 0, 0}}};
const std::vector<Matrix> kExtrinsics = {
    {"R", 3, 3, {0.93917728572814207, -0.021324650010645017, -0.34277001805035884,
                 0.017860378245771091, 0.99975255201679469, -0.013260528828977955,
                 0.34296797643692306, 0.0063319852992300991, 0.93932575451806521}},
    {"T", 3, 1, {-0.12, 1.0e-3, 2.5e-2}},
    // What stereoRectify adds (the sample writes them; rodfit ignores them).
    {"R1", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1}},
    {"R2", 3, 3, {1, 0, 0, 0, 1, 0, 0, 0, 1}},
    {"P1", 3, 4, {1200, 0, 640, 0, 0, 1200, 480, 0, 0, 0, 1, 0}},
    {"P2", 3, 4, {1200, 0, 640, -148, 0, 1200, 480, 0, 0, 0, 1, 0}},
    {"Q", 4, 4, {1, 0, 0, -640, 0, 1, 0, -480, 0, 0, 0, 1200, 0, 0, 8.1, 0}}};

// `key` renamed (M1 -> K1 ...) in a copy of `matrices`.
std::vector<Matrix> Renamed(std::vector<Matrix> matrices,
                            const std::vector<std::pair<const char*, const char*>>& names) {
  for (Matrix& m : matrices)
    for (const auto& [from, to] : names)
      if (std::string(m.key) == from) m.key = to;
  return matrices;
}

std::string Values(const Matrix& m, const char* separator) {
  std::string out;
  char buffer[40];
  for (size_t k = 0; k < m.data.size(); ++k) {
    std::snprintf(buffer, sizeof(buffer), "%.17g", m.data[k]);
    out += (k ? separator : "") + std::string(buffer);
  }
  return out;
}

// cv::FileStorage's YAML: the %YAML:1.0 directive, `---`, !!opencv-matrix maps of rows, cols,
// dt and data (the type tag of the OpenCV documentation's "XML/YAML/JSON file storages").
std::string Yaml(const std::vector<Matrix>& matrices, bool with_size) {
  std::string out = "%YAML:1.0\n---\n";
  if (with_size) out += "image_width: 1280\nimage_height: 960\n";
  for (const Matrix& m : matrices) {
    out += std::string(m.key) + ": !!opencv-matrix\n   rows: " + std::to_string(m.rows) +
           "\n   cols: " + std::to_string(m.cols) + "\n   dt: d\n   data: [ " + Values(m, ", ") +
           " ]\n";
  }
  return out;
}

// The XML form: <opencv_storage> with one element per key, type_id="opencv-matrix".
std::string Xml(const std::vector<Matrix>& matrices, bool with_size) {
  std::string out = "<?xml version=\"1.0\"?>\n<opencv_storage>\n";
  if (with_size) out += "<image_width>1280</image_width>\n<image_height>960</image_height>\n";
  for (const Matrix& m : matrices) {
    out += "<" + std::string(m.key) + " type_id=\"opencv-matrix\">\n  <rows>" +
           std::to_string(m.rows) + "</rows>\n  <cols>" + std::to_string(m.cols) +
           "</cols>\n  <dt>d</dt>\n  <data>\n    " + Values(m, " ") + "</data></" + m.key +
           ">\n";
  }
  return out + "</opencv_storage>\n";
}

// The JSON form: an object per matrix with "type_id": "opencv-matrix".
std::string Json(const std::vector<Matrix>& matrices, bool with_size) {
  std::string out = "{\n";
  if (with_size) out += "    \"image_width\": 1280,\n    \"image_height\": 960,\n";
  for (size_t k = 0; k < matrices.size(); ++k) {
    const Matrix& m = matrices[k];
    out += "    \"" + std::string(m.key) + "\": {\n        \"type_id\": \"opencv-matrix\",\n" +
           "        \"rows\": " + std::to_string(m.rows) + ",\n        \"cols\": " +
           std::to_string(m.cols) + ",\n        \"dt\": \"d\",\n        \"data\": [ " +
           Values(m, ", ") + " ]\n    }" + (k + 1 < matrices.size() ? ",\n" : "\n");
  }
  return out + "}\n";
}

std::vector<Matrix> Both(const std::vector<Matrix>& a, const std::vector<Matrix>& b) {
  std::vector<Matrix> out = a;
  out.insert(out.end(), b.begin(), b.end());
  return out;
}

void ExpectSamePair(const std::pair<Camera, Camera>& got, const std::pair<Camera, Camera>& want) {
  for (const auto& [a, b] : {std::make_pair(got.first, want.first),
                             std::make_pair(got.second, want.second)}) {
    EXPECT_EQ(a.K.fx, b.K.fx);
    EXPECT_EQ(a.K.fy, b.K.fy);
    EXPECT_EQ(a.K.cx, b.K.cx);
    EXPECT_EQ(a.K.cy, b.K.cy);
    EXPECT_EQ(a.K.k1, b.K.k1);
    EXPECT_EQ(a.K.k2, b.K.k2);
    EXPECT_EQ(a.K.p1, b.K.p1);
    EXPECT_EQ(a.K.p2, b.K.p2);
    EXPECT_EQ(a.K.k3, b.K.k3);
    EXPECT_EQ(a.K.width, b.K.width);
    EXPECT_EQ(a.K.height, b.K.height);
    EXPECT_LT((a.cam_from_world_R - b.cam_from_world_R).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_EQ(a.cam_from_world_t, b.cam_from_world_t);
  }
}

// The size the "images" give; counts its calls.
struct ImagesSize {
  int calls = 0;
  StereoFileOptions Options(const std::string& extrinsics = "") {
    StereoFileOptions options;
    options.extrinsics_path = extrinsics;
    options.image_size_when_absent = [this] {
      ++calls;
      return ImageSizePx{1280, 960};
    };
    return options;
  }
};

using Writer = std::string (*)(const std::vector<Matrix>&, bool);
struct Format {
  const char* extension;
  Writer write;
};
const Format kFormats[] = {{".yml", Yaml}, {".xml", Xml}, {".json", Json}};

TEST(StereoFile, TheSampleTwoFilesWithoutSizeInEveryFormat) {
  // intrinsics.yml (M1 D1 M2 D2) and extrinsics.yml (R T R1 R2 P1 P2 Q), as stereo_calib.cpp
  // writes them: no image size, so the images give it.
  const auto reference = LoadStereoCameras(DataPath("stereo.yaml"));
  for (const Format& f : kFormats) {
    SCOPED_TRACE(f.extension);
    const std::string intrinsics =
        WriteTemp(std::string("intrinsics") + f.extension, f.write(kIntrinsics, false));
    const std::string extrinsics =
        WriteTemp(std::string("extrinsics") + f.extension, f.write(kExtrinsics, false));
    ImagesSize images;
    const auto pair = LoadStereoCameras(intrinsics, images.Options(extrinsics));
    EXPECT_EQ(images.calls, 1);
    ExpectSamePair(pair, reference);
    EXPECT_EQ(pair.first.name, "rodfit_stereo_intrinsics[1]");
  }
}

TEST(StereoFile, EverySpellingWithAndWithoutSizeInEveryFormat) {
  const auto reference = LoadStereoCameras(DataPath("stereo.yaml"));
  const std::vector<std::vector<Matrix>> spellings = {
      Both(kIntrinsics, kExtrinsics),
      Both(Renamed(kIntrinsics, {{"M1", "K1"}, {"M2", "K2"}}), kExtrinsics),
      Both(Renamed(kIntrinsics, {{"M1", "cameraMatrix1"}, {"D1", "distCoeffs1"},
                                 {"M2", "cameraMatrix2"}, {"D2", "distCoeffs2"}}),
           kExtrinsics)};
  for (const Format& f : kFormats) {
    for (size_t s = 0; s < spellings.size(); ++s) {
      for (bool with_size : {true, false}) {
        SCOPED_TRACE(std::string(f.extension) + " spelling " + spellings[s][0].key +
                     (with_size ? " with size" : " without size"));
        const std::string path = WriteTemp("one" + std::to_string(s) + f.extension,
                                           f.write(spellings[s], with_size));
        ImagesSize images;
        ExpectSamePair(LoadStereoCameras(path, images.Options()), reference);
        // The images are read only when the file has no size.
        EXPECT_EQ(images.calls, with_size ? 0 : 1);
        if (with_size) ExpectSamePair(LoadStereoCameras(path), reference);
      }
    }
  }
}

TEST(StereoFile, FilesWrittenByFileStorageAsTheSampleDoes) {
  // `fs << "M1" << cameraMatrix[0] << "D1" << distCoeffs[0] ...`, then extrinsics: R, T.
  const auto reference = LoadStereoCameras(DataPath("stereo.yaml"));
  auto mat = [](const Matrix& m) {
    return cv::Mat(m.rows, m.cols, CV_64F, const_cast<double*>(m.data.data())).clone();
  };
  for (const char* extension : {".yml", ".xml", ".json"}) {
    SCOPED_TRACE(extension);
    const std::string intrinsics = ::testing::TempDir() + "rodfit_fs_intrinsics" + extension;
    const std::string extrinsics = ::testing::TempDir() + "rodfit_fs_extrinsics" + extension;
    {
      cv::FileStorage fs(intrinsics, cv::FileStorage::WRITE);
      for (const Matrix& m : kIntrinsics) fs << m.key << mat(m);
    }
    {
      cv::FileStorage fs(extrinsics, cv::FileStorage::WRITE);
      for (const Matrix& m : kExtrinsics) fs << m.key << mat(m);
    }
    ImagesSize images;
    ExpectSamePair(LoadStereoCameras(intrinsics, images.Options(extrinsics)), reference);
    EXPECT_EQ(images.calls, 1);
    std::remove(intrinsics.c_str());
    std::remove(extrinsics.c_str());
  }
}

// Loading fails with one line "PATH: KEY: ..." containing `fragment`.
void ExpectError(const std::string& path, const StereoFileOptions& options,
                 const std::string& error_file, const std::string& key,
                 const std::string& fragment) {
  try {
    LoadStereoCameras(path, options);
    ADD_FAILURE() << "no error";
  } catch (const CameraFileError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file, error_file);
    EXPECT_EQ(e.key, key);
    const std::string prefix = key.empty() ? error_file + ": " : error_file + ": " + key + ": ";
    EXPECT_EQ(what.rfind(prefix, 0), 0u) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(StereoFile, MistakesNameTheFileAndTheKey) {
  const std::string intrinsics = WriteTemp("e_intrinsics.yml", Yaml(kIntrinsics, false));
  const std::string extrinsics = WriteTemp("e_extrinsics.yml", Yaml(kExtrinsics, false));
  const std::string both = WriteTemp("e_both.yml", Yaml(Both(kIntrinsics, kExtrinsics), false));
  ImagesSize images;
  // No size and nothing to take it from: the file and image_width are named.
  StereoFileOptions no_images;
  no_images.extrinsics_path = extrinsics;
  ExpectError(intrinsics, no_images, intrinsics, "image_width", "the image size is required");
  ExpectError(both, {}, both, "image_width", "the image size is required");
  // R and T in neither file, or in both.
  ExpectError(intrinsics, images.Options(), intrinsics, "R", "missing");
  ExpectError(both, images.Options(extrinsics), both, "R", "extrinsics file");
  // A broken extrinsics file is named as such.
  std::vector<Matrix> short_t = kExtrinsics;
  short_t[1].rows = 2;
  short_t[1].data.pop_back();
  const std::string bad_t = WriteTemp("e_bad_t.yml", Yaml(short_t, false));
  ExpectError(intrinsics, images.Options(bad_t), bad_t, "T", "expected 3 values");
  const std::string no_t = WriteTemp("e_no_t.yml", Yaml({kExtrinsics[0]}, false));
  ExpectError(intrinsics, images.Options(no_t), no_t, "T", "missing");
  const std::string missing = ::testing::TempDir() + "rodfit_stereo_no_such_file.yml";
  ExpectError(intrinsics, images.Options(missing), missing, "", "cannot open");
  // Half a size is still an error, even when the images could give one.
  const std::string half =
      WriteTemp("e_half.yml", "image_width: 1280\n" + Yaml(kIntrinsics, false).substr(14));
  ImagesSize unused;
  ExpectError(half, unused.Options(extrinsics), half, "image_height", "missing");
  EXPECT_EQ(unused.calls, 0);
}

}  // namespace
}  // namespace rodfit
