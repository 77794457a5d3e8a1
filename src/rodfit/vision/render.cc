// Synthetic thread images: signed distance to a union of tapered capsules, analytic coverage,
// optional blur and seeded noise. See render.h for the model and its conventions.
#include "rodfit/vision/render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace rodfit {
namespace {

// One standard normal pair from raw 32-bit draws (Marsaglia's polar method: no trigonometry).
// std::normal_distribution is implementation-defined, so it would not give the same bytes on
// every standard library.
void NormalPair(std::mt19937* rng, double* z0, double* z1) {
  for (;;) {  // accepts with probability pi / 4
    const double u = static_cast<double>((*rng)()) / 2147483648.0 - 1.0;  // [-1, 1)
    const double v = static_cast<double>((*rng)()) / 2147483648.0 - 1.0;
    const double r2 = u * u + v * v;
    if (r2 > 0.0 && r2 < 1.0) {
      const double f = std::sqrt(-2.0 * std::log(r2) / r2);
      *z0 = u * f;
      *z1 = v * f;
      return;
    }
  }
}

// Per-pixel minimum signed distance to the tube (negative inside) and the contrast factor of
// the capsule that attains it.
struct DistanceField {
  cv::Mat1f sd;
  cv::Mat1f alpha;
};

void AddCapsule(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double wa, double wb,
                double min_half_width, DistanceField* field) {
  const double reach = std::max(std::max(wa, wb), min_half_width) + 1.0;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), b.x()) - reach)));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), b.y()) - reach)));
  const int x1 = std::min(field->sd.cols - 1,
                          static_cast<int>(std::ceil(std::max(a.x(), b.x()) + reach)));
  const int y1 = std::min(field->sd.rows - 1,
                          static_cast<int>(std::ceil(std::max(a.y(), b.y()) + reach)));
  const Eigen::Vector2d ab = b - a;
  const double len_sq = ab.squaredNorm();
  for (int y = y0; y <= y1; ++y) {
    float* sd_row = field->sd.ptr<float>(y);
    float* alpha_row = field->alpha.ptr<float>(y);
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d ap(x - a.x(), y - a.y());
      const double t = len_sq > 1e-18 ? std::clamp(ap.dot(ab) / len_sq, 0.0, 1.0) : 0.0;
      const double w = wa + t * (wb - wa);
      const double w_draw = std::max(w, min_half_width);
      const double sd = (ap - t * ab).norm() - w_draw;
      if (sd < sd_row[x]) {
        sd_row[x] = static_cast<float>(sd);
        alpha_row[x] = static_cast<float>(w_draw > 0.0 ? w / w_draw : 0.0);
      }
    }
  }
}

}  // namespace

bool RenderOptions::Check(std::string* why) const {
  std::ostringstream msg;
  if (width <= 0 || height <= 0) {
    msg << "image size " << width << "x" << height << " must be positive";
  } else if (!(min_half_width >= 0.0) || !std::isfinite(min_half_width)) {
    msg << "min_half_width " << min_half_width << " must be finite and >= 0";
  } else if (!(blur_sigma >= 0.0) || !std::isfinite(blur_sigma)) {
    msg << "blur_sigma " << blur_sigma << " must be finite and >= 0";
  } else if (!(noise_sigma >= 0.0) || !std::isfinite(noise_sigma)) {
    msg << "noise_sigma " << noise_sigma << " must be finite and >= 0";
  } else {
    return true;
  }
  if (why) *why = msg.str();
  return false;
}

cv::Mat RenderThreadImage(const std::vector<Eigen::Vector2d>& uv,
                          const std::vector<double>& half_width_px,
                          const RenderOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("RenderThreadImage: " + why);
  if (uv.empty() || uv.size() != half_width_px.size()) {
    throw std::invalid_argument("RenderThreadImage: need uv.size() == half_width_px.size() > 0");
  }
  for (size_t i = 0; i < uv.size(); ++i) {
    if (!uv[i].allFinite() || !std::isfinite(half_width_px[i]) || half_width_px[i] < 0.0) {
      throw std::invalid_argument("RenderThreadImage: vertex " + std::to_string(i) +
                                  " has a non-finite position or a bad half-width");
    }
  }

  DistanceField field{cv::Mat1f(options.height, options.width,
                                std::numeric_limits<float>::max()),
                      cv::Mat1f(options.height, options.width, 0.0f)};
  if (uv.size() == 1) {
    AddCapsule(uv[0], uv[0], half_width_px[0], half_width_px[0], options.min_half_width, &field);
  }
  for (size_t i = 0; i + 1 < uv.size(); ++i) {
    AddCapsule(uv[i], uv[i + 1], half_width_px[i], half_width_px[i + 1], options.min_half_width,
               &field);
  }

  cv::Mat image(options.height, options.width, CV_8UC3);
  for (int y = 0; y < image.rows; ++y) {
    const float* sd_row = field.sd.ptr<float>(y);
    const float* alpha_row = field.alpha.ptr<float>(y);
    cv::Vec3b* out = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.cols; ++x) {
      const double sd = sd_row[x];
      double cover = options.antialias ? std::clamp(0.5 - sd, 0.0, 1.0) : (sd <= 0.0 ? 1.0 : 0.0);
      cover *= alpha_row[x];
      for (int c = 0; c < 3; ++c) {
        out[x][c] = cv::saturate_cast<uchar>(options.background[c] +
                                             cover * (options.thread[c] - options.background[c]));
      }
    }
  }

  if (options.blur_sigma > 0.0) {
    cv::GaussianBlur(image, image, cv::Size(0, 0), options.blur_sigma, options.blur_sigma,
                     cv::BORDER_REPLICATE);
  }
  if (options.noise_sigma > 0.0) {
    std::mt19937 own_rng(options.seed);
    std::mt19937* rng = options.rng ? options.rng : &own_rng;
    uchar* data = image.ptr<uchar>(0);  // freshly allocated, hence continuous
    const size_t n = image.total() * image.channels();
    double z[2];
    for (size_t k = 0; k < n; ++k) {
      if (k % 2 == 0) NormalPair(rng, &z[0], &z[1]);
      data[k] = cv::saturate_cast<uchar>(data[k] + options.noise_sigma * z[k % 2]);
    }
  }
  return image;
}

}  // namespace rodfit
