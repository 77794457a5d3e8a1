// Tests of `rodfit fit` run as a user would (docs/cli.md, "fit"): an experiment synthesized with
// `rodfit synth` and fitted from starts three times too soft recovers the truth within 3 std, the
// profile JSON carries every field of the contract, `--report DIR` writes its tables and plots;
// the suture cantilever recipe recovers its truth.json; a parameter the cases cannot determine is
// reported as NOT IDENTIFIABLE with std null; and every bad input exits non-zero with one line on
// stderr naming the file (and key or row line) and leaves no profile behind.
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"

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

const std::string kSource = RODFIT_SOURCE_DIR;
const std::string kCameras = kSource + "/tests/data/synth/";
const std::string kRecipe = kSource + "/calibration/suture_cantilever/";

// A braided suture (the recipe's material, 30 segments to keep the test quick) sagging in two
// clamp rolls, so that gravity bends it about d2 (`flat`) and about d1 (`rolled`): both bending
// stiffnesses act. Each case has 3-D markers and marker pixels in one or both cameras. START1 and
// START2 are replaced by the values of bend_stiffness and bend_stiffness_2: the truth for synth,
// the start for fit.
const char* const kExperiment =
    R"(rod: {length: 0.2, segments: 30, radius: 2.5e-4, linear_density: 2.24e-4}
parameters:
  bend_stiffness: {value: START1, fit: true, min: 1.0e-8, max: 1.0e-3}
  bend_stiffness_2: {value: START2, fit: true, min: 1.0e-8, max: 1.0e-3}
  twist_stiffness: {value: 6.8e-6}
  stretch_stiffness: {value: 589}
gravity: [0, 0, -9.81]
cases:
  - name: flat
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    observations:
      - {type: markers3d, file: flat_markers.csv, sigma: 3.0e-4, count: 8}
      - {type: image_points, file: flat_front.csv, camera: cam_front.yaml, sigma: 0.5,
         s: [0.05, 0.1, 0.15, 0.2]}
      - {type: image_points, file: flat_top.csv, camera: cam_top.yaml, sigma: 0.5,
         s: [0.05, 0.1, 0.15, 0.2]}
  - name: rolled
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 1, 0]}
    observations:
      - {type: markers3d, file: rolled_markers.csv, sigma: 3.0e-4, count: 8}
      - {type: image_points, file: rolled_front.csv, camera: cam_front.yaml, sigma: 0.5,
         s: [0.05, 0.1, 0.15, 0.2]}
)";

const double kTrueB1 = 9.2e-6, kTrueB2 = 1.1e-5;

// Every START1 / START2 token of the template (there may be none left) set to a value.
std::string WithStarts(std::string text, const std::string& start1, const std::string& start2) {
  for (const auto& [key, value] : {std::pair<std::string, std::string>{"START1", start1},
                                   std::pair<std::string, std::string>{"START2", start2}}) {
    for (size_t at = text.find(key); at != std::string::npos; at = text.find(key, at))
      text.replace(at, key.size(), value);
  }
  return text;
}

class FitCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) {
    return test::RunRodfit(dir_, args);
  }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // Synthesizes `experiment` at the truth (B1 = 9.2e-6, B2 = 1.1e-5 N m^2) into DIR/data
  // (seed 5) and writes DIR/data/fit.yaml, the same experiment with both starts at 3e-6, about
  // three times too soft. Returns the path of fit.yaml.
  std::string SynthesizeAndWriteFit(const std::string& experiment = kExperiment) {
    dir_.Write("in/cam_front.yaml", ReadText(kCameras + "cam_front.yaml"));
    dir_.Write("in/cam_top.yaml", ReadText(kCameras + "cam_top.yaml"));
    const std::string truth_text = WithStarts(experiment, "9.2e-6", "1.1e-5");
    const std::string protocol = dir_.Write("in/protocol.yaml", truth_text);
    const RunResult run = Rodfit("synth " + Q(protocol) + " -o " + Q(dir_.File("data")) +
                                 " --seed 5");
    EXPECT_EQ(run.status, 0) << run.err;
    return WriteFitExperiment(experiment);
  }

  // `experiment` with the starts at 3e-6 as DIR/data/NAME.yaml, beside the synthesized data.
  std::string WriteFitExperiment(const std::string& experiment, const std::string& name = "fit") {
    return dir_.Write("data/" + name + ".yaml", WithStarts(experiment, "3.0e-6", "3.0e-6"));
  }

  // Runs `rodfit fit` and expects failure: non-zero exit, exactly one line on stderr starting
  // with "rodfit" and holding every one of `expected`, and no profile.
  void ExpectFitError(const std::string& experiment_path,
                      const std::vector<std::string>& expected) {
    const std::string profile = dir_.File("bad_profile.json");
    const RunResult run = Rodfit("fit " + Q(experiment_path) + " -o " + Q(profile));
    EXPECT_GT(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit"));
    for (const std::string& e : expected) EXPECT_THAT(run.err, HasSubstr(e));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(fs::exists(profile)) << run.err;
    // No temporary file (".bad_profile.json.tmp.*") left beside it either.
    for (const auto& entry : fs::directory_iterator(dir_.path()))
      EXPECT_THAT(entry.path().filename().string(), Not(HasSubstr("bad_profile"))) << entry.path();
  }

  TempDir dir_;
};

// Checks that a fitted parameter lies within 3 std of the truth (the profile's own std: a 3-sigma
// band fails a correct fit with probability 0.3 %, and the seeds here are fixed).
void ExpectWithinThreeStd(const json& parameter, double truth, const std::string& name) {
  ASSERT_TRUE(parameter.contains("std")) << name;
  ASSERT_TRUE(parameter["std"].is_number()) << name << ": " << parameter.dump();
  const double value = parameter["value"].get<double>(), std = parameter["std"].get<double>();
  EXPECT_GT(std, 0.0) << name;
  EXPECT_LT(std, 0.05 * truth) << name << ": the data should pin it down to a few percent";
  EXPECT_LT(std::abs(value - truth), 3.0 * std)
      << name << ": fitted " << value << " +- " << std << ", truth " << truth;
}

TEST_F(FitCliTest, HelpNamesTheOptions) {
  const RunResult run = Rodfit("fit --help");
  EXPECT_EQ(run.status, 0);
  for (const char* option : {"--output", "--report", "--quiet", "--threads"})
    EXPECT_THAT(run.out, HasSubstr(option));
}

