// `simulate` on a moving scene (a `dynamics:` block): the files it writes, a driven point that
// follows its path, and one-line errors for bad dynamics input (docs/formats.md, docs/cli.md).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "rodfit/io/csv.h"
#include "run_cli.h"

namespace rodfit::test {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

std::string Scene(const std::string& dynamics, const std::string& case_extra) {
  return "rod: {length: 1.0, segments: 20, radius: 0.0025, linear_density: 0.04}\n"
         "parameters:\n"
         "  bend_stiffness: {value: 2.0e-3}\n"
         "  twist_stiffness: {value: 1.5e-3}\n"
         "  stretch_stiffness: {value: 2.0e4}\n"
         "  damping: {value: 0.02}\n"
         "dynamics: " + dynamics + "\n"
         "cases:\n"
         "  - name: cable\n"
         "    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n" +
         case_extra;
}

TEST(SimulateDynamics, BundledSwingWritesTrajectoryReactionsAndSummary) {
  TempDir dir;
  const RunResult run = RunRodfit(dir, "simulate " + Quote(std::string(RODFIT_SOURCE_DIR) +
                                                           "/data/scenes/suture_swing.yaml") +
                                           " -o " + Quote(dir.File("o")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable traj = CsvTable::Read(dir.File("o/trajectory.csv"));
  // 1 s at 1 ms, every 10th step and t = 0: 101 frames of 51 vertices.
  ASSERT_EQ(traj.num_rows(), 101 * 51);
  const std::vector<double> t = traj.Column("t"), z = traj.Column("z"), v = traj.Column("vertex");
  EXPECT_EQ(t.front(), 0.0);
  EXPECT_NEAR(t.back(), 1.0, 1e-12);
  // The tip (vertex 50) has swung down by most of the rod's length at some time.
  double lowest = 0.0;
  for (int r = 0; r < traj.num_rows(); ++r)
    if (v[r] == 50) lowest = std::min(lowest, z[r]);
  EXPECT_LT(lowest, -0.15);
  const CsvTable reactions = CsvTable::Read(dir.File("o/reactions.csv"));
  EXPECT_EQ(reactions.num_rows(), 101);  // the clamp at every frame
  const CsvTable summary = CsvTable::Read(dir.File("o/summary.csv"));
  ASSERT_EQ(summary.num_rows(), 1);
  EXPECT_EQ(summary.Column("completed")[0], 1.0);
  EXPECT_EQ(summary.Column("steps")[0], 1000.0);
}

TEST(SimulateDynamics, DrivenEndPinFollowsItsPath) {
  TempDir dir;
  dir.Write("path.csv", "t,x,y,z\n0,0.9,0,0\n0.1,0.85,0.1,0.05\n");
  const RunResult run = RunRodfit(
      dir, "simulate " +
               Quote(dir.Write("s.yaml",
                               Scene("{time_step: 0.005, duration: 0.2, output_every: 2}",
                                     "    end_pin: {position: [0.5, 0, 0]}\n"
                                     "    drive: [{point: end_pin, file: path.csv}]\n"))) +
               " -o " + Quote(dir.File("o")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable traj = CsvTable::Read(dir.File("o/trajectory.csv"));
  const std::vector<double> t = traj.Column("t"), v = traj.Column("vertex"), x = traj.Column("x"),
                            y = traj.Column("y"), z = traj.Column("z");
  int checked = 0;
  for (int r = 0; r < traj.num_rows(); ++r) {
    if (v[r] != 20) continue;
    // Linear between the two rows, held after t = 0.1.
    const double w = std::min(1.0, t[r] / 0.1);
    EXPECT_NEAR(x[r], 0.9 - 0.05 * w, 1e-12) << "t = " << t[r];
    EXPECT_NEAR(y[r], 0.1 * w, 1e-12);
    EXPECT_NEAR(z[r], 0.05 * w, 1e-12);
    ++checked;
  }
  EXPECT_EQ(checked, 21);
  const CsvTable reactions = CsvTable::Read(dir.File("o/reactions.csv"));
  EXPECT_EQ(reactions.num_rows(), 2 * 21);  // clamp and end_pin
}

TEST(SimulateDynamics, ExplicitAboveItsStableStepIsRefusedWithTheLimit) {
  TempDir dir;
  const std::string text =
      Scene("{time_step: 0.001, duration: 0.01, integrator: explicit}", "");
  const std::string scene = dir.Write("s.yaml", text);
  const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
  EXPECT_EQ(run.status, 1);
  // Named by the case's entry in the file (file:line: case NAME:), as an input error would be.
  const size_t entry = text.find("- name: ");
  ASSERT_NE(entry, std::string::npos);
  const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + entry, '\n'));
  EXPECT_THAT(run.err, StartsWith("rodfit simulate: " + scene + ":" + std::to_string(line) +
                                  ": case "));
  EXPECT_THAT(run.err, HasSubstr("above the explicit integrator's stable step"));
  EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1);
  std::ifstream nothing(dir.File("o/trajectory.csv"));
  EXPECT_FALSE(nothing.good());
}

TEST(SimulateDynamics, BadDynamicsInputIsOneLineNamingFileLineAndKey) {
  struct Bad {
    std::string dynamics, extra, message;
    std::string file = "s.yaml:";  // the file the message names
  };
  const std::vector<Bad> cases = {
      {"{time_step: 0.001, duration: 1, integrator: rk4}", "", "dynamics.integrator: must be"},
      {"{time_step: 0, duration: 1}", "", "dynamics.time_step"},
      {"{time_step: 1e-9, duration: 1e6}", "", "above the limit of 100000000"},
      {"{duration: 1}", "", "dynamics.time_step"},
      {"{time_step: 0.001, duration: 1, substep: true}", "", "explicit integrator only"},
      {"{time_step: 0.001, duration: 1, max_halvings: 21}", "", "dynamics.max_halvings: must be in [0, 20], got 21"},
      {"{time_step: 0.001, duration: 1, integrator: explicit, max_halvings: 2}", "",
       "dynamics.max_halvings: is for the implicit integrators only"},
      {"{time_step: 0.001, duration: 1}", "    drive: [{point: end_pin, file: p.csv}]\n",
       "must name a point the case holds"},
      {"{time_step: 0.001, duration: 1}", "    initial: {shape: bent}\n",
       "must be equilibrium, start or a shape CSV file"},
      {"{time_step: 0.001, duration: 1}", "    driven: [{s: 0.5, file: q.csv}]\n",
       "q.csv:2: qw: not a unit quaternion", "q.csv:"},
      {"{time_step: 0.001, duration: 1}", "    driven: [{s: 1.5, file: p.csv}]\n",
       "driven[0].s: must be in [0, 1]"},
      {"{time_step: 0.001, duration: 1}",
       "    driven: [{s: 0, file: p.csv}, {s: 0, file: p.csv}]\n", "drives the clamp a second time"},
  };
  for (const Bad& bad : cases) {
    TempDir dir;
    dir.Write("p.csv", "t,x,y,z\n0,1,0,0\n");
    dir.Write("q.csv", "t,x,y,z,qw,qx,qy,qz\n0,0.5,0,0,0,0,0,0\n");
    const std::string scene = dir.Write("s.yaml", Scene(bad.dynamics, bad.extra));
    const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
    EXPECT_EQ(run.status, 1) << bad.message;
    EXPECT_THAT(run.err, HasSubstr(bad.message));
    EXPECT_THAT(run.err, HasSubstr(bad.file));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }
  // A drive without a dynamics block, and a path whose t does not increase.
  TempDir dir;
  dir.Write("p.csv", "t,x,y,z\n0,1,0,0\n0,1,0,0\n");
  const std::string no_dynamics =
      "rod: {length: 1.0, segments: 20, radius: 0.0025, linear_density: 0.04}\n"
      "parameters: {bend_stiffness: {value: 2e-3}, twist_stiffness: {value: 1.5e-3}, "
      "stretch_stiffness: {value: 2e4}}\n"
      "cases:\n  - clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}\n"
      "    end_pin: {position: [0.9, 0, 0]}\n    drive: [{point: end_pin, file: p.csv}]\n";
  RunResult run = RunRodfit(dir, "simulate " + Quote(dir.Write("a.yaml", no_dynamics)) + " -o " +
                                     Quote(dir.File("o")));
  EXPECT_THAT(run.err, HasSubstr("only for a moving scene"));
  run = RunRodfit(dir, "simulate " +
                           Quote(dir.Write("b.yaml",
                                           Scene("{time_step: 0.001, duration: 1}",
                                                 "    end_pin: {position: [0.9, 0, 0]}\n"
                                                 "    drive: [{point: end_pin, file: p.csv}]\n"))) +
                           " -o " + Quote(dir.File("o")));
  EXPECT_THAT(run.err, HasSubstr("p.csv:3: t: must increase"));
}

}  // namespace
}  // namespace rodfit::test

