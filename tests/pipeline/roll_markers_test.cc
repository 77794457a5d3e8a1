// The `roll_markers` observation kind (src/rodfit/pipeline/kinds/roll_markers.cc), added as one
// file and its registration line: markers on a stripe whose file gives the position and the
// material frame's roll at s. Its exact Jacobian against central differences of the state (the
// vertices and twist angles, reference frames transported in time as the solver's); the roll of
// a uniformly twisted rod against Saint-Venant torsion, phi(s) = M s / GJ; and the reason it
// exists: the torsion stiffness GJ of an isotropic rod is not identifiable from its 3-D shape
// under given loads (the centre-line depends on the twist moment, which the loads set, not on
// GJ), and is with the stripe's roll.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "io/temp_dir.h"
#include "rodfit/fit/fit.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/pipeline/synthesize.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/sensitivity.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

constexpr double kDegree = M_PI / 180.0;

// An isotropic cantilever, 3-D under gravity (-z), a dead sideways tip force (+y) and a follower
// twisting moment about its end tangent; with an end clamp instead when END is replaced.
// OBSERVATIONS is replaced by each test's entries.
const char* const kProtocol =
    "rod: {length: 0.2, segments: 40, radius: 2.5e-4, linear_density: 5.6e-5}\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-5, fit: true}\n"
    "  twist_stiffness: {value: 8.0e-6, fit: true}\n"
    "  stretch_stiffness: {value: 245}\n"
    "gravity: [0, 0, -9.81]\n"
    "cases:\n"
    "  - name: twisted\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    END\n"
    "    observations:\n"
    "      - OBSERVATION\n"
    "  - name: twisted_more\n"
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    tip_force: [0, -1.0e-4, 0]\n"
    "    tip_moment_follower: [0, 0, 6.0e-5]\n"
    "    observations:\n"
    "      - OBSERVATION2\n";

std::string Protocol(const std::string& observation, const std::string& observation2,
                     const std::string& end =
                         "tip_force: [0, 1.0e-4, 0]\n"
                         "    tip_moment_follower: [0, 0, 3.0e-5]") {
  std::string text = kProtocol;
  auto put = [&](const std::string& key, const std::string& value) {
    text.replace(text.find(key), key.size(), value);
  };
  put("OBSERVATION2", observation2);
  put("OBSERVATION", observation);
  put("END", end);
  return text;
}

// The measurement that the registry builds from a roll marker file, on the case's solution.
struct Built {
  Experiment experiment;
  FitInput input;
  CaseSolution solution;
  const Measurement* roll = nullptr;
};

void BuildRollCase(const TempDir& dir, const std::string& end, Built* out) {
  const std::string rows =
      "s,x,y,z,roll_deg\n0.013,0.013,0,0,1\n0.1,0.1,0,0,2\n0.17,0.17,0,0,3\n"
      "0.2,0.2,0,0,4\n";
  dir.Write("roll.csv", rows);
  const std::string entry = "{type: roll_markers, file: roll.csv, sigma: 1.0e-3, sigma_roll: 2}";
  const std::string path = dir.Write("experiment.yaml", Protocol(entry, entry, end));
  out->experiment = LoadExperiment(path);
  out->input = BuildFitInput(out->experiment);
  ASSERT_EQ(out->input.cases[0].measurements.size(), 1u);
  out->roll = out->input.cases[0].measurements[0].get();
  EXPECT_EQ(out->roll->type(), "roll_markers");
  out->solution = SolveCase(out->experiment.scene, 0, nullptr);
  ASSERT_TRUE(out->solution.ok()) << out->solution.summary.reason;
}

// The state moved along free-dof direction `dq` by h, its reference frames transported from
// `state` (as a solver's step does).
RodState Moved(const RodModel& model, const RodState& state, const Eigen::VectorXd& dq, double h) {
  RodState out = state;
  const int n = model.num_edges();
  for (int i = 1; i <= n; ++i) out.x.col(i) += h * dq.segment<3>(RodModel::VertexDof(i));
  for (int j = 0; j < n; ++j) out.theta[j] += h * dq[RodModel::TwistDof(j)];
  if (model.has_end_ghost()) out.end_theta += h * dq[RodModel::TwistDof(n)];
  out.SyncEdges();
  EXPECT_TRUE(UpdateReferenceFrames(model, state, &out));
  return out;
}

