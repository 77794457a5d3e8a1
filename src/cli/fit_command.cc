// `rodfit fit EXPERIMENT.yaml -o PROFILE.json [--report DIR] [--quiet]`: reads the experiment and
// its observation files, runs the identification and writes the profile (docs/cli.md, "fit").
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>
#include <glog/logging.h>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/fit/fit.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/sequence_input.h"
#include "rodfit/model/rod.h"
#include "rodfit/report/fit_report.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/profile.h"
#include "rodfit/io/progress.h"
#include "rodfit/pipeline/experiment.h"

namespace {

// The exit status of a fit that wrote its profile but could not determine every fitted parameter
// from the data (README "Exit codes"): distinct from an error (1, nothing written), so a script
// cannot take a profile with null values for a complete one.
constexpr int kNotAllDetermined = 4;
// The exit status of a fit that wrote its profile but whose residuals are far beyond the stated
// noise (rodfit::ResidualCheck::gross): the model does not explain the data, so the values are
// not to be used as they stand (cameras swapped, wrong units, a missing load).
constexpr int kResidualsNotExplained = 5;

// Ceres runs one thread per requested thread; far more than the cases (or the cores) gains
// nothing, and 2^31 of them end in std::bad_alloc.
constexpr int kMaxThreads = 256;

// "--threads N": an integer in [1, kMaxThreads], checked on the text so that 0, 1e300 or 300
// digits get the same short message with the range.
std::string CheckThreads(const std::string& text) {
  const std::string range = "must be an integer in [1, " + std::to_string(kMaxThreads) + "]";
  if (text.empty() || text.size() > 4 || text.find_first_not_of("0123456789") != std::string::npos)
    return range + ", got '" + (text.size() > 20 ? text.substr(0, 17) + "..." : text) + "'";
  const int n = std::stoi(text);
  if (n < 1 || n > kMaxThreads) return range + ", got " + text;
  return "";
}

// Stages the report (when asked) and the profile, then commits both together: the report first,
// so that no profile claims a finished run without its report; when the profile cannot be
// moved into place the report is rolled back. A failure leaves both locations as they were.
// Returns the report's own warnings (e.g. written without its 3-D views).
std::vector<std::string> WriteOutputs(const rodfit::Experiment& experiment,
                                      const rodfit::FitInput& input,
                                      const rodfit::FitOptions& options,
                                      const rodfit::FitResult& result,
                                      const std::string& profile_path,
                                      const std::string& report_dir,
                                      const std::vector<std::string>& warnings) {
  std::vector<rodfit::StagedDirectory*> outputs;
  std::unique_ptr<rodfit::StagedDirectory> report;
  std::vector<std::string> report_warnings;
  if (!report_dir.empty()) {
    report = std::make_unique<rodfit::StagedDirectory>(report_dir);
    report_warnings = rodfit::WriteFitReport(report.get(), experiment, input, result, warnings);
    outputs.push_back(report.get());
  }
  const std::filesystem::path profile(profile_path);
  rodfit::StagedDirectory profile_dir(profile.has_parent_path() ? profile.parent_path().string()
                                                                : std::string("."),
                                       /*stage_inside=*/true);
  profile_dir.Write(profile.filename().string(),
                    rodfit::FormatProfile(rodfit::ProfileJson(experiment, options, result)),
                    "profile file name");
  outputs.push_back(&profile_dir);
  rodfit::CommitAll(outputs);
  return report_warnings;
}

// The fitted parameters as the summary lists them.
void PrintEstimates(const rodfit::FitResult& result) {
  for (const rodfit::Parameter& p : result.parameters) {
    if (!p.fit) continue;
    if (p.identifiable)
      std::fprintf(stderr, "%-18s %.6g +- %.2g %s\n", p.name.c_str(), p.value, *p.std,
                   p.unit());
    else
      std::fprintf(stderr, "%-18s NOT IDENTIFIABLE: %s\n", p.name.c_str(), p.reason.c_str());
  }
}

// The residual variance against its chi-square band, warned about on one line even with
// --quiet (a warning is not progress). Trusted sigmas keep the std as stated, so nothing else
// would show that the residuals are not what those sigmas predict; untrusted ones scale the
// std by the variance, which covers sigmas stated too small but not a model error. The warning's
// text (empty: none) goes into the report's summary too.
std::string ResidualWarning(const rodfit::FitResult& result, const rodfit::FitOptions& options,
                            rodfit::ResidualCheck* check_out) {
  const rodfit::ResidualCheck check = rodfit::CheckResiduals(result, options);
  *check_out = check;
  const double v = result.residual_variance;
  char text[640] = "";
  if (check.above && options.trusted_sigmas)
    std::snprintf(text, sizeof(text),
                  "residual variance %.3g x the stated sigmas (expected %.2g to %.2g for %d "
                  "degrees of freedom): the model does not explain the data (cameras swapped? "
                  "wrong units? sigmas too small?)",
                  v, check.band.low, check.band.high, result.residual_dof);
  else if (check.above)
    std::snprintf(text, sizeof(text),
                  "residual variance %.3g x the stated sigmas (expected %.2g to %.2g for %d "
                  "degrees of freedom): %s; the std are scaled by it, but a model error (clamp "
                  "pose, rod length, camera calibration, a missing load) is not noise and they do "
                  "not cover it",
                  v, check.band.low, check.band.high, result.residual_dof,
                  check.gross ? "the model does not explain the data"
                              : "the sigmas understate the noise, or the model misses something");
  else if (check.below)
    std::snprintf(text, sizeof(text),
                  "residual variance %.3g x the stated sigmas (expected %.2g to %.2g for %d "
                  "degrees of freedom): the data scatter less than the sigmas say, so the std are "
                  "too large (sigmas too large?)",
                  v, check.band.low, check.band.high, result.residual_dof);
  return text;
}

// The exit status of a fit that wrote its profile (docs/cli.md, "Exit status").
int FitStatus(const rodfit::FitResult& result, const rodfit::ResidualCheck& check) {
  for (const rodfit::Parameter& p : result.parameters)
    if (p.fit && !p.identifiable) return kNotAllDetermined;
  if (check.gross) return kResidualsNotExplained;
  return EXIT_SUCCESS;
}

// A moving experiment (a dynamics: block): its fit: true parameters, damping included, fitted
// to its observation sequences (markers, points or pixels over time) by the motion fit
// (docs/cli.md, "fit"); the same outputs as the static fit. The report's page has no per-case
// figures (no static shapes).
int RunSequenceFit(const rodfit::Experiment& experiment, const std::string& experiment_path,
                   const std::string& profile_path, const std::string& report_dir, bool quiet) {
  const rodfit::SequenceInput input = rodfit::BuildSequenceInput(experiment);
  const std::vector<std::string> names = rodfit::FittedNames(experiment);
  if (names.empty()) {
    std::cerr << "rodfit fit: " << experiment_path
              << ": no parameter has fit: true (nothing to fit)\n";
    return EXIT_FAILURE;
  }
  rodfit::ProgressLine progress(quiet, STDERR_FILENO);
  if (progress.enabled()) progress.Update("fit: integrating the cases with their sensitivities");
  rodfit::MotionFitOptions fit_options = rodfit::SequenceFitOptionsOf(experiment, names);
  if (progress.enabled()) {
    fit_options.progress = [&progress](const rodfit::FitIterationInfo& i) {
      char text[96];
      std::snprintf(text, sizeof(text), "fit: iteration %d  cost %.4e  relative change %.1e",
                    i.iteration, i.cost, i.relative_decrease);
      progress.Update(text);
    };
  }
  rodfit::MotionFitResult motion;
  try {
    motion = rodfit::FitSequences(experiment.scene, input.sequences, names, experiment.statics,
                                  fit_options);
  } catch (const std::invalid_argument& e) {
    progress.Finish();
    std::cerr << "rodfit fit: " << experiment_path << ": " << e.what() << "\n";
    return EXIT_FAILURE;
  }
  progress.Finish();
  if (!motion.converged) {
    std::cerr << "rodfit fit: " << experiment_path << ": the fit failed: " << motion.message
              << " (no profile written)\n";
    return EXIT_FAILURE;
  }
  rodfit::Scene fitted = experiment.scene;
  for (size_t k = 0; k < names.size(); ++k)
    rodfit::SetMotionParameter(names[k], motion.values[k], &fitted);
  const rodfit::SequenceResiduals residuals =
      rodfit::EvaluateSequences(fitted, input.sequences, experiment.statics);
  const rodfit::FitResult result = rodfit::SequenceFitResult(experiment, input, motion, residuals);
  rodfit::FitOptions options = rodfit::FitOptionsOf(experiment);
  const rodfit::FitInput report_input;  // a moving experiment has no static cases
  rodfit::ResidualCheck check;
  std::vector<std::string> warnings;
  if (std::string w = ResidualWarning(result, options, &check); !w.empty()) warnings.push_back(w);
  for (const std::string& w :
       WriteOutputs(experiment, report_input, options, result, profile_path, report_dir, warnings))
    warnings.push_back(w);
  for (const std::string& w : warnings) std::fprintf(stderr, "rodfit fit: warning: %s\n", w.c_str());
  if (!quiet) {
    PrintEstimates(result);
    std::fprintf(stderr, "%d iterations, %d runs, %.3f s, residual variance %.3g; wrote %s\n",
                 result.iterations, motion.evaluations, result.seconds, result.residual_variance,
                 profile_path.c_str());
  }
  return FitStatus(result, check);
}

}  // namespace

