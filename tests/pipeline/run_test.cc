// The library's entry points (rodfit/pipeline/run.h): what they return is what the CLI writes
// (the profile is ProfileJson of the returned result, the files are the formats of the returned
// records), they write nothing unless an output is named, and their preconditions throw.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "io/temp_dir.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/profile.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/runtime/profile_format.h"

namespace rodfit {
namespace {

const std::string kSource = RODFIT_SOURCE_DIR;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

bool IsEmptyDirectory(const std::string& dir) {
  return std::filesystem::is_empty(std::filesystem::path(dir));
}

TEST(FitExperimentTest, ReturnsTheProfileOfItsResultAndWritesOnlyWhenAsked) {
  const Experiment experiment =
      LoadExperiment(kSource + "/calibration/suture_cantilever/experiment.yaml");
  const FitRun run = FitExperiment(experiment);
  ASSERT_TRUE(run.ok) << run.error;
  EXPECT_FALSE(run.moving);
  EXPECT_TRUE(run.all_determined);
  EXPECT_FALSE(run.misfit);
  EXPECT_EQ(run.profile, ProfileJson(experiment, run.options, run.result,
                                     CheckResiduals(run.result, run.options)));
  // The profile document's structure: parameters by name, each with its value.
  EXPECT_TRUE(run.profile.at("parameters").at("bend_stiffness").at("value").is_number());
  // The writer writes the keys the format declares (the reader's allowed ones): every top-level
  // key (`section` only with one), and in each parameter only declared keys.
  std::set<std::string> top(std::begin(profile_format::kDocumentKeys),
                            std::end(profile_format::kDocumentKeys));
  top.erase(profile_format::kSection);  // the scene has none
  std::set<std::string> keys;
  for (const auto& item : run.profile.items()) keys.insert(item.key());
  EXPECT_EQ(keys, top);
  const std::set<std::string> entry(std::begin(profile_format::kParameterKeys),
                                    std::end(profile_format::kParameterKeys));
  for (const auto& parameter : run.profile.at("parameters").items())
    for (const auto& item : parameter.value().items())
      EXPECT_TRUE(entry.count(item.key())) << parameter.key() << "." << item.key();

  test::TempDir dir;
  FitRunOptions options;
  options.profile_path = dir.File("profile.json");
  const FitRun written = FitExperiment(experiment, options);
  ASSERT_TRUE(written.ok) << written.error;
  EXPECT_EQ(ReadText(options.profile_path), FormatProfile(written.profile));
}

TEST(FitExperimentTest, AReportNeedsItsWriterAndAProfilePath) {
  const Experiment experiment =
      LoadExperiment(kSource + "/calibration/suture_cantilever/experiment.yaml");
  FitRunOptions options;
  options.report_dir = "report";
  EXPECT_THROW(FitExperiment(experiment, options), std::invalid_argument);
}

TEST(SimulateSceneTest, ReturnsTheShapesItsFilesHoldAndWritesOnlyIntoItsDirectory) {
  const Experiment experiment = LoadExperiment(kSource + "/data/scenes/cantilever.yaml");
  const SimulateRun run = SimulateScene(experiment);
  EXPECT_FALSE(run.moving);
  EXPECT_TRUE(run.first_failure.empty()) << run.first_failure;
  ASSERT_EQ(run.shapes.size(), experiment.scene.cases.size());
  EXPECT_EQ(run.shapes[0].x.cols(), experiment.scene.rod.segments + 1);
  ASSERT_GE(run.files.size(), 3u);
  EXPECT_EQ(run.files[0].first, "shapes.csv");
  EXPECT_EQ(run.files[0].second, FormatShapesCsv(run.shapes));

  test::TempDir dir;
  SimulateOptions options;
  options.output_dir = dir.File("out");
  const SimulateRun written = SimulateScene(experiment, options);
  for (const auto& [name, text] : written.files)
    EXPECT_EQ(ReadText(dir.File("out/" + name)), text) << name;
  EXPECT_EQ(written.files[0].second, run.files[0].second);  // the same scene, the same bytes
}

TEST(SimulateSceneTest, MarkersAreForAMovingScene) {
  const Experiment experiment = LoadExperiment(kSource + "/data/scenes/cantilever.yaml");
  test::TempDir dir;
  SimulateOptions options;
  options.marker_count = 5;
  options.output_dir = dir.path();
  EXPECT_THROW(SimulateScene(experiment, options), std::invalid_argument);
  EXPECT_TRUE(IsEmptyDirectory(dir.path()));
}

TEST(RolloutTest, NeedsAMovingSceneAndARecording) {
  const Experiment statics = LoadExperiment(kSource + "/data/scenes/cantilever.yaml");
  try {
    Rollout(statics, {}, {});
    ADD_FAILURE() << "no error for a scene without dynamics";
  } catch (const InputError& e) {
    EXPECT_EQ(e.key, "dynamics");
  }
  const Experiment moving = LoadExperiment(kSource + "/data/scenes/suture_swing.yaml");
  EXPECT_THROW(Rollout(moving, {}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rodfit
