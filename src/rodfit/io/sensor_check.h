// The check of an observed pixel against its camera's sensor, shared by the static image_points
// reader (fit_input.cc) and the pixel sequences of a moving experiment (marker_sequences.cc).
#pragma once

#include <algorithm>
#include <cstdio>
#include <string>

#include <Eigen/Core>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/observe/camera.h"

namespace rodfit {

/// An observed pixel must lie on its camera's sensor, give or take a quarter of the image (noise
/// added to samples near the border, refinement at the border): one farther out is not a pixel
/// of that camera (another camera's file, a value such as 1e308). Throws InputError naming the
/// row's line, the column u and the camera file.
inline void CheckOnSensor(const CsvTable& t, int row, const Eigen::Vector2d& uv, const Camera& cam,
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
