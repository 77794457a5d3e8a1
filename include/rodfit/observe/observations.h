// Observation models (docs/solvers.md, "Observations"): they map the vertices x_0..x_n of a rod to
// weighted residuals r = (model - measured) / sigma for `markers3d`, `points3d` and `image_points`
// (with an arc length s per pixel: markers; without: samples of the thread's image). Each model is
// a const object holding only its measurements (and camera). It offers one templated
// Residuals<T>(x_flat, residuals) for double and ceres::Jet, and a double Evaluate that adds the
// closed-form Jacobian d r / d x. That Jacobian is sparse: the residuals of one measurement
// depend on the two vertices of one edge at most, so VertexJacobian stores one dim x 6 block per
// measurement, and the fit chains it with the equilibrium sensitivities dx/dp.
//
// Closest-point residuals (`points3d`, `image_points` without s) are the vector from the sample q
// to its closest point (foot) p on the model polyline, r = (p(x) - q) / sigma, not the distance
// |p - q| / sigma. Both give the same cost |r|^2 / 2, but the distance is not differentiable
// where it vanishes (its gradient (p - q) / |p - q| is undefined there and flips across the
// curve) — which is exactly where a noise-free or well-fitted sample sits — while the vector is
// smooth there and Gauss–Newton sees the right curvature. The vector's component along an
// interior foot's edge is zero, so a sample carries the information of D - 1 residuals.
//
// Foot rules (shared by the double, Jet and closed-form paths, so all see the same branch):
// the foot is the closest point over all edges, each edge's parameter t clamped to [0, 1]; the
// search runs on plain doubles (the values of the Jets). When the unclamped projection falls
// strictly inside an edge, p = a + t e with t = (q - a)·e / |e|^2 moving with both vertices (the
// derivative includes dt/dx). When it falls at or beyond an end of its edge, the foot is that
// vertex and moves with it alone (dp/dx_v = I): beyond an end of the rod the residual is the
// vector to the end vertex; at an interior vertex this is exact for every sample strictly inside
// the vertex's normal cone (the outer side of a bend). On the boundary of that cone (projection
// exactly at t = 0 or 1 of an adjacent edge) the residual is continuous with a kink, and the
// vertex side is taken: one of the two one-sided derivatives, finite and consistent with the
// value. On the medial axis (equidistant from two edges on the inner side of a bend) the foot
// jumps and the lowest edge wins. The search scans every edge: O(n) per sample, exact even where
// the rod folds back close to itself (a coarse nearest-vertex search could miss the true foot
// there, and a spatial index does not pay at n of order 50).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <ceres/jet.h>
#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "rodfit/model/rod.h"
#include "rodfit/observe/camera.h"

namespace rodfit {

// ---------------------------------------------------------------------------------------------
// Packed vertex layout and the sparse Jacobian.

/// x_flat holds the vertices x_0..x_n as consecutive (x, y, z) triples: the column-major storage
/// of RodState::x. Read it through this view, never by index arithmetic.
template <typename T>
using VerticesView = Eigen::Map<const Eigen::Matrix<T, 3, Eigen::Dynamic>>;

/// Index in x_flat (and column of a dense d r / d x) of vertex i's first coordinate.
inline int VertexCoordinate(int i) { return 3 * i; }

/// d residuals / d vertices of one observation, stored by measurement. Measurement k owns the
/// residual rows [row, row + dim) and depends at most on the two vertices of one edge j, so its
/// derivatives are one dim x 6 block: columns 0..2 for x_j, 3..5 for x_{j+1}.
struct VertexJacobian {
  /// dim x 6 with dim <= 3; no heap allocation.
  using Block = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, 3, 6>;
  struct Entry {
    int row = 0;   ///< first residual row of the measurement
    int edge = 0;  ///< the block's columns are vertices edge and edge + 1
    Block d_r_d_x;
  };

  int num_residuals = 0;
  int num_vertices = 0;
  std::vector<Entry> entries;  ///< one per measurement, rows increasing

