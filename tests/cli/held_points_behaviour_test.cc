// What `rodfit simulate`, `synth` and `fit` do with held points, start shapes, solver options and
// `reaction` observations, run as a user would: forces.csv has one row per held point whose
// forces and moments balance the weight; summary.csv says how each solve ended; a grasp holds
// exactly its material point; a column past its buckling load is left for a stable equilibrium
// unless `escape_saddles: false`, which reports it unstable with a warning; --keep-going writes
// the converged cases and exits 3; sweeps with `start: previous` and start CSVs run; springs
// anchor to a curved rest shape; and a bending stiffness is recovered from markers and an end
// clamp's reaction synthesized by `rodfit synth`.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/shapes_csv.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using nlohmann::json;
using test::ReadText;
using test::Replace;
using test::RunResult;
using test::TempDir;
using ::testing::ElementsAre;
using ::testing::EndsWith;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A thread of EI = 1e-6 N m^2, EA = 245 N, 5e-5 kg/m; SEGMENTS, GRAVITY, SOLVER and CASES are
// filled in by each test.
const char* const kRod =
    "rod:\n"
    "  length: 0.2\n"
    "  segments: SEGMENTS\n"
    "  radius: 1.0e-4\n"
    "  linear_density: 5.0e-5\n"
    "parameters:\n"
    "  bend_stiffness: {value: 1.0e-6}\n"
    "  twist_stiffness: {value: 8.0e-7}\n"
    "  stretch_stiffness: {value: 245}\n"
    "gravity: GRAVITY\n"
    "SOLVERcases:\n";
constexpr double kLength = 0.2, kDensity = 5.0e-5, kBend = 1.0e-6;
const char* const kClamp = "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";

std::string Scene(int segments, const std::string& gravity, const std::string& cases,
                  const std::string& solver = "") {
  std::string text = Replace(kRod, "SEGMENTS", std::to_string(segments));
  text = Replace(text, "GRAVITY", gravity);
  text = Replace(text, "SOLVER", solver.empty() ? "" : "solver: " + solver + "\n");
  return text + cases;
}

// The held case of held_points_cli_test.cc: clamp, end_clamp, a pin at s = 0.06 and a grasp at
// s = 0.125 (between vertices 6 and 7 of the uniform rod; vertex 6 is moved onto it).
const std::string kHeldCase =
    std::string("  - name: held\n") + kClamp +
    "    end_clamp: {position: [0.18, 0, 0.02], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
    "    pins:\n"
    "      - {s: 0.06, position: [0.058, 0, 0.005]}\n"
    "    grasp: {s: 0.125, position: [0.12, 0.01, 0.01]}\n";

// The centre-line of a case at arc length s, linear between the vertices of shapes.csv.
Vector3d PointAt(const CaseShape& shape, double s) {
  const int n = static_cast<int>(shape.s.size());
  int k = static_cast<int>(std::upper_bound(shape.s.begin(), shape.s.end(), s) - shape.s.begin()) - 1;
  k = std::clamp(k, 0, n - 2);
  const double a = (s - shape.s[k]) / (shape.s[k + 1] - shape.s[k]);
  return (1.0 - a) * shape.x.col(k) + a * shape.x.col(k + 1);
}

// One row of forces.csv.
struct ForceRow {
  std::string name, point;
  double s;
  Vector3d x, f, m;
};

std::vector<ForceRow> ReadForces(const std::string& path) {
  const CsvTable t = CsvTable::Read(path);
  const auto names = t.TextColumn("case"), points = t.TextColumn("point");
  std::map<std::string, std::vector<double>> c;
  for (const char* k : {"s", "x", "y", "z", "fx", "fy", "fz", "mx", "my", "mz"}) c[k] = t.Column(k);
  std::vector<ForceRow> rows;
  for (int r = 0; r < t.num_rows(); ++r) {
    rows.push_back({names[r], points[r], c["s"][r], Vector3d(c["x"][r], c["y"][r], c["z"][r]),
                    Vector3d(c["fx"][r], c["fy"][r], c["fz"][r]),
                    Vector3d(c["mx"][r], c["my"][r], c["mz"][r])});
  }
  return rows;
}

