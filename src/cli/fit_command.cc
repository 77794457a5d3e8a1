// `rodfit fit EXPERIMENT.yaml -o PROFILE.json [--report DIR] [--quiet]`: reads the experiment and
// its observation files, runs the identification and writes the profile (docs/cli.md, "fit").
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include <CLI/CLI.hpp>
#include <glog/logging.h>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/progress.h"
#include "rodfit/pipeline/experiment.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/report/fit_report.h"

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
  // The cases' nuisances: fitted held frames, points and gravity (not material).
  for (const rodfit::NuisanceEstimate& n : result.nuisances)
    std::fprintf(stderr, "case %s, %s %s: (%.3g, %.3g, %.3g) +- (%.2g, %.2g, %.2g) %s\n",
                 n.case_name.c_str(), n.held.c_str(), n.quantity.c_str(), n.value[0],
                 n.value[1], n.value[2], n.std[0], n.std[1], n.std[2], n.unit.c_str());
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
  // On a terminal, one updating line while the fit runs (io/progress.h).
  rodfit::ProgressLine progress(quiet, STDERR_FILENO);
  rodfit::FitRunOptions options;
  options.num_threads = threads;
  options.profile_path = profile_path;
  options.report_dir = report_dir;
  options.write_report = [](rodfit::StagedDirectory* out, const rodfit::Experiment& e,
                            const rodfit::FitInput& input, const rodfit::FitResult& result,
                            const std::vector<std::string>& warnings) {
    return rodfit::WriteFitReport(out, e, input, result, warnings);
  };
  if (progress.enabled())
    options.progress = [&progress](const std::string& text, double fraction) {
      progress.Update(text, fraction);
    };
  const rodfit::FitRun run = rodfit::FitExperiment(experiment, options);
  progress.Finish();
  if (!run.ok) {
    std::cerr << "rodfit fit: " << experiment_path << ": " << run.error << "\n";
    return EXIT_FAILURE;
  }
  // The run's warnings: every one in the report's summary, with what to do; on stderr the
  // stretched spans in one line.
  const std::vector<std::string>& stretched = run.stretched;
  if (!stretched.empty())
    std::fprintf(stderr, "rodfit fit: warning: %s (check rod.length and the held positions)%s\n",
                 stretched.front().c_str(),
                 stretched.size() > 1
                     ? (" and " + std::to_string(stretched.size() - 1) + " more like it" +
                        (report_dir.empty() ? std::string() : ", all in the report's summary"))
                           .c_str()
                     : "");
  if (!run.residual_warning.empty())
    std::fprintf(stderr, "rodfit fit: warning: %s\n", run.residual_warning.c_str());
  for (const std::string& w : run.entry_warnings)
    std::fprintf(stderr, "rodfit fit: warning: %s\n", w.c_str());
  for (const std::string& w : run.report_warnings)
    std::fprintf(stderr, "rodfit fit: warning: %s\n", w.c_str());
  if (!quiet) {
    PrintEstimates(run.result);
    if (run.moving)
      std::fprintf(stderr, "%d iterations, %d runs, %.3f s, residual variance %.3g; wrote %s\n",
                   run.result.iterations, run.runs, run.result.seconds,
                   run.result.residual_variance, profile_path.c_str());
    else
      std::fprintf(stderr, "%d iterations, %.3f s, residual variance %.3g; wrote %s\n",
                   run.result.iterations, run.result.seconds, run.result.residual_variance,
                   profile_path.c_str());
  }
  // The exit status of a fit that wrote its profile (docs/cli.md, "Exit status").
  if (!run.all_determined) return kNotAllDetermined;
  if (run.misfit) return kResidualsNotExplained;
  return EXIT_SUCCESS;
}
