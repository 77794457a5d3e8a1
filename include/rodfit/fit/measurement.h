// One residual interface for every kind of measurement (docs/solvers.md, "Identification"):
// centre-line observations (markers, points, pixels, images, roll markers), force and moment
// readings on held points, and surface points around a poke, in a static case or at one frame of
// a moving case. A static fit case holds one list of these (FitCase::measurements); a moving
// case's observation sequence one per frame (fit/motion_fit.h). The fit, its residual counts and
// covariance, the RMS table of the profile and the report all iterate that list.
//
// A new measurement kind is one class of this interface (its counts, its unit, which parts of the
// solved rod it reads, its weighted residuals with their Jacobian by the fitted log-parameters)
// in the file of its observation kind (rodfit/pipeline/observation_kind.h), which also reads it
// from its file, synthesizes it and says how the report shows it.
#pragma once

#include <algorithm>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "rodfit/model/rod.h"
#include "rodfit/observe/observations.h"
#include "rodfit/solve/critical_twist.h"
#include "rodfit/solve/poke.h"
#include "rodfit/solve/reactions.h"

namespace rodfit {

/// What a measurement reads of the solved rod: a static case's equilibrium, or a moving case's
/// state at a frame's time; and its derivatives by the m fitted log-parameters when a Jacobian
/// is asked for (the d_ pointers are then set).
struct SolvedCase {
  const Mat3X* x = nullptr;  ///< the vertices [m], always set
  /// The model and its whole state (twist angles, reference frames): static cases only, for a
  /// measurement that needs_state().
  const RodModel* model = nullptr;
  const RodState* state = nullptr;
  /// Every held point's reaction (set when a measurement needs_reactions()).
  const std::vector<HeldReaction>* reactions = nullptr;
  /// The poked section's ring (set when a measurement needs_section()).
  const PokeResult* poke = nullptr;
  int num_parameters = 0;
  /// d x_flat / d log p: 3 (n + 1) x m, rows as observe/observations.h's VertexCoordinate.
  const Eigen::MatrixXd* d_x = nullptr;
  /// d q / d log p in the free-dof ordering (RodModel::VertexDof, TwistDof): needs_state().
  const Eigen::MatrixXd* d_q = nullptr;
  /// Per entry of `reactions`: d (force, moment) / d log p, 6 x m.
  const std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>>* d_reactions = nullptr;
  /// Per fitted parameter: d (ring node k, world) / d log p as a 3 x (nodes + 1) closed polyline
  /// (node 0 repeated at the end), as `poke->deformed_world`.
  const std::vector<Eigen::Matrix3Xd>* d_ring = nullptr;
  /// Per fitted parameter: what it moves, in the critical twist's terms (the stiffnesses a log
  /// column scales together, a spring zone; a ring parameter scales none): set by the static
  /// fit with d_q, for a measurement that differentiates a quantity of the model other than the
  /// state (a critical twist, solve/critical_twist.h).
  const std::vector<CriticalTwistParameter>* parameters = nullptr;
};

/// The misfit of one observation entry of a case at the fit.
struct ObservationFit {
  int case_index = 0;            ///< into FitInput::cases
  std::string case_name;
  std::string label;
  std::string type;
  int num_measurements = 0;
  double rms = 0.0;  ///< [m], [px] or [N]: the RMS of the residual vector's norm
  std::string unit;  ///< of rms: m, px or N
  /// Reactions with moments: the RMS of the moment residual's norm [N m] (NaN without).
  double rms_moment = std::numeric_limits<double>::quiet_NaN();
  /// Roll markers: the RMS of the roll error [deg] (NaN without).
  double rms_roll = std::numeric_limits<double>::quiet_NaN();
  /// What the fit's user must know about this entry at the fit, or empty (a critical twist whose
  /// model stays stable over its whole search range).
  std::string warning;
};

/// One measurement's residual at the fit that the report cannot recompute from the fitted
/// centre-line (a force or moment reading, a surface point, a roll): the error vector (model
/// minus measurement) in its unit and the sigma it was weighted with, for residuals.csv.
struct MeasurementResidual {
  int case_index = 0;
  std::string case_name;
  std::string observation;  ///< the entry's label, as in ObservationFit::label
  std::string unit;         ///< "N", "N m", "m" or "deg"
  int measurement = 0;      ///< index within the entry (per unit)
  Eigen::Vector3d error = Eigen::Vector3d::Zero();
  double sigma = 1.0;
  int components = 3;       ///< of `error` that are the measurement's (a roll's 1)
};

class Measurement {
 public:
  virtual ~Measurement() = default;

