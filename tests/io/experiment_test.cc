// Tests of the experiment / scene YAML reader (io/experiment.h, docs/formats.md): every class of
// bad input is an InputError naming the file, the 1-based line and the key; good files parse to the
// right values, with paths resolved against the YAML file's folder.
#include "rodfit/io/experiment.h"

#include <array>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "temp_dir.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

// A valid scene; the tests below change one line each, so the line numbers in comments hold.
const char* const kBase =
    "rod:\n"                                                                      // 1
    "  length: 0.2\n"                                                             // 2
    "  segments: 10\n"                                                            // 3
    "  radius: 1.0e-4\n"                                                          // 4
    "  linear_density: 5.0e-5\n"                                                  // 5
    "  rest_curvature: [0, 0, 0]\n"                                               // 6
    "parameters:\n"                                                               // 7
    "  bend_stiffness: {value: 1.0e-6, fit: true, min: 1.0e-9, max: 1.0e-3}\n"    // 8
    "  twist_stiffness: {value: 8.0e-7}\n"                                        // 9
    "  stretch_stiffness: {value: 245}\n"                                         // 10
    "  spring_stiffness: {value: 0}\n"                                            // 11
    "gravity: [0, 0, -9.81]\n"                                                    // 12
    "cases:\n"                                                                    // 13
    "  - name: flat\n"                                                            // 14
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"   // 15
    "    tip_force: [0, 0, 0]\n"                                                  // 16
    "    point_forces:\n"                                                         // 17
    "      - {s: 0.1, force: [0, 0, -0.001]}\n"                                   // 18
    "    observations:\n"                                                         // 19
    "      - {type: markers3d, file: flat.csv, sigma: 3.0e-4}\n"                  // 20
    "  - name: side\n"                                                            // 21
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 1, 0]}\n";  // 22

class ExperimentTest : public ::testing::Test {
 protected:
  // kBase with the first occurrence of `from` replaced by `to`.
  static std::string With(const std::string& from, const std::string& to) {
    std::string text = kBase;
    const size_t pos = text.find(from);
    EXPECT_NE(pos, std::string::npos) << from;
    if (pos != std::string::npos) text.replace(pos, from.size(), to);
    return text;
  }

  // Loads `yaml` from a file and returns the InputError's message ("" and a failure if none).
  std::string Error(const std::string& yaml) {
    const std::string path = dir_.Write("scene.yaml", yaml);
    try {
      LoadExperiment(path);
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "not one line";
      return e.what();
    }
    ADD_FAILURE() << "no InputError for:\n" << yaml;
    return "";
  }

  // The error names this file, line and key: `FILE:LINE: KEY:`.
  void ExpectError(const std::string& yaml, int line, const std::string& key) {
    EXPECT_THAT(Error(yaml),
                HasSubstr(dir_.File("scene.yaml") + ":" + std::to_string(line) + ": " + key + ":"));
  }

  TempDir dir_;
};

TEST_F(ExperimentTest, BaseSceneIsValid) {
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", kBase));
  EXPECT_EQ(ex.scene.cases.size(), 2u);
}

TEST_F(ExperimentTest, MalformedYamlNamesTheLine) {
  const std::string message = Error(With("  segments: 10", "   segments: 10"));
  EXPECT_THAT(message, HasSubstr(dir_.File("scene.yaml") + ":3: "));
}

TEST_F(ExperimentTest, UnknownKeysAreNamedAtEveryLevel) {
  ExpectError(With("gravity:", "gravty:"), 12, "gravty");
  ExpectError(With("  radius:", "  raduis:"), 4, "rod.raduis");
  ExpectError(With("{value: 245}", "{value: 245, fitt: true}"), 10,
              "parameters.stretch_stiffness.fitt");
  ExpectError(With("tangent: [1, 0, 0], normal: [0, 0, 1]", "tangnt: [1, 0, 0], normal: [0, 0, 1]"),
              15, "cases[0].clamp.tangnt");
  ExpectError(With("    tip_force:", "    tip_forse:"), 16, "cases[0].tip_forse");
  ExpectError(With("{s: 0.1,", "{s: 0.1, where: 1,"), 18, "cases[0].point_forces[0].where");
  ExpectError(With("sigma: 3.0e-4}", "sigm: 3.0e-4}"), 20, "cases[0].observations[0].sigm");
}

