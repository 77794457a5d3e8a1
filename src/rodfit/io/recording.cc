#include "rodfit/io/recording.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"
#include "rodfit/model/material_parameters.h"
#include "rodfit/model/scene.h"

namespace rodfit {

namespace {

// A coordinate as mocap software exports it: a number, or empty / "nan" (any case) where the
// marker was not seen (NaN returned). Anything else is an error naming the line and column.
double ParseCoordinate(const std::string& text, const std::string& path, int line,
                       const std::string& column) {
  std::string lower = text;
  for (char& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (lower.empty() || lower == "nan") return std::numeric_limits<double>::quiet_NaN();
  double v = 0.0;
  if (!ParseDouble(text, &v))
    throw InputError(path, line, column,
                     "not a number: '" + ClipForMessage(text) + "' (empty or nan: not seen)");
  return v;
}

// Frame numbers of the distinct times of a `t` column, and the frame interval [s]. The
// interval first from the median of successive differences; each time's frame from its
// predecessor's plus the rounded difference (a dropped frame is a difference of two
// intervals); then the interval and start refitted by least squares over all times, so jitter
// does not accumulate. A time further than kMaxJitter intervals from its frame's nominal time
// is irregular sampling: an error naming the line.
constexpr double kMaxJitter = 0.1;

struct TimeFrames {
  std::vector<double> times;  // distinct, increasing
  std::vector<long> frame;    // per distinct time
  double interval = 0.0;      // [s]
};

// The least-squares line t = t0 + k dt through the frames' times: its slope dt and the means of
// k and t (t0 = mean_t - mean_k dt).
struct FrameLine {
  double dt, mean_k, mean_t;
};

FrameLine FitFrameLine(const std::vector<long>& frame, const std::vector<double>& times) {
  const size_t n = times.size();
  double mk = 0.0, mt = 0.0;
  for (size_t i = 0; i < n; ++i) {
    mk += frame[i];
    mt += times[i];
  }
  mk /= n;
  mt /= n;
  double skk = 0.0, skt = 0.0;
  for (size_t i = 0; i < n; ++i) {
    skk += (frame[i] - mk) * (frame[i] - mk);
    skt += (frame[i] - mk) * (times[i] - mt);
  }
  return {skt / skk, mk, mt};
}

// Motion capture runs at a whole number of hertz: an interval whose rate is within 0.1 % of one
// is taken as it, so the rollout's time step can divide the interval exactly.
double WholeHertz(double dt) {
  const double rate = 1.0 / dt, whole = std::round(rate);
  return whole >= 1.0 && std::abs(rate - whole) <= 1e-3 * rate ? 1.0 / whole : dt;
}

// The documented rule is a bound: some t0 + k dt within kMaxJitter dt of every time. The
// least-squares line can miss it where one exists (alternating jitter near the bound over few
// frames tilts it): then the line of least largest offset (t0 the offsets' mid-range; dt,
// unless the frame rate is given, by a golden-section search on the offsets' range, which is
// convex in dt) is taken, when it keeps every time within the bound.
void MinimaxFrameLine(const TimeFrames& out, double frame_rate, double* dt, double* t0) {
  const size_t n = out.times.size();
  auto half_range = [&](double interval, double* start) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t i = 0; i < n; ++i) {
      const double r = out.times[i] - out.frame[i] * interval;
      lo = std::min(lo, r);
      hi = std::max(hi, r);
    }
    *start = 0.5 * (lo + hi);
    return 0.5 * (hi - lo);
  };
  double interval = *dt, start = 0.0;
  if (!(frame_rate > 0.0)) {
    double a = 0.8 * *dt, b = 1.2 * *dt;
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    for (int it = 0; it < 100 && b - a > 1e-15 * *dt; ++it) {
      const double c = b - g * (b - a), d = a + g * (b - a);
      if (half_range(c, &start) <= half_range(d, &start)) b = d; else a = c;
    }
    interval = WholeHertz(0.5 * (a + b));
  }
  if (half_range(interval, &start) <= kMaxJitter * interval) {
    *dt = interval;
    *t0 = start;
  }
}

TimeFrames FramesOfTimes(const CsvTable& table, const std::vector<double>& t,
                         const std::string& path, double frame_rate) {
  TimeFrames out;
  out.times = t;
  std::sort(out.times.begin(), out.times.end());
  out.times.erase(std::unique(out.times.begin(), out.times.end()), out.times.end());
  const size_t n = out.times.size();
  if (n < 2) throw InputError(path, table.line(0), "t", "needs at least 2 times");
  auto line_of = [&](double time) {
    for (int r = 0; r < table.num_rows(); ++r)
      if (t[r] == time) return table.line(r);
    return 0;
  };
  std::vector<double> diff(n - 1);
  for (size_t i = 1; i < n; ++i) diff[i - 1] = out.times[i] - out.times[i - 1];
  std::vector<double> sorted = diff;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  double dt = sorted[sorted.size() / 2];
  out.frame.assign(n, 0);
  // Alternating jitter (+9 %, -9 %, ...) puts every difference 18 % off the interval, and the
  // median with them: the interval is refined by least squares over the frames the differences
  // round to before any difference is judged against it.
  for (int round = 0; round < 5; ++round) {
    for (size_t i = 1; i < n; ++i)
      out.frame[i] = out.frame[i - 1] + std::max(1L, std::lround(diff[i - 1] / dt));
    const double refined = FitFrameLine(out.frame, out.times).dt;
    if (!(refined > 0.0) || std::abs(refined - dt) <= 1e-12 * dt) break;
    dt = refined;
  }
  for (size_t i = 1; i < n; ++i) {
    const long step = std::lround(diff[i - 1] / dt);
    if (step < 1 || std::abs(diff[i - 1] - step * dt) > 2.0 * kMaxJitter * dt) {
      char text[200];
      std::snprintf(text, sizeof(text),
                    "irregular sampling: %.6g s after the previous time, not a whole number of "
                    "frame intervals (%.6g s, jitter up to %.0f %% accepted)",
                    diff[i - 1], dt, 100.0 * kMaxJitter);
      throw InputError(path, line_of(out.times[i]), "t", text);
    }
    out.frame[i] = out.frame[i - 1] + step;
  }
  if (out.frame.back() >= 100000)
    throw InputError(path, line_of(out.times.back()), "t", "more than 100000 frames");
  // Least squares t = t0 + k dt.
  const FrameLine line = FitFrameLine(out.frame, out.times);
  const double fitted = line.dt;
  if (frame_rate > 0.0) {
    dt = 1.0 / frame_rate;
    if (std::abs(fitted - dt) > 0.01 * dt) {
      char text[200];
      std::snprintf(text, sizeof(text),
                    "--frame-rate %.6g Hz disagrees with the times of the t column (%.6g Hz)",
                    frame_rate, 1.0 / fitted);
      throw InputError(path, 1, "t", text);
    }
  } else {
    dt = WholeHertz(fitted);
  }
  double t0 = line.mean_t - line.mean_k * dt;
  bool within = true;
  for (size_t i = 0; i < n && within; ++i)
    within = std::abs(out.times[i] - (t0 + out.frame[i] * dt)) <= kMaxJitter * dt;
  if (!within) MinimaxFrameLine(out, frame_rate, &dt, &t0);
  for (size_t i = 0; i < n; ++i) {
    const double off = out.times[i] - (t0 + out.frame[i] * dt);
    if (std::abs(off) > kMaxJitter * dt) {
      char text[200];
      std::snprintf(text, sizeof(text),
                    "irregular sampling: %.3g s from its frame's nominal time (frame interval "
                    "%.6g s, jitter up to %.0f %% accepted)",
                    off, dt, 100.0 * kMaxJitter);
      throw InputError(path, line_of(out.times[i]), "t", text);
    }
  }
  if (dt > kMaxFrameInterval) {
    char text[240];
    std::snprintf(text, sizeof(text),
                  "the frames are %.6g s apart, more than %.3g s: times in milliseconds? (the t "
                  "column is in seconds; --frame-rate in Hz)",
                  dt, kMaxFrameInterval);
    throw InputError(path, table.line(0), "t", text);
  }
  out.interval = dt;
  return out;
}

// Markers numbered out of order along the rod (docs/formats.md, "Recordings"): in frame 0 the
// polyline through the seen markers in label order folds back (a turn above 150 degrees between
// successive gaps) or is far longer than the nearest-neighbour path through them.
void CheckMarkerOrder(const MarkerRecording& rec) {
  const Eigen::Matrix3Xd& f = rec.frames.front();
  std::vector<int> seen;
  for (int m = 0; m < f.cols(); ++m)
    if (f.col(m).allFinite()) seen.push_back(m);
  if (seen.size() < 3) return;
  double label_length = 0.0;
  for (size_t i = 1; i < seen.size(); ++i) label_length += (f.col(seen[i]) - f.col(seen[i - 1])).norm();
  for (size_t i = 1; i + 1 < seen.size(); ++i) {
    const Eigen::Vector3d a = f.col(seen[i]) - f.col(seen[i - 1]), b = f.col(seen[i + 1]) - f.col(seen[i]);
    const double cos_turn = a.dot(b) / std::max(a.norm() * b.norm(), 1e-300);
    if (cos_turn < std::cos(150.0 * M_PI / 180.0)) {
      char text[240];
      std::snprintf(text, sizeof(text),
                    "markers out of order along the rod: in frame 0 the line through markers %d, "
                    "%d, %d folds back (turns %.0f degrees); number the markers 0..M-1 along the rod",
                    seen[i - 1], seen[i], seen[i + 1], std::acos(std::max(-1.0, cos_turn)) * 180.0 / M_PI);
      throw InputError(rec.file, 0, "marker", text);
    }
  }
  // The greedy nearest-neighbour path from the first marker.
  std::vector<char> visited(seen.size(), 0);
  size_t at = 0;
  visited[0] = 1;
  double nn_length = 0.0;
  for (size_t step = 1; step < seen.size(); ++step) {
    size_t best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < seen.size(); ++j) {
      if (visited[j]) continue;
      const double d = (f.col(seen[j]) - f.col(seen[at])).norm();
      if (d < best_d) {
        best_d = d;
        best = j;
      }
    }
    visited[best] = 1;
    nn_length += best_d;
    at = best;
  }
  if (label_length > 1.5 * nn_length) {
    char text[240];
    std::snprintf(text, sizeof(text),
                  "markers out of order along the rod: in frame 0 the line through them in label "
                  "order is %.3g m, %.2g times the nearest-neighbour path; number the markers "
                  "0..M-1 along the rod",
                  label_length, label_length / nn_length);
    throw InputError(rec.file, 0, "marker", text);
  }
}

}  // namespace

