// `rodfit synth` then `rodfit fit` on a moving experiment, as a user would run them (docs/cli.md,
// "fit"; docs/formats.md, "Observation sequences"): the bundled suture swing
// (data/suture_swing_fit/) synthesized from its protocol writes a seeded marker sequence with
// noise and missing samples; fitted from starts 3x off, the bending stiffness and the air drag
// come back within 3 std, and the profile and report are the static fit's. The same swing seen
// only by one camera, as centre-line pixels per frame, gives them back too. Bad input exits 1
// with one line naming the file, line and key, and writes nothing.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::Quote;
using test::ReadText;
using test::Replace;
using test::RunResult;
using test::TempDir;
using ::testing::HasSubstr;

// The 1-based line of the first occurrence of `what` in `text`.
int LineOf(const std::string& text, const std::string& what) {
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + text.find(what), '\n'));
}

const std::string kExample = std::string(RODFIT_SOURCE_DIR) + "/data/suture_swing_fit/";

// `rodfit fit DIR/data/bad.yaml` fails as bad input should: exit 1, one line containing `where`,
// no profile written.
void ExpectFitOfBadYamlFails(const TempDir& dir, const std::string& where) {
  const RunResult run = test::RunRodfit(
      dir, "fit " + Quote(dir.File("data/bad.yaml")) + " -o " + Quote(dir.File("bad.json")));
  EXPECT_EQ(run.status, 1) << run.err;
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  EXPECT_THAT(run.err, HasSubstr(where));
  EXPECT_FALSE(fs::exists(dir.File("bad.json")));
}

// Synthesizes the protocol into `dir` and puts the fit's experiment (the starts) beside the data.
void Synthesize(const TempDir& dir, int seed) {
  const RunResult synth = test::RunRodfit(
      dir, "synth " + Quote(kExample + "protocol.yaml") + " -o " + Quote(dir.File("data")) +
               " --seed " + std::to_string(seed));
  ASSERT_EQ(synth.status, 0) << synth.err;
  fs::copy_file(kExample + "experiment.yaml", dir.File("data/experiment.yaml"),
                fs::copy_options::overwrite_existing);
}

TEST(SequenceFitCli, SynthThenFitRecoversBendingStiffnessAndDrag) {
  TempDir dir;
  Synthesize(dir, 7);
  const std::string csv = ReadText(dir.File("data/swing_markers.csv"));
  EXPECT_EQ(csv.rfind("frame,s,x,y,z\n", 0), 0u);
  // 26 frames x 4 markers, 10 % of them written as not seen.
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 26 * 4);
  size_t missing = 0;
  for (size_t at = csv.find(",,,"); at != std::string::npos; at = csv.find(",,,", at + 1)) ++missing;
  EXPECT_EQ(missing, 10u);
  // The same seed gives the same bytes.
  TempDir again;
  Synthesize(again, 7);
  EXPECT_EQ(ReadText(again.File("data/swing_markers.csv")), csv);

  const RunResult fit = test::RunRodfit(
      dir, "fit " + Quote(dir.File("data/experiment.yaml")) + " -o " +
               Quote(dir.File("profile.json")) + " --report " + Quote(dir.File("report")));
  ASSERT_EQ(fit.status, 0) << fit.err;
  const json profile = json::parse(ReadText(dir.File("profile.json")));
  const json truth = json::parse(ReadText(dir.File("data/truth.json")));
  for (const char* name : {"bend_stiffness", "damping"}) {
    const json& p = profile["parameters"][name];
    ASSERT_TRUE(p["fitted"].get<bool>()) << name;
    ASSERT_TRUE(p["identifiable"].get<bool>()) << name;
    const double value = p["value"], std = p["std"], t = truth["parameters"][name];
    EXPECT_LT(std::abs(value - t), 3.0 * std) << name << " " << value << " +- " << std;
    EXPECT_LT(std, 0.1 * t) << name;
    EXPECT_NE(p["start"].get<double>(), t);
  }
  // Held parameters are listed at their values, tied B2 with B1.
  EXPECT_FALSE(profile["parameters"]["twist_stiffness"]["fitted"].get<bool>());
  EXPECT_EQ(profile["parameters"]["bend_stiffness_2"]["tied_to"], "bend_stiffness");
  const json& summary = profile["fit"];
  EXPECT_TRUE(summary["success"].get<bool>());
  EXPECT_EQ(summary["num_residuals"].get<int>(), 3 * (26 * 4 - 10));
  EXPECT_NEAR(summary["residual_variance"].get<double>(), 1.0, 0.3);
  EXPECT_EQ(summary["correlation"]["parameters"], json({"bend_stiffness", "damping"}));
  ASSERT_EQ(summary["rms"].size(), 1u);
  EXPECT_EQ(summary["rms"][0]["observation"], "markers3d swing_markers.csv");
  EXPECT_EQ(summary["rms"][0]["count"].get<int>(), 26 * 4 - 10);
  // The report's tables: one summary row, one residual row per recorded sample.
  const std::string residuals = ReadText(dir.File("report/residuals.csv"));
  EXPECT_EQ(std::count(residuals.begin(), residuals.end(), '\n'), 1 + 26 * 4 - 10);
  EXPECT_THAT(ReadText(dir.File("report/summary.csv")),
              HasSubstr("swing,markers3d swing_markers.csv,markers3d,94,"));
  EXPECT_TRUE(fs::exists(dir.File("report/index.html")));
}

