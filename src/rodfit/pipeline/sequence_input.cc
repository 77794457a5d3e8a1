// Observation sequences of a moving experiment (sequence_input.h) and the readers of sequence
// files the kinds share (sequence_files.h).
#include "rodfit/pipeline/sequence_input.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <utility>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/pipeline/fit_input.h"
#include "rodfit/pipeline/kind_support.h"
#include "rodfit/pipeline/observation_kind.h"
#include "rodfit/pipeline/sequence_files.h"

namespace rodfit {
namespace {

// A sample more than this many sigmas from anything the model can give leaves no residual
// (model - measured) / sigma whose square sums over a file's rows in double precision (1e100^2 x
// 1e6 rows stays finite): the units or the entry's sigma are wrong.
constexpr double kMaxSigmas = 1e100;

// Where an entry's message points back to: its YAML line.
std::string EntryAt(const Experiment& ex, const ObservationSpec& spec) {
  return ex.path + " line " + std::to_string(spec.line);
}

// A file with a t column read by an entry that also gives frame_rate: the times are used as
// they are, but their median step must agree with 1 / frame_rate within a factor of 2 either way
// (room for jitter and up to half the frames dropped). A log stamped in milliseconds (or with
// the wrong rate) then fails with the reason instead of running a thousand times slower.
void CheckTimesAgainstRate(const Experiment& ex, const ObservationSpec& spec,
                           const std::vector<double>& t) {
  if (!(spec.frame_rate > 0.0)) return;
  std::vector<double> times(t);
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  if (times.size() < 3) return;
  std::vector<double> steps(times.size() - 1);
  for (size_t k = 0; k + 1 < times.size(); ++k) steps[k] = times[k + 1] - times[k];
  std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
  const double median = steps[steps.size() / 2], nominal = 1.0 / spec.frame_rate;
  if (!(median >= 0.5 * nominal && median <= 2.0 * nominal))
    throw InputError(spec.file, 1, "t",
                     "its times step by a median " + Short(median) + " s, but frame_rate " +
                         Short(spec.frame_rate) + " Hz (" + EntryAt(ex, spec) + ") says " +
                         Short(nominal) + " s: t must be in seconds (or leave frame_rate out)");
}

// A coordinate field: a number, or missing (empty, nan, NaN: the sample was not seen).
bool ReadCoordinate(const CsvTable& table, int row, const std::string& column,
                    const std::string& text, double* value) {
  std::string lower = text;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower.empty() || lower == "nan") return false;
  if (!ParseDouble(text, value))
    throw InputError(table.name(), table.line(row), column,
                     "not a number: '" + ClipForMessage(text) + "' (leave it empty or nan when "
                     "the sample was not seen)");
  return true;
}

// A recorded sample's value within reach of a residual: a pixel (with its camera) on the sensor
// and within kMaxSigmas of the image, a point (camera null) within 100 rod lengths of the clamp and
// kMaxSigmas of the rod.
void CheckReach(const KindContext& context, const CsvTable& table, int r, const Camera* camera,
                const Vec3& value) {
  const Experiment& ex = context.experiment();
  const ObservationSpec& spec = context.spec();
  const std::string& file = spec.file;
  const double length = ex.scene.rod.length;
  const Vec3& clamp = ex.scene.cases[context.case_index()].clamp.position;
  if (camera) {
    CheckOnSensor(table, r, value.head<2>(), *camera, spec.camera);
    const double reach = value.head<2>().norm() + camera->K.width + camera->K.height;
    if (!(reach / spec.sigma <= kMaxSigmas))
      throw InputError(file, table.line(r), "u",
                       "the pixel and the image lie more than " + Short(kMaxSigmas) +
                           " sigma apart (sigma " + Short(spec.sigma) + " px, " +
                           EntryAt(ex, spec) + "): too many for a residual (is sigma right?)");
  } else if (!((value - clamp).norm() <= 100.0 * length)) {
    throw InputError(file, table.line(r), "x",
                     "the point lies more than 100 rod lengths from the clamp: not on the rod "
                     "(wrong units or frame?)");
  } else if (!(((value - clamp).norm() + length) / spec.sigma <= kMaxSigmas)) {
    // Within reach of the rod, but sigma is so small that no residual can be formed.
    throw InputError(file, table.line(r), "x",
                     "the point and the rod lie more than " + Short(kMaxSigmas) +
                         " sigma apart (sigma " + Short(spec.sigma) + " m, " +
                         EntryAt(ex, spec) + "): too many for a residual (is sigma right?)");
  }
}

// The sequence's frames: per recorded time, its seen samples (by_t: their indices in samples) as
// one measurement.
ObservationSequence Frames(const KindContext& context, bool with_s,
                           const std::map<double, std::vector<int>>& by_t,
                           const std::vector<SequenceSample>& samples,
                           FrameMeasurement frame_measurement) {
  const ObservationSpec& spec = context.spec();
  const std::string& file = spec.file;
  const int case_index = context.case_index();
  ObservationSequence seq;
  seq.case_index = case_index;
  for (const auto& [t, indices] : by_t) {
    if (indices.empty()) continue;
    std::vector<const SequenceSample*> seen;
    for (const int k : indices) seen.push_back(&samples[k]);
    ObservationSequence::Frame frame;
    frame.t = t;
    frame.sample = indices;
    try {
      frame.measurement = frame_measurement(context, with_s, seen);
    } catch (const std::invalid_argument& e) {
      // The observation models' own checks (a camera failing its check).
      throw InputError(file, 0, spec.type, e.what());
    }
    seq.frames.push_back(std::move(frame));
  }
  return seq;
}

}  // namespace

