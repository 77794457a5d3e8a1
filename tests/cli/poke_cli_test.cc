// `surface_points` through the command line (ring_bend_stiffness): an entry in a case
// without a poke is a one-line error naming the file, the line and the key; `rodfit synth` then
// `rodfit fit` recovers the ring's bending stiffness from noisy points around the dent; and the
// tissue_poke recipe recovers its truth.json.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"
#include "rodfit/io/csv.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::ReadText;
using test::RunResult;
using test::Replace;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A poked bowel segment; ring_bend_stiffness is the truth for synth (line 11).
const char* const kScene =
    "rod:\n"                                                                            // 1
    "  length: 0.15\n"                                                                  // 2
    "  segments: 30\n"                                                                  // 3
    "  radius: 0.012\n"                                                                 // 4
    "  linear_density: 0.45\n"                                                          // 5
    "parameters:\n"                                                                     // 6
    "  bend_stiffness: {value: 2.0e-4}\n"                                               // 7
    "  twist_stiffness: {value: 1.5e-4}\n"                                              // 8
    "  stretch_stiffness: {value: 40}\n"                                                // 9
    "  spring_stiffness: {value: 300}\n"                                                // 10
    "  ring_bend_stiffness: {value: 2.0e-5, fit: true}\n"                               // 11
    "  ring_stretch_stiffness: {value: 5.0}\n"                                          // 12
    "springs:\n"                                                                        // 13
    "  - {from: 0.0, to: 0.15}\n"                                                       // 14
    "section: {radius: 0.012, nodes: 32}\n"                                             // 15
    "cases:\n"                                                                          // 16
    "  - name: side\n"                                                                  // 17
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"         // 18
    "    poke: {s: 0.075, force: [0, -0.03, 0]}\n"                                      // 19
    "    observations:\n"                                                               // 20
    "      - {type: surface_points, file: side.csv, sigma: 3.0e-5, count: 40}\n";       // 21

class PokeCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) { return test::RunRodfit(dir_, args); }
  static std::string Q(const std::string& s) { return test::Quote(s); }
  TempDir dir_;
};

TEST_F(PokeCliTest, SurfacePointsWithoutPokeIsOneLineError) {
  const std::string scene =
      dir_.Write("scene.yaml", Replace(kScene, "    poke: {s: 0.075, force: [0, -0.03, 0]}\n", ""));
  for (const char* command : {"fit", "synth"}) {
    SCOPED_TRACE(command);
    const RunResult run = Rodfit(std::string(command) + " " + Q(scene) + " -o " +
                                 Q(dir_.File("out")));
    EXPECT_GT(run.status, 0);
    EXPECT_THAT(run.err, StartsWith("rodfit: "));
    // The entry is on line 20 once the poke's line is gone.
    EXPECT_THAT(run.err, HasSubstr(scene + ":20: cases[0].observations[0].type:"));
    EXPECT_THAT(run.err, HasSubstr("poke"));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(fs::exists(dir_.File("out")));
  }
}

TEST_F(PokeCliTest, SurfacePointsRejectOtherKeys) {
  const std::string scene =
      dir_.Write("scene.yaml", Replace(kScene, "count: 40}", "count: 40, s: [0.075]}"));
  const RunResult run = Rodfit("fit " + Q(scene) + " -o " + Q(dir_.File("p.json")));
  EXPECT_GT(run.status, 0);
  EXPECT_THAT(run.err, HasSubstr(scene + ":21: cases[0].observations[0].s:"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
}

TEST_F(PokeCliTest, SynthThenFitRecoversRingBendStiffness) {
  const std::string scene = dir_.Write("scene.yaml", kScene);
  const std::string data = dir_.File("data");
  const RunResult synth = Rodfit("synth " + Q(scene) + " -o " + Q(data) + " --seed 3");
  ASSERT_EQ(synth.status, 0) << synth.err;
  const std::string csv = ReadText(data + "/side.csv");
  EXPECT_THAT(csv, StartsWith("x,y,z\n"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 41);
  // Start the fit three times too stiff.
  const std::string experiment = data + "/experiment.yaml";
  std::string text = ReadText(experiment);
  text = Replace(text, "{value: 2.0e-5, fit: true}", "{value: 6.0e-5, fit: true}");
  WriteFileAtomically(experiment, text);
  const std::string profile = dir_.File("profile.json");
  const std::string report = dir_.File("report");
  const RunResult fit = Rodfit("fit " + Q(experiment) + " -o " + Q(profile) + " --report " +
                               Q(report) + " --quiet");
  ASSERT_EQ(fit.status, 0) << fit.err;
  const json p = json::parse(ReadText(profile));
  const json& kb = p["parameters"]["ring_bend_stiffness"];
  EXPECT_EQ(kb["fitted"], true);
  ASSERT_TRUE(kb["std"].is_number()) << kb.dump();
  const double value = kb["value"].get<double>(), std = kb["std"].get<double>();
  EXPECT_LT(std, 0.15 * 2e-5);
  EXPECT_LT(std::abs(value - 2e-5), 3.0 * std) << value << " +- " << std;
  EXPECT_DOUBLE_EQ(p["parameters"]["ring_stretch_stiffness"]["value"].get<double>(), 5.0);
  EXPECT_THAT(ReadText(report + "/summary.csv"),
              HasSubstr("side,surface_points side.csv,surface_points,40,"));
}

TEST_F(PokeCliTest, TissuePokeRecipeRecoversItsTruth) {
  const std::string recipe = RODFIT_SOURCE_DIR "/calibration/tissue_poke/";
  const std::string profile = dir_.File("poke_profile.json");
  const RunResult run =
      Rodfit("fit " + Q(recipe + "experiment.yaml") + " -o " + Q(profile) + " --quiet");
  ASSERT_EQ(run.status, 0) << run.err;
  const json p = json::parse(ReadText(profile));
  const json truth = json::parse(ReadText(recipe + "truth.json"));
  const json& kb = p["parameters"]["ring_bend_stiffness"];
  ASSERT_TRUE(kb["std"].is_number()) << kb.dump();
  const double value = kb["value"].get<double>(), std = kb["std"].get<double>();
  const double t = truth["parameters"]["ring_bend_stiffness"].get<double>();
  EXPECT_LT(std::abs(value - t), 3.0 * std) << value << " +- " << std << ", truth " << t;
  EXPECT_NE(ReadText(recipe + "experiment.yaml").find("ring_bend_stiffness: {value: 6.0e-5"),
            std::string::npos);  // the start is off the truth
}

}  // namespace
}  // namespace rodfit
