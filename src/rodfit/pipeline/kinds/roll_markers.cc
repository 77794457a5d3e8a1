// Observation kind `roll_markers` (docs/formats.md, "Observation entries"): markers on a stripe
// painted along the thread, file `s,x,y,z,roll_deg`: each the marker's position [m] at arc length
// s, as `markers3d`, and the roll of the material frame there [deg] — the angle about the tangent
// from the clamp's normal carried along the centre-line without twisting (parallel transport) to
// the stripe's direction d1, 0 at the clamp, counted in whole turns (it may exceed 360°). The roll
// is what makes the torsion stiffness GJ identifiable from a 3-D shape: an isotropic rod's
// centre-line under given end loads does not depend on GJ (its twist moment is set by the loads),
// but its twist angle does.
//
// The model (DER, Bergou et al. 2008/2010): edge j's material director d1 is its reference
// director turned by theta_j, and the reference twist m_i at vertex i is the angle between the
// transport of edge i-1's reference director and edge i's (the clamp's frame before edge 0, the
// end clamp's ghost edge after edge n-1). The roll of edge j is
//   phi_j = theta_j + sum_{i <= j} m_i,
// the discrete integral of the torsion (theta_i - theta_{i-1} + m_i) from the clamp (whose ghost
// edge is untwisted). phi(s) is linear in s between the clamp (s = 0, phi = 0), the edges'
// midpoints and, with an end clamp, its ghost at s = L; over the last half edge of a free end it
// continues the last midpoints' line (a uniformly twisted rod rolls linearly to its end). Its exact
// derivative: d theta_j directly, and d m_i = kb_i . (dt_{i-1} + dt_i) / 2 with the curvature
// binormal kb_i = 2 t_{i-1} x t_i / (1 + t_{i-1} . t_i) and dt_k = P_k de_k / |e_k| (the reference
// frames transported in time, as the solver's; the clamp's and end clamp's tangents are fixed).
// Static scenes only: a moving case's runs sample the vertices, not the twist angles.
#include <cmath>

#include "rodfit/io/errors.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/synth/synth_entry.h"

