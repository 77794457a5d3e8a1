// The cost of one case of a fit (docs/solvers.md, "Identification"), internal to fit/: the
// fitted parameters and how they set the material, the robust loss as a residual transform, a
// case's residuals and exact Jacobian (CaseEvaluator: solve warm with the case's kept factor,
// then the case's measurements, measurement.h), and all cases as one Ceres block.
#pragma once

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <ceres/ceres.h>

#include "rodfit/fit/fit.h"
#include "rodfit/fit/measurement.h"
#include "rodfit/solve/reactions.h"
#include "rodfit/solve/sensitivity.h"
#include "rodfit/solve/statics.h"

namespace rodfit {
namespace fit_internal {

using Clock = std::chrono::steady_clock;

/// A fitted parameter: where it sits in FitInput::parameters and which stiffnesses it drives
/// (bend_stiffness drives B2 too when bend_stiffness_2 is absent: the isotropic tie).
struct Fitted {
  int input_index = 0;
  std::string name;
  std::vector<Stiffness> drives;  ///< rod stiffnesses it sets
  bool spring = false;            ///< a spring stiffness: drives the zones of `spring_zone_name`
  std::string spring_zone_name;   ///< "" for spring_stiffness, else the zone parameter
  int ring = 0;                   ///< 1: ring_bend_stiffness, 2: ring_stretch_stiffness
};

/// A fitted nuisance of one case (docs/solvers.md, "Nuisance parameters"), columns of the fit
/// after the material's with a zero-mean Gaussian prior of sigma per column:
/// - kRotation: a held frame's rotation vector phi [rad], R = Exp(phi) R_given about the held
///   point (3 columns);
/// - kPosition: a held point's offset [m] in world axes (3 columns; a clamp's frame moves with
///   its point);
/// - kGravity: the case's gravity turned by Exp(psi), psi = a b1 + b b2 [rad] perpendicular to
///   gravity (GravityTiltBasis; 2 columns).
struct Nuisance {
  enum class Kind { kRotation, kPosition, kGravity };
  Kind kind = Kind::kRotation;
  int case_index = 0;
  bool end_clamp = false;  ///< kRotation: the end clamp's frame, else the clamp's at s = 0
  /// kPosition: "clamp", "end_clamp", "end_pin", "pins[k]" or "grasp"; kGravity: "gravity".
  std::string held = "clamp";
  int pin = -1;            ///< kPosition of "pins[k]": k
  double sigma = 0.0;      ///< [rad] or [m]
  int first_column = 0;    ///< of its columns in the fit's parameter vector
  int size() const { return kind == Kind::kGravity ? 2 : 3; }
  std::string Name() const { return held; }
};

/// The nuisances of `in`, case by case (the clamp's rotation, the end clamp's, then the held
/// points' offsets: clamp, end clamp, end pin, pins, grasp; then gravity), their columns from
/// `first_column` on.
std::vector<Nuisance> Nuisances(const FitInput& in, int first_column);
/// Their number of columns.
int NuisanceColumns(const std::vector<Nuisance>& nuisances);

/// Exp(phi) (Rodrigues, exact at any angle; its Taylor series near 0) and the left Jacobian
/// J_l(phi): d Exp(phi) / d phi_k = [J_l(phi) e_k]x Exp(phi), i.e. a change of phi_k turns the
/// frame about the world axis J_l(phi) e_k.
Eigen::Matrix3d RotationExp(const Vec3& phi);
Eigen::Matrix3d RotationLeftJacobian(const Vec3& phi);

/// The two unit axes b1, b2 (columns) perpendicular to `gravity` that a gravity nuisance turns
/// it about: b1 the world axis least aligned with gravity, made perpendicular to it, and
/// b2 = b1 x g/|g|.
Eigen::Matrix<double, 3, 2> GravityTiltBasis(const Vec3& gravity);

/// The case's held frames and points moved by its nuisances' values in `x` (the fit's whole
/// vector).
LoadCase WithNuisances(const LoadCase& load_case, const std::vector<Nuisance>& own,
                       const double* x);
/// The case's gravity, turned by its gravity nuisance's value in `x` if it has one.
Vec3 GravityWithNuisances(const Vec3& gravity, const std::vector<Nuisance>& own, const double* x);

/// The prior of one nuisance as residuals value / sigma (one row per column) over the fit's
/// whole vector.
class NuisancePriorCost final : public ceres::CostFunction {
 public:
  NuisancePriorCost(const Nuisance& nuisance, int num_columns) : nuisance_(nuisance) {
    set_num_residuals(nuisance.size());
    mutable_parameter_block_sizes()->push_back(num_columns);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Nuisance nuisance_;
};

/// The fitted parameters of `in` in input order; throws std::invalid_argument for a parameter
/// the model does not have, a tie fitted apart, or springs and ring parameters without their
/// terms or observations.
std::vector<Fitted> FittedParameters(const FitInput& in);

/// The input's material with the fitted parameters at exp(logp).
Material MaterialAt(const FitInput& in, const std::vector<Fitted>& fitted, const double* logp);

/// The robust loss applied to one measurement's `dim` residuals and their Jacobian rows (`cols`
/// columns, row major; null: none) in place; a null loss leaves them.
void ApplyLoss(const ceres::LossFunction* loss, int dim, double* r, double* J, int cols);

/// The Ceres loss of `loss` at `scale` (null for kNone).
std::unique_ptr<ceres::LossFunction> MakeLoss(RobustLoss loss, double scale);

class CaseEvaluator {
 public:
  CaseEvaluator(const FitInput& in, int case_index, std::vector<Fitted> fitted,
                const ceres::LossFunction* loss);