  /// num_residuals x 3 num_vertices, columns as x_flat (VertexCoordinate).
  Eigen::MatrixXd ToDense() const;
  Eigen::SparseMatrix<double> ToSparse() const;
  /// d_r_d_x * d_x_d_p for d_x_d_p with 3 num_vertices rows (the fit's chain rule), in
  /// O(num_residuals * 6 * cols) without forming the dense Jacobian.
  Eigen::MatrixXd Multiply(const Eigen::MatrixXd& d_x_d_p) const;
};

// ---------------------------------------------------------------------------------------------
// Geometry shared by the models.

/// Position of an arc length on the rest rod: x(s) = (1 - a) x_edge + a x_{edge+1}, a in [0, 1].
/// s = L is edge n - 1 with a = 1; s at an interior vertex i is edge i with a = 0.
struct ArcLocation {
  int edge = 0;
  double a = 0.0;
};

/// Locates s among the rest arc lengths of the vertices (strictly increasing from 0; L the last).
/// Throws std::invalid_argument naming s when s is not finite or lies outside [0, L] (by more
/// than 1e-12 L, which absorbs the rounding of L = n (L / n); such an s is clamped to the end).
ArcLocation LocateArcLength(const std::vector<double>& vertex_arc_length, double s);

/// Rest arc lengths of a model's vertices (RodModel::arc_length), the input of the s-models.
std::vector<double> VertexArcLengths(const RodModel& model);

/// The closest point of a polyline to a query point (see the foot rules in the file comment).
struct PolylineFoot {
  int edge = -1;      ///< edge j (vertices j, j + 1) holding the foot; -1: no finite distance
  double t = 0.0;     ///< foot = (1 - t) x_j + t x_{j+1}
  int vertex = -1;    ///< the foot is this vertex and moves with it alone; -1: interior foot
  double distance_squared = std::numeric_limits<double>::infinity();
};

/// Scans all edges of the polyline with vertices as columns (at least 2) for the foot of q.
/// A zero-length edge counts as its first vertex. Instantiated for D = 2 and 3.
template <int D>
PolylineFoot ClosestPointOnPolyline(const Eigen::Matrix<double, D, Eigen::Dynamic>& vertices,
                                    const Eigen::Matrix<double, D, 1>& q);

namespace internal {

inline double ScalarPart(double v) { return v; }
template <typename S, int N>
double ScalarPart(const ceres::Jet<S, N>& v) {
  return ScalarPart(v.a);
}

/// The values of a matrix of doubles or Jets.
template <typename Derived>
Eigen::Matrix<double, Derived::RowsAtCompileTime, Eigen::Dynamic> ScalarParts(
    const Eigen::MatrixBase<Derived>& m) {
  Eigen::Matrix<double, Derived::RowsAtCompileTime, Eigen::Dynamic> out(m.rows(), m.cols());
  for (Eigen::Index j = 0; j < m.cols(); ++j) {
    for (Eigen::Index i = 0; i < m.rows(); ++i) out(i, j) = ScalarPart(m(i, j));
  }
  return out;
}

/// The foot point for a foot found on the values: a vertex, or the projection onto the edge
/// recomputed in T so that Jets carry dt/dx.
template <typename T, int D, typename Derived>
Eigen::Matrix<T, D, 1> FootPoint(const Eigen::MatrixBase<Derived>& vertices,
                                 const PolylineFoot& foot, const Eigen::Matrix<double, D, 1>& q) {
  if (foot.vertex >= 0) return vertices.col(foot.vertex);
  const Eigen::Matrix<T, D, 1> a = vertices.col(foot.edge);
  const Eigen::Matrix<T, D, 1> e = vertices.col(foot.edge + 1) - a;
  const T t = (q.template cast<T>() - a).dot(e) / e.squaredNorm();
  return a + t * e;
}

template <typename T>
void FillNaN(int count, T* residuals) {
  for (int i = 0; i < count; ++i) residuals[i] = T(std::numeric_limits<double>::quiet_NaN());
}

}  // namespace internal

// ---------------------------------------------------------------------------------------------
// The models.

/// What the observation models share: the rod's vertex count, the measurement sigma and the
/// checks of both. Not an interface: the fit holds every kind of measurement behind one
/// (rodfit/fit/measurement.h), which wraps these models; each model is a concrete class with the
/// same members (num_measurements, num_residuals, num_noise_residuals, unit, Evaluate, RmsError).
class ObservationModel {
 public:
  /// Names the model in messages: "markers3d", "points3d" or "image_points".
  const char* type() const { return type_; }
  int num_vertices() const { return num_vertices_; }
  /// Measurement standard deviation [m] or [px].
  double sigma() const { return sigma_; }