ObservationSequence ReadShapeSequence(const KindContext& context, bool pixels, SColumn s_column,
                                      FrameMeasurement frame_measurement) {
  const Experiment& ex = context.experiment();
  const ObservationSpec& spec = context.spec();
  const Camera* camera = pixels ? &context.camera() : nullptr;
  const double length = ex.scene.rod.length;
  const double duration = ex.scene.dynamics->duration;
  const CsvTable table = CsvTable::Read(spec.file);
  const std::string& file = spec.file;
  if (table.num_rows() < 1) throw InputError(file, 0, "", "no rows");
  const bool by_time = table.HasColumn("t");
  if (!by_time && !table.HasColumn("frame"))
    throw InputError(file, 1, "t", "a " + spec.type + " sequence needs a t column (or frame with "
                                   "the entry's frame_rate)");
  if (!by_time && !(spec.frame_rate > 0.0))
    throw InputError(file, 1, "frame", "a frame column needs frame_rate [Hz] in the entry (" +
                                           ex.path + " line " + std::to_string(spec.line) + ")");
  // Markers are identified by s; points3d and pixels without s are closest-point samples.
  const bool with_s =
      s_column == SColumn::kRequired || (s_column == SColumn::kOptional && table.HasColumn("s"));
  const std::vector<std::string> columns =
      pixels ? std::vector<std::string>{"u", "v"} : std::vector<std::string>{"x", "y", "z"};
  const std::vector<double> key = table.Column(by_time ? "t" : "frame");
  if (by_time) CheckTimesAgainstRate(ex, spec, key);
  const std::vector<double> s = with_s ? table.Column("s") : std::vector<double>();
  std::vector<std::vector<std::string>> text;
  for (const std::string& column : columns) text.push_back(table.TextColumn(column));
  std::map<double, std::vector<int>> by_t;  // time -> its recorded samples, in file order
  std::map<std::pair<double, double>, int> marker_line;  // (t, s) -> line (markers only)
  std::vector<SequenceSample> samples;
  for (int r = 0; r < table.num_rows(); ++r) {
    SequenceSample q;
    q.t = key[r];
    if (!by_time) {
      if (q.t != std::round(q.t) || q.t < 0.0)
        throw InputError(file, table.line(r), "frame", "must be an integer >= 0");
      q.t /= spec.frame_rate;
    }
    if (q.t < 0.0 || q.t > duration * (1.0 + 1e-12))
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "the sample's time " + Short(q.t) + " s lies outside the run [0, " +
                           Short(duration) + "] s (dynamics.duration)");
    if (with_s) {
      q.s = s[r];
      if (q.s < 0.0 || q.s > length)
        throw InputError(file, table.line(r), "s",
                         "must be in [0, " + Short(length) + "] (the rod's length)");
      if (const auto [it, fresh] = marker_line.emplace(std::make_pair(q.t, q.s), table.line(r));
          !fresh)
        throw InputError(file, table.line(r), "s",
                         "this marker's sample at this time is given twice (also line " +
                             std::to_string(it->second) + ")");
    }
    // Every time counts towards the limit, seen or not: it bounds the work of reading.
    by_t.emplace(q.t, std::vector<int>());
    if (static_cast<int>(by_t.size()) > kMaxSequenceTimes)
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "more than " + std::to_string(kMaxSequenceTimes) + " sample times");
    int given = 0;
    for (size_t a = 0; a < columns.size(); ++a)
      given += int(ReadCoordinate(table, r, columns[a], text[a][r], &q.value[a]));
    if (given == 0) continue;  // not seen
    if (given < static_cast<int>(columns.size()))
      throw InputError(file, table.line(r), columns[0],
                       pixels ? "u and v must be both given or both missing (a sample not seen)"
                              : "x, y and z must be all given or all missing (a sample not seen)");
    CheckReach(context, table, r, camera, q.value);
    by_t[q.t].push_back(static_cast<int>(samples.size()));
    samples.push_back(q);
  }
  if (samples.empty()) throw InputError(file, 0, "", "no recorded sample (every row is missing)");
  return Frames(context, with_s, by_t, samples, frame_measurement);
}

