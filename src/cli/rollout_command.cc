// `rodfit rollout SCENE.yaml RECORDING.csv -o DIR`: open-loop prediction of a recorded motion
// (solve/rollout.h) and its mean absolute coordinate error.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/progress.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/report/rollout_report.h"

namespace {

// The command line as given, before it is turned into the run's options.
struct RolloutArgs {
  std::string scene_path, output_dir, held_text = "0,1,-2,-1", initial = "equilibrium", fit_text;
  std::vector<std::string> recording_paths;
  // The fit's settings start at the library's defaults (MotionFitOptions, the one place each is
  // declared); the help states them from there.
  int max_evaluations = rodfit::MotionFitOptions().max_evaluations;
  double frame_rate = 0.0;
  int smooth_frames = 5;
  std::string held_ends = "pins";
  std::string method = "lm";
  double marker_sigma = rodfit::MotionFitOptions().marker_sigma;
  std::string unit = "m";
  std::string report_dir;
  bool quiet = false;
  int rest_knots = rodfit::MotionFitOptions().rest_curvature_knots;
  double fit_smoothness = rodfit::MotionFitOptions().rest_curvature_smoothness;
  double gripper_prior_deg = rodfit::MotionFitOptions().gripper_prior_deg;
  std::string parameters_path;
};

// A default as the help states it: the shortest text that reads back as the number.
std::string Shortest(double v) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", v);
  return text;
}

void DeclareOptions(CLI::App& app, RolloutArgs* a) {
  app.add_option("scene", a->scene_path, "scene YAML with a dynamics: block (docs/formats.md)")->required();
  app.add_option("recordings", a->recording_paths, "markers CSV(s): frame,marker,x,y,z or t,marker,x,y,z (or one row per frame: t,x0,y0,z0,x1,...)")->required();
  // What a motion sees: the rows of the parameter table in a moving thread's model.
  std::string fittable;
  for (const rodfit::MaterialParameterInfo& row : rodfit::MaterialParameters())
    if (rodfit::InMotionModel(row)) fittable += (fittable.empty() ? "" : ", ") + std::string(row.name);
  app.add_option("--fit", a->fit_text, "parameters to fit to the recordings, comma separated (" +
                                           fittable + "); their scene values are the start, > 0");
  app.add_option("--smooth", a->smooth_frames,
                 "held markers' paths smoothed by a centred quadratic over +-N frames (0: as recorded)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--held-ends", a->held_ends,
                 "how the held end markers hold the rod: pins (default: a clamp at marker 0 towards "
                 "marker 1, markers 1 and n-2 pinned), grippers (clamps at markers 0 and n-1, "
                 "their tangents from the first frames, roll by the minimal-twist frame) or "
                 "free-roll (as grippers, the end free to turn about its tangent)")
      ->check(CLI::IsMember({"grippers", "free-roll", "pins"}));
  app.add_option("--max-evaluations", a->max_evaluations,
                 "rollouts of every recording the fit may take (default " +
                     std::to_string(a->max_evaluations) + ")")
      ->check(CLI::Range(1, 100000));
  app.add_option("--method", a->method,
                 "lm (default): least squares with the rollout's exact sensitivities, with "
                 "covariance; bobyqa: derivative-free on the mean absolute error")
      ->check(CLI::IsMember({"lm", "bobyqa"}));
  app.add_option("--marker-sigma", a->marker_sigma, "[m] the markers' noise, weighting the fit's residuals")
      ->check(FiniteRange(0.0, 1e9));
  app.add_option("-o,--output", a->output_dir, "output directory, created if missing")->required();
  app.add_option("--frame-rate", a->frame_rate, "[Hz] with a frame column (with a t column: must agree with its times)")->check(FiniteRange(1e-6, 1e9));
  app.add_option("--unit", a->unit, "the recordings' positions: m (default) or mm")
      ->check(CLI::IsMember({"m", "mm"}));
  app.add_option("--held", a->held_text, "driven markers, comma separated; negative from the last (default 0,1,-2,-1)");
  app.add_option("--initial", a->initial, "equilibrium (default) or markers: the start shape")
      ->check(CLI::IsMember({"equilibrium", "markers"}));
  app.add_option("--report", a->report_dir,
                 "also write a report into DIR: index.html (error table, fitted parameters, per "
                 "recording a 3-D view over time and each marker's path) and its figures");
  app.add_flag("-q,--quiet", a->quiet, "no progress line");
  app.add_option("--rest-knots", a->rest_knots,
                 "with --fit rest_curvature: knots evenly along the rod (default " +
                     std::to_string(a->rest_knots) + ")")
      ->check(CLI::Range(3, 200));
  app.add_option("--rest-smoothness", a->fit_smoothness,
                 "[1/m] with --fit rest_curvature: the std of the curvature's second difference "
                 "over neighbouring knots (default " + Shortest(a->fit_smoothness) + ")")
      ->check(CLI::Range(1e-9, 1e9));
  app.add_option("--gripper-prior-deg", a->gripper_prior_deg,
                 "[deg] with --fit and --held-ends grippers or free-roll: each recording's "
                 "grippers carry a fitted tilt (about d1 and d2) with a Gaussian prior of this "
                 "std, reported per recording, never a parameter of the rod (0, the default: none)")
      ->check(CLI::Range(0.0, 90.0));
  app.add_option("--parameters", a->parameters_path,
                 "a motion_fit.json of rollout --fit on other recordings of the rod: its values "
                 "replace the scene's (with --fit: the start)");
}