 protected:
  /// Throws std::invalid_argument unless num_vertices >= 2 and sigma is positive and finite.
  ObservationModel(const char* type, int num_vertices, double sigma);
  /// Throws std::invalid_argument unless x has num_vertices() columns.
  void CheckVertices(const Mat3X& x) const;

 private:
  const char* type_;
  int num_vertices_;
  double sigma_;
};

// Each model's members, documented once here:
//   num_measurements(), num_residuals()
//   num_noise_residuals(): residuals that carry noise: a closest-point residual is perpendicular
//     to the curve, so a 3-D point carries 2 of its 3 and a pixel of an image curve 1 of its 2.
//     The residual variance 2 cost / (N - m) counts these, or it underestimates the noise.
//   unit(): the measurement's unit, "m" (3-D) or "px" (pixels).
//   Evaluate(x, residuals, d_r_d_x): residuals (model - measured) / sigma and, when d_r_d_x is
//     given, their closed-form Jacobian. x has num_vertices() columns [m] (throws
//     std::invalid_argument otherwise). Returns false when the model cannot be observed (a point
//     at or behind a camera; for the closest-point models also non-finite vertices, which leave
//     no foot): the residuals are then NaN, the Jacobian unspecified, and the caller must fail
//     the evaluation.
//   RmsError(x, rms): root mean square of the unweighted misfit per measurement,
//     sqrt(sum_k |e_k|^2 / M), in the measurement's unit ([m] or [px]); e_k = model - measured is
//     the 3-D or 2-D error vector (its norm is the distance for the closest-point models). False
//     when Evaluate fails.

/// A 3-D marker at rest arc length s.
struct Marker3d {
  double s = 0.0;                                    ///< [m], in [0, L]
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();  ///< [m]
};

/// `markers3d`: 3 residuals per marker, (x(s) - p) / sigma with x(s) the linear interpolation
/// of the vertices at the rest arc length s.
class Markers3dObservation final : public ObservationModel {
 public:
  /// vertex_arc_length: rest arc lengths of the vertices (VertexArcLengths). Throws
  /// std::invalid_argument for no markers, a non-finite point, a marker with s outside [0, L]
  /// (naming the marker's index and s), or a sigma [m] that is not positive.
  Markers3dObservation(const std::vector<double>& vertex_arc_length,
                       std::vector<Marker3d> markers, double sigma);

  int num_measurements() const { return static_cast<int>(markers_.size()); }
  int num_residuals() const { return 3 * num_measurements(); }
  int num_noise_residuals() const { return num_residuals(); }
  const char* unit() const { return "m"; }
  const std::vector<Marker3d>& markers() const { return markers_; }

  /// x_flat: 3 num_vertices() values (VerticesView); residuals: num_residuals() values.
  template <typename T>
  bool Residuals(const T* x_flat, T* residuals) const;
  bool Evaluate(const Mat3X& x, VecX* residuals,
                VertexJacobian* d_r_d_x = nullptr) const;
  bool RmsError(const Mat3X& x, double* rms) const;