TEST_F(FitCliTest, SynthesizedExperimentIsRecoveredAndTheProfileIsComplete) {
  const std::string experiment = SynthesizeAndWriteFit();
  const std::string profile_path = dir_.File("out/profile.json"), report = dir_.File("report");
  const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(profile_path) + " --report " +
                               Q(report) + " --threads 1");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.err, HasSubstr("bend_stiffness"));
  EXPECT_THAT(run.err, HasSubstr("wrote"));
  EXPECT_THAT(run.err, Not(HasSubstr("NOT IDENTIFIABLE")));

  const json p = json::parse(ReadText(profile_path));
  EXPECT_EQ(p["format"], "rodfit-profile");
  EXPECT_EQ(p["version"], 2);
  EXPECT_EQ(p["rod"]["segments"], 30);
  EXPECT_DOUBLE_EQ(p["rod"]["length"].get<double>(), 0.2);

  // Every parameter the model used, with value, std, fitted and unit.
  const json truth = json::parse(ReadText(dir_.File("data/truth.json")));
  const std::map<std::string, std::string> units = {{"bend_stiffness", "N m^2"},
                                                    {"bend_stiffness_2", "N m^2"},
                                                    {"twist_stiffness", "N m^2"},
                                                    {"stretch_stiffness", "N"},
                                                    {"spring_stiffness", "N/m^2"}};
  for (const auto& [name, unit] : units) {
    SCOPED_TRACE(name);
    ASSERT_TRUE(p["parameters"].contains(name));
    const json& q = p["parameters"][name];
    for (const char* key : {"value", "std", "fitted", "identifiable", "unit"})
      EXPECT_TRUE(q.contains(key)) << key;
    EXPECT_EQ(q["unit"], unit);
    const bool fitted = name == "bend_stiffness" || name == "bend_stiffness_2";
    EXPECT_EQ(q["fitted"], fitted);
    if (fitted) {
      EXPECT_EQ(q["identifiable"], true);
      ExpectWithinThreeStd(q, truth["parameters"][name].get<double>(), name);
    } else {
      EXPECT_TRUE(q["std"].is_null());  // a held value carries no uncertainty
      // As given; spring_stiffness is absent from the experiment: 0, no springs.
      const double given = truth["parameters"].contains(name)
                               ? truth["parameters"][name].get<double>()
                               : 0.0;
      EXPECT_DOUBLE_EQ(q["value"].get<double>(), given);
    }
  }
  EXPECT_DOUBLE_EQ(truth["parameters"]["bend_stiffness"].get<double>(), kTrueB1);
  EXPECT_DOUBLE_EQ(truth["parameters"]["bend_stiffness_2"].get<double>(), kTrueB2);

  const json& fit = p["fit"];
  EXPECT_EQ(fit["success"], true);
  EXPECT_GT(fit["iterations"].get<int>(), 0);
  // 2 cases x 8 markers x 3 + 3 pixel observations x 4 markers x 2 residuals.
  EXPECT_EQ(fit["num_residuals"], 2 * 8 * 3 + 3 * 4 * 2);
  // The sigmas are the synthesized noise: the residual variance is about 1 (chi-square with
  // 70 dof has a relative std of 0.17, so [0.4, 2] is a wide, never-flaky band).
  EXPECT_GT(fit["residual_variance"].get<double>(), 0.4);
  EXPECT_LT(fit["residual_variance"].get<double>(), 2.0);

  // One RMS entry per case and observation, in file order, in the observation's unit.
  const std::vector<std::tuple<std::string, std::string, std::string>> rms_expected = {
      {"flat", "markers3d", "m"},
      {"flat", "image_points", "px"},
      {"flat", "image_points", "px"},
      {"rolled", "markers3d", "m"},
      {"rolled", "image_points", "px"}};
  ASSERT_EQ(fit["rms"].size(), rms_expected.size()) << fit["rms"].dump();
  for (size_t k = 0; k < rms_expected.size(); ++k) {
    const json& r = fit["rms"][k];
    const auto& [case_name, type, unit] = rms_expected[k];
    EXPECT_EQ(r["case"], case_name);
    EXPECT_EQ(r["type"], type);
    EXPECT_EQ(r["unit"], unit);
    EXPECT_THAT(r["observation"].get<std::string>(), HasSubstr(type));
    const double rms = r["rms"].get<double>();
    // Noise-level residuals: sigma 0.3 mm per coordinate in 3-D (RMS of the norm ~0.5 mm),
    // 0.5 px per pixel coordinate.
    EXPECT_LT(rms, unit == "m" ? 1.5e-3 : 2.0) << k;
    EXPECT_GT(rms, 0.0) << k;
  }

  // A digest of the experiment, every data file and every camera.
  std::set<std::string> digested;
  for (const json& input : fit["inputs"]) {
    ASSERT_TRUE(input.contains("file") && input.contains("fnv1a64")) << input.dump();
    EXPECT_TRUE(std::regex_match(input["fnv1a64"].get<std::string>(), std::regex("[0-9a-f]{16}")))
        << input.dump();
    digested.insert(fs::path(input["file"].get<std::string>()).filename().string());
  }
  for (const char* name : {"fit.yaml", "flat_markers.csv", "flat_front.csv", "flat_top.csv",
                           "rolled_markers.csv", "rolled_front.csv", "cam_front.yaml",
                           "cam_top.yaml"})
    EXPECT_EQ(digested.count(name), 1u) << name;

  // Correlation among the fitted parameters: 2 x 2, unit diagonal, symmetric, |rho| < 1.
  const json& corr = fit["correlation"];
  EXPECT_EQ(corr["parameters"], json({"bend_stiffness", "bend_stiffness_2"}));
  ASSERT_EQ(corr["matrix"].size(), 2u);
  for (int i = 0; i < 2; ++i) {
    ASSERT_EQ(corr["matrix"][i].size(), 2u);
    EXPECT_NEAR(corr["matrix"][i][i].get<double>(), 1.0, 1e-12);
  }
  EXPECT_NEAR(corr["matrix"][0][1].get<double>(), corr["matrix"][1][0].get<double>(), 1e-12);
  EXPECT_LT(std::abs(corr["matrix"][0][1].get<double>()), 1.0);

  // The report: tables, the page and one camera figure per case and camera.
  for (const char* name : {"summary.csv", "residuals.csv", "index.html"})
    EXPECT_TRUE(fs::is_regular_file(report + "/" + name)) << name;
  EXPECT_THAT(ReadText(report + "/summary.csv"),
              StartsWith("case,observation,type,count,rms,unit"));
  // residuals.csv: a header and one row per measurement (2 x 8 markers + 12 marker pixels).
  const std::string residuals = ReadText(report + "/residuals.csv");
  EXPECT_EQ(std::count(residuals.begin(), residuals.end(), '\n'), 1 + 2 * 8 + 12);
  std::multiset<std::string> pictures;
  for (const auto& entry : fs::directory_iterator(report + "/figures")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("camera_", 0) == 0) {
      EXPECT_GT(fs::file_size(entry.path()), 0u) << name;
      pictures.insert(entry.path().stem().string().substr(7));  // camera_CASE_CAMERA.svg
    }
  }
  EXPECT_EQ(pictures, std::multiset<std::string>({"flat_cam_front", "flat_cam_top",
                                                  "rolled_cam_front"}));
}

