// Synthetic camera images of a thread (docs/solvers.md, "Observations": `images`): the projected
// centre-line, a 2-D polyline in pixels with a per-vertex half-width (the projected tube radius),
// is drawn as a union of tapered capsules with round joints and caps. Each pixel's coverage comes
// from its signed distance d to the tube, clamp(0.5 - d, 0, 1) — the area of a pixel that a
// straight edge covers — so edges are antialiased analytically and without bias at any angle
// (what remains is the pixel-area aliasing a real sensor has too, at most 1/(8 w) px on the
// mid-line). Threads thinner than `min_half_width` are drawn at that half-width with their
// contrast scaled by w / min_half_width, conserving the "ink" per unit length as a camera's
// point-spread function does. Optional Gaussian blur (defocus) and Gaussian pixel noise
// (Marsaglia's polar method on raw std::mt19937 output, so a seed gives the same bytes with
// every standard library) complete the camera model. Pixel centres are at integer coordinates
// (the OpenCV convention); the output is 8-bit BGR.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace rodfit {

struct RenderOptions {
  int width = 1280;                           ///< [px]
  int height = 1024;                          ///< [px]
  cv::Scalar background{235, 235, 235};       ///< BGR, a light table
  cv::Scalar thread{40, 40, 40};              ///< BGR, a dark thread
  bool antialias = true;                      ///< analytic area coverage; false = pixel-centre test
  double min_half_width = 0.75;               ///< [px] thinner threads: drawn this wide, fainter
  double blur_sigma = 0.0;                    ///< [px] Gaussian blur (defocus); 0 = none
  double noise_sigma = 0.0;                   ///< [grey levels] per pixel and channel; 0 = none
  std::uint32_t seed = 0;                     ///< noise seed when `rng` is null
  std::mt19937* rng = nullptr;                ///< if set, the noise draws from (and advances) it
  bool Check(std::string* why) const;
};

/// Renders the thread whose projected centre-line is `uv` [px] with half-widths `half_width_px`
/// (same size, >= 0, one per vertex, interpolated linearly along each segment). Parts outside the
/// image are clipped. Returns a CV_8UC3 image of options.height x options.width. Throws
/// std::invalid_argument for empty or mismatched inputs, non-finite values or bad options.
cv::Mat RenderThreadImage(const std::vector<Eigen::Vector2d>& uv,
                          const std::vector<double>& half_width_px,
                          const RenderOptions& options = RenderOptions());

}  // namespace rodfit
