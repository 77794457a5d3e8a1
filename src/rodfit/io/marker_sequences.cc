// Marker sequences of a moving experiment (marker_sequences.h).
#include "rodfit/io/marker_sequences.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <utility>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/io/fit_input.h"
#include "rodfit/model/material_parameters.h"

namespace rodfit {
namespace {

// Numbers in messages, as a person would type them.
std::string Short(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

// A coordinate field: a number, or missing (empty, nan, NaN: the marker was not seen).
bool ReadCoordinate(const CsvTable& table, int row, const std::string& column,
                    const std::string& text, double* value) {
  std::string lower = text;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower.empty() || lower == "nan") return false;
  if (!ParseDouble(text, value))
    throw InputError(table.name(), table.line(row), column,
                     "not a number: '" + ClipForMessage(text) + "' (leave it empty or nan when "
                     "the marker was not seen)");
  return true;
}

MarkerSequence ReadSequence(const Experiment& ex, int case_index, const ObservationSpec& spec) {
  const double length = ex.scene.rod.length;
  const double duration = ex.scene.dynamics->duration;
  const CsvTable table = CsvTable::Read(spec.file);
  const std::string& file = spec.file;
  if (table.num_rows() < 1) throw InputError(file, 0, "", "no rows");
  const bool by_time = table.HasColumn("t");
  if (!by_time && !table.HasColumn("frame"))
    throw InputError(file, 1, "t", "a markers3d sequence needs a t column (or frame with the "
                                   "entry's frame_rate)");
  if (!by_time && !(spec.frame_rate > 0.0))
    throw InputError(file, 1, "frame", "a frame column needs frame_rate [Hz] in the entry (" +
                                           ex.path + " line " + std::to_string(spec.line) + ")");
  const std::vector<double> key = table.Column(by_time ? "t" : "frame");
  const std::vector<double> s = table.Column("s");
  const std::vector<std::string> x = table.TextColumn("x"), y = table.TextColumn("y"),
                                 z = table.TextColumn("z");
  MarkerSequence seq;
  seq.case_index = case_index;
  seq.sigma = spec.sigma;
  std::map<double, int> times, markers;
  std::vector<std::pair<double, double>> rows;  // (t, s) of every row
  for (int r = 0; r < table.num_rows(); ++r) {
    double t = key[r];
    if (!by_time) {
      if (t != std::round(t) || t < 0.0)
        throw InputError(file, table.line(r), "frame", "must be an integer >= 0");
      t /= spec.frame_rate;
    }
    if (t < 0.0 || t > duration * (1.0 + 1e-12))
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "the sample's time " + Short(t) + " s lies outside the run [0, " +
                           Short(duration) + "] s (dynamics.duration)");
    if (s[r] < 0.0 || s[r] > length)
      throw InputError(file, table.line(r), "s",
                       "must be in [0, " + Short(length) + "] (the rod's length)");
    times.emplace(t, 0);
    markers.emplace(s[r], 0);
    if (static_cast<int>(times.size()) > kMaxSequenceTimes)
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "more than " + std::to_string(kMaxSequenceTimes) + " sample times");
    rows.emplace_back(t, s[r]);
  }
  for (auto& [t, index] : times) {
    index = static_cast<int>(seq.t.size());
    seq.t.push_back(t);
  }
  for (auto& [sm, index] : markers) {
    index = static_cast<int>(seq.s.size());
    seq.s.push_back(sm);
  }
  std::map<std::pair<int, int>, int> seen;  // (time, marker) -> line
  for (int r = 0; r < table.num_rows(); ++r) {
    const int time = times.at(rows[r].first), marker = markers.at(rows[r].second);
    if (const auto [it, fresh] = seen.emplace(std::make_pair(time, marker), table.line(r)); !fresh)
      throw InputError(file, table.line(r), "s",
                       "this marker's sample at this time is given twice (also line " +
                           std::to_string(it->second) + ")");
    Eigen::Vector3d p;
    const int given = int(ReadCoordinate(table, r, "x", x[r], &p.x())) +
                      int(ReadCoordinate(table, r, "y", y[r], &p.y())) +
                      int(ReadCoordinate(table, r, "z", z[r], &p.z()));
    if (given == 0) continue;  // not seen
    if (given < 3)
      throw InputError(file, table.line(r), given ? "x" : "",
                       "x, y and z must be all given or all missing (a marker not seen)");
    const Vec3& clamp = ex.scene.cases[case_index].clamp.position;
    if (!((p - clamp).norm() <= 100.0 * length))
      throw InputError(file, table.line(r), "x",
                       "the point lies more than 100 rod lengths from the clamp: not on the rod "
                       "(wrong units or frame?)");
    seq.samples.push_back({time, marker, p});
  }
  if (seq.samples.empty()) throw InputError(file, 0, "", "no recorded sample (every row is missing)");
  return seq;
}

}  // namespace