TEST(SequenceFitCli, BadInputIsOneLineAndWritesNothing) {
  TempDir dir;
  Synthesize(dir, 1);
  const std::string experiment = ReadText(dir.File("data/experiment.yaml"));
  auto fails = [&](const std::string& yaml, const std::string& csv, const std::string& where) {
    dir.Write("data/bad.yaml", yaml);
    dir.Write("data/bad.csv", csv);
    ExpectFitOfBadYamlFails(dir, where);
  };
  const std::string on_bad = Replace(experiment, "file: swing_markers.csv", "file: bad.csv");
  // A frame column without the entry's frame_rate.
  fails(Replace(on_bad, ", frame_rate: 100", ""), "frame,s,x,y,z\n0,0.2,0.2,0,0\n",
        dir.File("data/bad.csv") + ":1: frame:");
  // A sample after the run's end (frame 30 at 100 Hz = 0.3 s > 0.25 s).
  fails(on_bad, "frame,s,x,y,z\n0,0.2,0.2,0,0\n30,0.2,0.2,0,-0.1\n",
        dir.File("data/bad.csv") + ":3: frame:");
  // The midpoint integrator has no sensitivities.
  fails(Replace(experiment, "integrator: bdf2", "integrator: midpoint"), "",
        dir.File("data/bad.yaml") + ":" + std::to_string(LineOf(experiment, "integrator: bdf2")) +
            ": dynamics.integrator: the motion fit differentiates the bdf2 and backward_euler "
            "steps, not midpoint");
  // A fitted damping without motion.
  fails("rod: {length: 0.2, segments: 10, radius: 1.0e-4, linear_density: 5.0e-5}\n"
        "parameters:\n"
        "  bend_stiffness: {value: 1.0e-6}\n"
        "  twist_stiffness: {value: 8.0e-7}\n"
        "  stretch_stiffness: {value: 245}\n"
        "  damping: {value: 1.0e-4, fit: true}\n"
        "cases:\n"
        "  - clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n",
        "", dir.File("data/bad.yaml") + ":6: parameters.damping.fit:");
}

