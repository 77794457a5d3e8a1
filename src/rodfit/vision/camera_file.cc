// Camera files through cv::FileStorage (camera_file.h). The file is read into memory so that ROS
// YAML, which lacks the %YAML:1.0 header OpenCV's parser requires, can be given one; every value
// is checked (shape, finiteness, focal length, image size) and reported as "FILE: KEY: message".
#include "rodfit/vision/camera_file.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <sstream>
#include <vector>

#include <Eigen/Core>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace rodfit {
namespace {

std::string Num(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

std::string Join(const std::string& file, const std::string& key, const std::string& message) {
  return key.empty() ? file + ": " + message : file + ": " + key + ": " + message;
}

// Bounds on what reaches cv::FileStorage, whose recursive-descent parsers overflow the stack on
// deep nesting (50,000 levels crash it): a camera file is a few kilobytes and three levels deep.
constexpr std::uintmax_t kMaxFileBytes = 1u << 20;
constexpr int kMaxNesting = 64;
// Beyond these a value is a typo or garbage, not a lens: the projection would overflow or lose
// every digit (a 1e6 px image at a 1e-2 degree field of view still has f < 1e8 px).
constexpr double kMaxDistortion = 1e6;
constexpr double kMaxFocalPx = 1e8;
constexpr double kMaxPrincipalPointPx = 1e8;

// A value from the file as a message may show it: short, one line.
std::string Clip(const std::string& text) {
  constexpr size_t kMax = 80;
  std::string out = text.size() > kMax ? text.substr(0, kMax - 3) + "..." : text;
  for (char& c : out) {
    if (static_cast<unsigned char>(c) < 0x20) c = '?';
  }
  return out;
}

// One open file: the path for messages and the parsed tree.
class Document {
 public:
  explicit Document(const std::string& path) : path_(path) {
    std::error_code ec;
    // Checked before opening: a FIFO without a writer would block the open itself.
    const std::filesystem::file_status status = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(status)) Fail("", "cannot open file");
    if (!std::filesystem::is_regular_file(status)) {
      Fail("", "cannot open file: not a regular file (a directory, device, FIFO or socket)");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) Fail("", "cannot open file");
    const std::uintmax_t size = std::filesystem::file_size(path, ec);
    if (ec || size > kMaxFileBytes) {
      Fail("", "file too large for a camera file (" + std::to_string(size) + " bytes, at most " +
                   std::to_string(kMaxFileBytes) + ")");
    }
    // Read at most the bound, whatever the file grows to meanwhile.
    std::string content(static_cast<size_t>(kMaxFileBytes) + 1, '\0');
    in.read(&content[0], static_cast<std::streamsize>(content.size()));
    content.resize(static_cast<size_t>(in.gcount()));
    if (content.size() > kMaxFileBytes) Fail("", "file too large for a camera file");
    size_t start = content.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // UTF-8 BOM
    start = std::min(content.find_first_not_of(" \t\r\n", start), content.size());
    if (start == content.size()) Fail("", "malformed file: empty");
    const char first = content[start];
    const int depth = MarkupNestingDepth(content.substr(start));
    if (depth > kMaxNesting) {
      Fail("", "malformed file: nested " + std::to_string(depth) + " levels deep (at most " +
                   std::to_string(kMaxNesting) + ")");
    }
    // JSON and XML are detected by their first character; YAML needs the "%YAML" directive.
    if (first != '{' && first != '<' && content.compare(start, 5, "%YAML") != 0) {
      content = "%YAML:1.0\n" + content;
      header_lines_ = 1;
    }
    try {
      fs_.open(content, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    } catch (const cv::Exception& e) {
      Fail("", "malformed file: " + ParseMessage(e));
    }
    if (!fs_.isOpened()) Fail("", "malformed file");
    root_ = fs_.root();
    if (!root_.isMap()) Fail("", "malformed file: the top level is not a map of keys");
  }

  [[noreturn]] void Fail(const std::string& key, const std::string& message) const {
    throw CameraFileError(path_, key, message);
  }

  // The node of the first spelling present, its spelling in *key; none if absent. Two different
  // spellings of the same quantity are an error rather than a silent choice.
  cv::FileNode Find(std::initializer_list<const char*> spellings, std::string* key) const {
    cv::FileNode found;
    for (const char* s : spellings) {
      cv::FileNode node = root_[s];
      if (node.isNone()) continue;
      if (!found.isNone()) Fail(s, "given together with " + *key + "; keep one");
      found = node;
      *key = s;
    }
    if (found.isNone()) *key = *spellings.begin();
    return found;
  }

  cv::FileNode Require(std::initializer_list<const char*> spellings, std::string* key) const {
    cv::FileNode node = Find(spellings, key);
    if (node.isNone()) {
      std::string also;
      for (const char* s : spellings) also += (also.empty() ? "" : ", ") + std::string(s);
      Fail(*key, "missing (accepted spellings: " + also + ")");
    }
    return node;
  }

 private:
  // OpenCV puts "FILE(LINE): reason" of a parse error in the function field.
  std::string ParseMessage(const cv::Exception& e) const {
    const std::string& f = e.func;
    const size_t open = f.find('('), close = f.find("): ");
    if (open != std::string::npos && close != std::string::npos && close > open) {
      try {
        const int line = std::stoi(f.substr(open + 1, close - open - 1)) - header_lines_;
        return "line " + std::to_string(line) + ": " + f.substr(close + 3);
      } catch (const std::exception&) {
      }
    }
    return e.err;
  }

  std::string path_;
  cv::FileStorage fs_;
  cv::FileNode root_;
  int header_lines_ = 0;
};

double Number(const Document& doc, const cv::FileNode& node, const std::string& key) {
  if (!node.isInt() && !node.isReal()) doc.Fail(key, "expected a number");
  const double value = node.isInt() ? static_cast<double>(static_cast<int>(node))
                                    : static_cast<double>(node);
  if (!std::isfinite(value)) doc.Fail(key, "non-finite value");
  return value;
}

void AppendNumbers(const Document& doc, const cv::FileNode& seq, const std::string& key,
                   std::vector<double>* out) {
  for (cv::FileNodeIterator it = seq.begin(); it != seq.end(); ++it) {
    out->push_back(Number(doc, *it, key));
  }
}

// A matrix as an opencv-matrix / {rows, cols, data} map, a flat list (1 x n) or a list of rows.
Eigen::MatrixXd Matrix(const Document& doc, const cv::FileNode& node, const std::string& key) {
  std::vector<double> data;
  int rows = 0, cols = 0;
  if (node.isMap()) {
    const cv::FileNode r = node["rows"], c = node["cols"], d = node["data"];
    if (!r.isInt() || !c.isInt() || d.isNone()) doc.Fail(key, "a matrix needs rows, cols and data");
    rows = static_cast<int>(r);
    cols = static_cast<int>(c);
    const std::string dt = node["dt"].isString() ? static_cast<std::string>(node["dt"]) : "";
    if (!dt.empty() && std::isdigit(static_cast<unsigned char>(dt[0]))) cols *= dt[0] - '0';
    if (d.isSeq()) {
      AppendNumbers(doc, d, key, &data);
    } else {
      data.push_back(Number(doc, d, key));
    }
    if (rows < 0 || cols < 0 ||
        static_cast<long long>(data.size()) != static_cast<long long>(rows) * cols) {
      doc.Fail(key, "rows x cols = " + std::to_string(rows) + " x " + std::to_string(cols) +
                        " does not match " + std::to_string(data.size()) + " data values");
    }
  } else if (node.isSeq()) {
    rows = static_cast<int>(node.size());
    cols = -1;
    for (cv::FileNodeIterator it = node.begin(); it != node.end(); ++it) {
      if (!(*it).isSeq()) {  // a flat list
        data.clear();
        AppendNumbers(doc, node, key, &data);
        rows = 1;
        cols = static_cast<int>(data.size());
        break;
      }
      const size_t before = data.size();
      AppendNumbers(doc, *it, key, &data);
      const int n = static_cast<int>(data.size() - before);
      if (cols >= 0 && n != cols) doc.Fail(key, "rows of different lengths");
      cols = n;
    }
    if (cols < 0) cols = 0;
  } else {
    doc.Fail(key, "expected a matrix");
  }
  Eigen::MatrixXd m(rows, cols);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) m(i, j) = data[i * cols + j];
  }
  return m;
}

