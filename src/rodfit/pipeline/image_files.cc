// Image files and camera files as the experiment names them (image_files.h).
#include "rodfit/pipeline/image_files.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/vision/camera_file.h"
#include "rodfit/vision/image_codec.h"

namespace rodfit {
namespace {

std::uint32_t BigEndian(const std::string& b, size_t at, int bytes) {
  std::uint32_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

std::uint32_t LittleEndian(const std::string& b, size_t at, int bytes) {
  std::uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

}  // namespace

Camera LoadObservationCamera(const ObservationSpec& spec) {
  if (spec.camera_index == 0) return LoadCamera(spec.camera);
  const std::pair<Camera, Camera> pair = LoadStereoCameras(spec.camera);
  return spec.camera_index == 1 ? pair.first : pair.second;
}

bool ImageHeaderSize(const std::string& bytes, int* width, int* height) {
  auto set = [&](std::uint64_t w, std::uint64_t h) {
    *width = static_cast<int>(std::min<std::uint64_t>(w, 1u << 30));
    *height = static_cast<int>(std::min<std::uint64_t>(h, 1u << 30));
    return true;
  };
  if (bytes.size() >= 24 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0 &&
      bytes.compare(12, 4, "IHDR") == 0) {
    return set(BigEndian(bytes, 16, 4), BigEndian(bytes, 20, 4));
  }
  if (bytes.size() >= 26 && bytes.compare(0, 2, "BM") == 0) {
    const std::int32_t w = static_cast<std::int32_t>(LittleEndian(bytes, 18, 4));
    const std::int32_t h = static_cast<std::int32_t>(LittleEndian(bytes, 22, 4));
    return set(static_cast<std::uint64_t>(std::abs(static_cast<std::int64_t>(w))),
               static_cast<std::uint64_t>(std::abs(static_cast<std::int64_t>(h))));
  }
  if (bytes.size() >= 4 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
      static_cast<unsigned char>(bytes[1]) == 0xD8) {
    // JPEG: walk the marker segments to the first start-of-frame (SOF0..SOF15 but DHT, JPG, DAC).
    size_t at = 2;
    while (at + 9 < bytes.size()) {
      if (static_cast<unsigned char>(bytes[at]) != 0xFF) return false;
      const unsigned char marker = static_cast<unsigned char>(bytes[at + 1]);
      if (marker == 0xFF) {  // fill byte
        ++at;
        continue;
      }
      const size_t length = BigEndian(bytes, at + 2, 2);
      if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC)
        return set(BigEndian(bytes, at + 7, 2), BigEndian(bytes, at + 5, 2));
      if (length < 2) return false;
      at += 2 + length;
    }
  }
  return false;
}

cv::Mat ReadImageFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw InputError(path, 0, "", "cannot read the image: no such file");
  }
  // A directory, device or FIFO, or a file past the bound, never reaches the decoder; neither
  // does an image whose header claims more pixels than the limit (a small file can decode to
  // gigabytes).
  const std::string bytes = ReadInputFile(path, "an image file");
  int width = 0, height = 0;
  if (ImageHeaderSize(bytes, &width, &height) &&
      (width > kMaxImageSidePx || height > kMaxImageSidePx ||
       static_cast<long long>(width) * height > kMaxImagePixels)) {
    throw InputError(path, 0, "", "the image is " + std::to_string(width) + "x" +
                                      std::to_string(height) + " px, more than " +
                                      std::to_string(kMaxImageSidePx) + " px a side or " +
                                      std::to_string(kMaxImagePixels) + " pixels (the limit)");
  }
  cv::Mat image;
  std::string why;
  if (!DecodeImageBytes(bytes, kMaxImageSidePx, kMaxImagePixels, &image, &why)) {
    throw InputError(path, 0, "", "cannot read the image: " + why);
  }
  return image;
}

std::string EncodeImage(const std::string& path, const cv::Mat& image) {
  const std::string extension = std::filesystem::path(path).extension().string();
  const ImageFormat format = ImageFormatFromExtension(extension);
  if (format == ImageFormat::kUnknown) {
    throw InputError(path, 0, "", "cannot encode an image as '" + extension +
                                      "' (use .png, .jpg, .tif or .bmp)");
  }
  std::string bytes, why;
  if (!EncodeImageBytes(format, image, &bytes, &why)) {
    throw InputError(path, 0, "", "cannot encode the image: " + why);
  }
  return bytes;
}

void WriteImageFile(const std::string& path, const cv::Mat& image) {
  WriteFileAtomically(path, EncodeImage(path, image));
}

cv::Mat ReadMaskFile(const std::string& path, const Camera& camera) {
  const cv::Mat mask = ReadImageFile(path);
  if (mask.channels() != 1) {
    throw InputError(path, 0, "", "a mask must be a single-channel (grey) image, this one has " +
                                      std::to_string(mask.channels()) + " channels");
  }
  if (mask.cols != camera.K.width || mask.rows != camera.K.height) {
    throw InputError(path, 0, "",
                     "the mask is " + std::to_string(mask.cols) + "x" +
                         std::to_string(mask.rows) + " px but camera " + camera.name + " is " +
                         std::to_string(camera.K.width) + "x" + std::to_string(camera.K.height));
  }
  return mask;
}

}  // namespace rodfit
