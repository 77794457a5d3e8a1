// FitExperiment (run.h): `rodfit fit` as a library call — the static fit or, for a moving
// experiment, the motion fit; the residual check, the warnings, the profile and its outputs.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "rodfit/io/output_dir.h"
#include "rodfit/io/profile.h"
#include "rodfit/model/rod.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/model/check.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/pipeline/sequence_input.h"

namespace rodfit {
namespace {

// Stages the report (when asked) and the profile, then commits both together: the report first,
// so that no profile claims a finished run without its report; when the profile cannot be
// moved into place the report is rolled back. A failure leaves both locations as they were.
// Returns the report's own warnings (e.g. written without its 3-D views).
std::vector<std::string> WriteOutputs(const Experiment& experiment, const FitInput& input,
                                      const FitResult& result, const nlohmann::json& profile_json,
                                      const FitRunOptions& run,
                                      const std::vector<std::string>& warnings) {
  std::vector<StagedDirectory*> outputs;
  std::unique_ptr<StagedDirectory> report;
  std::vector<std::string> report_warnings;
  if (!run.report_dir.empty()) {
    report = std::make_unique<StagedDirectory>(run.report_dir);
    report_warnings = run.write_report(report.get(), experiment, input, result, warnings);
    outputs.push_back(report.get());
  }
  const std::filesystem::path profile(run.profile_path);
  StagedDirectory profile_dir(profile.has_parent_path() ? profile.parent_path().string()
                                                        : std::string("."),
                              /*stage_inside=*/true);
  profile_dir.Write(profile.filename().string(), FormatProfile(profile_json), "profile file name");
  outputs.push_back(&profile_dir);
  CommitAll(outputs);
  return report_warnings;
}

// The residual variance against its chi-square band, as one warning (empty: none). Trusted
// sigmas keep the std as stated, so nothing else would show that the residuals are not what
// those sigmas predict; untrusted ones scale the std by the variance, which covers sigmas stated
// too small but not a model error.
std::string ResidualWarning(const FitResult& result, const FitOptions& options,
                            ResidualCheck* check_out) {
  const ResidualCheck check = CheckResiduals(result, options);
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

// The verdicts, the profile and the outputs of a fit that succeeded.
void Finish(const Experiment& experiment, const FitInput& input, const FitRunOptions& options,
            FitRun* run) {
  ResidualCheck check;
  run->residual_warning = ResidualWarning(run->result, run->options, &check);
  if (!run->residual_warning.empty()) run->warnings.push_back(run->residual_warning);
  for (const ObservationFit& o : run->result.observations)
    if (!o.warning.empty())
      run->entry_warnings.push_back("case " + o.case_name + ": " + o.label + ": " + o.warning);
  run->warnings.insert(run->warnings.end(), run->entry_warnings.begin(),
                       run->entry_warnings.end());
  run->misfit = check.gross;
  for (const Parameter& p : run->result.parameters)
    if (p.fit && !p.identifiable) run->all_determined = false;
  run->profile = ProfileJson(experiment, run->options, run->result, check);
  if (!options.profile_path.empty())
    run->report_warnings =
        WriteOutputs(experiment, input, run->result, run->profile, options, run->warnings);
  run->ok = true;
}

// A moving experiment (a dynamics: block): its fit: true parameters, damping included, fitted
// to its observation sequences (markers, points or pixels over time) by the motion fit. The
// report's page has no per-case figures (no static shapes).
FitRun FitMovingExperiment(const Experiment& experiment, const FitRunOptions& options) {
  FitRun run;
  run.moving = true;
  const SequenceInput input = BuildSequenceInput(experiment);
  const std::vector<std::string> names = FittedNames(experiment);
  if (names.empty()) {
    run.error = "no parameter has fit: true (nothing to fit)";
    return run;
  }
  if (options.progress)
    options.progress("fit: integrating the cases with their sensitivities", NAN);
  MotionFitOptions fit_options = SequenceFitOptionsOf(experiment, names);
  if (options.progress) {
    fit_options.progress = [&options](const FitIterationInfo& i) {
      char text[96];
      std::snprintf(text, sizeof(text), "fit: iteration %d  cost %.4e  relative change %.1e",
                    i.iteration, i.cost, i.relative_decrease);
      options.progress(text, NAN);
    };
  }
  MotionFitResult motion;
  try {
    motion = FitSequences(experiment.scene, input.sequences, names, experiment.statics,
                          fit_options);
  } catch (const std::invalid_argument& e) {
    run.error = e.what();
    return run;
  }
  if (!motion.converged) {
    run.error = "the fit failed: " + motion.message + " (no profile written)";
    return run;
  }
  Scene fitted = experiment.scene;
  for (size_t k = 0; k < names.size(); ++k) SetMotionParameter(names[k], motion.values[k], &fitted);
  const SequenceResiduals residuals = EvaluateSequences(fitted, input.sequences, experiment.statics);
  run.result = SequenceFitResult(experiment, input, motion, residuals);
  run.runs = motion.evaluations;
  run.options = FitOptionsOf(experiment);
  const FitInput report_input;  // a moving experiment has no static cases
  Finish(experiment, report_input, options, &run);
  return run;
}

}  // namespace

FitRun FitExperiment(const Experiment& experiment, const FitRunOptions& options) {
  RODFIT_CHECK_ARG(
      options.report_dir.empty() || (options.write_report && !options.profile_path.empty()),
      "FitExperiment: a report_dir needs write_report and profile_path");
  if (experiment.scene.dynamics) return FitMovingExperiment(experiment, options);
  FitRun run;
  const FitInput input = BuildFitInput(experiment);
  // A camera behind the rod or looking elsewhere is bad data: said before the fit, naming the
  // camera file and the case (the fit would only fail to evaluate).
  CheckCamerasSeeTheStart(experiment);
  // Held points the rod reaches only by stretching more than 1 %: a wire between two clamps
  // measured farther apart than its length, or a length given short. Warned about after a fit
  // that succeeds (a failed fit says why it failed): the fit would take the stiffness to explain
  // what the geometry gets wrong.
  for (const FitCase& c : input.cases) {
    try {
      const RodModel model(input.rod, input.material, input.gravity, c.load_case, input.springs);
      for (const std::string& span : model.StretchedSpans(0.01))
        run.stretched.push_back("case " + DisplayCaseName(c.load_case.name) + ": " + span);
    } catch (const std::invalid_argument&) {
      // The fit names what is wrong with the case.
    }
  }
  run.options = FitOptionsOf(experiment);
  run.options.num_threads = options.num_threads;
  // The global search has a budget of evaluations, so its line has an ETA; Levenberg–Marquardt
  // stops when it converges, so its line has none.
  if (options.progress) {
    run.options.progress = [&options](const FitIterationInfo& i) {
      char text[96];
      if (i.global) {
        std::snprintf(text, sizeof(text), "fit: global search %d/%d  best cost %.4e", i.iteration,
                      i.budget, i.cost);
        options.progress(text, i.budget > 0 ? double(i.iteration) / i.budget : NAN);
      } else {
        std::snprintf(text, sizeof(text), "fit: iteration %d  cost %.4e  relative change %.1e",
                      i.iteration, i.cost, i.relative_decrease);
        options.progress(text, NAN);
      }
    };
  }
  bool ran = true;
  try {
    run.result = Fit(input, run.options);
  } catch (const std::invalid_argument& e) {
    run.error = e.what();
    ran = false;
  }
  run.options.progress = nullptr;  // the callback refers to `options`, which the caller owns
  if (!ran) return run;
  if (!run.result.success) {
    run.error = "the fit failed: " + run.result.message + " (no profile written)";
    return run;
  }
  for (const std::string& span : run.stretched)
    run.warnings.push_back(span + " (check rod.length and the held positions)");
  Finish(experiment, input, options, &run);
  return run;
}

}  // namespace rodfit
