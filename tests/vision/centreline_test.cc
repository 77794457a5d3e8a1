// Tests of image -> centre-line extraction (vision/centreline.h) on rendered threads with known
// centre-lines: arcs, S-curves and a perspective helix at half-widths 0.8 to 4 px, clean and
// blurred with noise (fixed seeds). Every extracted point must lie within 1 px of the truth, in
// order along it (no arc-length jump bigger than the spatial step, so nothing is skipped or
// scrambled) and cover it end to end. Also: border crossing, a bridged gap, crossings,
// self-touching threads, colour segmentation, failures with clear errors, the overlay, and a
// region of interest or mask that excludes clutter (a table edge, clamps).
#include "rodfit/vision/centreline.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "rodfit/vision/render.h"

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;
using Polyline = std::vector<Vec2>;

// ------------------------------------------------------------------------------- truth shapes

Polyline Arc() {  // 100 degrees of a 700 px circle
  Polyline p;
  for (int i = 0; i <= 400; ++i) {
    const double a = -M_PI + 0.9 + (M_PI - 1.8) * i / 400.0;
    p.emplace_back(640 + 700 * std::cos(a), 1000 + 700 * std::sin(a));
  }
  return p;
}

Polyline SCurve(double x0 = 150, double x1 = 1130) {
  Polyline p;
  for (int i = 0; i <= 600; ++i) {
    const double x = x0 + (x1 - x0) * i / 600.0;
    p.emplace_back(x, 512 + 220 * std::sin(2 * M_PI * (x - 150) / 980));
  }
  return p;
}

// A helix (radius 5 cm, `turns` turns over 50 cm) at `distance` m in front of a pinhole with a
// focal length of 2000 px per metre of distance (so its size in the image stays the same), its
// axis turned by `tilt_deg` about the vertical. Near-orthographic views are sinusoids that loop
// (the thread crosses itself in the image) once tan(tilt) > pitch / radius (0.53 for 3 turns);
// close up, perspective sharpens the near end into a cusp.
Polyline Helix(double tilt_deg, double turns, double distance) {
  Polyline p;
  const double b = tilt_deg * M_PI / 180, radius = 0.05, half_len = 0.25, f = 2000 * distance;
  const int n = 1200;
  for (int i = 0; i <= n; ++i) {
    const double t = 2 * M_PI * turns * i / n;
    const double hx = -half_len + 2 * half_len * i / n, hy = radius * std::cos(t),
                 hz = radius * std::sin(t);
    const double x = hx * std::cos(b) + hz * std::sin(b);
    const double z = distance - hx * std::sin(b) + hz * std::cos(b);
    p.emplace_back(640 + f * x / z, 512 + f * hy / z);
  }
  return p;
}

cv::Mat Render(const Polyline& truth, double half_width, double blur, double noise,
               unsigned seed = 1) {
  RenderOptions o;
  o.blur_sigma = blur;
  o.noise_sigma = noise;
  o.seed = seed;
  return RenderThreadImage(truth, std::vector<double>(truth.size(), half_width), o);
}

// --------------------------------------------------------------------------------- comparison

struct Comparison {
  bool ok = true;
  std::string failure;
  double max_dist = 0, rms_dist = 0;
  double s_first = 0, s_last = 0, length = 0;  // truth arc length of the first and last point
};

