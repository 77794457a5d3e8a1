// Hostile input on the newer surfaces (export, rollout, moving scenes): each defect found by
// trying them as a hostile user would, as a regression test. The output rule (never over an
// input, never over anything but a regular file, never to an empty path), physical sanity of a
// result returned with exit 0, a recording checked against the scene's rod, exports validated
// before anything is written, and one-line errors with exit 1.
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// A short moving scene: a 1 m cable clamped at 0, its end pinned and driven along `path.csv`.
std::string MovingScene(const std::string& drive_file, const std::string& extra = "",
                        const std::string& duration = "0.05") {
  return "rod: {length: 1.0, segments: 20, radius: 0.0025, linear_density: 0.04}\n"
         "parameters:\n"
         "  bend_stiffness: {value: 2.0e-3}\n"
         "  twist_stiffness: {value: 1.5e-3}\n"
         "  stretch_stiffness: {value: 2.0e4}\n"
         "  damping: {value: 0.02}\n"
         "dynamics: {time_step: 1.0e-3, duration: " + duration + ", output_every: 5}\n"
         "cases:\n"
         "  - name: carried\n"
         "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
         "    end_pin: {position: [0.8, 0, 0]}\n"
         "    drive:\n"
         "      - {point: end_pin, file: " + drive_file + "}\n" + extra;
}

const char kPath[] = "t,x,y,z\n0,0.8,0,0\n0.05,0.8,0,0.01\n";

// The recording of the moving scene written by `simulate --markers 8`, as t,marker,x,y,z.
std::string Recording(const TempDir& dir) {
  const std::string scene = dir.Write("scene.yaml", MovingScene("path.csv"));
  dir.Write("path.csv", kPath);
  const RunResult sim =
      RunRodfit(dir, "simulate " + Quote(scene) + " --markers 8 -o " + Quote(dir.File("sim")));
  EXPECT_EQ(sim.status, 0) << sim.err;
  std::ifstream in(dir.File("sim/markers.csv"));
  std::string line, out = "t,marker,x,y,z\n";
  std::getline(in, line);  // case,t,marker,x,y,z
  while (std::getline(in, line)) out += line.substr(line.find(',') + 1) + "\n";
  return out;
}

// --- 1. The output rule ---------------------------------------------------------------------

TEST(OutputRule, RolloutRefusesToWriteOverItsRecording) {
  TempDir dir;
  const std::string rec = Recording(dir);
  std::filesystem::create_directories(dir.File("out"));
  const std::string rec_path = dir.Write("out/rollout.csv", rec);
  const RunResult run = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " +
                                           Quote(rec_path) + " -q -o " + Quote(dir.File("out")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("is a recording"));
  EXPECT_EQ(ReadText(rec_path), rec);  // the input is untouched
}

TEST(OutputRule, SimulateRefusesToWriteOverADrivePathTipLoadOrVelocityFile) {
  TempDir dir;
  std::filesystem::create_directories(dir.File("out"));
  struct Case {
    std::string file, extra, what;
  };
  const std::vector<Case> cases = {
      {"out/trajectory.csv", "", "the drive path of cases[0]"},
      {"path.csv", "    tip_load: {file: out/reactions.csv}\n", "the tip load of cases[0]"},
      {"path.csv", "    initial: {shape: start, velocity: out/summary.csv}\n",
       "the initial velocity file of cases[0]"}};
  dir.Write("path.csv", kPath);
  for (const Case& c : cases) {
    dir.Write("out/trajectory.csv", kPath);
    dir.Write("out/reactions.csv", "t,fx,fy,fz\n0,0,0,0\n1,0,0,0.01\n");
    dir.Write("out/summary.csv", "s,vx,vy,vz\n0,0,0,0\n1,0,0,0\n");
    const std::string before = ReadText(dir.File("out/trajectory.csv")) +
                               ReadText(dir.File("out/reactions.csv")) +
                               ReadText(dir.File("out/summary.csv"));
    const std::string scene = dir.Write("s.yaml", MovingScene(c.file, c.extra));
    const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("out")));
    EXPECT_EQ(run.status, 1) << c.what << ": " << run.out;
    EXPECT_THAT(run.err, HasSubstr(c.what));
    EXPECT_EQ(ReadText(dir.File("out/trajectory.csv")) + ReadText(dir.File("out/reactions.csv")) +
                  ReadText(dir.File("out/summary.csv")),
              before);
  }
}

