// `rodfit rollout SCENE.yaml RECORDING.csv -o DIR`: open-loop prediction of a recorded motion
// (solve/rollout.h) and its mean absolute coordinate error.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include <CLI/CLI.hpp>

#include "cli_common.h"
#include "commands.h"
#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/recording.h"
#include "rodfit/fit/fit.h"
#include "rodfit/fit/motion_fit.h"
#include "rodfit/io/progress.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/report/rollout_report.h"
#include "rodfit/solve/rollout.h"
#include "rodfit/version.h"
#include "rodfit/pipeline/experiment.h"

int RunRollout(int argc, char** argv) {
  CLI::App app(
      "Predict recorded motions open-loop: the rod of SCENE (its rod, parameters, gravity and "
      "dynamics) with a vertex at every marker of each RECORDING, started from its first two "
      "frames, the held markers driven from the recording; write DIR/rollout.csv "
      "(recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z) and print the "
      "mean absolute coordinate error. With --fit, first fit those parameters to the recordings "
      "(DIR/motion_fit.json).",
      "rodfit rollout");
  std::string scene_path, output_dir, held_text = "0,1,-2,-1", initial = "equilibrium", fit_text;
  std::vector<std::string> recording_paths;
  int max_evaluations = 150;
  double frame_rate = 0.0;
  app.add_option("scene", scene_path, "scene YAML with a dynamics: block (docs/formats.md)")->required();
  app.add_option("recordings", recording_paths, "markers CSV(s): frame,marker,x,y,z or t,marker,x,y,z (or one row per frame: t,x0,y0,z0,x1,...)")->required();
  // What a motion sees: the rod's stiffness, damping and mass rows of the parameter table.
  std::string fittable;
  using rodfit::ParameterKind;
  for (const rodfit::MaterialParameterInfo& row : rodfit::MaterialParameters())
    if (row.kind == ParameterKind::kRodStiffness || row.kind == ParameterKind::kDamping ||
        row.kind == ParameterKind::kMass)
      fittable += (fittable.empty() ? "" : ", ") + std::string(row.name);
  app.add_option("--fit", fit_text, "parameters to fit to the recordings, comma separated (" +
                                        fittable + "); their scene values are the start, > 0");
  int smooth_frames = 5;
  std::string held_ends = "pins";
  app.add_option("--smooth", smooth_frames,
                 "held markers' paths smoothed by a centred quadratic over +-N frames (0: as recorded)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--held-ends", held_ends,
                 "how the held end markers hold the rod: pins (default: a clamp at marker 0 towards "
                 "marker 1, markers 1 and n-2 pinned), grippers (clamps at markers 0 and n-1, "
                 "their tangents from the first frames, roll by the minimal-twist frame) or "
                 "free-roll (as grippers, the end free to turn about its tangent)")
      ->check(CLI::IsMember({"grippers", "free-roll", "pins"}));
  app.add_option("--max-evaluations", max_evaluations, "rollouts of every recording the fit may take")
      ->check(CLI::Range(1, 100000));
  std::string method = "lm";
  double marker_sigma = 0.0;
  app.add_option("--method", method,
                 "lm (default): least squares with the rollout's exact sensitivities, with "
                 "covariance; bobyqa: derivative-free on the mean absolute error")
      ->check(CLI::IsMember({"lm", "bobyqa"}));
  app.add_option("--marker-sigma", marker_sigma, "[m] the markers' noise, weighting the fit's residuals")
      ->check(FiniteRange(0.0, 1e9));
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_option("--frame-rate", frame_rate, "[Hz] with a frame column (with a t column: must agree with its times)")->check(FiniteRange(1e-6, 1e9));
  std::string unit = "m";
  app.add_option("--unit", unit, "the recordings' positions: m (default) or mm")
      ->check(CLI::IsMember({"m", "mm"}));
  app.add_option("--held", held_text, "driven markers, comma separated; negative from the last (default 0,1,-2,-1)");
  app.add_option("--initial", initial, "equilibrium (default) or markers: the start shape")
      ->check(CLI::IsMember({"equilibrium", "markers"}));
  std::string report_dir;
  bool quiet = false;
  app.add_option("--report", report_dir,
                 "also write a report into DIR: index.html (error table, fitted parameters, per "
                 "recording a 3-D view over time and each marker's path) and its figures");
  app.add_flag("-q,--quiet", quiet, "no progress line");
  std::string parameters_path;
  app.add_option("--parameters", parameters_path,
                 "a motion_fit.json of rollout --fit on other recordings of the rod: its values "
                 "replace the scene's (with --fit: the start)");
  // CLI11's errors are exit 1 with one line, as every command's (cli_common.h, docs/cli.md).
  if (const int status = Parse(app, argc, argv); status >= 0) return status;
  if (!report_dir.empty()) {
    // Two staged directories moved onto one folder would replace each other: said before any
    // work.
    std::error_code ec;
    if (std::filesystem::weakly_canonical(report_dir, ec) ==
        std::filesystem::weakly_canonical(output_dir, ec))
      throw std::invalid_argument("--report DIR must differ from -o DIR (" + output_dir + ")");
  }
  const rodfit::Experiment experiment = rodfit::LoadExperiment(scene_path);
  if (!experiment.scene.dynamics)
    throw rodfit::InputError(scene_path, 1, "dynamics", "rollout needs a dynamics: block");
  // Every file the run reads; no output may replace one (checked now, before any work).
  std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
  for (const std::string& path : recording_paths) inputs.emplace_back(path, "a recording");
  if (!parameters_path.empty()) inputs.emplace_back(parameters_path, "--parameters");
  rodfit::CheckOutputDirectory(output_dir, {"rollout.csv", "motion_fit.json"}, inputs);
  if (!report_dir.empty()) rodfit::CheckOutputDirectory(report_dir, {"index.html"}, inputs);
  std::vector<rodfit::MarkerRecording> recs;
  std::vector<rodfit::MotionRecordingData> data;
  for (const std::string& path : recording_paths) {
    recs.push_back(rodfit::ReadMarkerRecording(path, frame_rate, unit == "mm" ? 1e-3 : 1.0));
    rodfit::CheckRecordingScale(recs.back(), experiment.scene.rod.length,
                                unit == "mm" ? "--unit mm is set" : "give --unit mm");
    rodfit::CheckRecordingFitsRod(recs.back(), experiment.scene.rod.length);
    data.push_back({path, recs.back().frame_interval, recs.back().frames});
  }
  rodfit::RolloutOptions options;
  options.initial_equilibrium = initial == "equilibrium";
  options.smooth_frames = smooth_frames;
  options.held_ends = held_ends == "grippers"    ? rodfit::RolloutOptions::HeldEnds::kGrippers
                      : held_ends == "free-roll" ? rodfit::RolloutOptions::HeldEnds::kFreeRoll
                                                 : rodfit::RolloutOptions::HeldEnds::kPinnedPairs;
  options.held_markers.clear();
  {
    std::stringstream ss(held_text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      double v = 0.0;
      if (!rodfit::ParseDouble(item, &v) || v != static_cast<int>(v))
        throw std::invalid_argument("--held: not an integer: '" + item.substr(0, 40) + "'");
      options.held_markers.push_back(static_cast<int>(v));
    }
  }
  rodfit::Scene scene = experiment.scene;
  if (!parameters_path.empty()) {
    for (const auto& [name, value] : rodfit::ReadMotionFitValues(parameters_path)) {
      rodfit::SetMotionParameter(name, value, &scene);
      std::printf("%s = %.6g from %s\n", name.c_str(), value, parameters_path.c_str());
    }
  }
  // Before the fit, so its sensitivities see the twist damping as the constant it is.
  if (rodfit::DefaultTwistDamping(&scene.material))
    std::printf("twist_damping not given: %.4g N m^2 s, bending's retardation time (bend_damping / "
                "bend_stiffness) times twist_stiffness\n",
                scene.material.twist_damping);
  std::string fit_json;
  // On a terminal, one updating line while the fit and the rollouts run (io/progress.h).
  rodfit::ProgressLine progress(quiet, STDERR_FILENO);
  std::vector<std::string> warnings;  // every warning of the run, for the report too
  std::unique_ptr<rodfit::MotionFitResult> fitted;
  if (!fit_text.empty()) {
    SilenceCeresLogging();
    std::vector<std::string> names;
    std::stringstream ss(fit_text);
    std::string item;
    while (std::getline(ss, item, ',')) names.push_back(item);
    rodfit::MotionFitOptions fit_options;
    fit_options.method = method == "bobyqa" ? rodfit::MotionFitMethod::kBobyqa
                                            : rodfit::MotionFitMethod::kLevenbergMarquardt;
    fit_options.max_evaluations = max_evaluations;
    fit_options.marker_sigma = marker_sigma;
    if (progress.enabled()) {
      progress.Update("rollout --fit: rolling out the recordings with their sensitivities");
      fit_options.progress = [&progress](const rodfit::FitIterationInfo& i) {
        char text[112];
        std::snprintf(text, sizeof(text),
                      "rollout --fit: iteration %d  cost %.4e  relative change %.1e", i.iteration,
                      i.cost, i.relative_decrease);
        progress.Update(text);
      };
    }
    rodfit::MotionFitResult fit;
    try {
      fit = rodfit::FitMotion(scene, data, names, options, experiment.statics, fit_options);
    } catch (const std::invalid_argument& e) {
      progress.Finish();
      throw std::invalid_argument(std::string("--fit: ") + e.what());
    }
    progress.Finish();
    // A least-squares fit that did not converge is not a result: said so, nothing written. The
    // derivative-free search has no such test (its budget is its stop) and is written as before.
    if (!fit.converged && fit_options.method == rodfit::MotionFitMethod::kLevenbergMarquardt) {
      std::cerr << "rodfit rollout: --fit did not converge: " << fit.message
                << " (nothing written)\n";
      return EXIT_FAILURE;
    }
    auto num = [](double v) { return std::isfinite(v) ? rodfit::FormatDouble(v) : std::string("null"); };
    auto quoted = [](const std::string& text) {
      std::string q = "\"";
      for (char ch : text) {
        if (ch == '"' || ch == '\\') q += std::string("\\") + ch;
        else q += static_cast<unsigned char>(ch) < 0x20 ? ' ' : ch;  // JSON: no raw control chars
      }
      return q + "\"";
    };
    const std::string method_text =
        fit_options.method == rodfit::MotionFitMethod::kBobyqa
            ? "BOBYQA on the predicted markers' mean absolute error (derivative-free)"
            : "Levenberg-Marquardt on the predicted markers' coordinates, Jacobian from the "
              "forward sensitivities through the implicit steps";
    fit_json = "{\n  \"rodfit_version\": \"" + std::string(RODFIT_VERSION) + "\",\n  \"method\": " +
               quoted(method_text) + ",\n  \"converged\": " + (fit.converged ? "true" : "false") +
               ",\n  \"message\": " + quoted(fit.message) + ",\n  \"evaluations\": " +
               std::to_string(fit.evaluations) + ",\n  \"iterations\": " +
               std::to_string(fit.iterations) + ",\n  \"residuals\": " +
               std::to_string(fit.residuals) + ",\n  \"residual_variance\": " +
               num(fit.residual_variance) + ",\n  \"marker_sigma_m\": " + num(marker_sigma) +
               ",\n  \"error_start_m\": " + rodfit::FormatDouble(fit.error_start) +
               ",\n  \"error_fitted_m\": " + rodfit::FormatDouble(fit.error_fitted) +
               ",\n  \"parameters\": {";
    for (size_t k = 0; k < names.size(); ++k) {
      rodfit::SetMotionParameter(names[k], fit.values[k], &scene);
      fit_json += std::string(k ? "," : "") + "\n    \"" + names[k] + "\": {\"start\": " +
                  rodfit::FormatDouble(fit.start[k]) + ", \"value\": " +
                  rodfit::FormatDouble(fit.values[k]) + ", \"std\": " + num(fit.std[k]) +
                  ", \"identifiable\": " + (fit.identifiable[k] ? "true" : "false") +
                  ", \"at_bound\": " + (fit.at_bound[k] ? "true" : "false") +
                  (fit.identifiable[k] ? std::string() : ", \"reason\": " + quoted(fit.reason[k])) + "}";
    }
    fit_json += "\n  },\n  \"correlation\": [";
    for (int i = 0; i < fit.covariance_log.rows(); ++i) {
      fit_json += std::string(i ? ", " : "") + "[";
      for (int j = 0; j < fit.covariance_log.cols(); ++j)
        fit_json += std::string(j ? ", " : "") +
                    num(fit.covariance_log(i, j) /
                        std::sqrt(fit.covariance_log(i, i) * fit.covariance_log(j, j)));
      fit_json += "]";
    }
    fit_json += "]\n}\n";
    std::printf("fitted over %zu recording(s) in %d rollouts (%s, %.3g s): mean error %.4g m -> %.4g m\n",
                data.size(), fit.evaluations, fit.method.c_str(), fit.seconds, fit.error_start,
                fit.error_fitted);
    if (!fit.converged) {
      std::fprintf(stderr, "rodfit rollout: --fit: %s\n", fit.message.c_str());
      warnings.push_back("--fit: " + fit.message);
    }
    for (size_t k = 0; k < names.size(); ++k) {
      std::printf("  %s: %.6g -> %.6g", names[k].c_str(), fit.start[k], fit.values[k]);
      if (fit.identifiable[k])
        std::printf(" +- %.3g", fit.std[k]);
      else
        std::printf(" (not identifiable: %s)", fit.reason[k].c_str());
      std::printf("%s\n", fit.at_bound[k] ? " [at its bound]" : "");
    }
    // With the markers' noise stated, the residual variance says whether the rollout's model
    // explains the recording: far above its chi-square band, the values absorb model error
    // (e.g. pins standing in for gripper clamps) and their std understates it.
    if (marker_sigma > 0.0 && fit.residuals > static_cast<int>(names.size())) {
      const rodfit::VarianceBand band =
          rodfit::ResidualVarianceBand(fit.residuals - static_cast<int>(names.size()));
      if (fit.residual_variance > band.high) {
        char text[400];
        std::snprintf(text, sizeof(text),
                      "residual variance %.3g x the marker noise (expected %.2g to %.2g for %d "
                      "degrees of freedom): the model does not explain the recording to its "
                      "noise (held points not as recorded? --marker-sigma too small?); the "
                      "values carry model error",
                      fit.residual_variance, band.low, band.high,
                      fit.residuals - static_cast<int>(names.size()));
        std::fprintf(stderr, "rodfit rollout: warning: %s\n", text);
        warnings.push_back(text);
      }
    }
    fitted = std::make_unique<rodfit::MotionFitResult>(fit);
  }
  std::string csv = "recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z\n";
  double sum_all = 0.0, sum_predicted = 0.0;
  int samples = 0;
  rodfit::RolloutReportInput report;
  report.scene_path = scene_path;
  for (size_t r = 0; r < recs.size(); ++r) {
    const rodfit::MarkerRecording& rec = recs[r];
    rodfit::RolloutResult result;
    if (progress.enabled())
      progress.Update("rollout: recording " + std::to_string(r + 1) + " of " +
                          std::to_string(recs.size()),
                      static_cast<double>(r) / recs.size());
    try {
      result = rodfit::Rollout(scene, rec.frame_interval, rec.frames, options, experiment.statics);
    } catch (const std::invalid_argument& e) {
      progress.Finish();
      throw rodfit::InputError(rec.file, 0, "", e.what());
    }
    progress.Finish();
    if (!result.ok) {
      std::cerr << "rodfit rollout: " << rec.file << ": " << result.reason << "\n";
      return EXIT_FAILURE;
    }
    for (size_t k = 0; k < result.predicted.size(); ++k) {
      for (int m = 0; m < static_cast<int>(result.marker_s.size()); ++m) {
        const Eigen::Vector3d o = rec.frames[k].col(m), p = result.predicted[k].col(m);
        auto num = [](double v) { return std::isfinite(v) ? rodfit::FormatDouble(v) : std::string(); };
        csv += std::to_string(r) + "," + std::to_string(k) + "," +
               rodfit::FormatDouble(k * rec.frame_interval) + "," + std::to_string(m) + "," +
               rodfit::FormatDouble(result.marker_s[m]) + "," + (result.held[m] ? "1," : "0,") +
               num(o[0]) + "," + num(o[1]) + "," + num(o[2]) + "," + num(p[0]) + "," +
               num(p[1]) + "," + num(p[2]) + "\n";
      }
    }
    sum_all += result.mae_all;
    sum_predicted += result.mae_predicted;
    samples += result.samples;
    if (result.halved_steps > 0) {
      std::cout << rec.file << ": " << result.halved_steps << " of its steps were taken in halves "
                << "(Newton did not converge at dynamics.time_step; dynamics.max_halvings)\n";
      warnings.push_back(rec.file + ": " + std::to_string(result.halved_steps) +
                         " of its steps were taken in halves (Newton did not converge at "
                         "dynamics.time_step): a smaller dynamics.time_step avoids it");
    }
    if (!report_dir.empty()) report.recordings.push_back({rec.file, rec.frame_interval, rec.frames, result});
  }
  // The report is staged beside the outputs and committed with them (nothing half-written).
  std::unique_ptr<rodfit::StagedDirectory> report_out;
  std::vector<std::string> report_warnings;
  if (!report_dir.empty()) {
    report.fit = fitted.get();
    report.warnings = warnings;
    report_out = std::make_unique<rodfit::StagedDirectory>(report_dir);
    report_out->SetInputs(inputs);
    report_warnings = rodfit::WriteRolloutReport(report_out.get(), report);
  }
  rodfit::StagedDirectory out(output_dir);
  out.SetInputs(inputs);
  out.Write("rollout.csv", csv, "output file name");
  if (!fit_json.empty()) out.Write("motion_fit.json", fit_json, "output file name");
  if (report_out)
    rodfit::CommitAll({report_out.get(), &out});
  else
    out.Commit();
  for (const std::string& w : report_warnings)
    std::fprintf(stderr, "rodfit rollout: warning: %s\n", w.c_str());
  const double n = static_cast<double>(recs.size());
  char line[256];
  std::snprintf(line, sizeof(line),
                "mean absolute coordinate error: %.4g m over all markers, %.4g m over the "
                "predicted ones (%d samples, %zu recording(s))\n",
                sum_all / n, sum_predicted / n, samples, recs.size());
  std::cout << line;
  return EXIT_SUCCESS;
}
