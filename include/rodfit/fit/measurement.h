// One residual interface for every kind of measurement a fit case holds (docs/solvers.md,
// "Identification"): centre-line observations (markers, points, pixels, images), force and
// moment readings on held points, and surface points around a poke. The fit, its residual
// counts and covariance, the RMS table of the profile and the report all iterate one list of
// these per case, in the case's residual order: centre-line observations, then force
// observations, then surface point sets.
//
// A new measurement kind is one class here: its counts, its unit, which parts of the solved case
// it reads (the shape always; the held points' reactions; the poked section's ring) and its
// weighted residuals with their Jacobian by the fitted log-parameters.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rodfit/fit/fit.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"

namespace rodfit {

/// The equilibrium of one fit evaluation of a case, and its derivatives by the m fitted
/// log-parameters when a Jacobian is asked for (the d_ pointers are then set).
struct SolvedCase {
  const RodState* state = nullptr;
  /// Every held point's reaction (set when a measurement needs_reactions()).
  const std::vector<HeldReaction>* reactions = nullptr;
  /// The poked section's ring (set when a measurement needs_section()).
  const PokeResult* poke = nullptr;
  int num_parameters = 0;
  /// d x_flat / d log p: 3 (n + 1) x m, rows as observe/observations.h's VertexCoordinate.
  const Eigen::MatrixXd* d_x = nullptr;
  /// Per entry of `reactions`: d (force, moment) / d log p, 6 x m.
  const std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>>* d_reactions = nullptr;
  /// Per fitted parameter: d (ring node k, world) / d log p as a 3 x (nodes + 1) closed polyline
  /// (node 0 repeated at the end), as `poke->deformed_world`.
  const std::vector<Eigen::Matrix3Xd>* d_ring = nullptr;
};

class CaseMeasurement {
 public:
  virtual ~CaseMeasurement() = default;

  /// The experiment's type: markers3d, points3d, image_points, images, grasp_force, reaction,
  /// surface_points.
  const std::string& type() const { return type_; }
  /// e.g. "markers3d flat_markers.csv": names the entry in messages and tables.
  const std::string& label() const { return label_; }
  /// Of the misfit: "m", "px" or "N" (a moment's is "N m", ObservationFit::rms_moment).
  virtual const char* unit() const = 0;
  virtual int num_measurements() const = 0;
  virtual int num_residuals() const = 0;
  /// Residuals that carry noise: a closest-point residual lies perpendicular to its curve, so a
  /// 3-D point carries 2 of its 3 (Observation::num_noise_residuals).
  virtual int num_noise_residuals() const = 0;
  /// Rows of measurement k: the robust loss sees each measurement's residual vector whole.
  virtual int measurement_rows(int k) const = 0;
  /// Names measurement k in messages: the entry's label, or the reading's own (a haptic
  /// sample's "grasp_force log.csv t=1.25").
  virtual std::string measurement_label(int /*k*/) const { return label(); }
  virtual bool needs_reactions() const { return false; }
  virtual bool needs_section() const { return false; }

  /// Writes the weighted residuals (model - measured) / sigma, num_residuals() of them, and,
  /// when `jacobian` is given (row major, num_residuals() x solved.num_parameters), their
  /// derivatives by the log-parameters. False when the measurement cannot be evaluated on the
  /// solved case, with why in *why (a point behind a camera, a reading at a point not held).
  virtual bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                        std::string* why) const = 0;

  /// The misfit at the fit: fills `fit`'s rms (and rms_moment) in unit() from the shape and the
  /// weighted residuals without the robust loss; appends one MeasurementResidual per
  /// measurement that the report cannot recompute from the shape (forces, surface points).
  virtual void Summarise(const Mat3X& shape, const double* residuals, ObservationFit* fit,
                         std::vector<MeasurementResidual>* per_measurement) const = 0;

 protected:
  CaseMeasurement(std::string type, std::string label)
      : type_(std::move(type)), label_(std::move(label)) {}

 private:
  std::string type_, label_;
};

/// The case's measurements in residual order: its centre-line observations, its force readings
/// grouped by observation (consecutive readings of one entry), its surface point sets.
std::vector<std::shared_ptr<const CaseMeasurement>> CaseMeasurements(const FitCase& fit_case);

}  // namespace rodfit
