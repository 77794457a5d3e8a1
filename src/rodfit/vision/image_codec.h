// Image file decoding and encoding (PNG, JPEG, TIFF, BMP) with libpng, libjpeg(-turbo) and
// libtiff directly.
//
// Why not OpenCV's imgcodecs: on Debian it links GDAL and with it about 120 shared libraries
// (DICOM, HEIF, PDF, HDF5, ...), and loading them took ~110 ms of every rodfit process, even
// `rodfit --help`. These three small libraries read what cameras and labs write, and rodfit
// checks an image's size against its limits before it allocates the pixels.
//
// Pixels follow OpenCV's conventions, so a cv::Mat from here is what cv::imdecode with
// IMREAD_UNCHANGED gives: 8- or 16-bit, one channel (grey), three (B, G, R) or four (B, G, R, A).
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace rodfit {

enum class ImageFormat { kUnknown, kPng, kJpeg, kTiff, kBmp };

/// The format of encoded bytes from their signature (kUnknown when none matches).
ImageFormat SniffImageFormat(const std::string& bytes);

/// The format a file extension names (".png", ".jpg"/".jpeg", ".tif"/".tiff", ".bmp"; any case),
/// kUnknown for any other.
ImageFormat ImageFormatFromExtension(const std::string& extension);

/// Decodes `bytes`. Grey and grey+alpha images give one channel (the alpha dropped), colour
/// three (BGR) or four (BGRA) channels, palettes expanded, bit depths below 8 widened to 8 and
/// 16-bit samples kept as CV_16U. Returns false with a one-line reason in *why (not an image,
/// truncated, an unsupported variant, or more than `max_side_px` a side or `max_pixels` pixels,
/// checked before the pixels are allocated). The libraries' own warnings are not printed.
bool DecodeImageBytes(const std::string& bytes, int max_side_px, long long max_pixels,
                      cv::Mat* image, std::string* why);

/// Encodes an 8-bit (any format) or 16-bit (PNG, TIFF) image of 1, 3 (BGR) or 4 (BGRA) channels.
/// JPEG drops the alpha channel and uses `jpeg_quality` (1-100). Returns false with *why.
bool EncodeImageBytes(ImageFormat format, const cv::Mat& image, std::string* bytes,
                      std::string* why, int jpeg_quality = 95);

}  // namespace rodfit