// The output folders, checked before any work: -o '' would mean "write nothing" to the library
// (and the working directory to a user), refused with the output rule's message.
void CheckOutputs(const RolloutArgs& a) {
  rodfit::CheckOutputDirectory(a.output_dir, {}, {});
  if (!a.report_dir.empty()) {
    // Two staged directories moved onto one folder would replace each other: said before any
    // work.
    std::error_code ec;
    if (std::filesystem::weakly_canonical(a.report_dir, ec) ==
        std::filesystem::weakly_canonical(a.output_dir, ec))
      throw std::invalid_argument("--report DIR must differ from -o DIR (" + a.output_dir + ")");
  }
}

// The run's options from the command line (its --parameters file read here).
rodfit::RolloutRunOptions RunOptions(const RolloutArgs& a) {
  rodfit::RolloutRunOptions options;
  rodfit::RolloutOptions& rollout = options.rollout;
  rollout.initial_equilibrium = a.initial == "equilibrium";
  rollout.smooth_frames = a.smooth_frames;
  rollout.held_ends = a.held_ends == "grippers"    ? rodfit::RolloutOptions::HeldEnds::kGrippers
                      : a.held_ends == "free-roll" ? rodfit::RolloutOptions::HeldEnds::kFreeRoll
                                                   : rodfit::RolloutOptions::HeldEnds::kPinnedPairs;
  rollout.held_markers.clear();
  std::stringstream held(a.held_text);
  std::string item;
  while (std::getline(held, item, ',')) {
    double v = 0.0;
    if (!rodfit::ParseDouble(item, &v) || v != static_cast<int>(v))
      throw std::invalid_argument("--held: not an integer: '" + item.substr(0, 40) + "'");
    rollout.held_markers.push_back(static_cast<int>(v));
  }
  if (!a.parameters_path.empty()) {
    options.parameters = rodfit::ReadMotionFitValues(a.parameters_path);
    options.parameters_path = a.parameters_path;
  }
  // The tilts are fitted only with --fit: said, not ignored.
  if (a.gripper_prior_deg > 0.0 && a.fit_text.empty())
    throw std::invalid_argument("--gripper-prior-deg: the grippers' tilts are fitted with --fit");
  if (!a.fit_text.empty()) {
    SilenceCeresLogging();
    std::stringstream fit(a.fit_text);
    while (std::getline(fit, item, ',')) options.fit.push_back(item);
    options.fit_options.method = a.method == "bobyqa" ? rodfit::MotionFitMethod::kBobyqa
                                                      : rodfit::MotionFitMethod::kLevenbergMarquardt;
    options.fit_options.max_evaluations = a.max_evaluations;
    options.fit_options.marker_sigma = a.marker_sigma;
    options.fit_options.rest_curvature_knots = a.rest_knots;
    options.fit_options.rest_curvature_smoothness = a.fit_smoothness;
    options.fit_options.gripper_prior_deg = a.gripper_prior_deg;
  }
  options.output_dir = a.output_dir;
  options.report_dir = a.report_dir;
  options.write_report = rodfit::WriteRolloutRunReport;
  return options;
}