// d r / d q of the roll markers (positions and roll) along random directions of the state,
// against central differences, on a cantilever and on a rod between two clamps (whose end
// clamp's ghost edge ends the roll's interpolation).
TEST(RollMarkers, JacobianEqualsCentralDifferencesOfTheState) {
  const std::vector<std::string> ends = {
      "tip_force: [0, 1.0e-4, 0]\n    tip_moment_follower: [0, 0, 3.0e-5]",
      "end_clamp: {position: [0.15, 0.05, 0.03], tangent: [0.2, 1, 0.3]}"};
  for (const std::string& end : ends) {
    TempDir dir;
    Built b;
    BuildRollCase(dir, end, &b);
    if (::testing::Test::HasFatalFailure()) return;
    const RodModel& model = *b.solution.model;
    const RodState& state = b.solution.state;
    // Three random directions, zero on held dofs (the solver never moves them).
    std::mt19937 rng(11);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const int m = 3;
    Eigen::MatrixXd dq(model.num_free_dofs(), m);
    for (int r = 0; r < dq.rows(); ++r)
      for (int c = 0; c < m; ++c) dq(r, c) = model.held_dofs()[r] ? 0.0 : gauss(rng);
    dq *= 1e-3;  // [m] and [rad] per unit step
    const Eigen::MatrixXd dx = VertexSensitivities(model, dq);
    SolvedCase solved;
    solved.x = &state.x;
    solved.model = &model;
    solved.state = &state;
    solved.num_parameters = m;
    solved.d_x = &dx;
    solved.d_q = &dq;
    const int rows = b.roll->num_residuals();
    ASSERT_EQ(rows, 16);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(rows, m);
    Eigen::VectorXd r0(rows);
    std::string why;
    ASSERT_TRUE(b.roll->Evaluate(solved, r0.data(), J.data(), &why)) << why;
    const double h = 1e-4;
    for (int c = 0; c < m; ++c) {
      Eigen::VectorXd rp(rows), rm(rows);
      for (const auto& [sign, r] : {std::pair<double, Eigen::VectorXd*>{h, &rp}, {-h, &rm}}) {
        const RodState moved = Moved(model, state, dq.col(c), sign);
        SolvedCase at = solved;
        at.x = &moved.x;
        at.state = &moved;
        ASSERT_TRUE(b.roll->Evaluate(at, r->data(), nullptr, &why)) << why;
      }
      const Eigen::VectorXd fd = (rp - rm) / (2.0 * h);
      EXPECT_LT((J.col(c) - fd).norm(), 1e-6 * std::max(1.0, fd.norm()))
          << end << "\ncolumn " << c << "\nanalytic " << J.col(c).transpose() << "\ncentral  "
          << fd.transpose();
      // The roll rows (every 4th) carry the twist: they must be tested, not zero.
      double roll_rows = 0.0;
      for (int k = 3; k < rows; k += 4) roll_rows += std::abs(fd[k]);
      EXPECT_GT(roll_rows, 1e-3) << end;
    }
  }
}

// A straight rod twisted by a follower moment M about its tangent alone (no gravity): uniform
// torsion M / GJ (Saint-Venant), so the stripe's roll at s is M s / GJ; the discrete roll, a
// sum of torsions over Voronoi lengths interpolated between the edges' midpoints, is exact for a
// linear roll. Synthesized without noise, the file holds it to round-off.
TEST(RollMarkers, UniformTwistRollsAsSaintVenant) {
  TempDir dir;
  std::string text = Protocol(
      "{type: roll_markers, file: a.csv, sigma: 1e-3, sigma_roll: 1, "
      "s: [0.004, 0.05, 0.123, 0.2]}",
      "{type: roll_markers, file: b.csv, sigma: 1e-3, sigma_roll: 1}",
      "tip_moment_follower: [0, 0, 3.0e-5]");
  text.replace(text.find("gravity: [0, 0, -9.81]"), 22, "gravity: [0, 0, 0]");
  const std::string path = dir.Write("protocol.yaml", text);
  SynthOptions options;
  options.add_noise = false;
  Synthesize(LoadExperiment(path), dir.File("out"), options);
  const CsvTable t = CsvTable::Read(dir.File("out/a.csv"));
  const std::vector<double> s = t.Column("s"), roll = t.Column("roll_deg"), y = t.Column("y");
  ASSERT_EQ(t.num_rows(), 4);
  const double M = 3.0e-5, GJ = 8.0e-6;  // [N m], [N m^2]
  for (int k = 0; k < 4; ++k) {
    EXPECT_NEAR(roll[k], M * s[k] / GJ / kDegree, 1e-9) << "s = " << s[k];
    EXPECT_NEAR(y[k], 0.0, 1e-10);  // a twisting moment alone leaves the rod straight
  }
  EXPECT_GT(roll.back(), 40.0);  // 43 degrees at the tip: a test that the roll is read at all
}

