// Bad inputs that the held points, moments, start shapes, solver options and `reaction`
// observations bring to a scene, run through `rodfit simulate` as a user would: each exits
// non-zero with exactly one line on stderr, `rodfit: FILE:LINE: KEY: message` (the line and key
// of the value at fault; a model error names the case's entry, `cases[k]`; a start CSV's own
// errors name the CSV, its row line and column), and creates no output directory.
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../io/temp_dir.h"
#include "run_cli.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::Replace;
using test::RunResult;
using test::TempDir;

// One case held at both ends (clamp, end_clamp), at an interior pin and by a grasp. The line
// numbers are those the error messages must name.
const std::string kHead =
    "rod:\n"                                                                      // 1
    "  length: 0.2\n"                                                             // 2
    "  segments: 10\n"                                                            // 3
    "  radius: 1.0e-4\n"                                                          // 4
    "  linear_density: 5.0e-5\n"                                                  // 5
    "parameters:\n"                                                               // 6
    "  bend_stiffness: {value: 1.0e-6}\n"                                         // 7
    "  twist_stiffness: {value: 8.0e-7}\n"                                        // 8
    "  stretch_stiffness: {value: 245}\n"                                         // 9
    "gravity: [0, 0, -9.81]\n"                                                    // 10
    "cases:\n"                                                                    // 11
    "  - name: held\n"                                                            // 12
    "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";  // 13
const std::string kEndClampLine =
    "    end_clamp: {position: [0.18, 0, 0.02], tangent: [1, 0, 0], normal: [0, 0, 1]}\n";  // 14
const std::string kPinsLines =
    "    pins:\n"                                                                 // 15
    "      - {s: 0.06, position: [0.058, 0, 0.005]}\n";                           // 16
const std::string kPinLine = "      - {s: 0.06, position: [0.058, 0, 0.005]}\n";
const std::string kGraspLine = "    grasp: {s: 0.125, position: [0.12, 0.01, 0.01]}\n";  // 17
const std::string kScene = kHead + kEndClampLine + kPinsLines + kGraspLine;

class HeldPointsCliTest : public ::testing::Test {
 protected:
  static std::string Q(const std::string& s) { return test::Quote(s); }

  std::string ScenePath() const { return dir_.File("scene.yaml"); }

  // `rodfit simulate` on `yaml` (written as DIR/scene.yaml) exits non-zero with exactly the line
  // "rodfit: MESSAGE" on stderr, nothing on stdout, and creates no output directory.
  void ExpectSimulateFails(const std::string& yaml, const std::string& message) {
    SCOPED_TRACE(message);
    const std::string scene = dir_.Write("scene.yaml", yaml);
    const std::string out = dir_.File("out");
    const RunResult run = test::RunRodfit(dir_, "simulate " + Q(scene) + " -o " + Q(out));
    EXPECT_GT(run.status, 0);
    EXPECT_EQ(run.err, "rodfit: " + message + "\n");
    EXPECT_EQ(run.out, "");
    EXPECT_FALSE(fs::exists(out));
  }

  // The error at `line` of the scene: "SCENE:LINE: KEY: message".
  std::string At(int line, const std::string& key, const std::string& message) const {
    return ScenePath() + ":" + std::to_string(line) + ": " + key + ": " + message;
  }

  TempDir dir_;
};

// The base every bad input below is one edit away from: it simulates.
TEST_F(HeldPointsCliTest, TheBaseSceneSimulates) {
  const std::string scene = dir_.Write("scene.yaml", kScene);
  const RunResult run =
      test::RunRodfit(dir_, "simulate " + Q(scene) + " -o " + Q(dir_.File("out")));
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  EXPECT_TRUE(fs::is_regular_file(dir_.File("out/shapes.csv")));
}

// ---- end_clamp ------------------------------------------------------------------------------

TEST_F(HeldPointsCliTest, EndClampNormalNearlyParallelToItsTangent) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine,
              "    end_clamp: {position: [0.18, 0, 0.02], tangent: [1, 0, 0], normal: [1, 0, 1.0e-4]}\n"),
      At(14, "cases[0].end_clamp.normal", "is (nearly) parallel to the tangent"));
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine,
              "    end_clamp: {position: [0.18, 0, 0.02], tangent: [1, 0, 0], normal: [-2, 0, 0]}\n"),
      At(14, "cases[0].end_clamp.normal", "is (nearly) parallel to the tangent"));
}

TEST_F(HeldPointsCliTest, EndClampZeroTangent) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine,
              "    end_clamp: {position: [0.18, 0, 0.02], tangent: [0, 0, 0], normal: [0, 0, 1]}\n"),
      At(14, "cases[0].end_clamp.tangent", "must not be zero"));
}

// ---- pins -----------------------------------------------------------------------------------

const char* const kPinRange =
    "must lie inside (0, 0.2) (the clamp holds s = 0; use end_pin for s = L), got ";

TEST_F(HeldPointsCliTest, PinAtTheClamp) {
  ExpectSimulateFails(Replace(kScene, kPinLine, "      - {s: 0, position: [0, 0, 0]}\n"),
                      At(16, "cases[0].pins[0].s", kPinRange + std::string("0")));
}