  /// FitOptions::jacobian_of_fixed_parameters: also compute the fixed stiffnesses' columns.
  void ComputeFixedColumns(bool on) { fixed_columns_ = on; }

  /// The warm start: the state to start from before the first evaluation (the case's start,
  /// e.g. the previous case's solution at the start values).
  void SetWarmStart(const RodState& state) {
    std::lock_guard<std::mutex> lock(mutex_);
    warm_ = state;
    has_warm_ = true;
  }

  /// The state of the last accepted iterate (or the start), if any.
  std::optional<RodState> WarmState() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!has_warm_) return std::nullopt;
    return warm_;
  }

  int num_residuals() const { return num_residuals_; }
  /// The columns of the fit's parameter vector: the material's log-parameters, then every
  /// case's nuisances (Nuisances).
  int num_parameters() const { return num_columns_; }

  struct Timing {
    double solve = 0, jacobian = 0, observation = 0;
    int solves = 0;
  };
  Timing timing() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return timing_;
  }
  /// Why the last failed evaluation failed (empty if none did), and whether the data failed
  /// (an observation that cannot be evaluated on the solved shape) rather than the solve.
  std::string last_failure(bool* data = nullptr) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (data) *data = data_failure_;
    return last_failure_;
  }

  /// x: the fit's whole parameter vector (num_parameters()); residuals: num_residuals();
  /// jacobian (row major num_residuals x num_parameters()) optional.
  /// `final_state`, when given, receives the equilibrium (the report's poked section needs it).
  bool Evaluate(const double* logp, double* residuals, double* jacobian, Mat3X* shape,
                RodState* final_state = nullptr) const;

 private:
  // The label of the measurement that residual row i belongs to.
  std::string ResidualLabel(int i) const;
  bool AllFinite(const double* residuals, const double* jacobian) const;
  // The poked section's ring at `material` and, with `d_ring`, its nodes' derivatives by the
  // fitted ring parameters (SolvedCase::d_ring); false when it has no stable solution.
  bool SolveSection(const RodModel& model, const RodState& state, const Material& material,
                    PokeResult* poke, std::vector<Eigen::Matrix3Xd>* d_ring) const;
  // Evaluate's steps after the solve. The derivatives by the columns (log p and the nuisances)
  // of what the measurements read.
  struct Derivatives {
    Eigen::MatrixXd dx;  // vertex positions, 3 (n + 1) x columns
    Eigen::MatrixXd dq;  // free dofs (when a measurement reads the state)
    std::vector<CriticalTwistParameter> column_terms;  // what each column moves
    // Per measured holder: d(reaction), 6 x columns (force rows, then moment rows).
    std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> d_reactions;
  };
  bool Differentiate(const RodModel& model, const RodState& state, const StaticsWorkspace& ws,
                     const double* logp, Derivatives* d) const;
  // The unit energy terms whose gradients are the fitted stiffnesses' (owner: each one's
  // column), then with fixed_columns_ those of the stiffnesses not fitted.
  void UnitTerms(std::vector<EnergyTerms>* terms, std::vector<int>* owner) const;
  bool NuisanceSensitivities(const RodModel& model, const RodState& state,
                             const StaticsWorkspace& ws, const double* logp, Eigen::MatrixXd* dq,
                             std::vector<CriticalTwistParameter>* column_terms) const;
  // The measurements at the solved case, each through the loss; false (the failure recorded)
  // when one cannot be evaluated.
  bool EvaluateMeasurements(const SolvedCase& view, double* residuals, double* jacobian) const;

  const FitInput& in_;
  const FitCase& case_;
  const MeasurementList& measurements_;  // in residual order
  bool needs_reactions_ = false, needs_section_ = false, needs_state_ = false;
  std::vector<Fitted> fitted_;
  std::vector<Nuisance> own_nuisances_;  // this case's
  int num_columns_ = 0;
  // What each fitted column moves, in the critical twist's terms (SolvedCase::parameters).
  std::vector<CriticalTwistParameter> column_terms_;
  const ceres::LossFunction* loss_;
  int num_residuals_ = 0;
  mutable std::mutex mutex_;  // guards the warm start only; evaluation is otherwise pure
  mutable RodState warm_;
  mutable bool has_warm_ = false;
  mutable StaticsWorkspace workspace_;  // the kept factor of the warm state
  StaticsOptions statics_;
  bool fixed_columns_ = false;
  mutable Timing timing_;  // accumulated under mutex_ by Charge
  mutable std::string last_failure_;
  mutable bool data_failure_ = false;

  void Charge(double* bucket, Clock::time_point* t0) const {
    const Clock::time_point now = Clock::now();
    std::lock_guard<std::mutex> lock(mutex_);
    *bucket += std::chrono::duration<double>(now - *t0).count();
    *t0 = now;
  }
};