namespace rodfit {
namespace {

constexpr char kName[] = "roll_markers";
constexpr double kDegree = M_PI / 180.0;  // [rad/deg]
constexpr char kSigmaRoll[] = "sigma_roll";

void Keys(EntryKeys* k, ObservationSpec* o) {
  k->Check(!k->load_case().symmetry.has_value(), "type",
           "roll markers are fitted on the whole rod: remove the case's symmetry");
  k->Path("file", &o->file, true);
  k->Positive("sigma", &o->sigma, true);                       // [m] of the positions
  k->Positive(kSigmaRoll, &o->kind_values[kSigmaRoll], true);  // [deg] of the roll
  k->Exclusive("s", "count");
  k->ArcLengths("s", &o->s);                       // synth: the markers' arc lengths
  k->Integer("count", &o->count, 1, kMaxSamples);  // synth: markers evenly spaced
}

#ifndef RODFIT_ENTRY_FORMATS_ONLY  // what the kind does (observation_kind.h)

// Where phi(s) is interpolated: node -1 is the clamp (phi = 0), node j < n edge j's midpoint, node
// n the end clamp's ghost; phi(s) = (1 - a) phi_node + a phi_{node + 1} (a > 1 past the last
// midpoint of a free end).
struct RollLocation {
  int node = -1;
  double a = 0.0;
};

// The interpolation nodes' arc lengths: the clamp, the edges' midpoints, the ghost at L.
std::vector<double> NodeArcLengths(const std::vector<double>& vertex_s, bool ghost) {
  std::vector<double> nodes = {0.0};
  for (size_t j = 0; j + 1 < vertex_s.size(); ++j)
    nodes.push_back(0.5 * (vertex_s[j] + vertex_s[j + 1]));
  if (ghost) nodes.push_back(vertex_s.back());
  return nodes;
}

RollLocation LocateRoll(const std::vector<double>& nodes, double s) {
  // nodes[k] is node k - 1; the last segment also takes the s beyond it.
  size_t k = 0;
  while (k + 2 < nodes.size() && s >= nodes[k + 1]) ++k;
  return {static_cast<int>(k) - 1, (s - nodes[k]) / (nodes[k + 1] - nodes[k])};
}

// The unit tangent of edge j of a state (the clamp's before edge 0, the ghost's after the last).
Vec3 Tangent(const RodModel& model, const RodState& state, int j) {
  if (j < 0) return state.clamp_t;
  if (j >= model.num_edges()) return state.end_t;
  return state.e.col(j).normalized();
}

// phi_j of every node j = 0..n-1 (and n with an end ghost).
std::vector<double> RollOfEdges(const RodModel& model, const RodState& state) {
  const int n = model.num_edges();
  const bool ghost = model.has_end_ghost();
  std::vector<double> phi;
  double twist = 0.0;  // sum of the reference twists so far
  for (int j = 0; j < n + (ghost ? 1 : 0); ++j) {
    twist += state.ref_twist[j];
    phi.push_back((j < n ? state.theta[j] : state.end_theta) + twist);
  }
  return phi;
}

double RollAt(const std::vector<double>& phi, const RollLocation& at) {
  const double lo = at.node < 0 ? 0.0 : phi[at.node];
  return (1.0 - at.a) * lo + at.a * phi[at.node + 1];
}

// d phi_j / d log p of every node, from the sensitivities of the vertices and twist angles:
// rows j, m columns.
Eigen::MatrixXd RollDerivatives(const RodModel& model, const RodState& state,
                                const Eigen::MatrixXd& d_x, const Eigen::MatrixXd& d_q) {
  const int n = model.num_edges();
  const bool ghost = model.has_end_ghost();
  const int m = static_cast<int>(d_q.cols());
  Eigen::MatrixXd out(n + (ghost ? 1 : 0), m);
  Eigen::RowVectorXd twist = Eigen::RowVectorXd::Zero(m);  // d sum m_i
  auto dx = [&](int i) { return d_x.middleRows(3 * i, 3); };
  for (int i = 0; i < out.rows(); ++i) {
    const Vec3 te = Tangent(model, state, i - 1), tf = Tangent(model, state, i);
    const Vec3 kb = 2.0 * te.cross(tf) / (1.0 + te.dot(tf));
    if (i >= 1) twist += kb.transpose() * (dx(i) - dx(i - 1)) / (2.0 * state.e.col(i - 1).norm());
    if (i < n) twist += kb.transpose() * (dx(i + 1) - dx(i)) / (2.0 * state.e.col(i).norm());
    out.row(i) = d_q.row(RodModel::TwistDof(i)) + twist;
  }
  return out;
}

// The entry's markers: positions (Markers3dObservation) and the roll at each, 4 residual rows
// per marker: x, y, z over sigma, then the roll over sigma_roll.
class RollMarkers final : public Measurement {
 public:
  RollMarkers(std::string label, const std::vector<double>& vertex_s, bool ghost,
              std::vector<Marker3d> markers, std::vector<double> roll_deg, double sigma,
              double sigma_roll_deg)
      : Measurement(kName, std::move(label)),
        positions_(vertex_s, markers, sigma),
        roll_(std::move(roll_deg)),
        sigma_roll_deg_(sigma_roll_deg) {
    const std::vector<double> nodes = NodeArcLengths(vertex_s, ghost);
    for (const Marker3d& marker : markers) at_.push_back(LocateRoll(nodes, marker.s));
    if (!(sigma_roll_deg_ > 0.0) || !std::isfinite(sigma_roll_deg_))
      throw std::invalid_argument("roll_markers: sigma_roll must be positive and finite");
    for (size_t k = 0; k < roll_.size(); ++k)
      if (!std::isfinite(roll_[k]))
        throw std::invalid_argument("roll_markers: marker " + std::to_string(k) +
                                    ": non-finite roll");
  }

  const char* unit() const override { return "m"; }
  int num_vertices() const override { return positions_.num_vertices(); }
  int num_measurements() const override { return positions_.num_measurements(); }
  int num_residuals() const override { return 4 * num_measurements(); }
  int num_noise_residuals() const override { return num_residuals(); }
  int measurement_rows(int) const override { return 4; }
  bool needs_state() const override { return true; }
  bool reads_held_frames() const override { return true; }  // phi counts from the clamp's d1
  // Samples: each marker's position [m], then its roll [deg].
  int num_samples() const override { return 2 * num_measurements(); }
  int sample_rows(int k) const override { return k % 2 == 0 ? 3 : 1; }
  double sample_sigma(int k) const override {
    return k % 2 == 0 ? positions_.sigma() : sigma_roll_deg_;
  }
  const char* sample_unit(int k) const override { return k % 2 == 0 ? "m" : "deg"; }

  bool Evaluate(const SolvedCase& solved, double* residuals, double* jacobian,
                std::string* why) const override {
    VecX r;
    VertexJacobian J;
    if (!positions_.Evaluate(*solved.x, &r, jacobian ? &J : nullptr)) {
      *why = "non-finite vertices";
      return false;
    }
    const std::vector<double> phi = RollOfEdges(*solved.model, *solved.state);
    const double inv_sigma = 1.0 / (sigma_roll_deg_ * kDegree);
    const int M = num_measurements();
    for (int k = 0; k < M; ++k) {
      for (int i = 0; i < 3; ++i) residuals[4 * k + i] = r[3 * k + i];
      residuals[4 * k + 3] = (RollAt(phi, at_[k]) - roll_[k] * kDegree) * inv_sigma;
    }
    if (jacobian) {
      const int m = solved.num_parameters;
      const Eigen::MatrixXd Jp = J.Multiply(*solved.d_x);
      const Eigen::MatrixXd d_phi =
          RollDerivatives(*solved.model, *solved.state, *solved.d_x, *solved.d_q);
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> out(
          jacobian, num_residuals(), m);
      for (int k = 0; k < M; ++k) {
        out.middleRows(4 * k, 3) = Jp.middleRows(3 * k, 3);
        const RollLocation& at = at_[k];
        Eigen::RowVectorXd d = Eigen::RowVectorXd::Zero(m);
        if (at.node >= 0) d += (1.0 - at.a) * d_phi.row(at.node);
        d += at.a * d_phi.row(at.node + 1);
        out.row(4 * k + 3) = d * inv_sigma;
      }
    }
    return true;
  }