MarkerRecording ReadMarkerRecording(const std::string& path, double frame_rate,
                                    double position_scale) {
  constexpr int kMaxFrames = 100000, kMaxMarkers = 10000;
  const CsvTable table = CsvTable::Read(path);
  MarkerRecording rec;
  rec.file = path;
  if (table.num_rows() < 1) throw InputError(path, 0, "", "no rows");
  if (table.HasColumn("case")) {
    // simulate --markers writes one recording per case into one file: one case per rollout.
    const std::vector<std::string> cases = table.TextColumn("case");
    for (int r = 1; r < table.num_rows(); ++r)
      if (cases[r] != cases[0])
        throw InputError(path, table.line(r), "case",
                         "a second case (" + ClipForMessage(cases[r]) +
                             "): a recording holds one case; split the file by its case column");
  }
  const bool by_frame = table.HasColumn("frame");
  if (!by_frame && !table.HasColumn("t"))
    throw InputError(path, 1, "frame", "needs a frame column (with --frame-rate) or a t column");
  const std::vector<double> key = table.Column(by_frame ? "frame" : "t");
  // Wide (one row per frame, as motion-capture software exports): x0,y0,z0,x1,y1,z1,... with
  // no marker column. Long: one row per marker and frame.
  const bool wide = !table.HasColumn("marker") && table.HasColumn("x0");
  std::vector<std::vector<std::string>> wide_text;  // per marker: x, y, z columns
  if (wide) {
    for (int m = 0; table.HasColumn("x" + std::to_string(m)); ++m) {
      if (m >= kMaxMarkers) throw InputError(path, 1, "x" + std::to_string(m), "more than 10000 markers");
      for (const char* axis : {"x", "y", "z"})
        wide_text.push_back(table.TextColumn(axis + std::to_string(m)));
    }
  }
  const std::vector<double> marker = wide ? std::vector<double>() : table.Column("marker");
  const std::vector<std::string> text[3] = {
      wide ? std::vector<std::string>() : table.TextColumn("x"),
      wide ? std::vector<std::string>() : table.TextColumn("y"),
      wide ? std::vector<std::string>() : table.TextColumn("z")};
  std::vector<long> frame_of(table.num_rows());
  int markers = 0;
  long frames = 0;
  if (!by_frame) {
    const TimeFrames tf = FramesOfTimes(table, key, path, frame_rate);
    rec.frame_interval = tf.interval;
    for (int r = 0; r < table.num_rows(); ++r) {
      const size_t i = static_cast<size_t>(
          std::lower_bound(tf.times.begin(), tf.times.end(), key[r]) - tf.times.begin());
      frame_of[r] = tf.frame[i];
    }
  } else {
    if (!(frame_rate > 0.0)) throw InputError(path, 1, "frame", "a frame column needs --frame-rate");
    rec.frame_interval = 1.0 / frame_rate;
    if (rec.frame_interval > kMaxFrameInterval)
      throw InputError(path, 1, "frame",
                       "--frame-rate " + FormatDouble(frame_rate) + " Hz puts the frames " +
                           FormatDouble(rec.frame_interval) + " s apart, more than " +
                           FormatDouble(kMaxFrameInterval) + " s: a rate in Hz (frames per second)?");
    for (int r = 0; r < table.num_rows(); ++r) {
      if (std::abs(key[r] - std::round(key[r])) > 1e-6 || key[r] < 0 || key[r] >= kMaxFrames)
        throw InputError(path, table.line(r), "frame", "must be an integer in [0, 100000)");
      frame_of[r] = std::lround(key[r]);
    }
  }
  for (int r = 0; r < table.num_rows(); ++r) {
    frames = std::max(frames, frame_of[r] + 1);
    if (wide) continue;
    if (marker[r] != std::round(marker[r]) || marker[r] < 0 || marker[r] >= kMaxMarkers)
      throw InputError(path, table.line(r), "marker", "must be an integer in [0, 10000)");
    markers = std::max(markers, static_cast<int>(marker[r]) + 1);
  }
  if (wide) markers = static_cast<int>(wide_text.size() / 3);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rec.frames.assign(frames, Eigen::Matrix3Xd::Constant(3, markers, nan));
  std::vector<std::vector<char>> given(frames, std::vector<char>(markers, 0));
  static const char* const kAxis[3] = {"x", "y", "z"};
  for (int r = 0; wide && r < table.num_rows(); ++r) {
    if (given[frame_of[r]][0])
      throw InputError(path, table.line(r), by_frame ? "frame" : "t", "this frame is given twice");
    for (int m = 0; m < markers; ++m) {
      given[frame_of[r]][m] = 1;
      Eigen::Vector3d p;
      for (int a = 0; a < 3; ++a)
        p[a] = ParseCoordinate(wide_text[3 * m + a][r], path, table.line(r),
                               kAxis[a] + std::to_string(m));
      if (p.allFinite()) rec.frames[frame_of[r]].col(m) = position_scale * p;
    }
  }
  for (int r = 0; !wide && r < table.num_rows(); ++r) {
    const int m = static_cast<int>(marker[r]);
    if (given[frame_of[r]][m])
      throw InputError(path, table.line(r), "marker", "this marker is given twice in one frame");
    given[frame_of[r]][m] = 1;
    Eigen::Vector3d p;
    for (int a = 0; a < 3; ++a) p[a] = ParseCoordinate(text[a][r], path, table.line(r), kAxis[a]);
    // A sample with any coordinate missing was not seen (left NaN).
    if (p.allFinite()) rec.frames[frame_of[r]].col(m) = position_scale * p;
  }
  CheckMarkerOrder(rec);
  return rec;
}