TEST_F(ExperimentTest, UnknownParameterName) {
  ExpectError(With("  spring_stiffness:", "  spring_stifness:"), 11, "parameters.spring_stifness");
}

TEST_F(ExperimentTest, DuplicateKey) {
  ExpectError(With("  segments: 10\n", "  segments: 10\n  segments: 12\n"), 4, "rod.segments");
}

TEST_F(ExperimentTest, MissingRequiredKeys) {
  ExpectError(With("  length: 0.2\n", ""), 1, "rod.length");
  ExpectError(With("  segments: 10\n", ""), 1, "rod.segments");
  ExpectError(With("  radius: 1.0e-4\n", ""), 1, "rod.radius");
  ExpectError(With("  linear_density: 5.0e-5\n", ""), 1, "rod.linear_density");
  ExpectError(With("  bend_stiffness: {value: 1.0e-6, fit: true, min: 1.0e-9, max: 1.0e-3}\n", ""),
              7, "parameters.bend_stiffness");
  ExpectError(With("  twist_stiffness: {value: 8.0e-7}\n", ""), 7, "parameters.twist_stiffness");
  ExpectError(With("  stretch_stiffness: {value: 245}\n", ""), 7, "parameters.stretch_stiffness");
  ExpectError(With("{value: 8.0e-7}", "{fit: false}"), 9, "parameters.twist_stiffness.value");
  ExpectError(With("    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 1, 0]}\n", ""),
              21, "cases[1].clamp");
  ExpectError(With("tangent: [1, 0, 0], normal: [0, 0, 1]", "tangent: [1, 0, 0]"), 15,
              "cases[0].clamp.normal");
  // Keys missing from the document itself have no line to name.
  const std::string text = kBase;
  EXPECT_THAT(Error(text.substr(0, text.find("cases:"))),
              HasSubstr(dir_.File("scene.yaml") + ": cases: missing"));
  EXPECT_THAT(Error(text.substr(text.find("parameters:"))),
              HasSubstr(dir_.File("scene.yaml") + ": rod: missing"));
}

TEST_F(ExperimentTest, NonPositiveSizesAndStiffnesses) {
  ExpectError(With("length: 0.2", "length: 0"), 2, "rod.length");
  ExpectError(With("radius: 1.0e-4", "radius: -1.0e-4"), 4, "rod.radius");
  // Issue 34: a radius outside its physical range (1e-7 to 1 m, at most the length) is refused
  // where it is read, not left to overflow in an export.
  for (const auto& [value, message] :
       {std::pair<std::string, std::string>{"1.0e308", "1e+308 m is outside the physical range"},
        {"1.0e-300", "1e-300 m is outside the physical range"},
        {"0.5", "0.5 m is more than the rod's length 0.2 m"}}) {
    ExpectError(With("radius: 1.0e-4", "radius: " + value), 4, "rod.radius");
    EXPECT_THAT(Error(With("radius: 1.0e-4", "radius: " + value)), HasSubstr(message));
  }
  ExpectError(With("linear_density: 5.0e-5", "linear_density: -1"), 5, "rod.linear_density");
  ExpectError(With("{value: 1.0e-6,", "{value: 0,"), 8, "parameters.bend_stiffness.value");
  ExpectError(With("{value: 8.0e-7}", "{value: -8.0e-7}"), 9, "parameters.twist_stiffness.value");
  ExpectError(With("{value: 245}", "{value: 0}"), 10, "parameters.stretch_stiffness.value");
  ExpectError(With("{value: 0}", "{value: -1}"), 11, "parameters.spring_stiffness.value");
  ExpectError(With("  spring_stiffness: {value: 0}\n",
                   "  spring_stiffness: {value: 0}\n  bend_stiffness_2: {value: 0}\n"),
              12, "parameters.bend_stiffness_2.value");
  // Fitted in log space: a fitted zero and a bound <= 0 have no logarithm.
  ExpectError(With("{value: 0}", "{value: 0, fit: true}"), 11, "parameters.spring_stiffness.value");
  ExpectError(With("min: 1.0e-9", "min: 0"), 8, "parameters.bend_stiffness.min");
}

