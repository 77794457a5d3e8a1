// Tests of the rodfit command (src/cli/main.cc) run as a user would: `rodfit simulate` on bad
// scenes and paths must exit non-zero with one line on stderr naming the file, line and key, and
// write nothing; on the bundled sample scene it must write shapes.csv with every vertex.
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../io/temp_dir.h"
#include "run_cli.h"
#include "rodfit/io/csv.h"

namespace rodfit {
namespace {

using test::RunResult;

using test::ReadText;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

class CliTest : public ::testing::Test {
 protected:
  // Runs `rodfit ARGS` with stdout and stderr captured in files of the temp dir.
  RunResult Rodfit(const std::string& args) {
    return test::RunRodfit(dir_, args);
  }

  static std::string Quote(const std::string& s) { return test::Quote(s); }

  // `rodfit simulate` on `yaml` fails with one stderr line containing `expected`, writing nothing.
  void ExpectSimulateFails(const std::string& yaml, const std::string& expected) {
    SCOPED_TRACE(expected);
    const std::string scene = dir_.Write("scene.yaml", yaml);
    const std::string out_dir = dir_.File("out");
    const RunResult run = Rodfit("simulate " + Quote(scene) + " -o " + Quote(out_dir));
    EXPECT_GT(run.status, 0);
    EXPECT_THAT(run.err, StartsWith("rodfit: "));
    EXPECT_THAT(run.err, HasSubstr(expected));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(std::filesystem::exists(out_dir + "/shapes.csv"));
    EXPECT_FALSE(std::filesystem::exists(out_dir));
  }

  std::string With(const std::string& from, const std::string& to) const {
    std::string text = kScene;
    const size_t pos = text.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    if (pos != std::string::npos) text.replace(pos, from.size(), to);
    return text;
  }

  static constexpr const char* kScene =
      "rod:\n"                                                                      // 1
      "  length: 0.2\n"                                                             // 2
      "  segments: 10\n"                                                            // 3
      "  radius: 1.0e-4\n"                                                          // 4
      "  linear_density: 5.0e-5\n"                                                  // 5
      "parameters:\n"                                                               // 6
      "  bend_stiffness: {value: 1.0e-6}\n"                                         // 7
      "  twist_stiffness: {value: 8.0e-7}\n"                                        // 8
      "  stretch_stiffness: {value: 245}\n"                                         // 9
      "gravity: [0, 0, -9.81]\n"                                                    // 10
      "cases:\n"                                                                    // 11
      "  - name: sag\n"                                                             // 12
      "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";  // 13

