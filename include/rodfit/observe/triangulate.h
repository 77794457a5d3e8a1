// Triangulation of centre-line pixels from calibrated cameras (docs/solvers.md, "Observations":
// `points3d` from `images`). A point is triangulated by the linear DLT (Hartley & Zisserman §12.2)
// in undistorted normalised coordinates, then refined by capped Gauss–Newton on the pixel
// reprojection error. Two ordered centre-line polylines seen by two cameras are matched along
// epipolar lines: each pixel of polyline A gives the line E x_a in camera B's undistorted image
// plane (for a rectified pair, the same row); its crossings with polyline B are triangulated,
// and one crossing per pixel is chosen so that the positions along B are monotone (the longest
// such chain), which keeps the order of A and resolves lines that cross B several times.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "rodfit/observe/camera.h"

namespace rodfit {

struct TriangulationOptions {
  int max_iterations = 10;         ///< Gauss–Newton iterations after the DLT (cap)
  double step_tolerance = 1e-12;   ///< [m] stop when the update is below this (times 1 + |p|)
};

/// One pixel observation of a point in one camera (the camera must outlive the call).
struct PixelView {
  const Camera* camera = nullptr;
  Eigen::Vector2d uv;  ///< [px]
};

struct TriangulatedPoint {
  bool ok = false;  ///< false: < 2 views, undistortion failed, rays parallel, point behind a camera
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  ///< [m]
  double rms_error_px = 0.0;  ///< RMS over views of the pixel reprojection error
  double max_error_px = 0.0;  ///< largest reprojection error over views
  int iterations = 0;         ///< Gauss–Newton iterations taken
};

/// Linear (DLT) triangulation from two or more views; false if degenerate.
bool TriangulateLinear(const std::vector<PixelView>& views, Eigen::Vector3d* p_world);

/// DLT followed by Gauss–Newton on the reprojection error.
TriangulatedPoint Triangulate(const std::vector<PixelView>& views,
                              const TriangulationOptions& options = {});
TriangulatedPoint Triangulate(const Camera& camera_a, const Eigen::Vector2d& uv_a,
                              const Camera& camera_b, const Eigen::Vector2d& uv_b,
                              const TriangulationOptions& options = {});

struct PolylineMatchOptions {
  double max_reprojection_error_px = 1.0;  ///< drop points whose RMS error exceeds this [px]
  TriangulationOptions triangulation;
};

/// One matched pixel of polyline A.
struct PolylineMatch {
  int index_a = 0;            ///< index of the pixel in polyline A
  double position_b = 0.0;    ///< crossing on B: segment index + fraction in [0, 1]
  Eigen::Vector2d uv_b;       ///< crossing pixel in camera B [px]
  Eigen::Vector3d p_world;    ///< [m]
  double error_px = 0.0;      ///< RMS reprojection error over the two views [px]
};

struct PolylineMatchResult {
  std::vector<PolylineMatch> points;  ///< in the order of polyline A (index_a increasing)
  int num_no_crossing = 0;   ///< pixels of A whose epipolar line misses B (or not undistortable)
  int num_failed = 0;        ///< crossings only triangulating behind a camera / degenerate
  int num_rejected = 0;      ///< reprojection error above the threshold
  int num_unordered = 0;     ///< pixels whose crossings all break the order along B
};

/// Matches the ordered pixel polylines a (camera_a) and b (camera_b) into 3-D points.
/// B may run in either direction relative to A. Cameras must not share their optical centre.
PolylineMatchResult MatchPolylines(const Camera& camera_a,
                                   const std::vector<Eigen::Vector2d>& polyline_a,
                                   const Camera& camera_b,
                                   const std::vector<Eigen::Vector2d>& polyline_b,
                                   const PolylineMatchOptions& options = {});

}  // namespace rodfit
