// Tests that rodfit's outputs do not mislead, run as a user would:
// `rodfit --version` prints the project's version, which the profile and truth.json carry; a
// fitted parameter the data do not determine is written with no value (null, its start apart)
// and the fit exits 4; `fit.trusted_sigmas: true` still checks the residual variance and warns
// when the stated sigmas do not match the residuals; and 3-D observations given in millimetres
// are an error naming the file.
#include <algorithm>
#include <filesystem>
#include <regex>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "rodfit/io/csv.h"
#include "rodfit/version.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::ReadText;
using test::Replace;
using test::RunResult;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// A braided suture sagging under gravity in one plane, seen by 10 markers with 0.3 mm noise:
// the markers determine the bending stiffness, and nothing twists the rod, so they do not depend
// on the twist stiffness at all. BEND and TWIST are the parameter entries, SIGMA the markers'
// stated sigma and FIT the optional `fit:` section.
const char* const kExperiment =
    R"(rod: {length: 0.2, segments: 20, radius: 2.5e-4, linear_density: 2.24e-4}
parameters:
  bend_stiffness: BEND
  twist_stiffness: TWIST
  stretch_stiffness: {value: 589}
gravity: [0, 0, -9.81]
cases:
  - name: flat
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    observations:
      - {type: markers3d, file: flat_markers.csv, sigma: SIGMA, count: 10}
FIT)";

const char* const kTrueBend = "{value: 9.2e-6}";
const char* const kFitBend = "{value: 3.0e-6, fit: true, min: 1.0e-8, max: 1.0e-3}";

std::string Experiment(const std::string& bend, const std::string& twist, const std::string& sigma,
                       const std::string& fit = "") {
  std::string text = Replace(kExperiment, "BEND", bend);
  text = Replace(text, "TWIST", twist);
  text = Replace(text, "SIGMA", sigma);
  return Replace(text, "FIT", fit);
}

class HonestOutputsTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) { return test::RunRodfit(dir_, args); }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // Synthesizes the experiment at the truth (B = 9.2e-6, GJ = 6.8e-6, markers' sigma 0.3 mm,
  // seed 3) into DIR/data.
  void Synthesize() {
    const std::string protocol =
        dir_.Write("in/protocol.yaml", Experiment(kTrueBend, "{value: 6.8e-6}", "3.0e-4"));
    const RunResult run = Rodfit("synth " + Q(protocol) + " -o " + Q(dir_.File("data")) +
                                 " --seed 3");
    ASSERT_EQ(run.status, 0) << run.err;
  }

  // `rodfit fit DIR/data/NAME.yaml -o DIR/NAME.json EXTRA` with the experiment `text` written
  // beside the synthesized data.
  RunResult Fit(const std::string& name, const std::string& text, const std::string& extra = "") {
    const std::string experiment = dir_.Write("data/" + name + ".yaml", text);
    return Rodfit("fit " + Q(experiment) + " -o " + Q(Profile(name)) + " " + extra);
  }
  std::string Profile(const std::string& name) const { return dir_.File(name + ".json"); }

  TempDir dir_;
};

TEST_F(HonestOutputsTest, VersionIsTheProjectVersion) {
  EXPECT_TRUE(std::regex_match(std::string(RODFIT_VERSION), std::regex(R"(\d+\.\d+\.\d+)")))
      << RODFIT_VERSION;
  const RunResult run = Rodfit("--version");
  EXPECT_EQ(run.status, 0);
  EXPECT_EQ(run.out, std::string("rodfit ") + RODFIT_VERSION + "\n");
  EXPECT_EQ(run.err, "");
  EXPECT_THAT(Rodfit("--help").out, HasSubstr("--version"));
}