// summary.csv, by column.
struct Summary {
  std::vector<std::string> names, reasons;
  std::vector<double> converged, stable, iterations, gradient_norm;
};

Summary ReadSummary(const std::string& path) {
  const CsvTable t = CsvTable::Read(path);
  return {t.TextColumn("case"),      t.TextColumn("reason"),    t.Column("converged"),
          t.Column("stable"),        t.Column("iterations"),    t.Column("gradient_norm")};
}

const CaseShape* Find(const std::vector<CaseShape>& shapes, const std::string& name) {
  for (const CaseShape& c : shapes)
    if (c.name == name) return &c;
  ADD_FAILURE() << "no case " << name << " in shapes.csv";
  return nullptr;
}

class HeldPointsBehaviourTest : public ::testing::Test {
 protected:
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // `rodfit simulate` on `yaml` (as DIR/NAME) into DIR/out; returns the run.
  RunResult Simulate(const std::string& yaml, const std::string& extra = "",
                     const std::string& name = "scene.yaml") {
    const std::string scene = dir_.Write(name, yaml);
    return test::RunRodfit(dir_, "simulate " + Q(scene) + " -o " + Q(Out()) + extra);
  }
  std::string Out(const std::string& file = "") const {
    return dir_.File(file.empty() ? "out" : "out/" + file);
  }

  TempDir dir_;
};

TEST_F(HeldPointsBehaviourTest, ForcesOfEveryHeldPointBalanceTheWeight) {
  const RunResult run = Simulate(Scene(10, "[0, 0, -9.81]", kHeldCase));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");

  EXPECT_THAT(ReadText(Out("forces.csv")), StartsWith("case,point,s,x,y,z,fx,fy,fz,mx,my,mz\n"));
  const std::vector<ForceRow> rows = ReadForces(Out("forces.csv"));
  // The clamp first, then the held points by arc length, each at its target.
  ASSERT_EQ(rows.size(), 4u);
  const std::vector<std::string> points = {"clamp", "pins[0]", "grasp", "end_clamp"};
  const std::vector<double> s = {0.0, 0.06, 0.125, 0.2};
  const std::vector<Vector3d> at = {Vector3d(0, 0, 0), Vector3d(0.058, 0, 0.005),
                                    Vector3d(0.12, 0.01, 0.01), Vector3d(0.18, 0, 0.02)};
  double largest_force = 0.0, largest_moment = 0.0;
  for (size_t k = 0; k < rows.size(); ++k) {
    SCOPED_TRACE(points[k]);
    EXPECT_EQ(rows[k].name, "held");
    EXPECT_EQ(rows[k].point, points[k]);
    EXPECT_NEAR(rows[k].s, s[k], 1e-15);
    EXPECT_EQ(rows[k].x, at[k]);
    EXPECT_TRUE(rows[k].f.allFinite() && rows[k].m.allFinite());
    largest_force = std::max(largest_force, rows[k].f.norm());
    largest_moment = std::max(largest_moment, rows[k].m.norm());
  }
  // Moments only at the clamps (of order EI / L = 5e-6 N m here); none at a pin or grasp.
  EXPECT_GT(rows[0].m.norm(), 1e-7);
  EXPECT_GT(rows[3].m.norm(), 1e-7);
  EXPECT_EQ(rows[1].m, Vector3d::Zero());
  EXPECT_EQ(rows[2].m, Vector3d::Zero());

  // The rod's balance: the forces the rod exerts on its holders sum to its weight, and their
  // moments about the origin (with the holders' moments) to the weight's moment. The weight is
  // lumped on the vertices as the model has it: half of each adjacent edge's rest length.
  const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(shapes.size(), 1u);
  const CaseShape& shape = shapes[0];
  ASSERT_EQ(shape.s.size(), 11u);
  const Vector3d g(0, 0, -9.81);
  Vector3d weight = Vector3d::Zero(), weight_moment = Vector3d::Zero();
  for (size_t i = 0; i < shape.s.size(); ++i) {
    double length = 0.0;
    if (i > 0) length += 0.5 * (shape.s[i] - shape.s[i - 1]);
    if (i + 1 < shape.s.size()) length += 0.5 * (shape.s[i + 1] - shape.s[i]);
    const Vector3d w = kDensity * length * g;
    weight += w;
    weight_moment += Vector3d(shape.x.col(i)).cross(w);
  }
  EXPECT_NEAR(weight.z(), -kDensity * kLength * 9.81, 1e-18);
  Vector3d force_sum = Vector3d::Zero(), moment_sum = Vector3d::Zero();
  for (const ForceRow& r : rows) {
    force_sum += r.f;
    moment_sum += r.x.cross(r.f) + r.m;
  }
  const double force_scale = largest_force + weight.norm();
  const double moment_scale = largest_moment + force_scale * kLength;
  EXPECT_LT((force_sum - weight).norm(), 1e-9 * force_scale)
      << "sum " << force_sum.transpose() << ", weight " << weight.transpose();
  EXPECT_LT((moment_sum - weight_moment).norm(), 1e-9 * moment_scale)
      << "sum " << moment_sum.transpose() << ", weight's " << weight_moment.transpose();

  // The held vertices are where their holders are.
  EXPECT_EQ(Vector3d(shape.x.col(0)), at[0]);
  EXPECT_EQ(Vector3d(shape.x.col(3)), at[1]);
  EXPECT_EQ(Vector3d(shape.x.col(6)), at[2]);
  EXPECT_EQ(Vector3d(shape.x.col(10)), at[3]);
}