TEST_F(FitCliTest, SutureCantileverRecipeRecoversItsTruth) {
  const std::string profile_path = dir_.File("suture_profile.json");
  const RunResult run =
      Rodfit("fit " + Q(kRecipe + "experiment.yaml") + " -o " + Q(profile_path) + " --quiet");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");  // --quiet
  const json p = json::parse(ReadText(profile_path));
  const json truth = json::parse(ReadText(kRecipe + "truth.json"));
  EXPECT_EQ(p["fit"]["success"], true);
  for (const char* name : {"bend_stiffness", "bend_stiffness_2"}) {
    SCOPED_TRACE(name);
    EXPECT_EQ(p["parameters"][name]["fitted"], true);
    EXPECT_EQ(p["parameters"][name]["identifiable"], true);
    ExpectWithinThreeStd(p["parameters"][name], truth["parameters"][name].get<double>(), name);
  }
  // The held ones are written as given.
  for (const char* name : {"twist_stiffness", "stretch_stiffness"}) {
    EXPECT_EQ(p["parameters"][name]["fitted"], false) << name;
    EXPECT_DOUBLE_EQ(p["parameters"][name]["value"].get<double>(),
                     truth["parameters"][name].get<double>())
        << name;
  }
  // 4 cases x (1 markers3d + 2 image_points).
  EXPECT_EQ(p["fit"]["rms"].size(), 12u);
}