// A vector of n values, whatever the orientation in the file.
Eigen::VectorXd Vector(const Document& doc, const cv::FileNode& node, const std::string& key,
                       int n) {
  const Eigen::MatrixXd m = Matrix(doc, node, key);
  if (m.size() != n || (m.rows() != 1 && m.cols() != 1)) {
    doc.Fail(key, "expected " + std::to_string(n) + " values, got a " +
                      std::to_string(m.rows()) + "x" + std::to_string(m.cols()) + " matrix");
  }
  return Eigen::Map<const Eigen::VectorXd>(m.data(), n);
}

int ImageDimension(const Document& doc, const cv::FileNode& node, const std::string& key) {
  const double v = Number(doc, node, key);
  if (!(v >= 1.0) || v != std::floor(v) || v > kMaxImageSidePx) {
    doc.Fail(key, "expected a positive integer of at most " + std::to_string(kMaxImageSidePx) +
                      " px, got " + Num(v));
  }
  return static_cast<int>(v);
}

// Synth renders, and extract and the fit decode, images of the camera's size.
void CheckImageArea(const Document& doc, const std::string& key, const CameraIntrinsics& K) {
  if (static_cast<std::int64_t>(K.width) * K.height > kMaxImagePixels) {
    doc.Fail(key, "the image is " + std::to_string(K.width) + "x" + std::to_string(K.height) +
                      " px, more than " + std::to_string(kMaxImagePixels) + " pixels (the limit)");
  }
}