// Walks the extracted points along the truth: each must lie within `tol` of a truth segment at
// an arc length no less than the previous point's (less `back` for noise along the tangent) and
// no more than the previous plus the spatial step plus `slack`. This is what "ordered, nothing
// skipped" means even where the truth crosses itself.
Comparison Compare(const Polyline& truth, const Polyline& uv, double tol = 1.0,
                   double back = 0.5, double slack = 3.0) {
  Comparison c;
  std::vector<double> s(truth.size(), 0.0);
  for (size_t i = 1; i < truth.size(); ++i) s[i] = s[i - 1] + (truth[i] - truth[i - 1]).norm();
  c.length = s.back();
  double prev = -1e9, sum_sq = 0;
  char buf[256];
  for (size_t k = 0; k < uv.size(); ++k) {
    // The first stretch of truth within tol at an admissible arc length, and on it the
    // nearest point.
    double best_s = 1e18, best_d = 1e18, nearest = 1e18;
    bool in_stretch = false;
    for (size_t i = 0; i + 1 < truth.size(); ++i) {
      const Vec2 ab = truth[i + 1] - truth[i];
      const double t = std::clamp((uv[k] - truth[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      const double d = (uv[k] - truth[i] - t * ab).norm();
      const double sk = s[i] + t * ab.norm();
      nearest = std::min(nearest, d);
      const bool admissible = d <= tol && sk >= prev - back;
      if (admissible && (best_s > 1e17 || in_stretch)) {
        in_stretch = true;
        if (d < best_d) { best_d = d; best_s = sk; }
      } else if (in_stretch) {
        in_stretch = false;
        if (best_s < 1e17) break;
      }
    }
    c.max_dist = std::max(c.max_dist, nearest);
    sum_sq += nearest * nearest;
    const double step = k > 0 ? (uv[k] - uv[k - 1]).norm() : 0;
    if (best_s > 1e17 || (k > 0 && best_s > prev + step + slack)) {
      if (c.ok) {
        std::snprintf(buf, sizeof(buf),
                      "point %zu (%.2f, %.2f): %.2f px from the truth; previous arc length %.1f,"
                      " step %.2f, next admissible arc length %s",
                      k, uv[k].x(), uv[k].y(), nearest, prev, step,
                      best_s > 1e17 ? "none" : std::to_string(best_s).c_str());
        c.failure = buf;
      }
      c.ok = false;
      if (best_s > 1e17) continue;
    }
    if (k == 0) c.s_first = best_s;
    prev = std::max(prev, best_s);
  }
  c.s_last = prev;
  c.rms_dist = uv.empty() ? 0 : std::sqrt(sum_sq / uv.size());
  return c;
}

#define EXPECT_FOLLOWS(cmp, end_tol)                                              \
  do {                                                                            \
    EXPECT_TRUE((cmp).ok) << (cmp).failure;                                       \
    EXPECT_LE((cmp).max_dist, 1.0);                                               \
    EXPECT_LE((cmp).s_first, (end_tol)) << "start not covered";                   \
    EXPECT_GE((cmp).s_last, (cmp).length - (end_tol)) << "end not covered";       \
  } while (0)

// ------------------------------------------------------------------ accuracy over a test grid

struct Case {
  const char* shape;
  double half_width, blur, noise;
};

class Accuracy : public ::testing::TestWithParam<Case> {};

TEST_P(Accuracy, WithinOnePixelOrderedEndToEnd) {
  const Case& c = GetParam();
  const std::string shape = c.shape;
  const Polyline truth = shape == "arc" ? Arc() : shape == "s" ? SCurve() : Helix(5, 3, 1.0);
  const cv::Mat img = Render(truth, c.half_width, c.blur, c.noise, 17);
  CentrelineOptions o;
  o.start_hint = truth.front();  // as the projected clamp would be
  o.image_name = "synthetic-" + shape;
  const CentrelineResult r = ExtractCentreline(img, o);
  const Comparison cmp = Compare(truth, r.uv);
  EXPECT_FOLLOWS(cmp, 3.0);
  EXPECT_EQ(r.num_pieces, 1) << r.BriefReport();
  EXPECT_EQ(r.start_choice, StartChoice::kNearestHint);
  std::printf("[ accuracy ] %-5s w %.1f blur %.1f noise %.0f: %zu pts, max %.3f rms %.3f px, "
              "ends %.2f / %.2f px short, half-width %.2f\n",
              c.shape, c.half_width, c.blur, c.noise, r.uv.size(), cmp.max_dist, cmp.rms_dist,
              cmp.s_first, cmp.length - cmp.s_last, r.mean_half_width_px);

  // Resampled at 2 px: the same truth, uniform steps.
  o.resample_spacing = 2.0;
  const CentrelineResult rs = ExtractCentreline(img, o);
  EXPECT_FOLLOWS(Compare(truth, rs.uv), 3.0);
  for (size_t i = 1; i < rs.uv.size(); ++i) ASSERT_NEAR((rs.uv[i] - rs.uv[i - 1]).norm(), 2.0, 0.3);
}

std::vector<Case> Grid() {
  std::vector<Case> cases;
  for (const char* shape : {"arc", "s", "helix"})
    for (double w : {0.8, 1.5, 2.5, 4.0})
      for (auto [blur, noise] : {std::pair{0.0, 0.0}, {1.0, 4.0}, {1.5, 8.0}})
        cases.push_back({shape, w, blur, noise});
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Shapes, Accuracy, ::testing::ValuesIn(Grid()),
                         [](const ::testing::TestParamInfo<Case>& info) {
                           char buf[64];
                           std::snprintf(buf, sizeof(buf), "%s_w%02d_blur%02d_noise%d",
                                         info.param.shape, int(info.param.half_width * 10),
                                         int(info.param.blur * 10), int(info.param.noise));
                           return std::string(buf);
                         });

// ------------------------------------------------------------------------------ special cases

TEST(CentrelineTest, StartsAtTheEndNearestTheHintOrTheBorder) {
  const Polyline truth = SCurve(300, 1130);  // the far end is nearer the right border
  const cv::Mat img = Render(truth, 2.0, 1.0, 4.0);
  CentrelineOptions o;
  const CentrelineResult r = ExtractCentreline(img, o);
  EXPECT_EQ(r.start_choice, StartChoice::kNearestBorder);
  EXPECT_LT((r.start - truth.back()).norm(), 3.0);
  const Polyline reversed(truth.rbegin(), truth.rend());
  EXPECT_FOLLOWS(Compare(reversed, r.uv), 3.0);

  o.start_hint = Vec2(290, 520);
  const CentrelineResult h = ExtractCentreline(img, o);
  EXPECT_LT((h.start - truth.front()).norm(), 3.0);
  EXPECT_FOLLOWS(Compare(truth, h.uv), 3.0);

  o.max_start_distance = 20;
  o.start_hint = Vec2(700, 100);
  EXPECT_THROW(ExtractCentreline(img, o), CentrelineError);
}

TEST(CentrelineTest, ThreadLeavingTheImageEndsAtTheBorder) {
  const Polyline full = SCurve(-120, 1000);  // enters through the left border
  const cv::Mat img = Render(full, 2.0, 1.0, 4.0, 3);
  const CentrelineResult r = ExtractCentreline(img, CentrelineOptions());
  EXPECT_EQ(r.start_choice, StartChoice::kNearestBorder);
  EXPECT_LT(r.start.x(), 0.5);  // starts on the border column
  const Comparison cmp = Compare(full, r.uv);
  EXPECT_TRUE(cmp.ok) << cmp.failure;
  EXPECT_LE(cmp.max_dist, 1.0);
  double s_enter = 0;  // truth arc length where it enters the image (x = 0)
  for (size_t i = 1; full[i].x() < 0; ++i) s_enter += (full[i] - full[i - 1]).norm();
  EXPECT_NEAR(cmp.s_first, s_enter, 3.0);
  EXPECT_GE(cmp.s_last, cmp.length - 3.0);
}

TEST(CentrelineTest, BridgesAGapInTheMask) {
  const Polyline truth = Arc();
  cv::Mat img = Render(truth, 2.0, 0.0, 0.0);
  // A 6 px wide band of background across the thread near its middle (an occluder).
  const Vec2 mid = truth[200];
  cv::rectangle(img, cv::Point(int(mid.x()) - 3, int(mid.y()) - 20),
                cv::Point(int(mid.x()) + 2, int(mid.y()) + 20), cv::Scalar::all(235), cv::FILLED);
  CentrelineOptions o;
  o.start_hint = truth.front();
  const CentrelineResult r = ExtractCentreline(img, o);
  EXPECT_EQ(r.num_gaps_bridged, 1) << r.BriefReport();
  EXPECT_EQ(r.num_pieces, 2);
  EXPECT_FOLLOWS(Compare(truth, r.uv, 1.0, 0.5, 12.0), 3.0);

  // A 40 px gap is more than max_gap: an error naming the image, or a dropped piece.
  cv::rectangle(img, cv::Point(int(mid.x()) - 20, int(mid.y()) - 30),
                cv::Point(int(mid.x()) + 20, int(mid.y()) + 30), cv::Scalar::all(235), cv::FILLED);
  o.image_name = "cam0/frame_0007.png";
  try {
    ExtractCentreline(img, o);
    ADD_FAILURE() << "expected a CentrelineError";
  } catch (const CentrelineError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cam0/frame_0007.png"), std::string::npos) << what;
    EXPECT_NE(what.find("max_gap"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  o.require_all_pieces = false;
  const CentrelineResult part = ExtractCentreline(img, o);
  EXPECT_EQ(part.num_pieces_dropped, 1);
  const Comparison cmp = Compare(truth, part.uv);
  EXPECT_TRUE(cmp.ok) << cmp.failure;
  EXPECT_LE(cmp.s_first, 3.0);
}

TEST(CentrelineTest, CrossingsAreContinuedStraightest) {
  // A helix seen obliquely loops three times: three genuine crossings. The loops' tops bend
  // with a radius of about 6.5 px; thicker threads than these (w > 3) fill the inside of the
  // bend and pull the centroid there up to 1 px inwards.
  for (double w : {1.0, 2.0, 3.0}) {
    const Polyline truth = Helix(40, 3, 2.0);
    const cv::Mat img = Render(truth, w, 1.0, 4.0, 5);
    CentrelineOptions o;
    o.start_hint = truth.front();
    const CentrelineResult r = ExtractCentreline(img, o);
    EXPECT_EQ(r.num_crossings_resolved, 3) << "w " << w << ": " << r.BriefReport();
    // Trimmed at each crossing: arc-length jumps there are as long as the straight chord.
    const Comparison cmp = Compare(truth, r.uv);
    EXPECT_FOLLOWS(cmp, 3.0);
    std::printf("[ crossing ] w %.1f: max %.3f rms %.3f px\n", w, cmp.max_dist, cmp.rms_dist);

    o.resolve_crossings = false;
    EXPECT_THROW(ExtractCentreline(img, o), CentrelineError);
  }
}

TEST(CentrelineTest, CuspIsOrderedThroughItsTip) {
  // Close up, the near end of a helix turns by almost 180 degrees: the legs merge below the tip
  // and the skeleton forks. The path runs up one leg and down the other; points where the legs
  // overlap cannot be placed on either and are dropped, so the arc length may jump there by up
  // to the merged length on both legs (slack 40 px).
  for (double w : {1.5, 2.5}) {
    const Polyline truth = Helix(8, 3, 0.5);
    const cv::Mat img = Render(truth, w, 1.0, 4.0, 5);
    CentrelineOptions o;
    o.start_hint = truth.front();
    const CentrelineResult r = ExtractCentreline(img, o);
    const Comparison cmp = Compare(truth, r.uv, 1.0, 0.5, 40.0);
    EXPECT_FOLLOWS(cmp, 3.0);
    std::printf("[ cusp     ] w %.1f: max %.3f rms %.3f px\n", w, cmp.max_dist, cmp.rms_dist);
  }
}

// A thread that touches itself (two strands meeting side by side): either ordered correctly or
// a CentrelineError — never scrambled.
void ExpectOrderedOrError(const Polyline& truth, double w, const char* what) {
  const cv::Mat img = Render(truth, w, 1.0, 4.0, 9);
  CentrelineOptions o;
  o.start_hint = truth.front();
  try {
    const CentrelineResult r = ExtractCentreline(img, o);
    SCOPED_TRACE(what);
    EXPECT_FOLLOWS(Compare(truth, r.uv), 3.0);
    std::printf("[ touching ] %s: ordered (%s)\n", what, r.BriefReport().c_str());
  } catch (const CentrelineError& e) {
    std::printf("[ touching ] %s: error: %s\n", what, e.what());
  }
}

TEST(CentrelineTest, SelfTouchingThreadIsOrderedOrAnError) {
  // A hairpin whose legs overlap by 1 px along x in [400, 600] and diverge on both sides: the
  // skeleton forks into three at both ends of the contact, which no straight continuation
  // explains, so the extraction must refuse.
  for (double w : {1.5, 3.0}) {
    auto g = [](double x) { return x > 600 ? 0.002 * (x - 600) * (x - 600)
                                           : x < 400 ? 0.002 * (400 - x) * (400 - x) : 0.0; };
    const double half_sep = w - 0.5;
    Polyline hairpin;
    for (int x = 200; x <= 700; ++x) hairpin.emplace_back(x, 500 + half_sep + g(x));
    const double r = half_sep + g(700);
    for (int i = 1; i < 100; ++i) {
      const double a = M_PI / 2 - M_PI * i / 100;
      hairpin.emplace_back(700 + r * std::cos(a), 500 + r * std::sin(a));
    }
    for (int x = 700; x >= 200; --x) hairpin.emplace_back(x, 500 - half_sep - g(x));
    const cv::Mat img = Render(hairpin, w, 1.0, 4.0, 9);
    CentrelineOptions o;
    o.start_hint = hairpin.front();
    o.image_name = "hairpin.png";
    try {
      ExtractCentreline(img, o);
      ADD_FAILURE() << "expected a CentrelineError for w " << w;
    } catch (const CentrelineError& e) {
      std::printf("[ touching ] hairpin w %.1f: %s\n", w, e.what());
      EXPECT_NE(std::string(e.what()).find("hairpin.png"), std::string::npos);
    }
  }
  // Two strands kissing tangentially at (600, 700): the thread bulges down, runs up the right
  // side and comes back left bulging up until it touches its first half.
  for (double w : {1.5, 2.5, 4.0}) {
    Polyline kiss;
    for (int i = 0; i <= 400; ++i) {
      const double t = i / 400.0;
      kiss.emplace_back(200 + 800 * t, 400 + 300 * std::sin(M_PI * t));
    }
    const double y_low = 1000 + 2 * w - 1;
    for (int i = 1; i < 100; ++i) kiss.emplace_back(1000, 400 + (y_low - 400) * i / 100);
    for (int i = 0; i <= 400; ++i) {
      const double t = 1 - i / 400.0;
      kiss.emplace_back(200 + 800 * t, y_low - 300 * std::sin(M_PI * t));
    }
    char what[64];
    std::snprintf(what, sizeof(what), "kissing strands w %.1f", w);
    ExpectOrderedOrError(kiss, w, what);
  }
}

TEST(CentrelineTest, ColourAndLightOnDarkSegmentation) {
  const Polyline truth = SCurve();
  RenderOptions ro;
  ro.thread = cv::Scalar(200, 90, 30);  // blue thread (BGR) on grey
  ro.blur_sigma = 1.0;
  ro.noise_sigma = 3.0;
  const cv::Mat img = RenderThreadImage(truth, std::vector<double>(truth.size(), 2.5), ro);
  CentrelineOptions o;
  o.segmentation = Segmentation::kColourRange;
  o.hsv_lo = cv::Scalar(95, 120, 60);
  o.hsv_hi = cv::Scalar(130, 255, 255);
  o.start_hint = truth.front();
  EXPECT_FOLLOWS(Compare(truth, ExtractCentreline(img, o).uv), 3.0);

  ro.background = cv::Scalar::all(20);
  ro.thread = cv::Scalar::all(220);
  const cv::Mat light = RenderThreadImage(truth, std::vector<double>(truth.size(), 1.5), ro);
  CentrelineOptions l;
  l.segmentation = Segmentation::kLightOnDark;
  l.start_hint = truth.front();
  EXPECT_FOLLOWS(Compare(truth, ExtractCentreline(light, l).uv), 3.0);
  cv::Mat grey;
  cv::cvtColor(light, grey, cv::COLOR_BGR2GRAY);
  EXPECT_FOLLOWS(Compare(truth, ExtractCentreline(grey, l).uv), 3.0);
}

TEST(CentrelineTest, EmptyOrClutteredImagesGiveClearErrors) {
  // Noise only: the thread is outside the image.
  const cv::Mat noise = Render({Vec2(-50, -50), Vec2(-60, -40)}, 2.0, 1.0, 6.0);
  CentrelineOptions o;
  o.image_name = "empty.png";
  try {
    ExtractCentreline(noise, o);
    ADD_FAILURE() << "expected a CentrelineError";
  } catch (const CentrelineError& e) {
    EXPECT_NE(std::string(e.what()).find("empty.png"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nothing segmented"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ExtractCentreline(cv::Mat(), o), CentrelineError);
  EXPECT_THROW(ExtractCentreline(cv::Mat(100, 100, CV_8UC3, cv::Scalar::all(235)), o),
               CentrelineError);
  // Wrong polarity: most of the image would be "thread".
  o.segmentation = Segmentation::kLightOnDark;
  o.threshold = 100;
  EXPECT_THROW(ExtractCentreline(Render(Arc(), 2.0, 0, 0), o), CentrelineError);
  // A closed ring has no ends to order from.
  Polyline ring;
  for (int i = 0; i <= 400; ++i)
    ring.emplace_back(640 + 200 * std::cos(2 * M_PI * i / 400), 512 + 200 * std::sin(2 * M_PI * i / 400));
  EXPECT_THROW(ExtractCentreline(Render(ring, 2.0, 1.0, 4.0), CentrelineOptions()), CentrelineError);
  // Invalid options are the caller's bug.
  CentrelineOptions bad;
  bad.max_gap = -1;
  EXPECT_THROW(ExtractCentreline(Render(Arc(), 2.0, 0, 0), bad), std::invalid_argument);
}

// ------------------------------------------------------------- region of interest and mask

// Arc length along `truth` to its first point outside `box` (where the thread leaves a clamp).
double ArcLengthLeaving(const Polyline& truth, const cv::Rect& box) {
  double s = 0;
  for (size_t i = 1; i < truth.size() && box.contains(cv::Point(int(std::lround(truth[i - 1].x())),
                                                                  int(std::lround(truth[i - 1].y()))));
       ++i)
    s += (truth[i] - truth[i - 1]).norm();
  return s;
}

// A lab photograph's table edge: a dark band across the bottom of the image, darker than the
// background but lighter than the thread. Otsu then separates the light table from everything
// dark, so the band is segmented with the thread.
TEST(CentrelineRegionTest, ClutterOutsideTheRoiIsIgnored) {
  const Polyline truth = SCurve(300, 980);
  const cv::Mat clean = Render(truth, 2.0, 1.0, 4.0, 5);
  CentrelineOptions o;
  o.start_hint = truth.front();
  o.image_name = "lab.png";
  const CentrelineResult r_clean = ExtractCentreline(clean, o);
  const Comparison c_clean = Compare(truth, r_clean.uv);
  EXPECT_FOLLOWS(c_clean, 3.0);

  cv::Mat cluttered = clean.clone();
  cv::rectangle(cluttered, cv::Point(0, 880), cv::Point(1279, 1023), cv::Scalar::all(90),
                cv::FILLED);
  // Without a region the band is taken as thread: a second piece that cannot be linked.
  try {
    ExtractCentreline(cluttered, o);
    ADD_FAILURE() << "expected a CentrelineError";
  } catch (const CentrelineError& e) {
    EXPECT_NE(std::string(e.what()).find("disjoint pieces"), std::string::npos) << e.what();
  }

  o.roi = cv::Rect(0, 0, 1280, 860);  // the rows above the band
  const CentrelineResult r = ExtractCentreline(cluttered, o);
  const Comparison cmp = Compare(truth, r.uv);
  EXPECT_FOLLOWS(cmp, 3.0);
  EXPECT_EQ(r.num_pieces, 1) << r.BriefReport();
  // The same accuracy as on the clean image: the band is out of the threshold's statistics.
  EXPECT_NEAR(r.threshold, r_clean.threshold, 2.0);
  EXPECT_LE(cmp.rms_dist, c_clean.rms_dist + 0.02);
  std::printf("[ roi ] clean max %.3f rms %.3f px; band outside the roi max %.3f rms %.3f px\n",
              c_clean.max_dist, c_clean.rms_dist, cmp.max_dist, cmp.rms_dist);
  // The mask is the segmentation: nothing of the band.
  EXPECT_EQ(cv::countNonZero(r.mask(cv::Rect(0, 860, 1280, 164))), 0);
}

// Clamps holding both ends: dark jaws (60 x 140 px) the thread runs into. A mask that excludes
// them (and 10 px round them) cuts the thread where it leaves each, and those cut ends are treated
// as ends at the image border.
TEST(CentrelineRegionTest, AMaskCutsTheThreadLikeTheImageBorder) {
  const Polyline truth = SCurve(300, 980);
  cv::Mat grey;
  cv::cvtColor(Render(truth, 2.0, 1.0, 4.0, 6), grey, cv::COLOR_BGR2GRAY);
  cv::Mat1b mask(grey.size(), uchar(255));
  std::vector<cv::Rect> excluded;
  for (const Vec2& end : {truth.front(), truth.back()}) {
    const cv::Point c(int(std::lround(end.x())), int(std::lround(end.y())));
    grey(cv::Rect(c.x - 30, c.y - 70, 60, 140)).setTo(60);
    excluded.emplace_back(c.x - 40, c.y - 80, 80, 160);
    mask(excluded.back()).setTo(0);
  }
  const cv::Mat before = grey.clone();
  CentrelineOptions o;
  o.image_name = "clamps.png";

  // Without the mask each clamp is a blob at an end of the thread: the cross-sections there are
  // dropped as too wide, but the jaws' area counts as thread, so the half-width that scales
  // pruning, the crossing merge distance and the cross-section reach is four times too large.
  const CentrelineResult unmasked = ExtractCentreline(grey, o);

  o.mask = mask;
  const CentrelineResult r = ExtractCentreline(grey, o);
  EXPECT_EQ(cv::countNonZero(grey != before), 0) << "the caller's image was changed";
  EXPECT_EQ(r.num_pieces, 1) << r.BriefReport();
  EXPECT_NEAR(r.mean_half_width_px, 2.0, 0.5);
  EXPECT_GT(unmasked.mean_half_width_px, 4 * 2.0) << unmasked.BriefReport();
  // Both ends are on the mask's border: the tie goes to the smaller u, the truth's first point.
  EXPECT_EQ(r.start_choice, StartChoice::kNearestBorder);
  const Comparison cmp = Compare(truth, r.uv);
  EXPECT_TRUE(cmp.ok) << cmp.failure;
  EXPECT_LE(cmp.max_dist, 1.0);
  // Both ends where the thread leaves the excluded boxes (as at the image border, the end is
  // the last whole cross-section inside, up to a half-width and the sampling step short).
  const double s_in = ArcLengthLeaving(truth, excluded[0]);
  const Polyline reversed(truth.rbegin(), truth.rend());
  const double s_out = cmp.length - ArcLengthLeaving(reversed, excluded[1]);
  EXPECT_NEAR(cmp.s_first, s_in, 3.0);
  EXPECT_NEAR(cmp.s_last, s_out, 3.0);
  std::printf("[ mask ] clamps masked: max %.3f rms %.3f px, ends %.2f / %.2f px from the mask\n",
              cmp.max_dist, cmp.rms_dist, cmp.s_first - s_in, s_out - cmp.s_last);

  // The clean image, its ends cut at the same boxes, for the same accuracy.
  cv::Mat clean_grey;
  cv::cvtColor(Render(truth, 2.0, 1.0, 4.0, 6), clean_grey, cv::COLOR_BGR2GRAY);
  const Comparison c_clean = Compare(truth, ExtractCentreline(clean_grey, o).uv);
  EXPECT_LE(cmp.rms_dist, c_clean.rms_dist + 0.02);

  // A thread end cut by the mask is not linked across a gap: with a band of the mask cleared
  // across the middle the two halves stay apart (as two pieces leaving the image would).
  const Vec2 mid = truth[300];
  cv::rectangle(o.mask, cv::Point(int(mid.x()) - 3, 0), cv::Point(int(mid.x()) + 3, 1023),
                cv::Scalar::all(0), cv::FILLED);
  EXPECT_THROW(ExtractCentreline(grey, o), CentrelineError);
}

TEST(CentrelineRegionTest, RegionsThatDoNotFitTheImageAreErrors) {
  const cv::Mat img = Render(Arc(), 2.0, 0, 0);
  auto message = [&](const CentrelineOptions& o) -> std::string {
    try {
      ExtractCentreline(img, o);
    } catch (const CentrelineError& e) {
      return e.what();
    }
    return "no error";
  };
  CentrelineOptions o;
  o.image_name = "left.png";
  o.roi = cv::Rect(1200, 0, 100, 100);  // past the right border (1280 px)
  std::string what = message(o);
  EXPECT_NE(what.find("left.png"), std::string::npos) << what;
  EXPECT_NE(what.find("roi [1200, 1300) x [0, 100) is not inside the 1280x1024"),
            std::string::npos) << what;
  EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  o.roi = cv::Rect(-1, 0, 10, 10);
  EXPECT_NE(message(o).find("is not inside"), std::string::npos) << message(o);
  o.roi = cv::Rect(10, 10, 0, 5);
  what = message(o);
  EXPECT_NE(what.find("roi [10, 10) x [10, 15) is empty"), std::string::npos) << what;

  o.roi.reset();
  o.mask = cv::Mat1b(100, 100, uchar(255));
  what = message(o);
  EXPECT_NE(what.find("left.png"), std::string::npos) << what;
  EXPECT_NE(what.find("the mask is 100x100 px but the image is 1280x1024 px"), std::string::npos)
      << what;
  o.mask = cv::Mat(img.size(), CV_8UC3, cv::Scalar::all(255));
  EXPECT_NE(message(o).find("the mask has 3 channels"), std::string::npos) << message(o);
  o.mask = cv::Mat1b(img.size(), uchar(0));
  EXPECT_NE(message(o).find("mask leaves no pixel"), std::string::npos) << message(o);
  // A roi where the mask is zero leaves nothing either.
  o.mask = cv::Mat1b(img.size(), uchar(255));
  o.mask(cv::Rect(0, 0, 200, 200)).setTo(0);
  o.roi = cv::Rect(0, 0, 100, 100);
  EXPECT_NE(message(o).find("roi and mask leave no pixel"), std::string::npos) << message(o);
  // A roi that holds no thread: nothing segmented, as for an empty image.
  o.mask.release();
  EXPECT_NE(message(o).find("nothing segmented"), std::string::npos) << message(o);
}

TEST(CentrelineTest, OverlayDrawsBothPolylines) {
  const Polyline truth = Arc();
  const cv::Mat img = Render(truth, 2.0, 0, 0);
  const Polyline shifted{Vec2(100, 100), Vec2(300, 100)};
  OverlayOptions oo;
  oo.mark_start = false;
  const cv::Mat over = DrawOverlay(img, truth, shifted, oo);
  ASSERT_EQ(over.type(), CV_8UC3);
  const Vec2 p = truth[150];
  // Antialiased lines blend into the image: test the dominant channels.
  const cv::Vec3b on_line = over.at<cv::Vec3b>(int(std::lround(p.y())), int(std::lround(p.x())));
  EXPECT_GT(on_line[1], 150);
  EXPECT_LT(on_line[0], 60);
  EXPECT_LT(on_line[2], 60);
  const cv::Vec3b on_second = over.at<cv::Vec3b>(100, 200);
  EXPECT_GT(on_second[0], 200);
  EXPECT_LT(on_second[1], 60);
  EXPECT_GT(on_second[2], 200);
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(DrawOverlay(grey, truth).type(), CV_8UC3);
}

}  // namespace
}  // namespace rodfit