TEST_F(HeldPointsBehaviourTest, SummaryCsvSaysHowEachSolveEnded) {
  const RunResult run = Simulate(Scene(10, "[0, 0, -9.81]",
                                       kHeldCase + "  - name: sag\n" + kClamp));
  ASSERT_EQ(run.status, 0) << run.err;
  const std::string text = ReadText(Out("summary.csv"));
  // No wall time in an output (reproducible outputs): simulate prints its time on stdout instead.
  EXPECT_THAT(text, StartsWith("case,converged,stable,iterations,gradient_norm,reason\n"));
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 3) << text;
  const Summary summary = ReadSummary(Out("summary.csv"));
  EXPECT_EQ(summary.names, std::vector<std::string>({"held", "sag"}));
  EXPECT_EQ(summary.converged, std::vector<double>({1, 1}));
  EXPECT_EQ(summary.stable, std::vector<double>({1, 1}));
  for (size_t k = 0; k < 2; ++k) {
    SCOPED_TRACE(summary.names[k]);
    EXPECT_GE(summary.iterations[k], 1);
    EXPECT_EQ(summary.iterations[k], std::floor(summary.iterations[k]));
    // Below the default tolerance 1e-9 x the load scale (here at most ~1 N).
    EXPECT_GE(summary.gradient_norm[k], 0.0);
    EXPECT_LT(summary.gradient_norm[k], 1e-8);
    EXPECT_THAT(summary.reasons[k], StartsWith("converged"));
  }
  // The held points are reached by continuation from the straight rod; the sag needs none.
  EXPECT_EQ(summary.reasons[0], "converged after continuation of the held points");
  EXPECT_EQ(summary.reasons[1], "converged");
}

TEST_F(HeldPointsBehaviourTest, GraspBetweenVerticesHoldsExactlyThatMaterialPoint) {
  // Vertices every 0.02: s = 0.137 lies between vertices 6 (0.12) and 7 (0.14).
  const double s = 0.137;
  const Vector3d target(0.125, 0.01, -0.02);
  const RunResult run = Simulate(Scene(10, "[0, 0, -9.81]",
                                       std::string("  - name: grasped\n") + kClamp +
                                           "    grasp: {s: 0.137, position: [0.125, 0.01, -0.02]}\n"));
  ASSERT_EQ(run.status, 0) << run.err;
  const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(shapes.size(), 1u);
  EXPECT_LT((PointAt(shapes[0], s) - target).norm(), 1e-12)
      << PointAt(shapes[0], s).transpose();
  // The nearest vertex (7) moved onto s; every other keeps its place on the rod.
  ASSERT_EQ(shapes[0].s.size(), 11u);
  for (int i = 0; i <= 10; ++i)
    EXPECT_NEAR(shapes[0].s[i], i == 7 ? s : kLength * i / 10, 1e-15) << i;
  const std::vector<ForceRow> rows = ReadForces(Out("forces.csv"));
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1].point, "grasp");
  EXPECT_NEAR(rows[1].s, s, 1e-15);
  EXPECT_EQ(rows[1].x, target);
}