TEST(OutputRule, EmptyOutputPathIsRefusedByEveryCommand) {
  TempDir dir;
  dir.Write("path.csv", kPath);
  const std::string scene = dir.Write("scene.yaml", MovingScene("path.csv"));
  const std::string rec = dir.Write("rec.csv", "t,marker,x,y,z\n0,0,0,0,0\n0,1,1,0,0\n");
  const std::string profile = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";
  for (const std::string& args :
       {"simulate " + Quote(scene) + " -o ''", "rollout " + Quote(scene) + " " + Quote(rec) + " -o ''",
        "export " + Quote(profile) + " --format json -o ''"}) {
    // Run from inside the temporary directory: nothing may appear there.
    const std::string cmd = "cd " + Quote(dir.File("cwd")) + " && '" + RODFIT_CLI + "' " + args +
                            " > /dev/null 2> " + Quote(dir.File("err.txt"));
    std::filesystem::create_directories(dir.File("cwd"));
    const int raw = std::system(cmd.c_str());
    EXPECT_EQ(WEXITSTATUS(raw), 1) << args;
    EXPECT_THAT(ReadText(dir.File("err.txt")), HasSubstr("empty")) << args;
    EXPECT_TRUE(std::filesystem::is_empty(dir.File("cwd"))) << args;
  }
}

// --- 2. Physical sanity of what is returned with exit 0 -------------------------------------

// The bundled suture swing with a tip-load series rising to 1e4 N: the edges were stretched by
// 4080 % and the tip thrown 8.4 m from a 0.2 m rod, with exit 0.
TEST(PhysicalSanity, ATipLoadTheRodCannotCarryStopsTheCaseNamingTheTime) {
  TempDir dir;
  std::string scene = ReadText(std::string(RODFIT_SOURCE_DIR) + "/data/scenes/suture_swing.yaml");
  scene = Replace(scene, "duration: 1.0 ", "duration: 0.1 ");
  scene += "    tip_load: {file: load.csv}\n";
  dir.Write("load.csv", "t,fx,fy,fz\n0,0,0,0\n0.05,1e4,0,0\n");
  const std::string path = dir.Write("swing.yaml", scene);
  const RunResult run = RunRodfit(dir, "simulate " + Quote(path) + " -o " + Quote(dir.File("o")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("case swing: t = "));
  EXPECT_THAT(run.err, HasSubstr("beyond the rod model's small-strain limit of 10 %"));
  EXPECT_FALSE(std::filesystem::exists(dir.File("o")));
  // With --keep-going, the frames up to there and exit 3.
  const RunResult kept =
      RunRodfit(dir, "simulate " + Quote(path) + " --keep-going -o " + Quote(dir.File("k")));
  EXPECT_EQ(kept.status, 3) << kept.err;
}

// An end pin driven to twice the rod's length: 100 % strain and a 20 kN reaction with exit 0.
TEST(PhysicalSanity, AnEndDrivenBeyondTheRodsReachStops) {
  TempDir dir;
  dir.Write("far.csv", "t,x,y,z\n0,0.8,0,0\n0.05,2.0,0,0\n");
  const std::string scene = dir.Write("s.yaml", MovingScene("far.csv"));
  const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("case carried: t = "));
  EXPECT_THAT(run.err, HasSubstr("small-strain limit"));
  // The same scene driven within reach runs.
  dir.Write("near.csv", kPath);
  const RunResult near = RunRodfit(dir, "simulate " + Quote(dir.Write("n.yaml", MovingScene("near.csv"))) +
                                            " -o " + Quote(dir.File("n")));
  EXPECT_EQ(near.status, 0) << near.err;
}

// --- 3. rollout checks the recording against the scene's rod ---------------------------------

TEST(RolloutRecording, ARecordingOfAnotherRodIsRefusedNamingTheFile) {
  TempDir dir;
  const std::string rec = Recording(dir);
  // The same recording scaled 1.5 times about the clamp.
  std::string scaled = "t,marker,x,y,z\n";
  std::istringstream in(rec);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string t, m, x, y, z;
    std::getline(row, t, ',');
    std::getline(row, m, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    std::getline(row, z, ',');
    scaled += t + "," + m + "," + std::to_string(1.5 * std::stod(x)) + "," +
              std::to_string(1.5 * std::stod(y)) + "," + std::to_string(1.5 * std::stod(z)) + "\n";
  }
  const std::string path = dir.Write("scaled.csv", scaled);
  const RunResult run = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " +
                                           Quote(path) + " -q -o " + Quote(dir.File("r")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("scaled.csv: frame 0: the markers' polyline is"));
  EXPECT_FALSE(std::filesystem::exists(dir.File("r")));
  // The recording itself is rolled out.
  const RunResult own = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " +
                                           Quote(dir.Write("own.csv", rec)) + " -q -o " +
                                           Quote(dir.File("r")));
  EXPECT_EQ(own.status, 0) << own.err;
}

