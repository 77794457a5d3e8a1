// rodfit.fit / simulate / rollout: the library's entry points (rodfit/pipeline/run.h), the calls
// the CLI's commands make, bound for Python (docs/python.md). Each returns the run as plain
// Python data (dicts, lists, numpy arrays); rodfit/__init__.py turns failures into exceptions and
// warnings into Python warnings.
#include <filesystem>
#include <string>
#include <vector>

#include <glog/logging.h>
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include "bindings.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/io/output_dir.h"
#include "rodfit/pipeline/run.h"
#include "rodfit/report/fit_report.h"
#include "rodfit/report/rollout_report.h"
#include "rodfit/runtime/profile.h"

namespace rodfit_python {

namespace {

using RowsX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Ceres logs through glog (a rank-deficient covariance, a failed step); rodfit reports for
// itself, in its results: as the CLI does (src/cli/fit_command.cc).
void SilenceCeresLogging() {
  FLAGS_minloglevel = google::GLOG_FATAL;
  FLAGS_stderrthreshold = google::GLOG_FATAL;
  if (!google::IsGoogleLoggingInitialized()) google::InitGoogleLogging("rodfit");
}

// An output must not overwrite one of the experiment's inputs (as the CLI refuses it).
void RefuseOverwritingInputs(const rodfit::Experiment& experiment,
                             const std::vector<std::string>& outputs) {
  if (outputs.empty()) return;
  const std::vector<rodfit::InputFile> inputs = rodfit::ExperimentInputs(experiment);
  for (const std::string& path : outputs) rodfit::RefuseOverwritingInput(path, inputs);
}

py::dict Fit(const rodfit::Experiment& experiment, int threads, const std::string& output,
             const std::string& report_dir) {
  if (threads < 1 || threads > 256)
    throw std::invalid_argument("threads: must be an integer in [1, 256], got " +
                                std::to_string(threads));
  if (!report_dir.empty() && output.empty())
    throw std::invalid_argument("report: needs output (the profile is written with the report)");
  std::vector<std::string> outputs;
  if (!output.empty()) outputs.push_back(output);
  for (const char* name : {"summary.csv", "residuals.csv", "index.html"})
    if (!report_dir.empty()) outputs.push_back((std::filesystem::path(report_dir) / name).string());
  RefuseOverwritingInputs(experiment, outputs);
  rodfit::FitRunOptions options;
  options.num_threads = threads;
  options.profile_path = output;
  options.report_dir = report_dir;
  if (!report_dir.empty())
    options.write_report = [](rodfit::StagedDirectory* out, const rodfit::Experiment& e,
                              const rodfit::FitInput& input, const rodfit::FitResult& result,
                              const std::vector<std::string>& warnings) {
      return rodfit::WriteFitReport(out, e, input, result, warnings);
    };
  rodfit::FitRun run;
  {
    py::gil_scoped_release release;
    run = rodfit::FitExperiment(experiment, options);
  }
  py::dict out;
  out["ok"] = run.ok;
  out["error"] = run.error.empty() ? "" : experiment.path + ": " + run.error;
  out["profile"] = run.ok ? JsonToPython(run.profile.dump()) : py::object(py::none());
  std::vector<std::string> warnings = run.warnings;
  warnings.insert(warnings.end(), run.report_warnings.begin(), run.report_warnings.end());
  out["warnings"] = warnings;
  out["all_determined"] = run.all_determined;
  out["misfit"] = run.misfit;
  out["iterations"] = run.result.iterations;
  out["seconds"] = run.result.seconds;
  return out;
}

py::dict ForceRow(const rodfit::CaseForce& f) {
  py::dict row;
  row["case"] = f.name;
  row["point"] = f.point;
  row["s"] = f.s;
  row["position"] = Eigen::Vector3d(f.position);
  row["force"] = Eigen::Vector3d(f.force);
  row["moment"] = Eigen::Vector3d(f.moment);
  return row;
}

py::dict Simulate(const rodfit::Experiment& scene, const rodfit::Profile* profile,
                  const std::string& output, bool keep_going) {
  rodfit::Experiment experiment = scene;
  if (profile) rodfit::UseProfileMaterial(*profile, &experiment.scene);
  rodfit::SimulateOptions options;
  options.keep_going = keep_going;
  options.output_dir = output;
  rodfit::SimulateRun run;
  {
    py::gil_scoped_release release;
    run = rodfit::SimulateScene(experiment, options);
  }
  py::dict out;
  out["moving"] = run.moving;
  out["first_failure"] = run.first_failure;
  out["warnings"] = run.warnings;
  out["seconds"] = run.seconds;
  py::dict shapes;
  for (const rodfit::CaseShape& shape : run.shapes)
    shapes[py::str(shape.name)] = RowsX3(shape.x.transpose());
  out["shapes"] = shapes;
  py::list forces;
  for (const rodfit::CaseForce& f : run.forces) forces.append(ForceRow(f));
  out["forces"] = forces;
  py::list summary;
  for (const rodfit::CaseSummaryRow& r : run.summary) {
    py::dict row;
    row["case"] = r.name;
    row["converged"] = r.converged;
    row["stable"] = r.stable;
    row["iterations"] = r.iterations;
    row["gradient_norm"] = r.gradient_norm;
    row["reason"] = r.reason;
    summary.append(row);
  }
  for (const rodfit::MotionSummaryRow& r : run.motion_summary) {
    py::dict row;
    row["case"] = r.name;
    row["completed"] = r.completed;
    row["steps"] = r.steps;
    row["newton_iterations"] = r.newton_iterations;
    row["stable_step"] = r.stable_step;
    row["reason"] = r.reason;
    summary.append(row);
  }
  out["summary"] = summary;
  // Moving: per case the times (T,), the centre-lines (T, n+1, 3) and per held point its
  // position, force and moment over time (T, 3).
  py::dict motions;
  for (const rodfit::CaseMotion& motion : run.motions) {
    const size_t frames = motion.frames.size();
    const size_t vertices = frames ? static_cast<size_t>(motion.frames[0].x.cols()) : 0;
    py::array_t<double> t(frames), x({frames, vertices, size_t{3}});
    auto tt = t.mutable_unchecked<1>();
    auto xx = x.mutable_unchecked<3>();
    py::dict reactions;
    for (size_t k = 0; k < frames; ++k) {
      const rodfit::CaseMotion::Frame& frame = motion.frames[k];
      tt(k) = frame.t;
      for (size_t i = 0; i < vertices; ++i)
        for (int j = 0; j < 3; ++j) xx(k, i, j) = frame.x(j, static_cast<Eigen::Index>(i));
    }
    if (frames) {
      for (size_t p = 0; p < motion.frames[0].reactions.size(); ++p) {
        RowsX3 position(frames, 3), force(frames, 3), moment(frames, 3);
        for (size_t k = 0; k < frames; ++k) {
          const rodfit::CaseForce& f = motion.frames[k].reactions.at(p);
          position.row(k) = f.position.transpose();
          force.row(k) = f.force.transpose();
          moment.row(k) = f.moment.transpose();
        }
        py::dict reaction;
        reaction["s"] = motion.frames[0].reactions[p].s;
        reaction["position"] = position;
        reaction["force"] = force;
        reaction["moment"] = moment;
        reactions[py::str(motion.frames[0].reactions[p].point)] = reaction;
      }
    }
    py::dict entry;
    entry["t"] = t;
    entry["x"] = x;
    entry["s"] = motion.s;
    entry["reactions"] = reactions;
    motions[py::str(motion.name)] = entry;
  }
  out["motions"] = motions;
  return out;
}

// `settings`: the keywords the caller gave (rodfit.rollout passes only those), read through
// RolloutOptions' and MotionFitOptions' Serialize; the others keep the library's defaults.
py::dict RunRollout(const rodfit::Experiment& scene, const std::vector<std::string>& recordings,
                    double frame_rate, bool millimetres, const std::vector<std::string>& fit,
                    const py::dict& settings, const std::string& output,
                    const std::string& report_dir) {
  rodfit::RolloutRunOptions options;
  DictSettings given(settings);
  rodfit::Serialize(&given, &options.rollout);
  rodfit::Serialize(&given, &options.fit_options);
  given.CheckAllRead();
  options.fit = fit;
  options.output_dir = output;
  options.report_dir = report_dir;
  if (!report_dir.empty())
    options.write_report = rodfit::WriteRolloutRunReport;
  std::vector<std::string> notes;
  options.note = [&notes](const std::string& line) { notes.push_back(line); };
  rodfit::RolloutRun run;
  {
    py::gil_scoped_release release;
    run = rodfit::Rollout(scene, rodfit::ReadRecordings(scene, recordings, frame_rate, millimetres),
                          options);
  }
  py::dict out;
  out["ok"] = run.ok;
  out["error"] = run.error;
  out["error_all"] = run.error_all;
  out["error_predicted"] = run.error_predicted;
  out["samples"] = run.samples;
  std::vector<std::string> warnings = run.warnings;
  warnings.insert(warnings.end(), run.report_warnings.begin(), run.report_warnings.end());
  out["warnings"] = warnings;
  out["notes"] = notes;
  out["misfit"] = run.misfit;
  out["failures"] = run.failures;
  out["fit_not_converged"] = run.fit_not_converged;
  out["fit_undetermined"] = run.fit_undetermined;
  out["fit"] = run.fit ? JsonToPython(run.fit_json.dump()) : py::object(py::none());
  // profile.json of the fit (the rod as fitted, its rest shape included), as `rodfit.fit`'s.
  out["profile"] = run.profile_text.empty() ? py::object(py::none()) : JsonToPython(run.profile_text);
  py::list results;
  for (size_t r = 0; r < run.results.size(); ++r) {
    const rodfit::RolloutResult& result = run.results[r];
    const size_t frames = result.predicted.size();
    const size_t markers = frames ? static_cast<size_t>(result.predicted[0].cols()) : 0;
    py::array_t<double> predicted({frames, markers, size_t{3}});
    auto pp = predicted.mutable_unchecked<3>();
    for (size_t k = 0; k < frames; ++k)
      for (size_t i = 0; i < markers; ++i)
        for (int j = 0; j < 3; ++j)
          pp(k, i, j) = result.predicted[k](j, static_cast<Eigen::Index>(i));
    py::dict entry;
    entry["file"] = r < run.recordings.size() ? run.recordings[r].file : std::string();
    entry["ok"] = result.ok;
    entry["reason"] = result.reason;
    entry["marker_s"] = result.marker_s;
    std::vector<bool> held(result.held.begin(), result.held.end());
    entry["held"] = held;
    entry["predicted"] = predicted;
    entry["mae_all"] = result.mae_all;
    entry["mae_predicted"] = result.mae_predicted;
    entry["samples"] = result.samples;
    entry["seconds"] = result.seconds;
    results.append(entry);
  }
  out["recordings"] = results;
  return out;
}

}  // namespace

void BindRun(py::module_& m) {
  SilenceCeresLogging();
  m.def("fit", &Fit, py::arg("experiment"), py::arg("threads") = 2, py::arg("output") = "",
        py::arg("report") = "",
        "rodfit::FitExperiment: {'ok', 'error', 'profile' (the profile JSON as Python data), "
        "'warnings', 'all_determined', 'misfit', 'iterations', 'seconds' [s]}. Use rodfit.fit.");
  m.def(
      "simulate",
      [](const rodfit::Experiment& scene, std::optional<rodfit::Profile> profile,
         const std::string& output, bool keep_going) {
        return Simulate(scene, profile ? &*profile : nullptr, output, keep_going);
      },
      py::arg("scene"), py::arg("profile") = py::none(), py::arg("output") = "",
      py::arg("keep_going") = false,
      "rodfit::SimulateScene, with the profile's material when given. Use rodfit.simulate.");
  m.def("rollout", &RunRollout, py::arg("scene"), py::arg("recordings"),
        py::arg("frame_rate") = 0.0, py::arg("millimetres") = false,
        py::arg("fit") = std::vector<std::string>{}, py::arg("settings") = py::dict(),
        py::arg("output") = "", py::arg("report") = "",
        "rodfit::Rollout of recordings (CSV paths); `settings` by key (RolloutOptions' and "
        "MotionFitOptions'), the others their defaults. Use rodfit.rollout.");
}

}  // namespace rodfit_python