// A column compressed past its buckling load: the straight rod is an equilibrium (a saddle) that
// Newton reaches from the straight start. With saddle escapes (the default) the solver leaves it
// for the buckled, stable shape; with `escape_saddles: false` it reports the straight column,
// stable = 0, and warns once, naming the case. A second, ordinary case is not warned about.
class BucklingTest : public HeldPointsBehaviourTest {
 protected:
  // Runs `column_case` (named "column") after a bent, stable case; returns the column's shape.
  CaseShape RunColumn(const std::string& column_case, bool escape, RunResult* run) {
    const std::string cases = std::string("  - name: bent\n") + kClamp +
                              "    tip_force: [0, 0, -2.0e-5]\n" + "  - name: column\n" + kClamp +
                              column_case;
    const std::string yaml = Scene(20, "[0, 0, 0]", cases, escape ? "" : "{escape_saddles: false}");
    *run = Simulate(yaml);
    EXPECT_EQ(run->status, 0) << run->err;
    const Summary summary = ReadSummary(Out("summary.csv"));
    EXPECT_EQ(summary.names, std::vector<std::string>({"bent", "column"}));
    EXPECT_EQ(summary.converged, std::vector<double>({1, 1}));
    EXPECT_EQ(summary.stable, std::vector<double>({1, escape ? 1.0 : 0.0}));
    if (escape) {
      EXPECT_EQ(run->err, "");
    } else {
      // Named by the case's entry in the file.
      const auto column_entry = yaml.begin() + yaml.find("- name: column");
      const int column_line = 1 + static_cast<int>(std::count(yaml.begin(), column_entry, '\n'));
      EXPECT_THAT(run->err, StartsWith("rodfit simulate: warning: " + dir_.File("scene.yaml") +
                                       ":" + std::to_string(column_line) + ": case column: "));
      EXPECT_THAT(run->err, HasSubstr("unstable"));
      EXPECT_EQ(std::count(run->err.begin(), run->err.end(), '\n'), 1) << run->err;
    }
    const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
    const CaseShape* column = Find(shapes, "column");
    fs::remove_all(Out());
    return column ? *column : CaseShape();
  }
};

TEST_F(BucklingTest, CantileverAtTwiceItsEulerLoad) {
  const double euler = M_PI * M_PI * kBend / (4 * kLength * kLength);  // clamped-free
  const std::string column = "    tip_force: [" + FormatDouble(-2 * euler) + ", 0, 0]\n";
  RunResult run;
  {
    SCOPED_TRACE("escape_saddles: true");
    const CaseShape shape = RunColumn(column, true, &run);
    ASSERT_EQ(shape.x.cols(), 21);
    // The elastica at P = 2 P_cr: the tip swings far out of line.
    const Vector3d tip = shape.x.col(20);
    EXPECT_GT(std::hypot(tip.y(), tip.z()), 0.2 * kLength) << tip.transpose();
    EXPECT_LT(tip.x(), 0.9 * kLength) << tip.transpose();
  }
  {
    SCOPED_TRACE("escape_saddles: false");
    const CaseShape shape = RunColumn(column, false, &run);
    ASSERT_EQ(shape.x.cols(), 21);
    const Vector3d tip = shape.x.col(20);
    EXPECT_LT(std::hypot(tip.y(), tip.z()), 1e-9) << tip.transpose();
    EXPECT_NEAR(tip.x(), kLength, 1e-5);
  }
}