// Prints what the run says and maps it to the exit status (docs/cli.md, "rollout"): 1 nothing
// written; everything that ran written, 3 a recording's rollout failed, 4 --fit did not converge
// or a value is not determined, 5 --fit's residuals beyond the markers' noise; the highest
// applies.
int ReportRun(const rodfit::RolloutRun& run) {
  if (run.fit && !run.fit->converged)
    std::fprintf(stderr, "rodfit rollout: --fit: %s\n", run.fit->message.c_str());
  if (!run.residual_warning.empty())
    std::fprintf(stderr, "rodfit rollout: warning: %s\n", run.residual_warning.c_str());
  if (!run.ok) {
    std::cerr << "rodfit rollout: " << run.error << "\n";
    return EXIT_FAILURE;
  }
  for (const std::string& f : run.failures) std::cerr << "rodfit rollout: " << f << "\n";
  for (const std::string& w : run.report_warnings)
    std::fprintf(stderr, "rodfit rollout: warning: %s\n", w.c_str());
  char line[256];
  std::snprintf(line, sizeof(line),
                "mean absolute coordinate error: %.4g m over all markers, %.4g m over the "
                "predicted ones (%d samples, %zu recording(s))\n",
                run.error_all, run.error_predicted, run.samples,
                run.recordings.size() - run.failures.size());
  std::cout << line;
  int status = EXIT_SUCCESS;
  if (!run.failures.empty()) {
    std::string names;
    for (const std::string& f : run.failures) names += (names.empty() ? "" : "; ") + f;
    std::fprintf(stderr, "rodfit rollout: %zu of %zu recording(s) failed (the others written): %s\n",
                 run.failures.size(), run.recordings.size(), names.c_str());
    status = 3;
  }
  if (run.fit_not_converged || run.fit_undetermined) status = 4;
  if (run.misfit) status = 5;
  return status;
}

}  // namespace

int RunRollout(int argc, char** argv) {
  CLI::App app(
      "Predict recorded motions open-loop: the rod of SCENE (its rod, parameters, gravity and "
      "dynamics) with a vertex at every marker of each RECORDING, started from its first two "
      "frames, the held markers driven from the recording; write DIR/rollout.csv "
      "(recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z) and print the "
      "mean absolute coordinate error. With --fit, first fit those parameters to the recordings "
      "(DIR/motion_fit.json).",
      "rodfit rollout");
  RolloutArgs args;
  DeclareOptions(app, &args);
  // CLI11's errors are exit 1 with one line, as every command's (cli_common.h, docs/cli.md).
  if (const int status = Parse(app, argc, argv); status >= 0) return status;
  CheckOutputs(args);
  const rodfit::Experiment experiment = rodfit::LoadExperiment(args.scene_path);
  std::vector<rodfit::MarkerRecording> recordings =
      rodfit::ReadRecordings(experiment, args.recording_paths, args.frame_rate, args.unit == "mm");
  rodfit::RolloutRunOptions options = RunOptions(args);
  // On a terminal, one updating line while the fit and the rollouts run (io/progress.h); it is
  // erased before a line is printed.
  rodfit::ProgressLine progress(args.quiet, STDERR_FILENO);
  if (progress.enabled() || progress.plain())
    options.progress = [&progress](const std::string& text, double fraction) {
      progress.Update(text, fraction);
    };
  options.note = [&progress](const std::string& line) {
    progress.Finish();
    std::cout << line << "\n" << std::flush;
  };
  const rodfit::RolloutRun run = rodfit::Rollout(experiment, std::move(recordings), options);
  progress.Finish();
  return ReportRun(run);
}
