// Limits and diagnoses of hostile input not covered by hostile_input_cli_test.cc and
// atomic_bounded_cli_test.cc, one named test each, run as a user would: scene YAML nested 50,000
// levels (flow and block) and YAML aliases (2000 aliased cases, a billion laughs) refused before
// any work with the limit named; every documented limit (segments, section nodes, synth counts,
// blur, image size) checked up front with the limit in the message; a NUL byte named as such;
// and the fit's diagnoses: a marker at 1e308 refused at read time naming the file and line, a
// camera behind the rod or looking elsewhere named (camera file and case) before the fit, a
// camera with k1 = 1e300 refused naming its file and key, a corrupt PNG giving one line (no
// libpng line), and a forward solve that fails told apart from bad data.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::ReadText;
using test::Replace;
using test::RunResult;
using test::TempDir;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

const std::string kCantilever = RODFIT_SOURCE_DIR "/data/scenes/cantilever.yaml";
const std::string kSuture = RODFIT_SOURCE_DIR "/calibration/suture_cantilever/";

class LimitsDiagnosesCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) { return test::RunRodfit(dir_, args); }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // One line on stderr naming `file`, exit 1, and no output folder.
  void ExpectRefused(const RunResult& run, const std::string& file, const std::string& message) {
    EXPECT_EQ(run.status, 1) << run.err;
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_LE(run.err.size(), 301u) << run.err;
    EXPECT_THAT(run.err, HasSubstr(file));
    EXPECT_THAT(run.err, HasSubstr(message));
    EXPECT_FALSE(fs::exists(dir_.File("out")));
  }

  RunResult Simulate(const std::string& scene_text) {
    return Rodfit("simulate " + Q(dir_.Write("scene.yaml", scene_text)) + " -o " +
                  Q(dir_.File("out")));
  }

  // The suture recipe copied into the test folder (its data and cameras), for the fit.
  std::string CopySuture() {
    for (const auto& entry : fs::directory_iterator(kSuture))
      fs::copy_file(entry.path(), dir_.File("in/" + entry.path().filename().string()),
                    fs::copy_options::overwrite_existing);
    return dir_.File("in/experiment.yaml");
  }
  RunResult FitSuture(const std::string& experiment) {
    return Rodfit("fit " + Q(experiment) + " -o " + Q(dir_.File("out/profile.json")) + " -q");
  }

  void SetUp() override { fs::create_directories(dir_.File("in")); }

  TempDir dir_;
};

TEST_F(LimitsDiagnosesCliTest, SceneNestedFiftyThousandLevelsIsRefusedWithTheLimit) {
  const std::string scene = ReadText(kCantilever);
  std::string flow = "[", maps, dashes, block;
  for (int i = 0; i < 50000; ++i) {
    flow += "[";
    maps += "{a: ";
    dashes += "- ";
  }
  for (int i = 1; i < 2000; ++i) block += std::string(i, ' ') + "a:\n";
  for (const std::string& extra :
       {"extra: " + flow + "\n", "extra: " + maps + "1\n", "extra:\n  " + dashes + "x\n",
        "extra:\n" + block}) {
    SCOPED_TRACE(extra.substr(0, 20));
    ExpectRefused(Simulate(scene + extra), "scene.yaml", "levels deep (at most 64)");
  }
}

TEST_F(LimitsDiagnosesCliTest, TwoThousandAliasedCasesAreRefusedWithTheLimit) {
  std::string scene = ReadText(kCantilever);
  scene = scene.substr(0, scene.find("cases:")) +
          "cases:\n  - &c\n    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], "
          "normal: [0, 0, 1]}\n";
  for (int i = 0; i < 1999; ++i) scene += "  - *c\n";
  ExpectRefused(Simulate(scene), "scene.yaml", "cases: at most 1000 cases, got 2000");
}

TEST_F(LimitsDiagnosesCliTest, BillionLaughsAreRefusedWithTheLimit) {
  std::string extra = "extra:\n  a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i < 12; ++i) {
    extra += "  a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) extra += (k ? ", *a" : "*a") + std::to_string(i - 1);
    extra += "]\n";
  }
  ExpectRefused(Simulate(ReadText(kCantilever) + extra), "scene.yaml",
                "more than 1000000 YAML nodes with aliases expanded (the limit)");
}