TEST_F(BucklingTest, ColumnShortenedByAnEndPin) {
  // The end pinned 1 cm short of the rod's length: 5 % end shortening, a thrust of ~12 N if it
  // stayed straight, against a clamped-pinned buckling load of ~5e-4 N.
  const std::string column = "    end_pin: {position: [0.19, 0, 0]}\n";
  RunResult run;
  {
    SCOPED_TRACE("escape_saddles: true");
    const CaseShape shape = RunColumn(column, true, &run);
    ASSERT_EQ(shape.x.cols(), 21);
    EXPECT_EQ(Vector3d(shape.x.col(20)), Vector3d(0.19, 0, 0));
    double lateral = 0.0;
    for (int i = 0; i <= 20; ++i)
      lateral = std::max(lateral, std::hypot(shape.x(1, i), shape.x(2, i)));
    EXPECT_GT(lateral, 0.05 * kLength);
  }
  {
    SCOPED_TRACE("escape_saddles: false");
    const CaseShape shape = RunColumn(column, false, &run);
    ASSERT_EQ(shape.x.cols(), 21);
    EXPECT_EQ(Vector3d(shape.x.col(20)), Vector3d(0.19, 0, 0));
    for (int i = 0; i <= 20; ++i) EXPECT_LT(std::hypot(shape.x(1, i), shape.x(2, i)), 1e-9) << i;
  }
}