// A value outside its row's physical range (the one the profile reader, --set and the exports
// check) is refused where the scene is read, naming the key: a 1e-300 kg/m rod was read and
// only refused when its model was built, naming the case instead.
TEST_F(ExperimentTest, ValuesOutsideTheirPhysicalRangeAreNamedByKey) {
  ExpectError(With("linear_density: 5.0e-5", "linear_density: 1.0e-300"), 5,
              "rod.linear_density");
  EXPECT_THAT(Error(With("linear_density: 5.0e-5", "linear_density: 1.0e-300")),
              HasSubstr("physical range"));
  ExpectError(With("{value: 8.0e-7}", "{value: 1.0e-40}"), 9, "parameters.twist_stiffness.value");
  ExpectError(With("{value: 245}", "{value: 1.0e+40}"), 10, "parameters.stretch_stiffness.value");
}

TEST_F(ExperimentTest, ZeroStiffnessSpringIsAllowed) {
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", kBase));
  EXPECT_EQ(ex.scene.material.spring_stiffness, 0.0);
}

TEST_F(ExperimentTest, SegmentsMustBeAnIntegerOfAtLeastTwo) {
  ExpectError(With("segments: 10", "segments: 1"), 3, "rod.segments");
  ExpectError(With("segments: 10", "segments: -4"), 3, "rod.segments");
  ExpectError(With("segments: 10", "segments: 2.5"), 3, "rod.segments");
  ExpectError(With("segments: 10", "segments: ten"), 3, "rod.segments");
}

TEST_F(ExperimentTest, NanAndInfinityAnywhere) {
  ExpectError(With("length: 0.2", "length: .nan"), 2, "rod.length");
  ExpectError(With("rest_curvature: [0, 0, 0]", "rest_curvature: [0, .inf, 0]"), 6,
              "rod.rest_curvature[1]");
  ExpectError(With("{value: 245}", "{value: .NaN}"), 10, "parameters.stretch_stiffness.value");
  ExpectError(With("max: 1.0e-3", "max: .inf"), 8, "parameters.bend_stiffness.max");
  ExpectError(With("gravity: [0, 0, -9.81]", "gravity: [0, 0, -.inf]"), 12, "gravity[2]");
  ExpectError(With("{s: 0.1,", "{s: .nan,"), 18, "cases[0].point_forces[0].s");
  ExpectError(With("sigma: 3.0e-4", "sigma: .nan"), 20, "cases[0].observations[0].sigma");
  ExpectError(With("length: 0.2", "length: nan"), 2, "rod.length");
}

TEST_F(ExperimentTest, VectorsNeedExactlyThreeNumbers) {
  ExpectError(With("gravity: [0, 0, -9.81]", "gravity: [0, -9.81]"), 12, "gravity");
  ExpectError(With("tip_force: [0, 0, 0]", "tip_force: [0, 0, 0, 0]"), 16, "cases[0].tip_force");
  ExpectError(With("position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]",
                   "position: 0, tangent: [1, 0, 0], normal: [0, 0, 1]"),
              15, "cases[0].clamp.position");
  ExpectError(With("force: [0, 0, -0.001]", "force: [0, 0, x]"), 18,
              "cases[0].point_forces[0].force[2]");
}

TEST_F(ExperimentTest, ClampNormalParallelOrTangentZero) {
  ExpectError(With("normal: [0, 0, 1]", "normal: [-2, 0, 0]"), 15, "cases[0].clamp.normal");
  ExpectError(With("normal: [0, 0, 1]", "normal: [1, 0, 1.0e-6]"), 15, "cases[0].clamp.normal");
  ExpectError(With("normal: [0, 0, 1]", "normal: [0, 0, 0]"), 15, "cases[0].clamp.normal");
  ExpectError(
      With("tangent: [1, 0, 0], normal: [0, 0, 1]", "tangent: [0, 0, 0], normal: [0, 0, 1]"), 15,
      "cases[0].clamp.tangent");
}

TEST_F(ExperimentTest, PointForceOutsideTheRod) {
  ExpectError(With("{s: 0.1,", "{s: 0.25,"), 18, "cases[0].point_forces[0].s");
  ExpectError(With("{s: 0.1,", "{s: -0.01,"), 18, "cases[0].point_forces[0].s");
  const Experiment ex = LoadExperiment(dir_.Write("ends.yaml", With("{s: 0.1,", "{s: 0.2,")));
  EXPECT_EQ(ex.scene.cases[0].point_forces[0].s, 0.2);  // the tip itself is on the rod
}

