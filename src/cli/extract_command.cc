// `rodfit extract IMAGE... -o CSV`: the centre-line of a thread in one image (pixels) or in two
// images of calibrated cameras (triangulated points) (docs/cli.md, "extract"). In the commands
// module: it decodes images and reads camera files through OpenCV.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/image_files.h"
#include "rodfit/pipeline/image_observations.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/observe/camera.h"
#include "rodfit/synth/synth.h"
#include "rodfit/vision/camera_file.h"
#include "rodfit/vision/centreline.h"

namespace {

// "U,V" -> pixel; false when it is not two finite numbers.
bool ParsePixel(const std::string& text, Eigen::Vector2d* uv) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos) return false;
  double u = 0.0, v = 0.0;
  if (!rodfit::ParseDouble(text.substr(0, comma), &u) ||
      !rodfit::ParseDouble(text.substr(comma + 1), &v)) {
    return false;
  }
  *uv = Eigen::Vector2d(u, v);
  return true;
}

// "X0,Y0,X1,Y1" -> the pixel rectangle with corners (X0, Y0) inclusive and (X1, Y1) exclusive;
// an empty `why` when it is not four integers with X0 < X1 and Y0 < Y1.
bool ParseRoi(const std::string& text, cv::Rect* roi, std::string* why) {
  std::vector<long long> corner;
  size_t from = 0;
  while (corner.size() < 5) {
    const size_t comma = text.find(',', from);
    const std::string field = text.substr(from, comma == std::string::npos ? comma : comma - from);
    double value = 0.0;
    if (!rodfit::ParseDouble(field, &value) || value != std::floor(value) ||
        std::abs(value) > rodfit::kMaxImageSidePx) {
      *why = "is not X0,Y0,X1,Y1 (four integer pixel corners)";
      return false;
    }
    corner.push_back(static_cast<long long>(value));
    if (comma == std::string::npos) break;
    from = comma + 1;
  }
  if (corner.size() != 4) {
    *why = "is not X0,Y0,X1,Y1 (four integer pixel corners)";
    return false;
  }
  if (corner[2] <= corner[0] || corner[3] <= corner[1]) {
    *why = "is empty (X1 must exceed X0 and Y1 exceed Y0; X1, Y1 are exclusive)";
    return false;
  }
  *roi = cv::Rect(static_cast<int>(corner[0]), static_cast<int>(corner[1]),
                  static_cast<int>(corner[2] - corner[0]), static_cast<int>(corner[3] - corner[1]));
  return true;
}

// The command line as given.
struct ExtractArgs {
  std::vector<std::string> images, camera_paths, stereo_paths, starts, overlays, rois, masks;
  std::string output_path;
};

void DeclareOptions(CLI::App& app, ExtractArgs* a) {
  app.add_option("images", a->images, "one image, or two images of two cameras")
      ->required()
      ->expected(1, 2);
  app.add_option("--camera", a->camera_paths, "camera file, one per image (docs/formats.md)");
  app.add_option("--stereo", a->stereo_paths,
                 "stereo calibration file holding both cameras (M1|K1 D1 M2|K2 D2 R T), or "
                 "OpenCV's stereo_calib pair: intrinsics.yml extrinsics.yml; without an image "
                 "size the images give it")
      ->expected(1, 2);
  app.add_option("-o,--output", a->output_path, "output CSV: u,v (one image) or x,y,z (two)")
      ->required();
  app.add_option("--overlay", a->overlays, "image with the centre-line drawn, one per image");
  app.add_option("--start", a->starts, "U,V: start the centre-line at the end nearest this pixel, "
                                       "one per image");
  app.add_option("--roi", a->rois, "X0,Y0,X1,Y1: seek the thread in these pixel columns X0..X1-1 "
                                   "and rows Y0..Y1-1 only, one per image");
  app.add_option("--mask", a->masks, "grey image, non-zero where the thread may be, one per image");
}

