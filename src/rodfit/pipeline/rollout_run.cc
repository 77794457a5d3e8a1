// Rollout (run.h): `rodfit rollout` as a library call — open-loop predictions of recorded
// motions (solve/rollout.h), after a motion fit of the asked parameters to them; rollout.csv and
// motion_fit.json in memory and, when asked, written.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/check.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/version.h"

namespace rodfit {
namespace {

void RequireDynamics(const Experiment& experiment) {
  if (!experiment.scene.dynamics)
    throw InputError(experiment.path, 1, "dynamics", "rollout needs a dynamics: block");
}

void Note(const RolloutRunOptions& options, const std::string& line) {
  if (options.note) options.note(line);
}

// motion_fit.json (docs/cli.md, "rollout"): the fit's summary, every parameter's start, value,
// std and identifiability, and the correlation of their logarithms.
std::string MotionFitText(const MotionFitResult& fit, const MotionFitOptions& fit_options,
                          const std::vector<std::string>& names) {
  auto num = [](double v) { return std::isfinite(v) ? FormatDouble(v) : std::string("null"); };
  auto quoted = [](const std::string& text) {
    std::string q = "\"";
    for (char ch : text) {
      if (ch == '"' || ch == '\\') q += std::string("\\") + ch;
      else q += static_cast<unsigned char>(ch) < 0x20 ? ' ' : ch;  // JSON: no raw control chars
    }
    return q + "\"";
  };
  const std::string method_text =
      fit_options.method == MotionFitMethod::kBobyqa
          ? "BOBYQA on the predicted markers' mean absolute error (derivative-free)"
          : "Levenberg-Marquardt on the predicted markers' coordinates, Jacobian from the "
            "forward sensitivities through the implicit steps";
  std::string text =
      "{\n  \"rodfit_version\": \"" + std::string(RODFIT_VERSION) + "\",\n  \"method\": " +
      quoted(method_text) + ",\n  \"converged\": " + (fit.converged ? "true" : "false") +
      ",\n  \"message\": " + quoted(fit.message) + ",\n  \"evaluations\": " +
      std::to_string(fit.evaluations) + ",\n  \"iterations\": " + std::to_string(fit.iterations) +
      ",\n  \"residuals\": " + std::to_string(fit.residuals) + ",\n  \"residual_variance\": " +
      num(fit.residual_variance) + ",\n  \"marker_sigma_m\": " + num(fit_options.marker_sigma) +
      ",\n  \"error_start_m\": " + FormatDouble(fit.error_start) +
      ",\n  \"error_fitted_m\": " + FormatDouble(fit.error_fitted) + ",\n  \"parameters\": {";
  for (size_t k = 0; k < names.size(); ++k) {
    text += std::string(k ? "," : "") + "\n    \"" + names[k] + "\": {\"start\": " +
            FormatDouble(fit.start[k]) + ", \"value\": " + FormatDouble(fit.values[k]) +
            ", \"std\": " + num(fit.std[k]) + ", \"identifiable\": " +
            (fit.identifiable[k] ? "true" : "false") + ", \"at_bound\": " +
            (fit.at_bound[k] ? "true" : "false") +
            (fit.identifiable[k] ? std::string() : ", \"reason\": " + quoted(fit.reason[k])) + "}";
  }
  text += "\n  },\n  \"correlation\": [";
  for (int i = 0; i < fit.covariance_log.rows(); ++i) {
    text += std::string(i ? ", " : "") + "[";
    for (int j = 0; j < fit.covariance_log.cols(); ++j)
      text += std::string(j ? ", " : "") +
              num(fit.covariance_log(i, j) /
                  std::sqrt(fit.covariance_log(i, i) * fit.covariance_log(j, j)));
    text += "]";
  }
  return text + "]\n}\n";
}

// The motion fit of options.fit to the recordings, its values set in `scene`. False: a
// least-squares fit that did not converge (run->error says so).
bool FitToRecordings(const Experiment& experiment, const RolloutRunOptions& options,
                     Scene* scene, RolloutRun* run) {
  const std::vector<std::string>& names = options.fit;
  std::vector<MotionRecordingData> data;
  for (const MarkerRecording& rec : run->recordings)
    data.push_back({rec.file, rec.frame_interval, rec.frames});
  MotionFitOptions fit_options = options.fit_options;
  if (options.progress) {
    options.progress("rollout --fit: rolling out the recordings with their sensitivities", NAN);
    fit_options.progress = [&options](const FitIterationInfo& i) {
      char text[112];
      std::snprintf(text, sizeof(text),
                    "rollout --fit: iteration %d  cost %.4e  relative change %.1e", i.iteration,
                    i.cost, i.relative_decrease);
      options.progress(text, NAN);
    };
  }
  MotionFitResult fit;
  try {
    fit = FitMotion(*scene, data, names, options.rollout, experiment.statics, fit_options);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--fit: ") + e.what());
  }
  // A least-squares fit that did not converge is not a result: said so, nothing written. The
  // derivative-free search has no such test (its budget is its stop) and is written as before.
  if (!fit.converged && fit_options.method == MotionFitMethod::kLevenbergMarquardt) {
    run->error = "--fit did not converge: " + fit.message + " (nothing written)";
    return false;
  }
  for (size_t k = 0; k < names.size(); ++k) SetMotionParameter(names[k], fit.values[k], scene);
  run->fit_text = MotionFitText(fit, fit_options, names);
  run->fit_json = nlohmann::json::parse(run->fit_text);
  char line[320];
  std::snprintf(line, sizeof(line),
                "fitted over %zu recording(s) in %d rollouts (%s, %.3g s): mean error %.4g m -> "
                "%.4g m",
                data.size(), fit.evaluations, fit.method.c_str(), fit.seconds, fit.error_start,
                fit.error_fitted);
  Note(options, line);
  if (!fit.converged) run->warnings.push_back("--fit: " + fit.message);
  for (size_t k = 0; k < names.size(); ++k) {
    std::snprintf(line, sizeof(line), "  %s: %.6g -> %.6g", names[k].c_str(), fit.start[k],
                  fit.values[k]);
    std::string text = line;
    if (fit.identifiable[k]) {
      std::snprintf(line, sizeof(line), " +- %.3g", fit.std[k]);
      text += line;
    } else {
      text += " (not identifiable: " + fit.reason[k] + ")";
    }
    Note(options, text + (fit.at_bound[k] ? " [at its bound]" : ""));
  }
  // With the markers' noise stated, the residual variance says whether the rollout's model
  // explains the recording: far above its chi-square band, the values absorb model error
  // (e.g. pins standing in for gripper clamps) and their std understates it.
  const int dof = fit.residuals - static_cast<int>(names.size());
  if (fit_options.marker_sigma > 0.0 && dof > 0) {
    const VarianceBand band = ResidualVarianceBand(dof);
    if (fit.residual_variance > band.high) {
      char text[400];
      std::snprintf(text, sizeof(text),
                    "residual variance %.3g x the marker noise (expected %.2g to %.2g for %d "
                    "degrees of freedom): the model does not explain the recording to its "
                    "noise (held points not as recorded? --marker-sigma too small?); the "
                    "values carry model error",
                    fit.residual_variance, band.low, band.high, dof);
      run->residual_warning = text;
      run->warnings.push_back(text);
      run->misfit = true;
    }
  }
  run->fit = std::make_shared<MotionFitResult>(fit);
  return true;
}

// Every recording predicted; rollout.csv and the errors. False: a rollout failed (run->error).
bool RollOut(const Experiment& experiment, const RolloutRunOptions& options, const Scene& scene,
             RolloutRun* run) {
  std::string& csv = run->csv;
  csv = "recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z\n";
  double sum_all = 0.0, sum_predicted = 0.0;
  const size_t count = run->recordings.size();
  for (size_t r = 0; r < count; ++r) {
    const MarkerRecording& rec = run->recordings[r];
    RolloutResult result;
    if (options.progress)
      options.progress("rollout: recording " + std::to_string(r + 1) + " of " +
                           std::to_string(count),
                       static_cast<double>(r) / count);
    try {
      result = Rollout(scene, rec.frame_interval, rec.frames, options.rollout, experiment.statics);
    } catch (const std::invalid_argument& e) {
      throw InputError(rec.file, 0, "", e.what());
    }
    if (!result.ok) {
      run->error = rec.file + ": " + result.reason;
      return false;
    }
    auto num = [](double v) { return std::isfinite(v) ? FormatDouble(v) : std::string(); };
    for (size_t k = 0; k < result.predicted.size(); ++k) {
      for (int m = 0; m < static_cast<int>(result.marker_s.size()); ++m) {
        const Eigen::Vector3d o = rec.frames[k].col(m), p = result.predicted[k].col(m);
        csv += std::to_string(r) + "," + std::to_string(k) + "," +
               FormatDouble(k * rec.frame_interval) + "," + std::to_string(m) + "," +
               FormatDouble(result.marker_s[m]) + "," + (result.held[m] ? "1," : "0,") +
               num(o[0]) + "," + num(o[1]) + "," + num(o[2]) + "," + num(p[0]) + "," +
               num(p[1]) + "," + num(p[2]) + "\n";
      }
    }
    sum_all += result.mae_all;
    sum_predicted += result.mae_predicted;
    run->samples += result.samples;
    if (result.halved_steps > 0) {
      Note(options, rec.file + ": " + std::to_string(result.halved_steps) +
                        " of its steps were taken in halves (Newton did not converge at "
                        "dynamics.time_step; dynamics.max_halvings)");
      run->warnings.push_back(rec.file + ": " + std::to_string(result.halved_steps) +
                              " of its steps were taken in halves (Newton did not converge at "
                              "dynamics.time_step): a smaller dynamics.time_step avoids it");
    }
    run->results.push_back(std::move(result));
  }
  run->error_all = sum_all / static_cast<double>(count);
  run->error_predicted = sum_predicted / static_cast<double>(count);
  return true;
}

// Every file a rollout reads: the scene's, the recordings and the --parameters file. No output
// may replace one (the output rule, io/output_dir.h).
std::vector<InputFile> RolloutInputs(const Experiment& experiment,
                                     const std::vector<MarkerRecording>& recordings,
                                     const RolloutRunOptions& options) {
  std::vector<InputFile> inputs = ExperimentInputs(experiment);
  for (const MarkerRecording& rec : recordings) inputs.emplace_back(rec.file, "a recording");
  if (!options.parameters_path.empty())
    inputs.emplace_back(options.parameters_path, "--parameters");
  return inputs;
}

// rollout.csv (and motion_fit.json) in the output directory and the report beside it, committed
// together (nothing half-written).
void WriteOutputs(const Experiment& experiment, const RolloutRunOptions& options,
                  RolloutRun* run) {
  const std::vector<InputFile> inputs = RolloutInputs(experiment, run->recordings, options);
  std::unique_ptr<StagedDirectory> report_out;
  if (!options.report_dir.empty()) {
    report_out = std::make_unique<StagedDirectory>(options.report_dir);
    report_out->SetInputs(inputs);
    run->report_warnings = options.write_report(report_out.get(), *run);
  }
  StagedDirectory out(options.output_dir);
  out.SetInputs(inputs);
  out.Write("rollout.csv", run->csv, "output file name");
  if (!run->fit_text.empty()) out.Write("motion_fit.json", run->fit_text, "output file name");
  if (report_out)
    CommitAll({report_out.get(), &out});
  else
    out.Commit();
}

}  // namespace

std::vector<MarkerRecording> ReadRecordings(const Experiment& experiment,
                                            const std::vector<std::string>& paths,
                                            double frame_rate, bool millimetres) {
  RequireDynamics(experiment);
  std::vector<MarkerRecording> recordings;
  for (const std::string& path : paths) {
    recordings.push_back(ReadMarkerRecording(path, frame_rate, millimetres ? 1e-3 : 1.0));
    CheckRecordingScale(recordings.back(), experiment.scene.rod.length,
                        millimetres ? "--unit mm is set" : "give --unit mm");
    // A recording of another rod (or scaled) is refused before any rollout, naming the file.
    CheckRecordingFitsRod(recordings.back(), experiment.scene.rod.length);
  }
  return recordings;
}

RolloutRun Rollout(const Experiment& experiment, std::vector<MarkerRecording> recordings,
                   const RolloutRunOptions& options) {
  RequireDynamics(experiment);
  RODFIT_CHECK_ARG(
      options.report_dir.empty() || (options.write_report && !options.output_dir.empty()),
      "Rollout: a report_dir needs write_report and output_dir");
  RODFIT_CHECK_ARG(!recordings.empty(), "Rollout: no recording");
  RolloutRun run;
  run.scene_path = experiment.path;
  run.recordings = std::move(recordings);
  // The output rule before any work: no output over an input, a FIFO, a directory, or to ''.
  if (!options.output_dir.empty()) {
    const std::vector<InputFile> inputs = RolloutInputs(experiment, run.recordings, options);
    CheckOutputDirectory(options.output_dir, {"rollout.csv", "motion_fit.json"}, inputs);
    if (!options.report_dir.empty()) CheckOutputDirectory(options.report_dir, {"index.html"}, inputs);
  }
  Scene scene = experiment.scene;
  for (const auto& [name, value] : options.parameters) {
    SetMotionParameter(name, value, &scene);
    char line[256];
    std::snprintf(line, sizeof(line), "%s = %.6g from ", name.c_str(), value);
    Note(options, line + options.parameters_path);
  }
  // Before the fit, so its sensitivities see the twist damping as the constant it is.
  if (DefaultTwistDamping(&scene.material)) {
    char line[256];
    std::snprintf(line, sizeof(line),
                  "twist_damping not given: %.4g N m^2 s, bending's retardation time "
                  "(bend_damping / bend_stiffness) times twist_stiffness",
                  scene.material.twist_damping);
    Note(options, line);
  }
  if (!options.fit.empty() && !FitToRecordings(experiment, options, &scene, &run)) return run;
  if (!RollOut(experiment, options, scene, &run)) return run;
  if (!options.output_dir.empty()) WriteOutputs(experiment, options, &run);
  run.ok = true;
  return run;
}

}  // namespace rodfit