TEST_F(ExperimentTest, BoundsMustBeOrderedAndHoldTheValue) {
  ExpectError(With("min: 1.0e-9, max: 1.0e-3", "min: 1.0e-3, max: 1.0e-3"), 8,
              "parameters.bend_stiffness.max");
  ExpectError(With("min: 1.0e-9, max: 1.0e-3", "min: 1.0e-2, max: 1.0e-3"), 8,
              "parameters.bend_stiffness.max");
  ExpectError(With("min: 1.0e-9", "min: 1.0e-5"), 8, "parameters.bend_stiffness.value");
  ExpectError(With("max: 1.0e-3", "max: 1.0e-7"), 8, "parameters.bend_stiffness.value");
}

TEST_F(ExperimentTest, DuplicateCaseNames) {
  ExpectError(With("  - name: side", "  - name: flat"), 21, "cases[1].name");
}

TEST_F(ExperimentTest, CaseNamesMustBeCsvSafe) {
  ExpectError(With("  - name: side", "  - name: 'a,b'"), 21, "cases[1].name");
}

TEST_F(ExperimentTest, EmptyCaseList) {
  const std::string text = kBase;
  ExpectError(text.substr(0, text.find("cases:")) + "cases: []\n", 13, "cases");
}

TEST_F(ExperimentTest, ObservationTypesAndTheirKeys) {
  ExpectError(With("type: markers3d", "type: marker3d"), 20, "cases[0].observations[0].type");
  ExpectError(With("type: markers3d,", "type: markers3d, camera: cam0.yaml,"), 20,
              "cases[0].observations[0].camera");
  ExpectError(With("type: markers3d", "type: image_points"), 20,
              "cases[0].observations[0].camera");  // a camera is required for pixels
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, s: [0.1, 0.3]}"), 20,
              "cases[0].observations[0].s[1]");
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, s: [0.1], count: 3}"), 20,
              "cases[0].observations[0].count");
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, outliers: 1}"), 20,
              "cases[0].observations[0].outliers");
  ExpectError(With("sigma: 3.0e-4}", "sigma: 0}"), 20, "cases[0].observations[0].sigma");
}

TEST_F(ExperimentTest, ImageBlurAndNoiseAreForImagesOnly) {
  const std::string images = "{type: images, file: a.png, camera: c.yaml, sigma: 1";
  const Experiment ex = LoadExperiment(dir_.Write(
      "scene.yaml", With("{type: markers3d, file: flat.csv, sigma: 3.0e-4",
                         images + ", blur: 1.5, noise: 4")));
  EXPECT_EQ(ex.cases[0].observations[0].blur, 1.5);
  EXPECT_EQ(ex.cases[0].observations[0].noise, 4.0);
  const Experiment plain = LoadExperiment(
      dir_.Write("scene.yaml", With("{type: markers3d, file: flat.csv, sigma: 3.0e-4", images)));
  EXPECT_EQ(plain.cases[0].observations[0].blur, 0.0);  // absent: a sharp, noise-free image
  EXPECT_EQ(plain.cases[0].observations[0].noise, 0.0);
  ExpectError(With("{type: markers3d, file: flat.csv, sigma: 3.0e-4", images + ", blur: -1"), 20,
              "cases[0].observations[0].blur");
  ExpectError(With("{type: markers3d, file: flat.csv, sigma: 3.0e-4", images + ", noise: -0.5"),
              20, "cases[0].observations[0].noise");
  ExpectError(With("{type: markers3d, file: flat.csv, sigma: 3.0e-4", images + ", noise: .nan"),
              20, "cases[0].observations[0].noise");
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, blur: 1}"), 20,
              "cases[0].observations[0].blur");  // markers3d: no image to blur
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, noise: 1}"), 20,
              "cases[0].observations[0].noise");
}