TEST_F(HeldPointsBehaviourTest, KeepGoingWritesTheConvergedCasesAndExits3) {
  // Two Newton iterations: enough for the hanging thread (gravity along the rod only stretches
  // it: one step is exact, the second confirms), not for the horizontal one's sag (four). The
  // solver counts a step when taken and confirms convergence at the next one, so with
  // max_iterations: 1 no case under gravity converges.
  const std::string yaml =
      Scene(10, "[0, 0, -9.81]",
            std::string("  - name: sag\n") + kClamp +
                "  - name: hang\n"
                "    clamp: {position: [0, 0, 0], tangent: [0, 0, -1], normal: [1, 0, 0]}\n",
            "{max_iterations: 2}");
  // The failure names the case's entry in the file, as an input error would.
  const int sag_line =
      1 + static_cast<int>(std::count(yaml.begin(), yaml.begin() + yaml.find("- name: sag"), '\n'));
  const std::string failure = "rodfit simulate: " + dir_.File("scene.yaml") + ":" +
                              std::to_string(sag_line) + ": case sag: no equilibrium found: ";
  // Without --keep-going: nothing written.
  RunResult run = Simulate(yaml);
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, StartsWith(failure));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(fs::exists(Out()));

  run = Simulate(yaml, " --keep-going");
  EXPECT_EQ(run.status, 3) << run.err;
  EXPECT_THAT(run.err, StartsWith(failure));
  EXPECT_THAT(run.err, EndsWith(" (other cases written)\n"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;

  const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(shapes.size(), 1u);
  EXPECT_EQ(shapes[0].name, "hang");
  ASSERT_EQ(shapes[0].x.cols(), 11);
  // Hanging straight down, stretched by its own weight (by rho g L^2 / (2 EA) = 4e-8 m).
  EXPECT_LT(shapes[0].x(2, 10), -kLength);
  EXPECT_GT(shapes[0].x(2, 10), -kLength * (1 + 1e-6));
  EXPECT_LT(std::abs(shapes[0].x(0, 10)), 1e-15);
  const std::vector<ForceRow> forces = ReadForces(Out("forces.csv"));
  ASSERT_EQ(forces.size(), 1u);
  EXPECT_EQ(forces[0].name, "hang");
  EXPECT_EQ(forces[0].point, "clamp");
  EXPECT_NEAR(forces[0].f.z(), -kDensity * kLength * 9.81, 1e-12);

  const Summary summary = ReadSummary(Out("summary.csv"));
  EXPECT_EQ(summary.names, std::vector<std::string>({"sag", "hang"}));
  EXPECT_EQ(summary.converged, std::vector<double>({0, 1}));
  EXPECT_EQ(summary.stable, std::vector<double>({0, 1}));
  EXPECT_THAT(summary.reasons[0], StartsWith("no equilibrium found: iteration limit reached"));
  EXPECT_THAT(summary.reasons[1], StartsWith("converged"));
}

TEST_F(HeldPointsBehaviourTest, SweepWithStartPreviousFollowsTheEndClamp) {
  // The end clamp carried along a path and turned, case by case, each case starting from the
  // previous one's equilibrium; the last end is free to turn about its tangent (no normal).
  const std::vector<Vector3d> ends = {Vector3d(0.19, 0, 0), Vector3d(0.17, 0.02, 0.02),
                                      Vector3d(0.14, 0.05, 0.04), Vector3d(0.10, 0.07, 0.05)};
  const std::string cases =
      std::string("  - name: step0\n") + kClamp +
      "    end_clamp: {position: [0.19, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
      "  - name: step1\n" + kClamp +
      "    end_clamp: {position: [0.17, 0.02, 0.02], tangent: [0.8, 0.6, 0], normal: [0, 0, 1]}\n"
      "    start: previous\n"
      "  - name: step2\n" + kClamp +
      "    end_clamp: {position: [0.14, 0.05, 0.04], tangent: [0, 1, 0], normal: [0, 0, 1]}\n"
      "    start: previous\n"
      "  - name: step3\n" + kClamp +
      "    end_clamp: {position: [0.10, 0.07, 0.05], tangent: [-0.6, 0.8, 0]}\n"
      "    start: previous\n";
  const RunResult run = Simulate(Scene(20, "[0, 0, -9.81]", cases));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const Summary summary = ReadSummary(Out("summary.csv"));
  EXPECT_EQ(summary.names, std::vector<std::string>({"step0", "step1", "step2", "step3"}));
  EXPECT_EQ(summary.converged, std::vector<double>(4, 1.0));
  EXPECT_EQ(summary.stable, std::vector<double>(4, 1.0));
  const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(shapes.size(), 4u);
  const std::vector<ForceRow> forces = ReadForces(Out("forces.csv"));
  ASSERT_EQ(forces.size(), 8u);
  for (size_t k = 0; k < 4; ++k) {
    SCOPED_TRACE(shapes[k].name);
    ASSERT_EQ(shapes[k].x.cols(), 21);
    EXPECT_EQ(Vector3d(shapes[k].x.col(20)), ends[k]);
    EXPECT_EQ(forces[2 * k + 1].point, "end_clamp");
    EXPECT_EQ(forces[2 * k + 1].x, ends[k]);
  }
  // The free-turning end carries no moment about its tangent.
  const Vector3d t = Vector3d(-0.6, 0.8, 0).normalized();
  EXPECT_LT(std::abs(forces[7].m.dot(t)), 1e-9 * forces[7].m.norm());
}

TEST_F(HeldPointsBehaviourTest, StartCsvsRelativeToTheSceneReachTheSameEquilibrium) {
  // A sagging cantilever (one equilibrium) from the straight rod, and from two start CSVs in a
  // folder beside the scene: an arc bent down through 1 rad as x,y,z (7 points, its s
  // rescaled to the rod) and as s,x,y,z.
  std::string xyz = "x,y,z\n", sxyz = "s,x,y,z\n";
  for (int k = 0; k <= 6; ++k) {
    const double a = k / 6.0, s = kLength * a;
    const std::string p = FormatDouble(kLength * std::sin(a)) + ",0," +
                          FormatDouble(-kLength * (1 - std::cos(a)));
    xyz += p + "\n";
    sxyz += FormatDouble(s) + "," + p + "\n";
  }
  dir_.Write("scenes/starts/arc.csv", xyz);
  dir_.Write("scenes/starts/arc_s.csv", sxyz);
  const std::string cases = std::string("  - name: straight\n") + kClamp +
                            "  - name: from_xyz\n" + kClamp + "    start: starts/arc.csv\n" +
                            "  - name: from_sxyz\n" + kClamp + "    start: starts/arc_s.csv\n";
  const RunResult run = Simulate(Scene(10, "[0, 0, -9.81]", cases), "", "scenes/scene.yaml");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const Summary summary = ReadSummary(Out("summary.csv"));
  EXPECT_EQ(summary.converged, std::vector<double>(3, 1.0));
  const std::vector<CaseShape> shapes = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(shapes.size(), 3u);
  EXPECT_LT(shapes[0].x(2, 10), -0.05);  // it sags
  for (size_t c = 1; c < 3; ++c) {
    SCOPED_TRACE(shapes[c].name);
    ASSERT_EQ(shapes[c].x.cols(), 11);
    EXPECT_LT((shapes[c].x - shapes[0].x).cwiseAbs().maxCoeff(), 1e-8);
  }
}

TEST_F(HeldPointsBehaviourTest, SpringsAnchorToTheCurvedRestShape) {
  // A rod curved at rest (bending and twist) on springs along its whole length, with no loads
  // and no gravity: the springs pull towards the rest shape, so they exert nothing and the rod
  // stays where the same rod without springs settles.
  const std::string cases = std::string("  - name: rest\n") + kClamp;
  std::string with_springs = Scene(20, "[0, 0, 0]", cases);
  with_springs = Replace(with_springs, "  linear_density: 5.0e-5\n",
                         "  linear_density: 5.0e-5\n  rest_curvature: [0, 10, 2]\n");
  const std::string without_springs = with_springs;
  with_springs = Replace(with_springs, "gravity:",
                         "springs:\n  - {from: 0.0, to: 0.2}\ngravity:");
  with_springs = Replace(with_springs, "  stretch_stiffness: {value: 245}\n",
                         "  stretch_stiffness: {value: 245}\n  spring_stiffness: {value: 50}\n");

  RunResult run = Simulate(without_springs);
  ASSERT_EQ(run.status, 0) << run.err;
  const std::vector<CaseShape> free = ReadShapesCsv(Out("shapes.csv"));
  fs::remove_all(Out());
  run = Simulate(with_springs);
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const std::vector<CaseShape> sprung = ReadShapesCsv(Out("shapes.csv"));
  ASSERT_EQ(free.size(), 1u);
  ASSERT_EQ(sprung.size(), 1u);
  ASSERT_EQ(sprung[0].x.cols(), 21);
  ASSERT_EQ(free[0].x.cols(), 21);
  // Curved indeed: 2 rad of bending over the rod takes the tip far from the straight one's.
  EXPECT_GT((Vector3d(free[0].x.col(20)) - Vector3d(kLength, 0, 0)).norm(), 0.05);
  EXPECT_LT((sprung[0].x - free[0].x).cwiseAbs().maxCoeff(), 1e-10);
  // Nothing loads the rod: the clamp holds (almost) nothing (EI / L^2 = 2.5e-5 N for scale).
  const std::vector<ForceRow> forces = ReadForces(Out("forces.csv"));
  ASSERT_EQ(forces.size(), 1u);
  EXPECT_LT(forces[0].f.norm(), 1e-9);
  EXPECT_LT(forces[0].m.norm(), 1e-10);
}

// ---- synth + fit with a reaction ------------------------------------------------------------

// A suture-like wire (EI 9.2e-6 N m^2) under gravity, clamped at s = 0 and end-clamped at s = L
// turned down through a quarter turn: 3-D markers, and 4 readings of the force and moment on the
// end clamp. TRUTH is the bending stiffness.
const char* const kReactionExperiment =
    R"(rod: {length: 0.2, segments: 20, radius: 2.5e-4, linear_density: 2.24e-4}
parameters:
  bend_stiffness: {value: TRUTH, fit: true, min: 1.0e-8, max: 1.0e-3}
  twist_stiffness: {value: 6.8e-6}
  stretch_stiffness: {value: 589}
gravity: [0, 0, -9.81]
cases:
  - name: bridge
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    end_clamp: {position: [0.12, 0, -0.12], tangent: [0, 0, -1], normal: [1, 0, 0]}
    observations:
      - {type: markers3d, file: bridge_markers.csv, sigma: 3.0e-4, count: 8}
      - {type: reaction, point: end_clamp, file: bridge_end.csv, sigma: 1.0e-5, sigma_moment: 1.0e-6, count: 4}
)";
constexpr double kTrueBend = 9.2e-6;

