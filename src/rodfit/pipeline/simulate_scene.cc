// SimulateScene (run.h): `rodfit simulate` as a library call — every case solved to static
// equilibrium, or integrated in time for a moving scene; the shapes, forces and trajectories in
// memory and, when asked, the output files. Linked into the `rodfit` executable without Ceres or
// OpenCV (docs/cli.md, "Start-up"): this file uses solve and io only.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/solve/case_dynamics.h"
#include "rodfit/model/tube_mesh.h"
#include "rodfit/solve/case_solve.h"
#include "rodfit/solve/poke.h"

namespace rodfit {
namespace {

void Progress(const SimulateOptions& options, const std::string& text, double fraction) {
  if (options.progress) options.progress(text, fraction);
}

// markers.csv: `count` markers evenly spaced in s, interpolated along each written frame's
// centre-line, with noise and drops, one recording per case (`case` column first).
std::string MarkersCsv(const std::vector<CaseMotion>& motions, const SimulateOptions& m) {
  std::mt19937 rng(m.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::string out = "case,t,marker,x,y,z\n";
  for (const CaseMotion& motion : motions) {
    const std::vector<double>& s = motion.s;
    for (size_t f = 0; f < motion.frames.size(); ++f) {
      const Eigen::Matrix3Xd& x = motion.frames[f].x;
      for (int k = 0; k < m.marker_count; ++k) {
        const double sk = s.back() * k / (m.marker_count - 1);
        size_t i = std::upper_bound(s.begin(), s.end(), sk) - s.begin();
        i = std::min(std::max<size_t>(i, 1), s.size() - 1);
        const double w = (sk - s[i - 1]) / (s[i] - s[i - 1]);
        Eigen::Vector3d p = (1 - w) * x.col(i - 1) + w * x.col(i);
        for (int c = 0; c < 3; ++c) p[c] += m.marker_noise * gauss(rng);
        const bool dropped = f >= 2 && uniform(rng) < m.marker_drop;
        if (dropped) continue;
        out += motion.name + "," + FormatDouble(motion.frames[f].t) + "," + std::to_string(k) +
               "," + FormatDouble(p[0]) + "," + FormatDouble(p[1]) + "," + FormatDouble(p[2]) +
               "\n";
      }
    }
  }
  return out;
}

// Writes `files` into the output directory all at once (nothing half-written), never over one of
// the run's inputs. `what` names where the file names came from.
void WriteFiles(const Experiment& experiment, const std::string& output_dir,
                const std::vector<std::pair<std::string, std::string>>& files, const char* what) {
  StagedDirectory out(output_dir);
  out.SetInputs(ExperimentInputs(experiment));
  // Case names become file names: the reader refuses paths, and Write keeps any name in DIR.
  for (const auto& [name, text] : files) out.Write(name, text, what);
  out.Commit();
}

// A moving scene: every case integrated in time by SimulateCaseDynamics.
void SimulateMotion(const Experiment& experiment, const SimulateOptions& options, SimulateRun* run) {
  const Scene& scene = experiment.scene;
  for (size_t k = 0; k < scene.cases.size(); ++k) {
    const LoadCase& load_case = scene.cases[k];
    CaseTrajectory trajectory;
    Progress(options,
             "simulate: integrating case " + std::to_string(k + 1) + " of " +
                 std::to_string(scene.cases.size()) + " (" + load_case.name + ")",
             static_cast<double>(k) / scene.cases.size());
    try {
      // Each step's simulated time (a long run's log says it is alive: io/progress.h).
      std::function<void(double)> step_progress;
      if (options.progress) {
        const double duration = scene.dynamics->duration;
        const double cases = static_cast<double>(scene.cases.size());
        step_progress = [&, k, duration, cases](double t) {
          const double done = (static_cast<double>(k) + std::min(t / duration, 1.0)) / cases;
          char text[160];
          std::snprintf(text, sizeof(text), "simulate: %.0f %% (case %s, t = %.3g s of %.3g s)",
                        100.0 * done, load_case.name.substr(0, 60).c_str(), t, duration);
          options.progress(text, done);
        };
      }
      trajectory = SimulateCaseDynamics(scene, static_cast<int>(k), experiment.statics,
                                        step_progress);
    } catch (const std::invalid_argument& e) {
      throw InputError(experiment.path, experiment.cases[k].line,
                       "cases[" + std::to_string(k) + "]", e.what());
    } catch (const std::runtime_error& e) {
      trajectory.ok = false;
      trajectory.reason = e.what();
    }
    run->seconds += trajectory.seconds;
    run->steps += trajectory.steps;
    run->motion_summary.push_back({load_case.name, trajectory.ok, trajectory.steps,
                                   trajectory.newton_iterations, trajectory.stable_step,
                                   trajectory.reason});
    if (!trajectory.ok && run->first_failure.empty())
      run->first_failure = CasePlace(experiment.path, experiment.cases[k].line, load_case.name) +
                           OneLine(trajectory.reason);
    CaseMotion motion;
    motion.name = load_case.name;
    motion.s = trajectory.s;
    for (const TrajectoryFrame& f : trajectory.frames) {
      CaseMotion::Frame frame;
      frame.t = f.t;
      frame.x = f.x;
      for (const HeldReaction& r : f.reactions)
        frame.reactions.push_back({load_case.name, r.point, r.s, r.position, r.force, r.moment});
      motion.frames.push_back(std::move(frame));
    }
    // A case that stopped early keeps the frames up to there only with keep_going.
    if (trajectory.ok || options.keep_going) run->motions.push_back(std::move(motion));
  }
  if (!run->first_failure.empty() && !options.keep_going) return;
  run->files = {{"trajectory.csv", FormatTrajectoryCsv(run->motions)},
                {"reactions.csv", FormatReactionsCsv(run->motions)},
                {"summary.csv", FormatMotionSummaryCsv(run->motion_summary)}};
  if (options.marker_count > 0)
    run->files.emplace_back("markers.csv", MarkersCsv(run->motions, options));
  if (!options.output_dir.empty())
    WriteFiles(experiment, options.output_dir, run->files, "output file name");
}

// A static scene: every case solved to equilibrium, each warm-started from the one before.
void SimulateStatics(const Experiment& experiment, const SimulateOptions& options,
                     SimulateRun* run) {
  const Scene& scene = experiment.scene;
  std::vector<CaseSolution> solutions;
  solutions.reserve(scene.cases.size());
  for (size_t k = 0; k < scene.cases.size(); ++k) {
    const LoadCase& load_case = scene.cases[k];
    Progress(options,
             "simulate: solving case " + std::to_string(k + 1) + " of " +
                 std::to_string(scene.cases.size()) + " (" + load_case.name + ")",
             static_cast<double>(k) / scene.cases.size());
    const std::string where = CasePlace(experiment.path, experiment.cases[k].line, load_case.name);
    CaseSolution solution;
    try {
      solution = SolveCase(scene, static_cast<int>(k),
                           solutions.empty() ? nullptr : &solutions.back(), experiment.statics);
    } catch (const std::invalid_argument& e) {
      // The case is not a valid rod: name the case's entry in the file.
      throw InputError(experiment.path, experiment.cases[k].line,
                       "cases[" + std::to_string(k) + "]", e.what());
    }
    const StaticsSummary& s = solution.summary;
    run->summary.push_back({load_case.name, s.converged, s.converged && s.stable, s.iterations,
                            s.gradient_norm, solution.seconds, s.reason});
    run->seconds += solution.seconds;
    if (!s.converged) {
      if (run->first_failure.empty()) run->first_failure = where + OneLine(s.reason);
      solutions.push_back(std::move(solution));
      continue;
    }
    if (!s.stable)
      run->warnings.push_back(where +
                              "the equilibrium found is unstable (a displacement the rod does not "
                              "resist); an experiment would not hold it");
    // A rod model is a small-strain model: an equilibrium that stretches or compresses an edge
    // by more than 10 % (held points pulled apart, a unit mistake in EA) is reported, not
    // silently returned.
    if (const double strain = LargestEdgeStrain(*solution.model, solution.state);
        strain > kSmallStrainLimit) {
      char percent[32];
      std::snprintf(percent, sizeof(percent), "%.3g", 100.0 * strain);
      run->warnings.push_back(where + "an edge is strained by " + percent +
                              " %, beyond the small strains of a rod model (held points too far "
                              "apart? stretch_stiffness in the wrong unit?)");
    }
    run->shapes.push_back({load_case.name, solution.shape_s, solution.shape});
    for (const HeldReaction& r : solution.reactions)
      run->forces.push_back({load_case.name, r.point, r.s, r.position, r.force, r.moment});
    if (solution.poke) {
      const PokeResult& poke = *solution.poke;
      if (!poke.ring.summary.IsUsable()) {
        if (run->first_failure.empty())
          run->first_failure = where + "cross-section: " + OneLine(poke.ring.summary.BriefReport());
        run->summary.back().converged = false;
        run->summary.back().reason = "cross-section: " + poke.ring.summary.BriefReport();
        solutions.push_back(std::move(solution));
        continue;
      }
      run->sections.push_back({load_case.name, poke.rest_world, poke.deformed_world});
      run->meshes.emplace_back(load_case.name,
                               FormatObj(PokedTube(*solution.model, solution.state,
                                                   *scene.section, poke)));
    }
    solutions.push_back(std::move(solution));
  }
  if (!run->first_failure.empty() && !options.keep_going) return;
  run->files = {{"shapes.csv", FormatShapesCsv(run->shapes)},
                {"forces.csv", FormatForcesCsv(run->forces)},
                {"summary.csv", FormatSummaryCsv(run->summary)}};
  if (!run->sections.empty())
    run->files.emplace_back("sections.csv", FormatSectionsCsv(run->sections));
  for (const auto& [name, obj] : run->meshes) run->files.emplace_back(name + ".obj", obj);
  // Only now, and all files at once: a run that fails while writing (a full disk, a directory
  // where a file goes) leaves the output directory as it was.
  if (!options.output_dir.empty())
    WriteFiles(experiment, options.output_dir, run->files, "case file name");
}

}  // namespace

SimulateRun SimulateScene(const Experiment& experiment, const SimulateOptions& options) {
  SimulateRun run;
  run.moving = static_cast<bool>(experiment.scene.dynamics);
  if (run.moving && !options.output_dir.empty()) {
    // The output rule before the work: no output over an input (a drive path, a tip load, ...).
    CheckOutputDirectory(options.output_dir,
                         {"trajectory.csv", "reactions.csv", "summary.csv", "markers.csv"},
                         ExperimentInputs(experiment));
  }
  // The work and the output a moving scene asks for, refused before the run starts when above
  // the documented limits (a scene within every other limit could run for hours).
  if (run.moving && !options.large)
    CheckMotionRunSize(EstimateMotionRun(experiment.scene, options.marker_count),
                       experiment.path, "--large");
  if (run.moving)
    SimulateMotion(experiment, options, &run);
  else if (options.marker_count > 0)
    throw std::invalid_argument("--markers is for a moving scene (a dynamics: block)");
  else
    SimulateStatics(experiment, options, &run);
  return run;
}

}  // namespace rodfit