TEST_F(ExperimentTest, ImageRoiAndMaskAreReadAndChecked) {
  const std::string markers = "{type: markers3d, file: flat.csv, sigma: 3.0e-4";
  const std::string images = "{type: images, file: a.png, camera: c.yaml, sigma: 1";
  const Experiment ex = LoadExperiment(dir_.Write(
      "exp/scene.yaml", With(markers, images + ", roi: [10, 20, 610, 420], mask: masks/a.png")));
  const ObservationSpec& obs = ex.cases[0].observations[0];
  ASSERT_TRUE(obs.roi.has_value());
  EXPECT_EQ(*obs.roi, (std::array<int, 4>{10, 20, 610, 420}));
  EXPECT_EQ(obs.mask, dir_.File("exp/masks/a.png"));  // relative to the YAML file
  // The mask is an input: nothing of the run may overwrite it.
  bool listed = false;
  for (const auto& [path, what] : ExperimentInputs(ex, false))
    listed |= path == obs.mask && what == "the mask of cases[0].observations[0]";
  EXPECT_TRUE(listed);
  const Experiment plain = LoadExperiment(dir_.Write("scene.yaml", With(markers, images)));
  EXPECT_FALSE(plain.cases[0].observations[0].roi.has_value());
  EXPECT_TRUE(plain.cases[0].observations[0].mask.empty());

  const std::string key = "cases[0].observations[0].roi";
  EXPECT_THAT(Error(With(markers, images + ", roi: [10, 20, 610]")),
              HasSubstr(key + ": expected [x0, y0, x1, y1] (4 pixel corners), got 3 values"));
  EXPECT_THAT(Error(With(markers, images + ", roi: 10")),
              HasSubstr(key + ": expected [x0, y0, x1, y1]"));
  ExpectError(With(markers, images + ", roi: [10, 20, 610.5, 420]"), 20, key + "[2]");
  ExpectError(With(markers, images + ", roi: [-1, 20, 610, 420]"), 20, key + "[0]");
  ExpectError(With(markers, images + ", roi: [10, 20, 99999, 420]"), 20, key + "[2]");
  EXPECT_THAT(Error(With(markers, images + ", roi: [610, 20, 610, 420]")),
              HasSubstr(key + "[2]: x1 must exceed x0 (610)"));
  EXPECT_THAT(Error(With(markers, images + ", roi: [10, 420, 610, 20]")),
              HasSubstr(key + "[3]: y1 must exceed y0 (420)"));
  ExpectError(With(markers, images + ", mask: \"\""), 20, "cases[0].observations[0].mask");
  // Only an images entry is extracted from an image.
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, roi: [0, 0, 10, 10]}"), 20, key);
  ExpectError(With("sigma: 3.0e-4}", "sigma: 3.0e-4, mask: m.png}"), 20,
              "cases[0].observations[0].mask");
}

TEST_F(ExperimentTest, FitBlockIsValidated) {
  const std::string text = std::string(kBase) + "fit:\n  loss: huberr\n";
  ExpectError(text, 24, "fit.loss");
  ExpectError(std::string(kBase) + "fit:\n  loss_scale: 0\n", 24, "fit.loss_scale");
  ExpectError(std::string(kBase) + "fit:\n  max_iterations: 0\n", 24, "fit.max_iterations");
  ExpectError(std::string(kBase) + "fit:\n  global: maybe\n", 24, "fit.global");
  ExpectError(std::string(kBase) + "fit:\n  globall: true\n", 24, "fit.globall");
}

TEST_F(ExperimentTest, UnreadableOrEmptyFiles) {
  EXPECT_THAT(Error(""), HasSubstr(dir_.File("scene.yaml") + ": empty file"));
  try {
    LoadExperiment(dir_.File("missing.yaml"));
    ADD_FAILURE() << "no error for a missing file";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(dir_.File("missing.yaml") + ": cannot open"));
  }
  EXPECT_THROW(LoadExperiment(dir_.path()), InputError);
  EXPECT_THAT(Error("- 1\n- 2\n"), HasSubstr(dir_.File("scene.yaml") + ":1: expected a mapping"));
}

