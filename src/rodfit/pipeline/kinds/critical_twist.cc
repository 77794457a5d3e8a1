// Observation kind `critical_twist` (docs/formats.md, "Critical twist entries"): the roll of the
// clamp at s = 0, about its own tangent, at which the case's equilibrium first loses stability (a
// wire hanging as a loop between two clamps snaps out of its plane), as a lab records it:
// `{type: critical_twist, value_deg: 812, sigma_deg: 5}`, or a file `roll_deg` of repeated
// trials. The model's critical roll is solve/critical_twist.h's CriticalTwist from the case's
// solved (untwisted) equilibrium, followed towards `max_roll_deg` (its sign the direction; a
// positive roll turns the clamp's d1 towards d2); its exact derivative by every fitted parameter
// is CriticalTwistDerivatives' (at a fold from the null vector of the Hessian, at a bifurcation
// from the zero eigenvalue along the path). A roll stays the observed quantity in radians inside
// the fit: the residual is (model - observed) / sigma. No loss of stability within the range is
// a defined outcome: the model's roll is the range's end (a residual with no derivative: pushing
// the parameters nearer cannot be told apart from staying stable) and the fit's summary warns.
// The twist stiffness GJ is what this measures: with a shape observation of the same loop
// (which fixes B and the clamp angles) the critical roll, ~ B / GJ, makes GJ identifiable.
// Static scenes only.
#include <cmath>
#include <limits>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

constexpr char kName[] = "critical_twist";
constexpr double kDegree = M_PI / 180.0;  // [rad/deg]
constexpr char kValue[] = "value_deg";
constexpr char kSigma[] = "sigma_deg";
constexpr char kMaxRoll[] = "max_roll_deg";
/// [deg] the search range when the entry gives none: four turns, beyond the 450–1000° that
/// loops of surgical wire reach.
constexpr double kDefaultMaxRollDeg = 1440.0;
/// [deg] the largest range an entry may ask for: each degree costs continuation steps.
constexpr double kLargestRollDeg = 36000.0;

