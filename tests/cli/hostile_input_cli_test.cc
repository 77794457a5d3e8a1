// Hostile input through the command line, each kind of bad input that this file
// covers as a test of its own: a poked case named as a path writes nothing anywhere; a camera
// file nested 50,000 levels deep is a one-line error, not a crash; `fit -o` onto its own
// experiment or data is refused before anything is written; `simulate` and `synth` that fail
// while writing leave the output directory as it was; a 1 MiB CSV field and `--threads 0` or
// `--threads 2147483647` give short one-line messages.
#include <algorithm>
#include <filesystem>
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

// A poked bowel segment (as tests/cli/poke_cli_test.cc): simulate writes side.obj and
// sections.csv for it.
const char* const kPokedScene =
    "rod: {length: 0.15, segments: 30, radius: 0.012, linear_density: 0.45}\n"      // 1
    "parameters:\n"                                                                 // 2
    "  bend_stiffness: {value: 2.0e-4}\n"                                           // 3
    "  twist_stiffness: {value: 1.5e-4}\n"                                          // 4
    "  stretch_stiffness: {value: 40}\n"                                            // 5
    "  spring_stiffness: {value: 300}\n"                                            // 6
    "  ring_bend_stiffness: {value: 2.0e-5}\n"                                      // 7
    "  ring_stretch_stiffness: {value: 5.0}\n"                                      // 8
    "springs:\n"                                                                    // 9
    "  - {from: 0.0, to: 0.15}\n"                                                   // 10
    "section: {radius: 0.012, nodes: 32}\n"                                         // 11
    "cases:\n"                                                                      // 12
    "  - name: side\n"                                                              // 13
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"     // 14
    "    poke: {s: 0.075, force: [0, -0.03, 0]}\n";                                 // 15

// A sagging thread with markers, points in a sub-folder and pixels of one camera.
const char* const kExperiment =
    "rod: {length: 0.2, segments: 10, radius: 2.5e-4, linear_density: 5.6e-5}\n"   // 1
    "parameters:\n"                                                                 // 2
    "  bend_stiffness: {value: 1.0e-5, fit: true}\n"                                // 3
    "  twist_stiffness: {value: 8.0e-6}\n"                                          // 4
    "  stretch_stiffness: {value: 245}\n"                                           // 5
    "cases:\n"                                                                      // 6
    "  - name: sag\n"                                                               // 7
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"     // 8
    "    observations:\n"                                                           // 9
    "      - {type: markers3d, file: m.csv, sigma: 3.0e-4, count: 5}\n"             // 10
    "      - {type: points3d, file: sub/p.csv, sigma: 3.0e-4}\n"                    // 11
    "      - {type: image_points, file: uv.csv, camera: CAMERA, sigma: 0.5}\n";     // 12

class HostileInputCliTest : public ::testing::Test {
 protected:
  RunResult Rodfit(const std::string& args) { return test::RunRodfit(dir_, args); }
  static std::string Q(const std::string& s) { return test::Quote(s); }

  // One line on stderr containing `expected`, a non-zero exit and no signal.
  static void ExpectOneLineError(const RunResult& run, const std::string& expected) {
    EXPECT_GT(run.status, 0) << run.err;
    EXPECT_THAT(run.err, StartsWith("rodfit"));
    EXPECT_THAT(run.err, HasSubstr(expected));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }

  // The experiment with its camera copied beside it (or at `camera` relative to it).
  std::string WriteExperiment(const std::string& name = "exp/experiment.yaml",
                              const std::string& camera = "cam_front.yaml") {
    const std::string path = dir_.Write(name, Replace(kExperiment, "CAMERA", camera));
    const fs::path camera_path = fs::path(path).parent_path() / camera;
    fs::create_directories(camera_path.parent_path());
    fs::copy_file(RODFIT_SOURCE_DIR "/tests/data/synth/cam_front.yaml", camera_path,
                  fs::copy_options::overwrite_existing);
    return path;
  }

  // The entries of a directory, by name.
  static std::vector<std::string> Entries(const std::string& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }

  TempDir dir_;
};

TEST_F(HostileInputCliTest, PokedCaseNamedAsPathWritesNothingOutside) {
  for (const std::string& name : {std::string("../../x"), std::string("/tmp/rodfit_evil"),
                                  std::string(".hidden")}) {
    SCOPED_TRACE(name);
    const std::string scene =
        dir_.Write("a/b/scene.yaml", Replace(kPokedScene, "name: side", "name: " + name));
    const RunResult run = Rodfit("simulate " + Q(scene) + " -o " + Q(dir_.File("a/b/out")));
    ExpectOneLineError(run, scene + ":13: cases[0].name: must not");
    EXPECT_FALSE(fs::exists(dir_.File("a/b/out")));
    EXPECT_FALSE(fs::exists(dir_.File("a/x.obj")));
    EXPECT_FALSE(fs::exists(dir_.File("x.obj")));
    EXPECT_FALSE(fs::exists("/tmp/rodfit_evil.obj"));
  }
}

