// Tests of the tissue side of the rodfit command run as a user would (docs/model.md,
// "Tissue springs" and "Held points"; docs/formats.md, `grasp_force`): `rodfit simulate` on the
// bundled bowel scene writes forces.csv with one row per grasped case; spring zones, cuts, zone
// parameters, grasps and haptic force logs that are wrong exit non-zero with one line on stderr
// naming the file, the line and the key (or the log's row line and column) and write nothing; and a
// spring stiffness is recovered from a haptic force log alone, synthesized by `rodfit synth` and
// fitted by `rodfit fit`; and the tissue_drag recipe recovers its truth.json.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using test::RunResult;
using test::Replace;

namespace fs = std::filesystem;
using nlohmann::json;
using test::ReadText;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

const std::string kBowelScene = RODFIT_SOURCE_DIR "/data/scenes/bowel_drag.yaml";

// A bowel segment on two spring zones; `drag` is cut free distally, grasped at s = 0.1 and has a
// haptic log. The line numbers are those the error messages must name.
const char* const kScene =
    "rod:\n"                                                                            // 1
    "  length: 0.15\n"                                                                  // 2
    "  segments: 20\n"                                                                  // 3
    "  radius: 0.012\n"                                                                 // 4
    "  linear_density: 0.45\n"                                                          // 5
    "parameters:\n"                                                                     // 6
    "  bend_stiffness: {value: 2.0e-4}\n"                                               // 7
    "  twist_stiffness: {value: 1.5e-4}\n"                                              // 8
    "  stretch_stiffness: {value: 40}\n"                                                // 9
    "  spring_stiffness: {value: 150, fit: true}\n"                                     // 10
    "  mesentery: {value: 400}\n"                                                       // 11
    "springs:\n"                                                                        // 12
    "  - {from: 0.0, to: 0.07}\n"                                                       // 13
    "  - {from: 0.07, to: 0.15, parameter: mesentery}\n"                                // 14
    "cases:\n"                                                                          // 15
    "  - name: rest\n"                                                                  // 16
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"         // 17
    "  - name: drag\n"                                                                  // 18
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"         // 19
    "    cut: [{from: 0.12, to: 0.15}]\n"                                               // 20
    "    grasp: {s: 0.1, position: [0.1, 0.015, 0.02]}\n"                               // 21
    "    observations:\n"                                                               // 22
    "      - {type: grasp_force, file: log.csv, sigma: 0.01, s: 0.1, max_speed: 1.0e-3}\n";  // 23

// A haptic log of `rows` samples at 200 Hz with the tool still at the grasp's position and a
// constant force: every sample but the ends is quasi-static.
std::string StillLog(int rows) {
  std::string csv = "t,tool_x,tool_y,tool_z,fx,fy,fz\n";
  for (int r = 0; r < rows; ++r)
    csv += FormatDouble(r / 200.0) + ",0.1,0.015,0.02,-0.5,-0.1,-0.6\n";
  return csv;
}

class TissueCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) {
    return test::RunRodfit(dir_, args);
  }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // A failed run: non-zero exit, one line on stderr starting "rodfit: " holding each of
  // `expected`.
  static void ExpectOneLineError(const RunResult& run, const std::vector<std::string>& expected) {
    EXPECT_GT(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit: "));
    for (const std::string& e : expected) EXPECT_THAT(run.err, HasSubstr(e));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }

  // `rodfit simulate` on `yaml` fails with one line holding `expected`; nothing is written.
  void ExpectSimulateFails(const std::string& yaml, const std::vector<std::string>& expected) {
    SCOPED_TRACE(expected.back());
    const std::string scene = dir_.Write("scene.yaml", yaml);
    const std::string out_dir = dir_.File("out");
    ExpectOneLineError(Rodfit("simulate " + Q(scene) + " -o " + Q(out_dir)), expected);
    EXPECT_FALSE(fs::exists(out_dir));
  }

  // `rodfit fit` on kScene with `log` as its force log fails with one line holding `expected`;
  // no profile (nor a temporary file beside it) is written.
  void ExpectFitFails(const std::string& log, const std::vector<std::string>& expected) {
    SCOPED_TRACE(expected.back());
    const std::string scene = dir_.Write("scene.yaml", kScene);
    dir_.Write("log.csv", log);
    const std::string profile = dir_.File("profile.json");
    ExpectOneLineError(Rodfit("fit " + Q(scene) + " -o " + Q(profile)), expected);
    for (const auto& entry : fs::directory_iterator(dir_.path()))
      EXPECT_THAT(entry.path().filename().string(), Not(StartsWith("profile"))) << entry.path();
  }

  TempDir dir_;
};