  // The positions' RMS [m] and the roll's [deg].
  void Summarise(const Mat3X&, const double* residuals, ObservationFit* fit,
                 std::vector<MeasurementResidual>* per_measurement) const override {
    double position_sum = 0.0, roll_sum = 0.0;
    for (int k = 0; k < num_measurements(); ++k) {
      for (int i = 0; i < 3; ++i) {
        const double e = residuals[4 * k + i] * positions_.sigma();
        position_sum += e * e;
      }
      const double e = residuals[4 * k + 3] * sigma_roll_deg_;
      roll_sum += e * e;
    }
    fit->rms = std::sqrt(position_sum / num_measurements());
    fit->rms_roll = std::sqrt(roll_sum / num_measurements());
    AppendSamples(residuals, *fit, per_measurement);
  }

 private:
  Markers3dObservation positions_;
  std::vector<double> roll_;  ///< [deg] per marker
  std::vector<RollLocation> at_;
  double sigma_roll_deg_;
};

void Build(const KindContext& c, FitCase* fit_case, std::vector<FitCase>*) {
  const ObservationSpec& spec = c.spec();
  const double L = c.rod_length();
  const CsvTable t = CsvTable::Read(spec.file);
  const auto s = t.Column("s"), x = t.Column("x"), y = t.Column("y"), z = t.Column("z"),
             roll = t.Column("roll_deg");
  std::vector<Marker3d> markers;
  std::vector<Eigen::Vector3d> positions;
  for (int r = 0; r < t.num_rows(); ++r) {
    CheckArcLength(t, r, s[r], L);
    markers.push_back({std::min(std::max(s[r], 0.0), L), Vec3(x[r], y[r], z[r])});
    positions.emplace_back(x[r], y[r], z[r]);
  }
  if (markers.empty()) throw InputError(spec.file, 0, "", "no rows");
  CheckPointsOnRod(t, "the markers", positions, c.load_case().clamp.position, L);
  // The roll model needs to know whether the case has an end ghost (an end clamp).
  const bool ghost = c.load_case().end_clamp.has_value();
  fit_case->measurements.push_back(
      std::make_shared<RollMarkers>(c.label(), c.vertex_arc_length(), ghost, std::move(markers),
                                    roll, spec.sigma, spec.kind_values.at(kSigmaRoll)));
}

// Positions as markers3d's, with the roll of the solved state at each marker; Gaussian noise of
// sigma on the positions and of sigma_roll on the roll.
std::string Synthesize(const SynthEntry& entry, std::string* report) {
  const Experiment& ex = *entry.experiment;
  const CaseSolution& solution = *entry.solution;
  const RodModel& model = *solution.model;
  const std::vector<double> s = MarkerArcLengths(*entry.spec, ex.scene.rod);
  const std::vector<double> nodes = NodeArcLengths(model.arc_lengths(), model.has_end_ghost());
  const std::vector<double> phi = RollOfEdges(model, solution.state);
  std::vector<Eigen::Vector3d> p(s.size());
  std::vector<Eigen::Matrix<double, 1, 1>> roll(s.size());
  for (size_t k = 0; k < s.size(); ++k) {
    p[k] = PointAtArcLength(*entry.shape, s[k]);
    roll[k](0) = RollAt(phi, LocateRoll(nodes, s[k])) / kDegree;
  }
  AddNoise(entry, &p);
  AddNoise(entry, entry.spec->kind_values.at(kSigmaRoll), &roll);
  std::string out = "s,x,y,z,roll_deg\n";
  for (size_t k = 0; k < s.size(); ++k)
    out += FormatDouble(s[k]) + "," + FormatDouble(p[k].x()) + "," + FormatDouble(p[k].y()) + "," +
           FormatDouble(p[k].z()) + "," + FormatDouble(roll[k](0)) + "\n";
  *report = Summary(entry, static_cast<int>(s.size()), 0, 0);
  return out;
}

#endif  // RODFIT_ENTRY_FORMATS_ONLY

}  // namespace

RODFIT_OBSERVATION_KIND(
    kRollMarkers,
    (EntryFormat{
        kName,
        "markers on a stripe: s,x,y,z,roll_deg (position [m] and the material frame's roll [deg])",
        Keys, /*may_move=*/false}),
    Build, nullptr, Synthesize, nullptr, ReportView::kMarkers3d);

}  // namespace rodfit