 private:
  std::vector<Marker3d> markers_;
  std::vector<ArcLocation> where_;  ///< per marker
};

/// `points3d`: unordered 3-D centre-line samples; 3 residuals per sample, (p(x) - q) / sigma with
/// p the closest point of the model polyline (file comment).
class Points3dObservation final : public ObservationModel {
 public:
  /// Throws std::invalid_argument for no samples, a non-finite sample, num_vertices < 2 or a
  /// sigma [m] that is not positive.
  Points3dObservation(int num_vertices, std::vector<Eigen::Vector3d> samples, double sigma);

  int num_measurements() const { return static_cast<int>(samples_.size()); }
  int num_residuals() const { return 3 * num_measurements(); }
  int num_noise_residuals() const { return 2 * num_measurements(); }
  const char* unit() const { return "m"; }
  const std::vector<Eigen::Vector3d>& samples() const { return samples_; }

  template <typename T>
  bool Residuals(const T* x_flat, T* residuals) const;
  bool Evaluate(const Mat3X& x, VecX* residuals,
                VertexJacobian* d_r_d_x = nullptr) const;
  bool RmsError(const Mat3X& x, double* rms) const;

 private:
  std::vector<Eigen::Vector3d> samples_;  ///< [m]
};

/// A pixel marker at rest arc length s.
struct MarkerPixel {
  double s = 0.0;                               ///< [m], in [0, L]
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();  ///< [px]
};

/// `image_points` with s: 2 residuals per marker, (Project(x(s)) - uv) / sigma.
/// Fails (false) when any marker's point is at or behind the camera.
class ImageMarkersObservation final : public ObservationModel {
 public:
  /// Throws std::invalid_argument as Markers3dObservation, and for a camera failing
  /// Camera::Check. sigma in [px].
  ImageMarkersObservation(const std::vector<double>& vertex_arc_length, const Camera& camera,
                          std::vector<MarkerPixel> markers, double sigma_px);

  int num_measurements() const { return static_cast<int>(markers_.size()); }
  int num_residuals() const { return 2 * num_measurements(); }
  int num_noise_residuals() const { return num_residuals(); }
  const char* unit() const { return "px"; }
  const std::vector<MarkerPixel>& markers() const { return markers_; }
  const Camera& camera() const { return camera_; }

  template <typename T>
  bool Residuals(const T* x_flat, T* residuals) const;
  bool Evaluate(const Mat3X& x, VecX* residuals,
                VertexJacobian* d_r_d_x = nullptr) const;
  bool RmsError(const Mat3X& x, double* rms) const;

 private:
  Camera camera_;
  std::vector<MarkerPixel> markers_;
  std::vector<ArcLocation> where_;
};

/// `image_points` without s: 2 residuals per pixel, (p(uv(x)) - m) / sigma with p the closest
/// point of the 2-D polyline through the projected vertices (file comment). Every vertex must
/// project: the evaluation fails (false) when any vertex is at or behind the camera, since a
/// polyline with a vertex behind the camera has no meaningful image.
class ImageCurveObservation final : public ObservationModel {
 public:
  /// Throws std::invalid_argument for no pixels, a non-finite pixel, num_vertices < 2, a
  /// sigma [px] that is not positive or a camera failing Camera::Check.
  ImageCurveObservation(int num_vertices, const Camera& camera,
                        std::vector<Eigen::Vector2d> pixels, double sigma_px);

  int num_measurements() const { return static_cast<int>(pixels_.size()); }
  int num_residuals() const { return 2 * num_measurements(); }
  int num_noise_residuals() const { return num_measurements(); }
  const char* unit() const { return "px"; }
  const std::vector<Eigen::Vector2d>& pixels() const { return pixels_; }
  const Camera& camera() const { return camera_; }

  template <typename T>
  bool Residuals(const T* x_flat, T* residuals) const;
  bool Evaluate(const Mat3X& x, VecX* residuals,
                VertexJacobian* d_r_d_x = nullptr) const;
  bool RmsError(const Mat3X& x, double* rms) const;

