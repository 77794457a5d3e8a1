// Rollout (run.h): `rodfit rollout` as a library call — open-loop predictions of recorded
// motions (solve/rollout.h), after a motion fit of the asked parameters to them; rollout.csv and
// motion_fit.json in memory and, when asked, written.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <filesystem>
#include <memory>
#include <stdexcept>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/io/profile.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/check.h"
#include "rodfit/model/rod.h"
#include "rodfit/io/recording.h"
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
                          const std::vector<std::string>& names, const std::vector<double>& rest_tau,
                          const std::vector<MotionRecordingData>& recordings) {
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
      ",\n  \"marker_sigma_used_m\": " + num(fit.marker_sigma) +
      ",\n  \"marker_sigma_estimated\": " + (fit.marker_sigma_estimated ? "true" : "false") +
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
  text += "\n  },";
  // The rest shape's knots (the last 2 K of fit.names), their values, std and start.
  const size_t knots = fit.rest_curvature_s.size(), logs = fit.names.size() - 2 * knots;
  if (knots > 0) {
    auto list = [&](const std::function<double(size_t)>& item) {
      std::string l = "[";
      for (size_t j = 0; j < knots; ++j) l += std::string(j ? ", " : "") + num(item(j));
      return l + "]";
    };
    // The largest |correlation| of a knot with bend_stiffness: one configuration confounds them.
    double confounded = NAN;
    for (size_t k = 0; k < logs; ++k)
      if (fit.names[k] == "bend_stiffness")
        for (size_t j = logs; j < fit.names.size(); ++j) {
          const double c = std::abs(fit.covariance_log(k, j)) /
                           std::sqrt(fit.covariance_log(k, k) * fit.covariance_log(j, j));
          if (std::isfinite(c)) confounded = std::isfinite(confounded) ? std::max(confounded, c) : c;
        }
    text += "\n  \"rest_shape\": {\"s_m\": " + list([&](size_t j) { return fit.rest_curvature_s[j]; }) +
            ", \"k1_per_m\": " + list([&](size_t j) { return fit.values[logs + 2 * j]; }) +
            ", \"k2_per_m\": " + list([&](size_t j) { return fit.values[logs + 2 * j + 1]; }) +
            ", \"tau_per_m\": " + list([&](size_t j) { return rest_tau.empty() ? 0.0 : rest_tau[j]; }) +
            ", \"k1_std\": " + list([&](size_t j) { return fit.std[logs + 2 * j]; }) +
            ", \"k2_std\": " + list([&](size_t j) { return fit.std[logs + 2 * j + 1]; }) +
            ", \"k1_start\": " + list([&](size_t j) { return fit.start[logs + 2 * j]; }) +
            ", \"k2_start\": " + list([&](size_t j) { return fit.start[logs + 2 * j + 1]; }) +
            ", \"smoothness_std_per_m\": " + num(fit_options.rest_curvature_smoothness) +
            ", \"prior_residuals\": " + std::to_string(fit.prior_residuals) +
            ", \"max_correlation_with_bend_stiffness\": " + num(confounded) + "},";
  }
  // The held frames' nuisances (MotionFitOptions::gripper_prior_deg): per recording, its
  // grippers' tilts about d1 and d2, apart from the parameters (never the rod's).
  if (!fit.gripper_rotation_deg.empty()) {
    auto pair = [&](const Vec3& v) { return "[" + num(v.x()) + ", " + num(v.y()) + "]"; };
    text += "\n  \"gripper_tilts\": {\"prior_std_deg\": " + num(fit_options.gripper_prior_deg) +
            ", \"prior_residuals\": " + std::to_string(fit.gripper_prior_residuals) +
            ", \"recordings\": [";
    for (size_t r = 0; r < fit.gripper_rotation_deg.size(); ++r)
      text += std::string(r ? "," : "") + "\n    {\"file\": " +
              quoted(r < recordings.size() ? recordings[r].name : std::string()) +
              ", \"clamp_deg\": " + pair(fit.gripper_rotation_deg[r][0]) +
              ", \"clamp_std_deg\": " + pair(fit.gripper_rotation_std_deg[r][0]) +
              ", \"end_deg\": " + pair(fit.gripper_rotation_deg[r][1]) +
              ", \"end_std_deg\": " + pair(fit.gripper_rotation_std_deg[r][1]) + "}";
    text += "]},";
  }
  text += "\n  \"names\": [";
  for (size_t k = 0; k < fit.names.size(); ++k) text += std::string(k ? ", " : "") + quoted(fit.names[k]);
  text += "],\n  \"correlation\": [";
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

// profile.json of a motion fit (docs/cli.md, "rollout"): the scene with the fitted values and
// rest shape (`fitted`) through the profile writer `rodfit fit` uses, the fit's log-parameters as
// its fitted parameters (value, start, std, identifiable), the rest shape in rod.rest_shape.
// Empty, with the reason in *why, when a rest-shape knot is not identifiable: a profile's rest
// shape has no way to say that one of its numbers is not a measurement.
std::string MotionFitProfile(const Experiment& experiment, const Scene& fitted,
                             const MotionFitResult& fit, std::string* why) {
  const size_t knots = fit.rest_curvature_s.size(), logs = fit.names.size() - 2 * knots;
  for (size_t k = logs; k < fit.names.size(); ++k)
    if (!fit.identifiable[k]) {
      *why = "profile.json not written: " + fit.names[k] + " is not identifiable (" +
             fit.reason[k] + ")";
      return "";
    }
  FitResult r;
  r.success = fit.converged;
  r.message = fit.message;
  r.iterations = fit.iterations;
  r.initial_cost = fit.initial_cost;
  r.final_cost = fit.final_cost;
  r.num_residuals = fit.residuals;
  r.residual_variance = fit.residual_variance;
  r.residual_dof = std::max(1, fit.noise_residuals - static_cast<int>(fit.names.size()) -
                                  fit.gripper_prior_residuals);  // one prior row per nuisance
  r.correlation.resize(static_cast<int>(logs), static_cast<int>(logs));
  for (size_t k = 0; k < logs; ++k) {
    Parameter p;
    p.name = fit.names[k];
    p.value = fit.values[k];
    p.fit = true;
    p.start = fit.start[k];
    p.identifiable = fit.identifiable[k];
    if (p.identifiable && std::isfinite(fit.std[k])) p.std = fit.std[k];
    p.reason = fit.reason[k];
    p.at_bound = fit.at_bound[k];
    r.parameters.push_back(p);
    r.fitted_names.push_back(p.name);
    for (size_t j = 0; j < logs; ++j)
      r.correlation(k, j) = fit.covariance_log(k, j) /
                            std::sqrt(fit.covariance_log(k, k) * fit.covariance_log(j, j));
  }
  Experiment e = experiment;
  e.scene = fitted;
  const FitOptions options;
  return FormatProfile(ProfileJson(e, options, r, CheckResiduals(r, options)));
}

// options.fit_options with, when options.progress is set, a progress line per iteration of the
// fit (the lines refer to `options`: it outlives the fit).
MotionFitOptions FitOptionsWithProgress(const RolloutRunOptions& options) {
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
  return fit_options;
}

// The fitted values set in `scene`: the log-parameters and, when the rest shape was fitted, its
// knots. Returns the rest twist at the fitted knots (empty without them).
std::vector<double> SetFittedValues(const MotionFitResult& fit, Scene* scene) {
  const size_t knots = fit.rest_curvature_s.size(), logs = fit.names.size() - 2 * knots;
  for (size_t k = 0; k < logs; ++k) SetMotionParameter(fit.names[k], fit.values[k], scene);
  std::vector<double> rest_tau;
  if (knots > 0) {
    // The fitted rest shape replaces the scene's profile (its rest twist kept).
    std::vector<Vec3> profile(knots);
    for (size_t j = 0; j < knots; ++j) {
      const Vec3 at = RestCurvatureProfileAt(scene->rod.rest_curvature_s,
                                             scene->rod.rest_curvature_profile, fit.rest_curvature_s[j]);
      profile[j] = Vec3(fit.values[logs + 2 * j], fit.values[logs + 2 * j + 1], at[2]);
      rest_tau.push_back(at[2]);
    }
    scene->rod.rest_curvature_s = fit.rest_curvature_s;
    scene->rod.rest_curvature_profile = profile;
  }
  return rest_tau;
}

// The fit's summary lines (options.note): the mean error before and after, each value with its
// start and std (or why it is not identifiable), each recording's fitted gripper tilts.
void NoteFit(const RolloutRunOptions& options, const MotionFitResult& fit,
             const std::vector<MotionRecordingData>& data) {
  char line[320];
  std::snprintf(line, sizeof(line),
                "fitted over %zu recording(s) in %d rollouts (%s, %.3g s): mean error %.4g m -> "
                "%.4g m",
                data.size(), fit.evaluations, fit.method.c_str(), fit.seconds, fit.error_start,
                fit.error_fitted);
  Note(options, line);
  for (size_t k = 0; k < fit.names.size(); ++k) {
    std::snprintf(line, sizeof(line), "  %s: %.6g -> %.6g", fit.names[k].c_str(), fit.start[k],
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
  for (size_t r = 0; r < fit.gripper_rotation_deg.size(); ++r) {
    const std::array<Vec3, 2>& v = fit.gripper_rotation_deg[r];
    const std::array<Vec3, 2>& sd = fit.gripper_rotation_std_deg[r];
    std::snprintf(line, sizeof(line),
                  "  gripper tilts (about d1, d2) of %s: clamp (%.3g, %.3g) +- (%.2g, %.2g) deg, "
                  "end (%.3g, %.3g) +- (%.2g, %.2g) deg",
                  data[r].name.c_str(), v[0].x(), v[0].y(), sd[0].x(), sd[0].y(), v[1].x(),
                  v[1].y(), sd[1].x(), sd[1].y());
    Note(options, line);
  }
}

// The residual variance says whether the rollout's model explains the recordings to the
// markers' noise (stated, or estimated from the recordings): above its chi-square band
// (stated) or above kEstimatedNoiseVarianceLimit (estimated: the estimate has its own error),
// the values absorb model error (e.g. pins standing in for gripper clamps) and their std
// understates it. A misfit is set in run (residual_warning, warnings, misfit).
void CheckResidualVariance(const MotionFitResult& fit, RolloutRun* run) {
  constexpr double kEstimatedNoiseVarianceLimit = 2.0;  // the model's error as large as the noise
  const int dof = fit.noise_residuals - static_cast<int>(fit.names.size()) -
                  fit.gripper_prior_residuals;  // the nuisances, one prior row each
  if (fit.marker_sigma > 0.0 && dof > 0 && std::isfinite(fit.residual_variance)) {
    const VarianceBand band = ResidualVarianceBand(dof);
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
      run->residual_warning = text;
      run->warnings.push_back(text);
      run->misfit = true;
    }
  }
}

// The motion fit of options.fit to the recordings, its values set in `scene`. False: a
// least-squares fit that did not converge (run->error says so).
bool FitToRecordings(const Experiment& experiment, const RolloutRunOptions& options,
                     Scene* scene, RolloutRun* run) {
  const std::vector<std::string>& names = options.fit;
  std::vector<MotionRecordingData> data;
  for (const MarkerRecording& rec : run->recordings)
    data.push_back({rec.file, rec.frame_interval, rec.frames});
  const MotionFitOptions fit_options = FitOptionsWithProgress(options);
  MotionFitResult fit;
  try {
    fit = FitMotion(*scene, data, names, options.rollout, experiment.statics, fit_options);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--fit: ") + e.what());
  }
  // A fit that fails at its start has no values: said so, nothing written.
  if (fit.values.size() != fit.start.size() || fit.std.size() != fit.start.size()) {
    run->error = "--fit: " + fit.message + " (nothing written)";
    return false;
  }
  // A least-squares fit that did not converge keeps its best point (Levenberg-Marquardt accepts
  // only steps that lower the cost): written with converged false.
  run->fit_not_converged = !fit.converged && fit_options.method == MotionFitMethod::kLevenbergMarquardt;
  const std::vector<double> rest_tau = SetFittedValues(fit, scene);
  for (size_t k = 0; k < fit.names.size(); ++k)
    run->fit_undetermined = run->fit_undetermined || !fit.identifiable[k];
  run->fit_text = MotionFitText(fit, fit_options, names, rest_tau, data);
  run->fit_json = nlohmann::json::parse(run->fit_text);
  std::string no_profile;
  run->profile_text = MotionFitProfile(experiment, *scene, fit, &no_profile);
  if (!no_profile.empty()) {
    Note(options, no_profile);
    run->warnings.push_back(no_profile);
  }
  NoteFit(options, fit, data);
  if (!fit.converged) run->warnings.push_back("--fit: " + fit.message);
  CheckResidualVariance(fit, run);
  run->fit = std::make_shared<MotionFitResult>(fit);
  return true;
}

// A CSV field: quoted, quotes doubled, line breaks as spaces.
std::string CsvField(const std::string& text) {
  std::string q = "\"";
  for (char ch : text) q += ch == '"' ? std::string("\"\"") : std::string(1, ch == '\n' ? ' ' : ch);
  return q + "\"";
}

// Recording r rolled out, a fitted recording with its grippers' fitted tilts (the fit's
// nuisances).
RolloutResult RollOutRecording(const Experiment& experiment, const RolloutRunOptions& options,
                               const Scene& scene, const RolloutRun& run, size_t r) {
  const MarkerRecording& rec = run.recordings[r];
  RolloutOptions rollout = options.rollout;
  if (run.fit && r < run.fit->gripper_rotation_deg.size())
    for (int g = 0; g < 2; ++g)
      rollout.gripper_rotation[g] += run.fit->gripper_rotation_deg[r][g] * (M_PI / 180.0);
  try {
    return Rollout(scene, rec.frame_interval, rec.frames, rollout, experiment.statics);
  } catch (const std::invalid_argument& e) {
    throw InputError(rec.file, 0, "", e.what());
  }
}

// Recording r's errors: its rows of rollout_error.csv (each frame's mean and largest error,
// the worst marker) and of recordings.csv (each predicted marker's mean |coordinate error| over
// the frames, the worst one).
void AppendErrorRows(size_t r, const MarkerRecording& rec, const RolloutResult& result,
                     RolloutRun* run) {
  const int M = static_cast<int>(result.marker_s.size());
  std::vector<double> sum(M, 0.0);
  std::vector<int> seen(M, 0);
  for (size_t k = 1; k < result.predicted.size(); ++k) {
    double frame_sum = 0.0, frame_max = 0.0;
    int frame_n = 0, frame_worst = -1;
    for (int m = 0; m < M; ++m) {
      if (result.held[m] || !rec.frames[k].col(m).allFinite()) continue;
      const Eigen::Vector3d d = result.predicted[k].col(m) - rec.frames[k].col(m);
      sum[m] += d.cwiseAbs().sum() / 3.0, ++seen[m];
      frame_sum += d.cwiseAbs().sum() / 3.0, ++frame_n;
      if (d.norm() > frame_max) frame_max = d.norm(), frame_worst = m;
    }
    run->over_time += std::to_string(r) + "," + std::to_string(k) + "," +
                      FormatDouble(k * rec.frame_interval) + "," +
                      (frame_n ? FormatDouble(frame_sum / frame_n) : std::string()) + "," +
                      (frame_n ? FormatDouble(frame_max) : std::string()) + "," +
                      (frame_worst >= 0 ? std::to_string(frame_worst) : std::string()) + "\n";
  }
  int worst = -1;
  for (int m = 0; m < M; ++m)
    if (seen[m] && (worst < 0 || sum[m] / seen[m] > sum[worst] / seen[worst])) worst = m;
  run->table += std::to_string(r) + "," + CsvField(rec.file) + ",ok," +
                std::to_string(result.predicted.size()) + "," +
                FormatDouble(result.mae_predicted) + "," + FormatDouble(result.mae_all) + "," +
                (worst >= 0 ? std::to_string(worst) + "," + FormatDouble(sum[worst] / seen[worst])
                            : std::string(",")) +
                ",\n";
}

// Recording r's rows of rollout.csv: every marker at every frame, observed and predicted.
void AppendRolloutRows(size_t r, const MarkerRecording& rec, const RolloutResult& result,
                       std::string* csv) {
  auto num = [](double v) { return std::isfinite(v) ? FormatDouble(v) : std::string(); };
  for (size_t k = 0; k < result.predicted.size(); ++k) {
    for (int m = 0; m < static_cast<int>(result.marker_s.size()); ++m) {
      const Eigen::Vector3d o = rec.frames[k].col(m), p = result.predicted[k].col(m);
      *csv += std::to_string(r) + "," + std::to_string(k) + "," +
              FormatDouble(k * rec.frame_interval) + "," + std::to_string(m) + "," +
              FormatDouble(result.marker_s[m]) + "," + (result.held[m] ? "1," : "0,") +
              num(o[0]) + "," + num(o[1]) + "," + num(o[2]) + "," + num(p[0]) + "," +
              num(p[1]) + "," + num(p[2]) + "\n";
    }
  }
}

// Every recording predicted; rollout.csv and the errors. False: a rollout failed (run->error).
bool RollOut(const Experiment& experiment, const RolloutRunOptions& options, const Scene& scene,
             RolloutRun* run) {
  std::string& csv = run->csv;
  csv = "recording,frame,t,marker,s,held,observed_x,observed_y,observed_z,x,y,z\n";
  double sum_all = 0.0, sum_predicted = 0.0;
  const size_t count = run->recordings.size();
  run->table = "recording,file,status,frames,mae_predicted_m,mae_all_m,worst_marker,"
               "worst_marker_mae_m,reason\n";
  run->over_time = "recording,frame,t,mae_predicted_m,max_error_m,worst_marker\n";
  int ran = 0;
  for (size_t r = 0; r < count; ++r) {
    const MarkerRecording& rec = run->recordings[r];
    if (options.progress)
      options.progress("rollout: recording " + std::to_string(r + 1) + " of " +
                           std::to_string(count),
                       static_cast<double>(r) / count);
    RolloutResult result = RollOutRecording(experiment, options, scene, *run, r);
    if (!result.ok) {
      // The others still run and are written; the run names the failure.
      run->failures.push_back(rec.file + ": " + result.reason);
      run->table += std::to_string(r) + "," + CsvField(rec.file) + ",failed,,,,,," +
                    CsvField(result.reason) + "\n";
      run->results.push_back(std::move(result));
      continue;
    }
    AppendErrorRows(r, rec, result, run);
    ++ran;
    AppendRolloutRows(r, rec, result, &csv);
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
  run->error_all = sum_all / static_cast<double>(std::max(ran, 1));
  run->error_predicted = sum_predicted / static_cast<double>(std::max(ran, 1));
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
  out.Write("recordings.csv", run->table, "output file name");
  out.Write("rollout_error.csv", run->over_time, "output file name");
  if (!run->fit_text.empty()) out.Write("motion_fit.json", run->fit_text, "output file name");
  if (!run->profile_text.empty()) out.Write("profile.json", run->profile_text, "output file name");
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
    CheckOutputDirectory(options.output_dir, {"rollout.csv", "motion_fit.json", "profile.json"},
                         inputs);
    if (!options.report_dir.empty()) CheckOutputDirectory(options.report_dir, {"index.html"}, inputs);
  }
  Scene scene = experiment.scene;
  for (const auto& [name, value] : options.parameters) {
    SetMotionParameter(name, value, &scene);
    char line[256];
    std::snprintf(line, sizeof(line), "%s = %.6g from ", name.c_str(), value);
    Note(options, line + options.parameters_path);
  }
  if (!options.parameters_path.empty() &&
      ReadMotionFitRestShape(options.parameters_path, scene.rod.length, &scene.rod.rest_curvature_s,
                             &scene.rod.rest_curvature_profile))
    Note(options, "rest shape (" + std::to_string(scene.rod.rest_curvature_s.size()) +
                      " knots) from " + options.parameters_path);
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
  if (!run.recordings.empty() && run.failures.size() == run.recordings.size()) {
    // Nothing ran: an error, and nothing written (a batch writes the recordings that ran).
    run.error = run.failures.size() == 1 ? run.failures.front()
                                         : "every recording failed: " + run.failures.front() +
                                               " (and " + std::to_string(run.failures.size() - 1) +
                                               " more)";
    return run;
  }
  if (!options.output_dir.empty()) WriteOutputs(experiment, options, &run);
  run.ok = true;
  return run;
}

}  // namespace rodfit
