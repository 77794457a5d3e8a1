// Camera image of a thread -> ordered centre-line pixels (docs/solvers.md, "Observations": `images`
// are reduced to `image_points`). Pipeline: segment (dark-on-light or light-on-dark by Otsu or a
// fixed threshold, or an HSV colour range) -> morphological closing -> keep components of a
// minimum area and fill pin-holes -> Guo–Hall parallel thinning (Guo & Hall, CACM 32(3), 1989,
// algorithm A1) -> skeleton graph under m-adjacency (Gonzalez & Woods), so staircase corners
// are not junctions -> prune spurs, contract forks joined by short branches, follow a cusp out
// to its tip and back -> continue each crossing straightest, or fail when that is ambiguous ->
// order from the start end, linking pieces across gaps of up to max_gap px (nearest
// direction-consistent end first) -> move every point to the intensity centroid across the
// local normal, dropping points whose cross-section runs into another strand or the image
// border -> put both ends at the centres of the thread's caps (or on the border) -> optional
// uniform resampling. A region of interest and a mask (CentrelineOptions::roi, ::mask) confine
// the search: pixels outside are background for the segmentation and its statistics, and their
// boundary is a border like the image's (an end cut there is not linked across, a cross-section
// reaching it is dropped, an end is fitted up to it). It never returns a scrambled order: what it cannot order unambiguously is
// a CentrelineError. Pixel centres are at integer coordinates (the OpenCV convention).
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace rodfit {

/// A one-line reason naming the image (when CentrelineOptions::image_name is set).
class CentrelineError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Segmentation {
  kDarkOnLight,  ///< thread darker than the background (grey threshold)
  kLightOnDark,  ///< thread lighter than the background (grey threshold)
  kColourRange,  ///< HSV range [hsv_lo, hsv_hi]; hue wraps round when hsv_lo[0] > hsv_hi[0]
};

struct CentrelineOptions {
  Segmentation segmentation = Segmentation::kDarkOnLight;
  /// Grey level for the threshold modes; < 0 = Otsu, clamped so that it never cuts into the
  /// background's noise (at least max(4 sigma_noise, min_contrast) from the background median).
  int threshold = -1;
  int min_contrast = 10;                          ///< [grey levels], see `threshold`
  cv::Scalar hsv_lo{0, 0, 0};                     ///< OpenCV HSV: H in [0, 180), S, V in [0, 255]
  cv::Scalar hsv_hi{180, 255, 255};
  double pre_blur_sigma = 0.0;                    ///< [px] smoothing before thresholding only
  /// More of the image (of the region, with `roi` or `mask`) than this = no thread.
  double max_foreground_fraction = 0.5;
  int min_component_area = 20;                    ///< [px] smaller blobs are clutter
  int max_hole_area = 16;                         ///< [px] background holes up to this are filled
  int closing_radius = 1;                         ///< [px] closes gaps of about 2 r px; 0 = off
  double min_spur_length = 6.0;                   ///< [px] prune spurs < max(this, 2 w + 2)
  double max_gap = 15.0;                          ///< [px] between skeleton ends of two pieces
  double max_link_turn_deg = 60.0;                ///< [deg] each end's turn into a gap link
  bool resolve_crossings = true;                  ///< false = every crossing is an error
  double max_crossing_turn_deg = 45.0;            ///< [deg] straightest pairing must turn less
  double min_crossing_margin_deg = 20.0;          ///< [deg] ... and beat the next one by this
  bool require_all_pieces = true;                 ///< false = drop pieces that cannot be linked
  bool subpixel = true;                           ///< centroid refinement across the normal
  bool fit_ends = true;                           ///< put the ends at the centres of the caps
  /// [px] resample at the uniform arc-length spacing nearest this that divides the length;
  /// 0 = one point per skeleton pixel (minus those dropped as unreliable).
  double resample_spacing = 0.0;
  /// The start is the thread end nearest this pixel (e.g. the projected clamp); without a hint
  /// it is the end nearest the image border, or the border of the region (`roi`, `mask`) where
  /// that is nearer (ties: the smaller u, then v).
  std::optional<Eigen::Vector2d> start_hint;
  double max_start_distance = 0.0;                ///< [px] hint farther from every end = error
  /// [px] The thread is sought inside this rectangle only: columns x .. x + width - 1, rows
  /// y .. y + height - 1; it must be non-empty and inside the image (else CentrelineError).
  std::optional<cv::Rect> roi;
  /// Single-channel, the image's size (else CentrelineError); non-zero = may hold thread. Empty
  /// = no mask. With `roi` both apply.
  cv::Mat mask;
  std::string image_name;                         ///< named in error messages
  bool Check(std::string* why) const;
};

enum class StartChoice { kNearestHint, kNearestBorder };

struct CentrelineResult {
  std::vector<Eigen::Vector2d> uv;   ///< [px] ordered from the start end
  std::vector<double> half_width_px; ///< [px] half the width at half contrast (0 = unmeasured)
  cv::Mat mask;                      ///< CV_8UC1 0/255: the segmentation that was kept
  Eigen::Vector2d start = Eigen::Vector2d::Zero();  ///< [px] = uv.front()
  Eigen::Vector2d end = Eigen::Vector2d::Zero();    ///< [px] = uv.back()
  StartChoice start_choice = StartChoice::kNearestBorder;
  double threshold = 0.0;            ///< grey level used (threshold modes)
  double mean_half_width_px = 0.0;   ///< mask area / skeleton length / 2
  int num_pieces = 0;                ///< skeleton pieces joined into the result
  int num_gaps_bridged = 0;
  int num_crossings_resolved = 0;
  int num_pieces_dropped = 0;        ///< only with require_all_pieces = false
  std::string BriefReport() const;
};

/// Extracts the ordered centre-line of the single thread in `image` (CV_8U or CV_16U; 1, 3 (BGR)
/// or 4 (BGRA) channels). Throws CentrelineError when nothing is segmented, when pieces cannot
/// be linked within max_gap, when the skeleton branches or closes into a loop that cannot be
/// ordered unambiguously, or when `roi` or `mask` does not fit the image, and
/// std::invalid_argument for invalid options.
CentrelineResult ExtractCentreline(const cv::Mat& image,
                                   const CentrelineOptions& options = CentrelineOptions());

struct OverlayOptions {
  cv::Scalar colour{0, 200, 0};          ///< BGR of the extracted centre-line
  cv::Scalar second_colour{255, 0, 255}; ///< BGR of the second (e.g. fitted) polyline
  int thickness = 1;                     ///< [px]
  bool mark_start = true;                ///< circle at the first point of each polyline
  bool mark_points = false;              ///< a dot at every point
};

/// A BGR copy of `image` (grey is converted) with `uv` and, if not empty, `second` drawn on it
/// with sub-pixel precision (for `rodfit extract --overlay`).
cv::Mat DrawOverlay(const cv::Mat& image, const std::vector<Eigen::Vector2d>& uv,
                    const std::vector<Eigen::Vector2d>& second = {},
                    const OverlayOptions& options = OverlayOptions());

}  // namespace rodfit