TEST_F(ExperimentTest, BundledSampleScene) {
  const Experiment ex = LoadExperiment(RODFIT_SOURCE_DIR "/data/scenes/cantilever.yaml");
  const Scene& scene = ex.scene;
  EXPECT_EQ(scene.rod.length, 0.2);
  EXPECT_EQ(scene.rod.segments, 50);
  EXPECT_EQ(scene.rod.radius, 1.25e-4);
  EXPECT_EQ(scene.rod.linear_density, 5.6e-5);
  EXPECT_EQ(scene.material.bend_stiffness, 9.6e-7);
  EXPECT_FALSE(scene.material.bend_stiffness_2.has_value());
  EXPECT_EQ(scene.material.twist_stiffness, 8.0e-7);
  EXPECT_EQ(scene.material.stretch_stiffness, 245.0);
  EXPECT_EQ(scene.material.spring_stiffness, 0.0);
  EXPECT_EQ(scene.gravity, Vec3(0, 0, -9.81));
  ASSERT_EQ(scene.cases.size(), 3u);
  EXPECT_EQ(scene.cases[0].name, "sag");
  EXPECT_EQ(scene.cases[0].clamp.tangent, Vec3(1, 0, 0));
  EXPECT_EQ(scene.cases[0].tip_force, Vec3::Zero());
  EXPECT_EQ(scene.cases[1].name, "tip_force");
  EXPECT_EQ(scene.cases[1].tip_force, Vec3(0, 4.8e-5, 0));
  ASSERT_EQ(scene.cases[1].point_forces.size(), 1u);
  EXPECT_EQ(scene.cases[1].point_forces[0].s, 0.1);
  EXPECT_EQ(scene.cases[2].name, "tip_moment");
  EXPECT_EQ(scene.cases[2].clamp.normal, Vec3(-1, 0, 1));
  EXPECT_EQ(scene.cases[2].tip_moment, Vec3(0, 4.8e-6, 0));
  EXPECT_EQ(ex.cases.size(), 3u);
  EXPECT_FALSE(ex.parameters.at("bend_stiffness").fit);
}

// The example of docs/formats.md, "Example", verbatim, in a sub-folder so that paths must be
// resolved.
TEST_F(ExperimentTest, DesignExampleParsesToTheRightValues) {
  const std::string yaml = R"(rod:
  length: 0.2               # [m]
  segments: 50              # number of edges
  radius: 1.25e-4           # [m]
  linear_density: 5.6e-5    # [kg/m]
  rest_curvature: [0, 0, 0] # [1/m] k1, k2, tau at rest (optional)
parameters:                 # each: value, and optionally fit, min, max
  bend_stiffness:    {value: 1.0e-6, fit: true, min: 1.0e-9, max: 1.0e-3}  # B1 [N m^2]
  bend_stiffness_2:  {value: 1.0e-6, fit: true}                            # B2; absent = B1
  twist_stiffness:   {value: 8.0e-7}                                       # GJ [N m^2]
  stretch_stiffness: {value: 245}                                          # EA [N]
  spring_stiffness:  {value: 0}                                            # K [N/m^2]
gravity: [0, 0, -9.81]      # [m/s^2]
cases:
  - name: flat
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    tip_force: [0, 0, 0]    # [N] at s = L
    tip_moment: [0, 0, 0]   # [N m] at s = L
    observations:
      - {type: markers3d, file: flat_markers.csv, sigma: 3.0e-4}
      - {type: image_points, camera: cam0.yaml, file: flat_cam0.csv, sigma: 0.5}
)";
  const std::string path = dir_.Write("lab/experiment.yaml", yaml);
  const Experiment ex = LoadExperiment(path);
  EXPECT_EQ(ex.path, path);
  EXPECT_EQ(ex.directory, dir_.File("lab"));

  const Parameter& b1 = ex.parameters.at("bend_stiffness");
  EXPECT_EQ(b1.value, 1.0e-6);
  EXPECT_TRUE(b1.fit);
  EXPECT_EQ(b1.min, 1.0e-9);
  EXPECT_EQ(b1.max, 1.0e-3);
  EXPECT_EQ(b1.line, 8);
  const Parameter& b2 = ex.parameters.at("bend_stiffness_2");
  EXPECT_TRUE(b2.fit);
  EXPECT_FALSE(b2.min.has_value());
  EXPECT_FALSE(b2.max.has_value());
  EXPECT_FALSE(ex.parameters.at("twist_stiffness").fit);
  EXPECT_EQ(ex.parameters.size(), 5u);
  EXPECT_EQ(ex.scene.material.bend_stiffness_2, 1.0e-6);
  EXPECT_EQ(ex.scene.material.stretch_stiffness, 245.0);

  ASSERT_EQ(ex.cases.size(), 1u);
  EXPECT_EQ(ex.cases[0].line, 15);
  const auto& obs = ex.cases[0].observations;
  ASSERT_EQ(obs.size(), 2u);
  EXPECT_EQ(obs[0].type, "markers3d");
  EXPECT_EQ(obs[0].file, dir_.File("lab/flat_markers.csv"));
  EXPECT_EQ(obs[0].camera, "");
  EXPECT_EQ(obs[0].sigma, 3.0e-4);
  EXPECT_EQ(obs[0].line, 20);
  EXPECT_EQ(obs[1].type, "image_points");
  EXPECT_EQ(obs[1].file, dir_.File("lab/flat_cam0.csv"));
  EXPECT_EQ(obs[1].camera, dir_.File("lab/cam0.yaml"));
  EXPECT_EQ(obs[1].sigma, 0.5);
  EXPECT_EQ(ex.fit.line, 0);  // no fit: block, defaults
  EXPECT_EQ(ex.fit.loss, RobustLoss::kNone);
}

