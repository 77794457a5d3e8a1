// Hostile input on the newer surfaces (export, rollout, moving scenes): each defect found by
// trying them as a hostile user would, as a regression test. The output rule (never over an
// input, never over anything but a regular file, never to an empty path), physical sanity of a
// result returned with exit 0, a recording checked against the scene's rod, exports validated
// before anything is written, and one-line errors with exit 1.
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;

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

TEST(OutputRule, ExportRefusesAFifoBeforeReadingTheProfile) {
  TempDir dir;
  const std::string fifo = dir.File("pipe");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string profile = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";
  for (const char* format : {"json", "sofa"}) {
    const RunResult run = RunRodfit(
        dir, "export " + Quote(profile) + " --format " + format + " -o " + Quote(fifo));
    EXPECT_EQ(run.status, 1) << format;
    EXPECT_THAT(run.err, HasSubstr("is not a file")) << format;
    struct stat st;
    ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode)) << format;
  }
}

}  // namespace
}  // namespace rodfit::test