SequenceInput BuildSequenceInput(const Experiment& experiment) {
  if (!experiment.scene.dynamics)
    throw InputError(experiment.path, 1, "dynamics", "marker sequences need a dynamics: block");
  SequenceInput input;
  for (size_t c = 0; c < experiment.cases.size(); ++c)
    for (const ObservationSpec& spec : experiment.cases[c].observations) {
      if (spec.type != "markers3d") continue;  // the reader admits no other in a moving scene
      input.sequences.push_back(ReadSequence(experiment, static_cast<int>(c), spec));
      input.labels.push_back("markers3d " + std::filesystem::path(spec.file).filename().string());
    }
  if (input.sequences.empty())
    throw InputError(experiment.path, 0, "cases",
                     "no markers3d sequence to fit to (add observations to a case)");
  return input;
}

std::vector<std::string> FittedNames(const Experiment& experiment) {
  std::vector<std::string> names;
  for (const MaterialParameterInfo& row : MaterialParameters()) {
    const auto it = experiment.parameters.find(row.name);
    if (it != experiment.parameters.end() && it->second.fit) names.push_back(row.name);
  }
  return names;
}

MotionFitOptions SequenceFitOptionsOf(const Experiment& experiment,
                                      const std::vector<std::string>& names) {
  MotionFitOptions options;
  options.max_evaluations = experiment.fit.max_iterations;
  options.trusted_sigmas = experiment.fit.trusted_sigmas;
  for (const std::string& name : names) {
    const ParameterSpec& p = experiment.parameters.at(name);
    options.lower.push_back(p.min ? *p.min : NAN);
    options.upper.push_back(p.max ? *p.max : NAN);
  }
  return options;
}

FitResult SequenceFitResult(const Experiment& experiment, const SequenceInput& input,
                            const MotionFitResult& motion, const SequenceResiduals& residuals) {
  FitResult r;
  r.success = motion.converged;
  r.message = motion.message;
  r.iterations = motion.iterations;
  r.initial_cost = motion.initial_cost;
  r.final_cost = motion.final_cost;
  r.num_residuals = motion.residuals;
  r.residual_dof = std::max(1, motion.residuals - static_cast<int>(motion.names.size()));
  r.residual_variance = motion.residual_variance;
  r.seconds = motion.seconds;
  r.forward_solves = motion.evaluations;
  r.fitted_names = motion.names;
  // Every parameter the static fit lists (the rod's and the springs'), then the damping
  // parameters the experiment gives.
  std::vector<std::string> listed;
  for (const FitParameter& p : FitParametersOf(experiment)) listed.push_back(p.name);
  for (const MaterialParameterInfo& row : MaterialParameters())
    if (row.kind == ParameterKind::kDamping && experiment.parameters.count(row.name))
      listed.push_back(row.name);
  for (const std::string& name : listed) {
    ParameterEstimate est;
    est.name = name;
    est.unit = MaterialParameterUnit(name);
    const auto spec = experiment.parameters.find(name);
    est.value = est.start = spec != experiment.parameters.end()
                                ? spec->second.value
                                : MaterialParameterValue(experiment.scene.material, name).value_or(0.0);
    const auto k = std::find(motion.names.begin(), motion.names.end(), name);
    if (k != motion.names.end()) {
      const size_t i = static_cast<size_t>(k - motion.names.begin());
      est.fitted = true;
      est.start = motion.start[i];
      est.value = motion.values[i];
      est.identifiable = motion.identifiable[i];
      est.reason = motion.reason[i];
      est.at_bound = motion.at_bound[i];
      if (motion.identifiable[i] && std::isfinite(motion.std[i])) est.std = motion.std[i];
    }
    r.parameters.push_back(est);
  }
  const int m = static_cast<int>(motion.names.size());
  r.correlation.resize(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j)
      r.correlation(i, j) = motion.covariance_log(i, j) /
                            std::sqrt(motion.covariance_log(i, i) * motion.covariance_log(j, j));
  for (size_t q = 0; q < input.sequences.size(); ++q) {
    const MarkerSequence& seq = input.sequences[q];
    ObservationFit o;
    o.case_index = seq.case_index;
    o.case_name = experiment.scene.cases[seq.case_index].name;
    o.label = input.labels[q];
    o.type = "markers3d";
    o.unit = "m";
    o.num_measurements = static_cast<int>(seq.samples.size());
    double sum = 0.0;
    if (q < residuals.error.size()) {
      // Each sample's error in the report's residuals.csv, in the file's order of samples.
      for (size_t k = 0; k < residuals.error[q].size(); ++k) {
        const Eigen::Vector3d& e = residuals.error[q][k];
        sum += e.squaredNorm();
        MeasurementResidual mr;
        mr.case_index = seq.case_index;
        mr.case_name = o.case_name;
        mr.observation = o.label;
        mr.unit = "m";
        mr.measurement = static_cast<int>(k);
        mr.error = e;
        mr.sigma = seq.sigma;
        r.measurement_residuals.push_back(mr);
      }
    }
    o.rms = std::sqrt(sum / std::max(1, o.num_measurements));
    r.observations.push_back(o);
  }
  return r;
}

}  // namespace rodfit