TEST_F(FitCliTest, TorsionFromPlanarCasesIsReportedNotIdentifiable) {
  // Only the `flat` case, with an isotropic rod: gravity bends it in a plane and nothing twists
  // it, so the markers do not depend on GJ at all.
  std::string text = Replace(kExperiment, "  bend_stiffness_2: {value: START2, fit: true, "
                                          "min: 1.0e-8, max: 1.0e-3}\n", "");
  text = Replace(text, "twist_stiffness: {value: 6.8e-6}",
                 "twist_stiffness: {value: START2, fit: true}");
  text = text.substr(0, text.find("  - name: rolled"));
  const std::string experiment = SynthesizeAndWriteFit(text);
  const std::string profile_path = dir_.File("planar.json");
  const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(profile_path));
  // Exit 4: the profile is written, but a fitted parameter is not determined by the data.
  ASSERT_EQ(run.status, 4) << run.err;
  EXPECT_THAT(run.err, HasSubstr("twist_stiffness"));
  EXPECT_THAT(run.err, HasSubstr("NOT IDENTIFIABLE"));
  const json p = json::parse(ReadText(profile_path));
  const json& gj = p["parameters"]["twist_stiffness"];
  EXPECT_EQ(gj["fitted"], true);
  EXPECT_TRUE(gj["std"].is_null()) << gj.dump();
  EXPECT_EQ(gj["identifiable"], false);
  ASSERT_TRUE(gj.contains("reason"));
  EXPECT_FALSE(gj["reason"].get<std::string>().empty());
  // Bending is still determined, and within 3 std of the truth.
  const json& b = p["parameters"]["bend_stiffness"];
  EXPECT_EQ(b["identifiable"], true);
  ExpectWithinThreeStd(b, kTrueB1, "bend_stiffness");
  // Isotropic: bend_stiffness_2 is written, tied to bend_stiffness.
  EXPECT_EQ(p["parameters"]["bend_stiffness_2"]["tied_to"], "bend_stiffness");
  EXPECT_DOUBLE_EQ(p["parameters"]["bend_stiffness_2"]["value"].get<double>(),
                   b["value"].get<double>());
  // A correlation with an undetermined parameter is not a number.
  EXPECT_TRUE(p["fit"]["correlation"]["matrix"][0][1].is_null());
}

class FitCliErrorTest : public FitCliTest {
 protected:
  void SetUp() override { good_ = SynthesizeAndWriteFit(); }
  // fit.yaml with one edit, written as DIR/data/NAME.yaml.
  std::string Edited(const std::string& from, const std::string& to, const std::string& name) {
    return WriteFitExperiment(Replace(kExperiment, from, to), name);
  }
  std::string good_;
};

TEST_F(FitCliErrorTest, TheUneditedExperimentFits) {
  const RunResult run = Rodfit("fit " + Q(good_) + " -o " + Q(dir_.File("p.json")) + " -q");
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_TRUE(fs::is_regular_file(dir_.File("p.json")));
}

TEST_F(FitCliErrorTest, NothingToFit) {
  std::string text = Replace(kExperiment, "START1, fit: true", "START1, fit: false");
  text = Replace(text, "START2, fit: true", "START2");
  ExpectFitError(WriteFitExperiment(text, "nothing"), {"nothing.yaml", "nothing to fit"});
}

TEST_F(FitCliErrorTest, MissingCameraFile) {
  ExpectFitError(Edited("camera: cam_top.yaml", "camera: cam_side.yaml", "nocam"),
                 {"cam_side.yaml", "cannot open"});
}

TEST_F(FitCliErrorTest, DataFileMissingAColumn) {
  std::string csv = ReadText(dir_.File("data/rolled_markers.csv"));
  csv = Replace(csv, "s,x,y,z", "s,x,y,w");
  dir_.Write("data/rolled_markers_noz.csv", csv);
  ExpectFitError(Edited("rolled_markers.csv", "rolled_markers_noz.csv", "nocolumn"),
                 {"rolled_markers_noz.csv", "z", "missing column"});
}

TEST_F(FitCliErrorTest, MarkerOutsideTheRod) {
  // The third data row (line 4 of the file) at s = 0.25 on a 0.2 m rod.
  const std::string csv = ReadText(dir_.File("data/flat_markers.csv"));
  std::vector<std::string> lines;
  for (size_t a = 0, b; a < csv.size(); a = b + 1) {
    b = csv.find('\n', a);
    if (b == std::string::npos) b = csv.size();
    lines.push_back(csv.substr(a, b - a));
  }
  ASSERT_GE(lines.size(), 4u);
  lines[3] = "0.25" + lines[3].substr(lines[3].find(','));
  std::string edited;
  for (const std::string& l : lines) edited += l + "\n";
  dir_.Write("data/flat_markers_long.csv", edited);
  ExpectFitError(Edited("flat_markers.csv", "flat_markers_long.csv", "outside"),
                 {"flat_markers_long.csv:4", "s", "0.25", "outside [0, 0.2"});
}