TEST_F(HeldPointsCliTest, PinAtTheEnd) {
  ExpectSimulateFails(Replace(kScene, kPinLine, "      - {s: 0.2, position: [0.18, 0, 0.02]}\n"),
                      At(16, "cases[0].pins[0].s", kPinRange + std::string("0.2")));
}

TEST_F(HeldPointsCliTest, PinBeforeTheRod) {
  ExpectSimulateFails(Replace(kScene, kPinLine, "      - {s: -0.01, position: [0, 0, 0]}\n"),
                      At(16, "cases[0].pins[0].s", kPinRange + std::string("-0.01")));
}

TEST_F(HeldPointsCliTest, PinBeyondTheRod) {
  ExpectSimulateFails(Replace(kScene, kPinLine, "      - {s: 0.3, position: [0.18, 0, 0.02]}\n"),
                      At(16, "cases[0].pins[0].s", kPinRange + std::string("0.3")));
}

TEST_F(HeldPointsCliTest, TwoPinsAtTheSameArcLength) {
  ExpectSimulateFails(
      Replace(kScene, kPinLine, kPinLine + "      - {s: 0.06, position: [0.058, 0.001, 0.005]}\n"),
      At(17, "cases[0].pins[1].s", "another pin holds s = 0.06 (line 16)"));
}

// ---- what s = L can carry -------------------------------------------------------------------

TEST_F(HeldPointsCliTest, EndClampAndEndPinInOneCase) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine, kEndClampLine + "    end_pin: {position: [0.18, 0, 0.02]}\n"),
      At(15, "cases[0].end_pin", "s = L is already held by end_clamp: give one"));
}

TEST_F(HeldPointsCliTest, TipForceOnAnEndClampedCase) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine, kEndClampLine + "    tip_force: [0, 0, -1.0e-4]\n"),
      At(15, "cases[0].tip_force", "acts on s = L, which the end_clamp holds: remove it"));
}

TEST_F(HeldPointsCliTest, TipForceOnAnEndPinnedCase) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine,
              "    end_pin: {position: [0.18, 0, 0.02]}\n    tip_force: [0, 0, -1.0e-4]\n"),
      At(15, "cases[0].tip_force", "acts on s = L, which the end_pin holds: remove it"));
}

TEST_F(HeldPointsCliTest, TipMomentOnAnEndClampedCase) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine, kEndClampLine + "    tip_moment: [0, 1.0e-6, 0]\n"),
      At(15, "cases[0].tip_moment", "acts on s = L, which the end_clamp holds: remove it"));
}

TEST_F(HeldPointsCliTest, FollowerTipMomentOnAnEndClampedCase) {
  ExpectSimulateFails(
      Replace(kScene, kEndClampLine, kEndClampLine + "    tip_moment_follower: [0, 1.0e-6, 0]\n"),
      At(15, "cases[0].tip_moment_follower",
         "acts on s = L, which the end_clamp holds: remove it"));
}

TEST_F(HeldPointsCliTest, GraspAtTheEndOfAnEndClampedCase) {
  ExpectSimulateFails(
      Replace(kScene, kGraspLine, "    grasp: {s: 0.2, position: [0.18, 0, 0.02]}\n"),
      At(17, "cases[0].grasp.s", "the grasp is at s = L, which the end_clamp holds"));
}

TEST_F(HeldPointsCliTest, GraspWithinHalfAnEdgeOfTheEndOfAnEndPinnedCase) {
  // 0.195 rounds to vertex 10 (s = L), which the end pin holds.
  ExpectSimulateFails(
      Replace(Replace(kScene, kEndClampLine, "    end_pin: {position: [0.18, 0, 0.02]}\n"),
              kGraspLine, "    grasp: {s: 0.195, position: [0.175, 0, 0.02]}\n"),
      At(17, "cases[0].grasp.s", "the grasp is at s = L, which the end_pin holds"));
}

// ---- model errors, named at the case's entry -----------------------------------------------

TEST_F(HeldPointsCliTest, PinAndGraspOnTheSameVertex) {
  // With 10 segments (vertices every 0.02) s = 0.06 and s = 0.065 both round to vertex 3.
  const std::string yaml =
      Replace(kScene, kGraspLine, "    grasp: {s: 0.065, position: [0.063, 0, 0.005]}\n");
  ExpectSimulateFails(yaml, At(12, "cases[0]",
                               "pins[0] (s = 0.06) and grasp (s = 0.065) fall on the same vertex: "
                               "use more segments"));
  // As the message says: with vertices every 0.005 they are two vertices, and the scene runs.
  const std::string scene =
      dir_.Write("scene.yaml", Replace(yaml, "segments: 10", "segments: 40"));
  const RunResult run =
      test::RunRodfit(dir_, "simulate " + Q(scene) + " -o " + Q(dir_.File("out")));
  EXPECT_EQ(run.status, 0) << run.err;
}

TEST_F(HeldPointsCliTest, EndPinFartherFromTheClampThanTheRodReaches) {
  ExpectSimulateFails(kHead + "    end_pin: {position: [0.4, 0, 0]}\n",
                      At(12, "cases[0]",
                         "end_pin (s = 0.2) is 0.4 m from the clamp (s = 0), but only 0.2 m of "
                         "rod lies between them"));
}