ObservationSequence ReadReactionSequence(const KindContext& context) {
  const Experiment& ex = context.experiment();
  const ObservationSpec& spec = context.spec();
  const int case_index = context.case_index();
  const double duration = ex.scene.dynamics->duration;
  const CsvTable table = CsvTable::Read(spec.file);
  const std::string& file = spec.file;
  if (table.num_rows() < 1) throw InputError(file, 0, "", "no rows");
  const bool by_time = table.HasColumn("t");
  if (!by_time && !table.HasColumn("frame"))
    throw InputError(file, 1, "t", "a reaction sequence needs a t column (or frame with the "
                                   "entry's frame_rate)");
  if (!by_time && !(spec.frame_rate > 0.0))
    throw InputError(file, 1, "frame", "a frame column needs frame_rate [Hz] in the entry (" +
                                           ex.path + " line " + std::to_string(spec.line) + ")");
  const bool moments = table.HasColumn("mx") || table.HasColumn("my") || table.HasColumn("mz");
  if (moments && !(spec.sigma_moment > 0.0))
    throw InputError(file, 1, "mx", "moment columns need sigma_moment in the entry (" + ex.path +
                                        " line " + std::to_string(spec.line) + ")");
  std::vector<std::string> columns = {"fx", "fy", "fz"};
  if (moments) columns.insert(columns.end(), {"mx", "my", "mz"});
  const std::vector<double> key = table.Column(by_time ? "t" : "frame");
  if (by_time) CheckTimesAgainstRate(ex, spec, key);
  std::vector<std::vector<std::string>> text;
  for (const std::string& column : columns) text.push_back(table.TextColumn(column));
  std::map<double, int> line_of_time;
  std::map<double, ForceMeasurement> by_t;
  for (int r = 0; r < table.num_rows(); ++r) {
    double t = key[r];
    if (!by_time) {
      if (t != std::round(t) || t < 0.0)
        throw InputError(file, table.line(r), "frame", "must be an integer >= 0");
      t /= spec.frame_rate;
    }
    if (t < 0.0 || t > duration * (1.0 + 1e-12))
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "the reading's time " + Short(t) + " s lies outside the run [0, " +
                           Short(duration) + "] s (dynamics.duration)");
    if (const auto [it, fresh] = line_of_time.emplace(t, table.line(r)); !fresh)
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "a reading at this time is given twice (also line " +
                           std::to_string(it->second) + ")");
    if (static_cast<int>(line_of_time.size()) > kMaxSequenceTimes)
      throw InputError(file, table.line(r), by_time ? "t" : "frame",
                       "more than " + std::to_string(kMaxSequenceTimes) + " sample times");
    double value[6] = {0, 0, 0, 0, 0, 0};
    int given = 0;
    for (size_t a = 0; a < columns.size(); ++a)
      given += int(ReadCoordinate(table, r, columns[a], text[a][r], &value[a]));
    if (given == 0) continue;  // not taken
    if (given < static_cast<int>(columns.size()))
      throw InputError(file, table.line(r), columns[0],
                       moments ? "fx, fy, fz, mx, my and mz must be all given or all missing (a "
                                 "reading not taken)"
                               : "fx, fy and fz must be all given or all missing (a reading not "
                                 "taken)");
    for (size_t a = 0; a < columns.size(); ++a) {
      // A reading is compared with a finite model force (moment): its own size in sigmas bounds
      // the residual.
      const double sigma = a < 3 ? spec.sigma : spec.sigma_moment;
      if (!(std::abs(value[a]) / sigma <= kMaxSigmas))
        throw InputError(file, table.line(r), columns[a],
                         Short(value[a]) + " is more than " + Short(kMaxSigmas) +
                             " sigma (" + (a < 3 ? "sigma " : "sigma_moment ") + Short(sigma) +
                             ", " + EntryAt(ex, spec) +
                             ") from zero: too many for a residual (wrong units, or is sigma "
                             "right?)");
    }
    ForceMeasurement reading;
    reading.point = spec.point;
    reading.sigma = spec.sigma;
    reading.force = Eigen::Vector3d(value[0], value[1], value[2]);
    reading.label = context.label() + " t=" + FormatDouble(t);
    if (moments) {
      reading.moment = Eigen::Vector3d(value[3], value[4], value[5]);
      reading.sigma_moment = spec.sigma_moment;
    }
    by_t.emplace(t, std::move(reading));
  }
  if (by_t.empty()) throw InputError(file, 0, "", "no reading (every row is missing)");
  ObservationSequence seq;
  seq.case_index = case_index;
  for (auto& [t, reading] : by_t) {
    ObservationSequence::Frame frame;
    frame.t = t;
    frame.measurement = std::make_shared<ForceReadings>(
        spec.type, context.label(), std::vector<ForceMeasurement>{std::move(reading)});
    seq.frames.push_back(std::move(frame));
  }
  return seq;
}