TEST_F(FitCliErrorTest, BoundsWithMinNotBelowMax) {
  ExpectFitError(Edited("START1, fit: true, min: 1.0e-8, max: 1.0e-3",
                        "START1, fit: true, min: 1.0e-5, max: 1.0e-5", "bounds"),
                 {"bounds.yaml:3", "max", "min"});
}

TEST_F(FitCliErrorTest, StartOutsideTheBounds) {
  ExpectFitError(Edited("START1, fit: true, min: 1.0e-8, max: 1.0e-3",
                        "START1, fit: true, min: 1.0e-5, max: 1.0e-3", "start"),
                 {"start.yaml:3", "value", "below min"});
}

TEST_F(FitCliErrorTest, FitThatDoesNotConvergeIsAnError) {
  // One Levenberg–Marquardt iteration from a start three decades too soft cannot converge.
  std::string text = Replace(kExperiment, "value: START1", "value: 1.0e-8");
  text = Replace(text, "value: START2", "value: 1.0e-8");
  text += "fit: {max_iterations: 1}\n";
  ExpectFitError(WriteFitExperiment(text, "capped"),
                 {"capped.yaml", "did not converge", "no profile written"});
}

TEST_F(FitCliErrorTest, ForwardSolveThatFailsIsAnError) {
  // A 400 N tip force pushing the `rolled` thread back along its clamp axis: two thirds of its
  // stretch stiffness EA and millions of times its Euler load pi^2 B / 4L^2. The statics solver
  // finds no equilibrium at the start (B = 3e-6 N m^2) nor at the upper bound (1e-3; `rodfit
  // simulate` reports the iteration cap at both), so the fit cannot even begin and must fail
  // without writing a profile.
  const std::string path = Edited("normal: [0, 1, 0]}\n",
                                  "normal: [0, 1, 0]}\n    tip_force: [-400, 0, 0]\n", "buckled");
  ExpectFitError(path, {"buckled.yaml", "forward solve", "no profile written"});
}

TEST_F(FitCliErrorTest, ReportThatCannotBeWrittenLeavesNoProfile) {
  // --report names a plain file: the run fails, and a failed run leaves no output behind.
  const std::string not_a_dir = dir_.Write("report_is_a_file", "x");
  const std::string profile = dir_.File("bad_profile.json");
  const RunResult run =
      Rodfit("fit " + Q(good_) + " -o " + Q(profile) + " --report " + Q(not_a_dir) + " -q");
  EXPECT_GT(run.status, 0);
  EXPECT_THAT(run.err, StartsWith("rodfit"));
  EXPECT_THAT(run.err, HasSubstr("report_is_a_file"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(fs::exists(profile));
}

TEST_F(FitCliErrorTest, SpringStiffnessWithoutSprings) {
  // No top-level `springs:` at all: K has nothing to act on.
  ExpectFitError(Edited("stretch_stiffness: {value: 589}",
                        "stretch_stiffness: {value: 589}\n"
                        "  spring_stiffness: {value: 10, fit: true}",
                        "springs"),
                 {"springs.yaml", "spring_stiffness", "no springs"});
  // Springs, but the only zone has its own stiffness parameter: spring_stiffness still acts on
  // nothing.
  ExpectFitError(
      Edited("stretch_stiffness: {value: 589}\n",
             "stretch_stiffness: {value: 589}\n  spring_stiffness: {value: 10, fit: true}\n"
             "  mesentery: {value: 10}\nsprings:\n  - {from: 0.1, to: 0.2, parameter: mesentery}\n",
             "zone_springs"),
      {"zone_springs.yaml", "spring_stiffness", "no spring zone"});
}

}  // namespace
}  // namespace rodfit