TEST_F(HostileInputCliTest, CameraNestedFiftyThousandLevelsIsAnErrorNotACrash) {
  // Both crashed OpenCV's FileStorage parsers with SIGSEGV before they were bounded.
  const int n = 50000;
  const std::string yaml =
      dir_.Write("deep.yaml", "%YAML:1.0\na: " + std::string(n, '[') + std::string(n, ']') + "\n");
  std::string xml_text = "<?xml version=\"1.0\"?>\n<opencv_storage>";
  for (int i = 0; i < n; ++i) xml_text += "<a>";
  for (int i = 0; i < n; ++i) xml_text += "</a>";
  const std::string xml = dir_.Write("deep.xml", xml_text + "</opencv_storage>\n");
  const std::string csv = dir_.File("points.csv");
  for (const std::string& camera : {yaml, xml}) {
    SCOPED_TRACE(camera);
    const RunResult run = Rodfit("extract " + Q(dir_.File("image.png")) + " --camera " +
                                 Q(camera) + " -o " + Q(csv));
    ExpectOneLineError(run, camera + ": malformed file: nested");
    EXPECT_FALSE(fs::exists(csv));
  }
}

TEST_F(HostileInputCliTest, FitRefusesToOverwriteItsOwnInputs) {
  const std::string experiment = WriteExperiment();
  const std::string markers = dir_.Write("exp/m.csv", "s,x,y,z\n0.2,0.2,0,0\n");
  const std::string camera = dir_.File("exp/cam_front.yaml");
  const std::string text = ReadText(experiment), camera_text = ReadText(camera);
  for (const auto& [output, input] :
       {std::pair<std::string, std::string>{experiment, experiment},
        {dir_.File("exp/../exp/m.csv"), markers},
        {dir_.File("exp/cam_front.yaml"), camera}}) {
    SCOPED_TRACE(output);
    const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(output) + " --quiet");
    ExpectOneLineError(run, output + ": is the ");
    EXPECT_THAT(run.err, HasSubstr("(" + input + "), an input of this run"));
  }
  EXPECT_EQ(ReadText(experiment), text);
  EXPECT_EQ(ReadText(markers), "s,x,y,z\n0.2,0.2,0,0\n");
  EXPECT_EQ(ReadText(camera), camera_text);
  // -o a directory is refused before the report is written.
  const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(dir_.File("exp")) +
                               " --report " + Q(dir_.File("report")) + " --quiet");
  ExpectOneLineError(run, dir_.File("exp") + ": is a directory");
  EXPECT_FALSE(fs::exists(dir_.File("report")));
}

TEST_F(HostileInputCliTest, ExtractRefusesToOverwriteItsCamera) {
  const std::string camera = dir_.Write("cam.yaml", "%YAML:1.0\n");
  const RunResult run = Rodfit("extract " + Q(dir_.File("image.png")) + " --camera " +
                               Q(camera) + " -o " + Q(camera));
  ExpectOneLineError(run, camera + ": is a camera file (" + camera + ")");
  EXPECT_EQ(ReadText(camera), "%YAML:1.0\n");
}

TEST_F(HostileInputCliTest, SynthRefusesToOverwriteItsCamera) {
  // The camera lies outside the experiment's folder, so synth copies it to DIR/cam_front.yaml:
  // with DIR its own folder that is the camera itself.
  const std::string experiment = WriteExperiment("exp/experiment.yaml", "../cams/cam_front.yaml");
  const std::string camera = dir_.File("cams/cam_front.yaml");
  const std::string camera_text = ReadText(camera);
  const RunResult run = Rodfit("synth " + Q(experiment) + " -o " + Q(dir_.File("cams")));
  ExpectOneLineError(run, "cam_front.yaml: is the camera of cases[0].observations[2]");
  EXPECT_EQ(ReadText(camera), camera_text);
  EXPECT_EQ(Entries(dir_.File("cams")), std::vector<std::string>{"cam_front.yaml"});
}