// The image size the file states; false when it states none (width and height both absent) and
// `optional`, else a missing size is an error naming the file and key.
bool ReadImageSize(const Document& doc, CameraIntrinsics* K, bool optional = false) {
  std::string size_key, w_key, h_key;
  const cv::FileNode size = doc.Find({"image_size", "imageSize", "cameraResolution"}, &size_key);
  const cv::FileNode width = doc.Find({"image_width", "image_Width", "imageWidth"}, &w_key);
  const cv::FileNode height = doc.Find({"image_height", "image_Height", "imageHeight"}, &h_key);
  if (!size.isNone()) {
    if (!width.isNone() || !height.isNone()) doc.Fail(size_key, "given together with " + w_key);
    const Eigen::VectorXd wh = Vector(doc, size, size_key, 2);
    for (int i = 0; i < 2; ++i) {
      if (!(wh(i) >= 1.0 && wh(i) <= kMaxImageSidePx && wh(i) == std::floor(wh(i)))) {
        doc.Fail(size_key, "expected [width, height] as positive integers of at most " +
                               std::to_string(kMaxImageSidePx) + " px");
      }
    }
    K->width = static_cast<int>(wh(0));
    K->height = static_cast<int>(wh(1));
    CheckImageArea(doc, size_key, *K);
    return true;
  }
  if (width.isNone() && height.isNone()) {
    if (optional) return false;
    doc.Fail(w_key, "missing: the image size is required (image_width and image_height, or "
                    "image_size: [width, height])");
  }
  if (height.isNone()) doc.Fail(h_key, "missing (image_width is given)");
  if (width.isNone()) doc.Fail(w_key, "missing (image_height is given)");
  K->width = ImageDimension(doc, width, w_key);
  K->height = ImageDimension(doc, height, h_key);
  CheckImageArea(doc, w_key, *K);
  return true;
}