SequenceInput BuildSequenceInput(const Experiment& experiment) {
  if (!experiment.scene.dynamics)
    throw InputError(experiment.path, 1, "dynamics",
                     "observation sequences need a dynamics: block");
  // The fit differentiates the implicit steps it has sensitivities of (motion_fit.h).
  const std::string& integrator = experiment.scene.dynamics->integrator;
  if (integrator != "bdf2" && integrator != "backward_euler")
    throw InputError(experiment.path, experiment.integrator_line, "dynamics.integrator",
                     "the motion fit differentiates the bdf2 and backward_euler steps, not " +
                         integrator + " (fit with bdf2; simulate may use " + integrator + ")");
  SequenceInput input;
  CameraCache cameras;  // each file read once
  for (size_t c = 0; c < experiment.cases.size(); ++c) {
    std::vector<double> arc;
    try {
      arc = CaseVertexArcLengths(experiment.scene, static_cast<int>(c));
    } catch (const std::invalid_argument& e) {
      throw InputError(experiment.path, experiment.cases[c].line,
                       "cases[" + std::to_string(c) + "]", e.what());
    }
    const LoadCase& load_case = experiment.scene.cases[c];
    for (const ObservationSpec& spec : experiment.cases[c].observations) {
      // The experiment reader admits in a moving scene only the kinds that may move.
      const ObservationKind& kind = KindOf(spec);
      if (!kind.build_sequence) continue;
      const KindContext context(experiment, static_cast<int>(c), spec, load_case, arc, &cameras);
      input.sequences.push_back(kind.build_sequence(context));
      input.labels.push_back(context.label());
    }
  }
  if (input.sequences.empty())
    throw InputError(experiment.path, 0, "cases",
                     "no observation sequence to fit to (add observations to a case)");
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
    const Parameter& p = experiment.parameters.at(name);
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
  r.residual_dof = std::max(1, motion.noise_residuals - static_cast<int>(motion.names.size()));
  r.residual_variance = motion.residual_variance;
  r.seconds = motion.seconds;
  r.forward_solves = motion.evaluations;
  r.cost_per_iteration = motion.cost_per_iteration;
  r.seconds_per_iteration = motion.seconds_per_iteration;
  // The runs with their sensitivities: the forward solves and Jacobians together.
  r.solve_seconds = motion.run_seconds;
  r.trajectories = residuals.trajectories;
  r.fitted_names = motion.names;
  // Every parameter the static fit lists (the rod's and the springs'), then those only motion
  // sees (damping, the rod's mass) that the experiment gives.
  std::vector<std::string> listed;
  for (const Parameter& p : FitParametersOf(experiment)) listed.push_back(p.name);
  for (const MaterialParameterInfo& row : MaterialParameters())
    if ((row.kind == ParameterKind::kDamping || row.kind == ParameterKind::kMass) &&
        experiment.parameters.count(row.name))
      listed.push_back(row.name);
  for (const std::string& name : listed) {
    Parameter est;
    const auto spec = experiment.parameters.find(name);
    if (spec != experiment.parameters.end()) est = spec->second;
    est.name = name;
    est.fit = false;
    est.value = est.start =
        spec != experiment.parameters.end()
            ? spec->second.value
            : MaterialParameterValue(experiment.scene.material, name).value_or(0.0);
    const auto k = std::find(motion.names.begin(), motion.names.end(), name);
    if (k != motion.names.end()) {
      const size_t i = static_cast<size_t>(k - motion.names.begin());
      est.fit = true;
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
    const ObservationSequence& seq = input.sequences[q];
    ObservationFit o;
    o.case_index = seq.case_index;
    o.case_name = experiment.scene.cases[seq.case_index].name;
    o.label = input.labels[q];
    // Each sample's error in residuals.csv, in the file's order of samples, numbered per unit;
    // a reading's force [N] and moment [N m] (two samples of one measurement) apart.
    const Measurement& first = *seq.frames.front().measurement;
    const int per = std::max(1, first.num_samples() / std::max(1, first.num_measurements()));
    o.type = first.type();
    o.unit = first.unit();
    o.num_measurements = seq.num_samples() / per;
    double sum = 0.0, sum_second = 0.0;
    if (q < residuals.error.size())
      for (size_t k = 0; k < residuals.error[q].size(); ++k) {
        const int part = static_cast<int>(k) % per;
        const Eigen::Vector3d& e = residuals.error[q][k];
        (part == 0 ? sum : sum_second) += e.squaredNorm();
        MeasurementResidual mr;
        mr.case_index = seq.case_index;
        mr.case_name = o.case_name;
        mr.observation = o.label;
        mr.unit = first.sample_unit(part);
        mr.measurement = static_cast<int>(k) / per;
        mr.error = e;
        mr.sigma = first.sample_sigma(part);
        r.measurement_residuals.push_back(mr);
      }
    o.rms = std::sqrt(sum / std::max(1, o.num_measurements));
    if (per == 2) o.rms_moment = std::sqrt(sum_second / std::max(1, o.num_measurements));
    r.observations.push_back(o);
  }
  return r;
}

}  // namespace rodfit