void Keys(EntryKeys* k, ObservationSpec* o) {
  const LoadCase& c = k->load_case();
  k->Check(c.end_clamp.has_value() && c.end_clamp->normal.has_value(), "type",
           "a critical twist needs an end_clamp with a normal (the rod held by two clamps)");
  k->Check(c.tip_moment.isZero() && c.tip_moment_follower.isZero() && c.point_moments.empty(),
           "type", "a critical twist is computed without moment loads");
  k->Check(!c.grasp.has_value() && !c.poke.has_value(), "type",
           "a critical twist is computed without a grasp or a poke");
  k->Check(!c.symmetry.has_value(), "type",
           "a critical twist leaves the case's plane: remove the case's symmetry");
  double& value = o->kind_values[kValue];
  double& max_roll = o->kind_values[kMaxRoll];
  value = std::numeric_limits<double>::quiet_NaN();
  max_roll = std::numeric_limits<double>::quiet_NaN();
  k->Exclusive(kValue, "file");
  k->Number(kValue, &value, -kLargestRollDeg, kLargestRollDeg);  // [deg]
  k->Path("file", &o->file, false);                              // CSV roll_deg: repeated trials
  k->Positive(kSigma, &o->kind_values[kSigma], true);            // [deg]
  k->Number(kMaxRoll, &max_roll, -kLargestRollDeg, kLargestRollDeg);  // [deg], signed
  k->Integer("count", &o->count, 1, 1000);  // synth: trials written to the file
  k->Check(!std::isnan(value) || !o->file.empty(), "type",
           "a critical_twist entry needs value_deg (the observed roll [deg]) or a file");
  k->Check(!(value == 0.0), kValue, "the critical roll must not be 0");
  k->Check(!(max_roll == 0.0), kMaxRoll, "the search range must not be 0");
  // The range's direction is the observation's; its default four turns that way.
  if (std::isnan(max_roll))
    max_roll = (std::isnan(value) || value > 0.0 ? 1.0 : -1.0) * kDefaultMaxRollDeg;
  k->Check(std::isnan(value) || value * max_roll > 0.0, kMaxRoll,
           "the search range must point the way of value_deg (the same sign)");
  k->Check(std::isnan(value) || std::abs(value) < std::abs(max_roll), kMaxRoll,
           "the search range must reach beyond value_deg");
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

// The continuation's options of an entry: the signed range.
CriticalTwistOptions OptionsOf(double max_roll_deg) {
  CriticalTwistOptions o;
  o.max_roll_rad = max_roll_deg * kDegree;
  return o;
}

// The entry's trials: one residual each, (model - observed) / sigma in radians.
class CriticalTwistReadings final : public Measurement {
 public:
  CriticalTwistReadings(std::string label, std::vector<double> roll_deg, double sigma_deg,
                        double max_roll_deg)
      : Measurement(kName, std::move(label)),
        roll_deg_(std::move(roll_deg)),
        sigma_deg_(sigma_deg),
        max_roll_deg_(max_roll_deg) {
    if (roll_deg_.empty()) throw std::invalid_argument("critical_twist: no observed roll");
    if (!(sigma_deg_ > 0.0) || !std::isfinite(sigma_deg_))
      throw std::invalid_argument("critical_twist: sigma_deg must be positive and finite");
    if (!(max_roll_deg_ != 0.0) || !std::isfinite(max_roll_deg_))
      throw std::invalid_argument("critical_twist: max_roll_deg must be finite and not 0");
  }

  const char* unit() const override { return "deg"; }
  int num_measurements() const override { return static_cast<int>(roll_deg_.size()); }
  int num_residuals() const override { return num_measurements(); }
  int num_noise_residuals() const override { return num_measurements(); }
  int measurement_rows(int) const override { return 1; }
  bool needs_state() const override { return true; }
  double sample_sigma(int) const override { return sigma_deg_; }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    if (!solved.model || !solved.state) {
      *why = "a critical twist needs the solved state (static cases only)";
      return false;
    }
    const CriticalTwistResult r =
        CriticalTwist(*solved.model, *solved.state, OptionsOf(max_roll_deg_));
    if (!r.ok) {
      *why = "the critical twist: " + r.message;
      return false;
    }
    const double inv_sigma = 1.0 / (sigma_deg_ * kDegree);
    // kNoneInRange: the roll reached, the range's end (CriticalTwistResult::critical_roll_rad).
    for (int k = 0; k < num_measurements(); ++k)
      residuals[k] = (r.critical_roll_rad - roll_deg_[k] * kDegree) * inv_sigma;
    if (!jacobian) return true;
    const int m = solved.num_parameters;
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(
        jacobian, num_residuals(), m);
    if (r.kind == TwistInstability::kNoneInRange) {
      out.setZero();
      return true;
    }
    if (!solved.parameters || static_cast<int>(solved.parameters->size()) != m) {
      *why = "the fitted parameters' terms are not given (SolvedCase::parameters)";
      return false;
    }
    Eigen::VectorXd d_roll;
    std::string derivative_why;
    if (!CriticalTwistDerivatives(*solved.model, r, *solved.parameters, &d_roll,
                                  &derivative_why)) {
      *why = "the critical twist's derivative: " + derivative_why;
      return false;
    }
    for (int k = 0; k < num_measurements(); ++k) out.row(k) = d_roll.transpose() * inv_sigma;
    return true;
  }

  // The RMS [deg]; a model stable over the whole range (its roll at the range's end) warned of.
  void Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override {
    double sum = 0.0;
    for (int k = 0; k < num_measurements(); ++k) {
      const double e = residuals[k] * sigma_deg_;
      sum += e * e;
    }
    fit->rms = std::sqrt(sum / num_measurements());
    const double model_deg = roll_deg_[0] + residuals[0] * sigma_deg_;
    if (std::abs(model_deg) >= std::abs(max_roll_deg_) * (1.0 - 1e-9))
      fit->warning = "the model stays stable up to max_roll_deg " + Short(max_roll_deg_) +
                     " (no critical twist in range): its residual is taken at the range's end";
    AppendSamples(residuals, *fit, per_measurement);
  }

 private:
  std::vector<double> roll_deg_;  ///< [deg] the trials
  double sigma_deg_;
  double max_roll_deg_;  ///< [deg] signed search range
};

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const double max_roll = spec.kind_values.at(kMaxRoll);
  std::vector<double> rolls;
  if (spec.file.empty()) {
    rolls.push_back(spec.kind_values.at(kValue));
  } else {
    const CsvTable t = CsvTable::Read(spec.file);
    const auto roll = t.Column("roll_deg");
    for (int r = 0; r < t.num_rows(); ++r) {
      if (!(roll[r] * max_roll > 0.0) || !(std::abs(roll[r]) < std::abs(max_roll)))
        throw InputError(t.name(), t.line(r), "roll_deg",
                         "the critical roll " + Short(roll[r]) +
                             " deg must lie between 0 and max_roll_deg " + Short(max_roll));
      rolls.push_back(roll[r]);
    }
    if (rolls.empty()) throw InputError(spec.file, 0, "", "no rows");
  }
  fit_case->measurements.push_back(std::make_shared<CriticalTwistReadings>(
      c.label(), std::move(rolls), spec.kind_values.at(kSigma), max_roll));
}

// The solved case's critical roll, `count` trials (default 1) with Gaussian noise of sigma_deg.
std::string Synthesize(const SynthEntry& entry, std::string* report) {
  const ObservationSpec& spec = *entry.spec;
  const CaseSolution& solution = *entry.solution;
  const double max_roll = spec.kind_values.at(kMaxRoll);
  const CriticalTwistResult r =
      CriticalTwist(*solution.model, solution.state, OptionsOf(max_roll));
  if (!r.ok) entry.Fail("case " + entry.CaseName() + ": the critical twist: " + r.message);
  if (r.kind == TwistInstability::kNoneInRange)
    entry.Fail("case " + entry.CaseName() + ": no loss of stability up to max_roll_deg " +
               Short(max_roll));
  const int n = spec.count > 0 ? spec.count : 1;
  std::vector<Eigen::Matrix<double, 1, 1>> roll(n);
  for (auto& v : roll) v(0) = r.critical_roll_rad / kDegree;
  AddNoise(entry, spec.kind_values.at(kSigma), &roll);
  std::string out = "roll_deg\n";
  for (const auto& v : roll) out += FormatDouble(v(0)) + "\n";
  *report = Summary(entry, n, 0, 0);
  return out;
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kCriticalTwist,
    (EntryFormat{kName,
                 "the clamp's roll at which the loop loses stability: value_deg, or a file "
                 "roll_deg [deg] of trials",
                 Keys, /*may_move=*/false}),
    Build, nullptr, Synthesize, nullptr, ReportView::kValue);

}  // namespace rodfit