void CheckRecordingScale(const MarkerRecording& recording, double rod_length,
                         const std::string& hint) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Eigen::Matrix3Xd& frame : recording.frames) {
    for (int m = 0; m < frame.cols(); ++m) {
      if (!frame.col(m).allFinite()) continue;
      lo = lo.cwiseMin(frame.col(m));
      hi = hi.cwiseMax(frame.col(m));
    }
  }
  if (!(hi.x() >= lo.x())) return;  // no marker seen: the rollout says so
  const double span = (hi - lo).norm();
  if (span > 100.0 * rod_length) {
    char text[256];
    std::snprintf(text, sizeof(text),
                  "the markers span %.4g m, more than 100 rod lengths (the rod is %.4g m): "
                  "millimetres read as metres? (%s)",
                  span, rod_length, hint.c_str());
    throw InputError(recording.file, 0, "x", text);
  }
  int seen = 0;
  for (int m = 0; m < recording.frames.front().cols(); ++m)
    seen += recording.frames.front().col(m).allFinite() ? 1 : 0;
  if (seen >= 2 && span < 0.01 * rod_length) {
    char text[256];
    std::snprintf(text, sizeof(text),
                  "the markers span %.4g m, less than a hundredth of the rod (%.4g m): metres "
                  "read as millimetres? (%s)",
                  span, rod_length, hint.c_str());
    throw InputError(recording.file, 0, "x", text);
  }
}