void ReadIntrinsics(const Document& doc, std::initializer_list<const char*> matrix_keys,
                    std::initializer_list<const char*> distortion_keys, CameraIntrinsics* K) {
  std::string key;
  const cv::FileNode k_node = doc.Find(matrix_keys, &key);
  if (k_node.isNone() && !doc.Find({"M1", "K1", "cameraMatrix1"}, &key).isNone()) {
    doc.Fail(*matrix_keys.begin(), "missing; this is a stereo file (" + key +
                                       "): load it as a pair (extract --stereo)");
  }
  Eigen::MatrixXd M = Matrix(doc, doc.Require(matrix_keys, &key), key);
  if (M.rows() == 1 && M.cols() == 9) M = Eigen::Map<Eigen::Matrix3d>(M.data()).transpose().eval();
  if (M.rows() != 3 || M.cols() != 3) {
    doc.Fail(key, "expected a 3x3 matrix, got " + std::to_string(M.rows()) + "x" +
                      std::to_string(M.cols()));
  }
  if (!(M(0, 0) > 0.0 && M(1, 1) > 0.0)) doc.Fail(key, "focal lengths must be positive");
  if (M(0, 0) > kMaxFocalPx || M(1, 1) > kMaxFocalPx) {
    doc.Fail(key, "focal length " + Num(std::max(M(0, 0), M(1, 1))) + " px is absurd (at most " +
                      Num(kMaxFocalPx) + ")");
  }
  if (std::abs(M(0, 2)) > kMaxPrincipalPointPx || std::abs(M(1, 2)) > kMaxPrincipalPointPx) {
    doc.Fail(key, "principal point (" + Num(M(0, 2)) + ", " + Num(M(1, 2)) +
                      ") px is absurd (at most " + Num(kMaxPrincipalPointPx) + " from 0)");
  }
  if (M(0, 1) != 0.0) doc.Fail(key, "non-zero skew is not supported (OpenCV ignores it too)");
  if (M(1, 0) != 0.0 || M(2, 0) != 0.0 || M(2, 1) != 0.0 || M(2, 2) != 1.0) {
    doc.Fail(key, "expected [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  K->fx = M(0, 0);
  K->fy = M(1, 1);
  K->cx = M(0, 2);
  K->cy = M(1, 2);

  std::string model_key;
  const cv::FileNode model = doc.Find({"distortion_model"}, &model_key);
  if (!model.isNone()) {
    const std::string name = model.isString() ? static_cast<std::string>(model) : "";
    if (name != "plumb_bob" && name != "rational_polynomial") {
      doc.Fail(model_key,
               "'" + Clip(name) + "' is not supported (plumb_bob, rational_polynomial)");
    }
  }
  const Eigen::MatrixXd D = Matrix(doc, doc.Require(distortion_keys, &key), key);
  if (D.rows() != 1 && D.cols() != 1 && D.size() != 0) doc.Fail(key, "expected a vector");
  const int n = static_cast<int>(D.size());
  if (n != 0 && n != 4 && n != 5 && n != 8 && n != 12 && n != 14) {
    doc.Fail(key, "expected 4, 5, 8, 12 or 14 coefficients, got " + std::to_string(n));
  }
  static const char* const kNames[] = {"k1", "k2", "p1", "p2", "k3", "k4", "k5",
                                       "k6", "s1", "s2", "s3", "s4", "tauX", "tauY"};
  double* const targets[] = {&K->k1, &K->k2, &K->p1, &K->p2, &K->k3};
  for (int i = 0; i < n; ++i) {
    const double d = D(i);
    // k1 = 1e300 would pass as finite and make every projection overflow in the fit.
    if (!(std::abs(d) <= kMaxDistortion)) {
      doc.Fail(key, std::string("coefficient ") + kNames[i] + " = " + Num(d) +
                        " is absurd (|k| at most " + Num(kMaxDistortion) + ")");
    }
    if (i < 5) {
      *targets[i] = d;
    } else if (d != 0.0) {
      doc.Fail(key, std::string("coefficient ") + kNames[i] + " = " + Num(d) +
                        " is not supported (only k1, k2, p1, p2, k3)");
    }
  }
}

Eigen::Matrix3d Rotation(const Document& doc, const cv::FileNode& node, const std::string& key) {
  Eigen::MatrixXd m = Matrix(doc, node, key);
  if (m.rows() == 1 && m.cols() == 9) m = Eigen::Map<Eigen::Matrix3d>(m.data()).transpose().eval();
  if (m.rows() != 3 || m.cols() != 3) doc.Fail(key, "expected a 3x3 rotation matrix");
  const Eigen::Matrix3d R = m;
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-5 ||
      R.determinant() < 0.0) {
    doc.Fail(key, "not a rotation matrix (R^T R != I to 1e-5, or det < 0)");
  }
  // Remove the rounding of printed values: the nearest rotation (polar decomposition).
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

Eigen::Matrix3d RotationFromRvec(const Document& doc, const cv::FileNode& node,
                                 const std::string& key) {
  const Eigen::Vector3d r = Vector(doc, node, key, 3);
  cv::Mat R;
  cv::Rodrigues(cv::Vec3d(r.x(), r.y(), r.z()), R);
  Eigen::Matrix3d out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) out(i, j) = R.at<double>(i, j);
  }
  return out;
}

// A pose as a rotation-vector pair (rvec/tvec) or, if allowed, a matrix pair (R/T); false if
// neither is present. Half a pair or both pairs are errors.
bool ReadPose(const Document& doc, bool allow_matrix_pair, Eigen::Matrix3d* R, Eigen::Vector3d* t) {
  std::string rv_key, tv_key, R_key, T_key;
  const cv::FileNode rvec = doc.Find({"rvec"}, &rv_key), tvec = doc.Find({"tvec"}, &tv_key);
  const cv::FileNode Rm = allow_matrix_pair ? doc.Find({"R"}, &R_key) : cv::FileNode();
  const cv::FileNode Tm = allow_matrix_pair ? doc.Find({"T"}, &T_key) : cv::FileNode();
  if (rvec.isNone() != tvec.isNone()) {
    doc.Fail(rvec.isNone() ? "rvec" : "tvec", "missing; give rvec and tvec together");
  }
  if (Rm.isNone() != Tm.isNone()) {
    doc.Fail(Rm.isNone() ? "R" : "T", "missing; give R and T together");
  }
  if (!rvec.isNone() && !Rm.isNone()) doc.Fail("R", "given together with rvec; keep one pose");
  if (!rvec.isNone()) {
    *R = RotationFromRvec(doc, rvec, rv_key);
    *t = Vector(doc, tvec, tv_key, 3);
    return true;
  }
  if (!Rm.isNone()) {
    *R = Rotation(doc, Rm, R_key);
    *t = Vector(doc, Tm, T_key, 3);
    return true;
  }
  return false;
}