  /// The observation kind (the entry's `type`): markers3d, points3d, image_points, images,
  /// grasp_force, reaction, surface_points, roll_markers, critical_twist.
  const std::string& type() const { return type_; }
  /// e.g. "markers3d flat_markers.csv": names the entry in messages and tables.
  const std::string& label() const { return label_; }
  /// Of the misfit: "m", "px" or "N" (a moment's is "N m", ObservationFit::rms_moment).
  virtual const char* unit() const = 0;
  virtual int num_measurements() const = 0;
  virtual int num_residuals() const = 0;
  /// Residuals that carry noise: a closest-point residual lies perpendicular to its curve, so a
  /// 3-D point carries 2 of its 3 (observe/observations.h).
  virtual int num_noise_residuals() const = 0;
  /// Rows of measurement k: the robust loss sees each measurement's residual vector whole.
  virtual int measurement_rows(int k) const = 0;
  /// Names measurement k in messages: the entry's label, or the reading's own (a haptic
  /// sample's "grasp_force log.csv t=1.25").
  virtual std::string measurement_label(int /*k*/) const { return label(); }
  /// The rod's vertex count it was built for (SolvedCase::x must have as many), or -1 when it
  /// reads no vertex (forces, surface points).
  virtual int num_vertices() const { return -1; }
  /// What it reads of the solved rod beyond the vertices (SolvedCase).
  virtual bool needs_state() const { return false; }
  virtual bool needs_reactions() const { return false; }
  virtual bool needs_section() const { return false; }
  /// Its model reads the held frames themselves, not only the solved state (a roll counted from
  /// the clamp's normal): its Jacobian by a fitted held frame's turn is not modelled, so a case
  /// with such a nuisance refuses it.
  virtual bool reads_held_frames() const { return false; }
  /// Reads nothing but the vertices: the report can evaluate it on a fitted centre-line alone.
  bool reads_vertices_only() const {
    return !needs_state() && !needs_reactions() && !needs_section();
  }

  /// Writes the weighted residuals (model - measured) / sigma, num_residuals() of them, and,
  /// when `jacobian` is given (row major, num_residuals() x solved.num_parameters), their
  /// derivatives by the log-parameters. False when the measurement cannot be evaluated on the
  /// solved rod, with why in *why (a point behind a camera, a reading at a point not held).
  virtual bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                        std::string* why) const = 0;

  /// The errors as the tables list them (residuals.csv, a sequence's samples): num_samples()
  /// vectors, sample k of sample_rows(k) <= 3 residual rows in sample_unit(k), weighted by
  /// sample_sigma(k), consecutive in the residuals. A measurement is one sample, except a force
  /// reading with a moment, whose force and moment are two.
  virtual int num_samples() const { return num_measurements(); }
  virtual int sample_rows(int k) const { return measurement_rows(k); }
  virtual double sample_sigma(int k) const = 0;
  virtual const char* sample_unit(int /*k*/) const { return unit(); }

  /// The misfit at the fit: fills `fit`'s rms (and rms_moment, rms_roll) from the shape and the
  /// weighted residuals without the robust loss; appends one MeasurementResidual per sample
  /// unless the measurement needs only the vertices (the report recomputes those from the
  /// fitted centre-line).
  virtual void Summarise(const Mat3X& shape, const double* residuals, ObservationFit* fit,
                         std::vector<MeasurementResidual>* per_measurement) const = 0;

 protected:
  Measurement(std::string type, std::string label)
      : type_(std::move(type)), label_(std::move(label)) {}
  /// Appends the samples of `residuals` as MeasurementResiduals, numbered per unit.
  void AppendSamples(const double* residuals, const ObservationFit& fit,
                     std::vector<MeasurementResidual>* per_measurement) const;

 private:
  std::string type_, label_;
};

using MeasurementList = std::vector<std::shared_ptr<const Measurement>>;

/// A centre-line observation model of observe/observations.h (markers, points, pixels) as a
/// measurement: its closed-form d r / d x chained with the vertices' sensitivities d x / d log p.
template <class Model>
class ShapeMeasurement final : public Measurement {
 public:
  ShapeMeasurement(std::string type, std::string label, Model model)
      : Measurement(std::move(type), std::move(label)), model_(std::move(model)) {}

  const Model& model() const { return model_; }
  int num_vertices() const override { return model_.num_vertices(); }
  const char* unit() const override { return model_.unit(); }
  int num_measurements() const override { return model_.num_measurements(); }
  int num_residuals() const override { return model_.num_residuals(); }
  int num_noise_residuals() const override { return model_.num_noise_residuals(); }
  int measurement_rows(int) const override {
    return model_.num_residuals() / std::max(1, model_.num_measurements());
  }
  double sample_sigma(int) const override { return model_.sigma(); }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    VecX r;
    VertexJacobian J;
    if (!model_.Evaluate(*solved.x, &r, jacobian ? &J : nullptr)) {
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
    model_.RmsError(shape, &fit->rms);
  }

