// The double path of the observation models (observations.h): validation of the measurements,
// the closest-point search, and the closed-form Jacobians d r / d x. Values are computed with
// the same expressions and branches as the templated Residuals<T>, so Evaluate and
// Residuals<double> return the same bits, Jets take the same branch, and the Jacobian is the
// exact derivative of the value returned.
#include "rodfit/observe/observations.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace rodfit {
namespace {

using Mat36 = Eigen::Matrix<double, 3, 6>;

std::string FormatNumber(double v) {
  std::ostringstream out;
  out << std::setprecision(15) << v;  // round-trips any value typed with up to 15 digits
  return out.str();
}

[[noreturn]] void Fail(const char* type, const std::string& what) {
  throw std::invalid_argument(std::string(type) + ": " + what);
}

void CheckArcLengths(const char* type, const std::vector<double>& vertex_arc_length) {
  if (vertex_arc_length.size() < 2) Fail(type, "vertex_arc_length.size() >= 2 violated");
  if (vertex_arc_length.front() != 0.0) Fail(type, "vertex_arc_length.front() == 0 violated");
  for (size_t i = 1; i < vertex_arc_length.size(); ++i) {
    if (!(vertex_arc_length[i] > vertex_arc_length[i - 1])) {
      Fail(type, "vertex arc lengths must increase strictly (vertex " + std::to_string(i) + ")");
    }
  }
}

ArcLocation LocateMarker(const char* type, const std::vector<double>& vertex_arc_length,
                         int index, double s) {
  try {
    return LocateArcLength(vertex_arc_length, s);
  } catch (const std::invalid_argument& e) {
    Fail(type, "marker " + std::to_string(index) + ": " + e.what());
  }
}

VertexJacobian::Entry MakeEntry(int row, int dim) {
  VertexJacobian::Entry entry;
  entry.row = row;
  entry.d_r_d_x.setZero(dim, 6);
  return entry;
}

void StartJacobian(int num_residuals, int num_vertices, int num_measurements,
                   VertexJacobian* jacobian) {
  jacobian->num_residuals = num_residuals;
  jacobian->num_vertices = num_vertices;
  jacobian->entries.clear();
  jacobian->entries.reserve(num_measurements);
}

// The RMS of every model (ObservationModel's comment): its own Evaluate, then sigma |r| / sqrt(M)
// since |r_k| sigma = |e_k|, so sum_k |e_k|^2 = sigma^2 |r|^2.
template <class Model>
bool RmsOf(const Model& model, const Mat3X& x, double* rms) {
  VecX r;
  if (!model.Evaluate(x, &r)) return false;
  *rms = model.sigma() * std::sqrt(r.squaredNorm() / model.num_measurements());
  return true;
}

bool FailEvaluation(VecX* residuals) {
  residuals->setConstant(std::numeric_limits<double>::quiet_NaN());
  return false;
}

/// The derivative of a foot with respect to the two vertices of an edge: d_p_d_ab is D x 2D,
/// columns 0..D-1 for vertex `edge`, D..2D-1 for vertex edge + 1.
template <int D>
struct FootJacobian {
  int edge = 0;
  Eigen::Matrix<double, D, 2 * D> d_p_d_ab;
};

template <int D>
FootJacobian<D> FootDerivative(const Eigen::Matrix<double, D, Eigen::Dynamic>& vertices,
                               const PolylineFoot& foot, const Eigen::Matrix<double, D, 1>& q) {
  using VecD = Eigen::Matrix<double, D, 1>;
  using MatD = Eigen::Matrix<double, D, D>;
  FootJacobian<D> out;
  out.d_p_d_ab.setZero();
  if (foot.vertex >= 0) {
    // The foot is the vertex itself (file comment of observations.h): dp/dx_v = I. Any edge
    // holding the vertex will do for the block; take the one it starts unless it is the last.
    out.edge = std::min(foot.vertex, static_cast<int>(vertices.cols()) - 2);
    out.d_p_d_ab.template block<D, D>(0, D * (foot.vertex - out.edge)) = MatD::Identity();
    return out;
  }
  out.edge = foot.edge;
  const VecD a = vertices.col(foot.edge);
  const VecD e = vertices.col(foot.edge + 1) - a;
  const VecD w = q - a;
  const double ee = e.squaredNorm();
  const double t = w.dot(e) / ee;
  // t = w·e / e·e with w = q - a, e = b - a:
  //   dt/da = (2 t e - e - w) / e·e,  dt/db = (w - 2 t e) / e·e;
  // p = a + t e:  dp/da = (1 - t) I + e dt/da^T,  dp/db = t I + e dt/db^T.
  // (Their sum I - e e^T / e·e: translating the edge moves the foot only across the edge.)
  const VecD dt_da = (2.0 * t * e - e - w) / ee;
  const VecD dt_db = (w - 2.0 * t * e) / ee;
  out.d_p_d_ab.template block<D, D>(0, 0) = (1.0 - t) * MatD::Identity() + e * dt_da.transpose();
  out.d_p_d_ab.template block<D, D>(0, D) = t * MatD::Identity() + e * dt_db.transpose();
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

Eigen::MatrixXd VertexJacobian::ToDense() const {
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(num_residuals, 3 * num_vertices);
  for (const Entry& entry : entries) {
    dense.block(entry.row, VertexCoordinate(entry.edge), entry.d_r_d_x.rows(), 6) =
        entry.d_r_d_x;
  }
  return dense;
}

Eigen::SparseMatrix<double> VertexJacobian::ToSparse() const {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(entries.size() * 18);
  for (const Entry& entry : entries) {
    for (int c = 0; c < 6; ++c) {
      for (int r = 0; r < entry.d_r_d_x.rows(); ++r) {
        triplets.emplace_back(entry.row + r, VertexCoordinate(entry.edge) + c,
                              entry.d_r_d_x(r, c));
      }
    }
  }
  Eigen::SparseMatrix<double> sparse(num_residuals, 3 * num_vertices);
  sparse.setFromTriplets(triplets.begin(), triplets.end());
  return sparse;
}

Eigen::MatrixXd VertexJacobian::Multiply(const Eigen::MatrixXd& d_x_d_p) const {
  if (d_x_d_p.rows() != 3 * num_vertices) {
    throw std::invalid_argument("VertexJacobian::Multiply: d_x_d_p.rows() == 3 * num_vertices");
  }
  Eigen::MatrixXd product = Eigen::MatrixXd::Zero(num_residuals, d_x_d_p.cols());
  for (const Entry& entry : entries) {
    product.middleRows(entry.row, entry.d_r_d_x.rows()).noalias() =
        entry.d_r_d_x * d_x_d_p.middleRows(VertexCoordinate(entry.edge), 6);
  }
  return product;
}

// ---------------------------------------------------------------------------------------------

ArcLocation LocateArcLength(const std::vector<double>& vertex_arc_length, double s) {
  if (vertex_arc_length.size() < 2) {
    throw std::invalid_argument("LocateArcLength: vertex_arc_length.size() >= 2 violated");
  }
  const double length = vertex_arc_length.back();
  const double slack = 1e-12 * length;
  if (!std::isfinite(s) || s < -slack || s > length + slack) {
    throw std::invalid_argument("arc length s = " + FormatNumber(s) + " m is outside [0, " +
                                FormatNumber(length) + "]");
  }
  s = std::clamp(s, 0.0, length);
  const int last_edge = static_cast<int>(vertex_arc_length.size()) - 2;
  // The edge starting at or before s: s at vertex i lands on edge i (a = 0), s = L on the last.
  const auto after = std::upper_bound(vertex_arc_length.begin(), vertex_arc_length.end(), s);
  ArcLocation at;
  at.edge = std::clamp(static_cast<int>(after - vertex_arc_length.begin()) - 1, 0, last_edge);
  const double s0 = vertex_arc_length[at.edge], s1 = vertex_arc_length[at.edge + 1];
  at.a = std::clamp((s - s0) / (s1 - s0), 0.0, 1.0);
  return at;
}

std::vector<double> VertexArcLengths(const RodModel& model) {
  std::vector<double> s(model.num_vertices());
  for (int i = 0; i < model.num_vertices(); ++i) s[i] = model.arc_length(i);
  return s;
}

template <int D>
PolylineFoot ClosestPointOnPolyline(const Eigen::Matrix<double, D, Eigen::Dynamic>& vertices,
                                    const Eigen::Matrix<double, D, 1>& q) {
  using VecD = Eigen::Matrix<double, D, 1>;
  PolylineFoot best;
  for (int j = 0; j + 1 < vertices.cols(); ++j) {
    const VecD a = vertices.col(j);
    const VecD e = vertices.col(j + 1) - a;
    const VecD w = q - a;
    const double ee = e.squaredNorm();
    const double we = w.dot(e);
    PolylineFoot foot;
    foot.edge = j;
    // Written with negations so that a NaN lands on a vertex rather than in a division; its
    // distance is NaN and never wins. A zero-length edge has no direction: its first vertex.
    if (!(ee > 0.0) || !(we > 0.0)) {
      foot.t = 0.0;
      foot.vertex = j;
    } else if (!(we < ee)) {
      foot.t = 1.0;
      foot.vertex = j + 1;
    } else {
      foot.t = we / ee;
    }
    // Vertex feet measure to the vertex itself, so that the two edges meeting there tie exactly.
    foot.distance_squared = foot.vertex >= 0 ? (q - vertices.col(foot.vertex)).squaredNorm()
                                             : (w - foot.t * e).squaredNorm();
    if (foot.distance_squared < best.distance_squared) best = foot;
  }
  return best;
}

template PolylineFoot ClosestPointOnPolyline<2>(const Eigen::Matrix<double, 2, Eigen::Dynamic>&,
                                                const Eigen::Matrix<double, 2, 1>&);
template PolylineFoot ClosestPointOnPolyline<3>(const Eigen::Matrix<double, 3, Eigen::Dynamic>&,
                                                const Eigen::Matrix<double, 3, 1>&);

// ---------------------------------------------------------------------------------------------

ObservationModel::ObservationModel(const char* type, int num_vertices, double sigma)
    : type_(type), num_vertices_(num_vertices), sigma_(sigma) {
  if (num_vertices < 2) Fail(type, "a rod needs at least 2 vertices");
  if (!(std::isfinite(sigma) && sigma > 0.0)) {
    Fail(type, "sigma must be positive and finite (got " + FormatNumber(sigma) + ")");
  }
}

void ObservationModel::CheckVertices(const Mat3X& x) const {
  if (x.cols() != num_vertices_) {
    throw std::invalid_argument(std::string(type()) + ": Evaluate: x.cols() == num_vertices() (" +
                                std::to_string(x.cols()) + " != " +
                                std::to_string(num_vertices_) + ")");
  }
}

// ---------------------------------------------------------------------------------------------

Markers3dObservation::Markers3dObservation(const std::vector<double>& vertex_arc_length,
                                           std::vector<Marker3d> markers, double sigma)
    : ObservationModel("markers3d", static_cast<int>(vertex_arc_length.size()), sigma),
      markers_(std::move(markers)) {
  CheckArcLengths(type(), vertex_arc_length);
  if (markers_.empty()) Fail(type(), "no markers");
  where_.reserve(markers_.size());
  for (size_t k = 0; k < markers_.size(); ++k) {
    if (!markers_[k].p_world.allFinite()) {
      Fail(type(), "marker " + std::to_string(k) + ": non-finite position");
    }
    where_.push_back(LocateMarker(type(), vertex_arc_length, static_cast<int>(k),
                                  markers_[k].s));
  }
}

bool Markers3dObservation::Evaluate(const Mat3X& x, VecX* residuals,
                                    VertexJacobian* d_r_d_x) const {
  CheckVertices(x);
  residuals->resize(num_residuals());
  Residuals(x.data(), residuals->data());
  if (d_r_d_x) {
    StartJacobian(num_residuals(), num_vertices(), num_measurements(), d_r_d_x);
    const double inv_sigma = 1.0 / sigma();
    for (int k = 0; k < num_measurements(); ++k) {
      VertexJacobian::Entry entry = MakeEntry(3 * k, 3);
      entry.edge = where_[k].edge;
      entry.d_r_d_x.leftCols<3>().diagonal().setConstant((1.0 - where_[k].a) * inv_sigma);
      entry.d_r_d_x.rightCols<3>().diagonal().setConstant(where_[k].a * inv_sigma);
      d_r_d_x->entries.push_back(entry);
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

Points3dObservation::Points3dObservation(int num_vertices, std::vector<Eigen::Vector3d> samples,
                                         double sigma)
    : ObservationModel("points3d", num_vertices, sigma), samples_(std::move(samples)) {
  if (samples_.empty()) Fail(type(), "no samples");
  for (size_t k = 0; k < samples_.size(); ++k) {
    if (!samples_[k].allFinite()) {
      Fail(type(), "sample " + std::to_string(k) + ": non-finite position");
    }
  }
}

bool Points3dObservation::Evaluate(const Mat3X& x, VecX* residuals,
                                   VertexJacobian* d_r_d_x) const {
  CheckVertices(x);
  residuals->resize(num_residuals());
  if (d_r_d_x) StartJacobian(num_residuals(), num_vertices(), num_measurements(), d_r_d_x);
  const double inv_sigma = 1.0 / sigma();
  for (int k = 0; k < num_measurements(); ++k) {
    const Eigen::Vector3d& q = samples_[k];
    const PolylineFoot foot = ClosestPointOnPolyline<3>(x, q);
    if (foot.edge < 0) return FailEvaluation(residuals);
    const Eigen::Vector3d p = internal::FootPoint<double, 3>(x, foot, q);
    residuals->segment<3>(3 * k) = (p - q) * inv_sigma;
    if (d_r_d_x) {
      const FootJacobian<3> d_p = FootDerivative<3>(x, foot, q);
      VertexJacobian::Entry entry = MakeEntry(3 * k, 3);
      entry.edge = d_p.edge;
      entry.d_r_d_x = d_p.d_p_d_ab * inv_sigma;
      d_r_d_x->entries.push_back(entry);
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

namespace {
void CheckCamera(const Camera& camera) {
  std::string why;
  if (!camera.Check(&why)) Fail("image_points", "camera '" + camera.name + "': " + why);
}
}  // namespace

ImageMarkersObservation::ImageMarkersObservation(const std::vector<double>& vertex_arc_length,
                                                 const Camera& camera,
                                                 std::vector<MarkerPixel> markers,
                                                 double sigma_px)
    : ObservationModel("image_points", static_cast<int>(vertex_arc_length.size()), sigma_px),
      camera_(camera),
      markers_(std::move(markers)) {
  CheckArcLengths(type(), vertex_arc_length);
  CheckCamera(camera_);
  if (markers_.empty()) Fail(type(), "no markers");
  where_.reserve(markers_.size());
  for (size_t k = 0; k < markers_.size(); ++k) {
    if (!markers_[k].uv.allFinite()) {
      Fail(type(), "marker " + std::to_string(k) + ": non-finite pixel");
    }
    where_.push_back(LocateMarker(type(), vertex_arc_length, static_cast<int>(k),
                                  markers_[k].s));
  }
}

bool ImageMarkersObservation::Evaluate(const Mat3X& x, VecX* residuals,
                                       VertexJacobian* d_r_d_x) const {
  CheckVertices(x);
  residuals->resize(num_residuals());
  if (d_r_d_x) StartJacobian(num_residuals(), num_vertices(), num_measurements(), d_r_d_x);
  const double inv_sigma = 1.0 / sigma();
  for (int k = 0; k < num_measurements(); ++k) {
    const ArcLocation& at = where_[k];
    // Same expression as Residuals<T>, so both paths return the same bits.
    const Eigen::Vector3d p = (1.0 - at.a) * x.col(at.edge) + at.a * x.col(at.edge + 1);
    Eigen::Vector2d uv;
    Mat23 d_uv_d_p;
    if (!Project(camera_, p, &uv, d_r_d_x ? &d_uv_d_p : nullptr)) {
      return FailEvaluation(residuals);
    }
    residuals->segment<2>(2 * k) = (uv - markers_[k].uv) * inv_sigma;
    if (d_r_d_x) {
      VertexJacobian::Entry entry = MakeEntry(2 * k, 2);
      entry.edge = at.edge;
      entry.d_r_d_x.leftCols<3>() = ((1.0 - at.a) * inv_sigma) * d_uv_d_p;
      entry.d_r_d_x.rightCols<3>() = (at.a * inv_sigma) * d_uv_d_p;
      d_r_d_x->entries.push_back(entry);
    }
  }
  return true;
}

// ---------------------------------------------------------------------------------------------

ImageCurveObservation::ImageCurveObservation(int num_vertices, const Camera& camera,
                                             std::vector<Eigen::Vector2d> pixels,
                                             double sigma_px)
    : ObservationModel("image_points", num_vertices, sigma_px),
      camera_(camera),
      pixels_(std::move(pixels)) {
  CheckCamera(camera_);
  if (pixels_.empty()) Fail(type(), "no pixels");
  for (size_t k = 0; k < pixels_.size(); ++k) {
    if (!pixels_[k].allFinite()) {
      Fail(type(), "pixel " + std::to_string(k) + ": non-finite value");
    }
  }
}

bool ImageCurveObservation::Evaluate(const Mat3X& x, VecX* residuals,
                                     VertexJacobian* d_r_d_x) const {
  CheckVertices(x);
  residuals->resize(num_residuals());
  Eigen::Matrix2Xd uv(2, num_vertices());
  std::vector<Mat23> d_uv_d_x(d_r_d_x ? num_vertices() : 0);
  for (int i = 0; i < num_vertices(); ++i) {
    Eigen::Vector2d uv_i;
    if (!Project(camera_, Eigen::Vector3d(x.col(i)), &uv_i, d_r_d_x ? &d_uv_d_x[i] : nullptr)) {
      return FailEvaluation(residuals);
    }
    uv.col(i) = uv_i;
  }
  if (d_r_d_x) StartJacobian(num_residuals(), num_vertices(), num_measurements(), d_r_d_x);
  const double inv_sigma = 1.0 / sigma();
  for (int k = 0; k < num_measurements(); ++k) {
    const Eigen::Vector2d& m = pixels_[k];
    const PolylineFoot foot = ClosestPointOnPolyline<2>(uv, m);
    if (foot.edge < 0) return FailEvaluation(residuals);
    const Eigen::Vector2d p = internal::FootPoint<double, 2>(uv, foot, m);
    residuals->segment<2>(2 * k) = (p - m) * inv_sigma;
    if (d_r_d_x) {
      // Chain rule through the projection of the edge's two vertices.
      const FootJacobian<2> d_p = FootDerivative<2>(uv, foot, m);
      VertexJacobian::Entry entry = MakeEntry(2 * k, 2);
      entry.edge = d_p.edge;
      entry.d_r_d_x.leftCols<3>() =
          inv_sigma * d_p.d_p_d_ab.leftCols<2>() * d_uv_d_x[d_p.edge];
      entry.d_r_d_x.rightCols<3>() =
          inv_sigma * d_p.d_p_d_ab.rightCols<2>() * d_uv_d_x[d_p.edge + 1];
      d_r_d_x->entries.push_back(entry);
    }
  }
  return true;
}

bool Markers3dObservation::RmsError(const Mat3X& x, double* rms) const {
  return RmsOf(*this, x, rms);
}
bool Points3dObservation::RmsError(const Mat3X& x, double* rms) const {
  return RmsOf(*this, x, rms);
}
bool ImageMarkersObservation::RmsError(const Mat3X& x, double* rms) const {
  return RmsOf(*this, x, rms);
}
bool ImageCurveObservation::RmsError(const Mat3X& x, double* rms) const {
  return RmsOf(*this, x, rms);
}

}  // namespace rodfit