// No output may be one of the inputs (an overlay written over its own image).
void CheckOutputs(const ExtractArgs& a) {
  std::vector<rodfit::InputFile> inputs;
  for (const std::string& image : a.images) inputs.emplace_back(image, "an input image");
  for (const std::string& camera : a.camera_paths) inputs.emplace_back(camera, "a camera file");
  for (const std::string& stereo : a.stereo_paths) inputs.emplace_back(stereo, "a stereo file");
  for (const std::string& mask : a.masks) inputs.emplace_back(mask, "a mask");
  rodfit::CheckOutputFile(a.output_path, inputs);
  for (const std::string& overlay : a.overlays) rodfit::CheckOutputFile(overlay, inputs);
}

// The images' cameras, from --stereo or one --camera per image; the usage error otherwise
// (empty when they loaded).
std::string LoadCameras(const ExtractArgs& a, std::vector<rodfit::Camera>* cameras) {
  const std::vector<std::string>& images = a.images;
  if (a.stereo_paths.empty()) {
    if (a.camera_paths.size() != images.size()) return "give one --camera per image, or --stereo";
    for (const std::string& path : a.camera_paths) cameras->push_back(rodfit::LoadCamera(path));
    return "";
  }
  if (images.size() != 2 || !a.camera_paths.empty()) return "--stereo needs two images and no --camera";
  if (a.stereo_paths.size() > 2) return "--stereo takes one file, or intrinsics and extrinsics";
  rodfit::StereoFileOptions stereo;
  if (a.stereo_paths.size() == 2) stereo.extrinsics_path = a.stereo_paths[1];
  // cv::stereoCalibrate calibrates a pair of one image size, which its callers rarely write
  // down: the images state it (decoded here once more; extraction decodes them again).
  stereo.image_size_when_absent = [&images]() {
    const cv::Mat a = rodfit::ReadImageFile(images[0]), b = rodfit::ReadImageFile(images[1]);
    if (a.size() != b.size()) {
      throw rodfit::InputError(
          images[1], 0, "", "the image is " + std::to_string(b.cols) + "x" +
          std::to_string(b.rows) + " px but " + images[0] + " is " + std::to_string(a.cols) +
          "x" + std::to_string(a.rows) +
          "; the stereo file states no image size, so the pair must be of one size (as "
          "cv::stereoCalibrate calibrates it)");
    }
    return rodfit::ImageSizePx{a.cols, a.rows};
  };
  const auto pair = rodfit::LoadStereoCameras(a.stereo_paths[0], stereo);
  *cameras = {pair.first, pair.second};
  return "";
}

// Each image's extraction options from --start and --roi (its --mask is read just before its
// extraction); the usage error otherwise (empty when they parsed).
std::string ExtractionOptions(const ExtractArgs& a,
                              std::vector<rodfit::CentrelineOptions>* options) {
  const size_t n = a.images.size();
  if (!a.starts.empty() && a.starts.size() != n) return "give one --start per image, or none";
  if (!a.overlays.empty() && a.overlays.size() != n) return "give one --overlay per image, or none";
  if (!a.rois.empty() && a.rois.size() != n) return "give one --roi per image, or none";
  if (!a.masks.empty() && a.masks.size() != n) return "give one --mask per image, or none";
  std::vector<cv::Rect> roi_rects(a.rois.size());
  for (size_t k = 0; k < a.rois.size(); ++k) {
    std::string why;
    if (!ParseRoi(a.rois[k], &roi_rects[k], &why)) return "--roi '" + a.rois[k] + "' " + why;
  }
  options->assign(n, rodfit::CentrelineOptions());
  for (size_t k = 0; k < n; ++k) {
    // Every --start is parsed before any image or mask is read (a usage error costs no decoding).
    if (!a.starts.empty()) {
      Eigen::Vector2d hint;
      if (!ParsePixel(a.starts[k], &hint)) return "--start '" + a.starts[k] + "' is not U,V";
      (*options)[k].start_hint = hint;
    }
    if (!a.rois.empty()) (*options)[k].roi = roi_rects[k];
  }
  return "";
}