std::string Stem(const std::string& path) {
  const size_t slash = path.find_last_of("/\\");
  std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const size_t dot = name.find_last_of('.');
  return dot == std::string::npos || dot == 0 ? name : name.substr(0, dot);
}

void CheckCamera(const Document& doc, const Camera& camera) {
  std::string why;
  if (!camera.Check(&why)) doc.Fail("", why);  // a safety net: the readers check each value
}

}  // namespace


CameraFileError::CameraFileError(const std::string& file_in, const std::string& key_in,
                                 const std::string& message)
    : std::runtime_error(Join(file_in, key_in, message)), file(file_in), key(key_in) {}

Camera LoadCamera(const std::string& path) {
  const Document doc(path);
  Camera camera;
  ReadIntrinsics(doc, {"camera_matrix", "Camera_Matrix", "cameraMatrix"},
                 {"distortion_coefficients", "Distortion_Coefficients", "distCoeffs",
                  "dist_coeffs"},
                 &camera.K);
  ReadImageSize(doc, &camera.K);
  ReadPose(doc, true, &camera.cam_from_world_R, &camera.cam_from_world_t);
  std::string key;
  const cv::FileNode name = doc.Find({"camera_name"}, &key);
  camera.name = name.isString() ? static_cast<std::string>(name) : Stem(path);
  CheckCamera(doc, camera);
  return camera;
}

std::pair<Camera, Camera> LoadStereoCameras(const std::string& path,
                                            const StereoFileOptions& options) {
  const Document doc(path);
  Camera first, second;
  // M1/M2 (OpenCV's stereo_calib sample), K1/K2 (what most lab tools and OpenCV's Python
  // examples write), cameraMatrix1/2 with distCoeffs1/2 (cv::stereoCalibrate's argument names).
  ReadIntrinsics(doc, {"M1", "K1", "cameraMatrix1"}, {"D1", "distCoeffs1"}, &first.K);
  ReadIntrinsics(doc, {"M2", "K2", "cameraMatrix2"}, {"D2", "distCoeffs2"}, &second.K);
  if (!ReadImageSize(doc, &first.K, /*optional=*/static_cast<bool>(options.image_size_when_absent))) {
    // Neither the sample nor cv::stereoCalibrate writes the size: the images have it.
    const ImageSizePx size = options.image_size_when_absent();
    first.K.width = size.width;
    first.K.height = size.height;
  }
  second.K.width = first.K.width;
  second.K.height = first.K.height;
  ReadPose(doc, false, &first.cam_from_world_R, &first.cam_from_world_t);
  // R and T from the extrinsics file when there is one (the sample's extrinsics.yml), and then
  // from there only: two relative poses would be a silent choice.
  std::optional<Document> extrinsics_doc;
  if (!options.extrinsics_path.empty()) {
    extrinsics_doc.emplace(options.extrinsics_path);
    for (const char* key : {"R", "T"}) {
      std::string spelled;
      if (!doc.Find({key}, &spelled).isNone()) {
        doc.Fail(key, "given here and in the extrinsics file " + options.extrinsics_path +
                          "; keep one");
      }
    }
  }
  const Document& pose_doc = extrinsics_doc ? *extrinsics_doc : doc;
  std::string R_key, T_key;
  const Eigen::Matrix3d R = Rotation(pose_doc, pose_doc.Require({"R"}, &R_key), R_key);
  const Eigen::Vector3d T = Vector(pose_doc, pose_doc.Require({"T"}, &T_key), T_key, 3);
  if (!(T.norm() > 0.0)) pose_doc.Fail(T_key, "zero baseline");
  // x2 = R x1 + T and x1 = R1 x_world + t1 give x2 = (R R1) x_world + (R t1 + T).
  second.cam_from_world_R = R * first.cam_from_world_R;
  second.cam_from_world_t = R * first.cam_from_world_t + T;
  first.name = Stem(path) + "[1]";
  second.name = Stem(path) + "[2]";
  CheckCamera(doc, first);
  CheckCamera(doc, second);
  return {first, second};
}

}  // namespace rodfit