void CheckRecordingFitsRod(const MarkerRecording& recording, double rod_length) {
  for (size_t k = 0; k < recording.frames.size(); ++k) {
    const Eigen::Matrix3Xd& frame = recording.frames[k];
    double polyline = 0.0;
    int last = -1, seen = 0;
    for (int m = 0; m < frame.cols(); ++m) {
      if (!frame.col(m).allFinite()) continue;
      if (last >= 0) polyline += (frame.col(m) - frame.col(last)).norm();
      last = m;
      ++seen;
    }
    if (seen < 2) continue;
    const double ratio = polyline / rod_length;
    const bool too_long = ratio > 1.0 + kRecordingLengthTolerance;
    const bool too_short = k == 0 && ratio < 1.0 - kRecordingLengthTolerance;
    if (!too_long && !too_short) continue;
    char text[400];
    std::snprintf(text, sizeof(text),
                  "frame %zu: the markers' polyline is %.4g m long, %.3g %% of the rod's length "
                  "(%.4g m); a recording of this rod lies within %.3g %% of it%s (a recording "
                  "of another rod, or scaled?)",
                  k, polyline, 100.0 * ratio, rod_length, 100.0 * kRecordingLengthTolerance,
                  k == 0 ? " in its first frame, whose markers are placed along the rod by it"
                         : "");
    throw InputError(recording.file, 0, "", text);
  }
}

