// `rodfit bench --quick` and `--stress` (docs/cli.md, "bench"): every row of the ladder within
// the accuracy its reference and discretisation allow, the files written, and a stress suite
// where no row returns a wrong answer as success.
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
  const std::vector<double> error = t.Column("error"), converged = t.Column("converged");
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