// Entries: sigma_roll is required and the file needs roll_deg; a symmetric case is refused.
TEST(RollMarkers, EntryAndFileErrorsNameTheirPlace) {
  TempDir dir;
  dir.Write("r.csv", "s,x,y,z\n0.1,0.1,0,0\n");
  const std::string missing =
      dir.Write("a.yaml", Protocol("{type: roll_markers, file: r.csv, sigma: 1e-3}",
                                   "{type: markers3d, file: r.csv, sigma: 1e-3}"));
  try {
    LoadExperiment(missing);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("cases[0].observations[0].sigma_roll: missing"));
  }
  const std::string no_column =
      dir.Write("b.yaml", Protocol("{type: roll_markers, file: r.csv, sigma: 1e-3, sigma_roll: 1}",
                                   "{type: markers3d, file: r.csv, sigma: 1e-3}"));
  try {
    BuildFitInput(LoadExperiment(no_column));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("r.csv"));
    EXPECT_THAT(std::string(e.what()), HasSubstr("roll_deg"));
  }
}

// The fit of B and GJ to two 3-D twisted cases, from starts twice the truth, with markers only
// and with roll markers (each synthesized with noise, sigma 0.2 mm and 1 degree). GJ is bounded
// to 0.5 - 2.5 times the truth, as a lab bounds it (a round section of an isotropic material has
// GJ / B = 1 / (1 + nu), 0.67 to 1): the discrete bending energy, written with the two edges'
// averaged directors (model/vertex_stencil.h), couples twist to bending at O((M l / GJ)^2), so
// that towards GJ -> 0 the shape alone would carry information of the discretization's making
// (40 segments, unbounded: the markers-only fit ran to GJ = 1.8e-6 +- 1.2e-6).
FitResult FitTwisted(const std::string& kind, unsigned seed) {
  TempDir dir;
  const std::string extra = kind == "roll_markers" ? ", sigma_roll: 1" : "";
  const std::string entry =
      "{type: " + kind + ", file: FILE, sigma: 2.0e-4, count: 10" + extra + "}";
  auto with_file = [&](const std::string& file) {
    std::string e = entry;
    e.replace(e.find("FILE"), 4, file);
    return e;
  };
  const std::string path =
      dir.Write("protocol.yaml", Protocol(with_file("a.csv"), with_file("b.csv")));
  SynthOptions options;
  options.seed = seed;
  Synthesize(LoadExperiment(path), dir.File("out"), options);
  FitInput input = BuildFitInput(LoadExperiment(dir.File("out/experiment.yaml")));
  for (Parameter& p : input.parameters) {
    if (p.fit) p.value *= 2.0;
    if (p.name == "twist_stiffness") p.min = 4.0e-6, p.max = 2.0e-5;
  }
  return Fit(input, FitOptions());
}

const Parameter& Estimate(const FitResult& r, const std::string& name) {
  for (const Parameter& p : r.parameters)
    if (p.name == name) return p;
  throw std::invalid_argument(name);
}

TEST(RollMarkers, MakeTwistStiffnessIdentifiableFromA3dTwistedShape) {
  const double B = 1.0e-5, GJ = 8.0e-6;  // the protocol's truth
  for (const unsigned seed : {1u, 2u}) {
    // Markers alone: the shape says nothing of GJ, and the fit says so.
    const FitResult shape = FitTwisted("markers3d", seed);
    ASSERT_TRUE(shape.success) << shape.message;
    const Parameter& gj_shape = Estimate(shape, "twist_stiffness");
    EXPECT_FALSE(gj_shape.identifiable) << "seed " << seed << ": " << gj_shape.value;
    EXPECT_THAT(gj_shape.reason,
                ::testing::AnyOf(HasSubstr("do not depend on it"), HasSubstr("below the noise")));
    const Parameter& b_shape = Estimate(shape, "bend_stiffness");
    ASSERT_TRUE(b_shape.identifiable && b_shape.std);
    EXPECT_LT(std::abs(b_shape.value - B), 3.0 * *b_shape.std) << "seed " << seed;

    // With the stripe's roll: both, each within 3 std of the truth.
    const FitResult roll = FitTwisted("roll_markers", seed);
    ASSERT_TRUE(roll.success) << roll.message;
    const Parameter& gj = Estimate(roll, "twist_stiffness");
    const Parameter& b = Estimate(roll, "bend_stiffness");
    ASSERT_TRUE(gj.identifiable && gj.std) << gj.reason;
    ASSERT_TRUE(b.identifiable && b.std) << b.reason;
    EXPECT_LT(std::abs(gj.value - GJ), 3.0 * *gj.std) << "seed " << seed << ": " << gj.value;
    EXPECT_LT(std::abs(b.value - B), 3.0 * *b.std) << "seed " << seed << ": " << b.value;
    EXPECT_LT(*gj.std, 0.05 * GJ);  // a measurement, not a bound
    // The RMS table has the roll's misfit in degrees, about the noise's 1 degree.
    for (const ObservationFit& o : roll.observations) {
      EXPECT_EQ(o.type, "roll_markers");
      EXPECT_GT(o.rms_roll, 0.3);
      EXPECT_LT(o.rms_roll, 2.0);
    }
  }
}

}  // namespace
}  // namespace rodfit
