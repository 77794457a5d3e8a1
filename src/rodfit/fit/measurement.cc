// The fit's measurement kinds behind one interface (measurement.h).
#include "rodfit/fit/measurement.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace rodfit {
namespace {

// A centre-line observation (observe/observations.h): its closed-form d r / d x chained with
// the vertices' sensitivities.
class CentrelineMeasurement final : public CaseMeasurement {
 public:
  CentrelineMeasurement(std::shared_ptr<const Observation> observation, std::string label)
      : CaseMeasurement(observation->type(), std::move(label)), obs_(std::move(observation)) {}

  const char* unit() const override { return obs_->unit(); }
  int num_measurements() const override { return obs_->num_measurements(); }
  int num_residuals() const override { return obs_->num_residuals(); }
  int num_noise_residuals() const override { return obs_->num_noise_residuals(); }
  int measurement_rows(int) const override {
    return obs_->num_residuals() / std::max(1, obs_->num_measurements());
  }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    VecX r;
    VertexJacobian J;
    if (!obs_->Evaluate(solved.state->x, &r, jacobian ? &J : nullptr)) {
      *why = "the observation model cannot be evaluated on the solved shape (a point behind the "
             "camera, or a non-finite residual)";
      return false;
    }
    Eigen::Map<VecX>(residuals, r.size()) = r;
    if (jacobian) {
      const Eigen::MatrixXd Jp = J.Multiply(*solved.d_x);
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          jacobian, Jp.rows(), Jp.cols()) = Jp;
    }
    return true;
  }

  void Summarise(const Mat3X& shape, const double*, ObservationFit* fit,
                 std::vector<MeasurementResidual>*) const override {
    // From the shape, in the measurement's unit: the closest-point models' error is a distance.
    obs_->RmsError(shape, &fit->rms);
  }

 private:
  std::shared_ptr<const Observation> obs_;
};

// The readings of one force observation (a haptic log's samples, a reaction entry): each the
// force, and at clamps the moment, on one held point.
class ForceObservation final : public CaseMeasurement {
 public:
  ForceObservation(std::vector<ForceMeasurement> readings, std::string label)
      : CaseMeasurement(readings.front().type, std::move(label)), readings_(std::move(readings)) {
    for (const ForceMeasurement& f : readings_) num_residuals_ += f.num_residuals();
  }

  const char* unit() const override { return "N"; }
  int num_measurements() const override { return static_cast<int>(readings_.size()); }
  int num_residuals() const override { return num_residuals_; }
  int num_noise_residuals() const override { return num_residuals_; }
  int measurement_rows(int k) const override { return readings_[k].num_residuals(); }
  std::string measurement_label(int k) const override { return readings_[k].label; }
  bool needs_reactions() const override { return true; }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    const int m = solved.num_parameters;
    const std::vector<HeldReaction>& reactions = *solved.reactions;
    int row = 0;
    for (const ForceMeasurement& f : readings_) {
      int which = -1;
      for (size_t h = 0; h < reactions.size(); ++h)
        if (reactions[h].point == f.point) which = static_cast<int>(h);
      if (which < 0) {  // the fit's CheckHeldPoints refuses this up front
        *why = "the case holds no " + f.point;
        return false;
      }
      const HeldReaction& reaction = reactions[which];
      double* rk = residuals + row;
      for (int i = 0; i < 3; ++i) rk[i] = (reaction.force[i] - f.force[i]) / f.sigma;
      if (f.moment)
        for (int i = 0; i < 3; ++i) rk[3 + i] = (reaction.moment[i] - (*f.moment)[i]) / f.sigma_moment;
      if (jacobian) {
        const auto& d = (*solved.d_reactions)[which];
        for (int i = 0; i < f.num_residuals(); ++i)
          for (int c = 0; c < m; ++c)
            jacobian[(row + i) * m + c] = d(i, c) / (i < 3 ? f.sigma : f.sigma_moment);
      }
      row += f.num_residuals();
    }
    return true;
  }

  // Forces in N and moments in N m, apart.
  void Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override {
    double force_sum = 0.0, moment_sum = 0.0;
    int with_moment = 0, row = 0;
    auto record = [&](const char* unit, int index, const Vec3& error, double sigma) {
      MeasurementResidual mr;
      mr.case_index = fit->case_index;
      mr.case_name = fit->case_name;
      mr.observation = label();
      mr.unit = unit;
      mr.measurement = index;
      mr.error = error;
      mr.sigma = sigma;
      per_measurement->push_back(mr);
    };
    for (size_t k = 0; k < readings_.size(); ++k) {
      const ForceMeasurement& f = readings_[k];
      const Vec3 force_error = Eigen::Map<const Vec3>(residuals + row) * f.sigma;
      force_sum += force_error.squaredNorm();
      record("N", static_cast<int>(k), force_error, f.sigma);
      if (f.moment) {
        const Vec3 moment_error = Eigen::Map<const Vec3>(residuals + row + 3) * f.sigma_moment;
        moment_sum += moment_error.squaredNorm();
        record("N m", with_moment, moment_error, f.sigma_moment);
        ++with_moment;
      }
      row += f.num_residuals();
    }
    fit->rms = std::sqrt(force_sum / static_cast<double>(readings_.size()));
    if (with_moment > 0) fit->rms_moment = std::sqrt(moment_sum / with_moment);
  }

 private:
  std::vector<ForceMeasurement> readings_;
  int num_residuals_ = 0;
};

