// `rodfit bench --quick` and `--stress` (docs/cli.md, "bench"): every row of the ladder within
// the accuracy its reference and discretisation allow, the files written, and a stress suite
// where no row returns a wrong answer as success.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/csv.h"
#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;

TEST(BenchCli, QuickLadderWritesCsvAndHtmlWithErrorsThatFallWithSegments) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "bench --quick -o " + Quote(dir.File("b")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable t = CsvTable::Read(dir.File("b/bench.csv"));
  const std::vector<std::string> problem = t.TextColumn("problem"), family = t.TextColumn("family"),
                                 setting = t.TextColumn("setting");
  // "nan" where a row has no reference (suture_swing_cost): std::stod reads it as NaN.
  std::vector<double> error;
  for (const std::string& e : t.TextColumn("error")) error.push_back(std::stod(e));
  const std::vector<double> converged = t.Column("converged");
  ASSERT_GT(t.num_rows(), 30);
  double helix_10 = 0, helix_1000 = 0, mattiasson_1000 = 0;
  for (int r = 0; r < t.num_rows(); ++r) {
    EXPECT_EQ(converged[r], 1.0) << problem[r] << " " << setting[r];
    if (problem[r] == "end_moment_helix" && family[r] == "segments" && setting[r] == "n=10") helix_10 = error[r];
    if (problem[r] == "end_moment_helix" && family[r] == "segments" && setting[r] == "n=1000") helix_1000 = error[r];
    if (problem[r] == "mattiasson_alpha3" && setting[r] == "n=1000") mattiasson_1000 = error[r];
  }
  // Second order in the segments: 100 times the segments, ~1e4 times smaller.
  EXPECT_LT(helix_1000, 1e-3 * helix_10);
  EXPECT_LT(helix_1000, 1e-5);
  // Mattiasson's table has 5 digits.
  EXPECT_LT(mattiasson_1000, 3e-5);
  const std::string html = ReadText(dir.File("b/index.html"));
  EXPECT_THAT(html, HasSubstr("<svg"));
  EXPECT_THAT(html, HasSubstr("time [s]"));
  EXPECT_THAT(html, HasSubstr("cantilever_frequency"));
}

// The statics rows against independent references (docs/cli.md, "bench"): each family's two
// --quick settings converged and stable, the finer within a bound above its measured error, and
// the error falling with the discretisation at second order (~4x per doubling: > 3x per doubling
// asserted) where the discretisation error is far above the reference's floor.
TEST(BenchCli, QuickLadderHasTheReferenceStaticsRowsConvergingAtSecondOrder) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "bench --quick -o " + Quote(dir.File("b")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable t = CsvTable::Read(dir.File("b/bench.csv"));
  const std::vector<std::string> problem = t.TextColumn("problem"), setting = t.TextColumn("setting"),
                                 unit = t.TextColumn("error_unit");
  std::vector<double> error;
  for (const std::string& e : t.TextColumn("error")) error.push_back(std::stod(e));
  const std::vector<double> converged = t.Column("converged"), stable = t.Column("stable");
  std::map<std::string, double> e;  // "problem setting" -> error
  for (int r = 0; r < t.num_rows(); ++r) {
    const std::string key = problem[r] + " " + setting[r];
    if (problem[r] != "clamped_clamped_sag" && problem[r] != "rest_curved_3d" &&
        problem[r] != "winkler_point_load" && problem[r] != "ring_point_load")
      continue;
    EXPECT_EQ(converged[r], 1.0) << key;
    EXPECT_EQ(stable[r], 1.0) << key;
    EXPECT_EQ(unit[r], problem[r] == "winkler_point_load" || problem[r] == "ring_point_load"
                           ? "relative" : "L") << key;
    e[key] = error[r];
  }
  ASSERT_EQ(e.size(), 8u) << "two --quick settings of each of the four problems";
  // Bounds about twice the measured errors of the finer setting (the errors are deterministic):
  // 4.8e-5 L, 8.9e-6 L, 2.5e-3 and 1.6e-3. The floors (reference, finite Winkler rod, the
  // ring's nonlinearity at its load: docs/cli.md, "bench") are at least 100 times lower, so the
  // ratios measure the discretisation: ~11x, 11x, 8.7x and 3.8x.
  struct Family {
    const char *problem, *coarse, *fine;
    double refinement;  // fine / coarse segments or nodes
    double bound;       // on the finer setting's error
  };
  for (const Family& f : {Family{"clamped_clamped_sag", "n=30", "n=100", 100.0 / 30, 1e-4},
                          Family{"rest_curved_3d", "n=30", "n=100", 100.0 / 30, 2e-5},
                          Family{"winkler_point_load", "n=100", "n=300", 3.0, 5e-3},
                          Family{"ring_point_load", "N=32", "N=64", 2.0, 3e-3}}) {
    const double coarse = e[std::string(f.problem) + " " + f.coarse];
    const double fine = e[std::string(f.problem) + " " + f.fine];
    EXPECT_LT(fine, f.bound) << f.problem;
    // Second order: 4x per doubling; more than 3x per doubling asserted.
    EXPECT_GT(coarse / fine, std::pow(3.0, std::log2(f.refinement))) << f.problem;
  }
}

