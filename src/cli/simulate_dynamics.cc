// `rodfit simulate` for a moving scene (a `dynamics:` block): every case integrated in time by
// SimulateCaseDynamics, its frames written as trajectory.csv and reactions.csv.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <iostream>
#include <stdexcept>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/progress.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/shapes_csv.h"
#include "rodfit/solve/case_dynamics.h"

namespace {

// markers.csv: `count` markers evenly spaced in s, interpolated along each written frame's
// centre-line, with noise and drops, one recording per case (`case` column first).
std::string MarkersCsv(const std::vector<rodfit::CaseMotion>& motions, const MarkerSampling& m) {
  std::mt19937 rng(m.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::string out = "case,t,marker,x,y,z\n";
  for (const rodfit::CaseMotion& motion : motions) {
    const std::vector<double>& s = motion.s;
    for (size_t f = 0; f < motion.frames.size(); ++f) {
      const Eigen::Matrix3Xd& x = motion.frames[f].x;
      for (int k = 0; k < m.count; ++k) {
        const double sk = s.back() * k / (m.count - 1);
        size_t i = std::upper_bound(s.begin(), s.end(), sk) - s.begin();
        i = std::min(std::max<size_t>(i, 1), s.size() - 1);
        const double w = (sk - s[i - 1]) / (s[i] - s[i - 1]);
        Eigen::Vector3d p = (1 - w) * x.col(i - 1) + w * x.col(i);
        for (int c = 0; c < 3; ++c) p[c] += m.noise * gauss(rng);
        const bool dropped = f >= 2 && uniform(rng) < m.drop;
        if (dropped) continue;
        out += motion.name + "," + rodfit::FormatDouble(motion.frames[f].t) + "," +
               std::to_string(k) + "," + rodfit::FormatDouble(p[0]) + "," +
               rodfit::FormatDouble(p[1]) + "," + rodfit::FormatDouble(p[2]) + "\n";
      }
    }
  }
  return out;
}

}  // namespace

int SimulateMotion(const rodfit::Experiment& experiment, const std::string& scene_path,
                   const std::string& output_dir, bool keep_going, const MarkerSampling& markers,
                   bool quiet) {
  // A long integration shows which case it is on (a terminal only; io/progress.h).
  rodfit::ProgressLine progress(quiet, 2);
  // The output rule before the work: no output over an input (a drive path, a tip load, ...).
  rodfit::CheckOutputDirectory(
      output_dir, {"trajectory.csv", "reactions.csv", "summary.csv", "markers.csv"},
      rodfit::ExperimentInputs(experiment));
  const rodfit::Scene& scene = experiment.scene;
  std::vector<rodfit::CaseMotion> motions;
  std::vector<rodfit::MotionSummaryRow> summary;
  std::string first_failure;
  double seconds = 0.0;
  for (size_t k = 0; k < scene.cases.size(); ++k) {
    const rodfit::LoadCase& load_case = scene.cases[k];
    rodfit::CaseTrajectory trajectory;
    if (progress.enabled())
      progress.Update("simulate: integrating case " + std::to_string(k + 1) + " of " +
                          std::to_string(scene.cases.size()) + " (" + load_case.name + ")",
                      static_cast<double>(k) / scene.cases.size());
    try {
      trajectory = rodfit::SimulateCaseDynamics(scene, static_cast<int>(k), experiment.statics);
    } catch (const std::invalid_argument& e) {
      throw rodfit::InputError(scene_path, experiment.cases[k].line,
                               "cases[" + std::to_string(k) + "]", e.what());
    } catch (const std::runtime_error& e) {
      trajectory.ok = false;
      trajectory.reason = e.what();
    }
    seconds += trajectory.seconds;
    summary.push_back({load_case.name, trajectory.ok, trajectory.steps,
                       trajectory.newton_iterations, trajectory.stable_step, trajectory.reason});
    if (!trajectory.ok && first_failure.empty())
      first_failure = CasePlace(scene_path, experiment.cases[k].line, load_case.name) +
                      OneLine(trajectory.reason);
    rodfit::CaseMotion motion;
    motion.name = load_case.name;
    motion.s = trajectory.s;
    for (const rodfit::TrajectoryFrame& f : trajectory.frames) {
      rodfit::CaseMotion::Frame frame;
      frame.t = f.t;
      frame.x = f.x;
      for (const rodfit::HeldReaction& r : f.reactions)
        frame.reactions.push_back({load_case.name, r.point, r.s, r.position, r.force, r.moment});
      motion.frames.push_back(std::move(frame));
    }
    // A case that stopped early keeps the frames up to there only with --keep-going.
    if (trajectory.ok || keep_going) motions.push_back(std::move(motion));
  }
  progress.Finish();
  if (!first_failure.empty() && !keep_going) {
    std::cerr << "rodfit simulate: " << first_failure << "\n";
    return EXIT_FAILURE;
  }
  rodfit::StagedDirectory out(output_dir);
  out.SetInputs(rodfit::ExperimentInputs(experiment));
  std::vector<std::pair<std::string, std::string>> files = {
      {"trajectory.csv", rodfit::FormatTrajectoryCsv(motions)},
      {"reactions.csv", rodfit::FormatReactionsCsv(motions)},
      {"summary.csv", rodfit::FormatMotionSummaryCsv(summary)}};
  if (markers.count > 0) files.emplace_back("markers.csv", MarkersCsv(motions, markers));
  for (const auto& [name, text] : files) out.Write(name, text, "output file name");
  out.Commit();
  if (!first_failure.empty()) {
    std::cerr << "rodfit simulate: " << first_failure << " (the frames up to there written)\n";
    return 3;
  }
  // The time goes to stdout, not into the files (outputs are reproducible byte for byte).
  int steps = 0;
  for (const rodfit::MotionSummaryRow& r : summary) steps += r.steps;
  std::printf("integrated %zu cases (%d steps) in %.3f s; wrote %s\n", summary.size(), steps,
              seconds, output_dir.c_str());
  return EXIT_SUCCESS;
}