TEST_F(TissueCliTest, SimulateBowelDragWritesOneForceRowPerGraspedCase) {
  const std::string out = dir_.File("bowel");
  const RunResult run = Rodfit("simulate " + Q(kBowelScene) + " -o " + Q(out));
  ASSERT_EQ(run.status, 0) << run.err;
  std::vector<std::string> grasped, all;
  for (const LoadCase& c : LoadExperiment(kBowelScene).scene.cases) {
    all.push_back(c.name);
    if (c.grasp) grasped.push_back(c.name);
  }
  ASSERT_GE(grasped.size(), 2u);
  ASSERT_LT(grasped.size(), all.size());  // a case without a grasp gets no row

  const std::string text = ReadText(out + "/forces.csv");
  EXPECT_THAT(text, StartsWith("case,point,s,x,y,z,fx,fy,fz,mx,my,mz\n"));
  const CsvTable all_forces = CsvTable::Parse(text, "forces.csv");
  // One row per held point: the clamp of every case, and the grasp of the grasped ones. Keep
  // the grasp rows (the force on the instrument).
  const auto points = all_forces.TextColumn("point"), names = all_forces.TextColumn("case");
  EXPECT_EQ(all_forces.num_rows(), static_cast<int>(all.size() + grasped.size()));
  std::vector<std::string> grasp_rows;
  std::vector<double> fx, fy, fz;
  const auto fx_all = all_forces.Column("fx"), fy_all = all_forces.Column("fy"),
             fz_all = all_forces.Column("fz");
  for (int r = 0; r < all_forces.num_rows(); ++r) {
    if (points[r] != "grasp") continue;
    grasp_rows.push_back(names[r]);
    fx.push_back(fx_all[r]), fy.push_back(fy_all[r]), fz.push_back(fz_all[r]);
  }
  EXPECT_EQ(grasp_rows, grasped);  // in file order
  for (size_t r = 0; r < fx.size(); ++r) {
    // Lifted 2 cm against springs, gravity and stretch: the instrument is pulled back and down
    // with a force of order a newton.
    const double norm = std::sqrt(fx[r] * fx[r] + fy[r] * fy[r] + fz[r] * fz[r]);
    EXPECT_GT(norm, 0.1) << r;
    EXPECT_LT(norm, 10.0) << r;
    EXPECT_LT(fz[r], 0.0) << r;
  }
  // Cutting the distal attachment free lightens the lift.
  ASSERT_EQ(grasped[1], "lifted_after_cut");
  EXPECT_LT(std::abs(fz[1]), std::abs(fz[0]));
  // Every case's shape is there too.
  const CsvTable shapes = CsvTable::Read(out + "/shapes.csv");
  EXPECT_EQ(shapes.num_rows(), static_cast<int>(all.size()) * 61);
}