TEST(RolloutRecording, EveryMarkerHeldIsRefusedNotScoredAsZero) {
  TempDir dir;
  const std::string rec = dir.Write("rec.csv", Recording(dir));
  const RunResult run = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " + Quote(rec) +
                                           " --held 0,1,2,3,4,5,6,7 -q -o " + Quote(dir.File("r")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("none is left to predict"));
  EXPECT_THAT(run.out, Not(HasSubstr("over the predicted ones")));
}

TEST(RolloutRecording, MillisecondTimesAreRefusedBeforeTheRun) {
  TempDir dir;
  const std::string rec = Recording(dir);
  std::string ms = "t,marker,x,y,z\n";
  std::istringstream in(rec);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    const size_t comma = line.find(',');
    ms += std::to_string(1000.0 * std::stod(line.substr(0, comma))) + line.substr(comma) + "\n";
  }
  const RunResult run = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " +
                                           Quote(dir.Write("ms.csv", ms)) + " -q -o " +
                                           Quote(dir.File("r")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("ms.csv:2: t: the frames are 5 s apart, more than 1 s"));
}

// --- 5. Work estimated before a run -----------------------------------------------------------

TEST(RunSize, AMovingSceneAboveTheWorkLimitIsRefusedUnlessAsked) {
  TempDir dir;
  dir.Write("path.csv", kPath);
  // 2000 segments x 1e5 steps: 2e8 vertex steps and more; refused at once.
  std::string scene = MovingScene("path.csv", "", "100");
  scene = Replace(scene, "segments: 20", "segments: 2000");
  const std::string path = dir.Write("big.yaml", scene);
  const RunResult run = RunRodfit(dir, "simulate " + Quote(path) + " -o " + Quote(dir.File("o")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("big.yaml: dynamics: the run would take 2e+08 vertex steps"));
  EXPECT_THAT(run.err, HasSubstr("--large"));
  // Output: a written frame every step of a 200-segment rod for 600 s.
  scene = MovingScene("path.csv", "", "600");
  scene = Replace(scene, "output_every: 5", "output_every: 1");
  const RunResult out = RunRodfit(dir, "simulate " + Quote(dir.Write("out.yaml", scene)) + " -o " +
                                           Quote(dir.File("o")));
  EXPECT_EQ(out.status, 1) << out.out;
  EXPECT_THAT(out.err, HasSubstr("bytes of CSV"));
}

// --- 6. Exit codes and messages ---------------------------------------------------------------

TEST(ExitCodes, OptionErrorsOfEveryCommandAreExitOneWithOneLine) {
  TempDir dir;
  for (const std::string& args :
       {std::string("rollout"), std::string("rollout a.yaml b.csv -o x --smooth -3"),
        std::string("rollout a.yaml b.csv -o x --no-such-option"), std::string("bench --no-such"),
        std::string("bench --calibration"), std::string("export"), std::string("fit"),
        std::string("simulate")}) {
    const RunResult run = RunRodfit(dir, args);
    EXPECT_EQ(run.status, 1) << args << ": " << run.err;
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << args << ": " << run.err;
    EXPECT_THAT(run.err, ::testing::StartsWith("rodfit ")) << args;
  }
}

TEST(ExitCodes, NanAndInfOptionsAreRefused) {
  TempDir dir;
  dir.Write("path.csv", kPath);
  const std::string scene = dir.Write("scene.yaml", MovingScene("path.csv"));
  const std::string rec = dir.Write("rec.csv", "t,marker,x,y,z\n0,0,0,0,0\n0,1,1,0,0\n");
  for (const std::string& args :
       {"simulate " + Quote(scene) + " --markers 4 --marker-noise nan -o " + Quote(dir.File("o")),
        "simulate " + Quote(scene) + " --markers 4 --marker-drop nan -o " + Quote(dir.File("o")),
        "rollout " + Quote(scene) + " " + Quote(rec) + " --frame-rate nan -o " + Quote(dir.File("o")),
        "rollout " + Quote(scene) + " " + Quote(rec) + " --marker-sigma inf -o " + Quote(dir.File("o"))}) {
    const RunResult run = RunRodfit(dir, args);
    EXPECT_EQ(run.status, 1) << args << ": " << run.out;
    EXPECT_THAT(run.err, HasSubstr("not a finite number")) << args;
    EXPECT_FALSE(std::filesystem::exists(dir.File("o"))) << args;
  }
}

TEST(ExitCodes, DuplicateFitNamesAreRefused) {
  TempDir dir;
  const std::string rec = dir.Write("rec.csv", Recording(dir));
  const RunResult run = RunRodfit(dir, "rollout " + Quote(dir.File("scene.yaml")) + " " + Quote(rec) +
                                           " --fit damping,damping -q -o " + Quote(dir.File("r")));
  EXPECT_EQ(run.status, 1) << run.out;
  EXPECT_THAT(run.err, HasSubstr("'damping' is named twice"));
}

}  // namespace
}  // namespace rodfit::test
