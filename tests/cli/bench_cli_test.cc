// `rodfit bench --quick` and `--stress` (docs/cli.md, "bench"): every row of the ladder within
// the accuracy its reference and discretisation allow, the files written, and a stress suite
// where no row returns a wrong answer as success.
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