TEST_F(TissueCliTest, TheBaseSceneSimulates) {
  // The edits below each break one thing in a scene that is otherwise valid.
  const std::string scene = dir_.Write("scene.yaml", kScene);
  const RunResult run = Rodfit("simulate " + Q(scene) + " -o " + Q(dir_.File("out")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable forces = CsvTable::Read(dir_.File("out/forces.csv"));
  EXPECT_EQ(forces.TextColumn("case"), std::vector<std::string>({"rest", "drag", "drag"}));
  EXPECT_EQ(forces.TextColumn("point"), std::vector<std::string>({"clamp", "clamp", "grasp"}));
}

TEST_F(TissueCliTest, SpringZonesThatOverlap) {
  ExpectSimulateFails(Replace(kScene, "{from: 0.0, to: 0.07}", "{from: 0.0, to: 0.09}"),
                      {dir_.File("scene.yaml") + ":14: springs[1]: overlaps the zone at line 13"});
}

TEST_F(TissueCliTest, ZoneLeavingTheRod) {
  ExpectSimulateFails(Replace(kScene, "to: 0.15, parameter", "to: 0.16, parameter"),
                      {dir_.File("scene.yaml") + ":14: springs[1].to: must be in [0, 0.15]",
                       "got 0.16"});
  ExpectSimulateFails(Replace(kScene, "{from: 0.0, to: 0.07}", "{from: -0.01, to: 0.07}"),
                      {dir_.File("scene.yaml") + ":13: springs[0].from: must be in [0, 0.15]"});
}

TEST_F(TissueCliTest, CutOutsideTheRod) {
  ExpectSimulateFails(Replace(kScene, "{from: 0.12, to: 0.15}", "{from: 0.12, to: 0.2}"),
                      {dir_.File("scene.yaml") + ":20: cases[1].cut[0].to: must be in [0, 0.15]",
                       "got 0.2"});
}

TEST_F(TissueCliTest, CutWithoutSprings) {
  std::string text = Replace(kScene, "  mesentery: {value: 400}\n", "");
  text = Replace(text,
                 "springs:\n  - {from: 0.0, to: 0.07}\n"
                 "  - {from: 0.07, to: 0.15, parameter: mesentery}\n",
                 "");
  // Four lines fewer: the cut is on line 16.
  ExpectSimulateFails(text, {dir_.File("scene.yaml") + ":16: cases[1].cut: a cut needs springs"});
}

TEST_F(TissueCliTest, ZoneParameterWithoutAParameterEntry) {
  ExpectSimulateFails(Replace(kScene, "  mesentery: {value: 400}\n", ""),
                      {dir_.File("scene.yaml") + ":6: parameters.mesentery: missing required key"});
}

TEST_F(TissueCliTest, GraspForceEntryWithoutS) {
  ExpectSimulateFails(Replace(kScene, "sigma: 0.01, s: 0.1, ", "sigma: 0.01, "),
                      {dir_.File("scene.yaml") +
                       ":23: cases[1].observations[0].s: missing required key"});
}

TEST_F(TissueCliTest, GraspAtTheClamp) {
  // 0.003 m is nearer vertex 0 than vertex 1 (edges of 7.5 mm).
  ExpectSimulateFails(Replace(kScene, "grasp: {s: 0.1,", "grasp: {s: 0.003,"),
                      {dir_.File("scene.yaml") + ":21: cases[1].grasp.s: the grasp is at the clamp"});
  ExpectSimulateFails(Replace(kScene, "sigma: 0.01, s: 0.1,", "sigma: 0.01, s: 0,"),
                      {dir_.File("scene.yaml") +
                       ":23: cases[1].observations[0].s: the grasp is at the clamp"});
}

TEST_F(TissueCliTest, TheStillLogIsReadByTheFit) {
  // The force logs below each break one thing in a log the fit reads: were this one refused
  // (exit 1), the error tests would be meaningless. A tool that never moves tells nothing about
  // the stiffness, so the fit writes the profile and says so with exit 4 (not determined).
  const std::string scene = dir_.Write("scene.yaml", kScene);
  dir_.Write("log.csv", StillLog(20));
  const RunResult run = Rodfit("fit " + Q(scene) + " -o " + Q(dir_.File("profile.json")) + " -q");
  ASSERT_EQ(run.status, 4) << run.err;
  EXPECT_TRUE(fs::is_regular_file(dir_.File("profile.json")));
}

TEST_F(TissueCliTest, ForceLogWithTimeGoingBack) {
  // The sixth data row (line 7: the header is line 1) is stamped before the fifth.
  std::string log = StillLog(20);
  log = Replace(log, "\n" + FormatDouble(5 / 200.0) + ",", "\n0.01,");
  ExpectFitFails(log, {dir_.File("log.csv") + ":7: t: time must increase strictly"});
  // A repeated time stamp is not an increase either.
  log = Replace(StillLog(20), "\n" + FormatDouble(10 / 200.0) + ",",
                "\n" + FormatDouble(9 / 200.0) + ",");
  ExpectFitFails(log, {dir_.File("log.csv") + ":12: t: time must increase strictly"});
}

TEST_F(TissueCliTest, ForceLogMissingAColumn) {
  std::string log = Replace(StillLog(20), "fx,fy,fz\n", "fx,fy,force_z\n");
  ExpectFitFails(log, {dir_.File("log.csv"), ": fz: missing column"});
  log = Replace(StillLog(20), "t,tool_x", "time,tool_x");
  ExpectFitFails(log, {dir_.File("log.csv"), ": t: missing column"});
}

TEST_F(TissueCliTest, SpringStiffnessFromAForceLogAlone) {
  // Truth K = 150 N/m^2 (the distal zone's 400 held); one drag of the grasped point by 2.5 cm in
  // 8 steps, the force on the instrument logged with 0.01 N noise; no tracked shape at all.
  const std::string protocol = dir_.Write(
      "in/protocol.yaml",
      "rod: {length: 0.15, segments: 30, radius: 0.012, linear_density: 0.45}\n"
      "parameters:\n"
      "  bend_stiffness: {value: 2.0e-4}\n"
      "  twist_stiffness: {value: 1.5e-4}\n"
      "  stretch_stiffness: {value: 40}\n"
      "  spring_stiffness: {value: 150, fit: true, min: 1, max: 1.0e5}\n"
      "  mesentery: {value: 400}\n"
      "springs:\n"
      "  - {from: 0.0, to: 0.07}\n"
      "  - {from: 0.07, to: 0.15, parameter: mesentery}\n"
      "cases:\n"
      "  - name: drag\n"
      "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
      "    grasp: {s: 0.1, position: [0.1, 0.015, 0.02]}\n"
      "    observations:\n"
      "      - {type: grasp_force, file: drag_force.csv, sigma: 0.01, s: 0.1, count: 8}\n");
  RunResult run = Rodfit("synth " + Q(protocol) + " -o " + Q(dir_.File("data")) + " --seed 3");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("drag_force.csv: grasp_force"));
  // The fit starts three times too soft.
  const std::string experiment = dir_.Write(
      "data/experiment.yaml", Replace(ReadText(dir_.File("data/experiment.yaml")),
                                      "{value: 150, fit: true", "{value: 50, fit: true"));
  const std::string profile = dir_.File("profile.json");
  run = Rodfit("fit " + Q(experiment) + " -o " + Q(profile));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.err, HasSubstr("spring_stiffness"));

  const json p = json::parse(ReadText(profile));
  const json truth = json::parse(ReadText(dir_.File("data/truth.json")));
  const double k_true = truth["parameters"]["spring_stiffness"].get<double>();
  EXPECT_DOUBLE_EQ(k_true, 150.0);
  const json& k = p["parameters"]["spring_stiffness"];
  EXPECT_EQ(k["fitted"], true);
  EXPECT_EQ(k["identifiable"], true);
  EXPECT_EQ(k["unit"], "N/m^2");
  ASSERT_TRUE(k["std"].is_number()) << k.dump();
  const double value = k["value"].get<double>(), std = k["std"].get<double>();
  // Eight force samples of 0.01 N against a few tenths of a newton: K to about 15 %.
  EXPECT_GT(std, 0.0);
  EXPECT_LT(std, 0.25 * k_true);
  // 3 std: a correct fit fails with probability 0.3 %, and the seed is fixed.
  EXPECT_LT(std::abs(value - k_true), 3.0 * std) << value << " +- " << std;
  // The held zone is written as given; every residual is a force, one RMS entry per sample.
  EXPECT_DOUBLE_EQ(p["parameters"]["mesentery"]["value"].get<double>(), 400.0);
  EXPECT_EQ(p["fit"]["num_residuals"], 8 * 3);
  for (const json& r : p["fit"]["rms"]) {
    EXPECT_EQ(r["type"], "grasp_force");
    EXPECT_EQ(r["unit"], "N");
  }
}