TEST_F(HostileInputCliTest, SimulateThatFailsToWriteLeavesTheOutputAsItWas) {
  const std::string scene = dir_.Write("scene.yaml", kPokedScene);
  const std::string out = dir_.File("out");
  dir_.Write("out/shapes.csv", "old\n");
  fs::create_directory(out + "/side.obj");  // where the case's OBJ goes
  RunResult run = Rodfit("simulate " + Q(scene) + " -o " + Q(out));
  ExpectOneLineError(run, "side.obj: exists and is not a file");
  EXPECT_EQ(ReadText(out + "/shapes.csv"), "old\n");
  EXPECT_EQ(Entries(out), (std::vector<std::string>{"shapes.csv", "side.obj"}));
  EXPECT_EQ(Entries(dir_.path()), (std::vector<std::string>{"out", "scene.yaml", "stderr.txt",
                                                            "stdout.txt"}));

  // Once the obstacle is gone the run writes every file, the old one replaced.
  fs::remove(out + "/side.obj");
  run = Rodfit("simulate " + Q(scene) + " -o " + Q(out));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(Entries(out), (std::vector<std::string>{"forces.csv", "sections.csv", "shapes.csv",
                                                    "side.obj", "summary.csv"}));
  EXPECT_THAT(ReadText(out + "/shapes.csv"), StartsWith("case,vertex,s,x,y,z\n"));

  // A scene that is one of the outputs is refused, the scene intact.
  const std::string inside = dir_.Write("out2/shapes.csv", kPokedScene);
  run = Rodfit("simulate " + Q(inside) + " -o " + Q(dir_.File("out2")));
  ExpectOneLineError(run, "shapes.csv: is the experiment");
  EXPECT_EQ(ReadText(inside), kPokedScene);
  EXPECT_EQ(Entries(dir_.File("out2")), std::vector<std::string>{"shapes.csv"});
}

TEST_F(HostileInputCliTest, SynthThatFailsToWriteLeavesTheOutputAsItWas) {
  const std::string experiment = WriteExperiment();
  const std::string out = dir_.File("out");
  dir_.Write("out/notes.txt", "mine\n");
  fs::create_directory(out + "/truth.json");  // the last file synth writes cannot be written
  RunResult run = Rodfit("synth " + Q(experiment) + " -o " + Q(out));
  ExpectOneLineError(run, "truth.json: exists and is not a file");
  EXPECT_EQ(Entries(out), (std::vector<std::string>{"notes.txt", "truth.json"}));
  EXPECT_TRUE(fs::is_empty(out + "/truth.json"));
  EXPECT_EQ(Entries(dir_.path()), (std::vector<std::string>{"exp", "out", "stderr.txt",
                                                            "stdout.txt"}));

  // A new directory under missing parents: on failure not even the parents are left.
  const std::string away = WriteExperiment("away/experiment.yaml", "cam_away.yaml");
  fs::copy_file(RODFIT_SOURCE_DIR "/tests/data/synth/cam_away.yaml",
                dir_.File("away/cam_away.yaml"), fs::copy_options::overwrite_existing);
  run = Rodfit("synth " + Q(away) + " -o " + Q(dir_.File("new/deeper/out")));
  ExpectOneLineError(run, "sees nothing of the rod");
  EXPECT_FALSE(fs::exists(dir_.File("new")));

  // And it succeeds once truth.json can be written, keeping the user's file.
  fs::remove(out + "/truth.json");
  run = Rodfit("synth " + Q(experiment) + " -o " + Q(out));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(Entries(out), (std::vector<std::string>{"cam_front.yaml", "experiment.yaml", "m.csv",
                                                    "notes.txt", "sub", "truth.json", "uv.csv"}));
  EXPECT_EQ(Entries(out + "/sub"), std::vector<std::string>{"p.csv"});
}

TEST_F(HostileInputCliTest, HugeCsvFieldGivesAShortMessage) {
  const std::string experiment = WriteExperiment();
  dir_.Write("exp/m.csv", "s,x,y,z\n0.2," + std::string(1 << 20, '9') + "x,0,0\n");
  const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(dir_.File("p.json")));
  ExpectOneLineError(run, "m.csv:2: x: expected a finite number, got '999");
  EXPECT_LE(run.err.size(), 300u);
  EXPECT_FALSE(fs::exists(dir_.File("p.json")));
}

TEST_F(HostileInputCliTest, ThreadsOutOfRangeGiveTheRange) {
  const std::string experiment = WriteExperiment();
  for (const std::string& threads :
       {std::string("0"), std::string("2147483647"), std::string(300, '9'),
        std::string("two")}) {
    SCOPED_TRACE(threads.substr(0, 20));
    const RunResult run = Rodfit("fit " + Q(experiment) + " -o " + Q(dir_.File("p.json")) +
                                 " --threads " + Q(threads));
    ExpectOneLineError(run, "must be an integer in [1, 256]");
    EXPECT_LE(run.err.size(), 200u) << run.err;
    EXPECT_THAT(run.err, Not(HasSubstr("bad_alloc")));
  }
  EXPECT_FALSE(fs::exists(dir_.File("p.json")));
}

}  // namespace
}  // namespace rodfit
