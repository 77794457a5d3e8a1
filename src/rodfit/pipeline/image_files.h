// Image files and camera files as an experiment names them (camera images, masks, synth's
// renders; an entry's camera), through vision's decoders (vision/image_codec.h) and camera
// readers (vision/camera_file.h): sizes checked before decoding, errors naming the file. In the
// pipeline rather than io, so that io reads and writes its formats without linking vision.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "rodfit/io/experiment.h"
#include "rodfit/observe/camera.h"

namespace rodfit {

/// Loads the camera of an image entry (one camera of a stereo file by its camera_index). Throws
/// CameraFileError (rodfit/vision/camera_file.h).
Camera LoadObservationCamera(const ObservationSpec& spec);

/// Reads an image file as stored (8- or 16-bit; grey, BGR or BGRA). Throws InputError
/// "PATH: cannot read the image" when it is missing or not an image, and names the limit when
/// its header claims more than kMaxImageSidePx a side or kMaxImagePixels (checked before the
/// decoder runs; the decoders' own warnings are kept off stderr).
cv::Mat ReadImageFile(const std::string& path);

/// The width and height a PNG, BMP or JPEG header states (false for other formats or a header
/// too short to tell), read without decoding.
bool ImageHeaderSize(const std::string& bytes, int* width, int* height);

/// The bytes of `image` encoded in the format of `path`'s extension (.png, .jpg, .bmp, .tif, ...).
/// Throws InputError naming `path` for an extension OpenCV cannot write.
std::string EncodeImage(const std::string& path, const cv::Mat& image);

/// EncodeImage, then WriteFileAtomically. Throws InputError.
void WriteImageFile(const std::string& path, const cv::Mat& image);

/// Reads the mask image `path` for CentrelineOptions::mask (non-zero = may hold thread). Throws
/// InputError naming `path` when it cannot be read (ReadImageFile), has more than one channel or
/// not the size of `camera`'s images.
cv::Mat ReadMaskFile(const std::string& path, const Camera& camera);

}  // namespace rodfit