// Points tracked around a poke (fit.h SurfacePoints) against the deformed ring. Only ring
// parameters move the ring (the fit refuses rod parameters together with surface points), so
// the Jacobian is the ring's d nodes / d log k chained through the foot.
class SurfacePointSet final : public CaseMeasurement {
 public:
  explicit SurfacePointSet(SurfacePoints points)
      : CaseMeasurement("surface_points", points.label), set_(std::move(points)) {}

  const char* unit() const override { return "m"; }
  int num_measurements() const override { return static_cast<int>(set_.points.size()); }
  int num_residuals() const override { return 3 * num_measurements(); }
  int num_noise_residuals() const override { return 2 * num_measurements(); }
  int measurement_rows(int) const override { return 3; }
  bool needs_section() const override { return true; }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    const int m = solved.num_parameters;
    const Eigen::Matrix3Xd& nodes = solved.poke->deformed_world;
    const int n = static_cast<int>(nodes.cols());
    // The closed ring as a polyline: node 0 repeated at the end (polyline vertex j is node j % n).
    Eigen::Matrix3Xd ring(3, n + 1);
    ring.leftCols(n) = nodes;
    ring.col(n) = nodes.col(0);
    int row = 0;
    for (const Eigen::Vector3d& q : set_.points) {
      const PolylineFoot foot = ClosestPointOnPolyline<3>(ring, q);
      if (foot.edge < 0) {
        *why = "no closest point on the deformed section (a non-finite ring)";
        return false;
      }
      Eigen::Vector3d p;
      double t = 0.0;
      Eigen::Vector3d a = Eigen::Vector3d::Zero(), e = Eigen::Vector3d::Zero();
      if (foot.vertex >= 0) {
        p = ring.col(foot.vertex);
      } else {
        a = ring.col(foot.edge);
        e = ring.col(foot.edge + 1) - a;
        t = (q - a).dot(e) / e.squaredNorm();
        p = a + t * e;
      }
      for (int i = 0; i < 3; ++i) residuals[row + i] = (p[i] - q[i]) / set_.sigma;
      if (jacobian) {
        const std::vector<Eigen::Matrix3Xd>& d_ring = *solved.d_ring;
        for (int c = 0; c < m; ++c) {
          Eigen::Vector3d dp;
          if (foot.vertex >= 0) {
            dp = d_ring[c].col(foot.vertex);
          } else {
            // p = a + t e, t = (q - a).e / |e|^2:
            // dt = (-da.e + (q - a).de - 2 t e.de) / |e|^2, dp = da + dt e + t de.
            const Eigen::Vector3d da = d_ring[c].col(foot.edge);
            const Eigen::Vector3d de = d_ring[c].col(foot.edge + 1) - da;
            const double dt =
                (-da.dot(e) + (q - a).dot(de) - 2.0 * t * e.dot(de)) / e.squaredNorm();
            dp = da + dt * e + t * de;
          }
          for (int i = 0; i < 3; ++i) jacobian[(row + i) * m + c] = dp[i] / set_.sigma;
        }
      }
      row += 3;
    }
    return true;
  }

  // The distance to the ring [m].
  void Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override {
    const int np = num_measurements();
    double sum = 0.0;
    for (int k = 0; k < np; ++k) {
      MeasurementResidual mr;
      mr.case_index = fit->case_index;
      mr.case_name = fit->case_name;
      mr.observation = label();
      mr.unit = "m";
      mr.measurement = k;
      mr.error = Eigen::Map<const Vec3>(residuals + 3 * k) * set_.sigma;
      mr.sigma = set_.sigma;
      sum += mr.error.squaredNorm();
      per_measurement->push_back(mr);
    }
    fit->rms = std::sqrt(sum / np);
  }

 private:
  SurfacePoints set_;
};

}  // namespace

std::vector<std::shared_ptr<const CaseMeasurement>> CaseMeasurements(const FitCase& fit_case) {
  std::vector<std::shared_ptr<const CaseMeasurement>> out;
  for (size_t o = 0; o < fit_case.observations.size(); ++o) {
    const auto& obs = fit_case.observations[o];
    out.push_back(std::make_shared<CentrelineMeasurement>(
        obs, o < fit_case.labels.size() ? fit_case.labels[o] : std::string(obs->type())));
  }
  // Consecutive readings of one observation (and one type) form one entry, as the RMS table
  // has one row per entry.
  const std::vector<ForceMeasurement>& forces = fit_case.grasp_forces;
  auto entry_of = [](const ForceMeasurement& f) {
    return f.observation.empty() ? f.label : f.observation;
  };
  for (size_t f = 0; f < forces.size();) {
    const size_t first = f;
    const std::string name = entry_of(forces[first]);
    std::vector<ForceMeasurement> readings;
    for (; f < forces.size() && entry_of(forces[f]) == name && forces[f].type == forces[first].type;
         ++f)
      readings.push_back(forces[f]);
    out.push_back(std::make_shared<ForceObservation>(std::move(readings), name));
  }
  for (const SurfacePoints& sp : fit_case.surface_points)
    out.push_back(std::make_shared<SurfacePointSet>(sp));
  return out;
}

}  // namespace rodfit