 private:
  Model model_;
};

/// A ShapeMeasurement of `model` (for inputs made by hand: tests, benchmarks, examples).
template <class Model>
std::shared_ptr<const Measurement> MakeShapeMeasurement(std::string type, std::string label,
                                                        Model model) {
  return std::make_shared<ShapeMeasurement<Model>>(std::move(type), std::move(label),
                                                   std::move(model));
}

/// The model of a ShapeMeasurement<Model>, or null when `m` is another measurement.
template <class Model>
const Model* ModelOf(const Measurement& m) {
  const auto* shape = dynamic_cast<const ShapeMeasurement<Model>*>(&m);
  return shape ? &shape->model() : nullptr;
}

/// A measured force (and optionally moment) on a holder of the case: the instrument at its
/// grasp (a quasi-static haptic sample), a pin, an end clamp or end pin, or the clamp.
struct ForceMeasurement {
  Vec3 force = Vec3::Zero();  ///< the force the rod exerts on the holder [N]
  double sigma = 1.0;         ///< [N]
  std::string label;          ///< e.g. "grasp_force drag_log.csv t=1.25"
  std::string point = "grasp";  ///< HeldReaction::point: clamp, end_clamp, end_pin, pins[k], grasp
  std::optional<Vec3> moment;   ///< [N m] about the held point, for clamps
  double sigma_moment = 1.0;    ///< [N m]
  /// [s] the haptic log's time of a `grasp_force` sample (for the report's force-versus-time
  /// plot); NaN for readings without a time.
  double time = std::numeric_limits<double>::quiet_NaN();
  int num_residuals() const { return moment ? 6 : 3; }
};

/// The readings of one force entry (a haptic log's sample, a reaction log's rows, one frame of a
/// reaction sequence): each the force, and at clamps the moment, on one held point, against the
/// solved rod's reactions.
class ForceReadings final : public Measurement {
 public:
  /// Throws std::invalid_argument for no readings.
  ForceReadings(std::string type, std::string label, std::vector<ForceMeasurement> readings);

  const std::vector<ForceMeasurement>& readings() const { return readings_; }
  const char* unit() const override { return "N"; }
  int num_measurements() const override { return static_cast<int>(readings_.size()); }
  int num_residuals() const override { return num_residuals_; }
  int num_noise_residuals() const override { return num_residuals_; }
  int measurement_rows(int k) const override { return readings_[k].num_residuals(); }
  std::string measurement_label(int k) const override { return readings_[k].label; }
  bool needs_reactions() const override { return true; }
  // Samples: each reading's force, then its moment when it has one.
  int num_samples() const override { return num_samples_; }
  int sample_rows(int) const override { return 3; }
  double sample_sigma(int k) const override;
  const char* sample_unit(int k) const override;

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override;
  /// Forces in N and moments in N m, apart.
  void Summarise(const Mat3X& shape, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override;

 private:
  // Reading and whether sample k is its moment.
  std::pair<int, bool> SampleOf(int k) const;
  std::vector<ForceMeasurement> readings_;
  int num_residuals_ = 0, num_samples_ = 0;
};

/// Points tracked on the tissue surface around a poke, in the poked cross-section's plane (a
/// laser profile or tracked dots on the dented section) [m]. Residual per point: the 3-D vector
/// from the point to its closest point on the deformed ring (the closed polyline of
/// PokeResult::deformed_world) over sigma, with observe/observations.h's foot rules. Only ring
/// parameters move the ring (the fit refuses rod parameters together with surface points), so
/// the Jacobian is the ring's d nodes / d log k chained through the foot.
class SurfacePointSet final : public Measurement {
 public:
  /// Throws std::invalid_argument for no points or a sigma [m] that is not positive.
  SurfacePointSet(std::string type, std::string label, std::vector<Eigen::Vector3d> points,
                  double sigma);

  const std::vector<Eigen::Vector3d>& points() const { return points_; }
  const char* unit() const override { return "m"; }
  int num_measurements() const override { return static_cast<int>(points_.size()); }
  int num_residuals() const override { return 3 * num_measurements(); }
  int num_noise_residuals() const override { return 2 * num_measurements(); }
  int measurement_rows(int) const override { return 3; }
  double sample_sigma(int) const override { return sigma_; }
  bool needs_section() const override { return true; }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override;
  /// The distance to the ring [m].
  void Summarise(const Mat3X& shape, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override;

 private:
  std::vector<Eigen::Vector3d> points_;  ///< [m], world
  double sigma_ = 1.0;                   ///< [m]
};

}  // namespace rodfit