namespace {

// The 1-based line of the first `"key"` at or after byte `from` of a JSON text (0: not found),
// so that a message points at the entry.
int JsonKeyLine(const std::string& text, const std::string& key, size_t from = 0) {
  const size_t at = text.find("\"" + key + "\"", from);
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

}  // namespace

std::vector<std::pair<std::string, double>> ReadMotionFitValues(const std::string& path) {
  constexpr std::uintmax_t kMaxBytes = std::uintmax_t{1} << 20;  // a few parameters: 1 MiB is ample
  const std::string text = ReadInputFile(path, "a motion fit file (motion_fit.json)", kMaxBytes);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path, 0, "", std::string("not JSON: ") + e.what());
  }
  const size_t params_at = text.find("\"parameters\"");
  if (!doc.is_object() || !doc.contains("parameters") || !doc["parameters"].is_object() ||
      (doc["parameters"].empty() && !doc.contains("rest_shape")))
    throw InputError(path, JsonKeyLine(text, "parameters"), "parameters",
                     "a motion fit file has a parameters object with each fitted value (written "
                     "by rollout --fit)");
  std::vector<std::pair<std::string, double>> values;
  for (const auto& [name, entry] : doc["parameters"].items()) {
    const int line = JsonKeyLine(text, name, params_at == std::string::npos ? 0 : params_at);
    const MaterialParameterInfo* row = FindMaterialParameter(name);
    if (!row || !InMotionModel(*row))
      throw InputError(path, line, "parameters." + ClipForMessage(name),
                       "not a parameter of the motion (bend_stiffness, damping, ...)");
    if (!entry.is_object() || !entry.contains("value") || !entry["value"].is_number() ||
        !(entry["value"].get<double>() > 0.0) || !std::isfinite(entry["value"].get<double>()))
      throw InputError(path, line, "parameters." + name + ".value", "must be a number > 0");
    values.emplace_back(name, entry["value"].get<double>());
  }
  return values;
}