class ReactionFitTest : public HeldPointsBehaviourTest {
 protected:
  // Synthesizes `experiment` (seed 3) into DIR/data, sets the bending stiffness's start in the
  // written DIR/data/experiment.yaml to twice the truth, fits it; returns the profile.
  json SynthAndFit(const std::string& experiment) {
    const std::string protocol =
        dir_.Write("in/protocol.yaml", Replace(experiment, "TRUTH", "9.2e-6"));
    RunResult run =
        test::RunRodfit(dir_, "synth " + Q(protocol) + " -o " + Q(dir_.File("data")) + " --seed 3");
    EXPECT_EQ(run.status, 0) << run.err;
    const std::string written = ReadText(dir_.File("data/experiment.yaml"));
    dir_.Write("data/experiment.yaml",
               Replace(written, "bend_stiffness: {value: 9.2e-6", "bend_stiffness: {value: 1.84e-5"));
    const std::string profile = dir_.File("profile.json");
    run = test::RunRodfit(dir_, "fit " + Q(dir_.File("data/experiment.yaml")) + " -o " +
                                    Q(profile) + " --threads 1");
    EXPECT_EQ(run.status, 0) << run.err;
    if (!fs::exists(profile)) return json();
    return json::parse(ReadText(profile));
  }
};

TEST_F(ReactionFitTest, BendStiffnessIsRecoveredFromMarkersAndAnEndClampReaction) {
  const json p = SynthAndFit(kReactionExperiment);
  ASSERT_TRUE(p.is_object());
  const json truth = json::parse(ReadText(dir_.File("data/truth.json")));
  EXPECT_DOUBLE_EQ(truth["parameters"]["bend_stiffness"].get<double>(), kTrueBend);
  // The reaction file holds forces and moments.
  EXPECT_THAT(ReadText(dir_.File("data/bridge_end.csv")), StartsWith("fx,fy,fz,mx,my,mz\n"));

  EXPECT_EQ(p["fit"]["success"], true);
  const json& b = p["parameters"]["bend_stiffness"];
  EXPECT_EQ(b["fitted"], true);
  EXPECT_EQ(b["identifiable"], true);
  ASSERT_TRUE(b["std"].is_number()) << b.dump();
  const double value = b["value"].get<double>(), std = b["std"].get<double>();
  EXPECT_GT(std, 0.0);
  EXPECT_LT(std, 0.05 * kTrueBend);
  EXPECT_LT(std::abs(value - kTrueBend), 3.0 * std) << value << " +- " << std;
  // 8 markers x 3, and 4 readings x (3 forces + 3 moments).
  EXPECT_EQ(p["fit"]["num_residuals"], 8 * 3 + 4 * 6);

  // One RMS entry per case and observation, in file order: the reaction's in newtons.
  const json& rms = p["fit"]["rms"];
  ASSERT_EQ(rms.size(), 2u) << rms.dump();
  EXPECT_EQ(rms[0]["type"], "markers3d");
  EXPECT_EQ(rms[1]["case"], "bridge");
  EXPECT_EQ(rms[1]["type"], "reaction") << rms[1].dump();
  EXPECT_EQ(rms[1]["observation"], "reaction bridge_end.csv") << rms[1].dump();
  EXPECT_EQ(rms[1]["count"], 4);
  EXPECT_EQ(rms[1]["unit"], "N");
  // Noise-level: sigma 1e-5 N per component (RMS of the norm ~1.7e-5 N).
  EXPECT_GT(rms[1]["rms"].get<double>(), 0.0);
  EXPECT_LT(rms[1]["rms"].get<double>(), 5e-5);
}

