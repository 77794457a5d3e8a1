// Point triangulation (DLT + Gauss–Newton) and epipolar matching of two centre-line polylines;
// see triangulate.h for the method.
#include "rodfit/observe/triangulate.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace rodfit {
namespace {

void CheckViews(const std::vector<PixelView>& views) {
  for (const PixelView& v : views) {
    if (v.camera == nullptr) {
      throw std::invalid_argument("Triangulate: PixelView::camera == nullptr");
    }
  }
}

// Sum of squared pixel residuals; false if the point is behind any camera.
bool ReprojectionCost(const std::vector<PixelView>& views, const Eigen::Vector3d& p,
                      double* cost, double* max_error) {
  *cost = 0.0;
  *max_error = 0.0;
  for (const PixelView& v : views) {
    Eigen::Vector2d uv;
    if (!Project(*v.camera, p, &uv)) return false;
    const double e2 = (uv - v.uv).squaredNorm();
    *cost += e2;
    *max_error = std::max(*max_error, std::sqrt(e2));
  }
  return std::isfinite(*cost);
}

Eigen::Vector2d PixelFromNormalized(const CameraIntrinsics& K, const Eigen::Vector2d& xy) {
  double xd, yd;
  DistortNormalized(K, xy.x(), xy.y(), &xd, &yd);
  return Eigen::Vector2d(K.fx * xd + K.cx, K.fy * yd + K.cy);
}

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

struct Candidate {
  int index_a;
  double position_b;
  Eigen::Vector2d uv_b;
  TriangulatedPoint point;
};

// Longest chain of candidates (sorted by index_a) with at most one per index_a and
// direction * position_b non-decreasing; ties go to the smallest sum of squared 3-D steps.
std::vector<int> LongestMonotoneChain(const std::vector<Candidate>& c, double direction,
                                      double* cost_out) {
  const int m = static_cast<int>(c.size());
  std::vector<int> length(m, 1), previous(m, -1);
  std::vector<double> cost(m, 0.0);
  int best = -1;
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < i; ++j) {
      if (c[j].index_a >= c[i].index_a) continue;
      if (direction * (c[i].position_b - c[j].position_b) < 0.0) continue;
      const double step = (c[i].point.p_world - c[j].point.p_world).squaredNorm();
      const int len = length[j] + 1;
      const double cst = cost[j] + step;
      if (len > length[i] || (len == length[i] && cst < cost[i])) {
        length[i] = len;
        cost[i] = cst;
        previous[i] = j;
      }
    }
    if (best < 0 || length[i] > length[best] ||
        (length[i] == length[best] && cost[i] < cost[best])) {
      best = i;
    }
  }
  std::vector<int> chain;
  for (int i = best; i >= 0; i = previous[i]) chain.push_back(i);
  std::reverse(chain.begin(), chain.end());
  *cost_out = best >= 0 ? cost[best] : 0.0;
  return chain;
}

}  // namespace

bool TriangulateLinear(const std::vector<PixelView>& views, Eigen::Vector3d* p_world) {
  CheckViews(views);
  if (views.size() < 2) return false;
  // Rows x P3 - P1 and y P3 - P2 with P = [R | t] acting on undistorted normalised
  // coordinates, where all entries are O(1) and no Hartley normalisation is needed.
  Eigen::MatrixXd A(2 * views.size(), 4);
  for (size_t i = 0; i < views.size(); ++i) {
    const Camera& cam = *views[i].camera;
    Eigen::Vector2d xy;
    if (!UndistortPixel(cam.K, views[i].uv, &xy)) return false;
    Eigen::Matrix<double, 3, 4> P;
    P << cam.cam_from_world_R, cam.cam_from_world_t;
    A.row(2 * i) = xy.x() * P.row(2) - P.row(0);
    A.row(2 * i + 1) = xy.y() * P.row(2) - P.row(1);
  }
  if (!A.allFinite()) return false;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Eigen::Vector4d X = svd.matrixV().col(3);
  // A (numerically) vanishing w means parallel rays: the point is at infinity.
  if (!(std::abs(X(3)) > 1e-12 * X.head<3>().norm())) return false;
  *p_world = X.head<3>() / X(3);
  return p_world->allFinite();
}

TriangulatedPoint Triangulate(const std::vector<PixelView>& views,
                              const TriangulationOptions& options) {
  TriangulatedPoint out;
  Eigen::Vector3d p;
  if (!TriangulateLinear(views, &p)) return out;
  double cost, max_error;
  if (!ReprojectionCost(views, p, &cost, &max_error)) return out;
  for (int it = 0; it < options.max_iterations; ++it) {
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Jtr = Eigen::Vector3d::Zero();
    for (const PixelView& v : views) {
      Eigen::Vector2d uv;
      Mat23 J;
      Project(*v.camera, p, &uv, &J);  // cannot fail: ReprojectionCost succeeded at p
      JtJ += J.transpose() * J;
      Jtr += J.transpose() * (uv - v.uv);
    }
    const Eigen::Vector3d step = -JtJ.ldlt().solve(Jtr);
    if (!step.allFinite()) break;
    double new_cost, new_max;
    // Gauss–Newton without damping: the DLT start is close, so a step that does not lower the
    // cost means we are at the minimum to rounding.
    if (!ReprojectionCost(views, p + step, &new_cost, &new_max) || !(new_cost < cost)) break;
    p += step;
    cost = new_cost;
    max_error = new_max;
    out.iterations = it + 1;
    if (step.norm() < options.step_tolerance * (1.0 + p.norm())) break;
  }
  out.ok = true;
  out.p_world = p;
  out.rms_error_px = std::sqrt(cost / views.size());
  out.max_error_px = max_error;
  return out;
}

