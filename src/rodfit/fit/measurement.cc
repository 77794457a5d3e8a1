// The measurement kinds the fit layer defines (measurement.h): force readings and surface points;
// the samples every kind lists in the tables.
#include "rodfit/fit/measurement.h"

#include <cmath>
#include <stdexcept>
#include <utility>

namespace rodfit {

void Measurement::AppendSamples(const double* residuals, const ObservationFit& fit,
                                std::vector<MeasurementResidual>* per_measurement) const {
  std::vector<std::pair<std::string, int>> counters;  // unit -> next index
  int row = 0;
  for (int k = 0; k < num_samples(); ++k) {
    MeasurementResidual mr;
    mr.case_index = fit.case_index;
    mr.case_name = fit.case_name;
    mr.observation = label();
    mr.unit = sample_unit(k);
    int* counter = nullptr;
    for (auto& [unit, next] : counters)
      if (unit == mr.unit) counter = &next;
    if (!counter) {
      counters.emplace_back(mr.unit, 0);
      counter = &counters.back().second;
    }
    mr.measurement = (*counter)++;
    mr.sigma = sample_sigma(k);
    const int rows = sample_rows(k);
    mr.components = rows;
    for (int i = 0; i < rows; ++i) mr.error[i] = residuals[row + i] * mr.sigma;
    per_measurement->push_back(mr);
    row += rows;
  }
}

// ---------------------------------------------------------------------------------------------

ForceReadings::ForceReadings(std::string type, std::string label,
                             std::vector<ForceMeasurement> readings)
    : Measurement(std::move(type), std::move(label)), readings_(std::move(readings)) {
  if (readings_.empty()) throw std::invalid_argument(this->label() + ": no readings");
  for (const ForceMeasurement& f : readings_) {
    num_residuals_ += f.num_residuals();
    num_samples_ += f.moment ? 2 : 1;
  }
}

std::pair<int, bool> ForceReadings::SampleOf(int k) const {
  for (int r = 0; r < static_cast<int>(readings_.size()); ++r) {
    if (k == 0) return {r, false};
    if (readings_[r].moment && k == 1) return {r, true};
    k -= readings_[r].moment ? 2 : 1;
  }
  return {static_cast<int>(readings_.size()) - 1, false};
}

double ForceReadings::sample_sigma(int k) const {
  const auto [r, moment] = SampleOf(k);
  return moment ? readings_[r].sigma_moment : readings_[r].sigma;
}

const char* ForceReadings::sample_unit(int k) const { return SampleOf(k).second ? "N m" : "N"; }

bool ForceReadings::Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                             std::string* why) const {
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
      for (int i = 0; i < 3; ++i)
        rk[3 + i] = (reaction.moment[i] - (*f.moment)[i]) / f.sigma_moment;
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

void ForceReadings::Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                              std::vector<MeasurementResidual>* per_measurement) const {
  double force_sum = 0.0, moment_sum = 0.0;
  int with_moment = 0, row = 0;
  for (const ForceMeasurement& f : readings_) {
    const Vec3 force_error = Eigen::Map<const Vec3>(residuals + row) * f.sigma;
    force_sum += force_error.squaredNorm();
    if (f.moment) {
      const Vec3 moment_error = Eigen::Map<const Vec3>(residuals + row + 3) * f.sigma_moment;
      moment_sum += moment_error.squaredNorm();
      ++with_moment;
    }
    row += f.num_residuals();
  }
  AppendSamples(residuals, *fit, per_measurement);
  fit->rms = std::sqrt(force_sum / static_cast<double>(readings_.size()));
  if (with_moment > 0) fit->rms_moment = std::sqrt(moment_sum / with_moment);
}

// ---------------------------------------------------------------------------------------------

SurfacePointSet::SurfacePointSet(std::string type, std::string label,
                                 std::vector<Eigen::Vector3d> points, double sigma)
    : Measurement(std::move(type), std::move(label)), points_(std::move(points)), sigma_(sigma) {
  if (points_.empty()) throw std::invalid_argument(this->label() + ": no points");
  if (!(sigma_ > 0.0)) throw std::invalid_argument(this->label() + ": sigma must be > 0");
}

bool SurfacePointSet::Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                               std::string* why) const {
  const int m = solved.num_parameters;
  const Eigen::Matrix3Xd& nodes = solved.poke->deformed_world;
  const int n = static_cast<int>(nodes.cols());
  // The closed ring as a polyline: node 0 repeated at the end (polyline vertex j is node j % n).
  Eigen::Matrix3Xd ring(3, n + 1);
  ring.leftCols(n) = nodes;
  ring.col(n) = nodes.col(0);
  int row = 0;
  for (const Eigen::Vector3d& q : points_) {
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
    for (int i = 0; i < 3; ++i) residuals[row + i] = (p[i] - q[i]) / sigma_;
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
        for (int i = 0; i < 3; ++i) jacobian[(row + i) * m + c] = dp[i] / sigma_;
      }
    }
    row += 3;
  }
  return true;
}

void SurfacePointSet::Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                                std::vector<MeasurementResidual>* per_measurement) const {
  const size_t first = per_measurement->size();
  AppendSamples(residuals, *fit, per_measurement);
  double sum = 0.0;
  for (size_t k = first; k < per_measurement->size(); ++k)
    sum += (*per_measurement)[k].error.squaredNorm();
  fit->rms = std::sqrt(sum / num_measurements());
}

}  // namespace rodfit