// One camera's view of the swing, frame by frame (docs/formats.md, "Observation sequences"):
// synth writes the centre-line pixels of tests/data/synth/cam_swing.yaml at 100 Hz with 0.5 px of
// noise, and the fit recovers the bending stiffness and the drag from them alone.
TEST(SequenceFitCli, PixelsOfOneCameraRecoverBendingStiffnessAndDrag) {
  TempDir dir;
  const std::string pixels =
      "{type: image_points, file: swing_pixels.csv, camera: cam_swing.yaml, sigma: 0.5, "
      "frame_rate: 100, drop: 0.1}";
  fs::copy_file(std::string(RODFIT_SOURCE_DIR) + "/tests/data/synth/cam_swing.yaml",
                dir.File("cam_swing.yaml"));
  dir.Write("protocol.yaml",
            Replace(ReadText(kExample + "protocol.yaml"),
                    "{type: markers3d, file: swing_markers.csv, sigma: 1.0e-3, s: [0.05, 0.1, "
                    "0.15, 0.2],\n         frame_rate: 100, drop: 0.1}",
                    pixels));
  const RunResult synth = test::RunRodfit(dir, "synth " + Quote(dir.File("protocol.yaml")) +
                                                   " -o " + Quote(dir.File("data")) + " --seed 3");
  ASSERT_EQ(synth.status, 0) << synth.err;
  const std::string csv = ReadText(dir.File("data/swing_pixels.csv"));
  EXPECT_EQ(csv.rfind("frame,u,v\n", 0), 0u);
  // 26 frames of 10 pixels (one per edge, the default), all on the sensor; 10 % not seen.
  const int samples = 26 * 10, seen = samples - 26;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + samples);
  size_t missing = 0;
  for (size_t at = csv.find(",,\n"); at != std::string::npos; at = csv.find(",,\n", at + 1))
    ++missing;
  EXPECT_EQ(static_cast<int>(missing), samples - seen);

  // The fit: the example's experiment (starts 3x off) observed by the pixels alone.
  dir.Write("data/experiment.yaml",
            Replace(ReadText(kExample + "experiment.yaml"),
                    "{type: markers3d, file: swing_markers.csv, sigma: 1.0e-3, frame_rate: 100}",
                    pixels));
  const RunResult fit = test::RunRodfit(
      dir, "fit " + Quote(dir.File("data/experiment.yaml")) + " -o " +
               Quote(dir.File("profile.json")) + " --report " + Quote(dir.File("report")));
  ASSERT_EQ(fit.status, 0) << fit.err;
  const json profile = json::parse(ReadText(dir.File("profile.json")));
  const json truth = json::parse(ReadText(dir.File("data/truth.json")));
  for (const char* name : {"bend_stiffness", "damping"}) {
    const json& p = profile["parameters"][name];
    ASSERT_TRUE(p["identifiable"].get<bool>()) << name;
    const double value = p["value"], std = p["std"], t = truth["parameters"][name];
    std::printf("%-15s truth %.4g  fitted %.4g +- %.2g  (%+.2f std)\n", name, t, value, std,
                (value - t) / std);
    EXPECT_LT(std::abs(value - t), 2.5 * std) << name << " " << value << " +- " << std;
    EXPECT_LT(std, 0.1 * t) << name;
  }
  // Two residuals per pixel, one of them carrying noise (across the imaged curve): the
  // variance is 1 over seen - 2 degrees of freedom.
  const json& summary = profile["fit"];
  EXPECT_EQ(summary["num_residuals"].get<int>(), 2 * seen);
  EXPECT_NEAR(summary["residual_variance"].get<double>(), 1.0, 0.3);
  ASSERT_EQ(summary["rms"].size(), 1u);
  EXPECT_EQ(summary["rms"][0]["observation"], "image_points swing_pixels.csv");
  EXPECT_EQ(summary["rms"][0]["type"], "image_points");
  EXPECT_EQ(summary["rms"][0]["unit"], "px");
  EXPECT_EQ(summary["rms"][0]["count"].get<int>(), seen);
  // The report: one residual row per pixel seen, in pixels.
  const std::string residuals = ReadText(dir.File("report/residuals.csv"));
  EXPECT_EQ(std::count(residuals.begin(), residuals.end(), '\n'), 1 + seen);
  EXPECT_THAT(residuals, HasSubstr("swing,image_points swing_pixels.csv,px,0,"));
  EXPECT_THAT(ReadText(dir.File("report/summary.csv")),
              HasSubstr("swing,image_points swing_pixels.csv,image_points," +
                        std::to_string(seen) + ","));
}

