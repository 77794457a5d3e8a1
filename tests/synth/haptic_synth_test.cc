// Tests of the haptic logs `rodfit synth` writes for `grasp_force` entries (synth/synth.h,
// SynthOptions): the same seed gives the same bytes (and another seed other bytes); the log
// follows the documented drag schedule with the solved grasp reaction at every stop; the samples
// where the tool dwells pass the fit's quasi-static filter (io/fit_input.cc, central-difference
// speed below max_speed) while every sample of a move is dropped; and a case without a grasp, a
// log of another grasped point or a log too long to write is a one-line error that writes
// nothing.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/synth/synth.h"
#include "rodfit/model/rod.h"
#include "rodfit/solve/rod_energy.h"
#include "rodfit/solve/statics.h"
#include "io/temp_dir.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/synthesize.h"

namespace rodfit {
namespace {

namespace fs = std::filesystem;
using test::TempDir;
using ::testing::HasSubstr;

// A bowel-like segment on two spring zones, grasped at s = 0.1 and dragged 2.5 cm (sideways and
// up); ENTRY is replaced by each test's grasp_force entry.
const char* const kExperiment = R"(rod: {length: 0.15, segments: 20, radius: 0.012, linear_density: 0.45}
parameters:
  bend_stiffness: {value: 2.0e-4}
  twist_stiffness: {value: 1.5e-4}
  stretch_stiffness: {value: 40}
  spring_stiffness: {value: 150, fit: true}
  mesentery: {value: 400}
springs:
  - {from: 0.0, to: 0.07}
  - {from: 0.07, to: 0.15, parameter: mesentery}
cases:
  - name: drag
    clamp: {position: [0, 0, 0], tangent: [2, 0, 0], normal: [0, 0, 1]}
    grasp: {s: 0.1, position: [0.1, 0.015, 0.02]}
    observations:
ENTRY)";

const std::string kDefaultEntry =
    "      - {type: grasp_force, file: drag_force.csv, sigma: 0.01, s: 0.1}\n";

std::string Text(const std::string& entry = kDefaultEntry) {
  std::string text = kExperiment;
  return text.replace(text.find("ENTRY"), 5, entry);
}

std::string LogOf(const SynthBundle& bundle, const std::string& name = "drag_force.csv") {
  for (const auto& [file, contents] : bundle.files)
    if (file == name) return contents;
  ADD_FAILURE() << name << " not in the bundle";
  return "";
}

struct Log {
  std::vector<double> t;
  std::vector<Vec3> tool, force;
};

Log ParseLog(const std::string& text) {
  const CsvTable table = CsvTable::Parse(text, "log.csv");
  EXPECT_EQ(table.header(), std::vector<std::string>({"t", "tool_x", "tool_y", "tool_z", "fx",
                                                      "fy", "fz"}));
  const auto t = table.Column("t"), x = table.Column("tool_x"), y = table.Column("tool_y"),
             z = table.Column("tool_z"), fx = table.Column("fx"), fy = table.Column("fy"),
             fz = table.Column("fz");
  Log log;
  for (int r = 0; r < table.num_rows(); ++r) {
    log.t.push_back(t[r]);
    log.tool.emplace_back(x[r], y[r], z[r]);
    log.force.emplace_back(fx[r], fy[r], fz[r]);
  }
  return log;
}

// The force on the instrument holding s at `position`, solved as simulate solves a grasp case.
Vec3 SolvedReaction(const Experiment& e, const Vec3& position) {
  LoadCase c = e.scene.cases[0];
  c.grasp = Grasp{0.1, position};
  const RodModel model(e.scene.rod, e.scene.material, e.scene.gravity, c, e.scene.springs);
  RodState state = model.StraightState();
  EXPECT_TRUE(SolveStatics(model, StaticsOptions(), &state).converged);
  return GraspReaction(model, state);
}

// The central-difference tool speed of row r (one-sided at the ends), as the fit computes it.
double Speed(const Log& log, int r) {
  const int n = static_cast<int>(log.t.size());
  const int a = std::max(0, r - 1), b = std::min(n - 1, r + 1);
  return (log.tool[b] - log.tool[a]).norm() / (log.t[b] - log.t[a]);
}

TEST(HapticSynth, SameSeedSameBytesOtherSeedOtherBytes) {
  TempDir dir;
  const std::string protocol = dir.Write("in/protocol.yaml", Text());
  const Experiment e = LoadExperiment(protocol);
  SynthOptions options;
  options.seed = 42;
  const std::string a = LogOf(MakeSynthBundle(e, options));
  const std::string b = LogOf(MakeSynthBundle(e, options));
  EXPECT_EQ(a, b);
  EXPECT_THAT(a, ::testing::StartsWith("t,tool_x,tool_y,tool_z,fx,fy,fz\n"));
  options.seed = 43;
  const std::string c = LogOf(MakeSynthBundle(e, options));
  EXPECT_NE(a, c);
  // Only the noise differs: same rows, same times.
  const Log la = ParseLog(a), lc = ParseLog(c);
  ASSERT_EQ(la.t.size(), lc.t.size());
  EXPECT_EQ(la.t, lc.t);

  // Written to disk, byte for byte, and experiment.yaml still points at the log.
  options.seed = 42;
  Synthesize(e, dir.File("out"), options);
  EXPECT_EQ(test::ReadText(dir.File("out/drag_force.csv")), a);
  const Experiment again = LoadExperiment(dir.File("out/experiment.yaml"));
  ASSERT_EQ(again.cases[0].observations.size(), 1u);
  EXPECT_EQ(again.cases[0].observations[0].type, "grasp_force");
  EXPECT_EQ(fs::path(again.cases[0].observations[0].file), fs::path(dir.File("out/drag_force.csv")));
}

TEST(HapticSynth, TheLogFollowsTheDragScheduleWithSolvedForces) {
  TempDir dir;
  const Experiment e = LoadExperiment(dir.Write("protocol.yaml", Text()));
  SynthOptions options;
  options.add_noise = false;
  const Log log = ParseLog(LogOf(MakeSynthBundle(e, options)));

  // Stops P_k = P_0 + k/8 (P_8 - P_0), P_0 the rest position of s = 0.1 (clamp tangent [2, 0, 0]
  // is not unit on purpose), P_8 the case's grasp.position.
  const int steps = options.haptic_default_steps;
  const Vec3 start(0.1, 0.0, 0.0), end(0.1, 0.015, 0.02);
  const double dt = 1.0 / options.haptic_rate;
  const int dwell = static_cast<int>(std::lround(options.haptic_dwell_time * options.haptic_rate));
  const double step_length = (end - start).norm() / steps;
  const int intervals = std::max(
      2, static_cast<int>(std::ceil(step_length /
                                    (options.haptic_move_speed_factor * 1e-3 * dt))));
  ASSERT_EQ(static_cast<int>(log.t.size()), 1 + steps * (intervals - 1 + dwell));
  for (size_t r = 0; r < log.t.size(); ++r) EXPECT_DOUBLE_EQ(log.t[r], r * dt) << r;
  EXPECT_EQ(log.tool[0], start);
  EXPECT_NEAR((log.force[0] - SolvedReaction(e, start)).norm(), 0.0, 1e-12);

  int r = 1;
  Vec3 previous_force = log.force[0];
  for (int k = 1; k <= steps; ++k) {
    SCOPED_TRACE("step " + std::to_string(k));
    const Vec3 stop = start + (double(k) / steps) * (end - start);
    const Vec3 force = SolvedReaction(e, stop);
    const Vec3 move_start = log.tool[r - 1];
    for (int j = 1; j < intervals; ++j, ++r) {  // moving at constant speed, forces interpolated
      const double f = double(j) / intervals;
      EXPECT_LT((log.tool[r] - (move_start + f * (stop - move_start))).norm(), 1e-15);
      EXPECT_LT((log.force[r] - (previous_force + f * (force - previous_force))).norm(), 1e-12);
    }
    for (int d = 0; d < dwell; ++d, ++r) {  // still at the stop, the solved reaction
      EXPECT_LT((log.tool[r] - stop).norm(), 1e-15);
      EXPECT_LT((log.force[r] - force).norm(), 1e-12 * force.norm());
    }
    previous_force = force;
  }
  // The drag pulls the tissue off its springs: a force of tenths of a newton on the instrument,
  // pointing back towards the rest position (minus the tool's displacement, roughly).
  EXPECT_GT(previous_force.norm(), 0.1);
  EXPECT_LT(previous_force.dot(end - start), 0.0);
}

TEST(HapticSynth, DwellSamplesAreQuasiStaticAndMovesAreNot) {
  TempDir dir;
  const std::string protocol = dir.Write("in/protocol.yaml", Text());
  SynthOptions options;
  options.seed = 7;
  options.add_noise = false;
  const Log exact = ParseLog(LogOf(MakeSynthBundle(LoadExperiment(protocol), options)));
  options.add_noise = true;
  Synthesize(LoadExperiment(protocol), dir.File("out"), options);
  const Log noisy = ParseLog(test::ReadText(dir.File("out/drag_force.csv")));
  ASSERT_EQ(exact.t.size(), noisy.t.size());
  const int n = static_cast<int>(exact.t.size());

  // The noise-free log says which rows dwell: a row whose tool equals both neighbours' (the last
  // row: its one neighbour's). The first and last rows of a dwell border a move.
  const double max_speed = 1e-3;  // the default
  std::set<std::string> dwell_times;
  int moves = 0, borders = 0;
  for (int r = 0; r < n; ++r) {
    const bool same_before = r > 0 && exact.tool[r - 1] == exact.tool[r];
    const bool same_after = r + 1 < n && exact.tool[r + 1] == exact.tool[r];
    const double speed = Speed(noisy, r);
    if (same_before && (same_after || r + 1 == n)) {
      dwell_times.insert(FormatDouble(noisy.t[r]));
      // Tool noise alone: about 0.1 max_speed, far below the threshold.
      EXPECT_LT(speed, 0.6 * max_speed) << "dwell row " << r;
    } else if (same_before || same_after) {
      ++borders;
      EXPECT_GT(speed, 5 * max_speed) << "dwell row next to a move " << r;
    } else {
      ++moves;
      EXPECT_GT(speed, 10 * max_speed) << "move row " << r;
    }
  }
  const int steps = options.haptic_default_steps;
  const int dwell = static_cast<int>(std::lround(options.haptic_dwell_time * options.haptic_rate));
  EXPECT_EQ(static_cast<int>(dwell_times.size()), steps * (dwell - 2) + 1);
  EXPECT_EQ(borders, 2 * steps - 1);
  EXPECT_GT(moves, steps);

  // The fit's filter keeps exactly the dwell rows: one grasped case per quasi-static sample
  // (no `count`: all of them), appended after the experiment's one case.
  const Experiment synthesized = LoadExperiment(dir.File("out/experiment.yaml"));
  const FitInput input = BuildFitInput(synthesized);
  ASSERT_EQ(input.cases.size(), 1 + dwell_times.size());
  std::set<std::string> kept;
  for (size_t c = 1; c < input.cases.size(); ++c) {
    const std::string& name = input.cases[c].load_case.name;
    ASSERT_EQ(name.rfind("drag@t=", 0), 0u) << name;
    kept.insert(name.substr(7));
  }
  EXPECT_EQ(kept, dwell_times);
}

TEST(HapticSynth, CountStepsGiveOneFitSamplePerDwell) {
  TempDir dir;
  const std::string protocol = dir.Write(
      "in/protocol.yaml",
      Text("      - {type: grasp_force, file: drag_force.csv, sigma: 0.01, s: 0.1, count: 5, "
           "max_speed: 2.0e-3}\n"));
  SynthOptions options;
  options.seed = 3;
  const SynthBundle bundle = Synthesize(LoadExperiment(protocol), dir.File("out"), options);
  EXPECT_THAT(bundle.report[0], HasSubstr("5 dwells"));
  const FitInput input = BuildFitInput(LoadExperiment(dir.File("out/experiment.yaml")));
  // `count` is both the number of steps synth makes and the number of quasi-static samples the
  // fit keeps (evenly thinned): one at each stop.
  ASSERT_EQ(input.cases.size(), 1u + 5u);
  const Vec3 start(0.1, 0.0, 0.0), end(0.1, 0.015, 0.02);
  for (int k = 1; k <= 5; ++k) {
    ASSERT_TRUE(input.cases[k].load_case.grasp.has_value());
    const Vec3 stop = start + (k / 5.0) * (end - start);
    EXPECT_LT((input.cases[k].load_case.grasp->position - stop).norm(), 1e-5) << k;
  }
}

TEST(HapticSynth, CaseWithoutAGraspOrAnotherGraspedPointIsAnError) {
  TempDir dir;
  std::string no_grasp = Text();
  no_grasp.replace(no_grasp.find("    grasp:"), no_grasp.find("    observations:") -
                                                    no_grasp.find("    grasp:"), "");
  const std::string path = dir.Write("in/protocol.yaml", no_grasp);
  try {
    Synthesize(LoadExperiment(path), dir.File("out"));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr(path + ":15: cases[0].observations[0]: case 'drag' has no grasp"));
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(dir.File("out")));

  const std::string other = dir.Write(
      "in/other.yaml",
      Text("      - {type: grasp_force, file: drag_force.csv, sigma: 0.01, s: 0.05}\n"));
  try {
    Synthesize(LoadExperiment(other), dir.File("out"));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("other.yaml:16: cases[0].observations[0]: s = 0.05 is not "
                                    "the case's grasp.s = 0.1"));
  }
  EXPECT_FALSE(fs::exists(dir.File("out")));

  // A max_speed so low that the moves would take days: refused before anything is solved.
  const std::string slow = dir.Write(
      "in/slow.yaml", Text("      - {type: grasp_force, file: drag_force.csv, sigma: 0.01, s: 0.1, "
                           "max_speed: 1.0e-9}\n"));
  try {
    Synthesize(LoadExperiment(slow), dir.File("out"));
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("slow.yaml:16: cases[0].observations[0]: the log would have"));
    EXPECT_THAT(e.what(), HasSubstr("raise max_speed"));
  }
  EXPECT_FALSE(fs::exists(dir.File("out")));
}

}  // namespace
}  // namespace rodfit
