// Reading calibrated cameras from OpenCV FileStorage files (docs/formats.md, "Camera files"): YAML
// with or without the %YAML:1.0 header, JSON and XML, in the key spellings labs have:
//  - rodfit / OpenCV calibration sample: camera_matrix, distortion_coefficients, image_width,
//    image_height (also cameraMatrix, distCoeffs / dist_coeffs, image_size: [w, h]);
//  - OpenCV tutorial: Camera_Matrix, Distortion_Coefficients, image_Width, image_Height;
//  - ROS camera_info YAML: camera_matrix / distortion_coefficients as {rows, cols, data},
//    distortion_model plumb_bob (or rational_polynomial with zero extra coefficients);
//  - stereo files (LoadStereoCameras): M1 D1 M2 D2 (OpenCV's stereo_calib sample) or K1 D1 K2 D2
//    or cameraMatrix1 distCoeffs1 cameraMatrix2 distCoeffs2, and R T with x_cam2 = R x_cam1 + T,
//    in one file or, as the sample writes them, in two (intrinsics.yml, extrinsics.yml); the
//    image size is optional there (neither the sample nor cv::stereoCalibrate writes one) and is
//    then taken from the pair's images.
// Matrices are !!opencv-matrix nodes, {rows, cols, data} maps, flat lists (row-major) or lists of
// rows. The world-to-camera pose is rvec/tvec (x_cam = R(rvec) x_world + tvec, Rodrigues) or R/T;
// no pose means the camera frame is the world frame. Distortion is OpenCV's (k1, k2, p1, p2[, k3])
// as in observe/camera.h; 8-, 12- and 14-vectors are accepted when the rational, thin-prism and
// tilt terms are zero. Translations are taken in metres (SI, docs/model.md, "Conventions") without
// conversion. Unknown keys are ignored: calibration tools write many (reprojection errors, per-view
// poses).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <utility>

#include "rodfit/model/markup_nesting.h"  // MarkupNestingDepth, the bound camera files are checked against
#include "rodfit/observe/camera.h"

namespace rodfit {

/// A camera file that cannot be used. what() is one line, "FILE: KEY: message" (or
/// "FILE: message" when the problem is not tied to a key, e.g. a missing or malformed file).
struct CameraFileError : std::runtime_error {
  CameraFileError(const std::string& file, const std::string& key, const std::string& message);
  std::string file;
  std::string key;  ///< the key as spelled in the file (or its canonical name when missing)
};

/// A camera's image is at most this many pixels a side and this many in all (docs/formats.md,
/// "Limits"): synth renders images of that size and extract decodes them.
inline constexpr int kMaxImageSidePx = 16384;
inline constexpr long long kMaxImagePixels = 1LL << 26;  // 67,108,864 (8K video is 33 M)

/// Loads one camera. Camera::name is the file's `camera_name` if present, else the file stem.
/// Throws CameraFileError.
Camera LoadCamera(const std::string& path);

/// An image size [px].
struct ImageSizePx {
  int width = 0;
  int height = 0;
};

/// Where a stereo pair's R and T come from, and what stands in for an image size the file leaves
/// out.
struct StereoFileOptions {
  /// A second file holding R and T: OpenCV's stereo_calib sample writes the intrinsics (M1 D1 M2
  /// D2) to intrinsics.yml and R T R1 R2 P1 P2 Q to extrinsics.yml. Empty: R and T are in the
  /// main file. Given, R and T must not be in the main file too.
  std::string extrinsics_path;
  /// Called only when the main file states no image size (image_width/image_height or
  /// image_size): the size of the pair's images, which cv::stereoCalibrate requires to be one
  /// size. It may throw (an image that cannot be read). Null: a missing size is an error naming
  /// the file and image_width.
  std::function<ImageSizePx()> image_size_when_absent;
};

/// Loads a stereo pair (M1|K1 D1 M2|K2 D2 R T and, if stated, the shared image size). Camera 1
/// is posed by rvec/tvec if present (else it is the world frame); camera 2 is [R | T] composed
/// with camera 1. Names are "STEM[1]" and "STEM[2]". Throws CameraFileError naming the file (the
/// main one or the extrinsics file) and the key.
std::pair<Camera, Camera> LoadStereoCameras(const std::string& path,
                                            const StereoFileOptions& options = {});

}  // namespace rodfit