bool ReadMotionFitRestShape(const std::string& path, double rod_length, std::vector<double>* s,
                            std::vector<Eigen::Vector3d>* profile) {
  constexpr std::uintmax_t kMaxBytes = std::uintmax_t{1} << 20;
  const std::string text = ReadInputFile(path, "a motion fit file (motion_fit.json)", kMaxBytes);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(path, 0, "", std::string("not JSON: ") + e.what());
  }
  if (!doc.is_object() || !doc.contains("rest_shape")) return false;
  const nlohmann::json& r = doc["rest_shape"];
  const int line = JsonKeyLine(text, "rest_shape");
  auto numbers = [&](const char* key, std::vector<double>* out) {
    if (!r.is_object() || !r.contains(key) || !r[key].is_array())
      throw InputError(path, line, std::string("rest_shape.") + key, "must be a list of numbers");
    out->clear();
    for (const nlohmann::json& v : r[key]) {
      if (!v.is_number() || !std::isfinite(v.get<double>()))
        throw InputError(path, line, std::string("rest_shape.") + key, "must be finite numbers");
      out->push_back(v.get<double>());
    }
  };
  std::vector<double> knots, k1, k2, tau;
  numbers("s_m", &knots);
  numbers("k1_per_m", &k1);
  numbers("k2_per_m", &k2);
  numbers("tau_per_m", &tau);
  if (knots.size() < 2 || k1.size() != knots.size() || k2.size() != knots.size() ||
      tau.size() != knots.size())
    throw InputError(path, line, "rest_shape",
                     "s_m, k1_per_m, k2_per_m and tau_per_m must have one entry per knot (2 or more)");
  for (size_t j = 0; j < knots.size(); ++j)
    if (knots[j] < 0.0 || knots[j] > rod_length * (1.0 + 1e-9) || (j > 0 && !(knots[j] > knots[j - 1])))
      throw InputError(path, line, "rest_shape.s_m",
                       "must increase strictly within the rod's length (" +
                           FormatDouble(rod_length) + " m)");
  *s = knots;
  profile->resize(knots.size());
  for (size_t j = 0; j < knots.size(); ++j) (*profile)[j] = Vec3(k1[j], k2[j], tau[j]);
  return true;
}

}  // namespace rodfit