// ---- start ----------------------------------------------------------------------------------

TEST_F(HeldPointsCliTest, StartPreviousOnTheFirstCase) {
  ExpectSimulateFails(kScene + "    start: previous\n",  // 18
                      At(18, "cases[0].start", "the first case has no previous case to start from"));
}

class StartCsvTest : public HeldPointsCliTest {
 protected:
  // The scene starting from DIR/start.csv holding `csv`.
  void ExpectStartFails(const std::string& csv, const std::string& message) {
    dir_.Write("start.csv", csv);
    ExpectSimulateFails(kScene + "    start: start.csv\n", message);
  }
  std::string Csv() const { return dir_.File("start.csv"); }
};

TEST_F(StartCsvTest, OnePoint) {
  ExpectStartFails("x,y,z\n0,0,0\n", Csv() + ": a start shape needs at least 2 points, got 1");
}

TEST_F(StartCsvTest, MissingColumn) {
  ExpectStartFails("x,y\n0,0\n0.2,0\n", Csv() + ": z: missing column (the header has x,y)");
}

TEST_F(StartCsvTest, RepeatedConsecutivePoints) {
  ExpectStartFails("x,y,z\n0,0,0\n0.1,0,0\n0.1,0,0\n0.2,0,0\n",
                   Csv() + ":4: x: repeats the point before it (a start shape's points must differ)");
}

TEST_F(StartCsvTest, ArcLengthNotIncreasing) {
  ExpectStartFails("s,x,y,z\n0,0,0,0\n0.1,0.1,0,0\n0.1,0.15,0,0\n0.2,0.2,0,0\n",
                   Csv() + ":4: s: must increase from row to row");
}

TEST_F(StartCsvTest, ArcLengthCoversOnlyPartOfTheRod) {
  // Found when the case's model places it on the rod's vertices: named at the case's entry.
  ExpectStartFails("s,x,y,z\n0,0,0,0\n0.05,0.05,0,0\n0.1,0.1,0,0\n",
                   At(12, "cases[0]", "start shape covers s in [0, 0.1], not the rod's [0, 0.2]"));
}

TEST_F(StartCsvTest, MissingFile) {
  // Named at the key that wants it, so the message says which entry of which file.
  ExpectSimulateFails(kScene + "    start: nowhere.csv\n",
                      At(18, "cases[0].start", "cannot open " + dir_.File("nowhere.csv") +
                                                   ": no such file"));
}

// ---- reaction observations ------------------------------------------------------------------

TEST_F(HeldPointsCliTest, ReactionAtAPointTheCaseDoesNotHold) {
  const std::string observations = "    observations:\n";  // 18
  ExpectSimulateFails(
      kScene + observations + "      - {type: reaction, point: end_pin, file: f.csv, sigma: 1.0e-4}\n",
      At(19, "cases[0].observations[0].point",
         "this case holds no 'end_pin' (it holds: clamp, end_clamp, pins[0], grasp)"));
  ExpectSimulateFails(
      kScene + observations +
          "      - {type: reaction, point: 'pins[1]', file: f.csv, sigma: 1.0e-4}\n",
      At(19, "cases[0].observations[0].point",
         "this case holds no 'pins[1]' (it holds: clamp, end_clamp, pins[0], grasp)"));
}

TEST_F(HeldPointsCliTest, SigmaMomentAtAPin) {
  ExpectSimulateFails(kScene + "    observations:\n"
                               "      - {type: reaction, point: 'pins[0]', file: f.csv, "
                               "sigma: 1.0e-4, sigma_moment: 1.0e-6}\n",
                      At(19, "cases[0].observations[0].sigma_moment",
                         "a moment is measured only at a clamp (clamp or end_clamp), not at "
                         "pins[0]"));
}

// ---- solver ---------------------------------------------------------------------------------

TEST_F(HeldPointsCliTest, SolverValueOutOfRange) {
  auto with_solver = [](const std::string& solver) {
    return Replace(kScene, "cases:\n", "solver: " + solver + "\ncases:\n");  // line 11
  };
  ExpectSimulateFails(with_solver("{max_iterations: 0}"),
                      At(11, "solver.max_iterations", "must be an integer in [1, 100000], got 0"));
  ExpectSimulateFails(with_solver("{gradient_tolerance: 0.5}"),
                      At(11, "solver.gradient_tolerance", "must be in [1e-16, 0.01], got 0.5"));
  ExpectSimulateFails(with_solver("{step_tolerance: 0}"),
                      At(11, "solver.step_tolerance", "must be in [1e-16, 0.01], got 0"));
}

TEST_F(HeldPointsCliTest, SolverUnknownKey) {
  ExpectSimulateFails(
      Replace(kScene, "cases:\n", "solver: {max_iteration: 5}\ncases:\n"),
      At(11, "solver.max_iteration",
         "unknown key (allowed: max_iterations, gradient_tolerance, step_tolerance, "
         "escape_saddles)"));
}

}  // namespace
}  // namespace rodfit