// Writes every output (path, contents; the CSV last): all staged (one staging directory per
// output folder), then committed together, the CSV's folder last, so that a failure on the way
// leaves every output location as it was and no CSV stands without its overlays. The usage
// error when one path is given twice (empty when written).
std::string WriteOutputs(const std::vector<std::pair<std::string, std::string>>& files) {
  std::vector<std::pair<std::string, std::unique_ptr<rodfit::StagedDirectory>>> folders;
  std::vector<std::string> finals;
  rodfit::StagedDirectory* staged = nullptr;
  for (const auto& [path, contents] : files) {
    const std::filesystem::path file(path);
    const std::string folder =
        file.has_parent_path() ? file.parent_path().lexically_normal().string() : ".";
    staged = nullptr;
    for (const auto& [name, dir] : folders) {
      if (name == folder) staged = dir.get();
    }
    if (staged == nullptr) {
      folders.emplace_back(folder, std::make_unique<rodfit::StagedDirectory>(folder, true));
      staged = folders.back().second.get();
    }
    const std::string final_path = staged->FinalPath(file.filename().string());
    for (const std::string& other : finals) {
      if (other == final_path) return path + " is given as two outputs";
    }
    finals.push_back(final_path);
    staged->Write(file.filename().string(), contents, "output file name");
  }
  std::vector<rodfit::StagedDirectory*> order;
  for (const auto& [name, dir] : folders) {
    if (dir.get() != staged) order.push_back(dir.get());
  }
  order.push_back(staged);  // the CSV's folder
  rodfit::CommitAll(order);
  return "";
}

}  // namespace

int RunExtract(int argc, char** argv) {
  CLI::App app(
      "Extract the ordered centre-line of a thread from a camera image (writes u,v), or from two "
      "images of two calibrated cameras (writes triangulated x,y,z).",
      "rodfit extract");
  ExtractArgs args;
  DeclareOptions(app, &args);
  if (const int status = Parse(app, argc, argv); status >= 0) return status;

  const std::vector<std::string>& images = args.images;
  const size_t n = images.size();
  auto fail = [](const std::string& why) {
    std::cerr << "rodfit extract: " << why << " (see --help)\n";
    return EXIT_FAILURE;
  };
  CheckOutputs(args);
  std::vector<rodfit::Camera> cameras;
  if (const std::string why = LoadCameras(args, &cameras); !why.empty()) return fail(why);
  std::vector<rodfit::CentrelineOptions> options;
  if (const std::string why = ExtractionOptions(args, &options); !why.empty())
    return fail(why);

  std::vector<rodfit::CentrelineResult> lines;
  for (size_t k = 0; k < n; ++k) {
    if (!args.masks.empty()) options[k].mask = rodfit::ReadMaskFile(args.masks[k], cameras[k]);
    lines.push_back(rodfit::ExtractCentrelineFromFile(images[k], cameras[k], options[k]));
  }
  std::string csv;
  std::vector<std::vector<Eigen::Vector2d>> reprojected(n);
  if (n == 1) {
    csv = rodfit::FormatImagePointsCsv(lines[0].uv);
  } else {
    const std::vector<Eigen::Vector3d> points = rodfit::TriangulateCentrelines(
        cameras[0], lines[0].uv, cameras[1], lines[1].uv, images[0], images[1]);
    csv = rodfit::FormatPoints3dCsv(points);
    for (size_t k = 0; k < n; ++k) {
      for (const Eigen::Vector3d& p : points) {
        Eigen::Vector2d uv;
        if (rodfit::Project(cameras[k], p, &uv)) reprojected[k].push_back(uv);
      }
    }
  }
  // Overlays are encoded before anything is written, so a bad --overlay leaves no CSV behind.
  std::vector<std::pair<std::string, std::string>> files;  // path, contents; the CSV last
  for (size_t k = 0; k < args.overlays.size(); ++k) {
    files.emplace_back(args.overlays[k],
                       rodfit::EncodeImage(args.overlays[k],
                                           rodfit::DrawOverlay(rodfit::ReadImageFile(images[k]),
                                                               lines[k].uv, reprojected[k])));
  }
  files.emplace_back(args.output_path, csv);
  if (const std::string why = WriteOutputs(files); !why.empty()) return fail(why);
  for (size_t k = 0; k < n; ++k) std::cout << images[k] << ": " << lines[k].BriefReport() << "\n";
  return EXIT_SUCCESS;
}
