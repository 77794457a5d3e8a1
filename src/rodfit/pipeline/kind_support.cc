// What the observation kinds share (kind_support.h).
#include "rodfit/pipeline/kind_support.h"

#include <algorithm>
#include <cstdio>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/image_files.h"

namespace rodfit {

const Camera& CameraCache::Get(const ObservationSpec& spec) {
  auto it = cameras_.find(CameraKey(spec));
  if (it == cameras_.end())
    it = cameras_.emplace(CameraKey(spec), LoadObservationCamera(spec)).first;
  return it->second;
}

std::string Short(double v) {
  char b[32];
  std::snprintf(b, sizeof(b), "%.10g", v);
  return b;
}

void CheckReach(const CsvTable& t, int row, const Eigen::Vector3d& p, const Vec3& clamp,
                double length, const char* column, double lengths) {
  const double d = (p - clamp).norm();
  if (!(d <= lengths * length)) {
    char b[160];
    std::snprintf(b, sizeof(b),
                  "the point lies %.3g m from the clamp, more than %.0f rod lengths (%.6g m): "
                  "not on the rod (wrong units or frame?)",
                  d, lengths, length);
    throw InputError(t.name(), t.line(row), column, b);
  }
}

void CheckArcLength(const CsvTable& t, int row, double s, double length) {
  if (!(s >= -1e-12 * length && s <= length * (1 + 1e-12)))
    throw InputError(t.name(), t.line(row), "s",
                     "marker arc length " + Short(s) + " m is outside [0, " + Short(length) + "]");
}

void CheckSpread(const std::string& file, const std::string& what,
                 const std::vector<Eigen::Vector3d>& points, double length) {
  if (points.empty()) return;
  Eigen::Vector3d low = points[0], high = points[0];
  for (const Eigen::Vector3d& p : points) low = low.cwiseMin(p), high = high.cwiseMax(p);
  const double spread = (high - low).norm();
  if (spread > 100.0 * length) {
    char b[96];
    std::snprintf(b, sizeof(b), " spread over %.3g m, %.0f x the rod length ", spread,
                  spread / length);
    throw InputError(
        file, 0, "",
        what + b + Short(length) + " m: millimetres given as metres? (x, y, z are in m)");
  }
}

void CheckPointsOnRod(const CsvTable& t, const std::string& what,
                      const std::vector<Eigen::Vector3d>& points, const Vec3& clamp,
                      double length) {
  for (int r = 0; r < static_cast<int>(points.size()); ++r)
    CheckReach(t, r, points[r], clamp, length, "x", kAbsurdReachLengths);
  CheckSpread(t.name(), what, points, length);
  for (int r = 0; r < static_cast<int>(points.size()); ++r)
    CheckReach(t, r, points[r], clamp, length);
}

void CheckOnSensor(const CsvTable& t, int row, const Eigen::Vector2d& uv, const Camera& cam,
                   const std::string& camera_file) {
  if (!cam.InImage(uv, -0.25 * std::max(cam.K.width, cam.K.height))) {
    char b[64];
    std::snprintf(b, sizeof(b), "pixel (%.6g, %.6g)", uv.x(), uv.y());
    throw InputError(t.name(), t.line(row), "u",
                     std::string(b) + " lies outside the " + std::to_string(cam.K.width) + "x" +
                         std::to_string(cam.K.height) + " image of camera " +
                         ClipForMessage(camera_file));
  }
}

}  // namespace rodfit