TEST(BenchCli, QuickLadderHasFitRecoveryRowsAndTheParetoFigure) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "bench --quick --calibration " +
                                           Quote(std::string(RODFIT_SOURCE_DIR) + "/calibration") +
                                           " -o " + Quote(dir.File("b")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable t = CsvTable::Read(dir.File("b/bench.csv"));
  const std::vector<std::string> problem = t.TextColumn("problem"), setting = t.TextColumn("setting"),
                                 family = t.TextColumn("family");
  std::vector<double> error;
  for (const std::string& e : t.TextColumn("error")) error.push_back(std::stod(e));
  const std::vector<double> converged = t.Column("converged");
  std::map<std::string, int> rows_per_recipe;
  int swing = 0;
  for (int r = 0; r < t.num_rows(); ++r) {
    swing += problem[r] == "suture_swing";
    if (problem[r].rfind("fit/", 0) != 0) continue;
    ++rows_per_recipe[problem[r]];
    EXPECT_EQ(converged[r], 1.0) << problem[r] << " " << family[r] << " " << setting[r];
    // Exact data: the fit stops at its own convergence tolerance, ~1e-6 relative at worst.
    if (setting[r] == "noise=0") {
      EXPECT_LT(error[r], 1e-5) << problem[r] << " " << family[r];
    }
  }
  // Two fitted parameters at three noise levels, two and one.
  EXPECT_EQ(rows_per_recipe["fit/suture_cantilever"], 6);
  EXPECT_EQ(rows_per_recipe["fit/tissue_drag"], 6);
  EXPECT_EQ(rows_per_recipe["fit/tissue_poke"], 3);
  EXPECT_EQ(swing, 12);  // three integrators, four time steps
  const std::string svg = ReadText(dir.File("b/pareto.svg"));
  EXPECT_THAT(svg, HasSubstr("<svg"));
  EXPECT_THAT(svg, HasSubstr("suture swing"));
  EXPECT_THAT(svg, HasSubstr("Mattiasson"));
}

TEST(BenchCli, SkipsGiveTheSameAnswerAndSayWhatTheyCannotMeasure) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "bench --skips --quick --calibration " +
                                           Quote(std::string(RODFIT_SOURCE_DIR) + "/calibration") +
                                           " -o " + Quote(dir.File("k")));
  ASSERT_EQ(run.status, 0) << run.out << run.err;
  const CsvTable t = CsvTable::Read(dir.File("k/bench.csv"));
  const std::vector<std::string> problem = t.TextColumn("problem"), family = t.TextColumn("family"),
                                 verdict = t.TextColumn("verdict"), note = t.TextColumn("note"),
                                 error = t.TextColumn("error");  // "nan" where not measured
  std::map<std::string, int> with, without;
  bool vision = false;
  for (int r = 0; r < t.num_rows(); ++r) {
    if (problem[r] == "skip/vision_for_markers") {
      vision = true;
      EXPECT_EQ(verdict[r], "not measured");
      EXPECT_THAT(note[r], HasSubstr("no images"));
      continue;
    }
    EXPECT_EQ(verdict[r], "same") << problem[r];
    EXPECT_LE(std::stod(error[r]), 1e-10) << problem[r];
    if (family[r] == "with skip") {
      ++with[problem[r]];
      EXPECT_THAT(note[r], HasSubstr("saving")) << problem[r];
    } else {
      ++without[problem[r]];
    }
  }
  EXPECT_TRUE(vision);
  for (const char* skip : {"skip/twist_elimination", "skip/section_without_poke",
                           "skip/mass_for_statics", "skip/jacobian_fixed_parameters"}) {
    EXPECT_GE(with[skip], 1) << skip;
    EXPECT_EQ(with[skip], without[skip]) << skip;
  }
  EXPECT_THAT(run.out, HasSubstr("saving"));
  EXPECT_THAT(ReadText(dir.File("k/index.html")), HasSubstr("<h2>Skips</h2>"));
}

TEST(BenchCli, StressSuiteHasNoWrongRow) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "bench --stress -o " + Quote(dir.File("s")));
  EXPECT_EQ(run.status, 0) << run.out << run.err;
  EXPECT_THAT(run.out, ::testing::Not(HasSubstr("WRONG")));
  const CsvTable t = CsvTable::Read(dir.File("s/bench.csv"));
  EXPECT_GE(t.num_rows(), 10);
  for (const std::string& v : t.TextColumn("verdict")) EXPECT_EQ(v, "ok");
}

}  // namespace
}  // namespace rodfit::test
