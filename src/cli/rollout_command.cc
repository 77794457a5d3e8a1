// `rodfit rollout SCENE.yaml RECORDING.csv -o DIR`: open-loop prediction of a recorded motion
// (solve/rollout.h) and its mean absolute coordinate error.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <cstdio>
#include <memory>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include <CLI/CLI.hpp>

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
#include "rodfit/model/rod.h"
#include "rodfit/report/rollout_report.h"
#include "rodfit/solve/rollout.h"
#include "rodfit/version.h"
#include "rodfit/pipeline/experiment.h"

namespace {
// The exit statuses of `rollout` beyond 0 and 1 (docs/cli.md, "rollout"): everything that ran is
// written in each case.
constexpr int kRecordingFailed = 3;     // a recording's rollout failed (the others written)
constexpr int kFitNotConverged = 4;     // --fit did not converge or a value is not determined
constexpr int kResidualsNotExplained = 5;  // --fit's residuals far beyond the markers' noise
// With the noise estimated from the recordings (not stated), the residual variance above which
// the model does not explain them: its error as large as the noise itself.
constexpr double kEstimatedNoiseVarianceLimit = 2.0;
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
      ->check(CLI::Range(0.0, 1e9));
  app.add_option("-o,--output", output_dir, "output directory, created if missing")->required();
  app.add_option("--frame-rate", frame_rate, "[Hz] with a frame column (with a t column: must agree with its times)")->check(CLI::Range(1e-6, 1e9));
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
  int rest_knots = rodfit::MotionFitOptions().rest_curvature_knots;
  double fit_smoothness = rodfit::MotionFitOptions().rest_curvature_smoothness;
  app.add_option("--rest-knots", rest_knots,
                 "with --fit rest_curvature: knots evenly along the rod (default 5)")
      ->check(CLI::Range(3, 200));
  app.add_option("--rest-smoothness", fit_smoothness,
                 "[1/m] with --fit rest_curvature: the std of the curvature's second difference "
                 "over neighbouring knots (default 2)")
      ->check(CLI::Range(1e-9, 1e9));
  std::string parameters_path;
  app.add_option("--parameters", parameters_path,
                 "a motion_fit.json of rollout --fit on other recordings of the rod: its values "
                 "replace the scene's (with --fit: the start)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
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
  std::vector<rodfit::MarkerRecording> recs;
  std::vector<rodfit::MotionRecordingData> data;
  for (const std::string& path : recording_paths) {
    recs.push_back(rodfit::ReadMarkerRecording(path, frame_rate, unit == "mm" ? 1e-3 : 1.0));
    rodfit::CheckRecordingScale(recs.back(), experiment.scene.rod.length,
                                unit == "mm" ? "--unit mm is set" : "give --unit mm");
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
    if (rodfit::ReadMotionFitRestShape(parameters_path, scene.rod.length,
                                       &scene.rod.rest_curvature_s,
                                       &scene.rod.rest_curvature_profile))
      std::printf("rest shape (%zu knots) from %s\n", scene.rod.rest_curvature_s.size(),
                  parameters_path.c_str());
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
  int status = EXIT_SUCCESS;  // the worst outcome so far (the statuses above)
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
    fit_options.rest_curvature_knots = rest_knots;
    fit_options.rest_curvature_smoothness = fit_smoothness;
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
    // A fit that fails at its start has no values: said so, nothing written.
    if (fit.values.size() != fit.start.size() || fit.std.size() != fit.start.size()) {
      std::cerr << "rodfit rollout: --fit: " << fit.message << " (nothing written)\n";
      return EXIT_FAILURE;
    }
    // A least-squares fit that did not converge still holds its best point (Levenberg-Marquardt
    // accepts only steps that lower the cost): written with converged false, the exit status 4.
    if (!fit.converged && fit_options.method == rodfit::MotionFitMethod::kLevenbergMarquardt)
      status = std::max(status, kFitNotConverged);
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
               ",\n  \"marker_sigma_used_m\": " + num(fit.marker_sigma) +
               ",\n  \"marker_sigma_estimated\": " + (fit.marker_sigma_estimated ? "true" : "false") +
               ",\n  \"error_start_m\": " + rodfit::FormatDouble(fit.error_start) +
               ",\n  \"error_fitted_m\": " + rodfit::FormatDouble(fit.error_fitted) +
               ",\n  \"parameters\": {";
    // The log-parameters by name; the rest shape's knots (the last 2 K names) in "rest_shape".
    const size_t knots = fit.rest_curvature_s.size();
    const size_t logs = fit.names.size() - 2 * knots;
    for (size_t k = 0; k < logs; ++k) {
      rodfit::SetMotionParameter(fit.names[k], fit.values[k], &scene);
      fit_json += std::string(k ? "," : "") + "\n    \"" + fit.names[k] + "\": {\"start\": " +
                  rodfit::FormatDouble(fit.start[k]) + ", \"value\": " +
                  rodfit::FormatDouble(fit.values[k]) + ", \"std\": " + num(fit.std[k]) +
                  ", \"identifiable\": " + (fit.identifiable[k] ? "true" : "false") +
                  ", \"at_bound\": " + (fit.at_bound[k] ? "true" : "false") +
                  (fit.identifiable[k] ? std::string() : ", \"reason\": " + quoted(fit.reason[k])) + "}";
    }
    fit_json += "\n  },";
    if (knots > 0) {
      // Applied to the scene (for the rollouts below) and written: knots, values, std.
      scene.rod.rest_curvature_s = fit.rest_curvature_s;
      scene.rod.rest_curvature_profile.assign(knots, Eigen::Vector3d::Zero());
      const rodfit::Scene& before = experiment.scene;
      auto list = [&](const std::function<std::string(size_t)>& item) {
        std::string text = "[";
        for (size_t j = 0; j < knots; ++j) text += std::string(j ? ", " : "") + item(j);
        return text + "]";
      };
      for (size_t j = 0; j < knots; ++j) {
        const Eigen::Vector3d at = rodfit::RestCurvatureProfileAt(
            before.rod.rest_curvature_s, before.rod.rest_curvature_profile, fit.rest_curvature_s[j]);
        scene.rod.rest_curvature_profile[j] =
            Eigen::Vector3d(fit.values[logs + 2 * j], fit.values[logs + 2 * j + 1], at[2]);
      }
      // The largest |correlation| of a knot with bend_stiffness: one configuration confounds them.
      double confounded = NAN;
      for (size_t k = 0; k < logs; ++k)
        if (fit.names[k] == "bend_stiffness")
          for (size_t j = logs; j < fit.names.size(); ++j) {
            const double c = std::abs(fit.covariance_log(k, j)) /
                             std::sqrt(fit.covariance_log(k, k) * fit.covariance_log(j, j));
            if (std::isfinite(c)) confounded = std::isfinite(confounded) ? std::max(confounded, c) : c;
          }
      fit_json += "\n  \"rest_shape\": {\"s_m\": " +
                  list([&](size_t j) { return rodfit::FormatDouble(fit.rest_curvature_s[j]); }) +
                  ", \"k1_per_m\": " + list([&](size_t j) { return rodfit::FormatDouble(fit.values[logs + 2 * j]); }) +
                  ", \"k2_per_m\": " + list([&](size_t j) { return rodfit::FormatDouble(fit.values[logs + 2 * j + 1]); }) +
                  ", \"tau_per_m\": " + list([&](size_t j) { return rodfit::FormatDouble(scene.rod.rest_curvature_profile[j][2]); }) +
                  ", \"k1_std\": " + list([&](size_t j) { return num(fit.std[logs + 2 * j]); }) +
                  ", \"k2_std\": " + list([&](size_t j) { return num(fit.std[logs + 2 * j + 1]); }) +
                  ", \"k1_start\": " + list([&](size_t j) { return rodfit::FormatDouble(fit.start[logs + 2 * j]); }) +
                  ", \"k2_start\": " + list([&](size_t j) { return rodfit::FormatDouble(fit.start[logs + 2 * j + 1]); }) +
                  ", \"smoothness_std_per_m\": " + rodfit::FormatDouble(fit_smoothness) +
                  ", \"prior_residuals\": " + std::to_string(fit.prior_residuals) +
                  ", \"max_correlation_with_bend_stiffness\": " + num(confounded) + "},";
      if (std::isfinite(confounded))
        std::printf("  rest shape: largest |correlation| of a knot with bend_stiffness %.2f\n",
                    confounded);
    }
    fit_json += "\n  \"names\": [";
    for (size_t k = 0; k < fit.names.size(); ++k)
      fit_json += std::string(k ? ", " : "") + quoted(fit.names[k]);
    fit_json += "],\n  \"correlation\": [";
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
    for (size_t k = 0; k < fit.names.size(); ++k) {
      std::printf("  %s: %.6g -> %.6g", fit.names[k].c_str(), fit.start[k], fit.values[k]);
      if (fit.identifiable[k])
        std::printf(" +- %.3g", fit.std[k]);
      else
        std::printf(" (not identifiable: %s)", fit.reason[k].c_str());
      std::printf("%s\n", fit.at_bound[k] ? " [at its bound]" : "");
    }
    for (size_t k = 0; k < fit.names.size(); ++k)
      if (!fit.identifiable[k]) status = std::max(status, kFitNotConverged);
    // The residual variance says whether the rollout's model explains the recordings to the
    // markers' noise (stated, or estimated from the recordings): above its chi-square band
    // (stated) or above kEstimatedNoiseVarianceLimit (estimated: the estimate has its own
    // error), the values absorb model error (e.g. pins standing in for gripper clamps) and their
    // std understates it: exit status 5, everything still written.
    const int dof = fit.noise_residuals - static_cast<int>(fit.names.size());
    if (fit.marker_sigma > 0.0 && dof > 0 && std::isfinite(fit.residual_variance)) {
      const rodfit::VarianceBand band = rodfit::ResidualVarianceBand(dof);
      const double limit = fit.marker_sigma_estimated ? kEstimatedNoiseVarianceLimit : band.high;
      if (fit.residual_variance > limit) {
        char text[480];
        std::snprintf(text, sizeof(text),
                      "residual variance %.3g x the marker noise (%.3g m, %s; expected %.2g to "
                      "%.2g for %d degrees of freedom%s): the model does not explain the "
                      "recordings to their noise (held points not as recorded? --marker-sigma "
                      "too small?); the values carry model error",
                      fit.residual_variance, fit.marker_sigma,
                      fit.marker_sigma_estimated ? "estimated from the recordings" : "--marker-sigma",
                      band.low, band.high, dof,
                      fit.marker_sigma_estimated ? ", at most 2 with an estimated noise" : "");
        std::fprintf(stderr, "rodfit rollout: warning: %s\n", text);
        warnings.push_back(text);
        status = std::max(status, kResidualsNotExplained);
      }
    }
    fitted = std::make_unique<rodfit::MotionFitResult>(fit);
  }
  std::string csv = "recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z\n";
  // Per recording (recordings.csv) and per frame (rollout_error.csv): what the report tabulates.
  std::string table = "recording,file,status,frames,mae_predicted_m,mae_all_m,worst_marker,"
                      "worst_marker_mae_m,reason\n";
  std::string over_time = "recording,frame,t,mae_predicted_m,max_error_m,worst_marker\n";
  std::vector<std::string> failures;
  int ran = 0;
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
    auto field = [](const std::string& text) {  // a CSV field: quoted, quotes doubled
      std::string q = "\"";
      for (char ch : text) q += ch == '"' ? std::string("\"\"") : std::string(1, ch == '\n' ? ' ' : ch);
      return q + "\"";
    };
    if (!result.ok) {
      // The others still run and are written; the exit status names the failure.
      std::cerr << "rodfit rollout: " << rec.file << ": " << result.reason << "\n";
      failures.push_back(rec.file + ": " + result.reason);
      table += std::to_string(r) + "," + field(rec.file) + ",failed,,,,,," + field(result.reason) + "\n";
      continue;
    }
    ++ran;
    {
      // Each predicted marker's error over the frames (mean |coordinate error|), the worst one.
      const int M = static_cast<int>(result.marker_s.size());
      std::vector<double> sum(M, 0.0);
      std::vector<int> count(M, 0);
      for (size_t k = 1; k < result.predicted.size(); ++k) {
        double frame_sum = 0.0, frame_max = 0.0;
        int frame_n = 0, frame_worst = -1;
        for (int m = 0; m < M; ++m) {
          if (result.held[m] || !rec.frames[k].col(m).allFinite()) continue;
          const Eigen::Vector3d d = result.predicted[k].col(m) - rec.frames[k].col(m);
          sum[m] += d.cwiseAbs().sum() / 3.0, ++count[m];
          frame_sum += d.cwiseAbs().sum() / 3.0, ++frame_n;
          if (d.norm() > frame_max) frame_max = d.norm(), frame_worst = m;
        }
        over_time += std::to_string(r) + "," + std::to_string(k) + "," +
                     rodfit::FormatDouble(k * rec.frame_interval) + "," +
                     (frame_n ? rodfit::FormatDouble(frame_sum / frame_n) : std::string()) + "," +
                     (frame_n ? rodfit::FormatDouble(frame_max) : std::string()) + "," +
                     (frame_worst >= 0 ? std::to_string(frame_worst) : std::string()) + "\n";
      }
      int worst = -1;
      for (int m = 0; m < M; ++m)
        if (count[m] && (worst < 0 || sum[m] / count[m] > sum[worst] / count[worst])) worst = m;
      table += std::to_string(r) + "," + field(rec.file) + ",ok," +
               std::to_string(result.predicted.size()) + "," +
               rodfit::FormatDouble(result.mae_predicted) + "," +
               rodfit::FormatDouble(result.mae_all) + "," +
               (worst >= 0 ? std::to_string(worst) + "," + rodfit::FormatDouble(sum[worst] / count[worst])
                           : std::string(",")) +
               ",\n";
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
    std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
    for (const std::string& path : recording_paths) inputs.emplace_back(path, "recording");
    if (!parameters_path.empty()) inputs.emplace_back(parameters_path, "--parameters");
    rodfit::RefuseOverwritingInput((std::filesystem::path(report_dir) / "index.html").string(), inputs);
    report.fit = fitted.get();
    report.warnings = warnings;
    report_out = std::make_unique<rodfit::StagedDirectory>(report_dir);
    report_warnings = rodfit::WriteRolloutReport(report_out.get(), report);
  }
  rodfit::StagedDirectory out(output_dir);
  std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
  if (!parameters_path.empty()) inputs.emplace_back(parameters_path, "--parameters");
  out.Write("rollout.csv", csv, "output file name");
  rodfit::RefuseOverwritingInput(out.FinalPath("rollout.csv"), inputs);
  out.Write("recordings.csv", table, "output file name");
  rodfit::RefuseOverwritingInput(out.FinalPath("recordings.csv"), inputs);
  out.Write("rollout_error.csv", over_time, "output file name");
  rodfit::RefuseOverwritingInput(out.FinalPath("rollout_error.csv"), inputs);
  if (!fit_json.empty()) {
    out.Write("motion_fit.json", fit_json, "output file name");
    rodfit::RefuseOverwritingInput(out.FinalPath("motion_fit.json"), inputs);
  }
  if (report_out)
    rodfit::CommitAll({report_out.get(), &out});
  else
    out.Commit();
  for (const std::string& w : report_warnings)
    std::fprintf(stderr, "rodfit rollout: warning: %s\n", w.c_str());
  const double n = static_cast<double>(std::max(ran, 1));
  char line[256];
  std::snprintf(line, sizeof(line),
                "mean absolute coordinate error: %.4g m over all markers, %.4g m over the "
                "predicted ones (%d samples, %d recording(s))\n",
                sum_all / n, sum_predicted / n, samples, ran);
  std::cout << line;
  if (!failures.empty()) {
    std::string names;
    for (const std::string& f : failures) names += (names.empty() ? "" : "; ") + f;
    std::fprintf(stderr, "rodfit rollout: %zu of %zu recording(s) failed (the others written): %s\n",
                 failures.size(), recs.size(), names.c_str());
    status = std::max(status, kRecordingFailed);
  }
  return status;
}
