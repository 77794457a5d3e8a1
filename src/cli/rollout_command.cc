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
#include "cli_settings.h"
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

// The command line as given, before it is turned into the run's options. The rollout's and the
// fit's settings are their configurations' (RolloutOptions, MotionFitOptions: each setting's
// option, default, range and help declared once, by their Serialize; cli_settings.h).
struct RolloutArgs {
  std::string scene_path, output_dir, fit_text;
  std::vector<std::string> recording_paths;
  double frame_rate = 0.0;
  std::string unit = "m";
  std::string report_dir;
  bool quiet = false;
  std::string parameters_path;
  CliSettings settings{[](rodfit::SettingsArchive* a) {
    rodfit::RolloutOptions rollout;
    rodfit::MotionFitOptions fit;
    Serialize(a, &rollout);
    Serialize(a, &fit);
  }};
};

void DeclareOptions(CLI::App& app, RolloutArgs* a) {
  app.add_option("scene", a->scene_path, "scene YAML with a dynamics: block (docs/formats.md)")->required();
  app.add_option("recordings", a->recording_paths, "markers CSV(s): frame,marker,x,y,z or t,marker,x,y,z (or one row per frame: t,x0,y0,z0,x1,...)")->required();
  // What a motion sees: the rows of the parameter table in a moving thread's model.
  std::string fittable;
  for (const rodfit::MaterialParameterInfo& row : rodfit::MaterialParameters())
    if (rodfit::InMotionModel(row)) fittable += (fittable.empty() ? "" : ", ") + std::string(row.name);
  app.add_option("--fit", a->fit_text, "parameters to fit to the recordings, comma separated (" +
                                           fittable + "); their scene values are the start, > 0");
  a->settings.Add(&app, "smooth_frames");
  a->settings.Add(&app, "held_ends");
  a->settings.Add(&app, "max_evaluations");
  a->settings.Add(&app, "method");
  a->settings.Add(&app, "marker_sigma");
  app.add_option("-o,--output", a->output_dir, "output directory, created if missing")->required();
  app.add_option("--frame-rate", a->frame_rate, "[Hz] with a frame column (with a t column: must agree with its times)")->check(FiniteRange(1e-6, 1e9));
  app.add_option("--unit", a->unit, "the recordings' positions: m (default) or mm")
      ->check(CLI::IsMember({"m", "mm"}));
  a->settings.Add(&app, "held_markers");
  a->settings.Add(&app, "initial");
  app.add_option("--report", a->report_dir,
                 "also write a report into DIR: index.html (error table, fitted parameters, per "
                 "recording a 3-D view over time and each marker's path) and its figures");
  app.add_flag("-q,--quiet", a->quiet, "no progress line");
  a->settings.Add(&app, "rest_curvature_knots");
  a->settings.Add(&app, "rest_curvature_smoothness");
  app.add_option("--parameters", a->parameters_path,
                 "a motion_fit.json of rollout --fit on other recordings of the rod: its values "
                 "replace the scene's (with --fit: the start)");
  a->settings.CheckAllAdded();
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
rodfit::RolloutRunOptions RunOptions(RolloutArgs& a) {
  rodfit::RolloutRunOptions options;
  a.settings.Read([&](rodfit::SettingsArchive* s) { Serialize(s, &options.rollout); });
  if (!a.parameters_path.empty()) {
    options.parameters = rodfit::ReadMotionFitValues(a.parameters_path);
    options.parameters_path = a.parameters_path;
  }
  if (!a.fit_text.empty()) {
    SilenceCeresLogging();
    std::stringstream fit(a.fit_text);
    std::string item;
    while (std::getline(fit, item, ',')) options.fit.push_back(item);
    a.settings.Read([&](rodfit::SettingsArchive* s) { Serialize(s, &options.fit_options); });
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
