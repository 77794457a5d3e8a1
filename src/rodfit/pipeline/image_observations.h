// Camera images -> observations the fit uses (docs/solvers.md, "Observations"), a pipeline step
// above vision (which works on cv::Mat only) and io (which reads the files): one image becomes
// `image_points` without s (the ordered centre-line pixels from ExtractCentreline, started at the
// clamped end by hinting the projected clamp position); two images of one case from two
// calibrated cameras become `points3d` by matching the two centre-lines along epipolar lines and
// triangulating (MatchPolylines). Errors name the image.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/image_files.h"
#include "rodfit/model/scene.h"
#include "rodfit/observe/camera.h"
#include "rodfit/observe/triangulate.h"
#include "rodfit/vision/centreline.h"

namespace rodfit {

/// ExtractCentreline on the image file `path` taken by `camera`. The image must have the camera's
/// size (InputError otherwise); options.image_name defaults to `path`. Throws InputError or
/// CentrelineError (one line, naming the image) when nothing can be extracted.
CentrelineResult ExtractCentrelineFromFile(const std::string& path, const Camera& camera,
                                           CentrelineOptions options = CentrelineOptions());

/// The `image_points` (u, v, without s) of an `images` entry of `load_case`: its centre-line
/// ordered from the end nearest the projected clamp position (when the clamp projects; else
/// options.start_hint or the border rule of ExtractCentreline), searched inside the entry's
/// `roi` and `mask` when it has them. `result`, if given, receives the
/// whole extraction (mask, widths, report) for overlays.
std::vector<Eigen::Vector2d> ImagePointsFromImage(const ObservationSpec& spec,
                                                  const Camera& camera,
                                                  const LoadCase& load_case,
                                                  const CentrelineOptions& options =
                                                      CentrelineOptions(),
                                                  CentrelineResult* result = nullptr);

/// Triangulates two ordered centre-lines seen by two cameras (MatchPolylines), in the order of
/// uv_a. Throws InputError naming `name_a` when no point matches. `result`, if given, receives
/// the match statistics.
std::vector<Eigen::Vector3d> TriangulateCentrelines(
    const Camera& camera_a, const std::vector<Eigen::Vector2d>& uv_a, const Camera& camera_b,
    const std::vector<Eigen::Vector2d>& uv_b, const std::string& name_a,
    const std::string& name_b, const PolylineMatchOptions& options = PolylineMatchOptions(),
    PolylineMatchResult* result = nullptr);

/// The `points3d` of a case with two `images` entries from two cameras: ImagePointsFromImage on
/// each, then TriangulateCentrelines, ordered from the clamped end.
std::vector<Eigen::Vector3d> TriangulatedPoints(
    const ObservationSpec& spec_a, const Camera& camera_a, const ObservationSpec& spec_b,
    const Camera& camera_b, const LoadCase& load_case,
    const CentrelineOptions& options = CentrelineOptions(),
    const PolylineMatchOptions& match_options = PolylineMatchOptions(),
    PolylineMatchResult* result = nullptr);

}  // namespace rodfit