TEST_F(ExperimentTest, PathsResolveAgainstTheYamlFolder) {
  const std::string yaml =
      With("{type: markers3d, file: flat.csv, sigma: 3.0e-4}",
           "{type: markers3d, file: ../data/m.csv, sigma: 3.0e-4}\n"
           "      - {type: points3d, file: /abs/p.csv, sigma: 1.0e-3, count: 40, outliers: 0.1}\n"
           "      - {type: images, file: img/0001.png, camera: cams/c0.yaml, sigma: 1}\n"
           "      - {type: image_points, file: uv.csv, camera: c0.json, sigma: 0.5, "
           "s: [0, 0.1, 0.2]}");
  const Experiment ex = LoadExperiment(dir_.Write("a/b/scene.yaml", yaml));
  const auto& obs = ex.cases[0].observations;
  ASSERT_EQ(obs.size(), 4u);
  EXPECT_EQ(obs[0].file, dir_.File("a/data/m.csv"));
  EXPECT_EQ(obs[1].file, "/abs/p.csv");
  EXPECT_EQ(obs[1].count, 40);
  EXPECT_EQ(obs[1].outliers, 0.1);
  EXPECT_EQ(obs[2].file, dir_.File("a/b/img/0001.png"));
  EXPECT_EQ(obs[2].camera, dir_.File("a/b/cams/c0.yaml"));
  EXPECT_EQ(obs[3].s, std::vector<double>({0, 0.1, 0.2}));
  EXPECT_EQ(obs[3].line, 23);
}

TEST_F(ExperimentTest, DefaultsForOptionalKeys) {
  const std::string yaml =
      "rod: {length: 1, segments: 4, radius: 0.01, linear_density: 0}\n"
      "parameters:\n"
      "  bend_stiffness: {value: 1}\n"
      "  twist_stiffness: {value: 1}\n"
      "  stretch_stiffness: {value: 1.0e5}\n"
      "cases:\n"
      "  - clamp: {position: [0, 0, 0], tangent: [0, 0, 2], normal: [3, 0, 0]}\n";
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", yaml));
  EXPECT_EQ(ex.scene.gravity, Vec3(0, 0, -9.81));
  EXPECT_EQ(ex.scene.rod.rest_curvature, Vec3::Zero());
  EXPECT_EQ(ex.scene.material.spring_stiffness, 0.0);
  EXPECT_FALSE(ex.scene.material.bend_stiffness_2.has_value());
  EXPECT_EQ(ex.scene.cases[0].name, "case0");
  EXPECT_EQ(ex.scene.cases[0].tip_moment, Vec3::Zero());
  EXPECT_TRUE(ex.cases[0].observations.empty());
  EXPECT_EQ(ex.scene.cases[0].clamp.tangent, Vec3(0, 0, 2));  // kept as given, not normalised
}

TEST_F(ExperimentTest, FitBlock) {
  const std::string yaml = std::string(kBase) +
                           "fit:\n"
                           "  loss: soft_l1\n"
                           "  loss_scale: 2.5\n"
                           "  global: true\n"
                           "  max_iterations: 40\n"
                           "  trusted_sigmas: true\n";
  const Experiment ex = LoadExperiment(dir_.Write("scene.yaml", yaml));
  EXPECT_EQ(ex.fit.loss, RobustLoss::kSoftL1);
  EXPECT_EQ(ex.fit.loss_scale, 2.5);
  EXPECT_TRUE(ex.fit.global);
  EXPECT_EQ(ex.fit.max_iterations, 40);
  EXPECT_TRUE(ex.fit.trusted_sigmas);
  EXPECT_EQ(ex.fit.line, 23);
}

}  // namespace
}  // namespace rodfit
