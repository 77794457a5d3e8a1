// Image -> ordered thread centre-line; see centreline.h for the pipeline. Internally the skeleton
// lives in an image padded by one zero pixel on every side, so neighbour look-ups need no bounds
// checks; coordinates are shifted back when pieces are built.
#include "rodfit/vision/centreline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include <Eigen/QR>
#include <opencv2/imgproc.hpp>

namespace rodfit {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

[[noreturn]] void Fail(const CentrelineOptions& options, const std::string& what) {
  const std::string where = options.image_name.empty() ? "" : options.image_name + ": ";
  throw CentrelineError(where + "centre-line extraction: " + what);
}

std::string At(const Vec2& p) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "(%.1f, %.1f)", p.x(), p.y());
  return buf;
}

// Median of the positive values (unmeasured ones are 0), or `fallback` if there are none.
double MedianPositive(const std::vector<double>& values, double fallback) {
  std::vector<double> v;
  for (double x : values) if (x > 0) v.push_back(x);
  if (v.empty()) return fallback;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Where the thread may be: the image, or its pixels inside options.roi and options.mask. The
// region's boundary is treated like the image's border wherever that matters.
struct Region {
  cv::Size size;
  cv::Mat1b allowed;  // 255 = may hold thread; empty = the whole image
  cv::Mat1f dist;     // [px] from each allowed pixel to the nearest excluded one; empty likewise
  int area = 0;       // [px] allowed pixels

  bool Allows(int x, int y) const { return allowed.empty() || allowed(y, x) != 0; }

  // [px] from p (a pixel position) to the nearest border: 0 on the outermost pixels of the
  // image, and on the allowed pixels next to an excluded one.
  double BorderDistance(const Vec2& p) const {
    double d = std::min({p.x(), p.y(), size.width - 1 - p.x(), size.height - 1 - p.y()});
    if (!dist.empty()) {
      const int x = std::clamp(static_cast<int>(std::lround(p.x())), 0, size.width - 1);
      const int y = std::clamp(static_cast<int>(std::lround(p.y())), 0, size.height - 1);
      d = std::min(d, std::max(0.0, dist(y, x) - 1.0));
    }
    return d;
  }
};

std::string RoiText(const cv::Rect& r) {
  std::ostringstream out;
  out << "[" << r.x << ", " << r.x + r.width << ") x [" << r.y << ", " << r.y + r.height << ")";
  return out.str();
}

// Checks options.roi and options.mask against the image and builds the region they leave.
Region MakeRegion(const cv::Mat& image, const CentrelineOptions& o) {
  Region region;
  region.size = image.size();
  region.area = static_cast<int>(image.total());
  const std::string size = std::to_string(image.cols) + "x" + std::to_string(image.rows);
  if (o.roi) {
    const cv::Rect& r = *o.roi;
    if (r.width <= 0 || r.height <= 0)
      Fail(o, "roi " + RoiText(r) + " is empty (x1 must exceed x0 and y1 y0)");
    if (r.x < 0 || r.y < 0 || r.x + r.width > image.cols || r.y + r.height > image.rows)
      Fail(o, "roi " + RoiText(r) + " is not inside the " + size + " px image");
  }
  if (!o.mask.empty()) {
    if (o.mask.channels() != 1) {
      Fail(o, "the mask has " + std::to_string(o.mask.channels()) +
                  " channels (it must be a single-channel image)");
    }
    if (o.mask.size() != image.size()) {
      Fail(o, "the mask is " + std::to_string(o.mask.cols) + "x" + std::to_string(o.mask.rows) +
                  " px but the image is " + size + " px");
    }
  }
  if (!o.roi && o.mask.empty()) return region;
  region.allowed = cv::Mat1b(image.size(), uchar(0));
  if (o.roi) region.allowed(*o.roi).setTo(255);
  else region.allowed.setTo(255);
  if (!o.mask.empty()) {
    cv::Mat1b nonzero;
    cv::compare(o.mask, 0, nonzero, cv::CMP_NE);
    region.allowed &= nonzero;
  }
  region.area = cv::countNonZero(region.allowed);
  if (region.area == 0) {
    // A roi alone is never empty here (checked above): the mask is zero where it looks.
    Fail(o, o.roi ? "the roi and mask leave no pixel to search (the mask is zero inside the roi)"
                  : "the mask leaves no pixel to search (it is zero everywhere)");
  }
  // Distances to the nearest excluded pixel; the zero padding makes the image border one too,
  // so that a single look-up serves both.
  cv::Mat1b padded;
  cv::copyMakeBorder(region.allowed, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
  cv::Mat1f dist;
  cv::distanceTransform(padded, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  region.dist = dist(cv::Rect(1, 1, image.cols, image.rows)).clone();
  return region;
}

// ---------------------------------------------------------------------------------------------
// Segmentation

cv::Mat1b ToGrey(const cv::Mat& image) {
  cv::Mat eight = image;
  if (image.depth() == CV_16U) image.convertTo(eight, CV_8U, 1.0 / 256.0);
  cv::Mat1b grey;
  if (eight.channels() == 1) grey = eight;
  else if (eight.channels() == 3) cv::cvtColor(eight, grey, cv::COLOR_BGR2GRAY);
  else cv::cvtColor(eight, grey, cv::COLOR_BGRA2GRAY);
  return grey;
}

cv::Mat3b ToBgr(const cv::Mat& image) {
  cv::Mat eight = image;
  if (image.depth() == CV_16U) image.convertTo(eight, CV_8U, 1.0 / 256.0);
  cv::Mat3b bgr;
  if (eight.channels() == 1) cv::cvtColor(eight, bgr, cv::COLOR_GRAY2BGR);
  else if (eight.channels() == 4) cv::cvtColor(eight, bgr, cv::COLOR_BGRA2BGR);
  else bgr = eight.clone();
  return bgr;
}

// Median of the grey levels where `where` is set (all pixels when `where` is empty).
int MedianGrey(const cv::Mat1b& grey, const cv::Mat1b& where, std::array<double, 256>* hist_out) {
  std::array<int, 256> count{};
  const bool all = where.empty();
  for (int y = 0; y < grey.rows; ++y) {
    const uchar* g = grey.ptr<uchar>(y);
    const uchar* w = all ? nullptr : where.ptr<uchar>(y);
    for (int x = 0; x < grey.cols; ++x) count[g[x]] += all || w[x];
  }
  std::array<double, 256> hist;
  double n = 0;
  for (int l = 0; l < 256; ++l) n += hist[l] = count[l];
  if (hist_out) *hist_out = hist;
  double acc = 0;
  for (int l = 0; l < 256; ++l) {
    acc += hist[l];
    if (acc >= 0.5 * n) return l;
  }
  return 255;
}

// Otsu's threshold on a grey-level histogram: the last level of the darker class that maximises
// the between-class variance w0 w1 (m0 - m1)^2 (the first maximum on ties, as cv::threshold).
// Computed here rather than by cv::threshold so that it sees the region's pixels only.
int OtsuLevel(const std::array<double, 256>& hist) {
  double n = 0, sum = 0;
  for (int l = 0; l < 256; ++l) {
    n += hist[l];
    sum += l * hist[l];
  }
  double w0 = 0, sum0 = 0, best = 0;
  int level = 0;
  for (int l = 0; l < 255; ++l) {
    w0 += hist[l];
    sum0 += l * hist[l];
    const double w1 = n - w0;
    if (w0 <= 0 || w1 <= 0) continue;
    const double gap = sum0 / w0 - (sum - sum0) / w1;
    const double between = w0 * w1 * gap * gap;
    if (between > best) {
      best = between;
      level = l;
    }
  }
  return level;
}

struct Segmented {
  cv::Mat1b mask;         // 0/255
  cv::Mat1b grey;         // for the sub-pixel weights (threshold modes)
  double threshold = 0;
};

// Pixels outside the region are background: they are left out of every statistic, filled with
// the region's median grey before the pre-blur (so clutter there does not bleed in) and cleared
// in the mask.
Segmented Segment(const cv::Mat& image, const Region& region, const CentrelineOptions& o) {
  Segmented s;
  if (o.segmentation == Segmentation::kColourRange) {
    cv::Mat hsv;
    cv::cvtColor(ToBgr(image), hsv, cv::COLOR_BGR2HSV);
    if (o.pre_blur_sigma > 0) cv::GaussianBlur(hsv, hsv, cv::Size(0, 0), o.pre_blur_sigma);
    if (o.hsv_lo[0] <= o.hsv_hi[0]) {
      cv::inRange(hsv, o.hsv_lo, o.hsv_hi, s.mask);
    } else {  // hue wraps round (red): [lo, 180) or [0, hi]
      cv::Mat1b a, b;
      cv::inRange(hsv, o.hsv_lo, cv::Scalar(180, o.hsv_hi[1], o.hsv_hi[2]), a);
      cv::inRange(hsv, cv::Scalar(0, o.hsv_lo[1], o.hsv_lo[2]), o.hsv_hi, b);
      s.mask = a | b;
    }
    if (!region.allowed.empty()) s.mask &= region.allowed;
    return s;
  }
  s.grey = ToGrey(image);
  if (!region.allowed.empty()) {
    const int fill = MedianGrey(s.grey, region.allowed, nullptr);
    s.grey = s.grey.clone();  // may share the caller's pixels
    s.grey.setTo(fill, region.allowed == 0);
  }
  cv::Mat1b smooth = s.grey;
  if (o.pre_blur_sigma > 0) cv::GaussianBlur(s.grey, smooth, cv::Size(0, 0), o.pre_blur_sigma);
  const bool dark = o.segmentation == Segmentation::kDarkOnLight;
  if (o.threshold >= 0) {
    s.threshold = o.threshold;
  } else {
    // Otsu alone splits the background's noise when the thread covers a tiny fraction of the
    // image; keep the threshold outside the background's noise band (robust sigma from MAD).
    std::array<double, 256> hist;
    const int median = MedianGrey(smooth, region.allowed, &hist);
    std::array<double, 256> dev{};
    for (int l = 0; l < 256; ++l) dev[std::abs(l - median)] += hist[l];
    double acc = 0, mad = 0;
    for (int l = 0; l < 256; ++l) {
      acc += dev[l];
      if (acc >= 0.5 * region.area) { mad = l; break; }
    }
    const double band = std::max(4.0 * 1.4826 * mad, static_cast<double>(o.min_contrast));
    const double otsu = OtsuLevel(hist);
    s.threshold = dark ? std::min(otsu, median - band) : std::max(otsu, median + band);
  }
  if (dark) s.mask = smooth <= s.threshold;
  else s.mask = smooth > s.threshold;
  if (!region.allowed.empty()) s.mask &= region.allowed;
  return s;
}

// Closing, component filter and pin-hole filling; neither closing nor filling may reach out of
// the region.
void CleanMask(const CentrelineOptions& o, const Region& region, cv::Mat1b* mask) {
  if (o.closing_radius > 0) {
    const int k = 2 * o.closing_radius + 1;
    cv::morphologyEx(*mask, *mask, cv::MORPH_CLOSE,
                     cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
    if (!region.allowed.empty()) *mask &= region.allowed;
  }
  cv::Mat1i labels;
  cv::Mat stats, centroids;
  int n = cv::connectedComponentsWithStats(*mask, labels, stats, centroids, 8, CV_32S);
  std::vector<uchar> keep(n, 0);
  for (int i = 1; i < n; ++i) keep[i] = stats.at<int>(i, cv::CC_STAT_AREA) >= o.min_component_area;
  for (int y = 0; y < mask->rows; ++y) {
    uchar* m = mask->ptr<uchar>(y);
    const int* l = labels.ptr<int>(y);
    for (int x = 0; x < mask->cols; ++x) m[x] = keep[l[x]] ? 255 : 0;
  }

  cv::Mat1b background = ~(*mask);
  n = cv::connectedComponentsWithStats(background, labels, stats, centroids, 4, CV_32S);
  std::vector<uchar> fill(n, 0);
  for (int i = 1; i < n; ++i) {
    const int l = stats.at<int>(i, cv::CC_STAT_LEFT), t = stats.at<int>(i, cv::CC_STAT_TOP);
    const int w = stats.at<int>(i, cv::CC_STAT_WIDTH), h = stats.at<int>(i, cv::CC_STAT_HEIGHT);
    const bool inner = l > 0 && t > 0 && l + w < mask->cols && t + h < mask->rows;
    fill[i] = inner && stats.at<int>(i, cv::CC_STAT_AREA) <= o.max_hole_area;
  }
  for (int y = 0; y < mask->rows; ++y) {
    uchar* m = mask->ptr<uchar>(y);
    const int* l = labels.ptr<int>(y);
    for (int x = 0; x < mask->cols; ++x) m[x] |= fill[l[x]] ? 255 : 0;
  }
  if (!region.allowed.empty()) *mask &= region.allowed;
}

// ---------------------------------------------------------------------------------------------
// Thinning and the skeleton graph

// Neighbours N, NE, E, SE, S, SW, W, NW (P2..P9 in Guo & Hall's numbering).
constexpr int kDx[8] = {0, 1, 1, 1, 0, -1, -1, -1};
constexpr int kDy[8] = {-1, -1, 0, 1, 1, 1, 0, -1};

// Guo–Hall algorithm A1 on a 0/1 image with a zero border; only the foreground pixels are
// visited, so the cost is proportional to the thread's area, not the image's.
void ThinGuoHall(cv::Mat1b* img) {
  std::vector<cv::Point> live, doomed;
  cv::findNonZero(*img, live);
  for (int iter = 0; iter < img->rows + img->cols; ++iter) {
    bool changed = false;
    for (int sub = 0; sub < 2; ++sub) {
      doomed.clear();
      for (const cv::Point& p : live) {
        if (!(*img)(p)) continue;
        bool q[10];  // q[2..9] = P2..P9
        for (int k = 0; k < 8; ++k) q[k + 2] = (*img)(p.y + kDy[k], p.x + kDx[k]) != 0;
        const int c = (!q[2] && (q[3] || q[4])) + (!q[4] && (q[5] || q[6])) +
                      (!q[6] && (q[7] || q[8])) + (!q[8] && (q[9] || q[2]));
        const int n1 = (q[9] || q[2]) + (q[3] || q[4]) + (q[5] || q[6]) + (q[7] || q[8]);
        const int n2 = (q[2] || q[3]) + (q[4] || q[5]) + (q[6] || q[7]) + (q[8] || q[9]);
        const int n = std::min(n1, n2);
        const bool m = sub == 0 ? ((q[6] || q[7] || !q[9]) && q[8])
                                : ((q[2] || q[3] || !q[5]) && q[4]);
        if (c == 1 && n >= 2 && n <= 3 && !m) doomed.push_back(p);
      }
      for (const cv::Point& p : doomed) (*img)(p) = 0;
      changed = changed || !doomed.empty();
    }
    if (!changed) break;
    live.erase(std::remove_if(live.begin(), live.end(),
                              [&](const cv::Point& p) { return !(*img)(p); }),
               live.end());
  }
}

// m-adjacent neighbours: a diagonal neighbour counts only when no 4-neighbour is shared, so the
// staircase corners thinning leaves are paths, not junctions.
int MNeighbours(const cv::Mat1b& skel, cv::Point p, cv::Point out[8]) {
  bool on[8];
  for (int k = 0; k < 8; ++k) on[k] = skel(p.y + kDy[k], p.x + kDx[k]) != 0;
  int n = 0;
  for (int k = 0; k < 8; ++k) {
    if (!on[k]) continue;
    if (k % 2 == 1 && (on[k - 1] || on[(k + 1) % 8])) continue;
    out[n++] = cv::Point(p.x + kDx[k], p.y + kDy[k]);
  }
  return n;
}

double PathLength(const std::vector<cv::Point>& px) {
  double len = 0;
  for (size_t i = 1; i < px.size(); ++i) len += std::hypot(px[i].x - px[i - 1].x, px[i].y - px[i - 1].y);
  return len;
}

struct Node {
  bool junction = false;
  bool alive = true;
  std::vector<cv::Point> px;
  std::vector<int> ends;  // 2 * branch + side (0 = the branch's first pixel)
};
struct Branch {
  int node[2] = {-1, -1};
  std::vector<cv::Point> px;  // from a pixel of node[0] to a pixel of node[1]
  bool alive = true;
};
struct Graph {
  std::vector<Node> nodes;
  std::vector<Branch> branches;
  std::vector<std::vector<cv::Point>> cycles;  // closed skeleton loops without nodes
  std::vector<cv::Point> dots;                 // components thinned to one pixel
  double length = 0;                           // [px] of the whole skeleton
};

int AddBranch(Graph* g, std::vector<cv::Point> px, int a, int b) {
  const int id = static_cast<int>(g->branches.size());
  Branch br;
  br.node[0] = a;
  br.node[1] = b;
  br.px = std::move(px);
  g->branches.push_back(std::move(br));
  g->nodes[a].ends.push_back(2 * id);
  g->nodes[b].ends.push_back(2 * id + 1);
  return id;
}

Graph BuildGraph(const cv::Mat1b& skel) {
  Graph g;
  std::vector<cv::Point> pts;
  cv::findNonZero(skel, pts);
  cv::Mat1b degree(skel.size(), uchar(0));
  cv::Point nb[8];
  for (const cv::Point& p : pts) {
    degree(p) = static_cast<uchar>(MNeighbours(skel, p, nb));
    for (int k = 0; k < degree(p); ++k) g.length += 0.5 * std::hypot(nb[k].x - p.x, nb[k].y - p.y);
  }
  cv::Mat1i label(skel.size(), -1);
  for (const cv::Point& p : pts) {
    if (degree(p) == 0) g.dots.push_back(p);
    if (degree(p) == 1) {
      label(p) = static_cast<int>(g.nodes.size());
      g.nodes.push_back(Node{false, true, {p}, {}});
    }
    if (degree(p) < 3 || label(p) >= 0) continue;
    // Junction pixels touching each other (8-connected) form one junction node.
    const int id = static_cast<int>(g.nodes.size());
    g.nodes.push_back(Node{true, true, {}, {}});
    std::vector<cv::Point> stack{p};
    label(p) = id;
    while (!stack.empty()) {
      const cv::Point q = stack.back();
      stack.pop_back();
      g.nodes[id].px.push_back(q);
      for (int k = 0; k < 8; ++k) {
        const cv::Point r(q.x + kDx[k], q.y + kDy[k]);
        if (skel(r) && degree(r) >= 3 && label(r) < 0) { label(r) = id; stack.push_back(r); }
      }
    }
  }
  cv::Mat1b visited(skel.size(), uchar(0));
  for (int n = 0; n < static_cast<int>(g.nodes.size()); ++n) {
    const std::vector<cv::Point> node_px = g.nodes[n].px;
    for (const cv::Point& q : node_px) {
      const int count = MNeighbours(skel, q, nb);
      for (int k = 0; k < count; ++k) {
        const cv::Point r = nb[k];
        if (label(r) == n) continue;
        if (label(r) >= 0) {
          if (n < label(r)) AddBranch(&g, {q, r}, n, label(r));
          continue;
        }
        if (visited(r)) continue;
        std::vector<cv::Point> path{q, r};
        visited(r) = 1;
        cv::Point prev = q, cur = r;
        for (size_t guard = 0; guard <= pts.size(); ++guard) {
          cv::Point next(-1, -1), around[8];
          const int c2 = MNeighbours(skel, cur, around);
          for (int j = 0; j < c2; ++j) if (around[j] != prev) { next = around[j]; break; }
          if (next.x < 0 || (label(next) < 0 && visited(next))) break;  // cannot happen
          path.push_back(next);
          if (label(next) >= 0) { AddBranch(&g, path, n, label(next)); break; }
          visited(next) = 1;
          prev = cur;
          cur = next;
        }
      }
    }
  }
  for (const cv::Point& p : pts) {  // what is left of degree 2 are closed loops
    if (degree(p) != 2 || visited(p) || label(p) >= 0) continue;
    std::vector<cv::Point> loop{p};
    visited(p) = 1;
    for (cv::Point cur = p;;) {
      const int c2 = MNeighbours(skel, cur, nb);
      cv::Point next(-1, -1);
      for (int j = 0; j < c2; ++j) if (!visited(nb[j])) { next = nb[j]; break; }
      if (next.x < 0) break;
      visited(next) = 1;
      loop.push_back(next);
      cur = next;
    }
    g.cycles.push_back(std::move(loop));
  }
  return g;
}

void ReplaceEnd(Node* node, int from, int to) {
  std::replace(node->ends.begin(), node->ends.end(), from, to);
}

// The pixels of branch end e (2 * branch + side) ordered from its node outwards.
std::vector<cv::Point> FromNode(const Graph& g, int e) {
  std::vector<cv::Point> px = g.branches[e / 2].px;
  if (e % 2 == 1) std::reverse(px.begin(), px.end());
  return px;
}

// Unit direction from the node of branch end e to the branch pixel `dist` px along it.
Eigen::Vector2d DirectionFrom(const Graph& g, int e, double dist) {
  const std::vector<cv::Point> px = FromNode(g, e);
  double len = 0;
  size_t i = 1;
  for (; i + 1 < px.size() && len < dist; ++i) len += std::hypot(px[i].x - px[i - 1].x, px[i].y - px[i - 1].y);
  const Eigen::Vector2d d(px[std::min(i, px.size() - 1)].x - px[0].x, px[std::min(i, px.size() - 1)].y - px[0].y);
  return d.norm() > 0 ? Eigen::Vector2d(d.normalized()) : Eigen::Vector2d::Zero();
}

// Replaces the branches of ends e1 and e2 at junction j by one branch running in along e1,
// through `middle`, and out along e2; j dies.
void JoinThrough(int j, int e1, int e2, const std::vector<cv::Point>& middle, Graph* g) {
  std::vector<cv::Point> px = FromNode(*g, e1);
  std::reverse(px.begin(), px.end());
  px.insert(px.end(), middle.begin(), middle.end());
  const std::vector<cv::Point> out = FromNode(*g, e2);
  px.insert(px.end(), out.begin(), out.end());
  const int b1 = e1 / 2, b2 = e2 / 2, s1 = e1 % 2, s2 = e2 % 2;
  const int na = g->branches[b1].node[1 - s1], nc = g->branches[b2].node[1 - s2];
  g->branches[b1].alive = g->branches[b2].alive = false;
  g->nodes[j].alive = false;
  const int id = static_cast<int>(g->branches.size());
  ReplaceEnd(&g->nodes[na], 2 * b1 + (1 - s1), 2 * id);
  ReplaceEnd(&g->nodes[nc], 2 * b2 + (1 - s2), 2 * id + 1);
  Branch nb;
  nb.node[0] = na;
  nb.node[1] = nc;
  nb.px = std::move(px);
  g->branches.push_back(std::move(nb));
}

double Angle(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return std::acos(std::clamp(a.dot(b) / std::max(a.norm() * b.norm(), 1e-12), -1.0, 1.0));
}

// Prunes the spurs shorter than spur_len at each junction (thinning artefacts at the caps and
// on bumps), keeping a straight continuation where the thread ends. Whether any was pruned.
bool PruneSpurs(double spur_len, double probe, Graph* g) {
  bool changed = false;
  for (int j = 0; j < static_cast<int>(g->nodes.size()); ++j) {
    if (!g->nodes[j].alive || !g->nodes[j].junction) continue;
    std::vector<std::pair<double, int>> spurs;
    for (int e : g->nodes[j].ends) {
      const Branch& b = g->branches[e / 2];
      const int other = b.node[1 - e % 2];
      if (other != j && !g->nodes[other].junction && PathLength(b.px) < spur_len)
        spurs.emplace_back(PathLength(b.px), e);
    }
    std::sort(spurs.begin(), spurs.end());
    if (!spurs.empty() && g->nodes[j].ends.size() == spurs.size() + 1) {
      // Only one long branch: the thread ends here. A spur that continues it straight is its
      // last few pixels, not a thinning artefact; keep the straightest one within 30 degrees.
      int main_e = -1;
      for (int e : g->nodes[j].ends)
        if (std::none_of(spurs.begin(), spurs.end(), [e](const auto& sp) { return sp.second == e; }))
          main_e = e;
      const Eigen::Vector2d in = -DirectionFrom(*g, main_e, probe);
      double best = kPi / 6;
      size_t tail = spurs.size();
      for (size_t k = 0; k < spurs.size(); ++k) {
        const double turn = Angle(in, DirectionFrom(*g, spurs[k].second, probe));
        if (turn < best) { best = turn; tail = k; }
      }
      if (tail < spurs.size()) spurs.erase(spurs.begin() + tail);
    }
    for (const auto& [len, e] : spurs) {
      Node& jn = g->nodes[j];
      if (jn.ends.size() <= 1) break;  // keep the longest: a short piece is still a piece
      Branch& b = g->branches[e / 2];
      b.alive = false;
      g->nodes[b.node[1 - e % 2]].alive = false;
      jn.ends.erase(std::find(jn.ends.begin(), jn.ends.end(), e));
      jn.px.push_back(b.px[b.px.size() / 2]);  // the junction keeps a trace of where it was
      changed = true;
    }
  }
  return changed;
}

// Contracts the junctions joined by branches shorter than merge_len. Whether any was.
bool MergeJunctions(double merge_len, Graph* g) {
  bool changed = false;
  for (Branch& b : g->branches) {
    if (!b.alive || !g->nodes[b.node[0]].junction || !g->nodes[b.node[1]].junction ||
        PathLength(b.px) >= merge_len)
      continue;
    const int id = static_cast<int>(&b - g->branches.data());
    const int j = b.node[0], k = b.node[1];
    Node& jn = g->nodes[j];
    if (k != j) {
      Node& kn = g->nodes[k];
      jn.px.insert(jn.px.end(), kn.px.begin(), kn.px.end());
      for (int e : kn.ends) {
        if (e / 2 == id) continue;
        jn.ends.push_back(e);
        g->branches[e / 2].node[e % 2] = j;
      }
      kn.alive = false;
    }
    jn.ends.erase(std::remove_if(jn.ends.begin(), jn.ends.end(),
                                 [id](int e) { return e / 2 == id; }),
                  jn.ends.end());
    jn.px.insert(jn.px.end(), b.px.begin(), b.px.end());
    b.alive = false;
    changed = true;
  }
  return changed;
}

// Dissolves the junctions left with no branch, one or two, and turns a cusp (two branches
// leaving in a V, a spur shorter than cusp_len along its bisector) into one path out to the tip
// and back. Whether any changed.
bool DissolveJunctions(double cusp_len, double probe, Graph* g) {
  bool changed = false;
  for (int j = 0; j < static_cast<int>(g->nodes.size()); ++j) {
    Node& jn = g->nodes[j];
    if (!jn.alive || !jn.junction) continue;
    if (jn.ends.empty()) {
      g->dots.push_back(jn.px.front());
      jn.alive = false;
      changed = true;
    } else if (jn.ends.size() == 1) {
      jn.junction = false;
      changed = true;
    } else if (jn.ends.size() == 2 && jn.ends[0] / 2 != jn.ends[1] / 2) {
      JoinThrough(j, jn.ends[0], jn.ends[1], {}, g);
      changed = true;
    } else if (jn.ends.size() == 3) {
      int spur = -1;  // the shortest branch out to a free end
      for (int e : jn.ends) {
        const Branch& b = g->branches[e / 2];
        if (g->nodes[b.node[1 - e % 2]].junction || PathLength(b.px) >= cusp_len) continue;
        if (spur < 0 || PathLength(b.px) < PathLength(g->branches[spur / 2].px)) spur = e;
      }
      if (spur < 0) continue;
      std::vector<int> legs;
      for (int e : jn.ends) if (e != spur) legs.push_back(e);
      if (legs[0] / 2 == legs[1] / 2) continue;  // a loop with a tail: the thread touches itself
      const Eigen::Vector2d da = DirectionFrom(*g, legs[0], probe);
      const Eigen::Vector2d db = DirectionFrom(*g, legs[1], probe);
      const Eigen::Vector2d ds = DirectionFrom(*g, spur, probe);
      if (Angle(da, db) > kPi / 3 || Angle(ds, -(da + db)) > kPi / 4) continue;
      std::vector<cv::Point> tip = FromNode(*g, spur), back(tip.rbegin() + 1, tip.rend());
      tip.insert(tip.end(), back.begin(), back.end());
      g->branches[spur / 2].alive = false;
      g->nodes[g->branches[spur / 2].node[1 - spur % 2]].alive = false;
      JoinThrough(j, legs[0], legs[1], tip, g);
      changed = true;
    }
  }
  return changed;
}

// Simplifies the skeleton of a thread of half-width hw until nothing changes: prunes spurs
// shorter than spur_len (thinning artefacts at the caps and on bumps), contracts junctions
// joined by branches shorter than 8 hw + 6 (a crossing thins to two forks up to about
// 2 hw / tan(angle / 2) apart), dissolves junctions left with one or two branches, and turns a
// sharp bend (a cusp: two branches leaving in a V, a spur along its bisector out to the tip)
// into one path out to the tip and back.
void Simplify(double hw, double spur_len, Graph* g) {
  const double merge_len = 8 * hw + 6, cusp_len = 6 * hw + 6, probe = 2 * hw + 4;
  for (int pass = 0; pass < 1000; ++pass) {
    // Each phase on the graph the one before left, as one pass did.
    bool changed = PruneSpurs(spur_len, probe, g);
    changed |= MergeJunctions(merge_len, g);
    changed |= DissolveJunctions(cusp_len, probe, g);
    if (!changed) return;
  }
}

// ---------------------------------------------------------------------------------------------
// Pieces, crossings and linking

struct End {
  Vec2 pos = Vec2::Zero();
  Vec2 dir = Vec2::Zero();  // unit, pointing out of the piece; zero when too short to tell
  int junction = -1;        // node id, or -1 for a free end
  bool border = false;      // free end at the image's (or region's) border: the thread leaves
};
struct Piece {
  std::vector<Vec2> pts;
  End end[2];
};

// Total turn of a path leaving end a and entering the piece of end b (both outward).
double Turn(const End& a, const End& b) {
  if (a.dir.isZero() || b.dir.isZero()) return kPi / 2;
  const Vec2 chord = b.pos - a.pos;
  if (chord.norm() < 2.0) return Angle(a.dir, -b.dir);
  return Angle(a.dir, chord) + Angle(chord, -b.dir);
}

void SetEndDirections(double half_width, Piece* piece) {
  const int n = static_cast<int>(piece->pts.size());
  const int m = std::min(n - 1, std::max(3, static_cast<int>(std::lround(2 * half_width))));
  const Vec2 d0 = piece->pts.front() - piece->pts[m];
  const Vec2 d1 = piece->pts.back() - piece->pts[n - 1 - m];
  piece->end[0].pos = piece->pts.front();
  piece->end[1].pos = piece->pts.back();
  piece->end[0].dir = d0.norm() > 1.5 ? Vec2(d0.normalized()) : Vec2::Zero();
  piece->end[1].dir = d1.norm() > 1.5 ? Vec2(d1.normalized()) : Vec2::Zero();
}

// A pairing of the branch ends at a junction (indices into its list of ends).
struct Matching {
  std::vector<std::pair<int, int>> pairs;
  double total_turn = 0, worst_turn = 0;  // [rad]
};

// Every perfect matching of the ends listed in `open`, with its summed and worst turn.
void Matchings(const std::vector<const End*>& ends, std::vector<int>* open,
               std::vector<std::pair<int, int>>* pairs, double sum, double worst,
               std::vector<Matching>* out) {
  if (open->empty()) {
    out->push_back({*pairs, sum, worst});
    return;
  }
  const int a = open->front();
  for (size_t i = 1; i < open->size(); ++i) {
    const int b = (*open)[i];
    const double t = Turn(*ends[a], *ends[b]);
    std::vector<int> rest;
    for (size_t k = 1; k < open->size(); ++k) if (k != i) rest.push_back((*open)[k]);
    pairs->emplace_back(a, b);
    Matchings(ends, &rest, pairs, sum + t, std::max(worst, t), out);
    pairs->pop_back();
  }
}

// ---------------------------------------------------------------------------------------------
// Sub-pixel refinement

// Foreground weight in [0, 1]: intensity contrast against the background, or the mask.
// A sample is inside when every pixel its bilinear interpolation reads is in the image and in
// the region: the region's boundary cuts a cross-section as the image border does.
struct Weights {
  cv::Mat1b src;
  const Region* region = nullptr;
  double zero = 0, one = 255;  // grey levels of weight 0 and 1
  bool Inside(const Eigen::Vector2d& q) const {
    if (!(q.x() >= 0 && q.y() >= 0 && q.x() <= src.cols - 1 && q.y() <= src.rows - 1))
      return false;
    if (region == nullptr || region->allowed.empty()) return true;
    const int x0 = static_cast<int>(q.x()), y0 = static_cast<int>(q.y());
    const int x1 = static_cast<int>(std::ceil(q.x())), y1 = static_cast<int>(std::ceil(q.y()));
    return region->Allows(x0, y0) && region->Allows(x1, y0) && region->Allows(x0, y1) &&
           region->Allows(x1, y1);
  }
  double At(double x, double y) const {
    x = std::clamp(x, 0.0, src.cols - 1.0);
    y = std::clamp(y, 0.0, src.rows - 1.0);
    const int x0 = std::min(static_cast<int>(x), src.cols - 2 < 0 ? 0 : src.cols - 2);
    const int y0 = std::min(static_cast<int>(y), src.rows - 2 < 0 ? 0 : src.rows - 2);
    const int x1 = std::min(x0 + 1, src.cols - 1), y1 = std::min(y0 + 1, src.rows - 1);
    const double fx = x - x0, fy = y - y0;
    const double v = (1 - fy) * ((1 - fx) * src(y0, x0) + fx * src(y0, x1)) +
                     fy * ((1 - fx) * src(y1, x0) + fx * src(y1, x1));
    return std::clamp((v - zero) / (one - zero), 0.0, 1.0);
  }
};

std::vector<Vec2> Tangents(const std::vector<Vec2>& p) {
  const int n = static_cast<int>(p.size()), k = 3;
  std::vector<Vec2> t(n);
  for (int i = 0; i < n; ++i) {
    Vec2 d = p[std::min(n - 1, i + k)] - p[std::max(0, i - k)];
    if (d.norm() < 1.0) d = p[std::min(n - 1, i + 1)] - p[std::max(0, i - 1)];
    t[i] = d.norm() >= 0.5 ? Vec2(d.normalized()) : Vec2::Zero();  // zero: turns back here
  }
  return t;
}

// Moves each point to the weight centroid of the contiguous run across its normal and measures
// the run's width at weight 0.5 (the local half-width). Returns which points to keep: a point
// whose run is cut by the image border (or the region's), is lopsided or much wider than the
// median run (it runs into another strand at a crossing, where the thread touches itself or in
// a cusp), or where the path turns back on itself (a cusp's tip) has no trustworthy centroid.
std::vector<char> Refine(const Weights& w, double reach, std::vector<Vec2>* pts,
                         std::vector<double>* half) {
  constexpr double kStep = 0.25, kFloor = 0.1;
  const int m = static_cast<int>(std::ceil(reach / kStep));
  std::vector<double> prof(2 * m + 1), run(pts->size(), 0.0);
  std::vector<char> keep(pts->size(), 1), skewed(pts->size(), 0);
  half->assign(pts->size(), 0.0);
  for (int pass = 0; pass < 2; ++pass) {
    const std::vector<Vec2> tangent = Tangents(*pts);
    for (size_t i = 0; i < pts->size(); ++i) {
      if (tangent[i].isZero()) {
        keep[i] = 0;
        continue;
      }
      const Vec2 nrm(-tangent[i].y(), tangent[i].x());
      const Vec2 p = (*pts)[i];
      for (int k = -m; k <= m; ++k) {
        const Vec2 q = p + (k * kStep) * nrm;
        prof[k + m] = w.Inside(q) ? w.At(q.x(), q.y()) : -1.0;
      }
      if (prof[m] <= kFloor) continue;
      int lo = m, hi = m;
      while (lo > 0 && prof[lo - 1] > kFloor) --lo;
      while (hi < 2 * m && prof[hi + 1] > kFloor) ++hi;
      if ((lo > 0 && prof[lo - 1] < 0) || (hi < 2 * m && prof[hi + 1] < 0)) {
        keep[i] = 0;
        continue;
      }
      keep[i] = 1;
      skewed[i] = 0;
      run[i] = (hi - lo + 1) * kStep;
      double sw = 0, swt = 0;
      for (int k = lo; k <= hi; ++k) { sw += prof[k]; swt += prof[k] * (k - m) * kStep; }
      (*pts)[i] = p + (swt / sw) * nrm;
      int a = lo, b = hi;
      while (a <= hi && prof[a] < 0.5) ++a;
      while (b >= lo && prof[b] < 0.5) --b;
      if (a > b) continue;
      // Linear interpolation of the 0.5 crossings on both flanks.
      const double left = a > 0 && prof[a - 1] < 0.5
                              ? a - (prof[a] - 0.5) / (prof[a] - prof[a - 1]) : a - 0.5;
      const double right = b < 2 * m && prof[b + 1] < 0.5
                               ? b + (prof[b] - 0.5) / (prof[b] - prof[b + 1]) : b + 0.5;
      (*half)[i] = 0.5 * (right - left) * kStep;
      // A clean cross-section is symmetric: its centroid is midway between the half-height
      // crossings. A faint second strand at the edge of the run pulls the centroid only.
      skewed[i] = std::abs(swt / sw - (0.5 * (left + right) - m) * kStep) > 0.4;
    }
  }
  for (size_t i = 0; i < skewed.size(); ++i) if (skewed[i]) keep[i] = 0;
  // Much wider than usual at the floor or at half height: another strand is in the run.
  constexpr double kNone = std::numeric_limits<double>::infinity();
  const double run_limit = 1.5 * MedianPositive(run, kNone) + 2.0;
  const double half_limit = 1.4 * MedianPositive(*half, kNone) + 0.3;
  for (size_t i = 0; i < run.size(); ++i)
    if (run[i] > run_limit || (*half)[i] > half_limit) keep[i] = 0;
  return keep;
}

// Ends the polyline (`back` = at its last point) at the centre of the thread's cap. Thinning
// leaves the skeleton's end anywhere inside the cap, so: fit a parabola in arc length to the
// points a little before the cap (2 hw + 1 to 2 hw + 1 + max(6, 3 hw) px from the end), where
// the cross-section is whole; march along it to where the weight falls to 0.5 and step back by
// the half-width there (the cap's centre), or stop at the image's (or region's) border; drop the
// points beyond that, or extend the last point out to it.
void FitEnd(const Weights& w, double hw, bool back, std::vector<Vec2>* pts,
            std::vector<double>* half) {
  const int n = static_cast<int>(pts->size());
  if (n < 3) return;
  auto at = [&](int i) { return back ? n - 1 - i : i; };  // i-th point from the end
  const double near = 2 * hw + 1, far = near + std::max(6.0, 3 * hw);
  std::vector<int> window;
  std::vector<double> arc, hs;  // arc length from the end; half-widths in the window
  double dist = 0;
  for (int i = 1; i < n && dist < far; ++i) {
    dist += ((*pts)[at(i)] - (*pts)[at(i - 1)]).norm();
    if (dist < near) continue;
    window.push_back(i);
    arc.push_back(dist);
    hs.push_back((*half)[at(i)]);
  }
  if (window.size() < 3) return;
  // x(s), y(s) = a0 + a1 s + a2 s^2 with s the arc length towards the end from the first point.
  Eigen::MatrixXd basis(window.size(), 3);
  Eigen::MatrixXd xy(window.size(), 2);
  for (size_t k = 0; k < window.size(); ++k) {
    const double sk = arc[0] - arc[k];
    basis.row(k) << 1.0, sk, sk * sk;
    xy.row(k) = (*pts)[at(window[k])].transpose();
  }
  const Eigen::MatrixXd coef = basis.colPivHouseholderQr().solve(xy);
  auto curve = [&](double t) -> Vec2 {
    return (coef.row(0) + t * coef.row(1) + t * t * coef.row(2)).transpose();
  };
  const Vec2 q = curve(0.0);
  const int i_near = window.front();
  if (coef.row(1).norm() < 0.5) return;
  const double h = MedianPositive(hs, hw);
  constexpr double kStep = 0.25;
  const double reach = near + 3 * hw + 10;
  double prev_w = w.At(q.x(), q.y()), s_end = -1;
  for (double t = kStep; t <= reach; t += kStep) {
    const Vec2 r = curve(t);
    if (!w.Inside(r)) {
      s_end = t - kStep;  // the thread leaves the image
      break;
    }
    const double cur = w.At(r.x(), r.y());
    if (cur < 0.5) {
      const double edge = prev_w > cur ? t - kStep * (0.5 - cur) / (prev_w - cur) : t;
      s_end = std::max(0.0, edge - h);
      break;
    }
    prev_w = cur;
  }
  if (s_end < 0) return;  // no cap found: leave the end as it is
  // Refined points are on the mid-line even inside the cap; only how far they go is wrong.
  const Vec2 centre = curve(s_end);
  const Vec2 along = (coef.row(1) + 2 * s_end * coef.row(2)).transpose().normalized();
  int cut = 0;  // points beyond the cap's centre
  while (cut < i_near && ((*pts)[at(cut)] - centre).dot(along) > 0.25) ++cut;
  const Vec2 last = (*pts)[at(cut)];
  const double short_by = (centre - last).dot(along);
  if (back) {
    pts->resize(n - cut);
    half->resize(n - cut);
    if (short_by > 0.5) {
      pts->push_back(last + short_by * along);
      half->push_back(h);
    }
  } else {
    pts->erase(pts->begin(), pts->begin() + cut);
    half->erase(half->begin(), half->begin() + cut);
    if (short_by > 0.5) {
      pts->insert(pts->begin(), last + short_by * along);
      half->insert(half->begin(), h);
    }
  }
}

void Resample(double spacing, std::vector<Vec2>* pts, std::vector<double>* half) {
  const size_t n = pts->size();
  if (n < 2 || spacing <= 0) return;
  std::vector<double> s(n, 0.0);
  for (size_t i = 1; i < n; ++i) s[i] = s[i - 1] + ((*pts)[i] - (*pts)[i - 1]).norm();
  const int count = std::max(1, static_cast<int>(std::lround(s.back() / spacing)));
  std::vector<Vec2> out;
  std::vector<double> out_half;
  size_t j = 0;
  for (int k = 0; k <= count; ++k) {
    const double sk = s.back() * k / count;
    while (j + 2 < n && s[j + 1] < sk) ++j;
    const double len = s[j + 1] - s[j];
    const double f = len > 0 ? std::clamp((sk - s[j]) / len, 0.0, 1.0) : 0.0;
    out.push_back((1 - f) * (*pts)[j] + f * (*pts)[j + 1]);
    out_half.push_back((1 - f) * (*half)[j] + f * (*half)[j + 1]);
  }
  *pts = std::move(out);
  *half = std::move(out_half);
}

// ---------------------------------------------------------------------------------------------
// The stages of ExtractCentreline

// Segmentation with its sanity checks and clean-up; throws when nothing usable is left.
Segmented SegmentThread(const cv::Mat& image, const Region& region, const CentrelineOptions& o) {
  Segmented seg = Segment(image, region, o);
  const double fraction = cv::countNonZero(seg.mask) / static_cast<double>(region.area);
  if (fraction > o.max_foreground_fraction) {
    Fail(o, "segmentation covers " + std::to_string(std::lround(100 * fraction)) + "% of the " +
                (region.allowed.empty() ? "image" : "region (roi, mask)") +
                ", not a thread (wrong mode or threshold?)");
  }
  CleanMask(o, region, &seg.mask);
  if (cv::countNonZero(seg.mask) == 0) {
    Fail(o, "nothing segmented (threshold " + std::to_string(std::lround(seg.threshold)) +
                ", min_component_area " + std::to_string(o.min_component_area) + " px)");
  }
  return seg;
}

// Every live branch as a piece in image coordinates, trimmed by hw + 1.5 px where it enters a
// junction (the skeleton bends towards the junction there); components thinned to a dot are
// pieces of one point.
std::vector<Piece> MakePieces(const Graph& graph, double hw, const Region& region) {
  const Vec2 one(1, 1);  // the padding
  auto border_dist = [&](const Vec2& p) { return region.BorderDistance(p); };
  std::vector<Piece> pieces;
  for (const Branch& b : graph.branches) {
    if (!b.alive) continue;
    std::vector<Vec2> pts;
    for (const cv::Point& q : b.px)
      if (pts.empty() || pts.back() != Vec2(q.x, q.y) - one) pts.push_back(Vec2(q.x, q.y) - one);
    for (int side = 0; side < 2; ++side) {
      const Node& node = graph.nodes[b.node[side]];
      if (!node.junction) continue;
      if (side == 1) std::reverse(pts.begin(), pts.end());
      auto in_node = [&](const Vec2& p) {
        for (const cv::Point& q : node.px) if (Vec2(q.x, q.y) - one == p) return true;
        return false;
      };
      size_t cut = 0;
      Vec2 exit = pts.front();
      while (cut < pts.size() && in_node(pts[cut])) exit = pts[cut++];
      while (cut + 1 < pts.size() && (pts[cut] - exit).norm() < hw + 1.5) ++cut;
      pts.erase(pts.begin(), pts.begin() + std::min(cut, pts.size() - 1));
      if (side == 1) std::reverse(pts.begin(), pts.end());
    }
    Piece piece;
    piece.pts = std::move(pts);
    SetEndDirections(hw, &piece);
    for (int side = 0; side < 2; ++side) {
      const Node& node = graph.nodes[b.node[side]];
      piece.end[side].junction = node.junction ? b.node[side] : -1;
      piece.end[side].border = !node.junction && border_dist(piece.end[side].pos) <= hw + 2;
    }
    pieces.push_back(std::move(piece));
  }
  for (const cv::Point& q : graph.dots) {
    Piece piece;
    piece.pts = {Vec2(q.x, q.y) - one};
    piece.end[0].pos = piece.end[1].pos = piece.pts[0];
    pieces.push_back(std::move(piece));
  }
  return pieces;
}

// At every junction pairs the piece ends so that the thread continues straightest; returns the
// partner of each piece end (2 * piece + side), -1 for free ends. Throws when a junction has an
// odd number of branches or no clearly straightest pairing.
std::vector<int> PairAtJunctions(const Graph& graph, const std::vector<Piece>& pieces,
                                 const CentrelineOptions& o, int* crossings) {
  const int np = static_cast<int>(pieces.size());
  std::vector<int> partner(2 * np, -1);
  std::vector<std::vector<int>> at_junction(graph.nodes.size());
  for (int p = 0; p < np; ++p)
    for (int s = 0; s < 2; ++s)
      if (pieces[p].end[s].junction >= 0) at_junction[pieces[p].end[s].junction].push_back(2 * p + s);
  for (size_t j = 0; j < at_junction.size(); ++j) {
    const std::vector<int>& ids = at_junction[j];
    if (ids.empty()) continue;
    Vec2 centre = Vec2::Zero();
    for (const cv::Point& q : graph.nodes[j].px) centre += Vec2(q.x - 1, q.y - 1);
    centre /= graph.nodes[j].px.size();
    const std::string count = std::to_string(ids.size());
    if (ids.size() % 2 == 1 || ids.size() > 8) {
      Fail(o, "the skeleton branches at " + At(centre) + " (" + count +
                  " branches meet; does the thread touch itself?)");
    }
    if (ids.size() > 2 && !o.resolve_crossings) {
      Fail(o, "the thread crosses itself at " + At(centre) + " (resolve_crossings is off)");
    }
    std::vector<const End*> ends;
    std::vector<int> open;
    for (int id : ids) {
      open.push_back(static_cast<int>(ends.size()));
      ends.push_back(&pieces[id / 2].end[id % 2]);
    }
    std::vector<std::pair<int, int>> pairs;
    std::vector<Matching> all;
    Matchings(ends, &open, &pairs, 0, 0, &all);
    std::sort(all.begin(), all.end(),
              [](const Matching& a, const Matching& b) { return a.total_turn < b.total_turn; });
    if (ids.size() > 2) {
      const bool straight = all[0].worst_turn <= o.max_crossing_turn_deg * kDeg;
      const bool clear = all[1].total_turn - all[0].total_turn >= o.min_crossing_margin_deg * kDeg;
      if (!straight || !clear) {
        Fail(o, "ambiguous crossing at " + At(centre) + " (" + count +
                    " branches, no clearly straightest continuation; the thread touches itself?)");
      }
      *crossings += static_cast<int>(ids.size()) / 2 - 1;
    }
    for (const auto& [a, b] : all[0].pairs) {
      partner[ids[a]] = ids[b];
      partner[ids[b]] = ids[a];
    }
  }
  return partner;
}

// Pieces joined through junctions, from one free end to the other.
struct Chain {
  std::vector<std::pair<int, bool>> pieces;  // piece, reversed
  End end[2];                                // outward at the first and the last point
};

// Walks from every free end through the junction pairings. Pieces never reached form closed
// loops: an error, or counted in *dropped.
std::vector<Chain> MakeChains(const std::vector<Piece>& pieces, const std::vector<int>& partner,
                              const CentrelineOptions& o, int* dropped) {
  const int np = static_cast<int>(pieces.size());
  std::vector<Chain> chains;
  std::vector<char> used(np, 0);
  for (int p0 = 0; p0 < np; ++p0) {
    for (int s0 = 0; s0 < 2; ++s0) {
      if (used[p0] || pieces[p0].end[s0].junction >= 0) continue;
      Chain c;
      c.end[0] = pieces[p0].end[s0];
      int p = p0, s = s0;
      for (int guard = 0; guard <= np; ++guard) {
        used[p] = 1;
        c.pieces.emplace_back(p, s == 1);
        const int exit = 2 * p + (1 - s);
        c.end[1] = pieces[p].end[1 - s];
        if (partner[exit] < 0 || used[partner[exit] / 2]) break;
        p = partner[exit] / 2;
        s = partner[exit] % 2;
      }
      chains.push_back(std::move(c));
    }
  }
  for (int p = 0; p < np; ++p) {
    if (used[p]) continue;
    if (o.require_all_pieces) {
      Fail(o, "the thread closes into a loop through a crossing near " + At(pieces[p].end[0].pos) +
                  " (no visible ends)");
    }
    ++*dropped;
  }
  return chains;
}

// Picks the start end (nearest the hint, else nearest the border), then links chains end to
// end across gaps: from the current last end, the nearest free end within max_gap whose gap
// both ends turn into by at most max_link_turn_deg; never across an end on the image border or
// the region's (the thread leaves the view there).
// Returns the ordered points.
std::vector<Vec2> LinkChains(const std::vector<Chain>& chains, const std::vector<Piece>& pieces,
                             const Region& region, const CentrelineOptions& o,
                             CentrelineResult* result) {
  auto border_dist = [&](const Vec2& p) { return region.BorderDistance(p); };
  const int nc = static_cast<int>(chains.size());
  int start_chain = 0, start_side = 0;
  double best = std::numeric_limits<double>::infinity();
  for (int c = 0; c < nc; ++c) {
    for (int s = 0; s < 2; ++s) {
      const Vec2& p = chains[c].end[s].pos;
      const double score = o.start_hint ? (p - *o.start_hint).norm() : border_dist(p);
      const Vec2& q = chains[start_chain].end[start_side].pos;
      if (score < best - 1e-9 ||
          (score < best + 1e-9 && (p.x() < q.x() || (p.x() == q.x() && p.y() < q.y())))) {
        best = score;
        start_chain = c;
        start_side = s;
      }
    }
  }
  if (o.start_hint && o.max_start_distance > 0 && best > o.max_start_distance) {
    Fail(o, "no thread end within " + std::to_string(std::lround(o.max_start_distance)) +
                " px of the start hint " + At(*o.start_hint) + " (nearest " +
                std::to_string(std::lround(best)) + " px away)");
  }
  result->start_choice = o.start_hint ? StartChoice::kNearestHint : StartChoice::kNearestBorder;
  std::vector<std::pair<int, bool>> order{{start_chain, start_side == 1}};
  std::vector<char> linked(nc, 0);
  linked[start_chain] = 1;
  End tail = chains[start_chain].end[1 - start_side];
  for (int guard = 0; guard < nc; ++guard) {
    int best_c = -1, best_s = 0;
    double best_cost = std::numeric_limits<double>::infinity();
    for (int c = 0; c < nc; ++c) {
      for (int s = 0; s < 2 && !linked[c]; ++s) {
        const End& e = chains[c].end[s];
        const Vec2 gap = e.pos - tail.pos;
        const double d = gap.norm();
        if (d > o.max_gap || tail.border || e.border) continue;
        double cost = d;
        if (d >= 2.0 && !tail.dir.isZero() && !e.dir.isZero()) {
          const double ta = Angle(tail.dir, gap), tb = Angle(gap, -e.dir);
          if (ta > o.max_link_turn_deg * kDeg || tb > o.max_link_turn_deg * kDeg) continue;
          cost = d * (1.0 + (ta + tb) / kPi);
        }
        if (cost < best_cost) { best_cost = cost; best_c = c; best_s = s; }
      }
    }
    if (best_c < 0) break;
    linked[best_c] = 1;
    order.emplace_back(best_c, best_s == 1);
    tail = chains[best_c].end[1 - best_s];
    ++result->num_gaps_bridged;
  }
  for (int c = 0; c < nc; ++c) {
    if (linked[c]) continue;
    if (o.require_all_pieces) {
      Fail(o, std::to_string(nc) + " disjoint pieces; the one ending at " + At(chains[c].end[0].pos) +
                  " cannot be linked within max_gap = " + std::to_string(std::lround(o.max_gap)) +
                  " px (last linked end at " + At(tail.pos) + ")");
    }
    result->num_pieces_dropped += static_cast<int>(chains[c].pieces.size());
  }

  std::vector<Vec2> pts;
  for (const auto& [c, chain_rev] : order) {
    std::vector<std::pair<int, bool>> seq = chains[c].pieces;
    if (chain_rev) {
      std::reverse(seq.begin(), seq.end());
      for (auto& s : seq) s.second = !s.second;
    }
    for (const auto& [p, rev] : seq) {
      const std::vector<Vec2>& src = pieces[p].pts;
      if (rev) pts.insert(pts.end(), src.rbegin(), src.rend());
      else pts.insert(pts.end(), src.begin(), src.end());
      ++result->num_pieces;
    }
  }
  return pts;
}

// Weights for the sub-pixel stage: grey contrast between the background's median and the
// skeleton's median, or the mask in colour mode or without usable contrast.
Weights MakeWeights(const Segmented& seg, const cv::Mat1b& skel, const Region& region,
                    const CentrelineOptions& o) {
  Weights weights;
  weights.region = &region;
  if (!seg.grey.empty()) {
    const cv::Mat1b on_skeleton = skel(cv::Rect(1, 1, seg.grey.cols, seg.grey.rows));
    cv::Mat1b background = seg.mask == 0;
    if (!region.allowed.empty()) background &= region.allowed;
    const double bg = MedianGrey(seg.grey, background, nullptr);
    const double fg = MedianGrey(seg.grey, on_skeleton, nullptr);
    if (std::abs(bg - fg) >= 0.5 * o.min_contrast) {
      weights.src = seg.grey;
      weights.zero = bg;
      weights.one = fg;
    }
  }
  if (weights.src.empty()) weights.src = seg.mask;
  return weights;
}

}  // namespace

bool CentrelineOptions::Check(std::string* why) const {
  std::ostringstream msg;
  if (threshold > 255) msg << "threshold " << threshold << " must be <= 255";
  else if (min_component_area < 1) msg << "min_component_area must be >= 1";
  else if (closing_radius < 0 || closing_radius > 50) msg << "closing_radius must be in [0, 50]";
  else if (!(max_gap >= 0)) msg << "max_gap must be >= 0";
  else if (!(pre_blur_sigma >= 0)) msg << "pre_blur_sigma must be >= 0";
  else if (!(max_foreground_fraction > 0 && max_foreground_fraction <= 1))
    msg << "max_foreground_fraction must be in (0, 1]";
  else if (!(resample_spacing >= 0)) msg << "resample_spacing must be >= 0";
  else if (!(max_start_distance >= 0)) msg << "max_start_distance must be >= 0";
  else if (start_hint && !start_hint->allFinite()) msg << "start_hint must be finite";
  else return true;
  if (why) *why = msg.str();
  return false;
}

std::string CentrelineResult::BriefReport() const {
  double len = 0;
  for (size_t i = 1; i < uv.size(); ++i) len += (uv[i] - uv[i - 1]).norm();
  std::ostringstream out;
  out << "centre-line: " << uv.size() << " points, length " << std::lround(len) << " px, start "
      << At(start) << " (nearest the " << (start_choice == StartChoice::kNearestHint ? "hint" : "border")
      << "), end " << At(end) << ", " << num_pieces << " piece(s), " << num_gaps_bridged
      << " gap(s) bridged, " << num_crossings_resolved << " crossing(s) resolved, "
      << num_pieces_dropped << " dropped, half-width "
      << std::lround(100 * mean_half_width_px) / 100.0 << " px";
  return out.str();
}

CentrelineResult ExtractCentreline(const cv::Mat& image, const CentrelineOptions& o) {
  std::string why;
  if (!o.Check(&why)) throw std::invalid_argument("CentrelineOptions: " + why);
  if (image.empty()) Fail(o, "the image is empty");
  if ((image.depth() != CV_8U && image.depth() != CV_16U) ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4))
    Fail(o, "unsupported image type (need 8- or 16-bit, 1, 3 or 4 channels)");

  const Region region = MakeRegion(image, o);
  CentrelineResult result;
  const Segmented seg = SegmentThread(image, region, o);
  result.threshold = seg.threshold;
  result.mask = seg.mask;

  cv::Mat1b skel;
  cv::copyMakeBorder(seg.mask, skel, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
  skel = skel / 255;
  ThinGuoHall(&skel);
  Graph graph = BuildGraph(skel);
  const double area = cv::countNonZero(seg.mask);
  const double hw = std::max(0.5, area / std::max(1.0, graph.length + graph.dots.size()) / 2);
  result.mean_half_width_px = hw;
  Simplify(hw, std::max(o.min_spur_length, 2 * hw + 2), &graph);
  if (!graph.cycles.empty() && o.require_all_pieces) {
    const cv::Point q = graph.cycles[0][0];
    Fail(o, "the skeleton is a closed loop near " + At(Vec2(q.x - 1, q.y - 1)) +
                " with no visible ends");
  }
  result.num_pieces_dropped = static_cast<int>(graph.cycles.size());

  const std::vector<Piece> pieces = MakePieces(graph, hw, region);
  const std::vector<int> partner =
      PairAtJunctions(graph, pieces, o, &result.num_crossings_resolved);
  const std::vector<Chain> chains = MakeChains(pieces, partner, o, &result.num_pieces_dropped);
  if (chains.empty()) Fail(o, "the thread has no visible ends (only closed loops)");
  std::vector<Vec2> pts = LinkChains(chains, pieces, region, o, &result);

  const Weights weights = MakeWeights(seg, skel, region, o);
  std::vector<double> half(pts.size(), 0.0);
  if (o.subpixel) {
    const std::vector<char> keep = Refine(weights, std::min(40.0, 3 * hw + 3), &pts, &half);
    if (std::count(keep.begin(), keep.end(), 1) >= 2) {
      size_t k = 0;
      for (size_t i = 0; i < pts.size(); ++i) {
        if (!keep[i]) continue;
        pts[k] = pts[i];
        half[k++] = half[i];
      }
      pts.resize(k);
      half.resize(k);
    }
  }
  if (o.fit_ends) {
    // The half-width at weight 0.5 where measured (the mask's is wider for faint, blurred
    // threads) tells the cap from the whole cross-section.
    const double h_profile = MedianPositive(half, hw);
    FitEnd(weights, h_profile, false, &pts, &half);
    FitEnd(weights, h_profile, true, &pts, &half);
  }
  Resample(o.resample_spacing, &pts, &half);
  result.uv = std::move(pts);
  result.half_width_px = std::move(half);
  result.start = result.uv.front();
  result.end = result.uv.back();
  return result;
}

cv::Mat DrawOverlay(const cv::Mat& image, const std::vector<Eigen::Vector2d>& uv,
                    const std::vector<Eigen::Vector2d>& second, const OverlayOptions& options) {
  cv::Mat3b out = ToBgr(image);
  constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
  auto draw = [&](const std::vector<Eigen::Vector2d>& line, const cv::Scalar& colour) {
    if (line.empty()) return;
    std::vector<cv::Point> px;
    for (const Eigen::Vector2d& p : line) {
      px.emplace_back(static_cast<int>(std::lround(p.x() * (1 << kShift))),
                      static_cast<int>(std::lround(p.y() * (1 << kShift))));
    }
    cv::polylines(out, px, false, colour, options.thickness, cv::LINE_AA, kShift);
    if (options.mark_points)
      for (const cv::Point& q : px) cv::circle(out, q, 1 << kShift, colour, cv::FILLED, cv::LINE_AA, kShift);
    if (options.mark_start)
      cv::circle(out, px.front(), (4 + options.thickness) << kShift, colour, options.thickness,
                 cv::LINE_AA, kShift);
  };
  draw(second, options.second_colour);
  draw(uv, options.colour);
  return out;
}

}  // namespace rodfit