/// Every case as one residual block, the cases evaluated on `num_threads` threads, each writing
/// its own rows. Ceres, on one thread, then sums cost and gradient over the rows in their fixed
/// order, so results do not depend on the thread count or on which thread took which case
/// (with a block per case, Ceres' per-thread partial sums changed the last digits; docs/cli.md,
/// "Reproducible outputs").
class AllCasesCost final : public ceres::CostFunction {
 public:
  AllCasesCost(std::vector<const CaseEvaluator*> cases, int num_threads)
      : cases_(std::move(cases)), num_threads_(std::max(1, num_threads)) {
    int rows = 0;
    for (const CaseEvaluator* c : cases_) {
      first_row_.push_back(rows);
      rows += c->num_residuals();
    }
    set_num_residuals(rows);
    mutable_parameter_block_sizes()->push_back(cases_.empty() ? 0 : cases_[0]->num_parameters());
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  std::vector<const CaseEvaluator*> cases_;
  std::vector<int> first_row_;
  int num_threads_;
};

/// `full` over the first `m` parameters alone, the rest held at `held` (the material with the
/// nuisances at their priors' mean: the fit's first stage, fit.cc).
class MaterialOnlyCost final : public ceres::CostFunction {
 public:
  MaterialOnlyCost(std::unique_ptr<ceres::CostFunction> full, int m, std::vector<double> held)
      : full_(std::move(full)), m_(m), held_(std::move(held)) {
    set_num_residuals(full_->num_residuals());
    mutable_parameter_block_sizes()->push_back(m_);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int M = m_ + static_cast<int>(held_.size());
    std::vector<double> x(M);
    std::copy(parameters[0], parameters[0] + m_, x.begin());
    std::copy(held_.begin(), held_.end(), x.begin() + m_);
    const double* blocks[] = {x.data()};
    if (!jacobians || !jacobians[0]) return full_->Evaluate(blocks, residuals, nullptr);
    const int rows = num_residuals();
    std::vector<double> J(static_cast<size_t>(rows) * M);  // row-major, as Ceres writes it
    double* jac[] = {J.data()};
    if (!full_->Evaluate(blocks, residuals, jac)) return false;
    for (int r = 0; r < rows; ++r)
      std::copy(J.begin() + static_cast<size_t>(r) * M, J.begin() + static_cast<size_t>(r) * M + m_,
                jacobians[0] + static_cast<size_t>(r) * m_);
    return true;
  }

 private:
  std::unique_ptr<ceres::CostFunction> full_;
  int m_;
  std::vector<double> held_;
};

}  // namespace fit_internal
}  // namespace rodfit