TEST_F(LimitsDiagnosesCliTest, DocumentedLimitsAreCheckedUpFrontWithTheLimit) {
  const std::string scene = ReadText(kCantilever);
  ExpectRefused(Simulate(Replace(scene, "segments: 50", "segments: 1000000")), "scene.yaml",
                "rod.segments: must be an integer in [2, 100000], got 1000000");
  ExpectRefused(Simulate(Replace(scene, "segments: 50", "segments: 1e9")), "scene.yaml",
                "rod.segments: must be an integer in [2, 100000], got '1e9'");
  ExpectRefused(Simulate(Replace(scene, "gravity:", "section: {radius: 1.0e-3, nodes: 4096}\n"
                                                    "gravity:")),
                "scene.yaml", "section.nodes: must be an integer in [8, 256], got 4096");
  // synth: counts and blur, before anything is solved or rendered.
  const std::string synth = dir_.Write(
      "in/synth.yaml",
      scene + "    observations:\n"
                                           "      - {type: markers3d, file: m.csv, sigma: 1.0e-4, "
                                           "count: 1000000000}\n");
  RunResult run = Rodfit("synth " + Q(synth) + " -o " + Q(dir_.File("out")));
  ExpectRefused(run, "synth.yaml", "count: must be an integer in [1, 100000], got 1000000000");
  fs::copy_file(RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml", dir_.File("in/cam.yaml"));
  dir_.Write("in/synth.yaml",
             scene + "    observations:\n"
                     "      - {type: images, file: i.png, camera: cam.yaml, sigma: 0.5, blur: 1e6}\n");
  run = Rodfit("synth " + Q(synth) + " -o " + Q(dir_.File("out")));
  ExpectRefused(run, "synth.yaml", "blur: must be in [0, 100], got 1000000");
  // A camera's image size bounds what synth renders and extract decodes.
  dir_.Write("in/cam.yaml", Replace(ReadText(dir_.File("in/cam.yaml")), "image_width: 1280",
                                    "image_width: 1000000000"));
  dir_.Write("in/synth.yaml",
             scene + "    observations:\n"
                     "      - {type: images, file: i.png, camera: cam.yaml, sigma: 0.5}\n");
  run = Rodfit("synth " + Q(synth) + " -o " + Q(dir_.File("out")));
  ExpectRefused(run, "cam.yaml", "image_width: expected a positive integer of at most 16384 px");
}

TEST_F(LimitsDiagnosesCliTest, NulByteInAYamlIsNamedAsSuch) {
  const std::string scene = Replace(ReadText(kCantilever), "segments: 50",
                                    std::string("segments: \"4\0\"", 14));
  const RunResult run = Simulate(scene);
  ExpectRefused(run, "scene.yaml:", "control character 0x00: not a YAML text");
  EXPECT_THAT(run.err, Not(HasSubstr("escape")));
}

TEST_F(LimitsDiagnosesCliTest, MarkerAt1e308IsRefusedAtReadTimeNamingFileAndLine) {
  const std::string experiment = CopySuture();
  const std::string markers = dir_.File("in/up30_markers.csv");
  std::string text = ReadText(markers);
  text.insert(text.find('\n') + 1, "0.1,1e308,0,0\n");
  std::ofstream(markers, std::ios::trunc) << text;
  ExpectRefused(FitSuture(experiment), "up30_markers.csv:2: x:",
                "more than 10000 rod lengths (0.2 m): not on the rod");
}

TEST_F(LimitsDiagnosesCliTest, HapticLogOutOfReachOrAt1e308IsNamedAsBadData) {
  const std::string drag = RODFIT_SOURCE_DIR "/calibration/tissue_drag/";
  for (const char* f : {"experiment.yaml", "rest_markers.csv", "drag_markers.csv"})
    fs::copy_file(drag + f, dir_.File(std::string("in/") + f));
  const std::string log = ReadText(drag + "drag_force.csv");
  const size_t second = log.find('\n') + 1, third = log.find('\n', second) + 1;
  const std::string row = log.substr(second, third - second);  // t,tool_x,...,fz
  const std::string experiment = dir_.File("in/experiment.yaml");
  // The tool 1e308 m away: refused when the log is read, naming its line and column.
  std::string far = row;
  far.replace(far.find(',') + 1, far.find(',', far.find(',') + 1) - far.find(',') - 1, "1e308");
  dir_.Write("in/drag_force.csv", log.substr(0, second) + far + log.substr(third));
  ExpectRefused(FitSuture(experiment), "drag_force.csv:2: tool_x:",
                "more than 100 rod lengths (0.15 m): not on the rod");
  // Force readings of 1e308 N (fz of every row): their residuals overflow. Bad data, named by
  // the reading, not a solver failure nor a NaN gradient.
  std::string huge = log.substr(0, second);
  for (size_t at = second; at < log.size();) {
    const size_t end = log.find('\n', at);
    const std::string line = log.substr(at, end - at);
    huge += line.substr(0, line.rfind(',') + 1) + "1e308\n";
    at = end + 1;
  }
  dir_.Write("in/drag_force.csv", huge);
  const RunResult run = FitSuture(experiment);
  ExpectRefused(run, "experiment.yaml", "bad data: case drag@t=");
  EXPECT_THAT(run.err, HasSubstr("grasp_force drag_force.csv t="));
  EXPECT_THAT(run.err, HasSubstr("is not finite"));
  EXPECT_THAT(run.err, Not(HasSubstr("nan")));
}

TEST_F(LimitsDiagnosesCliTest, CameraBehindTheRodIsNamedBeforeTheFit) {
  const std::string experiment = CopySuture();
  const std::string camera = dir_.File("in/cam_front.yaml");
  // The camera turned round: the rod is behind it.
  const std::string turned = Replace(ReadText(camera), "-0.1, -0.004999609421, 0.399968753662",
                                    "-0.1, -0.004999609421, -0.399968753662");
  std::ofstream(camera, std::ios::trunc) << turned;
  const RunResult run = FitSuture(experiment);
  ExpectRefused(run, "cam_front.yaml: case flat, image_points flat_front.csv:",
                "lies behind this camera");
  EXPECT_THAT(run.err, Not(HasSubstr("forward solve")));
}

TEST_F(LimitsDiagnosesCliTest, CameraLookingElsewhereIsNamedBeforeTheFit) {
  const std::string experiment = CopySuture();
  const std::string camera = dir_.File("in/cam_top.yaml");
  // Shifted 2 m sideways in its own frame: still in front of the rod, never seeing it.
  const std::string moved = Replace(ReadText(camera), "-0.1, -0.00474962895, 0.398468870835",
                                   "2.0, 2.0, 0.4");
  std::ofstream(camera, std::ios::trunc) << moved;
  const RunResult run = FitSuture(experiment);
  ExpectRefused(run, "cam_top.yaml: case flat, image_points flat_top.csv:",
                "projects entirely outside the");
  EXPECT_THAT(run.err, HasSubstr("the camera looks elsewhere"));
}

TEST_F(LimitsDiagnosesCliTest, CameraWithAbsurdDistortionIsRefusedNamingFileAndKey) {
  const std::string experiment = CopySuture();
  const std::string camera = dir_.File("in/cam_front.yaml");
  const std::string absurd = Replace(ReadText(camera), "-0.08, 0.05", "1e300, 0.05");
  std::ofstream(camera, std::ios::trunc) << absurd;
  const RunResult run = FitSuture(experiment);
  ExpectRefused(run, "cam_front.yaml: distortion_coefficients:", "is absurd");
  EXPECT_THAT(run.err, Not(HasSubstr("nan")));
}

TEST_F(LimitsDiagnosesCliTest, CorruptPngGivesOneLineWithoutTheDecodersOwn) {
  // A real image rendered by synth, its IHDR checksum broken and its data cut short: libpng
  // would print a line of its own.
  const std::string scene = ReadText(kCantilever);
  fs::copy_file(RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml", dir_.File("in/cam.yaml"));
  const std::string synth = dir_.Write(
      "in/synth.yaml", scene + "    observations:\n"
                               "      - {type: images, file: i.png, camera: cam.yaml, sigma: 0.5}\n");
  RunResult run = Rodfit("synth " + Q(synth) + " -o " + Q(dir_.File("made")));
  ASSERT_EQ(run.status, 0) << run.err;
  std::string png = ReadText(dir_.File("made/i.png"));
  ASSERT_GT(png.size(), 64u);
  png[29] = static_cast<char>(png[29] ^ 0x55);
  png.resize(png.size() / 2);
  dir_.Write("in/broken.png", png);
  run = Rodfit("extract " + Q(dir_.File("in/broken.png")) + " --camera " +
               Q(dir_.File("in/cam.yaml")) + " -o " + Q(dir_.File("out/p.csv")));
  ExpectRefused(run, "broken.png", "cannot read the image");
  EXPECT_THAT(run.err, Not(HasSubstr("libpng")));
}

TEST_F(LimitsDiagnosesCliTest, ForwardSolveFailureIsToldApartFromBadData) {
  // One Newton iteration cannot reach the sagging equilibrium: a solver limit, not the data.
  const std::string experiment = CopySuture();
  std::ofstream(experiment, std::ios::app) << "solver: {max_iterations: 1}\n";
  const RunResult run = FitSuture(experiment);
  ExpectRefused(run, "experiment.yaml", "the forward solve fails at the start values");
  EXPECT_THAT(run.err, HasSubstr("a solver limit, not bad data"));
  EXPECT_THAT(run.err, HasSubstr("case "));
}

}  // namespace
}  // namespace rodfit