TEST_F(TissueCliTest, TissueDragRecipeRecoversItsTruth) {
  const std::string recipe = RODFIT_SOURCE_DIR "/calibration/tissue_drag/";
  const std::string profile = dir_.File("tissue_profile.json");
  const RunResult run =
      Rodfit("fit " + Q(recipe + "experiment.yaml") + " -o " + Q(profile) + " --quiet");
  ASSERT_EQ(run.status, 0) << run.err;
  const json p = json::parse(ReadText(profile));
  const json truth = json::parse(ReadText(recipe + "truth.json"));
  EXPECT_EQ(p["fit"]["success"], true);
  for (const char* name : {"spring_stiffness", "mesentery"}) {
    SCOPED_TRACE(name);
    const json& k = p["parameters"][name];
    EXPECT_EQ(k["fitted"], true);
    EXPECT_EQ(k["identifiable"], true);
    ASSERT_TRUE(k["std"].is_number()) << k.dump();
    const double value = k["value"].get<double>(), std = k["std"].get<double>();
    const double t = truth["parameters"][name].get<double>();
    EXPECT_LT(std, 0.15 * t);
    EXPECT_LT(std::abs(value - t), 3.0 * std) << value << " +- " << std << ", truth " << t;
  }
  // The starts are off the truth, so the fit had to move.
  const Experiment e = LoadExperiment(recipe + "experiment.yaml");
  EXPECT_NE(e.parameters.at("spring_stiffness").value,
            truth["parameters"]["spring_stiffness"].get<double>());
  EXPECT_NE(e.parameters.at("mesentery").value, truth["parameters"]["mesentery"].get<double>());
  // 2 cases x 10 markers x 3 + 8 force samples x 3.
  EXPECT_EQ(p["fit"]["num_residuals"], 2 * 10 * 3 + 8 * 3);
}

}  // namespace
}  // namespace rodfit