namespace rodfit::test {
namespace {

// rollout on a recording made by simulate: the cable's vertices every 5th as markers at 100 Hz
// (t,marker,x,y,z), the same scene: the prediction follows the recording to well under a
// millimetre except for the start's finite-difference velocity.
// The contract's spelling of driven points: `driven: [{s, file}]` with the clamp's frame as a
// quaternion (qw,qx,qy,qz: d3 = R e_z, d1 = R e_x), s = L creating the end pin, `integrator:
// implicit` and `rod.vertex_s`, against the same motion as `drive:` with tx..nz columns on a
// declared end_pin: the same trajectory, to the digit (the quaternions written from the frame
// columns' tangent and normal, so the two files hold the same held frames).
TEST(SimulateDynamics, DrivenByArcLengthWithQuaternionsMatchesDriveByPointName) {
  TempDir dir;
  // The clamp turns 0.3 rad about z over 0.2 s while moving up; the far end slides along y.
  std::string quaternion = "t,x,y,z,qw,qx,qy,qz\n", frame = "t,x,y,z,tx,ty,tz,nx,ny,nz\n";
  for (int k = 0; k <= 4; ++k) {
    const double t = 0.05 * k, a = 0.3 * t / 0.2, z = 0.05 * t / 0.2;
    // The rotation whose columns are the held directors: d1 (normal) = R e_x, d3 (tangent) =
    // R e_z; the tangent is x turned by a about z, the normal z.
    const Eigen::Vector3d tangent(std::cos(a), std::sin(a), 0.0), normal(0, 0, 1);
    Eigen::Matrix3d R;
    R.col(0) = normal;
    R.col(2) = tangent;
    R.col(1) = tangent.cross(normal);
    const Eigen::Quaterniond q(R);
    quaternion += FormatDouble(t) + ",0,0," + FormatDouble(z) + "," + FormatDouble(q.w()) + "," +
                  FormatDouble(q.x()) + "," + FormatDouble(q.y()) + "," + FormatDouble(q.z()) + "\n";
    frame += FormatDouble(t) + ",0,0," + FormatDouble(z) + "," + FormatDouble(tangent.x()) + "," +
             FormatDouble(tangent.y()) + ",0,0,0,1\n";
  }
  dir.Write("clamp_q.csv", quaternion);
  dir.Write("clamp_f.csv", frame);
  dir.Write("end.csv", "t,x,y,z\n0,0.9,0,0\n0.2,0.85,0.1,0\n");
  std::string vertex_s = "[0";
  for (int k = 1; k < 20; ++k) vertex_s += ", " + FormatDouble(k / 20.0 + (k % 2 ? 0.01 : -0.01));
  vertex_s += ", 1.0]";
  auto scene = [&](const std::string& integrator, const std::string& extra) {
    return Replace(Scene("{time_step: 0.005, duration: 0.2, output_every: 4, integrator: " +
                             integrator + "}",
                         extra),
                   "segments: 20", "vertex_s: " + vertex_s);
  };
  const std::string a = dir.Write(
      "a.yaml", scene("implicit", "    driven: [{s: 0, file: clamp_q.csv}, {s: 1.0, file: end.csv}]\n"));
  const std::string b = dir.Write(
      "b.yaml", scene("bdf2", "    end_pin: {position: [0.9, 0, 0]}\n"
                              "    drive: [{point: clamp, file: clamp_f.csv}, "
                              "{point: end_pin, file: end.csv}]\n"));
  RunResult run = RunRodfit(dir, "simulate " + Quote(a) + " -o " + Quote(dir.File("oa")));
  ASSERT_EQ(run.status, 0) << run.err;
  run = RunRodfit(dir, "simulate " + Quote(b) + " -o " + Quote(dir.File("ob")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable ta = CsvTable::Read(dir.File("oa/trajectory.csv"));
  const CsvTable tb = CsvTable::Read(dir.File("ob/trajectory.csv"));
  ASSERT_EQ(ta.num_rows(), tb.num_rows());
  ASSERT_EQ(ta.num_rows(), 11 * 21);  // 40 steps written every 4th, and t = 0
  const std::vector<double> sa = ta.Column("s");
  EXPECT_NEAR(sa[1], 0.06, 1e-12);  // the given vertex_s, not an even spacing
  double worst = 0.0;
  for (const char* c : {"x", "y", "z"}) {
    const std::vector<double> xa = ta.Column(c), xb = tb.Column(c);
    for (int r = 0; r < ta.num_rows(); ++r) worst = std::max(worst, std::abs(xa[r] - xb[r]));
  }
  EXPECT_LT(worst, 1e-9);
  // A frame on a point that holds only a position is one line naming the key.
  const std::string bad = dir.Write(
      "bad.yaml", scene("implicit", "    driven: [{s: 0.5, file: clamp_q.csv}]\n"));
  run = RunRodfit(dir, "simulate " + Quote(bad) + " -o " + Quote(dir.File("oc")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("bad.yaml:"));
  EXPECT_THAT(run.err, HasSubstr("holds a position only"));
}

// initial: {frames: [f0, f1]} starts in f0 with the velocity (f1 - f0) / interval: the same
// motion as the shape and a velocity CSV given apart (and t columns give the interval).
TEST(SimulateDynamics, InitialFromTwoFramesIsShapeAndDifferenceVelocity) {
  TempDir dir;
  std::string f0 = "s,x,y,z\n", f1 = f0, f0t = "t,s,x,y,z\n", f1t = f0t, v = "s,vx,vy,vz\n";
  for (int k = 0; k <= 10; ++k) {
    const double sk = 0.1 * k, bend = 0.02 * sk * sk, dy = 1e-3 * sk;  // [m]
    f0 += FormatDouble(sk) + "," + FormatDouble(sk) + ",0," + FormatDouble(-bend) + "\n";
    f1 += FormatDouble(sk) + "," + FormatDouble(sk) + "," + FormatDouble(dy) + "," +
          FormatDouble(-bend) + "\n";
    f0t += "0.5," + FormatDouble(sk) + "," + FormatDouble(sk) + ",0," + FormatDouble(-bend) + "\n";
    f1t += "0.51," + FormatDouble(sk) + "," + FormatDouble(sk) + "," + FormatDouble(dy) + "," +
           FormatDouble(-bend) + "\n";
    v += FormatDouble(sk) + ",0," + FormatDouble(dy / 0.01) + ",0\n";
  }
  dir.Write("f0.csv", f0);
  dir.Write("f1.csv", f1);
  dir.Write("f0t.csv", f0t);
  dir.Write("f1t.csv", f1t);
  dir.Write("v.csv", v);
  const std::string dyn = "{time_step: 0.002, duration: 0.02, output_every: 5}";
  const std::string a = dir.Write(
      "a.yaml", Scene(dyn, "    initial: {frames: [f0.csv, f1.csv], frame_interval: 0.01}\n"));
  const std::string b = dir.Write("b.yaml", Scene(dyn, "    initial: {frames: [f0t.csv, f1t.csv]}\n"));
  const std::string c = dir.Write("c.yaml", Scene(dyn, "    initial: {shape: f0.csv, velocity: v.csv}\n"));
  std::vector<std::vector<double>> y;
  for (const std::string& scene : {a, b, c}) {
    const std::string out = dir.File("o" + std::to_string(y.size()));
    const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(out));
    ASSERT_EQ(run.status, 0) << run.err;
    y.push_back(CsvTable::Read(out + "/trajectory.csv").Column("y"));
  }
  ASSERT_EQ(y[0].size(), y[2].size());
  double worst_ab = 0.0, worst_ac = 0.0, moved = 0.0;
  for (size_t r = 0; r < y[0].size(); ++r) {
    worst_ab = std::max(worst_ab, std::abs(y[0][r] - y[1][r]));
    worst_ac = std::max(worst_ac, std::abs(y[0][r] - y[2][r]));
    moved = std::max(moved, std::abs(y[0][r]));
  }
  EXPECT_GT(moved, 1e-4);  // the tip moves sideways at ~0.1 m/s
  EXPECT_LT(worst_ab, 1e-12);
  EXPECT_LT(worst_ac, 1e-12);
  // Frames without an interval (no t column) name the key.
  const std::string bad = dir.Write("bad.yaml", Scene(dyn, "    initial: {frames: [f0.csv, f1.csv]}\n"));
  const RunResult run = RunRodfit(dir, "simulate " + Quote(bad) + " -o " + Quote(dir.File("ob")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("initial.frames: give frame_interval"));
  // A velocity file whose arc lengths leave the rod (another rod's, or millimetres): one line
  // naming the file, its row and the column, and nothing written.
  dir.Write("v_off.csv", "s,vx,vy,vz\n0,0,0,0\n0.5,0,0.1,0\n1.5,0,0.2,0\n");
  const std::string off =
      dir.Write("off.yaml", Scene(dyn, "    initial: {shape: f0.csv, velocity: v_off.csv}\n"));
  const RunResult off_run =
      RunRodfit(dir, "simulate " + Quote(off) + " -o " + Quote(dir.File("ooff")));
  EXPECT_EQ(off_run.status, 1);
  EXPECT_THAT(off_run.err, HasSubstr("v_off.csv:4: s: must lie on the rod, in [0, 1] m"));
  EXPECT_FALSE(std::filesystem::exists(dir.File("ooff")));
}

TEST(SimulateDynamics, BadVertexArcLengthsAreOneLineNamingTheKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"[0.1, 0.5, 1.0]", "vertex_s[0]: must be 0"},
      {"[0, 0.5, 0.4, 1.0]", "vertex_s[2]: must be larger than the one before"},
      {"[0, 0.5, 0.9]", "vertex_s[2]: must be rod.length 1"},
      {"[0, 1.0]", "rod.vertex_s: expected 3 to"},
  };
  for (const auto& [list, message] : cases) {
    TempDir dir;
    const std::string scene = dir.Write(
        "s.yaml", Replace(Scene("{time_step: 0.001, duration: 0.01}", ""), "segments: 20",
                          "vertex_s: " + list));
    const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
    EXPECT_EQ(run.status, 1) << list;
    EXPECT_THAT(run.err, HasSubstr("s.yaml:")) << list;
    EXPECT_THAT(run.err, HasSubstr(message)) << run.err;
  }
  // Both keys: they must agree.
  TempDir dir;
  const std::string scene = dir.Write(
      "s.yaml", Replace(Scene("{time_step: 0.001, duration: 0.01}", ""), "segments: 20",
                        "segments: 3, vertex_s: [0, 0.5, 1.0]"));
  const RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("rod.segments: disagrees with vertex_s (2 segments)"));
}

TEST(Rollout, PredictsARecordingMadeBySimulate) {
  TempDir dir;
  dir.Write("path.csv", "t,x,y,z\n0,0.9,0,0\n0.3,0.8,0.1,0.05\n");
  const std::string scene = dir.Write(
      "s.yaml", Scene("{time_step: 0.005, duration: 0.3, output_every: 2}",
                      "    end_pin: {position: [0.9, 0, 0]}\n"
                      "    drive: [{point: end_pin, file: path.csv}]\n"));
  RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("o")));
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable traj = CsvTable::Read(dir.File("o/trajectory.csv"));
  const std::vector<double> t = traj.Column("t"), v = traj.Column("vertex"), x = traj.Column("x"),
                            y = traj.Column("y"), z = traj.Column("z");
  std::string rec = "t,marker,x,y,z\n";
  for (int r = 0; r < traj.num_rows(); ++r) {
    if (static_cast<int>(v[r]) % 5 != 0) continue;
    rec += FormatDouble(t[r]) + "," + std::to_string(static_cast<int>(v[r]) / 5) + "," +
           FormatDouble(x[r]) + "," + FormatDouble(y[r]) + "," + FormatDouble(z[r]) + "\n";
  }
  dir.Write("rec.csv", rec);
  run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("rec.csv")) + " -o " +
                           Quote(dir.File("r")) + " --held 0,1,-1");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("mean absolute coordinate error"));
  {
    // A batch with a recording whose rollout fails (its last, held marker jumps 0.25 m along x at
    // t = 0.15 s: the recording still lies within the rod's length, but the jump tears the rod's
    // end beyond its small-strain limit): the other is rolled out and written, the failing one
    // named in its row of recordings.csv and on stderr, exit 3.
    const CsvTable table = CsvTable::Read(dir.File("rec.csv"));
    const std::vector<double> rt = table.Column("t"), rm = table.Column("marker"),
                              rx = table.Column("x"), ry = table.Column("y"), rz = table.Column("z");
    const int last = static_cast<int>(*std::max_element(rm.begin(), rm.end()));
    std::string torn = "t,marker,x,y,z\n";
    for (int r = 0; r < table.num_rows(); ++r) {
      const int m = static_cast<int>(rm[r]);
      const double shift = rt[r] >= 0.15 && m == last ? 0.25 : 0.0;
      torn += FormatDouble(rt[r]) + "," + std::to_string(m) + "," + FormatDouble(rx[r] + shift) +
              "," + FormatDouble(ry[r]) + "," + FormatDouble(rz[r]) + "\n";
    }
    dir.Write("torn.csv", torn);
    run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("rec.csv")) + " " +
                             Quote(dir.File("torn.csv")) + " -o " + Quote(dir.File("batch")) +
                             " --held 0,1,-1");
    EXPECT_EQ(run.status, 3) << run.err;
    EXPECT_THAT(run.err, HasSubstr("1 of 2 recording(s) failed (the others written): "));
    EXPECT_THAT(run.err, HasSubstr("torn.csv: t = "));
    const CsvTable rows = CsvTable::Read(dir.File("batch/recordings.csv"));
    ASSERT_EQ(rows.num_rows(), 2);
    const CsvTable written = CsvTable::Read(dir.File("batch/rollout.csv"));
    EXPECT_GT(written.num_rows(), 0);
    for (double r : written.Column("recording")) EXPECT_EQ(r, 0.0);  // only the one that ran
    std::ifstream in_rows(dir.File("batch/recordings.csv"));
    const std::string text((std::istreambuf_iterator<char>(in_rows)), std::istreambuf_iterator<char>());
    EXPECT_THAT(text, HasSubstr(",ok,"));
    EXPECT_THAT(text, HasSubstr(",failed,"));
    const CsvTable over_time = CsvTable::Read(dir.File("batch/rollout_error.csv"));
    EXPECT_GT(over_time.num_rows(), 0);
  }
  const CsvTable out = CsvTable::Read(dir.File("r/rollout.csv"));
  EXPECT_EQ(out.num_rows(), 31 * 5);  // 31 frames of 5 markers
  // The rollout's clamp points along the chord to marker 1 (5 edges away), the truth's along
  // x: the sag between them tilts it, the one difference between the two models here.
  const std::vector<double> ox = out.Column("observed_x"), px = out.Column("x"),
                            oz = out.Column("observed_z"), pz = out.Column("z");
  double sum = 0.0;
  for (int r = 0; r < out.num_rows(); ++r) sum += std::abs(ox[r] - px[r]) + std::abs(oz[r] - pz[r]);
  EXPECT_LT(sum / (2 * out.num_rows()), 3e-3) << run.out;
  // --fit: drag started 3x too high, fitted to the recording: the error does not grow, and
  // motion_fit.json holds the start and the fitted value.
  const std::string high_drag = dir.Write(
      "h.yaml", Replace(Scene("{time_step: 0.005, duration: 0.3, output_every: 2}",
                              "    end_pin: {position: [0.9, 0, 0]}\n"),
                        "damping: {value: 0.02}", "damping: {value: 0.06}"));
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("f")) + " --held 0,1,-1 --fit damping "
                           "--max-evaluations 20");
  // The recording is noise-free, so its noise estimated from it (none given) is tiny and the
  // rollout's model (bound below) does not explain it to that: exit 5, everything written.
  ASSERT_EQ(run.status, 5) << run.err;
  EXPECT_THAT(run.err, HasSubstr("estimated from the recordings"));
  EXPECT_THAT(run.out, HasSubstr("damping: 0.06 ->"));
  std::ifstream in(dir.File("f/motion_fit.json"));
  const std::string json((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(json, HasSubstr("\"damping\": {\"start\": 0.059999999999999998"));
  // The least-squares fit (the default) says whether it converged and how well the data
  // determine each value: here the rollout's model (vertices at the markers, the clamp along the
  // chord to marker 1) differs from simulate's, and the drag alone runs to its bound.
  EXPECT_THAT(json, HasSubstr("\"converged\": true"));
  EXPECT_THAT(json, HasSubstr("\"identifiable\": "));
  EXPECT_THAT(json, HasSubstr("\"at_bound\": "));
  {
    // Beside it profile.json: the rod as fitted, the fitted drag with its start, what `rodfit
    // export` and a simulator read (export checks it as the runtime's reader does).
    const nlohmann::json fit = nlohmann::json::parse(json);
    std::ifstream profile_in(dir.File("f/profile.json"));
    ASSERT_TRUE(profile_in.good());
    const nlohmann::json profile = nlohmann::json::parse(profile_in);
    EXPECT_EQ(profile["format"], "rodfit-profile");
    EXPECT_EQ(profile["parameters"]["damping"]["start"], 0.06);
    EXPECT_EQ(profile["parameters"]["damping"]["fitted"], true);
    EXPECT_FALSE(profile["rod"].contains("rest_shape"));  // not fitted, none in the scene
    // The drag runs to its bound here (above): not identifiable, so the profile has no value
    // for it, and export refuses it by its key until one is given with --set.
    ASSERT_EQ(fit["parameters"]["damping"]["identifiable"], false);
    EXPECT_TRUE(profile["parameters"]["damping"]["value"].is_null());
    RunResult exported =
        RunRodfit(dir, "export " + Quote(dir.File("f/profile.json")) + " --format json -o " +
                           Quote(dir.File("f_export.json")));
    EXPECT_EQ(exported.status, 1);
    EXPECT_THAT(exported.err, HasSubstr("profile.json: parameters.damping.value: is null"));
    exported = RunRodfit(dir, "export " + Quote(dir.File("f/profile.json")) +
                                  " --format xpbd --time-step 0.001 --set damping=0.02 -o " +
                                  Quote(dir.File("f_export.json")));
    EXPECT_EQ(exported.status, 0) << exported.err;
  }
  {
    // With the rest shape fitted, profile.json carries its knots as motion_fit.json has them
    // (rod.rest_shape), and export rebuilds the rod with them. The recording: the rollout's
    // prediction of rec.csv by the cable curved at rest (k2° = 0.5 1/m; paths as recorded,
    // --smooth 0), its held markers as recorded; the fit starts straight. Its residuals stay
    // above the stated 0.1 mm (exit 5: everything written), but every knot is determined, so
    // the profile is written (one that is not: no profile.json, said on stdout, as above).
    const std::string curved = dir.Write(
        "curved.yaml", Replace(Scene("{time_step: 0.005, duration: 0.3, output_every: 2}",
                                     "    end_pin: {position: [0.9, 0, 0]}\n"),
                               "linear_density: 0.04}", "linear_density: 0.04, rest_curvature: [0, 0.5, 0]}"));
    run = RunRodfit(dir, "rollout " + Quote(curved) + " " + Quote(dir.File("rec.csv")) + " -o " +
                             Quote(dir.File("cr")) + " --held 0,1,-1 --smooth 0");
    ASSERT_EQ(run.status, 0) << run.err;
    const CsvTable made = CsvTable::Read(dir.File("cr/rollout.csv"));
    const std::vector<double> mt = made.Column("t"), mm = made.Column("marker"),
                              mx = made.Column("x"), my = made.Column("y"), mz = made.Column("z"),
                              ox = made.Column("observed_x"), oy = made.Column("observed_y"),
                              oz = made.Column("observed_z");
    // The held markers as recorded (marker 1 gives the clamp's tangent), the others predicted.
    const int last = static_cast<int>(*std::max_element(mm.begin(), mm.end()));
    std::string own = "t,marker,x,y,z\n";
    for (int r = 0; r < made.num_rows(); ++r) {
      const int m = static_cast<int>(mm[r]);
      const bool held = m == 0 || m == 1 || m == last;
      own += FormatDouble(mt[r]) + "," + std::to_string(m) + "," +
             FormatDouble(held ? ox[r] : mx[r]) + "," + FormatDouble(held ? oy[r] : my[r]) + "," +
             FormatDouble(held ? oz[r] : mz[r]) + "\n";
    }
    dir.Write("own.csv", own);
    run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("own.csv")) + " -o " +
                             Quote(dir.File("rs")) + " --held 0,1,-1 --smooth 0 --fit "
                             "rest_curvature --rest-knots 3 --marker-sigma 1e-4");
    ASSERT_TRUE(run.status == 0 || run.status == 5) << run.out << run.err;
    EXPECT_THAT(run.out, Not(HasSubstr("not identifiable")));
    std::ifstream fit_in(dir.File("rs/motion_fit.json")), profile_in(dir.File("rs/profile.json"));
    ASSERT_TRUE(fit_in.good());
    ASSERT_TRUE(profile_in.good()) << run.err;
    const nlohmann::json fit = nlohmann::json::parse(fit_in), profile = nlohmann::json::parse(profile_in);
    for (const char* key : {"s_m", "k1_per_m", "k2_per_m", "tau_per_m"})
      EXPECT_EQ(profile["rod"]["rest_shape"][key], fit["rest_shape"][key]) << key;
    const RunResult exported =
        RunRodfit(dir, "export " + Quote(dir.File("rs/profile.json")) + " --format xpbd "
                       "--time-step 0.001 -o " + Quote(dir.File("rs_xpbd.json")));
    ASSERT_EQ(exported.status, 0) << exported.err;
    std::ifstream xpbd_in(dir.File("rs_xpbd.json"));
    const nlohmann::json xpbd = nlohmann::json::parse(xpbd_in);
    ASSERT_TRUE(xpbd["joints"][1].contains("rest_curvature"));
    // Joint 1 sits at s = L / 20 (20 segments), before the second knot at L / 2: its rest
    // curvature is the first two knots' interpolation.
    const double k1_0 = fit["rest_shape"]["k1_per_m"][0], k1_1 = fit["rest_shape"]["k1_per_m"][1];
    EXPECT_NEAR(xpbd["joints"][1]["rest_curvature"][0].get<double>(), k1_0 + 0.1 * (k1_1 - k1_0),
                1e-9 * (1.0 + std::abs(k1_0) + std::abs(k1_1)));
  }
  // Fitted with the bending stiffness, the drag is determined (measured 0.023 +- 0.006; the
  // truth 0.02) and the bending, which this slow drag hardly shows, is reported as not.
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("b")) + " --held 0,1,-1 --fit "
                           "bend_stiffness,damping --max-evaluations 150");
  ASSERT_EQ(run.status, 5) << run.err;  // not explained to the estimated noise, as above
  EXPECT_THAT(run.out, HasSubstr("bend_stiffness: 0.002 -> "));
  EXPECT_THAT(run.out, HasSubstr("(not identifiable: "));
  EXPECT_THAT(run.out, ::testing::ContainsRegex("damping: 0.06 -> 0.0[12][0-9]* \\+- 0.00"));
  // With the markers' noise stated, a misfit far beyond it is said: the rollout's model misses
  // this noise-free recording by millimetres (the clamp along the chord; bound above), far more
  // than a 10 um noise; a 5 cm noise covers it.
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("s1")) + " --held 0,1,-1 --fit damping "
                           "--max-evaluations 20 --marker-sigma 1e-5");
  ASSERT_EQ(run.status, 5) << run.err;
  EXPECT_THAT(run.err, HasSubstr("the model does not explain the recordings to their noise"));
  EXPECT_TRUE(std::ifstream(dir.File("s1/motion_fit.json")).good());
  EXPECT_TRUE(std::ifstream(dir.File("s1/rollout.csv")).good());
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("s2")) + " --held 0,1,-1 --fit damping "
                           "--max-evaluations 20 --marker-sigma 0.05");
  // Explained to a 5 cm noise, which however leaves the drag undetermined (exit 4, not 5).
  ASSERT_EQ(run.status, 4) << run.err;
  EXPECT_THAT(run.out, HasSubstr("(not identifiable: "));
  EXPECT_THAT(run.err, ::testing::Not(HasSubstr("does not explain")));
  // A least-squares fit stopped by its budget writes its best point with converged false (exit
  // 4; with a noise that explains the recording, so that the status is not 5's).
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("n")) + " --held 0,1,-1 --fit "
                           "bend_stiffness,damping --max-evaluations 2 --marker-sigma 0.05");
  EXPECT_EQ(run.status, 4) << run.err;
  EXPECT_THAT(run.err, HasSubstr("--fit: stopped at max_evaluations"));
  {
    std::ifstream n_in(dir.File("n/motion_fit.json"));
    const std::string n_json((std::istreambuf_iterator<char>(n_in)), std::istreambuf_iterator<char>());
    EXPECT_THAT(n_json, HasSubstr("\"converged\": false"));
  }
  // --parameters: the values fitted to one recording carried to the rollout of another (here
  // the same one, as a held-out recording of the rod would be): the same prediction as the fit's
  // own rollout, and the file's mistakes said in one line naming it, its line and the key.
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("p")) + " --held 0,1,-1 --parameters " +
                           Quote(dir.File("b/motion_fit.json")));
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("damping = 0.0"));
  {
    std::ifstream fitted_in(dir.File("b/rollout.csv")), carried_in(dir.File("p/rollout.csv"));
    const std::string fitted((std::istreambuf_iterator<char>(fitted_in)), std::istreambuf_iterator<char>());
    const std::string carried((std::istreambuf_iterator<char>(carried_in)), std::istreambuf_iterator<char>());
    EXPECT_FALSE(fitted.empty());
    EXPECT_EQ(carried, fitted);
  }
  const struct {
    std::string json, message;
  } bad_files[] = {
      {"{\"parameters\": ", "p.json: not JSON: "},
      {"{\"converged\": true}", "p.json: parameters: a motion fit file has a parameters object"},
      {"{\n  \"parameters\": {\n    \"length\": {\"value\": 1}\n  }\n}\n",
       "p.json:3: parameters.length: not a parameter of the motion"},
      {"{\n  \"parameters\": {\n    \"damping\": {\"value\": -1}\n  }\n}\n",
       "p.json:3: parameters.damping.value: must be a number > 0"},
  };
  for (const auto& bad : bad_files) {
    dir.Write("p.json", bad.json);
    run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                             " -o " + Quote(dir.File("q")) + " --held 0,1,-1 --parameters " +
                             Quote(dir.File("p.json")));
    EXPECT_EQ(run.status, 1) << bad.message;
    EXPECT_THAT(run.err, HasSubstr(bad.message));
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
  }
  EXPECT_FALSE(std::ifstream(dir.File("q/rollout.csv")).good());
  // The derivative-free search it replaced, on request.
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("y")) + " --held 0,1,-1 --fit damping "
                           "--method bobyqa --max-evaluations 20");
  ASSERT_EQ(run.status, 5) << run.err;  // the noise-free recording, as with --fit above
  std::ifstream by(dir.File("y/motion_fit.json"));
  const std::string bjson((std::istreambuf_iterator<char>(by)), std::istreambuf_iterator<char>());
  EXPECT_THAT(bjson, HasSubstr("BOBYQA"));
  // The grippers' tilts as nuisances (--gripper-prior-deg): printed per recording, written in
  // motion_fit.json's gripper_tilts (a pair of angles and of std per gripper), not among its
  // parameters; with pins (the default held ends) refused in one line, nothing written.
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("tilts")) + " --held-ends grippers --fit "
                           "damping --gripper-prior-deg 10 --max-evaluations 20");
  ASSERT_NE(run.status, 1) << run.err;
  EXPECT_THAT(run.out, HasSubstr("gripper tilts (about d1, d2) of "));
  {
    std::ifstream tin(dir.File("tilts/motion_fit.json"));
    const nlohmann::json tj = nlohmann::json::parse(tin);
    ASSERT_TRUE(tj.contains("gripper_tilts")) << tj.dump();
    EXPECT_EQ(tj["gripper_tilts"]["prior_std_deg"].get<double>(), 10.0);
    EXPECT_EQ(tj["gripper_tilts"]["prior_residuals"].get<int>(), 4);
    ASSERT_EQ(tj["gripper_tilts"]["recordings"].size(), 1u);
    const nlohmann::json& one = tj["gripper_tilts"]["recordings"][0];
    EXPECT_THAT(one["file"].get<std::string>(), HasSubstr("rec.csv"));
    for (const char* key : {"clamp_deg", "clamp_std_deg", "end_deg", "end_std_deg"})
      EXPECT_EQ(one[key].size(), 2u) << key;
    EXPECT_EQ(tj["parameters"].size(), 1u);
    EXPECT_TRUE(tj["parameters"].contains("damping"));
    EXPECT_EQ(tj["names"].size(), 1u);
  }
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("tilts_pins")) + " --fit damping "
                           "--gripper-prior-deg 10 --held-ends pins");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("need grippers"));
  EXPECT_FALSE(std::ifstream(dir.File("tilts_pins/motion_fit.json")).good());
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("tilts_nofit")) + " --held-ends grippers "
                           "--gripper-prior-deg 10");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("--gripper-prior-deg: the grippers' tilts are fitted with --fit"));
  EXPECT_FALSE(std::ifstream(dir.File("tilts_nofit/rollout.csv")).good());
  run = RunRodfit(dir, "rollout " + Quote(high_drag) + " " + Quote(dir.File("rec.csv")) +
                           " -o " + Quote(dir.File("g")) + " --fit length");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("--fit: a motion fit cannot fit 'length'"));
  // The same recording in millimetres: with --unit mm the same rollout; without it, an error
  // that names the file and the likely cause (and metres given as millimetres likewise).
  std::string rec_mm = "t,marker,x,y,z\n";
  for (int r = 0; r < traj.num_rows(); ++r) {
    if (static_cast<int>(v[r]) % 5 != 0) continue;
    rec_mm += FormatDouble(t[r]) + "," + std::to_string(static_cast<int>(v[r]) / 5) + "," +
              FormatDouble(1e3 * x[r]) + "," + FormatDouble(1e3 * y[r]) + "," +
              FormatDouble(1e3 * z[r]) + "\n";
  }
  dir.Write("rec_mm.csv", rec_mm);
  run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("rec_mm.csv")) + " -o " +
                           Quote(dir.File("mm")) + " --held 0,1,-1 --unit mm");
  ASSERT_EQ(run.status, 0) << run.err;
  const CsvTable out_mm = CsvTable::Read(dir.File("mm/rollout.csv"));
  ASSERT_EQ(out_mm.num_rows(), out.num_rows());
  const std::vector<double> px_mm = out_mm.Column("x"), ox_mm = out_mm.Column("observed_x");
  for (int r = 0; r < out.num_rows(); ++r) {
    EXPECT_NEAR(ox_mm[r], ox[r], 1e-12) << r;
    EXPECT_NEAR(px_mm[r], px[r], 1e-9) << r;
  }
  run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("rec_mm.csv")) + " -o " +
                           Quote(dir.File("mm2")) + " --held 0,1,-1");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("rec_mm.csv: x: the markers span"));
  EXPECT_THAT(run.err, HasSubstr("millimetres read as metres? (give --unit mm)"));
  run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("rec.csv")) + " -o " +
                           Quote(dir.File("mm3")) + " --held 0,1,-1 --unit mm");
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("metres read as millimetres? (--unit mm is set)"));
  // A frame column without its rate is one line naming the file.
  dir.Write("bad.csv", "frame,marker,x,y,z\n0,0,0,0,0\n");
  run = RunRodfit(dir, "rollout " + Quote(scene) + " " + Quote(dir.File("bad.csv")) + " -o " +
                           Quote(dir.File("r2")));
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("bad.csv:1: frame: a frame column needs --frame-rate"));
}

