// Images -> image_points and points3d (see image_observations.h).
#include "rodfit/io/image_observations.h"

#include <cstdio>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"

namespace rodfit {
namespace {

std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", v);
  return buffer;
}

}  // namespace

cv::Mat ReadImageFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw InputError(path, 0, "", "cannot read the image: no such file");
  }
  // A directory, device or FIFO, or a file past the bound, never reaches the decoder.
  CheckInputFile(path, "an image file");
  cv::Mat image;
  try {
    image = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) throw InputError(path, 0, "", "cannot read the image: not an image OpenCV reads");
  return image;
}

std::string EncodeImage(const std::string& path, const cv::Mat& image) {
  const std::string extension = std::filesystem::path(path).extension().string();
  std::vector<uchar> bytes;
  bool ok = false;
  try {
    ok = !extension.empty() && cv::imencode(extension, image, bytes);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) {
    throw InputError(path, 0, "", "cannot encode an image as '" + extension +
                                      "' (use .png, .jpg, .bmp or .tif)");
  }
  return std::string(bytes.begin(), bytes.end());
}

void WriteImageFile(const std::string& path, const cv::Mat& image) {
  WriteFileAtomically(path, EncodeImage(path, image));
}

CentrelineResult ExtractCentrelineFromFile(const std::string& path, const Camera& camera,
                                           CentrelineOptions options) {
  const cv::Mat image = ReadImageFile(path);
  if (image.cols != camera.K.width || image.rows != camera.K.height) {
    throw InputError(path, 0, "",
                     "the image is " + std::to_string(image.cols) + "x" +
                         std::to_string(image.rows) + " px but camera " + camera.name + " is " +
                         std::to_string(camera.K.width) + "x" + std::to_string(camera.K.height));
  }
  if (options.image_name.empty()) options.image_name = path;
  CentrelineResult result = ExtractCentreline(image, options);
  if (result.uv.empty()) throw InputError(path, 0, "", "no centre-line extracted");
  return result;
}

std::vector<Eigen::Vector2d> ImagePointsFromImage(const ObservationSpec& spec,
                                                  const Camera& camera,
                                                  const LoadCase& load_case,
                                                  const CentrelineOptions& options,
                                                  CentrelineResult* result) {
  CentrelineOptions o = options;
  Eigen::Vector2d clamp_uv;
  if (Project(camera, load_case.clamp.position, &clamp_uv)) o.start_hint = clamp_uv;
  CentrelineResult extracted = ExtractCentrelineFromFile(spec.file, camera, o);
  std::vector<Eigen::Vector2d> uv = extracted.uv;
  if (result) *result = std::move(extracted);
  return uv;
}

std::vector<Eigen::Vector3d> TriangulateCentrelines(
    const Camera& camera_a, const std::vector<Eigen::Vector2d>& uv_a, const Camera& camera_b,
    const std::vector<Eigen::Vector2d>& uv_b, const std::string& name_a,
    const std::string& name_b, const PolylineMatchOptions& options, PolylineMatchResult* result) {
  const PolylineMatchResult match = MatchPolylines(camera_a, uv_a, camera_b, uv_b, options);
  if (match.points.empty()) {
    throw InputError(name_a, 0, "",
                     "no centre-line point matched in " + name_b + " (" +
                         std::to_string(match.num_no_crossing) + " without an epipolar crossing, " +
                         std::to_string(match.num_rejected) + " above " +
                         Show(options.max_reprojection_error_px) +
                         " px reprojection error, " + std::to_string(match.num_failed) +
                         " degenerate)");
  }
  std::vector<Eigen::Vector3d> points;
  points.reserve(match.points.size());
  for (const PolylineMatch& m : match.points) points.push_back(m.p_world);
  if (result) *result = match;
  return points;
}

std::vector<Eigen::Vector3d> TriangulatedPoints(
    const ObservationSpec& spec_a, const Camera& camera_a, const ObservationSpec& spec_b,
    const Camera& camera_b, const LoadCase& load_case, const CentrelineOptions& options,
    const PolylineMatchOptions& match_options, PolylineMatchResult* result) {
  const std::vector<Eigen::Vector2d> uv_a =
      ImagePointsFromImage(spec_a, camera_a, load_case, options);
  const std::vector<Eigen::Vector2d> uv_b =
      ImagePointsFromImage(spec_b, camera_b, load_case, options);
  return TriangulateCentrelines(camera_a, uv_a, camera_b, uv_b, spec_a.file, spec_b.file,
                                match_options, result);
}

}  // namespace rodfit