TEST_F(HonestOutputsTest, ProfileAndTruthCarryTheVersionAndTheStarts) {
  Synthesize();
  const json truth = json::parse(ReadText(dir_.File("data/truth.json")));
  EXPECT_EQ(truth["rodfit_version"], RODFIT_VERSION);

  const RunResult run = Fit("fit", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-4"), "--quiet");
  ASSERT_EQ(run.status, 0) << run.err;
  const json p = json::parse(ReadText(Profile("fit")));
  EXPECT_EQ(p["rodfit_version"], RODFIT_VERSION);
  const json& b = p["parameters"]["bend_stiffness"];
  EXPECT_EQ(b["identifiable"], true);
  EXPECT_DOUBLE_EQ(b["start"].get<double>(), 3.0e-6);
  EXPECT_NEAR(b["value"].get<double>(), 9.2e-6, 3.0 * b["std"].get<double>());
  // A parameter that is not fitted has no start: its value is the given one.
  EXPECT_FALSE(p["parameters"]["twist_stiffness"].contains("start"));
  EXPECT_DOUBLE_EQ(p["parameters"]["twist_stiffness"]["value"].get<double>(), 6.8e-6);
}

TEST_F(HonestOutputsTest, UnidentifiableParameterIsWrittenWithoutAValue) {
  Synthesize();
  const RunResult run =
      Fit("planar", Experiment(kFitBend, "{value: 2.0e-6, fit: true, min: 1.0e-7, max: 1.0e-4}",
                               "3.0e-4"));
  // The profile is written, and the status says that not every fitted parameter is determined.
  EXPECT_EQ(run.status, 4) << run.err;
  ASSERT_TRUE(fs::exists(Profile("planar"))) << run.err;
  EXPECT_THAT(run.err, HasSubstr("twist_stiffness"));
  EXPECT_THAT(run.err, HasSubstr("NOT IDENTIFIABLE"));
  const json p = json::parse(ReadText(Profile("planar")));
  const json& gj = p["parameters"]["twist_stiffness"];
  // Where the fit stopped is not a measurement: no number an importer could take for one.
  EXPECT_TRUE(gj["value"].is_null()) << gj.dump();
  EXPECT_TRUE(gj["std"].is_null()) << gj.dump();
  EXPECT_EQ(gj["fitted"], true);
  EXPECT_EQ(gj["identifiable"], false);
  EXPECT_DOUBLE_EQ(gj["start"].get<double>(), 2.0e-6);
  ASSERT_TRUE(gj["reason"].is_string()) << gj.dump();
  EXPECT_FALSE(gj["reason"].get<std::string>().empty());
  // The bending stiffness is determined and keeps its value.
  const json& b = p["parameters"]["bend_stiffness"];
  EXPECT_EQ(b["identifiable"], true);
  ASSERT_TRUE(b["value"].is_number()) << b.dump();
  EXPECT_NEAR(b["value"].get<double>(), 9.2e-6, 3.0 * b["std"].get<double>());
}

TEST_F(HonestOutputsTest, TrustedSigmasStillCheckTheResidualVariance) {
  Synthesize();
  const std::string trusted = "fit: {trusted_sigmas: true}\n";
  // Sigmas that match the noise: the variance is about 1 and nothing is said, with --quiet.
  {
    const RunResult run =
        Fit("right", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-4", trusted), "--quiet");
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_EQ(run.err, "");
    const json fit = json::parse(ReadText(Profile("right")))["fit"];
    EXPECT_EQ(fit["sigmas_trusted"], true);
    EXPECT_GT(fit["residual_variance"].get<double>(), 0.38);  // the band for 29 dof
    EXPECT_LT(fit["residual_variance"].get<double>(), 2.0);
  }
  // Sigmas stated ten times too small (mm read as 0.1 mm, or a model that misses a load): the
  // variance is ~100; the profile says so and one warning line does, even with --quiet, and the
  // exit status 5 says that the values are not to be used as they stand.
  {
    const RunResult run =
        Fit("small", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-5", trusted), "--quiet");
    ASSERT_EQ(run.status, 5) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit fit: warning: residual variance "));
    EXPECT_THAT(run.err, HasSubstr("x the stated sigmas"));
    EXPECT_THAT(run.err, HasSubstr("the model does not explain the data"));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    const json fit = json::parse(ReadText(Profile("small")))["fit"];
    EXPECT_GT(fit["residual_variance"].get<double>(), 30.0);
    EXPECT_EQ(fit["residuals_explained"], false);
    // The band for 29 degrees of freedom: about 0.39 to 2.0.
    EXPECT_NEAR(fit["residual_variance_band"][0].get<double>(), 0.39, 0.02);
    EXPECT_NEAR(fit["residual_variance_band"][1].get<double>(), 2.0, 0.05);
  }
  // Sigmas ten times too large: the variance is ~0.01, the std far too pessimistic.
  {
    const RunResult run =
        Fit("large", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-3", trusted), "--quiet");
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit fit: warning: residual variance "));
    EXPECT_THAT(run.err, HasSubstr("scatter less than the sigmas say"));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }
}

TEST_F(HonestOutputsTest, UntrustedSigmasAreNotWarnedAboutAsTrusted) {
  // Without trusted_sigmas the variance rescales the std (the fit absorbs wrong sigmas), so the
  // trusted-sigmas warning does not apply.
  Synthesize();
  const RunResult run = Fit("untrusted", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-3"),
                            "--quiet");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
}

TEST_F(HonestOutputsTest, UntrustedSigmasStillSayWhenTheResidualsExceedThem) {
  // Untrusted sigmas scale the std by the residual variance, which covers noise stated too
  // small but not a model error: above the band one warning line says so (even with --quiet)
  // and the profile marks it; far above it (sigmas 100 times too small, a model far from the
  // data) the exit status is 5.
  Synthesize();
  {
    const RunResult run =
        Fit("third", Experiment(kFitBend, "{value: 6.8e-6}", "1.0e-4"), "--quiet");
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit fit: warning: residual variance "));
    EXPECT_THAT(run.err, HasSubstr("the sigmas understate the noise, or the model misses"));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    const json fit = json::parse(ReadText(Profile("third")))["fit"];
    EXPECT_EQ(fit["residuals_explained"], false);
  }
  {
    const RunResult run =
        Fit("hundredth", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-6"), "--quiet");
    ASSERT_EQ(run.status, 5) << run.err;
    EXPECT_THAT(run.err, HasSubstr("the model does not explain the data"));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }
  {
    const RunResult run =
        Fit("right", Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-4"), "--quiet");
    ASSERT_EQ(run.status, 0) << run.err;
    EXPECT_EQ(run.err, "");
    const json fit = json::parse(ReadText(Profile("right")))["fit"];
    EXPECT_EQ(fit["residuals_explained"], true);
  }
}

// The markers of DIR/data/flat_markers.csv with x, y, z multiplied by 1000 (millimetres), as
// DIR/data/NAME; `with_s` keeps the s column (markers3d), else x,y,z only (points3d).
void WriteInMillimetres(const TempDir& dir, const std::string& name, bool with_s) {
  const CsvTable t = CsvTable::Read(dir.File("data/flat_markers.csv"));
  const auto s = t.Column("s"), x = t.Column("x"), y = t.Column("y"), z = t.Column("z");
  std::string csv = with_s ? "s,x,y,z\n" : "x,y,z\n";
  for (int r = 0; r < t.num_rows(); ++r)
    csv += (with_s ? FormatDouble(s[r]) + "," : "") + FormatDouble(1000 * x[r]) + "," +
           FormatDouble(1000 * y[r]) + "," + FormatDouble(1000 * z[r]) + "\n";
  dir.Write("data/" + name, csv);
}

TEST_F(HonestOutputsTest, MarkersInMillimetresAreAnError) {
  Synthesize();
  WriteInMillimetres(dir_, "flat_markers_mm.csv", true);
  const std::string text = Replace(Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-4"),
                                   "flat_markers.csv", "flat_markers_mm.csv");
  const RunResult run = Fit("mm", text);
  EXPECT_EQ(run.status, 1) << run.err;
  EXPECT_THAT(run.err, StartsWith("rodfit: "));
  EXPECT_THAT(run.err, HasSubstr("flat_markers_mm.csv"));
  EXPECT_THAT(run.err, HasSubstr("x the rod length 0.2 m"));
  EXPECT_THAT(run.err, HasSubstr("millimetres given as metres"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(fs::exists(Profile("mm")));
}

TEST_F(HonestOutputsTest, PointsInMillimetresAreAnError) {
  Synthesize();
  WriteInMillimetres(dir_, "flat_points_mm.csv", false);
  const std::string text =
      Replace(Experiment(kFitBend, "{value: 6.8e-6}", "3.0e-4"),
              "{type: markers3d, file: flat_markers.csv, sigma: 3.0e-4, count: 10}",
              "{type: points3d, file: flat_points_mm.csv, sigma: 3.0e-4}");
  const RunResult run = Fit("mm_points", text);
  EXPECT_EQ(run.status, 1) << run.err;
  EXPECT_THAT(run.err, HasSubstr("flat_points_mm.csv"));
  EXPECT_THAT(run.err, HasSubstr("millimetres given as metres"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_FALSE(fs::exists(Profile("mm_points")));
}

}  // namespace
}  // namespace rodfit