TriangulatedPoint Triangulate(const Camera& camera_a, const Eigen::Vector2d& uv_a,
                              const Camera& camera_b, const Eigen::Vector2d& uv_b,
                              const TriangulationOptions& options) {
  return Triangulate({PixelView{&camera_a, uv_a}, PixelView{&camera_b, uv_b}}, options);
}

PolylineMatchResult MatchPolylines(const Camera& camera_a,
                                   const std::vector<Eigen::Vector2d>& polyline_a,
                                   const Camera& camera_b,
                                   const std::vector<Eigen::Vector2d>& polyline_b,
                                   const PolylineMatchOptions& options) {
  // Pose of B relative to A: x_b = R_ba x_a + t_ba; essential matrix E = [t_ba]x R_ba.
  const Eigen::Matrix3d R_ba = camera_b.cam_from_world_R * camera_a.cam_from_world_R.transpose();
  const Eigen::Vector3d t_ba = camera_b.cam_from_world_t - R_ba * camera_a.cam_from_world_t;
  if (!(t_ba.norm() > 0.0)) {
    throw std::invalid_argument("MatchPolylines: the two cameras share their optical centre");
  }
  const Eigen::Matrix3d E = Skew(t_ba) * R_ba;

  // Polyline B in B's undistorted normalised image plane, where epipolar lines are straight.
  const int nb = static_cast<int>(polyline_b.size());
  std::vector<Eigen::Vector3d> b_hom(nb);
  std::vector<bool> b_ok(nb);
  for (int k = 0; k < nb; ++k) {
    Eigen::Vector2d xy;
    b_ok[k] = UndistortPixel(camera_b.K, polyline_b[k], &xy);
    b_hom[k] = b_ok[k] ? Eigen::Vector3d(xy.x(), xy.y(), 1.0) : Eigen::Vector3d::Zero();
  }

  PolylineMatchResult result;
  std::vector<Candidate> candidates;
  std::vector<double> s(nb);
  for (int i = 0; i < static_cast<int>(polyline_a.size()); ++i) {
    Eigen::Vector2d xa;
    Eigen::Vector3d line = Eigen::Vector3d::Zero();
    if (UndistortPixel(camera_a.K, polyline_a[i], &xa)) line = E * xa.homogeneous();
    const double line_norm = line.head<2>().norm();
    std::vector<std::pair<double, Eigen::Vector3d>> crossings;  // (position on B, point)
    if (line_norm > 1e-12) {  // zero at the epipole: no line
      for (int k = 0; k < nb; ++k) s[k] = line.dot(b_hom[k]) / line_norm;
      for (int k = 0; k < nb; ++k) {
        if (!b_ok[k]) continue;
        if (s[k] == 0.0) crossings.emplace_back(k, b_hom[k]);
        if (k + 1 < nb && b_ok[k + 1] && s[k] * s[k + 1] < 0.0) {
          const double f = s[k] / (s[k] - s[k + 1]);
          crossings.emplace_back(k + f, (1.0 - f) * b_hom[k] + f * b_hom[k + 1]);
        }
      }
    }
    if (crossings.empty()) {
      ++result.num_no_crossing;
      continue;
    }
    bool any_triangulated = false, any_accepted = false;
    for (const auto& [position, q] : crossings) {
      const Eigen::Vector2d uv_b = PixelFromNormalized(camera_b.K, q.head<2>());
      const TriangulatedPoint p =
          Triangulate(camera_a, polyline_a[i], camera_b, uv_b, options.triangulation);
      if (!p.ok) continue;
      any_triangulated = true;
      if (!(p.rms_error_px <= options.max_reprojection_error_px)) continue;
      any_accepted = true;
      candidates.push_back({i, position, uv_b, p});
    }
    if (!any_triangulated) {
      ++result.num_failed;
    } else if (!any_accepted) {
      ++result.num_rejected;
    }
  }

  // B may be ordered either way relative to A: keep the longer monotone chain.
  double cost_up, cost_down;
  const std::vector<int> up = LongestMonotoneChain(candidates, +1.0, &cost_up);
  const std::vector<int> down = LongestMonotoneChain(candidates, -1.0, &cost_down);
  const bool use_up = up.size() > down.size() || (up.size() == down.size() && cost_up <= cost_down);
  const std::vector<int>& chain = use_up ? up : down;

  int num_matched_pixels = 0;
  for (size_t c = 0; c < candidates.size(); ++c) {
    if (c == 0 || candidates[c].index_a != candidates[c - 1].index_a) ++num_matched_pixels;
  }
  result.num_unordered = num_matched_pixels - static_cast<int>(chain.size());
  for (int c : chain) {
    const Candidate& cand = candidates[c];
    result.points.push_back(
        {cand.index_a, cand.position_b, cand.uv_b, cand.point.p_world, cand.point.rms_error_px});
  }
  return result;
}

}  // namespace rodfit