  TempDir dir_;
};

TEST_F(CliTest, HelpAndUsage) {
  RunResult run = Rodfit("--help");
  EXPECT_EQ(run.status, 0);
  EXPECT_THAT(run.out, HasSubstr("simulate"));
  run = Rodfit("simulate --help");
  EXPECT_EQ(run.status, 0);
  EXPECT_THAT(run.out, HasSubstr("--output"));
  run = Rodfit("");
  EXPECT_GT(run.status, 0);
  EXPECT_EQ(run.err, "rodfit: no command given (see rodfit --help)\n");
  run = Rodfit("frobnicate");
  EXPECT_GT(run.status, 0);
  EXPECT_EQ(run.err, "rodfit: unknown command 'frobnicate' (see rodfit --help)\n");
}

TEST_F(CliTest, MissingArgumentsAreOneLineErrors) {
  const std::string scene = dir_.Write("scene.yaml", kScene);
  for (const std::string& args : {std::string("simulate"), "simulate " + Quote(scene)}) {
    const RunResult run = Rodfit(args);
    EXPECT_GT(run.status, 0) << args;
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }
  const RunResult run =
      Rodfit("simulate " + Quote(dir_.File("nope.yaml")) + " -o " + Quote(dir_.File("o")));
  EXPECT_GT(run.status, 0);
  EXPECT_THAT(run.err, StartsWith("rodfit: " + dir_.File("nope.yaml") + ": cannot open file"));
}

TEST_F(CliTest, BadScenesNameFileLineAndKey) {
  const std::string file = dir_.File("scene.yaml");
  ExpectSimulateFails(With("  radius:", "  raduis:"), file + ":4: rod.raduis: unknown key");
  ExpectSimulateFails(With("  length: 0.2\n", ""), file + ":1: rod.length: missing required key");
  ExpectSimulateFails(With("{value: 245}", "{value: 0}"),
                      file + ":9: parameters.stretch_stiffness.value: must be > 0");
  ExpectSimulateFails(With("segments: 10", "segments: 1"), file + ":3: rod.segments: ");
  ExpectSimulateFails(With("length: 0.2", "length: .nan"), file + ":2: rod.length: must be finite");
  ExpectSimulateFails(With("gravity: [0, 0, -9.81]", "gravity: [0, -9.81]"),
                      file + ":10: gravity: expected a list of 3 numbers");
}

TEST_F(CliTest, UnwritableOutputDirectory) {
  const std::string scene = dir_.Write("scene.yaml", kScene);
  for (const std::string& out :
       {std::string("/proc/forbidden"), dir_.Write("file", "x") + "/sub"}) {
    const RunResult run = Rodfit("simulate " + Quote(scene) + " -o " + Quote(out));
    EXPECT_GT(run.status, 0) << out;
    EXPECT_THAT(run.err, StartsWith("rodfit: " + out + ": "));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(std::filesystem::exists(out + "/shapes.csv"));
  }
}

// Relies on the case being beyond the statics solver: an axial thrust of 1e3 N is about 1e7
// times this thread's Euler load. Should a future solver find that equilibrium, pick a harder case.
TEST_F(CliTest, UnconvergedCaseFailsWithoutOutput) {
  // One Newton iteration cannot reach the sagging shape from the straight rod.
  const std::string text =
      With("gravity: [0, 0, -9.81]\n", "gravity: [0, 0, -9.81]\nsolver: {max_iterations: 1}\n");
  const std::string scene = dir_.Write("scene.yaml", text);
  const std::string out_dir = dir_.File("out");
  const RunResult run = Rodfit("simulate " + Quote(scene) + " -o " + Quote(out_dir));
  EXPECT_GT(run.status, 0);
  // Named by the case's entry in the file, as an input error would be.
  const int sag_line =
      1 + static_cast<int>(std::count(text.begin(), text.begin() + text.find("- name: sag"), '\n'));
  EXPECT_THAT(run.err, StartsWith("rodfit simulate: " + scene + ":" + std::to_string(sag_line) +
                                  ": case sag: no equilibrium found: "));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(std::filesystem::exists(out_dir));
}

TEST_F(CliTest, LoadsBeyondARodAreRefusedNamingTheCase) {
  // 1000 N on a suture of EA = 245 N would stretch it past twice its length: a unit mistake.
  const std::string scene =
      dir_.Write("scene.yaml",
                 With("    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n",
                      "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
                      "    tip_force: [-1.0e3, 0, 0]\n"));
  const std::string out_dir = dir_.File("out");
  const RunResult run = Rodfit("simulate " + Quote(scene) + " -o " + Quote(out_dir));
  EXPECT_GT(run.status, 0);
  EXPECT_THAT(run.err, StartsWith("rodfit: " + scene + ":12: cases[0]: the loads (1000 N) would "
                                  "stretch the rod by more than 100 %"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(std::filesystem::exists(out_dir));
}

TEST_F(CliTest, SimulatesTheSampleScene) {
  const std::string out_dir = dir_.File("new/out");  // created with its parents
  const RunResult run =
      Rodfit("simulate " RODFIT_SOURCE_DIR "/data/scenes/cantilever.yaml -o " + Quote(out_dir));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");

  const std::string path = out_dir + "/shapes.csv";
  const std::string text = ReadText(path);
  EXPECT_EQ(text.substr(0, text.find('\n')), "case,vertex,s,x,y,z");
  const CsvTable table = CsvTable::Read(path);
  constexpr int kCases = 3, kSegments = 50;  // data/scenes/cantilever.yaml
  ASSERT_EQ(table.num_rows(), kCases * (kSegments + 1));
  const std::vector<std::string> names = table.TextColumn("case");
  const std::vector<double> vertex = table.Column("vertex");
  const std::vector<double> s = table.Column("s");
  const std::vector<double> x = table.Column("x");
  const std::vector<double> z = table.Column("z");
  EXPECT_EQ(names.front(), "sag");
  EXPECT_EQ(names.back(), "tip_moment");
  EXPECT_EQ(vertex[kSegments], kSegments);
  EXPECT_EQ(s[0], 0.0);
  EXPECT_NEAR(s[kSegments], 0.2, 1e-15);  // rest arc length of the tip
  EXPECT_EQ(x[0], 0.0);                   // vertex 0 is held at the clamp position
  EXPECT_LT(z[kSegments], 0.0);           // the horizontally clamped "sag" case hangs down
  std::vector<std::string> listing;
  for (const auto& entry : std::filesystem::directory_iterator(out_dir)) {
    listing.push_back(entry.path().filename().string());
  }
  // No temporary file left.
  EXPECT_THAT(listing,
              ::testing::UnorderedElementsAre("shapes.csv", "forces.csv", "summary.csv"));
  // Every case has its clamp's reaction, and a summary row with how its solve ended.
  const CsvTable forces = CsvTable::Read(out_dir + "/forces.csv");
  EXPECT_EQ(forces.header(), std::vector<std::string>({"case", "point", "s", "x", "y", "z", "fx",
                                                       "fy", "fz", "mx", "my", "mz"}));
  EXPECT_EQ(forces.TextColumn("point"), std::vector<std::string>(kCases, "clamp"));
  const CsvTable summary = CsvTable::Read(out_dir + "/summary.csv");
  EXPECT_EQ(summary.TextColumn("case"), std::vector<std::string>({"sag", "tip_force", "tip_moment"}));
  EXPECT_EQ(summary.Column("converged"), std::vector<double>(kCases, 1.0));
  EXPECT_EQ(summary.Column("stable"), std::vector<double>(kCases, 1.0));
}

}  // namespace
}  // namespace rodfit
