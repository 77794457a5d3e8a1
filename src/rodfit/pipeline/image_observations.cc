// Images -> image_points and points3d (see image_observations.h).
#include "rodfit/pipeline/image_observations.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/image_files.h"

namespace rodfit {
namespace {

std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", v);
  return buffer;
}

}  // namespace

// Declared in io/experiment.h beside CameraKey, defined here with the other code that reads
// cameras: the experiment reader then links no OpenCV, and neither does `rodfit simulate`
// (docs/cli.md, "Start-up").
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
  if (spec.roi) {
    const std::array<int, 4>& c = *spec.roi;
    o.roi = cv::Rect(c[0], c[1], c[2] - c[0], c[3] - c[1]);
  }
  if (!spec.mask.empty()) o.mask = ReadMaskFile(spec.mask, camera);
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