 private:
  Camera camera_;
  std::vector<Eigen::Vector2d> pixels_;  ///< [px]
};

// ---------------------------------------------------------------------------------------------
// Templated residuals (defined here so that any Jet size passes through).

template <typename T>
bool Markers3dObservation::Residuals(const T* x_flat, T* residuals) const {
  const VerticesView<T> x(x_flat, 3, num_vertices());
  const T inv_sigma = T(1.0 / sigma());
  for (int k = 0; k < num_measurements(); ++k) {
    const ArcLocation& at = where_[k];
    const Eigen::Matrix<T, 3, 1> p =
        T(1.0 - at.a) * x.col(at.edge) + T(at.a) * x.col(at.edge + 1);
    Eigen::Map<Eigen::Matrix<T, 3, 1>>(residuals + 3 * k) =
        (p - markers_[k].p_world.cast<T>()) * inv_sigma;
  }
  return true;
}

template <typename T>
bool Points3dObservation::Residuals(const T* x_flat, T* residuals) const {
  const VerticesView<T> x(x_flat, 3, num_vertices());
  const Eigen::Matrix3Xd x_value = internal::ScalarParts(x);
  const T inv_sigma = T(1.0 / sigma());
  for (int k = 0; k < num_measurements(); ++k) {
    const PolylineFoot foot = ClosestPointOnPolyline<3>(x_value, samples_[k]);
    if (foot.edge < 0) {
      internal::FillNaN(num_residuals(), residuals);
      return false;
    }
    const Eigen::Matrix<T, 3, 1> p = internal::FootPoint<T, 3>(x, foot, samples_[k]);
    Eigen::Map<Eigen::Matrix<T, 3, 1>>(residuals + 3 * k) =
        (p - samples_[k].cast<T>()) * inv_sigma;
  }
  return true;
}

template <typename T>
bool ImageMarkersObservation::Residuals(const T* x_flat, T* residuals) const {
  const VerticesView<T> x(x_flat, 3, num_vertices());
  const T inv_sigma = T(1.0 / sigma());
  for (int k = 0; k < num_measurements(); ++k) {
    const ArcLocation& at = where_[k];
    const Eigen::Matrix<T, 3, 1> p =
        T(1.0 - at.a) * x.col(at.edge) + T(at.a) * x.col(at.edge + 1);
    Eigen::Matrix<T, 2, 1> uv;
    if (!Project(camera_, p, &uv)) {
      internal::FillNaN(num_residuals(), residuals);
      return false;
    }
    Eigen::Map<Eigen::Matrix<T, 2, 1>>(residuals + 2 * k) =
        (uv - markers_[k].uv.cast<T>()) * inv_sigma;
  }
  return true;
}

template <typename T>
bool ImageCurveObservation::Residuals(const T* x_flat, T* residuals) const {
  const VerticesView<T> x(x_flat, 3, num_vertices());
  Eigen::Matrix<T, 2, Eigen::Dynamic> uv(2, num_vertices());
  for (int i = 0; i < num_vertices(); ++i) {
    const Eigen::Matrix<T, 3, 1> p = x.col(i);
    Eigen::Matrix<T, 2, 1> uv_i;
    if (!Project(camera_, p, &uv_i)) {
      internal::FillNaN(num_residuals(), residuals);
      return false;
    }
    uv.col(i) = uv_i;
  }
  const Eigen::Matrix2Xd uv_value = internal::ScalarParts(uv);
  const T inv_sigma = T(1.0 / sigma());
  for (int k = 0; k < num_measurements(); ++k) {
    const PolylineFoot foot = ClosestPointOnPolyline<2>(uv_value, pixels_[k]);
    if (foot.edge < 0) {
      internal::FillNaN(num_residuals(), residuals);
      return false;
    }
    const Eigen::Matrix<T, 2, 1> p = internal::FootPoint<T, 2>(uv, foot, pixels_[k]);
    Eigen::Map<Eigen::Matrix<T, 2, 1>>(residuals + 2 * k) =
        (p - pixels_[k].cast<T>()) * inv_sigma;
  }
  return true;
}

}  // namespace rodfit