TEST_F(ReactionFitTest, EveryReactionObservationHasItsOwnRmsEntry) {
  // A second reaction, at the clamp, forces only.
  const std::string experiment =
      std::string(kReactionExperiment) +
      "      - {type: reaction, point: clamp, file: bridge_clamp.csv, sigma: 1.0e-5, count: 2}\n";
  const json p = SynthAndFit(experiment);
  ASSERT_TRUE(p.is_object());
  EXPECT_EQ(p["fit"]["num_residuals"], 8 * 3 + 4 * 6 + 2 * 3);
  const json& rms = p["fit"]["rms"];
  ASSERT_EQ(rms.size(), 3u) << rms.dump();
  EXPECT_EQ(rms[0]["observation"], "markers3d bridge_markers.csv");
  EXPECT_EQ(rms[1]["observation"], "reaction bridge_end.csv");
  EXPECT_EQ(rms[1]["count"], 4);
  EXPECT_EQ(rms[2]["observation"], "reaction bridge_clamp.csv");
  EXPECT_EQ(rms[2]["count"], 2);
  for (size_t k = 1; k < 3; ++k) {
    EXPECT_EQ(rms[k]["type"], "reaction");
    EXPECT_EQ(rms[k]["unit"], "N");
  }
}

}  // namespace
}  // namespace rodfit