// A clamp force log beside the markers (docs/formats.md, "Observation sequences"; the bundled
// data/suture_swing_fit/experiment_density.yaml on a new draw): synth writes the swing's clamp
// force and moment at 200 Hz, and the fit takes the rod's linear density as a parameter
// (parameters.linear_density) with the stiffness and the drag. The markers alone leave the
// density free (their motion is the same for a rod with mass, stiffness and drag all scaled:
// all three are then reported not identifiable); the force log fixes the scale. All three come
// back within 3 std, the profile's rod carries the fitted density, and `simulate --profile` on a
// scene that leaves the density out uses it.
TEST(SequenceFitCli, AClampForceLogDeterminesTheLinearDensity) {
  TempDir dir;
  const RunResult synth = test::RunRodfit(
      dir, "synth " + Quote(kExample + "protocol.yaml") + " -o " + Quote(dir.File("data")) +
               " --seed 5");
  ASSERT_EQ(synth.status, 0) << synth.err;
  const std::string log = ReadText(dir.File("data/clamp_force.csv"));
  EXPECT_EQ(log.rfind("frame,fx,fy,fz,mx,my,mz\n", 0), 0u);
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1 + 51);  // 0.25 s at 200 Hz, frames 0-50

  const std::string experiment = ReadText(kExample + "experiment_density.yaml");
  dir.Write("data/experiment.yaml", experiment);
  const RunResult fit = test::RunRodfit(
      dir, "fit " + Quote(dir.File("data/experiment.yaml")) + " -o " +
               Quote(dir.File("profile.json")) + " --report " + Quote(dir.File("report")));
  ASSERT_EQ(fit.status, 0) << fit.err;
  const json profile = json::parse(ReadText(dir.File("profile.json")));
  const json truth = json::parse(ReadText(dir.File("data/truth.json")));
  EXPECT_EQ(truth["parameters"]["linear_density"].get<double>(), 5.6e-5);
  for (const char* name : {"bend_stiffness", "damping", "linear_density"}) {
    const json& p = profile["parameters"][name];
    ASSERT_TRUE(p["fitted"].get<bool>()) << name;
    ASSERT_TRUE(p["identifiable"].get<bool>()) << name;
    const double value = p["value"], std = p["std"], t = truth["parameters"][name];
    std::printf("%-15s truth %.4g  fitted %.4g +- %.2g  (%+.2f std)\n", name, t, value, std,
                (value - t) / std);
    EXPECT_LT(std::abs(value - t), 3.0 * std) << name << " " << value << " +- " << std;
    EXPECT_LT(std, 0.02 * t) << name;
  }
  EXPECT_EQ(profile["parameters"]["linear_density"]["unit"], "kg/m");
  EXPECT_EQ(profile["rod"]["linear_density"], profile["parameters"]["linear_density"]["value"]);
  const json& rms = profile["fit"]["rms"];
  ASSERT_EQ(rms.size(), 2u);
  EXPECT_EQ(rms[1]["observation"], "reaction clamp_force.csv");
  EXPECT_EQ(rms[1]["unit"], "N");
  EXPECT_THAT(ReadText(dir.File("report/residuals.csv")),
              HasSubstr("reaction clamp_force.csv,N m,"));

  // Without the force log the three move together: none is identifiable (exit 4).
  std::string markers_only = experiment.substr(0, experiment.find("      - {type: reaction"));
  dir.Write("data/markers_only.yaml", markers_only);
  const RunResult free_scale = test::RunRodfit(
      dir, "fit " + Quote(dir.File("data/markers_only.yaml")) + " -o " +
               Quote(dir.File("markers_only.json")));
  EXPECT_EQ(free_scale.status, 4) << free_scale.err;
  const json scale_free = json::parse(ReadText(dir.File("markers_only.json")));
  for (const char* name : {"bend_stiffness", "damping", "linear_density"})
    EXPECT_FALSE(scale_free["parameters"][name]["identifiable"].get<bool>()) << name;

  // The profile supplies the rod's density to a scene that leaves it out: the same motion as the
  // scene given that density in full.
  std::string scene = experiment;
  scene = scene.substr(0, scene.find("parameters:")) + scene.substr(scene.find("gravity:"));
  dir.Write("data/scene.yaml", scene);
  const RunResult from_profile = test::RunRodfit(
      dir, "simulate " + Quote(dir.File("data/scene.yaml")) + " --profile " +
               Quote(dir.File("profile.json")) + " -o " + Quote(dir.File("sim_profile")));
  ASSERT_EQ(from_profile.status, 0) << from_profile.err;
  dir.Write("data/scene_density.yaml",
            Replace(scene, "radius: 1.25e-4           # [m]\n",
                    "radius: 1.25e-4           # [m]\n  linear_density: " +
                        profile["rod"]["linear_density"].dump() + "\n"));
  const RunResult given = test::RunRodfit(
      dir, "simulate " + Quote(dir.File("data/scene_density.yaml")) + " --profile " +
               Quote(dir.File("profile.json")) + " -o " + Quote(dir.File("sim_given")));
  ASSERT_EQ(given.status, 0) << given.err;
  EXPECT_EQ(ReadText(dir.File("sim_profile/trajectory.csv")),
            ReadText(dir.File("sim_given/trajectory.csv")));
  // A scene whose density differs from the profile's is refused, naming the key.
  dir.Write("data/scene_other.yaml",
            Replace(scene, "radius: 1.25e-4           # [m]\n",
                    "radius: 1.25e-4           # [m]\n  linear_density: 5.0e-5\n"));
  const RunResult other = test::RunRodfit(
      dir, "simulate " + Quote(dir.File("data/scene_other.yaml")) + " --profile " +
               Quote(dir.File("profile.json")) + " -o " + Quote(dir.File("sim_other")));
  EXPECT_EQ(other.status, 1);
  EXPECT_THAT(other.err, HasSubstr("rod.linear_density:"));
  EXPECT_FALSE(fs::exists(dir.File("sim_other/trajectory.csv")));

  // The density given twice, or as a parameter of a scene that does not move: one line each.
  auto fails = [&](const std::string& yaml, const std::string& where) {
    dir.Write("data/bad.yaml", yaml);
    ExpectFitOfBadYamlFails(dir, where);
  };
  fails(Replace(experiment, "radius: 1.25e-4           # [m]\n",
                "radius: 1.25e-4           # [m]\n  linear_density: 5.6e-5\n"),
        dir.File("data/bad.yaml") + ":13: rod.linear_density: given twice");
  std::string still = experiment.substr(0, experiment.find("dynamics:")) +
                      experiment.substr(experiment.find("cases:"));
  still = Replace(still, "  damping:           {value: 6.7e-5, fit: true}    # [N s/m^2]\n", "");
  still = still.substr(0, still.find("    initial:"));
  fails(still,
        dir.File("data/bad.yaml") + ":17: parameters.linear_density: only in a moving scene");
}

}  // namespace
}  // namespace rodfit