void SilenceCeresLogging() {
  // Ceres logs through glog (a rank-deficient covariance, a failed step); rodfit reports for
  // itself, in one line.
  FLAGS_minloglevel = google::GLOG_FATAL;
  FLAGS_stderrthreshold = google::GLOG_FATAL;
  if (!google::IsGoogleLoggingInitialized()) google::InitGoogleLogging("rodfit");
}

int RunFit(int argc, char** argv) {
  CLI::App app("Fit the experiment's `fit: true` parameters to its observations and write the "
               "profile JSON. Exit 0 when every fitted parameter is determined by the data, 4 "
               "when the profile was written but some are not (written with value null), 1 on "
               "an error (nothing written).",
               "rodfit fit");
  std::string experiment_path, profile_path, report_dir;
  bool quiet = false;
  int threads = 2;
  app.add_option("experiment", experiment_path, "experiment YAML")->required();
  app.add_option("-o,--output", profile_path, "profile JSON to write")->required();
  app.add_option("--report", report_dir, "also write a report (tables and plots) into DIR");
  app.add_option("--threads", threads, "cases evaluated in parallel, 1 to " +
                                           std::to_string(kMaxThreads))
      ->check(CLI::Validator(CheckThreads, "INT", "threads"));
  app.add_flag("-q,--quiet", quiet, "no progress line and no summary");
  // CLI11's errors are exit 1 with one line, as every command's (cli_common.h, docs/cli.md).
  if (const int status = Parse(app, argc, argv); status >= 0) return status;

  SilenceCeresLogging();

  const rodfit::Experiment experiment = rodfit::LoadExperiment(experiment_path);
  // Before the fit, so that no run ends by overwriting its own data (`-o experiment.yaml`).
  {
    std::error_code ec;
    if (std::filesystem::is_directory(profile_path, ec)) {
      throw rodfit::InputError(profile_path, 0, "",
                               "is a directory; -o takes the profile's file name");
    }
    const std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
    rodfit::CheckOutputFile(profile_path, inputs);
    if (!report_dir.empty()) {
      for (const char* name : {"summary.csv", "residuals.csv", "index.html"})
        rodfit::RefuseOverwritingInput((std::filesystem::path(report_dir) / name).string(),
                                       inputs);
    }
  }
  if (experiment.scene.dynamics)
    return RunSequenceFit(experiment, experiment_path, profile_path, report_dir, quiet);
  const rodfit::FitInput input = rodfit::BuildFitInput(experiment);
  // A camera behind the rod or looking elsewhere is bad data: said before the fit, naming the
  // camera file and the case (the fit would only fail to evaluate).
  rodfit::CheckCamerasSeeTheStart(experiment);
  // Held points the rod reaches only by stretching more than 1 %: a wire between two clamps
  // measured farther apart than its length, or a length given short. Said after a fit that
  // succeeds (even with --quiet; a failed fit's one line says why it failed): the fit would take
  // the stiffness to explain what the geometry gets wrong.
  std::vector<std::string> stretched;
  for (const rodfit::FitCase& c : input.cases) {
    try {
      const rodfit::RodModel model(input.rod, input.material, input.gravity, c.load_case,
                                   input.springs);
      for (const std::string& span : model.StretchedSpans(0.01))
        stretched.push_back("case " + rodfit::DisplayCaseName(c.load_case.name) + ": " + span);
    } catch (const std::invalid_argument&) {
      // The fit names what is wrong with the case.
    }
  }
  rodfit::FitOptions options = rodfit::FitOptionsOf(experiment);
  options.num_threads = threads;
  // The global search has a budget of evaluations, so its line has an ETA; Levenberg–Marquardt
  // stops when it converges, so its line has none.
  rodfit::ProgressLine progress(quiet, STDERR_FILENO);
  if (progress.enabled()) {
    options.progress = [&progress](const rodfit::FitIterationInfo& i) {
      char text[96];
      if (i.global) {
        std::snprintf(text, sizeof(text), "fit: global search %d/%d  best cost %.4e", i.iteration,
                      i.budget, i.cost);
        progress.Update(text, i.budget > 0 ? double(i.iteration) / i.budget : NAN);
      } else {
        std::snprintf(text, sizeof(text), "fit: iteration %d  cost %.4e  relative change %.1e",
                      i.iteration, i.cost, i.relative_decrease);
        progress.Update(text);
      }
    };
  }
  rodfit::FitResult result;
  try {
    result = rodfit::Fit(input, options);
  } catch (const std::invalid_argument& e) {
    std::cerr << "rodfit fit: " << experiment_path << ": " << e.what() << "\n";
    return EXIT_FAILURE;
  }
  progress.Finish();
  if (!result.success) {
    std::cerr << "rodfit fit: " << experiment_path << ": the fit failed: " << result.message
              << " (no profile written)\n";
    return EXIT_FAILURE;
  }
  // The run's warnings: every one in the report's summary, with what to do; on stderr the
  // stretched spans in one line.
  rodfit::ResidualCheck check;
  std::vector<std::string> warnings;
  for (const std::string& span : stretched)
    warnings.push_back(span + " (check rod.length and the held positions)");
  std::string residual_warning = ResidualWarning(result, options, &check);
  if (!residual_warning.empty()) warnings.push_back(residual_warning);
  const std::vector<std::string> report_warnings =
      WriteOutputs(experiment, input, options, result, profile_path, report_dir, warnings);
  if (!stretched.empty())
    std::fprintf(stderr, "rodfit fit: warning: %s (check rod.length and the held positions)%s\n",
                 stretched.front().c_str(),
                 stretched.size() > 1
                     ? (" and " + std::to_string(stretched.size() - 1) + " more like it" +
                        (report_dir.empty() ? std::string() : ", all in the report's summary"))
                           .c_str()
                     : "");
  if (!residual_warning.empty())
    std::fprintf(stderr, "rodfit fit: warning: %s\n", residual_warning.c_str());
  for (const std::string& w : report_warnings)
    std::fprintf(stderr, "rodfit fit: warning: %s\n", w.c_str());
  if (!quiet) {
    PrintEstimates(result);
    std::fprintf(stderr, "%d iterations, %.3f s, residual variance %.3g; wrote %s\n",
                 result.iterations, result.seconds, result.residual_variance,
                 profile_path.c_str());
  }
  return FitStatus(result, check);
}