// The bundled scene's own recording, noise-free and as motion capture gives it (1 mm noise, 2 %
// of the samples dropped), rolled out at the scene's time step, at half of it and at the
// recording's 10 ms frame interval (how held-out recordings are scored), with the pins at
// markers 1 and n-2 (the scene's far end is a pin, free to turn, which the default jaws, clamps
// along the end markers' chords, are not: 6.0 mm noise-free with them): the pins kink the rod
// and drive the edges' twist, which this scene leaves undamped; the rollout damps it with bending's retardation time (rollout.h, DefaultTwistDamping), without
// which each of these stopped at 0.24-0.53 s with a Newton step that did not converge. At 10 ms
// the noisy recording stopped at 0.43 s before the implicit step's residual merit and its
// budget of 50 Newton iterations (docs/solvers.md, "Dynamics").
TEST(Rollout, BundledSceneOwnRecordingAtItsStepHalfAndFrameInterval) {
  TempDir dir;
  const std::string scenes = std::string(RODFIT_SOURCE_DIR) + "/data/scenes/";
  std::ifstream scene_in(scenes + "cable_drive.yaml"), path_in(scenes + "cable_end_path.csv");
  const std::string scene_text((std::istreambuf_iterator<char>(scene_in)), std::istreambuf_iterator<char>());
  const std::string path_text((std::istreambuf_iterator<char>(path_in)), std::istreambuf_iterator<char>());
  ASSERT_NE(scene_text.find("time_step: 1.0e-3"), std::string::npos);
  const std::string scene = dir.Write("s.yaml", scene_text);
  const std::string half = dir.Write("h.yaml", Replace(scene_text, "time_step: 1.0e-3", "time_step: 5.0e-4"));
  const std::string frame = dir.Write("f.yaml", Replace(scene_text, "time_step: 1.0e-3", "time_step: 1.0e-2"));
  dir.Write("cable_end_path.csv", path_text);
  RunResult run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("c")) + " --markers 10");
  ASSERT_EQ(run.status, 0) << run.err;
  run = RunRodfit(dir, "simulate " + Quote(scene) + " -o " + Quote(dir.File("n")) +
                           " --markers 10 --marker-noise 1e-3 --marker-drop 0.02 --seed 3");
  ASSERT_EQ(run.status, 0) << run.err;
  // Measured (predicted markers): 3.0 mm noise-free, 5.4 mm with noise, at each step (5.5 mm at
  // 10 ms); the goal for real recordings is 10 mm.
  const struct {
    std::string recording;
    double bound;
  } recordings[] = {{"c/markers.csv", 4e-3}, {"n/markers.csv", 7e-3}};
  for (const auto& rec : recordings) {
    for (const std::string& s : {scene, half, frame}) {
      run = RunRodfit(dir, "rollout " + Quote(s) + " " + Quote(dir.File(rec.recording)) + " -o " +
                               Quote(dir.File("r")) + " --held-ends pins");
      ASSERT_EQ(run.status, 0) << rec.recording << " " << s << ": " << run.err;
      EXPECT_THAT(run.out, HasSubstr("twist_damping not given: 1.5e-05 N m^2 s"));
      const size_t at = run.out.find("m over all markers, ");
      ASSERT_NE(at, std::string::npos) << run.out;
      const double predicted = std::stod(run.out.substr(at + 20));
      EXPECT_LT(predicted, rec.bound) << rec.recording << " " << s;
    }
  }
}

}  // namespace
}  // namespace rodfit::test
